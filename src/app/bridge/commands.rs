//! The app's commands turned into engine commands, and the pins' list kept in step.

use super::*;

impl Bridge {
    /// Asks the engine for its pins when their revision moved, and takes the list in when
    /// the answer arrived.
    pub(super) fn poll_pins(&mut self, revision: u64) {
        // One question at a time: a newer revision is asked about once the answer is in.
        if self.pins_seen != Some(revision) && self.pins_list.is_none() {
            let (tx, rx) = bounded(1);
            if self
                .engine()
                .commands()
                .send(Command::ListPins { reply: tx })
                .is_ok()
            {
                self.pins_seen = Some(revision);
                self.pins_list = Some(rx);
            }
        }
        let Some(pins) = self.pins_list.as_ref().and_then(|rx| rx.try_recv().ok()) else {
            return;
        };
        self.pins_list = None;
        self.pin_lines = pins
            .iter()
            .enumerate()
            .map(|(i, p)| crate::tools::describe_pin(i, p))
            .collect();
        self.pin_marks = pins
            .into_iter()
            .map(|p| match p {
                crate::dynamics::Constraint::Point { at }
                | crate::dynamics::Constraint::Normal { at, .. } => vec![at],
                crate::dynamics::Constraint::Curve { points } => points,
            })
            .collect();
    }

    pub(super) fn fail(&self, what: &str, error: String) {
        let _ = self.events.send(EngineEvent::Failed {
            what: what.into(),
            error,
        });
    }

    pub(super) fn send(&self, what: &str, cmd: Command) {
        if self.engine().commands().send(cmd).is_err() {
            self.fail(what, "the simulation loop has stopped".into());
        }
    }

    /// Starts a compact RBF worker of `particles` particles (on this thread, never a loop) and
    /// hands it to the engine, or switches the mode off.
    pub(super) fn set_compact(&mut self, what: &str, particles: Option<usize>) {
        self.compact_particles = particles;
        let link = match particles.map(|n| CompactRbfLink::spawn(CompactSettings::new(n))) {
            None => None,
            Some(Ok(link)) => Some(Box::new(link)),
            Some(Err(e)) => {
                self.compact_particles = None;
                return self.fail(what, e.to_string());
            }
        };
        self.send(what, Command::SetCompactRbf(link));
    }

    pub(super) fn apply(&mut self, cmd: EngineCommand) {
        let what = cmd.name();
        match cmd {
            EngineCommand::SelectTool(choice) => {
                // The view's brush keeps the last spread radius through a geometric tool.
                if let Some(r) = choice.spread_radius_fu() {
                    self.tool_radius = r;
                }
                self.send(what, Command::SetTool(choice));
            }
            EngineCommand::SetMaterial(m) => self.send(what, Command::SetMaterial(m)),
            EngineCommand::SetAutoDetail {
                automatic,
                force_tools,
            } => self.send(
                what,
                Command::SetAutoDetail {
                    automatic: Some(automatic),
                    force_tools: Some(force_tools),
                },
            ),
            EngineCommand::PaintMaterial(paint) => {
                self.send(what, Command::PaintMaterial { paint, reply: None });
            }
            EngineCommand::ClearMaterialPaint => self.send(what, Command::ClearMaterialPaint),
            EngineCommand::Mask(edit) => self.send(what, Command::Mask { edit, reply: None }),
            EngineCommand::StrokeStart => self.send(what, Command::StrokeStart),
            EngineCommand::StrokeStop => self.send(what, Command::StrokeStop),
            EngineCommand::SetSymmetry(s) => self.send(what, Command::SetSymmetry(s)),
            EngineCommand::SetCompactRbf { particles } => self.set_compact(what, particles),
            EngineCommand::Undo => self.send(what, Command::Undo),
            EngineCommand::Redo => self.send(what, Command::Redo),
            EngineCommand::Pin(request) => {
                let (tx, rx) = bounded(1);
                self.pin_replies.push(rx);
                self.send(
                    what,
                    Command::Constrain {
                        request,
                        reply: Some(tx),
                    },
                );
            }
            EngineCommand::Refine { lo, hi, level } => {
                let (tx, rx) = bounded(1);
                self.refine_replies.push(rx);
                self.send(
                    what,
                    Command::Refine {
                        lo,
                        hi,
                        level,
                        reply: Some(tx),
                    },
                );
            }
            EngineCommand::Unpin { index } => {
                let (tx, rx) = bounded(1);
                self.pin_replies.push(rx);
                self.send(
                    what,
                    Command::Unconstrain {
                        index,
                        reply: Some(tx),
                    },
                );
            }
            EngineCommand::Save { path } => {
                let (tx, rx) = bounded(1);
                self.saves.push(rx);
                self.send(
                    what,
                    Command::Save {
                        path,
                        as_session: true,
                        reply: Some(tx),
                    },
                );
            }
            EngineCommand::Export { path } => {
                let set = self.exports.latest().value.clone();
                let ev = match export_chunks(&set, &path) {
                    Ok(n) => EngineEvent::Done {
                        what: what.into(),
                        detail: format!("wrote {} ({n} triangles)", path.display()),
                    },
                    Err(error) => EngineEvent::Failed {
                        what: what.into(),
                        error: error.to_string(),
                    },
                };
                let _ = self.events.send(ev);
            }
            EngineCommand::Load { path } => {
                self.load(crate::app::command::ClaySource::File(path), false);
            }
            EngineCommand::Replace { with, keep_history } => self.load(with, keep_history),
            EngineCommand::AnswerRemoval { yes } => {
                self.send(what, Command::AnswerRemoval(yes));
            }
            edit @ (EngineCommand::AddTool(_)
            | EngineCommand::Csg { .. }
            | EngineCommand::Emboss { .. }) => {
                match super::super::edit_requests::edit_command(edit) {
                    Some(Ok((cmd, pending))) => {
                        self.edit_replies.push((what, pending));
                        self.send(what, cmd);
                    }
                    Some(Err(error)) => self.fail(what, error),
                    None => {}
                }
            }
            EngineCommand::SetMaxForce { max_force_n } => {
                match self.engine().force_limit().request(max_force_n) {
                    Ok(()) => {
                        let device_max = self.device.max_force_n;
                        let detail = if max_force_n > device_max {
                            format!(
                                "{max_force_n:.2} N asked; the device's own maximum {device_max:.2} N applies"
                            )
                        } else {
                            format!("{max_force_n:.2} N")
                        };
                        let _ = self.events.send(EngineEvent::Done {
                            what: what.into(),
                            detail,
                        });
                    }
                    Err(error) => self.fail(what, error.to_string()),
                }
            }
            EngineCommand::SetHapticGain { gain } => match self.engine().haptic_gain().set(gain) {
                Ok(()) => {
                    let _ = self.events.send(EngineEvent::Done {
                        what: what.into(),
                        detail: format!("{gain:.2}"),
                    });
                }
                Err(error) => self.fail(what, error.to_string()),
            },
            EngineCommand::ConnectDevice { spec, max_force_n } => {
                self.connect(what, &spec, max_force_n);
            }
            EngineCommand::DisconnectDevice => {
                match self.engine().disconnect_device(SWAP_TIMEOUT) {
                    Ok(report) => {
                        // The panel keeps the last device's description, shown as disconnected.
                        self.connected = false;
                        let detail = match &report.replaced {
                            Some(replaced) => closed_detail(&replaced.name, &report.close),
                            None => "no device was connected".into(),
                        };
                        let _ = self.events.send(EngineEvent::Done {
                            what: what.into(),
                            detail,
                        });
                    }
                    Err(e) => self.fail(what, e.to_string()),
                }
            }
        }
    }
}
