//! Sessions in and out of the running stage: the session it hands back (with every section it
//! carries unchanged), loading a session between two steps, and whether a session fits.

#[allow(clippy::wildcard_imports)] // the stage's own module: its types and imports
use super::*;

/// What a loaded session holds besides the sculpted patch, its paint and its uniform
/// material: the engine sculpts one density patch with a uniform material, and keeps the
/// rest untouched so that saving loses nothing.
#[derive(Clone, Debug, Default)]
pub(super) struct CarriedSections {
    /// Density patches after the first, unchanged.
    pub(super) extra_patches: Vec<BSplineLattice>,
    /// Spatially varying material grids (not applied by the simulation).
    pub(super) material_grids: Vec<crate::io::MaterialGrid>,
    /// The tool library.
    pub(super) tools: Vec<crate::io::ToolPreset>,
    /// Name, creation time and writer of the session.
    pub(super) meta: crate::io::SessionMeta,
}

impl SimulationStage {
    /// The session as it stands: the sculpted patch, its paint and the uniform material,
    /// with every part of the loaded session the engine does not simulate (further patches,
    /// material grids, tool library, metadata) carried through unchanged.
    #[must_use]
    pub fn session(&self) -> Session {
        let mut clay = self.clay.clone();
        clay.patches
            .extend(self.carried.extra_patches.iter().cloned());
        Session {
            clay,
            material: MaterialFields {
                uniform: self.config.material,
                grids: self.carried.material_grids.clone(),
            },
            tools: self.carried.tools.clone(),
            meta: self.carried.meta.clone(),
        }
    }

    /// Installs `session` (read from `source`): the clay and the uniform material replace
    /// the current ones, the active region is dropped, the undo history is cleared (its
    /// steps are differences against the replaced clay, meaningless on the new one) and the
    /// whole field is marked changed so both readers receive all of it. A stroke held across
    /// the load continues on the new clay as a new stroke (a new undo step).
    ///
    /// # Errors
    /// When the session does not fit the running engine (see [`check_loadable`]); nothing
    /// changes then.
    pub fn load(
        &mut self,
        session: Session,
        source: &std::path::Path,
    ) -> Result<String, LoadRefused> {
        check_loadable(self.lattice(), &session, source)?;
        let ignored_grids = session.material.grids.len();
        // The stroke in progress ends on the old clay (its step is dropped with the history).
        self.end_stroke_now();
        self.history.clear();
        let Session {
            clay,
            material,
            tools,
            meta,
        } = session;
        let mut patches = clay.patches;
        let extra_patches = patches.split_off(1);
        let extra = extra_patches.len();
        self.carried = CarriedSections {
            extra_patches,
            material_grids: material.grids,
            tools,
            meta,
        };
        self.clay = Clay {
            patches,
            colour: clay.colour,
            constraints: clay.constraints,
        };

        self.colour_dirty = true;
        self.config.material = material.uniform;
        let whole = CoeffBox::whole(self.lattice().dims);
        self.mark_changed(whole);
        self.sessions_loaded += 1;
        let d = self.lattice().dims;
        let mut summary = format!(
            "loaded {} ({}×{}×{} coefficients); undo history cleared",
            source.display(),
            d[0],
            d[1],
            d[2]
        );
        if ignored_grids > 0 {
            summary.push_str(&format!(
                "; {ignored_grids} material grid(s) kept but not applied (the engine simulates a uniform material)"
            ));
        }
        if extra > 0 {
            summary.push_str(&format!(
                "; {extra} further patch(es) kept unchanged (the engine sculpts the first)"
            ));
        }
        Ok(summary)
    }
}

/// Whether `session` can replace the clay of an engine running on `running`: the haptic and
/// graphics loops hold copies sized for that lattice (allocated once, so the haptic tick never
/// allocates), so the session's first density patch (the one sculpted; further patches are
/// carried unchanged) must have the same dimensions, spacing, origin and iso-level, and
/// finite coefficients.
///
/// # Errors
/// The first mismatch, naming `source`.
pub fn check_loadable(
    running: &BSplineLattice,
    session: &Session,
    source: &std::path::Path,
) -> Result<(), LoadRefused> {
    let file = || source.to_path_buf();
    let Some(patch) = session.clay.patches.first() else {
        return Err(LoadRefused::NoPatch { file: file() });
    };
    let (ours, theirs) = (LatticeShape::of(running), LatticeShape::of(patch));
    if ours != theirs {
        return Err(LoadRefused::LatticeMismatch {
            file: file(),
            session: theirs,
            running: ours,
        });
    }
    if let Some(index) = patch.coeffs.iter().position(|c| !c.is_finite()) {
        return Err(LoadRefused::NonFinite {
            file: file(),
            index,
            value: patch.coeffs[index],
        });
    }
    Ok(())
}
