//! The starting clays are flat where they should be flat and round where they should be round,
//! measured on the exported mesh (octree, weld, OBJ written and read back) of `build_clay` at
//! the resolutions a script may ask for (`[clay] resolution`, 8 to 96):
//! - block: each face flat within 0.02% of the block's size over its part two and a half knot
//!   spans or more from the edges (blocks under 11 coefficients across have no such part: their
//!   faces bow, measured and bounded separately), the face where the box's face is (within a
//!   hundredth of a span), no vertex above a face's plane by more than 0.05% of the size (no
//!   ridge along an edge, no knob at a corner), the eight corners and the twelve edges alike and
//!   rounded as one box of radius one to two knot spans would be, and the surface convex around
//!   every corner (no pinch);
//! - sphere: every vertex within two hundredths of a knot span of the asked radius.
//!
//! The block is the middle half of the lattice: `[(n − 1)/4, 3(n − 1)/4]` knot spans on each
//! axis; the sphere has radius `(n − 1)/4` spans about the lattice's centre. Every figure is
//! printed (`--nocapture`).

use dynaclay::engine::{CLAY_SPACING, build_clay};
use dynaclay::field::BSplineLattice;
use dynaclay::io::{ClayShape, ClaySpec};
use dynaclay::mesh::{BrickOctree, MeshFormat, SampleGrid, write_mesh};
use glam::Vec3;

/// Marching-cubes cells per knot span, as the engine meshes (`EngineConfig::cells_per_span`).
const CELLS_PER_SPAN: u32 = 4;
/// The part of a face at least this many knot spans from its edges is flat by design.
const FLAT_MARGIN_SPANS: f32 = 2.5;
/// Faces flat within this fraction of the block's size.
const FLATNESS: f32 = 2e-4;
/// No vertex above a face's plane by more than this fraction of the size.
const RIDGE: f32 = 5e-4;
/// A face's plane within this many knot spans of the box's face.
const FACE_PLACE_SPANS: f32 = 0.01;
/// Convex around a corner within this many knot spans (a marching-cubes facet's error is
/// about a thousandth of a span; the least-squares fit of a sharp box was pinched by a
/// quarter of a span).
const CONCAVITY_SPANS: f32 = 0.01;
/// Every sphere vertex within this many knot spans of the radius.
const SPHERE_SPANS: f32 = 0.02;

/// Positions and normals of the exported mesh of `field`, read back from its OBJ file.
fn exported(field: &BSplineLattice, name: &str) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut octree = BrickOctree::new(SampleGrid::for_lattice(field, CELLS_PER_SPAN).unwrap());
    octree.rebuild(field);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    write_mesh(&path, &octree.weld(), MeshFormat::Obj).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    let parse = |l: &str| {
        let v: Vec<f32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
        Vec3::new(v[0], v[1], v[2])
    };
    let positions: Vec<Vec3> = text
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(parse)
        .collect();
    let normals: Vec<Vec3> = text
        .lines()
        .filter_map(|l| l.strip_prefix("vn "))
        .map(parse)
        .collect();
    assert_eq!(positions.len(), normals.len());
    assert!(!positions.is_empty(), "{name}: empty mesh");
    (positions, normals)
}

fn clay(shape: ClayShape, resolution: usize) -> BSplineLattice {
    build_clay(&ClaySpec {
        shape,
        resolution,
        session: None,
    })
    .unwrap()
}

fn min_max(values: impl IntoIterator<Item = f32>) -> (f32, f32) {
    values
        .into_iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        })
}

/// What the block's exported mesh measures, in field units.
#[derive(Debug)]
struct BlockFigures {
    size: f32,
    /// Largest peak-to-peak spread of a face's vertices along its normal over the part of the
    /// face [`FLAT_MARGIN_SPANS`] or more from its edges (`None` when the block has no such part).
    face_spread: Option<f32>,
    /// Largest distance of a face's measured plane (mean over that part) from the box's face.
    face_offset: Option<f32>,
    /// Largest depth of a face's centre (its vertices within half a span of the centre line)
    /// below the box's face.
    centre_drop: f32,
    /// Highest any vertex rises above a face's plane (the measured one where there is one,
    /// else the box's face), outside the corners' regions (within the flat margin of two
    /// faces): an edge's ridge.
    ridge: f32,
    /// The same for the vertices in the corners' regions (the flat margin, or half the
    /// half-size if less, from two faces): a corner's knob.
    corner_excess: f32,
    /// Distance from each of the box's corners to the nearest vertex.
    corner_insets: [f32; 8],
    /// Distance from the middle of each of the box's edges to the nearest vertex.
    edge_insets: [f32; 12],
    /// The largest amount by which a vertex near a corner lies outside the tangent plane
    /// (exported normal) of another vertex within 1.5 spans of it (zero for a convex corner).
    corner_concavity: f32,
}

fn measure_block(resolution: usize) -> BlockFigures {
    let field = clay(ClayShape::Block, resolution);
    let (v, normals) = exported(&field, "block.obj");
    let h = CLAY_SPACING;
    let extent = (resolution - 1) as f32 * h;
    let centre = Vec3::splat(0.5 * extent);
    let half = 0.25 * extent;
    let margin = FLAT_MARGIN_SPANS * h;
    let mut face_spread: Option<f32> = None;
    let mut face_offset: Option<f32> = None;
    let mut centre_drop = 0.0_f32;
    let mut ridge = f32::NEG_INFINITY;
    let mut corner_excess = f32::NEG_INFINITY;
    for axis in 0..3 {
        for sign in [-1.0_f32, 1.0] {
            // Height above the centre along the face's normal, and distances across the face.
            let along = |p: Vec3| sign * (p[axis] - centre[axis]);
            let across = |p: Vec3| {
                let d = (p - centre).abs();
                (d[(axis + 1) % 3], d[(axis + 2) % 3])
            };
            let on_face = |p: Vec3| along(p) > half - h;
            let flat: Vec<f32> = v
                .iter()
                .filter(|&&p| on_face(p) && across(p).0.max(across(p).1) <= half - margin)
                .map(|&p| along(p))
                .collect();
            let plane = if flat.is_empty() {
                half
            } else {
                let (lo, hi) = min_max(flat.iter().copied());
                let mean = flat.iter().sum::<f32>() / flat.len() as f32;
                face_spread = Some(face_spread.unwrap_or(0.0).max(hi - lo));
                face_offset = Some(face_offset.unwrap_or(0.0).max((mean - half).abs()));
                mean
            };
            let (_, top) = min_max(
                v.iter()
                    .filter(|&&p| on_face(p) && across(p).0.max(across(p).1) <= 0.5 * h)
                    .map(|&p| along(p)),
            );
            centre_drop = centre_drop.max(half - top);
            for &p in &v {
                let (b, c) = across(p);
                if b.min(c) > half - margin.min(0.5 * half) {
                    corner_excess = corner_excess.max(along(p) - plane);
                } else {
                    ridge = ridge.max(along(p) - plane);
                }
            }
        }
    }
    let nearest = |q: Vec3| {
        v.iter()
            .map(|&p| (p - q).length())
            .fold(f32::INFINITY, f32::min)
    };
    let mut corner_insets = [0.0; 8];
    let mut corner_concavity = 0.0_f32;
    for (c, inset) in corner_insets.iter_mut().enumerate() {
        let s = Vec3::new(
            if c & 1 == 0 { -1.0 } else { 1.0 },
            if c & 2 == 0 { -1.0 } else { 1.0 },
            if c & 4 == 0 { -1.0 } else { 1.0 },
        );
        let corner = centre + s * half;
        *inset = nearest(corner);
        let near: Vec<usize> = (0..v.len())
            .filter(|&i| ((v[i] - corner) * s).min_element() > -margin)
            .collect();
        for &i in &near {
            let n = normals[i].normalize_or_zero();
            for &j in &near {
                if (v[j] - v[i]).length() < 1.5 * h {
                    corner_concavity = corner_concavity.max((v[j] - v[i]).dot(n));
                }
            }
        }
    }
    let mut edge_insets = [0.0; 12];
    for (e, inset) in edge_insets.iter_mut().enumerate() {
        // Edge `e` runs along axis `e / 4`, at the signs `e % 4` on the other two axes.
        let axis = e / 4;
        let mut mid = centre;
        mid[(axis + 1) % 3] += if e & 1 == 0 { -half } else { half };
        mid[(axis + 2) % 3] += if e & 2 == 0 { -half } else { half };
        *inset = nearest(mid);
    }
    BlockFigures {
        size: 2.0 * half,
        face_spread,
        face_offset,
        centre_drop,
        ridge,
        corner_excess,
        corner_insets,
        edge_insets,
        corner_concavity,
    }
}

/// Measures the block at `resolution`, prints the figures and checks them.
fn check_block(resolution: usize) {
    let f = measure_block(resolution);
    let h = CLAY_SPACING;
    let pct = |x: f32| 100.0 * x / f.size;
    let (c_lo, c_hi) = min_max(f.corner_insets);
    let (e_lo, e_hi) = min_max(f.edge_insets);
    println!(
        "block {resolution}³ (size {:.3}): face spread {}, face plane off by {}, centre {:.4}% below the face, \
         ridge {:.4}%, corner knob {:.4}%, corner inset {:.3}% ({:.3} spans: radius {:.2}), edge \
         inset {:.3}% ({:.3} spans: radius {:.2}), corner concavity {:.4} spans",
        f.size,
        f.face_spread
            .map_or("— (no flat part)".into(), |x| format!("{:.4}%", pct(x))),
        f.face_offset
            .map_or("—".into(), |x| format!("{:.4} spans", x / h)),
        pct(f.centre_drop),
        pct(f.ridge),
        pct(f.corner_excess),
        pct(c_hi),
        c_hi / h,
        c_hi / h / (3f32.sqrt() - 1.0),
        pct(e_hi),
        e_hi / h,
        e_hi / h / (2f32.sqrt() - 1.0),
        f.corner_concavity / h,
    );
    if let (Some(spread), Some(offset)) = (f.face_spread, f.face_offset) {
        assert!(
            spread <= FLATNESS * f.size,
            "{resolution}³: a face's flat part spreads {:.4}% of the size",
            pct(spread)
        );
        assert!(
            offset <= FACE_PLACE_SPANS * h,
            "{resolution}³: a face's plane is {:.4} spans off the box's face",
            offset / h
        );
    } else {
        // Under five spans across, the rounding of opposite edges meets: the face bows, its
        // centre a little below the box's face.
        assert!(resolution < 11, "{resolution}³ has no flat part");
        assert!(
            f.centre_drop <= 0.2 * h,
            "{resolution}³: a face's centre is {:.3} spans below the box's face",
            f.centre_drop / h
        );
    }
    assert!(
        f.ridge <= RIDGE * f.size,
        "{resolution}³: an edge rises {:.4}% of the size above a face",
        pct(f.ridge)
    );
    assert!(
        f.corner_excess <= RIDGE * f.size,
        "{resolution}³: a corner rises {:.4}% of the size above a face",
        pct(f.corner_excess)
    );
    assert!(
        c_hi - c_lo <= 1e-4 * f.size && e_hi - e_lo <= 1e-4 * f.size,
        "{resolution}³: corners {c_lo}..{c_hi}, edges {e_lo}..{e_hi} differ"
    );
    // Rounded evenly: a box rounded with radius r has its corners (√3 − 1) r and its edges
    // (√2 − 1) r in from the sharp box's; the radii the two give agree within 10%, and are
    // between one and two knot spans.
    let (r_corner, r_edge) = (c_hi / (3f32.sqrt() - 1.0), e_hi / (2f32.sqrt() - 1.0));
    assert!(
        (r_corner / r_edge - 1.0).abs() <= 0.1 && (h..=2.0 * h).contains(&r_edge),
        "{resolution}³: corners rounded as by radius {r_corner}, edges by {r_edge}"
    );
    assert!(
        f.corner_concavity <= CONCAVITY_SPANS * h,
        "{resolution}³: a corner is concave by {:.4} spans (a pinch)",
        f.corner_concavity / h
    );
}

/// Measures the sphere at `resolution`, prints the figures and checks them.
fn check_sphere(resolution: usize) {
    let field = clay(ClayShape::Sphere, resolution);
    let (v, _) = exported(&field, "sphere.obj");
    let h = CLAY_SPACING;
    let extent = (resolution - 1) as f32 * h;
    let centre = Vec3::splat(0.5 * extent);
    let radius = 0.25 * extent;
    let (lo, hi) = min_max(v.iter().map(|&p| (p - centre).length() - radius));
    println!(
        "sphere {resolution}³ (radius {radius:.3}): radius deviation {:.4}..{:.4}% of the \
         diameter ({:.4}..{:.4} spans)",
        50.0 * lo / radius,
        50.0 * hi / radius,
        lo / h,
        hi / h
    );
    assert!(
        lo.abs().max(hi.abs()) <= SPHERE_SPANS * h,
        "{resolution}³: sphere vertices {lo}..{hi} off the radius"
    );
}

#[test]
fn blocks_have_flat_faces_no_ridges_and_even_convex_corners() {
    for n in [8, 9, 10, 11, 12, 16, 24, 32, 48] {
        check_block(n);
    }
}

#[test]
fn the_largest_block_has_flat_faces_no_ridges_and_even_convex_corners() {
    check_block(96);
}

#[test]
fn spheres_keep_their_radius() {
    for n in [8, 12, 16, 24, 32, 48, 96] {
        check_sphere(n);
    }
}
