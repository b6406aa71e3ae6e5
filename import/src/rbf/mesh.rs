//! The RBF as a field the mesher can extract, and the distance between its zero set and the
//! clay's surface measured on meshes (the symmetric Hausdorff distance of the issue's
//! accuracy bar).

use glam::{DVec3, Vec3};

use super::fit::Rbf;
use dynaclay_core::field::{BSplineLattice, ImplicitField};
use dynaclay_core::mesh::{
    BrickOctree, GridError, Hausdorff, SampleGrid, ScalarField, TriMesh, hausdorff,
};

impl Rbf {
    /// An upper bound on `|∇I|` over the ball of radius `rho` around `m`:
    /// `|∇|x − c|³| = 3 |x − c|² ≤ 3 (|m − c| + ρ)²`.
    #[must_use]
    pub fn gradient_bound(&self, m: DVec3, rho: f64) -> f64 {
        let linear = DVec3::new(self.poly[1], self.poly[2], self.poly[3]).length();
        self.centres
            .iter()
            .zip(&self.weights)
            .map(|(c, w)| {
                let r = (m - *c).length() + rho;
                3.0 * w.abs() * r * r
            })
            .sum::<f64>()
            + linear
    }
}

/// The zero set of `I` (solid where `I > 0`, like the clay above its iso-level).
impl ImplicitField for Rbf {
    fn iso(&self) -> f32 {
        0.0
    }

    fn value(&self, p: Vec3) -> f32 {
        Rbf::value(self, p.as_dvec3()) as f32
    }

    fn value_and_gradient(&self, p: Vec3) -> (f32, Vec3) {
        let x = p.as_dvec3();
        (Rbf::value(self, x) as f32, Rbf::gradient(self, x).as_vec3())
    }
}

impl ScalarField for Rbf {
    /// `I(m) ± ρ · max |∇I|` over the box's circumscribed ball, widened by a relative 10⁻⁵
    /// for the rounding of the samples to `f32`.
    fn bounds(&self, min: Vec3, max: Vec3) -> Option<(f32, f32)> {
        let (lo, hi) = (min.as_dvec3(), max.as_dvec3());
        let m = 0.5 * (lo + hi);
        let rho = 0.5 * (hi - lo).length();
        let v = Rbf::value(self, m);
        let reach = rho * self.gradient_bound(m, rho);
        let slack = 1e-5 * (v.abs() + reach) + 1e-9;
        let (a, b) = (v - reach - slack, v + reach + slack);
        (a.is_finite() && b.is_finite()).then_some((a as f32, b as f32))
    }
}

/// The meshes of the clay's surface and of the RBF's zero set, extracted by the same mesher on
/// the same grid (`cells_per_span` cells per knot span of the clay, over its whole support).
///
/// # Errors
/// [`GridError`] when the grid cannot be made.
pub fn clay_and_rbf_meshes(
    clay: &BSplineLattice,
    rbf: &Rbf,
    cells_per_span: u32,
) -> Result<(TriMesh, TriMesh), GridError> {
    let grid = SampleGrid::for_lattice(clay, cells_per_span)?;
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get().min(4));
    let clay_mesh = BrickOctree::build_with_threads(grid, clay, threads).weld();
    let rbf_mesh = BrickOctree::build_with_threads(grid, rbf, threads).weld();
    Ok((clay_mesh, rbf_mesh))
}

/// The Hausdorff distance, both ways, between the clay's surface and the RBF's zero set, on
/// meshes from [`clay_and_rbf_meshes`] (`a` is the clay, `b` the RBF). `None` when either
/// mesh is empty.
///
/// # Errors
/// [`GridError`] when the grid cannot be made.
pub fn clay_rbf_distance(
    clay: &BSplineLattice,
    rbf: &Rbf,
    cells_per_span: u32,
) -> Result<Option<Hausdorff>, GridError> {
    let (a, b) = clay_and_rbf_meshes(clay, rbf, cells_per_span)?;
    Ok(hausdorff(&a, &b))
}
