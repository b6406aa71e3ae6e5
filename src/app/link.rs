//! The app's only connection to the engine: commands out over a bounded crossbeam channel,
//! published state in through triple buffers, answers back over a second channel.
//!
//! Guarantee: nothing on either side ever waits for the other. The app sends with `try_send`
//! and reads with `try_recv` and [`SnapshotReader::latest`]; the engine drains commands with
//! `try_recv` between simulation steps and publishes with [`SnapshotWriter::publish_clone_of`]
//! (wait-free). The haptic and simulation loops therefore never wait on the GUI, and a GUI
//! that stops drawing costs them nothing. [`RepaintSignal::request`] may briefly take egui's
//! context lock: call it from the graphics loop or other non-real-time threads only (the app
//! polls the view at display rate anyway).

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, OnceLock};

use crossbeam::channel::{self, Receiver, Sender, TrySendError};

pub use crossbeam::channel::SendError as EventSendError;
use dynaclay_loops::{SnapshotReader, SnapshotWriter, Stamped, snapshot_channel};

use super::command::{EngineCommand, EngineEvent};
use super::meshes::MeshSet;
use super::view::EngineView;
use crate::engine::{EngineClock, MeshStamp};
use crate::field::{BSplineLattice, MultiPatchField};
use crate::particles::ParticleView;
use crate::pointset::PointSetView;

/// The particle count a new link asks for.
pub const DEFAULT_PARTICLES: usize = 2000;

/// Commands that may queue before [`EngineLink::send`] reports the engine as not keeping up.
pub const COMMAND_QUEUE_LEN: usize = 1024;

/// Wakes the app when new data arrives. Cheap to clone; does nothing until the app installs
/// its waker.
#[derive(Clone, Default)]
pub struct RepaintSignal {
    waker: Arc<OnceLock<Box<dyn Fn() + Send + Sync>>>,
}

impl RepaintSignal {
    /// Installs the function that requests a repaint (the app passes egui's
    /// `Context::request_repaint`). Only the first call takes effect.
    pub fn install(&self, waker: impl Fn() + Send + Sync + 'static) {
        let _ = self.waker.set(Box::new(waker));
    }

    /// Asks the app to draw a new frame. Not for the haptic loop (see the module docs).
    pub fn request(&self) {
        if let Some(w) = self.waker.get() {
            w();
        }
    }
}

impl std::fmt::Debug for RepaintSignal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RepaintSignal")
            .field("installed", &self.waker.get().is_some())
            .finish()
    }
}

/// The engine's sender of answers for the app's log: each answer also wakes the app, so a
/// line (an import's progress, a save's outcome) shows without waiting for other input.
/// Never blocks (the channel is unbounded); for non-real-time threads only, like
/// [`RepaintSignal::request`].
#[derive(Clone, Debug)]
pub struct EventSender {
    events: Sender<EngineEvent>,
    repaint: RepaintSignal,
}

impl EventSender {
    /// Queues `event` for the app and wakes it.
    ///
    /// # Errors
    /// The event back when the app's end is gone.
    pub fn send(&self, event: EngineEvent) -> Result<(), EventSendError<EngineEvent>> {
        let sent = self.events.send(event);
        self.repaint.request();
        sent
    }

    /// Answers the app has not taken yet.
    #[must_use]
    pub fn len(&self) -> usize {
        self.events.len()
    }

    /// Whether the app has taken every answer.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.events.is_empty()
    }
}

/// A running engine's clock and the stamps of its graphics loop's meshes (see
/// [`crate::engine::MotionToPhoton`]); each engine started behind the link sends its own.
pub struct MeshStampSource {
    /// The engine's clock: a frame's time is read on it.
    pub clock: EngineClock,
    /// The stamps, published by the graphics loop after the meshes they describe.
    pub stamps: SnapshotReader<MeshStamp>,
}

/// Why a command did not reach the engine.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SendError {
    /// The engine is not draining its queue (stalled or busy); the command was dropped.
    #[error("{command}: the engine's command queue is full ({COMMAND_QUEUE_LEN} waiting); command dropped", COMMAND_QUEUE_LEN = COMMAND_QUEUE_LEN)]
    QueueFull { command: &'static str },
    /// No engine is listening (not started, or stopped).
    #[error("{command}: no engine is running")]
    NoEngine { command: &'static str },
}

/// The app's end.
pub struct EngineLink {
    commands: Sender<EngineCommand>,
    events: Receiver<EngineEvent>,
    view: SnapshotReader<EngineView>,
    meshes: SnapshotReader<MeshSet>,
    field: SnapshotReader<MultiPatchField>,
    particles: SnapshotReader<ParticleView>,
    particle_count: Arc<AtomicUsize>,
    particles_on: Arc<AtomicBool>,
    points: SnapshotReader<PointSetView>,
    repaint: RepaintSignal,
    /// Where each new engine's stamps arrive, and the running one's.
    stamp_sources: Receiver<MeshStampSource>,
    stamp_source: Option<MeshStampSource>,
}

/// The engine's end of the particles on the clay: the view it publishes and the count and
/// switch the app sets (see [`crate::particles::ParticleFollower::with_handles`]).
pub struct ParticleEndpoint {
    pub view: SnapshotWriter<ParticleView>,
    pub count: Arc<AtomicUsize>,
    pub on: Arc<AtomicBool>,
}

/// The engine's end: drain `commands` between steps, publish `view` and `meshes`, report
/// outcomes on `events` (which wakes the app), and call `repaint.request()` after publishing
/// meshes or a view that draws differently.
pub struct EngineEndpoint {
    pub commands: Receiver<EngineCommand>,
    /// Answers for the app's log (each one wakes the app).
    pub events: EventSender,
    pub view: SnapshotWriter<EngineView>,
    pub meshes: SnapshotWriter<MeshSet>,
    /// The graphics loop's copy of the clay, for picking under the pointer.
    pub field: SnapshotWriter<MultiPatchField>,
    /// The particles shown on the clay (off until the app turns them on).
    pub particles: ParticleEndpoint,
    /// The loaded point set as it follows the clay (see [`crate::pointset::PointSetFollower`]).
    pub points: SnapshotWriter<PointSetView>,
    pub repaint: RepaintSignal,
    /// Where each engine started sends its clock and mesh stamps.
    pub mesh_stamps: Sender<MeshStampSource>,
}

/// The field shown before the engine publishes one: the smallest lattice, empty everywhere, so
/// every pick misses.
fn no_clay() -> MultiPatchField {
    MultiPatchField::from(
        BSplineLattice::zeros([4; 3], 1.0, glam::Vec3::ZERO)
            .unwrap_or_else(|e| unreachable!("a 4³ lattice with unit spacing is valid: {e}")),
    )
}

/// A connected pair (allocates the channels and the three copies of each snapshot).
#[must_use]
pub fn engine_link() -> (EngineLink, EngineEndpoint) {
    let (cmd_tx, cmd_rx) = channel::bounded(COMMAND_QUEUE_LEN);
    let (ev_tx, ev_rx) = channel::unbounded();
    let (view_tx, view_rx) = snapshot_channel(&EngineView::default());
    let (mesh_tx, mesh_rx) = snapshot_channel(&MeshSet::new());
    let (field_tx, field_rx) = snapshot_channel(&no_clay());
    let (particles_tx, particles_rx) = snapshot_channel(&ParticleView::default());
    let particle_count = Arc::new(AtomicUsize::new(DEFAULT_PARTICLES));
    let particles_on = Arc::new(AtomicBool::new(false));
    let (points_tx, points_rx) = snapshot_channel(&PointSetView::default());
    let repaint = RepaintSignal::default();
    let (stamps_tx, stamps_rx) = channel::unbounded();
    (
        EngineLink {
            commands: cmd_tx,
            events: ev_rx,
            view: view_rx,
            meshes: mesh_rx,
            field: field_rx,
            particles: particles_rx,
            particle_count: Arc::clone(&particle_count),
            particles_on: Arc::clone(&particles_on),
            points: points_rx,
            repaint: repaint.clone(),
            stamp_sources: stamps_rx,
            stamp_source: None,
        },
        EngineEndpoint {
            commands: cmd_rx,
            events: EventSender {
                events: ev_tx,
                repaint: repaint.clone(),
            },
            view: view_tx,
            meshes: mesh_tx,
            field: field_tx,
            particles: ParticleEndpoint {
                view: particles_tx,
                count: particle_count,
                on: particles_on,
            },
            points: points_tx,
            repaint,
            mesh_stamps: stamps_tx,
        },
    )
}

impl Default for EngineLink {
    /// A link with no engine behind it: every send fails with [`SendError::NoEngine`] and the
    /// view stays at its default.
    fn default() -> Self {
        let (link, endpoint) = engine_link();
        drop(endpoint);
        link
    }
}

impl EngineLink {
    /// Queues `command` without waiting.
    ///
    /// # Errors
    /// [`SendError::QueueFull`] when the engine is not keeping up, [`SendError::NoEngine`] when
    /// nothing listens; the command is dropped in both cases.
    pub fn send(&self, command: EngineCommand) -> Result<(), SendError> {
        let name = command.name();
        self.commands.try_send(command).map_err(|e| match e {
            TrySendError::Full(_) => SendError::QueueFull { command: name },
            TrySendError::Disconnected(_) => SendError::NoEngine { command: name },
        })
    }

    /// The next answer from the engine, if one is waiting.
    pub fn try_event(&self) -> Option<EngineEvent> {
        // Empty and disconnected both mean: nothing to show now.
        self.events.try_recv().ok()
    }

    /// The newest published view (wait-free).
    pub fn view(&mut self) -> &Stamped<EngineView> {
        self.view.latest()
    }

    /// The stamp of the newest meshes, with whether the engine changed since the last call
    /// (its clock and strokes start over); `None` before an engine sent its stamps.
    /// Wait-free. Fetch it before the meshes: they are then at least as new as the stamp.
    pub fn mesh_stamp(&mut self) -> Option<(MeshStamp, bool)> {
        let mut new_engine = false;
        while let Ok(source) = self.stamp_sources.try_recv() {
            self.stamp_source = Some(source);
            new_engine = true;
        }
        let source = self.stamp_source.as_mut()?;
        Some((source.stamps.latest().value, new_engine))
    }

    /// The time now on the running engine's clock (`None` before an engine sent its stamps).
    #[must_use]
    pub fn engine_now_ns(&self) -> Option<u64> {
        self.stamp_source.as_ref().map(|s| s.clock.now_ns())
    }

    /// The newest published meshes (wait-free).
    pub fn meshes(&mut self) -> &Stamped<MeshSet> {
        self.meshes.latest()
    }

    /// The newest published copy of the clay (wait-free).
    pub fn field(&mut self) -> &Stamped<MultiPatchField> {
        self.field.latest()
    }

    /// The newest published particles (wait-free; empty while they are off).
    pub fn particles(&mut self) -> &Stamped<ParticleView> {
        self.particles.latest()
    }

    /// The newest meshes, and the newest particles when they are on (both wait-free), for
    /// one frame of the 3D view.
    pub fn scene(&mut self) -> (&Stamped<MeshSet>, Option<&Stamped<ParticleView>>) {
        let on = self.particles_on();
        (self.meshes.latest(), on.then(|| self.particles.latest()))
    }

    /// Turns the particles on the clay on or off (the graphics loop picks it up at its next
    /// update; off, it drops them and stops the work).
    pub fn set_particles_on(&self, on: bool) {
        self.particles_on.store(on, Ordering::Relaxed);
    }

    /// Whether the particles are on.
    #[must_use]
    pub fn particles_on(&self) -> bool {
        self.particles_on.load(Ordering::Relaxed)
    }

    /// Asks for `count` particles (0 is ignored by the follower).
    pub fn set_particle_count(&self, count: usize) {
        self.particle_count.store(count, Ordering::Relaxed);
    }

    /// The particle count asked for.
    #[must_use]
    pub fn particle_count(&self) -> usize {
        self.particle_count.load(Ordering::Relaxed)
    }

    /// The newest published point set (wait-free; not loaded until a point cloud is).
    pub fn points(&mut self) -> &Stamped<PointSetView> {
        self.points.latest()
    }

    /// The signal the engine uses to wake the app.
    #[must_use]
    pub fn repaint_signal(&self) -> RepaintSignal {
        self.repaint.clone()
    }
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicUsize, Ordering};

    use super::*;

    #[test]
    fn commands_arrive_in_order_and_views_are_latest_only() {
        let (mut link, mut end) = engine_link();
        link.send(EngineCommand::Undo).unwrap();
        link.send(EngineCommand::Redo).unwrap();
        assert_eq!(end.commands.try_recv(), Ok(EngineCommand::Undo));
        assert_eq!(end.commands.try_recv(), Ok(EngineCommand::Redo));
        assert!(end.commands.try_recv().is_err());

        for steps in 1..=3 {
            end.view.back_mut().clone_from(&EngineView {
                undo_steps: steps,
                ..EngineView::default()
            });
            end.view.publish();
        }
        let v = link.view();
        assert_eq!((v.version, v.value.undo_steps), (3, 3));
    }

    #[test]
    fn a_full_queue_or_a_missing_engine_is_reported_not_waited_on() {
        let (link, end) = engine_link();
        for _ in 0..COMMAND_QUEUE_LEN {
            link.send(EngineCommand::StrokeStop).unwrap();
        }
        assert_eq!(
            link.send(EngineCommand::Undo),
            Err(SendError::QueueFull { command: "undo" })
        );
        drop(end);
        let err = link.send(EngineCommand::Redo).unwrap_err();
        assert_eq!(err, SendError::NoEngine { command: "redo" });
        assert!(err.to_string().contains("no engine"));
        assert!(EngineLink::default().send(EngineCommand::Undo).is_err());
    }

    #[test]
    fn each_answer_for_the_log_wakes_the_app() {
        let (link, end) = engine_link();
        let wakes = Arc::new(AtomicUsize::new(0));
        let w = Arc::clone(&wakes);
        link.repaint_signal().install(move || {
            w.fetch_add(1, Ordering::Relaxed);
        });
        for n in 0..3 {
            end.events
                .send(EngineEvent::Done {
                    what: "load".into(),
                    detail: format!("line {n}"),
                })
                .unwrap();
        }
        assert_eq!(wakes.load(Ordering::Relaxed), 3);
        assert_eq!(end.events.len(), 3);
        while link.try_event().is_some() {}
        assert!(end.events.is_empty());
    }

    #[test]
    fn repaint_signal_calls_the_installed_waker_once_installed() {
        let count = Arc::new(AtomicUsize::new(0));
        let signal = RepaintSignal::default();
        signal.request();
        let c = Arc::clone(&count);
        signal.clone().install(move || {
            c.fetch_add(1, Ordering::Relaxed);
        });
        signal.request();
        signal.request();
        assert_eq!(count.load(Ordering::Relaxed), 2);
    }
}
