//! The fitted clay meshed for checking, and the mesh's topology, as the import tests check
//! them. Shared by `#[path]` (this folder is not a test target of its own).

use std::collections::HashMap;

use dynaclay::field::MultiPatchField;
use dynaclay::mesh::{BrickOctree, SampleGrid, TriMesh};

/// The zero set of `field`, meshed at a third of its base knot spacing over the base's
/// support, welded.
pub fn mesh_of(field: &MultiPatchField) -> TriMesh {
    let base = &field.patches[0].lattice;
    let (lo, hi) = base.support();
    let grid = SampleGrid::covering(lo, hi, base.spacing / 3.0).unwrap();
    BrickOctree::build(grid, field).weld()
}

/// Whether every edge has two faces, and `V − E + F`.
pub fn topology(mesh: &TriMesh) -> (bool, i64) {
    let mut edges = HashMap::new();
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_insert(0u32) += 1;
        }
    }
    let closed = edges.values().all(|&n| n == 2);
    let euler = mesh.positions.len() as i64 - edges.len() as i64 + mesh.triangles.len() as i64;
    (closed, euler)
}
