//! Commands: what the stage does with each [`Command`] between two steps, and how it answers.

#[allow(clippy::wildcard_imports)] // the stage's own module: its types and imports
use super::*;

impl SimulationStage {
    /// Applies every queued command (non-blocking).
    pub fn apply_commands(&mut self) {
        self.apply_commands_at_most(u32::MAX);
    }

    /// Applies up to `limit` queued commands in arrival order (non-blocking) and returns how
    /// many it applied; a replay applies exactly the recorded number before each step.
    pub fn apply_commands_at_most(&mut self, limit: u32) -> u32 {
        self.poll_compact();
        let mut applied = 0;
        while applied < limit {
            let Ok(cmd) = self.commands.try_recv() else {
                break;
            };
            let ok = self.apply(cmd);
            applied += 1;
            self.counters.commands_applied(1);
            if !ok {
                self.counters.command_errors(1);
            }
        }
        self.commands_since_step = self.commands_since_step.saturating_add(applied);
        applied
    }

    fn apply(&mut self, cmd: Command) -> bool {
        self.pins_revision += u64::from(constrain::may_change_pins(&cmd));
        match cmd {
            #[cfg(feature = "fault-injection")]
            Command::InjectPanic(site) => match site {
                crate::PanicSite::Simulation => {
                    panic!("injected: the simulation loop panics")
                }
                crate::PanicSite::Io => {
                    if let Some(io) = &self.io {
                        let _ = io.send(IoJob::InjectPanic);
                    }
                    true
                }
            },
            Command::SetTool(tool) => {
                // A held stroke ends with the tool it was made with.
                self.end_stroke_now();
                self.tool.set(tool);
                true
            }
            Command::SetMaterial(m) => {
                self.config.material = m;
                true
            }
            Command::SetAutoDetail {
                automatic,
                force_tools,
            } => {
                if let Some(on) = automatic {
                    self.config.auto_detail = on;
                }
                if let Some(on) = force_tools {
                    self.config.auto_detail_force = on;
                }
                true
            }
            Command::PaintMaterial { paint, reply } => {
                let result = self.paint_material(&paint);
                let ok = result.is_ok();
                if let Some(r) = reply {
                    let _ = r.send(result);
                }
                ok
            }
            Command::ClearMaterialPaint => {
                self.material_grids.retain(|g| g.param().is_none());
                self.refresh_region_material();
                true
            }
            Command::Mask { edit, reply } => {
                let result = self.edit_mask(&edit);
                let ok = result.is_ok();
                if let Some(r) = reply {
                    let _ = r.send(result);
                }
                ok
            }
            Command::StrokeStart => {
                self.stroke_armed = true;
                true
            }
            Command::StrokeStop => {
                self.stroke_armed = false;
                true
            }
            Command::SetSymmetry(symmetry) => {
                // A held stroke ends mirrored as it began.
                self.end_stroke_now();
                self.symmetry = symmetry;
                true
            }
            Command::ApplyTool {
                tool,
                poses,
                duration_s,
                patch,
                reply,
            } => {
                self.end_stroke_now();
                // A tool that will be refused needs no estimate: its error says why.
                let share = if tool.validate().is_ok() {
                    let each_s = duration_s / poses.len().max(1) as f32;
                    let change = tool_volume_change(&self.clay, &tool, &poses, each_s, patch);
                    let guard = self.config.removal_guard;
                    match self
                        .removal
                        .admits_step(guard, &self.clay, tool.action.name(), change)
                    {
                        Ok(share) => share,
                        Err(refused) => {
                            let step = Command::ApplyTool {
                                tool,
                                poses,
                                duration_s,
                                patch,
                                reply,
                            };
                            self.removal.hold(step, refused);
                            return false;
                        }
                    }
                } else {
                    0.0
                };
                // Past the box budget the tool is applied clipped to the box, and the step
                // answers with why.
                let growth = self.make_room_for_tool(&tool, &poses, patch);
                // A script's tool on the base (the default) gets the detail its brush needs; a
                // smoothing over detail smooths every patch under it.
                let (patches, own_term) = match (patch, self.patches_smoothed(&tool, &poses)) {
                    (0, Some(patches)) => (patches, true),
                    (0, None) => (vec![self.patch_for_brush(&tool, &poses)], false),
                    (patch, _) => (vec![patch], false),
                };
                let mut rec = StepRecorder::new(tool.action.name());
                let mut result = None;
                for patch in patches {
                    let options = ApplyOptions {
                        patch,
                        own_term,
                        ..ApplyOptions::default()
                    };
                    let applied = apply_stroke(
                        &mut self.clay,
                        &tool,
                        &poses,
                        duration_s,
                        &options,
                        Some(&mut rec),
                    );
                    // The first patch's result is the answer (a later failure replaces it);
                    // every other patch's box is published here.
                    match (&result, applied) {
                        (None, first) => result = Some(first),
                        (Some(_), Ok(report)) => {
                            if let Some(b) = report.coeff_box {
                                self.mark_changed(usize::from(report.patch), b);
                            }
                        }
                        (Some(Ok(_)), Err(e)) => result = Some(Err(e)),
                        (Some(Err(_)), Err(_)) => {}
                    }
                }
                let result = match (result.unwrap_or_else(|| Ok(ToolReport::default())), growth) {
                    (Ok(_), Err(refused)) => Err(ToolError::Growth(refused)),
                    (result, _) => result,
                };
                self.colour_dirty |= tool.action.paints();
                // Whatever was applied before a failure stays undoable.
                let changed = self.commit(rec);
                let ok = self.edited(result, tool.action.name(), share, reply);
                if changed && matches!(tool.action, ToolAction::Contact(_)) {
                    self.contact_committed();
                }
                ok
            }
            Command::Csg {
                op,
                other,
                patch,
                reply,
            } => {
                self.end_stroke_now();
                let change = csg_volume_change(&self.clay, &other, op, patch);
                let guard = self.config.removal_guard;
                let share = match self
                    .removal
                    .admits_step(guard, &self.clay, op.name(), change)
                {
                    Ok(share) => share,
                    Err(refused) => {
                        let step = Command::Csg {
                            op,
                            other,
                            patch,
                            reply,
                        };
                        self.removal.hold(step, refused);
                        return false;
                    }
                };
                let mut rec = StepRecorder::new(format!("csg {}", op.name()));
                let options = ApplyOptions {
                    patch,
                    ..ApplyOptions::default()
                };
                let result = apply_csg(&mut self.clay, &other, op, &options, Some(&mut rec));
                // The other clay's paint may come along.
                self.colour_dirty = true;
                self.commit(rec);
                self.edited(result, op.name(), share, reply)
            }
            Command::AnswerRemoval(yes) => match self.removal.answer(yes) {
                // The yes lets the held step through now.
                Some(step) => self.apply(step),
                None => true,
            },
            Command::ReportRemovals(to) => {
                self.removal.report_to(to);
                true
            }
            Command::MakeTool {
                name,
                selection,
                action,
                falloff_fu,
                reply,
            } => {
                let result = self.make_tool(&name, &selection, action, falloff_fu);
                answer(reply, result)
            }
            Command::AddTool { preset, reply } => {
                let line = self.add_tool(*preset);
                answer(reply, Ok(line))
            }
            Command::ApplyLibraryTool {
                tool,
                poses,
                duration_s,
                patch,
                reply,
            } => match self.library_tool(&tool) {
                Ok(tool) => self.apply(Command::ApplyTool {
                    tool,
                    poses,
                    duration_s,
                    patch,
                    reply,
                }),
                Err(e) => answer(reply, Err(e)),
            },
            Command::SetLibraryTool { tool: named, reply } => match self.library_tool(&named) {
                Ok(tool) => {
                    // A held stroke ends with the tool it was made with.
                    self.end_stroke_now();
                    let line = format!(
                        "holding library tool {:?} ({})",
                        named.name,
                        tool.action.name()
                    );
                    self.tool.set(ToolChoice::Geometric(tool));
                    answer(reply, Ok(line))
                }
                Err(e) => answer(reply, Err(e)),
            },
            Command::Emboss {
                relief,
                params,
                patch,
                reply,
            } => {
                self.end_stroke_now();
                let what = if params.engrave { "engrave" } else { "emboss" };
                let mut rec = StepRecorder::new(what);
                let result = apply_emboss(
                    &mut self.clay,
                    &relief,
                    &params,
                    patch,
                    ApplyOptions::default().samples_per_span,
                    Some(&mut rec),
                );
                self.commit(rec);
                self.embossed(result, what, reply)
            }
            Command::Refine {
                lo,
                hi,
                level,
                reply,
            } => {
                self.end_stroke_now();
                let result = self.refine(lo, hi, level);
                let ok = result.is_ok();
                self.clay_revision += 1;
                if let Some(r) = reply {
                    let _ = r.send(result);
                }
                ok
            }
            Command::Undo | Command::Redo => {
                self.end_stroke_now();
                let patches = self.clay.density.patches.len();
                let done = if matches!(cmd, Command::Undo) {
                    self.history.undo(&mut self.clay)
                } else {
                    self.history.redo(&mut self.clay)
                };
                if self.clay.density.patches.len() != patches {
                    // The step had folded a detail patch away: the layout changes back (the
                    // offered copy holds the step's coefficients).
                    self.publish_layout();
                } else if let Ok(Some(_)) = &done {
                    // Only the step's bricks changed.
                    let step = if matches!(cmd, Command::Undo) {
                        self.history.next_redo()
                    } else {
                        self.history.next_undo()
                    };
                    let boxes: Vec<(u16, CoeffBox)> = step
                        .map(|s| s.density_boxes().collect())
                        .unwrap_or_default();
                    for (patch, b) in boxes {
                        self.mark_changed(usize::from(patch), b);
                    }
                } else if done.is_err() {
                    // A refused step leaves the clay as it was; publish it whole all the same.
                    self.mark_all_changed();
                }
                // The paint and the mask are published whole; the graphics loop wakes for them.
                self.changed_since_publish = true;
                self.colour_dirty = true;
                self.mask_dirty = true;
                self.clay_revision += 1;
                self.cancel_compact();
                done.is_ok()
            }
            Command::SetCompactRbf(link) => {
                self.end_stroke_now();
                self.set_compact(link.map(|l| *l));
                true
            }
            Command::Constrain { request, reply } => {
                let result = self.pin(&request).map_err(CommandError::from);
                let ok = result.is_ok();
                reply.map(|r| r.send(result));
                ok
            }
            Command::Unconstrain { index, reply } => {
                let result = self.unpin(index).map_err(CommandError::from);
                let ok = result.is_ok();
                reply.map(|r| r.send(result));
                ok
            }
            Command::ListPins { reply } => reply.send(self.clay.constraints.clone()).is_ok(),
            Command::Snapshot { reply } => reply.send(self.session()).is_ok(),
            Command::Load {
                session,
                source,
                keep_history,
                reply,
            } => {
                let result = self.load(*session, &source, keep_history);
                let ok = result.is_ok();
                self.clay_revision += 1;
                self.cancel_compact();
                if let Some(r) = reply {
                    let _ = r.send(result.map_err(CommandError::from));
                }
                ok
            }
            Command::Save {
                path,
                as_session,
                reply,
            } => match &self.io {
                Some(io) => io
                    .send(IoJob::Save(Box::new(SaveJob {
                        path,
                        as_session,
                        session: self.session(),
                        reply,
                    })))
                    .is_ok(),
                None => {
                    if let Some(r) = reply {
                        let _ = r.send(Err(SaveError::NoIoThread));
                    }
                    false
                }
            },
        }
    }

    /// Publishes a tool or CSG edit's box and answers `reply` with its account and the share
    /// of the clay it was estimated to remove; returns whether it succeeded.
    fn edited(
        &mut self,
        result: Result<ToolReport, dynaclay_core::tools::ToolError>,
        what: &str,
        removed_fraction: f32,
        reply: Option<EditReply>,
    ) -> bool {
        let answer = self.edit_answer(result, what).map(|note| EditOutcome {
            note,
            removed_fraction,
        });
        let ok = answer.is_ok();
        if let Some(r) = reply {
            let _ = r.send(answer);
        }
        ok
    }

    /// Publishes an emboss's box and answers `reply`; returns whether it succeeded.
    fn embossed(
        &mut self,
        result: Result<ToolReport, dynaclay_core::tools::ToolError>,
        what: &str,
        reply: Option<Reply>,
    ) -> bool {
        let answer = self.edit_answer(result, what);
        let ok = answer.is_ok();
        if let Some(r) = reply {
            let _ = r.send(answer);
        }
        ok
    }

    /// Publishes an edit's box (every patch after a failure, which may have applied some
    /// poses) and says what it did.
    fn edit_answer(
        &mut self,
        result: Result<ToolReport, dynaclay_core::tools::ToolError>,
        what: &str,
    ) -> Result<String, CommandError> {
        match result {
            Ok(report) => {
                if let Some(b) = report.coeff_box {
                    self.mark_changed(usize::from(report.patch), b);
                }
                Ok(format!(
                    "{what}: {} samples visited, {} dirtied",
                    report.visited, report.dirtied
                ))
            }
            Err(error) => {
                match &error {
                    dynaclay_core::tools::ToolError::DenseBudget(refused) => {
                        self.note_budget_refusal((*refused).into());
                    }
                    dynaclay_core::tools::ToolError::Growth(
                        dynaclay_core::tools::GrowthError::ClayTooLarge { dims, total },
                    ) => {
                        self.note_budget_refusal(crate::BudgetRefusal::ClayBox {
                            dims: *dims,
                            total: *total,
                        });
                    }
                    _ => {}
                }
                // A failed application may have applied earlier poses: publish the patch.
                self.mark_all_changed();
                Err(CommandError::Tool {
                    what: what.to_owned(),
                    error,
                })
            }
        }
    }

    /// Adds a detail patch (see [`Command::Refine`]) and hands the new layout to the readers;
    /// returns what was added (without a "refine" prefix: the caller names the command).
    fn refine(&mut self, lo: Vec3, hi: Vec3, level: u32) -> Result<String, CommandError> {
        let n = self.clay.refine(lo, hi, level)?;
        self.pending.push(None);
        self.publish_layout();
        let l = &self.clay.density.patches[n].lattice;
        Ok(format!(
            "detail patch {n}, {}×{}×{} coefficients at knot spacing {} (level {level})",
            l.dims[0], l.dims[1], l.dims[2], l.spacing
        ))
    }
}

/// Sends `result` on `reply` (if any); returns whether it succeeded.
fn answer<T>(
    reply: Option<crossbeam::channel::Sender<Result<T, CommandError>>>,
    result: Result<T, CommandError>,
) -> bool {
    let ok = result.is_ok();
    if let Some(r) = reply {
        let _ = r.send(result);
    }
    ok
}
