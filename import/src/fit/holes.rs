//! Capping the holes of an open mesh, so a scan that is closed but for a few gaps (the Stanford
//! bunny's base, where the scanner could not see) takes the signed-distance path of a closed
//! mesh instead of being fitted as a point cloud.
//!
//! A point cloud's sign comes from a flood of the outside that cannot pass holes narrower than
//! its gap ([`super::cloud::DEFAULT_GAP_SPANS`] knot spans); a wider hole lets the outside in
//! and the fitted surface comes apart (the bunny, fitted as a cloud, came back as three
//! pieces). A mesh says exactly where its holes are: each boundary loop (the edges used by one
//! triangle, chained head to tail) is capped with a fan of triangles from the loop's centroid,
//! wound against the loop's own faces, so the capped mesh is closed and consistently wound.
//! The signed distance's winding number tolerates a fan that folds over a non-convex loop.
//!
//! Only holes no wider than [`MAX_CAPPED_HOLE`] of the mesh's size are capped: a wider opening
//! is the shape's own (a cup's mouth, a sheet's edge), and capping it would invent a face as
//! large as the object.

use std::collections::HashMap;

use glam::Vec3;

use super::watertight::WeldedMesh;

/// The widest hole capped, as a fraction of the mesh's longest side (a hole's width is the
/// longest side of its boundary loop's box).
pub const MAX_CAPPED_HOLE: f32 = 0.5;

/// A mesh whose holes were capped, and what was capped.
#[derive(Clone, Debug, PartialEq)]
pub struct CappedMesh {
    /// The mesh with one centroid vertex and a fan of triangles per hole.
    pub mesh: WeldedMesh,
    /// Holes capped.
    pub holes: usize,
    /// The widest capped hole, fraction of the mesh's longest side.
    pub widest: f32,
}

/// Why an open mesh's holes were not capped.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum UncappedHoles {
    /// The mesh has no boundary edge: nothing to cap.
    #[error("it has no boundary edges")]
    NoHoles,
    /// The boundary edges do not chain into loops (a vertex where boundary edges meet unevenly,
    /// from faces wound against their neighbours or edges shared by three faces).
    #[error("its boundary edges do not form loops")]
    NotLoops,
    /// A hole wider than [`MAX_CAPPED_HOLE`] of the mesh's size: an opening of the shape.
    #[error(
        "a hole spans {:.0}% of its size (holes up to {:.0}% are capped)",
        100.0 * width,
        100.0 * MAX_CAPPED_HOLE
    )]
    TooWide {
        /// The widest hole, fraction of the mesh's longest side.
        width: f32,
    },
}

/// Caps every hole of `mesh` (welded; its faces around each hole wound consistently) with a
/// fan from the hole's centroid.
///
/// # Errors
/// [`UncappedHoles`]: no hole, boundary edges that do not chain into loops, or a hole wider
/// than [`MAX_CAPPED_HOLE`] of the mesh's size.
pub fn cap_holes(mesh: &WeldedMesh) -> Result<CappedMesh, UncappedHoles> {
    let loops = boundary_loops(&mesh.triangles)?;
    if loops.is_empty() {
        return Err(UncappedHoles::NoHoles);
    }
    let size = extent(mesh.positions.iter().copied()).max(f32::MIN_POSITIVE);
    let widest = loops
        .iter()
        .map(|l| extent(l.iter().map(|&v| mesh.positions[v as usize])) / size)
        .fold(0.0f32, f32::max);
    if widest > MAX_CAPPED_HOLE {
        return Err(UncappedHoles::TooWide { width: widest });
    }
    let mut capped = mesh.clone();
    for hole in &loops {
        let centre = hole
            .iter()
            .map(|&v| mesh.positions[v as usize].as_dvec3())
            .sum::<glam::DVec3>()
            / hole.len() as f64;
        let c = capped.positions.len() as u32;
        capped.positions.push(centre.as_vec3());
        // The loop runs the way its faces use the edges; the cap uses each edge backwards.
        for (k, &a) in hole.iter().enumerate() {
            let b = hole[(k + 1) % hole.len()];
            capped.triangles.push([b, a, c]);
        }
    }
    Ok(CappedMesh {
        mesh: capped,
        holes: loops.len(),
        widest,
    })
}

/// The longest side of the points' box.
fn extent(points: impl Iterator<Item = Vec3>) -> f32 {
    let (lo, hi) = points.fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), p| {
        (a.min(p), b.max(p))
    });
    (hi - lo).max_element().max(0.0)
}

/// The boundary edges (used by one triangle), directed as their triangle uses them, chained
/// head to tail into closed loops of vertices.
fn boundary_loops(triangles: &[[u32; 3]]) -> Result<Vec<Vec<u32>>, UncappedHoles> {
    let mut uses: HashMap<(u32, u32), u32> = HashMap::new();
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *uses.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    // Tail → heads of the boundary edges leaving it.
    let mut leaving: HashMap<u32, Vec<u32>> = HashMap::new();
    let mut count = 0usize;
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if uses[&(a.min(b), a.max(b))] == 1 {
                leaving.entry(a).or_default().push(b);
                count += 1;
            }
        }
    }
    // Deterministic order: loops start from the lowest free vertex.
    let mut starts: Vec<u32> = leaving.keys().copied().collect();
    starts.sort_unstable();
    let mut loops = Vec::new();
    let mut walked = 0usize;
    for start in starts {
        while leaving.get(&start).is_some_and(|h| !h.is_empty()) {
            let mut hole = Vec::new();
            let mut at = start;
            loop {
                let next = leaving
                    .get_mut(&at)
                    .and_then(Vec::pop)
                    .ok_or(UncappedHoles::NotLoops)?;
                hole.push(at);
                walked += 1;
                at = next;
                if at == start {
                    break;
                }
            }
            loops.push(hole);
        }
    }
    if walked != count {
        return Err(UncappedHoles::NotLoops);
    }
    Ok(loops)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::watertight::check_closed;

    /// A box of 1 × 1 × `depth` as 12 triangles, wound outward; its first two triangles are
    /// the face at z = 0.
    fn cuboid(depth: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        crate::fit::test_boxes::box_mesh(Vec3::ZERO, Vec3::new(1.0, 1.0, depth))
    }

    #[test]
    fn a_long_box_without_its_end_is_capped_closed_and_wound_as_its_faces() {
        let (positions, mut triangles) = cuboid(4.0);
        triangles.drain(0..2);
        let (open, check) = check_closed(&positions, &triangles);
        assert_eq!(check.boundary_edges, 4);
        let capped = cap_holes(&open).unwrap();
        assert_eq!(capped.holes, 1);
        assert!((capped.widest - 0.25).abs() < 1e-6);
        let (_, check) = check_closed(&capped.mesh.positions, &capped.mesh.triangles);
        assert!(check.is_closed(), "{}", check.describe());
        assert_eq!(
            check.reoriented, 0,
            "the cap is wound as the faces around it"
        );
    }

    #[test]
    fn a_wide_opening_is_left_open_and_a_closed_mesh_has_nothing_to_cap() {
        let (positions, mut triangles) = cuboid(1.0);
        let (closed, _) = check_closed(&positions, &triangles);
        assert_eq!(cap_holes(&closed), Err(UncappedHoles::NoHoles));
        // A cube without two opposite faces: two holes, each as wide as the cube.
        triangles.drain(0..4);
        let (tube, _) = check_closed(&positions, &triangles);
        let e = cap_holes(&tube).unwrap_err();
        assert!(
            matches!(e, UncappedHoles::TooWide { width } if width == 1.0),
            "{e}"
        );
        assert!(e.to_string().contains("100%"), "{e}");
    }

    #[test]
    fn boundary_edges_that_do_not_chain_are_refused() {
        // Two triangles sharing an edge but wound the same way along it: the edge is used twice
        // (not a boundary), and the four boundary edges meet unevenly at two vertices.
        let positions = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::ONE];
        let triangles = vec![[0, 1, 2], [1, 2, 3]];
        let (mesh, _) = check_closed(&positions, &triangles);
        assert_eq!(cap_holes(&mesh), Err(UncappedHoles::NotLoops));
    }
}
