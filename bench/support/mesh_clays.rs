//! The clays the mesh benches and the multi-level re-mesh's profiling harness share: a
//! sphere lattice, and a sphere with three nested detail levels and a stroke on the finest.
//! Shared by `#[path]` (this folder is not a bench target of its own).
// Each bench target uses the builders it needs.
#![allow(dead_code)]

use dynaclay::field::{BSplineLattice, MultiPatchField};
use glam::Vec3;

/// A sphere of `radius_spans` knot spans as a B-spline lattice (ramp of the signed
/// distance, 6 spans wide), sized so that the support spans `n + 3` spans.
pub fn sphere_lattice(n: usize, radius_spans: f32) -> BSplineLattice {
    let spacing = 1.0;
    let mut lattice = BSplineLattice::zeros([n; 3], spacing, Vec3::ZERO).unwrap();
    let centre = Vec3::splat((n - 1) as f32 / 2.0);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let d = radius_spans - (lattice.node_position(i, j, k) - centre).length();
                let idx = lattice.index(i, j, k);
                lattice
                    .coeffs
                    .set_flat(idx, (0.5 + d / 6.0).clamp(0.0, 1.0));
            }
        }
    }
    lattice
}

/// A clay of three levels: the sphere of [`sphere_lattice`] (24³, radius 8 spans) with nested
/// detail patches of levels 1, 2 and 3 around its +x pole, each holding a bump as wide as
/// two of its own knot spans (so the multi-level mesher meshes each at its own spacing
/// there); and the finest patch's coefficients on the surface at the pole, dented by a stroke
/// as fine as that patch. Returns the clay before and after the stroke, and the world box
/// outside which the stroke changed nothing.
pub fn three_level_clay() -> (MultiPatchField, MultiPatchField, (Vec3, Vec3)) {
    let base = sphere_lattice(24, 8.0);
    let centre = Vec3::splat(11.5);
    let pole = centre + Vec3::X * 8.0;
    let mut field = MultiPatchField::new(base);
    let mut finest = 0;
    for level in 1..=3_u32 {
        let spacing = 1.0 / (1 << level) as f32;
        // Each patch 6 base spans across at level 1, halving per level.
        let half = Vec3::splat(3.0 / (1 << (level - 1)) as f32);
        finest = field.refine(pole - half, pole + half, level).unwrap();
        let lattice = &mut field.patches[finest].lattice;
        let [nx, ny, nz] = lattice.dims;
        let width = 2.0 * spacing;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let x = lattice.node_position(i, j, k);
                    let bump = 0.01 * (-(x - pole).length_squared() / (width * width)).exp();
                    let idx = lattice.index(i, j, k);
                    lattice.coeffs.set_flat(idx, bump);
                }
            }
        }
    }
    let before = field.clone();
    let mut after = field;
    let patch = &mut after.patches[finest];
    let node = ((pole - patch.lattice.origin) / patch.lattice.spacing).round();
    let first = [node.x as usize, node.y as usize, node.z as usize];
    // The bumps move the surface out by about a fifth of a base span at the pole: three
    // nodes along +x from the pole hold it.
    for step in 0..3 {
        let idx = patch.lattice.index(first[0] + step, first[1], first[2]);
        patch.lattice.coeffs.add_flat(idx, -0.05);
    }
    let change = patch.coefficient_change_box(first, [first[0] + 2, first[1], first[2]]);
    (before, after, change)
}
