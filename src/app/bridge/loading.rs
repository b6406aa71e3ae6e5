//! Loading for the window: the clay the load worker read, fitted or built (see
//! [`super::load_worker`]) offered to the running simulation from the bridge thread, and the
//! engine restarted on a clay of another layout.

use super::load_worker::LoadWorker;
use super::*;
use crate::app::command::ClaySource;

impl Bridge {
    /// Serves Open, Import and New (and the launch's Load): the clay is read, fitted or built
    /// on a worker thread while the old clay stays in use, then offered to the simulation by
    /// [`Bridge::poll_load_worker`]. One load at a time: another while one runs is refused.
    pub(super) fn load(&mut self, source: ClaySource, keep_history: bool) {
        if let Some(running) = &self.load_worker {
            return self.fail(
                "load",
                format!(
                    "{} is still loading; wait for it before loading another clay",
                    running.source()
                ),
            );
        }
        match LoadWorker::start(source, keep_history, self.events.clone()) {
            Ok(worker) => self.load_worker = Some(worker),
            Err(e) => self.fail("load", format!("cannot start the load: {e}")),
        }
    }

    /// Takes the load worker's clay when it is ready and offers it to the simulation.
    pub(super) fn poll_load_worker(&mut self) {
        let Some(worker) = self.load_worker.as_mut() else {
            return;
        };
        let Some(result) = worker.try_take() else {
            return;
        };
        let keep_history = worker.keep_history();
        self.load_worker = None;
        let _ = self.events.send(EngineEvent::Progress(None));
        match result {
            Ok(prepared) => self.offer(
                prepared.session,
                &prepared.source,
                true,
                prepared.points,
                keep_history,
            ),
            Err(error) => self.fail("load", error.to_string()),
        }
    }

    /// Offers `session` to the running simulation; with `retry`, a refusal for its layout
    /// restarts the engine on it.
    pub(super) fn offer(
        &mut self,
        session: Session,
        source: &Path,
        retry: bool,
        points: Option<Box<FollowedPoints>>,
        keep_history: bool,
    ) {
        let (tx, rx) = bounded(1);
        let kept = (retry && self.restart.is_some()).then(|| Box::new(session.clone()));
        let tools = session.tools.clone();
        let sent = self.engine().commands().send(Command::Load {
            session: Box::new(session),
            source: source.to_path_buf(),
            keep_history,
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
        let session_path = &mut self.session_path;
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
                    if pending.source.is_file() {
                        let is_session =
                            crate::app::replace_dialog::is_session_path(&pending.source);
                        if is_session {
                            *session_path = Some(pending.source.clone());
                        }
                        let _ = events.send(EngineEvent::FileDone {
                            path: pending.source.clone(),
                            is_session,
                        });
                    }
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
        // Autosave and the replaced clay follow the session worked on now (the last Save As
        // or Open), not the one the window started with.
        let (autosave_at, keep_replaced_at) = match &self.session_path {
            Some(current) => (
                Some(current.clone()),
                current.with_extension("replaced.dclay"),
            ),
            None => (settings.autosave.clone(), settings.keep_replaced_at.clone()),
        };
        let kept = match save_session(&keep_replaced_at, &stopped.report.session) {
            Ok(()) => format!(
                "the replaced clay, unsaved work included, is in {}",
                keep_replaced_at.display()
            ),
            Err(e) => format!("the replaced clay could not be kept: {e}"),
        };
        let Some(device) = stopped.device else {
            return self.fail(what, "the device left with the old engine".into());
        };
        let autosave = autosave_at
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
        // The new engine has no history to keep: the replaced clay is in the file above.
        self.offer(session, source, false, points, false);
    }
}
