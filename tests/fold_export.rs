//! A fold judged on what a run exports: a fine ball (radius 0.02, a fifth of a knot span of the
//! default clay) carves a groove on the block's top and refines under itself (a level-3 patch);
//! a broad smoothing wipes it and, at the smoothing's commit, the patch folds back into the
//! base. The exported `sculpt.obj` is then compared with the export of the same smoothing on a
//! clay never carved: both ways, every vertex over the smoothed place lies within the fold's
//! tolerance (a quarter of the detail patch's knot span, [`COARSEN_TOLERANCE_SPANS`]) plus the
//! meshing error of the export, which this test measures on the never-carved export itself
//! (how far its vertices lie from its own field's surface, both meshes' share of it). The
//! carved run without the smoothing shows what was there to wipe: a groove on its export,
//! and two patches in its saved session.

use std::path::Path;
use std::process::Command;

use dynaclay::field::{COARSEN_TOLERANCE_SPANS, MultiPatchField};
use dynaclay::io::load_session;
use glam::Vec3;

#[path = "support/exported_mesh.rs"]
#[allow(dead_code)] // shared: this test reads a run's files and measures distances
mod exported_mesh;

use exported_mesh::{Exported, read_obj};

const BIN: &str = env!("CARGO_BIN_EXE_dynaclay");

/// The default block: a 24³ lattice of knot spacing 0.1; its top face is at y = 1.725, its
/// middle at x = z = 1.15.
const SPACING: f32 = 0.1;
const TOP_Y: f32 = 1.725;
const MID: f32 = 1.15;
/// The fine ball's radius: its width (0.04) needs three halvings of the base's spacing.
const FINE_RADIUS: f32 = 0.02;
const DETAIL_LEVEL: u32 = 3;

/// The carve: the fine ball along x over the top's middle, 0.1 long.
fn carve_step() -> String {
    let positions: Vec<String> = (0..=20)
        .map(|n| format!("[{}, {TOP_Y}, {MID}]", MID - 0.05 + 0.005 * n as f32))
        .collect();
    format!(
        "[[step]]\ndo = \"tool\"\nshape = {{ kind = \"sphere\", radius_fu = {FINE_RADIUS} }}\n\
         action = {{ kind = \"remove\" }}\npositions = [{}]\nduration_s = 1.0\nfalloff_fu = {}\n",
        positions.join(", "),
        0.25 * FINE_RADIUS
    )
}

/// The smoothing: a ball of radius 0.25 with a kernel of 1.5 base spans, along the groove,
/// for 3 s.
fn smooth_step() -> String {
    let positions: Vec<String> = (0..=10)
        .map(|n| format!("[{}, {TOP_Y}, {MID}]", MID - 0.05 + 0.01 * n as f32))
        .collect();
    format!(
        "[[step]]\ndo = \"tool\"\nshape = {{ kind = \"sphere\", radius_fu = 0.25 }}\n\
         action = {{ kind = \"smooth\", rate_per_s = 20.0, kernel_fu = 0.15 }}\n\
         positions = [{}]\nduration_s = 3.0\nfalloff_fu = 0.05\n",
        positions.join(", ")
    )
}

/// Runs a script of `steps` in lockstep into `dir/name`; returns the exported mesh read back
/// and the clay of the saved session.
fn run(dir: &Path, name: &str, steps: &[String]) -> (Exported, MultiPatchField) {
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, format!("version = 1\n{}", steps.concat())).unwrap();
    let out = dir.join(name);
    let run = Command::new(BIN)
        .args(["run", "--lockstep", "--no-rt", "--script"])
        .arg(&path)
        .arg("--out")
        .arg(&out)
        .output()
        .expect("binary runs");
    assert!(
        run.status.success(),
        "{name}: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let session = load_session(&out.join("session.dclay")).expect("the run saved its session");
    (read_obj(&out.join("sculpt.obj")), session.clay.density)
}

/// The distance from `p` to the triangle `a b c`.
fn point_triangle_distance(p: Vec3, [a, b, c]: [Vec3; 3]) -> f32 {
    let n = (b - a).cross(c - a);
    let area2 = n.length_squared();
    if area2 > 1e-20 {
        // The projection onto the plane, if it falls inside (barycentric signs).
        let q = p - n * ((p - a).dot(n) / area2);
        let inside = [(a, b), (b, c), (c, a)]
            .iter()
            .all(|&(u, v)| (v - u).cross(q - u).dot(n) >= 0.0);
        if inside {
            return (p - q).length();
        }
    }
    // Else the nearest point is on an edge.
    [(a, b), (b, c), (c, a)]
        .iter()
        .map(|&(u, v)| {
            let e = v - u;
            let t = if e.length_squared() > 0.0 {
                ((p - u).dot(e) / e.length_squared()).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (p - (u + e * t)).length()
        })
        .fold(f32::INFINITY, f32::min)
}

/// The largest distance from a vertex of `from` inside the box `lo..hi` to the surface of
/// `to` (a one-sided Hausdorff distance over that box); `to`'s triangles within `reach` of
/// the box are searched.
fn one_sided_hausdorff(from: &Exported, to: &Exported, lo: Vec3, hi: Vec3, reach: f32) -> f32 {
    let (slo, shi) = (lo - Vec3::splat(reach), hi + Vec3::splat(reach));
    let near: Vec<[Vec3; 3]> = to
        .triangles
        .iter()
        .map(|t| t.map(|i| to.vertices[i]))
        .filter(|t| t.iter().any(|v| v.cmpge(slo).all() && v.cmple(shi).all()))
        .collect();
    assert!(!near.is_empty(), "the other mesh has triangles there");
    let vertices: Vec<Vec3> = from
        .vertices
        .iter()
        .copied()
        .filter(|v| v.cmpge(lo).all() && v.cmple(hi).all())
        .collect();
    assert!(vertices.len() > 100, "the mesh has vertices there");
    vertices
        .iter()
        .map(|&p| {
            near.iter()
                .map(|&t| point_triangle_distance(p, t))
                .fold(f32::INFINITY, f32::min)
        })
        .fold(0.0, f32::max)
}

/// The largest distance of `mesh`'s vertices inside `lo..hi` from `field`'s surface, to first
/// order (`|F − iso| / |∇F|`): the exporter's meshing error there.
fn meshing_error(mesh: &Exported, field: &MultiPatchField, lo: Vec3, hi: Vec3) -> f32 {
    let iso = field.iso();
    mesh.vertices
        .iter()
        .filter(|v| v.cmpge(lo).all() && v.cmple(hi).all())
        .map(|&v| {
            let (value, gradient) = field.value_and_gradient(v);
            (value - iso).abs() / gradient.length().max(1e-6)
        })
        .fold(0.0, f32::max)
}

#[test]
fn a_wiped_groove_folds_back_and_exports_as_the_smoothed_clay_never_carved() {
    let dir = tempfile::tempdir().unwrap();
    let (carved, carved_clay) = run(dir.path(), "carved", &[carve_step()]);
    let (folded, folded_clay) = run(dir.path(), "folded", &[carve_step(), smooth_step()]);
    let (reference, reference_clay) = run(dir.path(), "reference", &[smooth_step()]);

    // What there was to wipe: the groove on the carved export, on its detail patch.
    assert_eq!(
        carved_clay.patches.len(),
        2,
        "the fine ball refined under itself"
    );
    let detail_spacing = carved_clay.patches[1].lattice.spacing;
    assert!(
        (detail_spacing - SPACING / (1 << DETAIL_LEVEL) as f32).abs() < 1e-6,
        "a level-{DETAIL_LEVEL} patch: spacing {detail_spacing}"
    );
    // The height of the surface at the top's middle, found from above along y.
    let above = Vec3::new(MID, TOP_Y + 0.1, MID);
    let top_of = |mesh: &Exported| {
        let t = mesh
            .crossings(above, -Vec3::Y)
            .into_iter()
            .filter(|&t| t > 0.0)
            .fold(f32::INFINITY, f32::min);
        above.y - t
    };
    let (groove_depth, reference_top) = (TOP_Y - top_of(&carved), top_of(&reference) - TOP_Y);
    // The two runs that were smoothed: the fold left the carved one on the base alone.
    assert_eq!(folded_clay.patches.len(), 1, "the wiped patch folded back");
    assert_eq!(reference_clay.patches.len(), 1);

    // Over the smoothed place (the ball's reach around the stroke, from above the top to
    // below the groove's bottom).
    let (lo, hi) = (
        Vec3::new(MID - 0.35, TOP_Y - 0.15, MID - 0.3),
        Vec3::new(MID + 0.35, TOP_Y + 0.1, MID + 0.3),
    );
    let reach = 0.05;
    let folded_to_reference = one_sided_hausdorff(&folded, &reference, lo, hi, reach);
    let reference_to_folded = one_sided_hausdorff(&reference, &folded, lo, hi, reach);
    let fold_tolerance = COARSEN_TOLERANCE_SPANS * detail_spacing;
    // Each mesh lies within its meshing error of its own field's surface: the two meshes
    // together add at most twice the larger.
    let reference_mesh_error = meshing_error(&reference, &reference_clay, lo, hi);
    let folded_mesh_error = meshing_error(&folded, &folded_clay, lo, hi);
    let mesh_error = reference_mesh_error.max(folded_mesh_error);
    let tolerance = fold_tolerance + 2.0 * mesh_error;
    eprintln!(
        "carved: groove {:.4} deep at the middle ({} triangles); folded against never carved \
         over the smoothed place: {folded_to_reference:.5} one way, {reference_to_folded:.5} \
         the other; tolerance {tolerance:.5} (fold {fold_tolerance:.5} + 2 × meshing \
         {mesh_error:.5}); smoothed top {reference_top:+.4} from the block's",
        groove_depth,
        carved.triangles.len()
    );
    assert!(
        groove_depth > 0.5 * FINE_RADIUS,
        "the carved export shows the groove: {groove_depth} deep"
    );
    assert!(
        folded_to_reference <= tolerance && reference_to_folded <= tolerance,
        "the folded clay's export is {folded_to_reference} / {reference_to_folded} from the \
         never-carved clay's, over {tolerance}"
    );
}
