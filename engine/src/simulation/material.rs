//! The painted material in the running stage: grids of mass, damping, stiffness and plastic
//! drift rate over the base patch (Hua & Qin §4.1), painted by commands and applied to the mass points of every
//! region the stage makes, and to the live region when they change.

#[allow(clippy::wildcard_imports)] // the stage's own module: its types and imports
use super::*;
use dynaclay_core::dynamics::{MaterialPaint, apply_grids, paint_grids};

impl SimulationStage {
    /// The uniform material of a region on density patch `patch`: the live region's material
    /// scaled to the volume its mass points hold (a detail patch's hold less than the base's),
    /// with [`SimConfig::detail_base_yield`] its yield density times the spacing ratio.
    pub(super) fn region_material_of(&self, patch: usize) -> Material {
        if patch == 0 {
            self.region_material
        } else {
            let mut m = self
                .region_material
                .for_volume_ratio(self.volume_ratio(patch));
            if self.config.detail_base_yield {
                m.yield_density *= self.spacing_ratio(patch) as f32;
            }
            m
        }
    }

    /// The base's knot spacing over `patch`'s (1 on the base; a power of two on a detail
    /// patch): the stride of a region's coarse springs there.
    pub(super) fn spacing_ratio(&self, patch: usize) -> usize {
        let lattice = &self.clay.density.patches[patch].lattice;
        let ratio = self.clay.base().spacing / lattice.spacing;
        if ratio.is_finite() && ratio >= 1.0 {
            ratio.round() as usize
        } else {
            1
        }
    }

    /// Volume of a mass point of `patch` against one of the base patch.
    fn volume_ratio(&self, patch: usize) -> f32 {
        let lattice = &self.clay.density.patches[patch].lattice;
        (lattice.spacing / self.clay.base().spacing).powi(3)
    }

    /// Gives `state` (a region on `self.region_patch`) the painted values where they are.
    pub(super) fn apply_painted_material(&self, state: &mut RegionState) {
        if self.material_grids.is_empty() {
            return;
        }
        let patch = self.region_patch;
        let ratio = if patch == 0 {
            1.0
        } else {
            self.volume_ratio(patch)
        };
        apply_grids(
            &self.material_grids,
            self.clay.base(),
            &self.clay.density.patches[patch].lattice,
            ratio,
            state,
        );
    }

    /// The live region's mass, damping, stiffness and drift rate made again from its uniform material
    /// and the painted grids (after a paint or a clear).
    pub(super) fn refresh_region_material(&mut self) {
        let Some(mut state) = self.region.take() else {
            return;
        };
        let m = self.region_material_of(self.region_patch);
        state.mass.fill(m.mass);
        state.material_mass = m.mass;
        state.damping.fill(m.damping);
        state.stiffness.fill(m.stiffness);
        state.plasticity_per_s.fill(m.plasticity_per_s);
        self.apply_painted_material(&mut state);
        self.region = Some(state);
    }

    /// Applies a [`Command::PaintMaterial`]: paints the grids (a parameter without a grid
    /// gets one over the base patch, filled with the uniform material's value) and refreshes
    /// the live region.
    pub(super) fn paint_material(&mut self, paint: &MaterialPaint) -> Result<String, CommandError> {
        let set = paint_grids(
            &mut self.material_grids,
            self.clay.base(),
            &self.config.material,
            paint,
        )?;
        self.refresh_region_material();
        Ok(format!("material painted at {set} grid samples"))
    }

    /// The painted material grids (every grid the session carries, simulated or not).
    #[must_use]
    pub fn material_grids(&self) -> &[dynaclay_core::io::MaterialGrid] {
        &self.material_grids
    }
}
