//! A pull on a point-set surface (Guo & Qin §4): the surface point nearest a target is dragged
//! there by the density-spring dynamics on a sculpting region around both, with dynamic
//! sampling (§4.3) every [`RESAMPLE_EVERY`] steps. Shared by `dynaclay points --pull` and the
//! `points` script step.

use glam::Vec3;

use super::error::PointSetError;
use super::sampling::{SamplingOptions, resample};
use super::sculpt::{PointSetSculpt, SculptOptions};
use super::surface::PointSet;
use dynaclay_core::dynamics::{Distribution, Material, ToolForce, start_on_surface};

/// Steps between two resamplings during a pull.
pub const RESAMPLE_EVERY: u32 = 25;
/// Density force per unit of force integral (field units are world units here).
pub const PULL_GAIN: f32 = 5e6;

/// What a pull did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PullReport {
    /// Points inside the sculpting region at the end.
    pub in_region: usize,
    /// Points in the whole set at the end.
    pub points: usize,
}

/// The most lattice nodes a pull's sculpting region may hold (128³: about 2 GB of
/// simulation state at most).
pub const MAX_PULL_REGION_NODES: usize = 1 << 21;

/// Drags the surface point nearest to `target` there: a sculpting region around both, the
/// dynamics for `steps` steps (plastic clay that does not yield back), resampling every
/// [`RESAMPLE_EVERY`] steps and once at the end.
///
/// # Errors
/// [`PointSetError::TooFewPoints`] for an empty set, or a failed step, resampling or index.
pub fn pull(set: &mut PointSet, target: Vec3, steps: u32) -> Result<PullReport, PointSetError> {
    let nearest = set
        .points
        .iter()
        .copied()
        .min_by(|a, b| {
            (*a - target)
                .length_squared()
                .total_cmp(&(*b - target).length_squared())
        })
        .ok_or(PointSetError::TooFewPoints { got: 0, need: 1 })?;
    let h = set.spacing_fu;
    let reach = (target - nearest).length();
    let margin = Vec3::splat(reach + 6.0 * h);
    let (lo, hi) = (nearest.min(target) - margin, nearest.max(target) + margin);
    // The region's lattice has a node per point spacing: bounded before it is made.
    let nodes = ((hi - lo) / h + Vec3::splat(4.0))
        .to_array()
        .iter()
        .map(|&n| f64::from(n))
        .product::<f64>();
    if !(nodes.is_finite() && nodes <= MAX_PULL_REGION_NODES as f64) {
        return Err(PointSetError::PullTooFar {
            reach,
            nodes,
            spacing: h,
            max: MAX_PULL_REGION_NODES,
        });
    }
    let mut opts = SculptOptions::for_spacing(h);
    opts.material = Material {
        yield_density: 0.0,
        ..Material::PLASTIC
    };
    let mut sculpt = PointSetSculpt::new(set, lo, hi, &opts)?;
    let sampling = SamplingOptions::for_target(h);
    let radius = (reach * 0.75).max(3.0 * h);
    for step in 0..steps {
        let start = start_on_surface(&sculpt.lattice, nearest, target);
        let force = ToolForce {
            start,
            end: target,
            distribution: Distribution::Gaussian,
            radius,
            gain: PULL_GAIN,
        };
        sculpt.step(set, &[force])?;
        if step % RESAMPLE_EVERY == RESAMPLE_EVERY - 1 {
            resample(set, Some(sculpt.grid_box()), &sampling)?;
            sculpt.enlist(set);
        }
    }
    resample(set, Some(sculpt.grid_box()), &sampling)?;
    set.reindex()?;
    Ok(PullReport {
        in_region: sculpt.member_count(),
        points: set.len(),
    })
}
