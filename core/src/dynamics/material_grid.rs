//! Material painted over the clay: Hua & Qin's spatially varying mass `μ(u, v, w)`, damping
//! `γ(u, v, w)` and stiffness `ρ(u, v, w)` (§4.1), and the plastic drift rate beside them,
//! each held as a grid of values, and the region's mass points given the values of the grids
//! where they sit.
//!
//! A grid of `g` samples along an axis spans the base patch's coefficient nodes along it:
//! sample `s` sits at lattice coordinate `s (n − 1) / (g − 1)` of a base lattice with `n`
//! coefficients (a grid of one sample is constant along that axis). Between samples the value
//! is trilinear; beyond the nodes it is the nearest sample's. A painted grid has one sample
//! per coefficient node. The values are the material's own (not factors): where a grid
//! covers the clay it takes the place of the uniform material's value. Plain data and pure
//! functions; the simulation stage owns the grids and applies them when it makes a region.

use glam::Vec3;

use crate::field::BSplineLattice;

use super::material::Material;
use super::region::RegionState;

/// One spatially varying material parameter, sampled on a grid (x fastest) over the base
/// patch (see the module docs for where its samples sit).
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialGrid {
    /// Which parameter: `stiffness`, `damping`, `mass` or `plasticity` (see
    /// [`MaterialParam`]; a grid of another name is carried but not simulated).
    pub name: String,
    /// Samples per axis.
    pub dims: [usize; 3],
    /// The values, `dims[0] · dims[1] · dims[2]` of them, x fastest.
    pub values: Vec<f32>,
}

/// The material parameters a grid may hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MaterialParam {
    /// Mass per mass point (`μ`); positive.
    Mass,
    /// Damping per mass point (`γ`); zero or more.
    Damping,
    /// Spring stiffness per mass point (`ρ`; a spring takes the mean of its ends); zero or
    /// more.
    Stiffness,
    /// Plastic drift rate of the rest densities, per second; zero or more (zero: the clay
    /// springs back there).
    Plasticity,
}

impl MaterialParam {
    /// The parameters the simulation applies per mass point: all four.
    pub const SIMULATED: [Self; 4] = [Self::Mass, Self::Damping, Self::Stiffness, Self::Plasticity];

    /// The grid name of this parameter.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::Mass => "mass",
            Self::Damping => "damping",
            Self::Stiffness => "stiffness",
            Self::Plasticity => "plasticity",
        }
    }

    /// The parameter a grid called `name` holds, if it is one of the four.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::SIMULATED.into_iter().find(|p| p.name() == name)
    }

    /// Whether a mass point's value of this parameter scales with the volume it holds
    /// (mass, damping and stiffness, as [`Material::for_volume_ratio`]); a drift rate does
    /// not.
    #[must_use]
    pub const fn scales_with_volume(self) -> bool {
        !matches!(self, Self::Plasticity)
    }

    /// The uniform material's value of this parameter.
    #[must_use]
    pub fn uniform(self, m: &Material) -> f32 {
        match self {
            Self::Mass => m.mass,
            Self::Damping => m.damping,
            Self::Stiffness => m.stiffness,
            Self::Plasticity => m.plasticity_per_s,
        }
    }

    /// Whether `v` is a valid value: finite, and positive for mass, zero or more otherwise.
    #[must_use]
    pub fn accepts(self, v: f32) -> bool {
        v.is_finite() && (v > 0.0 || (v == 0.0 && self != Self::Mass))
    }
}

/// Why a grid or a paint was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MaterialGridError {
    /// The values do not fill the grid's dimensions (or a dimension is 0).
    #[error("material grid {name}: {len} values for dims {dims:?}")]
    Size {
        /// The grid's name.
        name: String,
        /// Its dimensions.
        dims: [usize; 3],
        /// How many values it holds.
        len: usize,
    },
    /// A value out of range for its parameter.
    #[error("material grid {name}: value {value} at index {index} must be finite and {need}")]
    Value {
        /// The grid's name.
        name: String,
        /// Where, in the values.
        index: usize,
        /// The value.
        value: f32,
        /// What it must be.
        need: &'static str,
    },
    /// A paint's region is not a region.
    #[error("material paint: {0}")]
    Region(&'static str),
    /// A paint's value out of range.
    #[error("material paint: {name} = {value} must be finite and {need}")]
    PaintValue {
        /// Which parameter.
        name: &'static str,
        /// The value asked for.
        value: f32,
        /// What it must be.
        need: &'static str,
    },
}

/// Most samples one material grid holds (64 MiB of `f32`): a grid is dense over the whole
/// base, so over a base of more coefficient nodes than this (the clay's box may be far larger
/// than its surface, see [`crate::field::MAX_CLAY_BOX_COEFFS`]) it has fewer samples than
/// nodes ([`grid_dims_over`]).
pub const MAX_GRID_SAMPLES: usize = 16 << 20;

/// Samples per axis of a painted grid over a base of `nodes` coefficient nodes per axis: one
/// per node, or, when that would be more than [`MAX_GRID_SAMPLES`], one every `s` nodes along
/// every axis, `s` the least stride that fits.
#[must_use]
pub fn grid_dims_over(nodes: [usize; 3]) -> [usize; 3] {
    let count = |dims: [usize; 3]| dims.iter().fold(1_usize, |a, &n| a.saturating_mul(n));
    let mut stride = 1;
    loop {
        let dims = nodes.map(|n| n.saturating_sub(1) / stride + 1);
        if count(dims) <= MAX_GRID_SAMPLES {
            return dims;
        }
        stride += 1;
    }
}

fn need(p: MaterialParam) -> &'static str {
    if p == MaterialParam::Mass {
        "positive"
    } else {
        "zero or more"
    }
}

impl MaterialGrid {
    /// A grid called `param.name()` of `dims` samples, all `value`.
    #[must_use]
    pub fn filled(param: MaterialParam, dims: [usize; 3], value: f32) -> Self {
        Self {
            name: param.name().into(),
            dims,
            values: vec![value; dims.iter().product()],
        }
    }

    /// This grid over `old_base` carried onto `grown_base`, the same base grown by whole
    /// coefficients (see `Clay::grow`): the grid keeps its sample spacing in knot spans, so a
    /// grid of one sample per coefficient keeps one per coefficient, and every new sample takes
    /// the value the old grid gives at its world position (a sample beyond the old box takes
    /// the nearest edge value: the material there is the material next to it).
    ///
    /// # Panics
    /// When the grid does not hold `dims` values (see [`MaterialGrid::validate`]).
    #[must_use]
    pub fn grown(&self, old_base: &BSplineLattice, grown_base: &BSplineLattice) -> Self {
        let dims: [usize; 3] = std::array::from_fn(|a| {
            let (g, n, m) = (self.dims[a], old_base.dims[a], grown_base.dims[a]);
            if g == n {
                m
            } else if g <= 1 || n <= 1 {
                g
            } else {
                let ratio = (g - 1) as f64 / (n - 1) as f64;
                1 + ((m - 1) as f64 * ratio).round() as usize
            }
        });
        // Past the sample budget the grown grid is coarser (its samples still span the base).
        let dims = if dims.iter().fold(1_usize, |a, &n| a.saturating_mul(n)) > MAX_GRID_SAMPLES {
            grid_dims_over(grown_base.dims)
        } else {
            dims
        };
        let mut grown = Self {
            name: self.name.clone(),
            dims,
            values: Vec::with_capacity(dims.iter().product()),
        };
        for k in 0..dims[2] {
            for j in 0..dims[1] {
                for i in 0..dims[0] {
                    let x = grown.position(grown_base, [i, j, k]);
                    grown.values.push(self.sample(old_base, x));
                }
            }
        }
        grown
    }

    /// The parameter the grid holds, if its name is one of the four.
    #[must_use]
    pub fn param(&self) -> Option<MaterialParam> {
        MaterialParam::from_name(&self.name)
    }

    /// Checks the size and every value: in range for a grid of a known parameter, finite for
    /// one carried under another name.
    ///
    /// # Errors
    /// The first problem: a size that does not match, or a value out of range.
    pub fn validate(&self) -> Result<(), MaterialGridError> {
        let len = self.values.len();
        if self.dims.contains(&0) || len != self.dims.iter().product::<usize>() {
            return Err(MaterialGridError::Size {
                name: self.name.clone(),
                dims: self.dims,
                len,
            });
        }
        // A grid of a known parameter takes that parameter's values; one carried under another
        // name, finite ones.
        let accepts = |v: f32| self.param().map_or(v.is_finite(), |p| p.accepts(v));
        if let Some(index) = self.values.iter().position(|&v| !accepts(v)) {
            return Err(MaterialGridError::Value {
                name: self.name.clone(),
                index,
                value: self.values[index],
                need: self.param().map_or("finite", need),
            });
        }
        Ok(())
    }

    /// Grid coordinate (in samples) of the base lattice coordinate `u` along `axis`, clamped
    /// to the grid.
    fn coord(&self, base: &BSplineLattice, axis: usize, u: f32) -> f32 {
        let g = self.dims[axis];
        let n = base.dims[axis];
        if g <= 1 || n <= 1 {
            return 0.0;
        }
        (u * (g - 1) as f32 / (n - 1) as f32).clamp(0.0, (g - 1) as f32)
    }

    /// The value at world point `x` (trilinear between samples; `a + t (b − a)`, so a grid
    /// of one value gives that value exactly everywhere).
    ///
    /// # Panics
    /// When the grid does not hold `dims` values (see [`MaterialGrid::validate`]).
    #[must_use]
    pub fn sample(&self, base: &BSplineLattice, x: Vec3) -> f32 {
        let u = base.to_lattice(x);
        let mut i0 = [0_usize; 3];
        let mut i1 = [0_usize; 3];
        let mut t = [0.0_f32; 3];
        for a in 0..3 {
            let c = self.coord(base, a, u[a]);
            let f = c.floor();
            i0[a] = f as usize;
            i1[a] = (i0[a] + 1).min(self.dims[a] - 1);
            t[a] = c - f;
        }
        let [gx, gy, _] = self.dims;
        let at = |i: usize, j: usize, k: usize| self.values[i + gx * (j + gy * k)];
        let lerp = |a: f32, b: f32, t: f32| a + t * (b - a);
        let plane = |k: usize| {
            let y0 = lerp(at(i0[0], i0[1], k), at(i1[0], i0[1], k), t[0]);
            let y1 = lerp(at(i0[0], i1[1], k), at(i1[0], i1[1], k), t[0]);
            lerp(y0, y1, t[1])
        };
        lerp(plane(i0[2]), plane(i1[2]), t[2])
    }

    /// World position of sample `(i, j, k)` over `base`.
    fn position(&self, base: &BSplineLattice, s: [usize; 3]) -> Vec3 {
        let mut u = Vec3::ZERO;
        for a in 0..3 {
            let (g, n) = (self.dims[a], base.dims[a]);
            u[a] = if g <= 1 {
                0.0
            } else {
                s[a] as f32 * (n.max(1) - 1) as f32 / (g - 1) as f32
            };
        }
        base.origin + base.spacing * u
    }

    /// Sets every sample inside `region` to `value`; returns how many it set.
    ///
    /// # Panics
    /// When the grid does not hold `dims` values.
    pub fn paint(&mut self, base: &BSplineLattice, region: &PaintRegion, value: f32) -> usize {
        let [gx, gy, gz] = self.dims;
        let mut set = 0;
        for k in 0..gz {
            for j in 0..gy {
                for i in 0..gx {
                    if region.contains(self.position(base, [i, j, k])) {
                        self.values[i + gx * (j + gy * k)] = value;
                        set += 1;
                    }
                }
            }
        }
        set
    }
}

/// Where a material paint lands, field coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PaintRegion {
    /// A ball.
    Sphere {
        /// Its centre.
        centre: Vec3,
        /// Its radius, field units.
        radius_fu: f32,
    },
    /// An axis-aligned box.
    Box {
        /// Lowest corner.
        min: Vec3,
        /// Highest corner.
        max: Vec3,
    },
}

impl PaintRegion {
    /// Whether `x` is inside (boundary included).
    #[must_use]
    pub fn contains(&self, x: Vec3) -> bool {
        match *self {
            Self::Sphere { centre, radius_fu } => {
                x.distance_squared(centre) <= radius_fu * radius_fu
            }
            Self::Box { min, max } => x.cmpge(min).all() && x.cmple(max).all(),
        }
    }

    /// Checks that the region is finite and not empty.
    ///
    /// # Errors
    /// What is wrong with it.
    pub fn validate(&self) -> Result<(), MaterialGridError> {
        match *self {
            Self::Sphere { centre, radius_fu } => {
                if !centre.is_finite() {
                    return Err(MaterialGridError::Region("the centre must be finite"));
                }
                if !(radius_fu.is_finite() && radius_fu > 0.0) {
                    return Err(MaterialGridError::Region(
                        "radius_fu must be finite and positive",
                    ));
                }
            }
            Self::Box { min, max } => {
                if !(min.is_finite() && max.is_finite()) {
                    return Err(MaterialGridError::Region("the corners must be finite"));
                }
                if !min.cmple(max).all() {
                    return Err(MaterialGridError::Region(
                        "min must not exceed max on any axis",
                    ));
                }
            }
        }
        Ok(())
    }
}

/// A paint: the values to set in a region (an absent value is left as it is).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialPaint {
    /// Where.
    pub region: PaintRegion,
    /// Mass per mass point there.
    pub mass: Option<f32>,
    /// Damping there.
    pub damping: Option<f32>,
    /// Stiffness there.
    pub stiffness: Option<f32>,
    /// Plastic drift rate there, per second.
    pub plasticity_per_s: Option<f32>,
}

impl MaterialPaint {
    /// The value this paint sets for `param`, if any.
    #[must_use]
    pub fn value(&self, param: MaterialParam) -> Option<f32> {
        match param {
            MaterialParam::Mass => self.mass,
            MaterialParam::Damping => self.damping,
            MaterialParam::Stiffness => self.stiffness,
            MaterialParam::Plasticity => self.plasticity_per_s,
        }
    }

    /// Checks the region and every value.
    ///
    /// # Errors
    /// The first problem.
    pub fn validate(&self) -> Result<(), MaterialGridError> {
        self.region.validate()?;
        for p in MaterialParam::SIMULATED {
            if let Some(v) = self.value(p)
                && !p.accepts(v)
            {
                return Err(MaterialGridError::PaintValue {
                    name: p.name(),
                    value: v,
                    need: need(p),
                });
            }
        }
        if MaterialParam::SIMULATED
            .iter()
            .all(|&p| self.value(p).is_none())
        {
            return Err(MaterialGridError::Region(
                "nothing to paint: give mass, damping, stiffness or plasticity",
            ));
        }
        Ok(())
    }
}

/// Applies `paint` to `grids` over the base lattice `base`: a parameter it sets that has no
/// grid yet gets one (a sample per coefficient node, filled with `uniform`'s value) first.
/// Returns the samples set.
///
/// # Errors
/// When the paint is not valid ([`MaterialPaint::validate`]) or a grid it would change is
/// not ([`MaterialGrid::validate`]); nothing changes then.
pub fn paint_grids(
    grids: &mut Vec<MaterialGrid>,
    base: &BSplineLattice,
    uniform: &Material,
    paint: &MaterialPaint,
) -> Result<usize, MaterialGridError> {
    paint.validate()?;
    for g in grids.iter() {
        if g.param().is_some_and(|p| paint.value(p).is_some()) {
            g.validate()?;
        }
    }
    let mut set = 0;
    for p in MaterialParam::SIMULATED {
        let Some(v) = paint.value(p) else {
            continue;
        };
        let at = match grids.iter().position(|g| g.param() == Some(p)) {
            Some(at) => at,
            None => {
                let dims = grid_dims_over(base.dims);
                grids.push(MaterialGrid::filled(p, dims, p.uniform(uniform)));
                grids.len() - 1
            }
        };
        set += grids[at].paint(base, &paint.region, v);
    }
    Ok(set)
}

/// Gives the mass points of `state` the values of `grids` where they sit: for each parameter
/// that has a valid grid (the first of its name), every mass point takes the grid's value at
/// its world position, times `volume_ratio` for mass, damping and stiffness (the volume a
/// mass point of the region's patch holds against one of the base's, as
/// [`Material::for_volume_ratio`]; a drift rate is the same at any volume).
/// `lattice` is the patch the region is on (in world coordinates), `base` the base patch the
/// grids span. Parameters without a grid keep their values. Returns whether any grid applied.
pub fn apply_grids(
    grids: &[MaterialGrid],
    base: &BSplineLattice,
    lattice: &BSplineLattice,
    volume_ratio: f32,
    state: &mut RegionState,
) -> bool {
    let mut any = false;
    for p in MaterialParam::SIMULATED {
        let Some(grid) = grids.iter().find(|g| g.param() == Some(p)) else {
            continue;
        };
        if grid.validate().is_err() {
            continue;
        }
        any = true;
        let [mx, my, mz] = state.grid.dims;
        let grid_of_points = state.grid;
        let field = match p {
            MaterialParam::Mass => &mut state.mass,
            MaterialParam::Damping => &mut state.damping,
            MaterialParam::Stiffness => &mut state.stiffness,
            MaterialParam::Plasticity => &mut state.plasticity_per_s,
        };
        let scale = if p.scales_with_volume() {
            volume_ratio
        } else {
            1.0
        };
        for k in 0..mz {
            for j in 0..my {
                for i in 0..mx {
                    let x = grid_of_points.position(lattice, i, j, k);
                    let v = grid.sample(base, x);
                    // Exact for a ratio of 1 (`v · 1 = v`).
                    field[i + mx * (j + my * k)] = v * scale;
                }
            }
        }
    }
    any
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::CoeffBox;

    fn base() -> BSplineLattice {
        BSplineLattice::zeros([11, 9, 7], 0.1, Vec3::new(0.5, 0.0, -0.2)).unwrap()
    }

    #[test]
    fn a_grid_over_a_base_past_the_sample_budget_is_coarser_and_spans_it() {
        assert_eq!(grid_dims_over([96, 80, 64]), [96, 80, 64]);
        let dims = grid_dims_over([1024, 1024, 1024]);
        assert!(
            dims.iter().product::<usize>() <= MAX_GRID_SAMPLES,
            "{dims:?}"
        );
        assert_eq!(dims, [256; 3], "one sample every fourth node");
        let long = grid_dims_over([40_000, 40, 40]);
        assert!(
            long.iter().product::<usize>() <= MAX_GRID_SAMPLES,
            "{long:?}"
        );
    }

    #[test]
    fn a_grid_is_trilinear_between_its_samples_over_the_base_nodes() {
        let base = base();
        // Two samples per axis: the corners of the node box; value = 1 + x + 2y + 4z (in
        // sample units), which trilinear interpolation reproduces exactly.
        let mut g = MaterialGrid::filled(MaterialParam::Stiffness, [2, 2, 2], 0.0);
        for (n, v) in g.values.iter_mut().enumerate() {
            *v = 1.0 + (n & 1) as f32 + 2.0 * ((n >> 1) & 1) as f32 + 4.0 * (n >> 2) as f32;
        }
        let at = |u: [f32; 3]| {
            base.origin + base.spacing * Vec3::new(u[0] * 10.0, u[1] * 8.0, u[2] * 6.0)
        };
        for u in [
            [0.0, 0.0, 0.0],
            [1.0, 1.0, 1.0],
            [0.25, 0.5, 0.75],
            [0.9, 0.1, 0.3],
        ] {
            let want = 1.0 + u[0] + 2.0 * u[1] + 4.0 * u[2];
            assert!((g.sample(&base, at(u)) - want).abs() < 1e-5, "{u:?}");
        }
        // Beyond the nodes: the nearest sample's value.
        assert_eq!(g.sample(&base, at([-1.0, -1.0, -1.0])), 1.0);
        assert_eq!(g.sample(&base, at([2.0, 2.0, 2.0])), 8.0);
        // A uniform grid gives its value exactly.
        let u = MaterialGrid::filled(MaterialParam::Mass, [11, 9, 7], 0.3);
        for x in [at([0.13, 0.77, 0.41]), at([0.5, 0.5, 0.5])] {
            assert_eq!(u.sample(&base, x).to_bits(), 0.3_f32.to_bits());
        }
    }

    #[test]
    fn painting_creates_grids_from_the_uniform_material_and_sets_the_region() {
        let base = base();
        let mut grids = Vec::new();
        let paint = MaterialPaint {
            region: PaintRegion::Box {
                min: Vec3::new(0.0, -1.0, -1.0),
                max: Vec3::new(0.95, 1.0, 1.0),
            },
            mass: None,
            damping: None,
            stiffness: Some(5000.0),
            plasticity_per_s: None,
        };
        let set = paint_grids(&mut grids, &base, &Material::PLASTIC, &paint).unwrap();
        // Nodes at x = 0.5 .. 0.9 (five columns) of 9 × 7.
        assert_eq!(set, 5 * 9 * 7);
        assert_eq!(grids.len(), 1);
        assert_eq!(grids[0].dims, base.dims);
        let g = &grids[0];
        assert_eq!(g.sample(&base, Vec3::new(0.6, 0.4, 0.1)), 5000.0);
        assert_eq!(
            g.sample(&base, Vec3::new(1.2, 0.4, 0.1)),
            Material::PLASTIC.stiffness
        );
        // Bad paints are refused and change nothing.
        for bad in [
            MaterialPaint {
                mass: Some(0.0),
                ..paint
            },
            MaterialPaint {
                stiffness: Some(f32::NAN),
                ..paint
            },
            MaterialPaint {
                stiffness: None,
                ..paint
            },
            MaterialPaint {
                region: PaintRegion::Sphere {
                    centre: Vec3::ZERO,
                    radius_fu: -1.0,
                },
                ..paint
            },
        ] {
            let before = grids.clone();
            assert!(paint_grids(&mut grids, &base, &Material::PLASTIC, &bad).is_err());
            assert_eq!(grids, before);
        }
        let bad_grid = MaterialGrid {
            name: "mass".into(),
            dims: [1, 1, 2],
            values: vec![1.0, -2.0],
        };
        let e = bad_grid.validate().unwrap_err().to_string();
        assert!(
            e.contains("mass") && e.contains("-2") && e.contains("index 1"),
            "{e}"
        );
        // A grid carried under another name still holds finite values, and no grid is empty.
        let carried = MaterialGrid {
            name: "roughness".into(),
            dims: [2, 1, 1],
            values: vec![0.5, f32::NAN],
        };
        assert!(
            carried
                .validate()
                .unwrap_err()
                .to_string()
                .contains("finite")
        );
        let empty = MaterialGrid {
            name: "stiffness".into(),
            dims: [0, 3, 3],
            values: Vec::new(),
        };
        assert!(empty.validate().is_err());
        let negative_rate = MaterialGrid::filled(MaterialParam::Plasticity, [1, 1, 1], -1.0);
        assert!(negative_rate.validate().is_err());
    }

    #[test]
    fn the_region_takes_the_grids_values_scaled_by_its_volume_ratio() {
        let lattice = base();
        let b = CoeffBox {
            min: [2, 2, 2],
            max: [6, 5, 4],
        };
        let mut state = RegionState::new(&lattice, b, [9, 7, 5], Material::PLASTIC).unwrap();
        let before = state.clone();
        assert!(!apply_grids(&[], &lattice, &lattice, 1.0, &mut state));
        assert_eq!(state.mass, before.mass);
        let mut heavy = MaterialGrid::filled(MaterialParam::Mass, lattice.dims, 1.0);
        heavy.paint(
            &lattice,
            &PaintRegion::Box {
                min: Vec3::splat(-10.0),
                max: Vec3::new(0.85, 10.0, 10.0),
            },
            4.0,
        );
        let grids = [heavy];
        assert!(apply_grids(&grids, &lattice, &lattice, 0.125, &mut state));
        for k in 0..5 {
            for j in 0..7 {
                for i in 0..9 {
                    let x = state.grid.position(&lattice, i, j, k);
                    let m = state.mass[state.point_index(i, j, k)];
                    let want = 0.125 * grids[0].sample(&lattice, x);
                    assert_eq!(m, want);
                    if x.x <= 0.8 + 1e-4 {
                        assert_eq!(m, 0.5);
                    }
                }
            }
        }
        assert_eq!(state.stiffness, before.stiffness);
    }
}
