//! Sessions in and out of the running stage: the session it hands back (with every section it
//! carries unchanged), loading a session between two steps, and whether a session fits.

#[allow(clippy::wildcard_imports)] // the stage's own module: its types and imports
use super::*;

/// What a loaded session holds besides its clay and its material: the engine keeps it
/// untouched so that saving loses nothing.
#[derive(Clone, Debug, Default)]
pub(super) struct CarriedSections {
    /// The tool library.
    pub(super) tools: Vec<dynaclay_core::io::ToolPreset>,
    /// Name, creation time and writer of the session.
    pub(super) meta: dynaclay_core::io::SessionMeta,
}

impl SimulationStage {
    /// The session as it stands: the clay (every density patch, its paint and pins), the
    /// uniform material and the painted material grids, with every part of the loaded session
    /// the engine does not use (tool library, metadata) carried through unchanged.
    #[must_use]
    pub fn session(&self) -> Session {
        Session {
            clay: self.clay.clone(),
            material: MaterialFields {
                uniform: self.config.material,
                grids: self.material_grids.clone(),
            },
            tools: self.carried.tools.clone(),
            meta: self.carried.meta.clone(),
        }
    }

    /// Installs `session` (read from `source`): the clay, the uniform material and the
    /// painted material grids replace the current ones, the active region is dropped and both
    /// readers are handed a copy of the new clay (see `publish_layout`). A stroke held across
    /// the load continues on the new clay as a new stroke (a new undo step).
    ///
    /// The undo history is cleared, unless `keep_history` asks to keep it: the replacement is
    /// then recorded as one more step (every coefficient and the pins, as XOR differences
    /// against the replaced clay), so Undo brings the replaced clay back and the steps before
    /// it still apply. The material is not part of a step: Undo restores the clay only. A
    /// session whose paint (colour) is present where the running clay has none, or the other
    /// way round, cannot be one step and clears the history; the summary says which happened.
    ///
    /// # Errors
    /// When the session does not fit the running engine (see [`check_loadable`]); nothing
    /// changes then.
    pub fn load(
        &mut self,
        session: Session,
        source: &std::path::Path,
        keep_history: bool,
    ) -> Result<String, LoadRefused> {
        check_loadable(&self.clay.density, &session, source)?;
        let painted = session
            .material
            .grids
            .iter()
            .filter(|g| g.param().is_some())
            .count();
        // The stroke in progress ends on the old clay (its step is dropped with the history).
        self.end_stroke_now();
        let same_paint_layout = self.clay.colour.is_some() == session.clay.colour.is_some();
        let recorder = (keep_history && same_paint_layout).then(|| {
            let mut rec = StepRecorder::new(format!("open {}", source.display()));
            rec.touch_all(&self.clay);
            rec.touch_constraints(&self.clay);
            rec
        });
        if recorder.is_none() {
            self.history.clear();
        }
        let Session {
            clay,
            material,
            tools,
            meta,
        } = session;
        let patches = clay.density.patches.len();
        self.carried = CarriedSections { tools, meta };
        self.material_grids = material.grids;
        self.clay = clay;

        let history_note = match recorder {
            Some(rec) => {
                self.history.commit(rec, &self.clay);
                "undo history kept (Undo brings the replaced clay back)"
            }
            None if keep_history => {
                "undo history cleared (the paint of one clay has no counterpart in the other)"
            }
            None => "undo history cleared",
        };
        self.colour_dirty = true;
        self.mask_dirty = true;
        self.config.material = material.uniform;
        // The readers take the loaded clay as a copy, as they take a new layout: a
        // publication of every coefficient would grow each snapshot buffer to the clay's
        // dense size and keep it.
        self.publish_layout();
        self.sessions_loaded += 1;
        // A session file loaded is the session being worked on, so autosave follows it; an
        // imported cloud, mesh or volume is not one, and autosave stays where it was.
        let is_session_file = source
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("dclay"));
        if is_session_file && let Some(io) = &self.io {
            // The I/O thread gone means no autosave either: nothing to follow.
            let _ = io.send(IoJob::Follow(source.to_path_buf()));
        }
        let d = self.lattice().dims;
        let mut summary = format!(
            "loaded {} ({}×{}×{} coefficients); {history_note}",
            source.display(),
            d[0],
            d[1],
            d[2]
        );
        if painted > 0 {
            summary.push_str(&format!("; {painted} painted material grid(s)"));
        }
        if patches > 1 {
            summary.push_str(&format!("; {patches} density patches"));
        }
        Ok(summary)
    }
}

/// Whether `session` can replace the clay of an engine running on `running`: the haptic and
/// graphics loops hold copies laid out for that field (allocated once, so the haptic tick
/// never allocates), so the session's density must have as many patches, each with the same
/// lattice dimensions, spacing, origin and iso-level and the same map, and finite
/// coefficients. The base patch must be in world coordinates.
///
/// # Errors
/// The first mismatch, naming `source`.
pub fn check_loadable(
    running: &MultiPatchField,
    session: &Session,
    source: &std::path::Path,
) -> Result<(), LoadRefused> {
    let file = || source.to_path_buf();
    let theirs = &session.clay.density.patches;
    let Some(base) = theirs.first() else {
        return Err(LoadRefused::NoPatch { file: file() });
    };
    if !base.is_identity() {
        return Err(LoadRefused::MappedBase { file: file() });
    }
    let layout = || LoadRefused::PatchLayout {
        file: file(),
        session: theirs.len(),
        running: running.patches.len(),
    };
    if theirs.len() != running.patches.len() {
        return Err(layout());
    }
    for (ours, patch) in running.patches.iter().zip(theirs) {
        let (a, b) = (
            LatticeShape::of(&ours.lattice),
            LatticeShape::of(&patch.lattice),
        );
        if a != b {
            return Err(LoadRefused::LatticeMismatch {
                file: file(),
                session: b,
                running: a,
            });
        }
        if ours.world_to_patch != patch.world_to_patch {
            return Err(layout());
        }
    }
    let mut offset = 0;
    for patch in theirs {
        let coeffs = &patch.lattice.coeffs;
        if let Some(index) = coeffs.iter().position(|c| !c.is_finite()) {
            return Err(LoadRefused::NonFinite {
                file: file(),
                index: offset + index,
                value: coeffs[index],
            });
        }
        offset += coeffs.len();
    }
    session
        .clay
        .check_dense_budget()
        .map_err(|error| LoadRefused::DenseBudget {
            file: file(),
            error,
        })
}
