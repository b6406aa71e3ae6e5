//! The load worker: one thread per Open, Import or New that reads a session, fits a point
//! cloud, mesh or volume as `dynaclay import` does, or builds a new clay, while the bridge
//! keeps serving the window and the old clay stays in use. Its log lines and progress go
//! straight to the app; its result comes back over a channel of one that the bridge polls
//! without waiting. Dropping the worker (the window closed, the bridge stopped) asks the fit
//! to stop at its next stage, and the thread ends on its own.

use super::*;
use crossbeam::channel::TryRecvError;

use crate::app::command::{ClaySource, LoadProgress};

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
    /// The session file could not be read.
    #[error("{0}")]
    Read(CommandError),
    /// The new clay could not be made.
    #[error("{0}")]
    New(#[from] crate::app::new_clay::NewClayError),
    /// The window closed (the bridge stopped) while the fit ran.
    #[error("{}: cancelled", path.display())]
    Cancelled {
        /// The file.
        path: PathBuf,
    },
}

/// The least move of the progress bar worth an event, of the whole load.
const PROGRESS_STEP: f32 = 0.005;

/// A clay read, fitted or built, ready to offer to the simulation.
pub(super) struct Prepared {
    pub(super) session: Session,
    /// The file it came from (or a name for a new clay).
    pub(super) source: PathBuf,
    /// The point set that follows it (a point cloud's).
    pub(super) points: Option<Box<FollowedPoints>>,
}

/// Tells the app how a load on the worker thread goes: log lines and the progress bar.
pub(super) struct LoadReporter {
    pub(super) events: EventSender,
    /// The source as the progress bar names it.
    pub(super) source: String,
    /// Set when the load is no longer wanted; the fit stops at its next stage.
    pub(super) cancel: Arc<AtomicBool>,
}

impl LoadReporter {
    /// One line for the log.
    pub(super) fn say(&self, detail: String) {
        let _ = self.events.send(EngineEvent::Done {
            what: "load".into(),
            detail,
        });
    }

    /// Moves the progress bar to `fraction` of the load, doing `stage`.
    pub(super) fn progress(&self, fraction: f32, stage: impl Into<String>) {
        let _ = self.events.send(EngineEvent::Progress(Some(LoadProgress {
            source: self.source.clone(),
            fraction: fraction.clamp(0.0, 1.0),
            stage: stage.into(),
        })));
    }

    fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }
}

/// Reads, fits or builds the clay `source` names (a session is read, an importable file
/// fitted as `dynaclay import` fits it, a new clay built), telling `report` each stage. Runs
/// on the load worker, never on the bridge or a loop thread.
pub(super) fn prepare(
    source: &ClaySource,
    report: &LoadReporter,
) -> Result<Prepared, ImportFailed> {
    match source {
        ClaySource::New(spec) => {
            report.progress(0.0, "building the new clay");
            let name = "new clay";
            let session = spec.session(name, crate::io::unix_now_s())?;
            report.say(format!("new clay: {}", spec.describe()));
            Ok(Prepared {
                session,
                source: PathBuf::from("new clay"),
                points: None,
            })
        }
        ClaySource::File(path) if is_point_cloud(path) => {
            let (session, points) = import_points(path, report)?;
            Ok(Prepared {
                session,
                source: path.clone(),
                points,
            })
        }
        ClaySource::File(path) if crate::fit::is_importable(path) => Ok(Prepared {
            session: import(path, report)?,
            source: path.clone(),
            points: None,
        }),
        ClaySource::File(path) => {
            report.progress(0.0, "reading the session");
            let session =
                load_session(path).map_err(|e| ImportFailed::Read(CommandError::Read(e)))?;
            Ok(Prepared {
                session,
                source: path.clone(),
                points: None,
            })
        }
    }
}

/// Fits a point cloud as [`import`] does and builds its point-set surface (Guo & Qin §3) in
/// the clay's units: the clay is the fit, and the points, with their normals (oriented over a
/// spanning tree when the file has none), follow it. A cloud whose point set cannot be built
/// still loads its clay (the log says why it has no points). The log's point count is the
/// point set's, which is what the panel shows.
fn import_points(
    path: &Path,
    report: &LoadReporter,
) -> Result<(Session, Option<Box<FollowedPoints>>), ImportFailed> {
    let say = |detail: String| report.say(detail);
    say(format!("importing {}", path.display()));
    let settings = ImportSettings::default();
    // The fit is most of the work; the point set the last tenth.
    let imported = import_cloud(
        path,
        &settings,
        &mut fit_stage_reporter(report, settings.max_depth, 0.9),
        &mut |line| say(line),
    )
    .map_err(|source| fit_failed(path, source, report))?;
    report.progress(0.9, "building the point set");
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
            let _ = report.events.send(EngineEvent::Failed {
                what: "load".into(),
                error: format!("{}: no point set ({e}); the clay loads", path.display()),
            });
            None
        }
    };
    Ok((imported.into_session(path, crate::io::unix_now_s()), points))
}

/// Fits `path` with `dynaclay import`'s defaults (a volume without `--iso` at its mid-range
/// intensity), telling the log each stage and report line.
fn import(path: &Path, report: &LoadReporter) -> Result<Session, ImportFailed> {
    let say = |detail: String| report.say(detail);
    say(format!("importing {}", path.display()));
    let settings = ImportSettings {
        midrange_iso: true,
        ..ImportSettings::default()
    };
    import_session(
        path,
        &settings,
        &mut fit_stage_reporter(report, settings.max_depth, 1.0),
        &mut |line| say(line),
    )
    .map_err(|e| match e {
        ImportError::NeedsDims => ImportFailed::NeedsDims {
            path: path.to_path_buf(),
        },
        source => fit_failed(path, source, report),
    })
}

/// The fit's error, or [`ImportFailed::Cancelled`] when the reporter stopped it.
fn fit_failed(path: &Path, source: ImportError, report: &LoadReporter) -> ImportFailed {
    if report.cancelled() {
        ImportFailed::Cancelled {
            path: path.to_path_buf(),
        }
    } else {
        ImportFailed::Fit {
            path: path.to_path_buf(),
            source: Box::new(source),
        }
    }
}

/// A fit's progress callback: tells the log each stage (signing, the base lattice, and each
/// depth of detail patches once) and moves the progress bar through `0 ..= share` of the
/// load by the fit's stage fractions ([`FitProgress::fraction`], `max_depth` the fit's
/// deepest level). It stops the fit when the load is cancelled.
fn fit_stage_reporter(
    report: &LoadReporter,
    max_depth: u32,
    share: f32,
) -> impl FnMut(FitProgress) -> bool + '_ {
    let mut last_depth = None;
    let mut signing_said = false;
    // The bar moves in steps of half a percent at least, so a fit of thousands of patches
    // sends the app a few hundred events, not one per patch.
    let mut last_fraction = -1.0_f32;
    move |stage| {
        let fraction = share * stage.fraction(max_depth);
        let moved = fraction - last_fraction >= PROGRESS_STEP;
        match stage {
            FitProgress::Signing => {
                if !signing_said {
                    signing_said = true;
                    report.progress(fraction, "signing the points");
                }
            }
            FitProgress::Base => {
                report.say("fitting the base lattice".into());
                report.progress(fraction, "fitting the base lattice");
                last_fraction = fraction;
            }
            FitProgress::Detail { depth, done, of } => {
                if last_depth != Some(depth) {
                    last_depth = Some(depth);
                    report.say(format!("depth {depth}: fitting {of} detail patches"));
                }
                if moved {
                    report.progress(fraction, format!("depth {depth}: {done} of {of} patches"));
                    last_fraction = fraction;
                }
            }
        }
        !report.cancelled()
    }
}

/// A load running on its own thread.
pub(super) struct LoadWorker {
    result: Receiver<Result<Prepared, ImportFailed>>,
    cancel: Arc<AtomicBool>,
    keep_history: bool,
    source: String,
}

impl LoadWorker {
    /// Starts reading, fitting or building `source` on a new thread; its log lines and
    /// progress go to `events`.
    ///
    /// # Errors
    /// The thread could not be started.
    pub(super) fn start(
        source: ClaySource,
        keep_history: bool,
        events: EventSender,
    ) -> std::io::Result<Self> {
        let name = match &source {
            ClaySource::File(path) => path.display().to_string(),
            ClaySource::New(_) => "new clay".to_owned(),
        };
        let cancel = Arc::new(AtomicBool::new(false));
        let report = LoadReporter {
            events,
            source: name.clone(),
            cancel: Arc::clone(&cancel),
        };
        let (tx, result) = bounded(1);
        std::thread::Builder::new()
            .name("dynaclay-load".into())
            .spawn(move || {
                report.progress(0.0, "starting");
                // The bridge gone means nobody wants the clay: nothing to report.
                let _ = tx.send(prepare(&source, &report));
            })?;
        Ok(Self {
            result,
            cancel,
            keep_history,
            source: name,
        })
    }

    /// The prepared clay or why it failed, once the worker is done; `None` while it runs.
    pub(super) fn try_take(&mut self) -> Option<Result<Prepared, ImportFailed>> {
        match self.result.try_recv() {
            Ok(result) => Some(result),
            Err(TryRecvError::Empty) => None,
            Err(TryRecvError::Disconnected) => Some(Err(ImportFailed::Cancelled {
                path: self.source.clone().into(),
            })),
        }
    }

    /// Whether the replaced clay's undo history is to be kept.
    pub(super) fn keep_history(&self) -> bool {
        self.keep_history
    }

    /// What is being loaded, for messages.
    pub(super) fn source(&self) -> &str {
        &self.source
    }
}

impl Drop for LoadWorker {
    fn drop(&mut self) {
        // NOTE: Relaxed: the flag carries no data; the fit reads it at its next stage.
        self.cancel.store(true, Ordering::Relaxed);
    }
}
