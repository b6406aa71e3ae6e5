//! Loading on the bridge thread: sessions read, point clouds, meshes and volumes fitted,
//! offered to the running simulation, and the engine restarted on a clay of another layout.

use super::*;

/// Why the window could not fit a file it was asked to load.
#[derive(Debug, thiserror::Error)]
pub(super) enum ImportFailed {
    /// A raw volume names no dimensions; the command line can give them.
    #[error(
        "{}: a raw volume does not say its dimensions; run `dynaclay import {} --dims X,Y,Z \
         --iso V --out SESSION.dclay` and load the session",
        path.display(),
        path.display()
    )]
    NeedsDims {
        /// The volume.
        path: PathBuf,
    },
    /// The fit failed.
    #[error("{}: {source}", path.display())]
    Fit {
        /// The file.
        path: PathBuf,
        /// Why (boxed: an import error is large).
        source: Box<ImportError>,
    },
}

impl Bridge {
    /// Serves the Load button: a session is read here, an importable file (point cloud, mesh,
    /// volume) is fitted here as `dynaclay import` fits it (its report and progress go to the
    /// log); the result is offered to the running simulation, and a refusal for its layout
    /// restarts the engine on it (see [`Bridge::poll_loads`]).
    pub(super) fn load(&mut self, path: &Path) {
        if is_point_cloud(path) {
            return match self.import_points(path) {
                Ok((session, points)) => self.offer(session, path, true, points),
                Err(error) => self.fail("load", error.to_string()),
            };
        }
        let session = if crate::fit::is_importable(path) {
            match self.import(path) {
                Ok(s) => s,
                Err(error) => return self.fail("load", error.to_string()),
            }
        } else {
            match load_session(path) {
                Ok(s) => s,
                Err(e) => return self.fail("load", CommandError::Read(e).to_string()),
            }
        };
        self.offer(session, path, true, None);
    }

    /// Tells the log one line of a load in progress.
    pub(super) fn say_load(&self, detail: String) {
        let _ = self.events.send(EngineEvent::Done {
            what: "load".into(),
            detail,
        });
    }

    /// Fits a point cloud as [`Bridge::import`] does and builds its point-set surface (Guo &
    /// Qin §3) in the clay's units, here on the bridge thread: the clay is the fit, and the
    /// points, with their normals (oriented over a spanning tree when the file has none),
    /// follow it. A cloud whose point set cannot be built still loads its clay (the log says
    /// why it has no points).
    pub(super) fn import_points(
        &self,
        path: &Path,
    ) -> Result<(Session, Option<Box<FollowedPoints>>), ImportFailed> {
        let say = |detail: String| self.say_load(detail);
        say(format!("importing {}", path.display()));
        let imported = import_cloud(
            path,
            &ImportSettings::default(),
            &mut fit_stage_reporter(&say),
            &mut |line| say(line),
        )
        .map_err(|source| ImportFailed::Fit {
            path: path.to_path_buf(),
            source: Box::new(source),
        })?;
        let cloud = imported.cloud_in_field_units();
        let points = match PointSet::build(&cloud, &PointSetOptions::default()) {
            Ok((mut set, times)) => {
                if let Some(colours) = imported.colours.as_ref().filter(|c| c.len() == set.len()) {
                    set.colours.clone_from(colours);
                }
                say(format!(
                    "point set: {} points, spacing {:.4}, built in {:.0} ms; shown as splats \
                     following the clay",
                    set.len(),
                    set.spacing_fu,
                    times.total_ns() as f64 / 1e6
                ));
                Some(Box::new(FollowedPoints::of_set(&set)))
            }
            Err(e) => {
                self.fail(
                    "load",
                    format!("{}: no point set ({e}); the clay loads", path.display()),
                );
                None
            }
        };
        Ok((imported.into_session(path, crate::io::unix_now_s()), points))
    }

    /// Fits `path` with `dynaclay import`'s defaults (a volume without `--iso` at its
    /// mid-range intensity), telling the log each stage and report line.
    pub(super) fn import(&self, path: &Path) -> Result<Session, ImportFailed> {
        let say = |detail: String| self.say_load(detail);
        say(format!("importing {}", path.display()));
        let settings = ImportSettings {
            midrange_iso: true,
            ..ImportSettings::default()
        };
        let session = import_session(
            path,
            &settings,
            &mut fit_stage_reporter(&say),
            &mut |line| say(line),
        );
        session.map_err(|e| match e {
            ImportError::NeedsDims => ImportFailed::NeedsDims {
                path: path.to_path_buf(),
            },
            source => ImportFailed::Fit {
                path: path.to_path_buf(),
                source: Box::new(source),
            },
        })
    }

    /// Offers `session` to the running simulation; with `retry`, a refusal for its layout
    /// restarts the engine on it.
    pub(super) fn offer(
        &mut self,
        session: Session,
        source: &Path,
        retry: bool,
        points: Option<Box<FollowedPoints>>,
    ) {
        let (tx, rx) = bounded(1);
        let kept = (retry && self.restart.is_some()).then(|| Box::new(session.clone()));
        let tools = session.tools.clone();
        let sent = self.engine().commands().send(Command::Load {
            session: Box::new(session),
            source: source.to_path_buf(),
            reply: Some(tx),
        });
        if sent.is_err() {
            return self.fail("load", CommandError::Stopped.to_string());
        }
        self.loads.push(PendingLoad {
            reply: rx,
            session: kept,
            source: source.to_path_buf(),
            points,
            tools,
        });
    }

    /// Forwards the simulation's answers to loads; a session refused because its patch
    /// layout differs from the running clay's starts a new engine on it.
    pub(super) fn poll_loads(&mut self) {
        let mut restart = None;
        let events = &self.events;
        let points = &self.points;
        self.loads.retain_mut(|pending| {
            let answer = match pending.reply.try_recv() {
                Ok(answer) => answer,
                Err(crossbeam::channel::TryRecvError::Empty) => return true,
                Err(crossbeam::channel::TryRecvError::Disconnected) => Err(CommandError::Stopped),
            };
            let event = match answer {
                Ok(detail) => {
                    // The clay is in: its points (or none) follow it from now on. A full
                    // queue means the graphics loop stalled; it takes the newest when back.
                    let _ = points.try_send(pending.points.take());
                    let _ = events.send(EngineEvent::Library(std::mem::take(&mut pending.tools)));
                    EngineEvent::Done {
                        what: "load".into(),
                        detail,
                    }
                }
                Err(CommandError::Load(
                    LoadRefused::PatchLayout { .. } | LoadRefused::LatticeMismatch { .. },
                )) if pending.session.is_some() && restart.is_none() => {
                    restart = pending
                        .session
                        .take()
                        .map(|s| (s, pending.source.clone(), pending.points.take()));
                    return false;
                }
                Err(error) => EngineEvent::Failed {
                    what: "load".into(),
                    error: error.to_string(),
                },
            };
            let _ = events.send(event);
            false
        });
        if let Some((session, source, points)) = restart {
            self.restart_on(*session, &source, points);
        }
    }

    /// Stops the engine (its device closed, the replaced clay written to
    /// [`RestartSettings::keep_replaced_at`]) and starts a new one on `session`'s clay with
    /// the same device, force limit and haptic gain; the session's paint, pins and material
    /// are then installed by a load, as at launch.
    pub(super) fn restart_on(
        &mut self,
        session: Session,
        source: &Path,
        points: Option<Box<FollowedPoints>>,
    ) {
        let what = "load";
        let Some(settings) = self.restart.clone() else {
            return self.fail(what, "the engine cannot restart here".into());
        };
        if !self.connected {
            return self.fail(
                what,
                format!(
                    "{}: its clay needs a new engine, which starts with the device: connect one \
                     first",
                    source.display()
                ),
            );
        }
        let density = session.clay.density.clone();
        if !density.patches[0].is_identity() {
            return self.fail(
                what,
                format!("{}: the session's base patch is mapped", source.display()),
            );
        }
        let old = settings.config;
        let mut config = EngineConfig::for_clay(&density, &self.device);
        config.haptic_rate_hz = old.haptic_rate_hz;
        config.sim_rate_hz = old.sim_rate_hz;
        config.graphics_rate_hz = old.graphics_rate_hz;
        config.haptic_rt_priority = old.haptic_rt_priority;
        config.stale_fresh = old.stale_fresh;
        config.stale_limit = old.stale_limit;
        config.safety = old.safety;
        config.sim.material = session.material.uniform;
        let Some(engine) = self.engine.take() else {
            return;
        };
        let force_limit_n = engine.force_limit().requested_n();
        let gain = engine.haptic_gain().get();
        let stopped = match engine.stop_keeping_parts() {
            Ok(s) => s,
            Err(e) => return self.fail(what, format!("stopping the engine: {e}")),
        };
        let kept = match save_session(&settings.keep_replaced_at, &stopped.report.session) {
            Ok(()) => format!(
                "the replaced clay, unsaved work included, is in {}",
                settings.keep_replaced_at.display()
            ),
            Err(e) => format!("the replaced clay could not be kept: {e}"),
        };
        let Some(device) = stopped.device else {
            return self.fail(what, "the device left with the old engine".into());
        };
        let autosave = settings
            .autosave
            .as_ref()
            .map(|p| Autosave::new(p, AutosavePolicy::default(), std::time::Instant::now()));
        let started = Engine::start_with(
            &config,
            density.clone(),
            device,
            stopped.sink,
            StartOptions {
                autosave,
                schedule: None,
            },
        );
        let mut engine = match started {
            Ok(engine) => engine,
            Err(e) => {
                return self.fail(
                    what,
                    format!(
                        "the engine could not start on {}: {e}; {kept}",
                        source.display()
                    ),
                );
            }
        };
        super::send_stamps(&mut engine, &self.mesh_stamps);
        let _ = engine.force_limit().request(force_limit_n);
        let _ = engine.haptic_gain().set(gain);
        self.engine = Some(engine);
        self.restarts += 1;
        if let Some(n) = self.compact_particles {
            self.set_compact("compact RBF clay", Some(n));
        }
        let base = density.base();
        let top = base.node_position(base.dims[0] - 1, base.dims[1] - 1, base.dims[2] - 1);
        self.new_clay = Some((
            WorldBox {
                min: base.origin,
                max: top,
            },
            config.map,
        ));
        self.pins_seen = None;
        self.pins_list = None;
        self.pin_lines.clear();
        self.pin_marks.clear();
        let _ = self.events.send(EngineEvent::Done {
            what: what.into(),
            detail: format!(
                "{} has another clay layout ({}×{}×{} coefficients, {} patch(es)): restarted \
                 the engine on it with the same device; {kept}",
                source.display(),
                base.dims[0],
                base.dims[1],
                base.dims[2],
                density.patches.len()
            ),
        });
        self.offer(session, source, false, points);
    }
}

/// A fit's progress callback that tells `say` each stage: signing, the base lattice, and each
/// depth of detail patches once. It never cancels the fit.
pub(super) fn fit_stage_reporter(say: &impl Fn(String)) -> impl FnMut(FitProgress) -> bool + '_ {
    let mut last_depth = None;
    move |stage| {
        match stage {
            FitProgress::Signing => say("signing the points".into()),
            FitProgress::Base => say("fitting the base lattice".into()),
            FitProgress::Detail { depth, of, .. } => {
                if last_depth != Some(depth) {
                    last_depth = Some(depth);
                    say(format!("depth {depth}: fitting {of} detail patches"));
                }
            }
        }
        true
    }
}
