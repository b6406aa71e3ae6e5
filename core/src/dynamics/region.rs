//! The simulated local region R (Hua & Qin §7.3): the coefficients of a box, the mass-point
//! grid over them, and the dynamic state and material fields on that grid.
//!
//! Only the coefficients of the box move; every other coefficient of the lattice is fixed and
//! contributes a constant `d_fixed` to the densities of R's mass points, so
//! `d = A' p_R + d_fixed`. Mass points just outside R are fixed too: a boundary mass point's
//! spring to an outside neighbour pulls it toward its own rest density, which anchors R.

use crate::field::{BSplineLattice, CoeffBox, KronError, KronScratch, KroneckerBasis, MassGrid};

use super::material::{Material, Neighbourhood};
use super::springs::offsets;

/// Why a region could not be set up.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RegionError {
    /// The coefficient box is empty or not inside the lattice.
    #[error("region {:?}..={:?} is empty or outside the lattice {dims:?}", .coeffs.min, .coeffs.max)]
    BadBox {
        /// The box asked for.
        coeffs: CoeffBox,
        /// The lattice's dimensions.
        dims: [usize; 3],
    },
    /// Fewer mass points than coefficients along an axis (the system would be singular).
    #[error(
        "region needs at least as many mass points as coefficients per axis: {mass_dims:?} < {coeff_dims:?}"
    )]
    TooFewMassPoints {
        /// Mass points asked for per axis.
        mass_dims: [usize; 3],
        /// Coefficients per axis.
        coeff_dims: [usize; 3],
    },
    /// The operator could not be factored.
    #[error("region basis: {0}")]
    Basis(KronError),
}

/// The state of the simulated region: coefficients and their velocity, densities, rest
/// densities, and the per-mass-point material fields (editable; `mass`, `damping`,
/// `stiffness` and `plasticity_per_s` are indexed like the densities, x fastest).
#[derive(Clone, Debug)]
pub struct RegionState {
    /// The mass grid (and the coefficient box it spans).
    pub grid: MassGrid,
    /// `A'` on the grid with its Kronecker Gram factors.
    pub basis: KroneckerBasis,
    /// Coefficients of the box (`p_R`), x fastest.
    pub p: Vec<f32>,
    /// Coefficient velocities `ṗ_R`.
    pub p_dot: Vec<f32>,
    /// Densities `d = A' p_R + d_fixed` at the mass points.
    pub d: Vec<f32>,
    /// Density velocities `ḋ = A' ṗ_R`.
    pub d_dot: Vec<f32>,
    /// Contribution of the fixed coefficients outside the box.
    pub d_fixed: Vec<f32>,
    /// Rest densities (drift with plasticity).
    pub rest: Vec<f32>,
    /// Mass per mass point.
    pub mass: Vec<f32>,
    /// Damping per mass point.
    pub damping: Vec<f32>,
    /// Spring stiffness per mass point (a spring uses the mean of its two ends).
    pub stiffness: Vec<f32>,
    /// Which neighbours the density springs join (from the material the region was made
    /// with).
    pub neighbourhood: Neighbourhood,
    /// Plastic drift rate per mass point, per second.
    pub plasticity_per_s: Vec<f32>,
    /// Yield threshold of the plastic drift.
    pub yield_density: f32,
    /// Current adaptive time step, seconds (0 until the first step).
    pub dt_s: f32,
    /// Simulated time, seconds.
    pub time_s: f64,
    /// Published version (incremented by every successful step).
    pub version: u64,
    /// Calm steps in a row (for the step to grow back).
    pub calm_steps: u32,
    /// Steps since the densities were last recomputed from the coefficients.
    pub steps_since_resync: u32,
    /// How firmly the freeze mask holds each coefficient of the box, `0..=1`, indexed like
    /// `p` (empty: nothing held). A held coefficient takes `1 − m` of its acceleration and a
    /// fully held one does not move at all ([`crate::tools::region_holds`] fills it).
    pub held: Vec<f32>,
    /// Mass points between two coarse points of the region's coarse springs (1, the
    /// default: none). See [`RegionState::set_coarse_springs`].
    pub coarse_stride: usize,
    /// The base's knot spacing over the region's patch's (1 on the base).
    pub spacing_ratio: usize,
    /// How many of the region's own knot spans the step's halving threshold
    /// ([`super::StepParams::max_velocity_change`]) is reckoned in (1 on the base, the spacing
    /// ratio where the threshold is the base's; see [`RegionState::set_base_step_threshold`]).
    pub threshold_ratio: usize,
    /// How many times its patch's travel per step a force may move the clay while it is far
    /// from its end (1: the patch's travel; see [`RegionState::set_planned_travel_ratio`]).
    pub planned_travel_ratio: usize,
    /// Mass per point of the material the region was made with, before any painted mass
    /// (`mass` holds the painted values): the mass a force tool's per-step travel cap is
    /// sized for where the clay is painted heavier, so heavy clay lags as its mass asks
    /// (see [`super::Simulator::gather_forces`]).
    pub material_mass: f32,
}

impl RegionState {
    /// Set up the region over the coefficients `coeffs` of `lattice` with `mass_dims` mass
    /// points per axis (spanning the box's coefficient nodes), at rest in the lattice's
    /// current shape.
    ///
    /// # Errors
    /// When the box is not inside the lattice or has more coefficients than mass points on
    /// an axis.
    pub fn new(
        lattice: &BSplineLattice,
        coeffs: CoeffBox,
        mass_dims: [usize; 3],
        material: Material,
    ) -> Result<Self, RegionError> {
        if !coeffs.fits(lattice.dims) {
            return Err(RegionError::BadBox {
                coeffs,
                dims: lattice.dims,
            });
        }
        let n = coeffs.dims();
        if (0..3).any(|a| mass_dims[a] < n[a]) {
            return Err(RegionError::TooFewMassPoints {
                mass_dims,
                coeff_dims: n,
            });
        }
        let grid = MassGrid {
            coeffs,
            dims: mass_dims,
        };
        let basis = grid.basis().map_err(RegionError::Basis)?;
        let count = grid.count();
        let mut state = Self {
            grid,
            basis,
            p: vec![0.0; coeffs.count()],
            p_dot: vec![0.0; coeffs.count()],
            d: vec![0.0; count],
            d_dot: vec![0.0; count],
            d_fixed: vec![0.0; count],
            rest: vec![0.0; count],
            mass: vec![material.mass; count],
            damping: vec![material.damping; count],
            stiffness: vec![material.stiffness; count],
            neighbourhood: material.neighbourhood,
            plasticity_per_s: vec![material.plasticity_per_s; count],
            yield_density: material.yield_density,
            dt_s: 0.0,
            time_s: 0.0,
            version: 0,
            calm_steps: 0,
            steps_since_resync: 0,
            held: Vec::new(),
            coarse_stride: 1,
            spacing_ratio: 1,
            threshold_ratio: 1,
            planned_travel_ratio: 1,
            material_mass: material.mass,
        };
        state.reload(lattice);
        Ok(state)
    }

    /// Take the lattice's current coefficients as the new shape at rest (after a geometric
    /// edit, an undo or a load): `p_R` and `d_fixed` re-read, velocities zeroed, rest densities
    /// set to the current ones. Material fields are kept. Allocates nothing.
    ///
    /// # Panics
    /// When `lattice` is not the lattice the region was made on (dimensions differ).
    pub fn reload(&mut self, lattice: &BSplineLattice) {
        let b = self.grid.coeffs;
        assert!(b.fits(lattice.dims), "region outside the lattice");
        let n = b.dims();
        for k in 0..n[2] {
            for j in 0..n[1] {
                let row = lattice.index(b.min[0], b.min[1] + j, b.min[2] + k);
                let dst = n[0] * (j + n[1] * k);
                lattice.coeffs.read_row(row, &mut self.p[dst..dst + n[0]]);
            }
        }
        self.p_dot.fill(0.0);
        self.d_fixed_from(lattice);
        self.resync_densities_with(&mut KronScratch::for_basis(&self.basis));
        self.d_dot.fill(0.0);
        self.rest.copy_from_slice(&self.d);
        self.calm_steps = 0;
    }

    /// Takes over the elastic memory of `old`, a region on the same lattice that this one
    /// replaces (a stroke that moved past it), at its perfectly elastic mass points: at
    /// every point the two share whose drift rate (`plasticity_per_s`, set before this call)
    /// is zero, the rest density becomes the current one minus `old`'s deviation from rest
    /// there, so an elastic dent made in `old` still springs back. An elastic point's rest
    /// never drifts, so the one it had is the only rest it can have; a plastic point's rest
    /// follows the clay anyway, and it takes the clay as it is (as a new region does
    /// everywhere). Points `old` did not hold keep the current shape as rest. Nothing is
    /// carried when the grids' mass points do not coincide (another count per knot span).
    /// Returns the number of points carried. Allocates nothing.
    pub fn carry_rest_from(&mut self, old: &RegionState) -> usize {
        let (new_box, old_box) = (self.grid.coeffs, old.grid.coeffs);
        // Index of a new mass point in the old grid, per axis.
        let mut shift = [0_i64; 3];
        for (a, shift) in shift.iter_mut().enumerate() {
            let (s_new, s_old) = (self.grid.step(a), old.grid.step(a));
            if s_new <= 0.0 || (s_new - s_old).abs() > 1e-9 {
                return 0;
            }
            let per_span = (1.0 / s_new).round();
            if (per_span * s_new - 1.0).abs() > 1e-9 {
                return 0;
            }
            *shift = (new_box.min[a] as i64 - old_box.min[a] as i64) * per_span as i64;
        }
        let (m, mo) = (self.grid.dims, old.grid.dims);
        let mut carried = 0;
        for k in 0..m[2] {
            let ko = k as i64 + shift[2];
            if ko < 0 || ko >= mo[2] as i64 {
                continue;
            }
            for j in 0..m[1] {
                let jo = j as i64 + shift[1];
                if jo < 0 || jo >= mo[1] as i64 {
                    continue;
                }
                for i in 0..m[0] {
                    let io = i as i64 + shift[0];
                    if io < 0 || io >= mo[0] as i64 {
                        continue;
                    }
                    let n = self.point_index(i, j, k);
                    if self.plasticity_per_s[n] != 0.0 {
                        continue;
                    }
                    let no = old.point_index(io as usize, jo as usize, ko as usize);
                    self.rest[n] = self.d[n] - (old.d[no] - old.rest[no]);
                    carried += 1;
                }
            }
        }
        carried
    }

    /// Makes the region's material two-level (see `dynamics::coarse`): on a detail patch
    /// whose knot spacing is `1/ratio` of the base's, springs between every `stride`-th mass
    /// point, on the deviation from rest averaged around them, restore a shape several
    /// coarse spacings large as strongly as the base does, while a shape finer than a coarse
    /// spacing meets (almost) only the patch's own volume-scaled springs. A force tool's
    /// travel per step ([`super::StepParams::max_coast_step_spans`]) and the step's halving
    /// threshold ([`super::StepParams::max_velocity_change`]) are then reckoned in the base's
    /// knot spans (`ratio` of the patch's), as the material resists a dent as the base does.
    /// `ratio` 1 (or 0): none, as on the base; `stride` 1: the base's travel and threshold
    /// without coarse springs.
    pub fn set_coarse_springs(&mut self, ratio: usize, stride: usize) {
        self.spacing_ratio = ratio.max(1);
        self.threshold_ratio = ratio.max(1);
        self.coarse_stride = stride.max(1);
    }

    /// Reckons the step's halving threshold ([`super::StepParams::max_velocity_change`]) in
    /// the base's knot spans on a detail patch whose knot spacing is `1/ratio` of the base's,
    /// so the region's step halves for the same motion in the world as a base region's; a
    /// force tool's travel per step stays in the patch's own spans. `ratio` 1 (or 0): the
    /// patch's own spans, as on the base.
    pub fn set_base_step_threshold(&mut self, ratio: usize) {
        self.threshold_ratio = ratio.max(1);
    }

    /// Lets a force on a detail patch whose knot spacing is `1/ratio` of the base's move the
    /// clay up to the base's travel per step while it is far from its end: never further in a
    /// step than what is left of its vector, and never less than the patch's own travel
    /// ([`super::StepParams::max_coast_step_spans`] of its spans). For the tools whose
    /// targets are planned along a stroke (the chisel, the squirt), which must reach them in
    /// the time a base region takes. `ratio` 1 (or 0): the patch's own travel.
    pub fn set_planned_travel_ratio(&mut self, ratio: usize) {
        self.planned_travel_ratio = ratio.max(1);
    }

    fn d_fixed_from(&mut self, lattice: &BSplineLattice) {
        self.grid.fixed_outside(lattice, &mut self.d_fixed);
    }

    /// `d = A' p_R + d_fixed` recomputed exactly.
    ///
    /// # Panics
    /// When `scratch` was not made for this region's basis (too small).
    pub(crate) fn resync_densities_with(&mut self, scratch: &mut KronScratch) {
        self.basis.apply(&self.p, &mut self.d, scratch);
        for (d, f) in self.d.iter_mut().zip(&self.d_fixed) {
            *d += f;
        }
        self.steps_since_resync = 0;
    }

    /// The coefficient box of the region.
    #[must_use]
    pub fn coeff_box(&self) -> CoeffBox {
        self.grid.coeffs
    }

    /// Index of mass point `(i, j, k)` in the per-point vectors.
    #[must_use]
    pub fn point_index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.grid.dims[0] * (j + self.grid.dims[1] * k)
    }

    /// Whether every mass point has the same mass.
    #[must_use]
    pub fn mass_is_uniform(&self) -> bool {
        let first = self.mass.first().copied().unwrap_or(0.0);
        // Lane-wise so it vectorises: it runs every step.
        let chunks = self.mass.chunks_exact(8);
        let tail = chunks.remainder();
        for c in chunks {
            let mut same = true;
            for &m in c {
                same &= m == first;
            }
            if !same {
                return false;
            }
        }
        tail.iter().all(|&m| m == first)
    }

    /// Elastic energy `½ Σ w k (Δe)²` over the springs of the region's neighbourhood (anchors
    /// included) plus kinetic energy `½ Σ μ ḋ²`, where `e = d − rest`. For tests and
    /// diagnostics.
    #[must_use]
    pub fn energy(&self) -> f64 {
        let m = self.grid.dims;
        let mut elastic = 0.0;
        for k in 0..m[2] {
            for j in 0..m[1] {
                for i in 0..m[0] {
                    let n = self.point_index(i, j, k);
                    let kk = f64::from(self.stiffness[n]);
                    let here = f64::from(self.d[n] - self.rest[n]);
                    for (o, w) in offsets(self.neighbourhood) {
                        let w = f64::from(w);
                        let q = [i as i64 + o[0], j as i64 + o[1], k as i64 + o[2]];
                        if (0..3).all(|a| q[a] >= 0 && q[a] < m[a] as i64) {
                            // Each spring is seen from both ends: half its energy each time.
                            let nq = self.point_index(q[0] as usize, q[1] as usize, q[2] as usize);
                            let kn = f64::from(self.stiffness[nq]);
                            let diff = f64::from(self.d[nq] - self.rest[nq]) - here;
                            elastic += 0.125 * w * (kk + kn) * diff * diff;
                        } else {
                            elastic += 0.5 * w * kk * here * here;
                        }
                    }
                }
            }
        }
        let kinetic: f64 = self
            .mass
            .iter()
            .zip(&self.d_dot)
            .map(|(&mu, &v)| 0.5 * f64::from(mu) * f64::from(v) * f64::from(v))
            .sum();
        elastic + kinetic
    }
}

/// Scratch length for `apply_axes` on a region basis.
pub(crate) fn scratch_len(basis: &KroneckerBasis) -> usize {
    let [nx, ny, nz] = basis.cols();
    let [mx, my, mz] = basis.rows();
    nx.max(mx) * ny.max(my) * nz.max(mz)
}
