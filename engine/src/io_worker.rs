//! The engine's file I/O, off every loop: writes the saves the simulation thread hands over
//! and runs autosave. When autosave is due it asks the simulation for a copy of the session
//! (a [`Command::Snapshot`], answered between two simulation steps) and writes the recovery
//! file itself, so neither the haptic nor the simulation loop ever waits on a disk.
//!
//! The threaded engine runs [`IoWorker::run`] on its own thread; the lockstep driver calls
//! [`IoWorker::poll`] between samples.

use std::time::{Duration, Instant};

use crossbeam::channel::{Receiver, RecvTimeoutError, Sender, TryRecvError, bounded};

use super::command::Command;
use super::error::SaveError;
use super::simulation::IoJob;
use dynaclay_core::io::{Autosave, Session, save_session};

/// What the I/O worker did over a run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct IoReport {
    /// Saves written on request.
    pub saves: u32,
    /// Recovery files written by autosave.
    pub autosaves: u32,
    /// Every failed write, with its path.
    pub errors: Vec<String>,
}

/// The I/O worker's state.
pub struct IoWorker {
    jobs: Receiver<IoJob>,
    commands: Sender<Command>,
    autosave: Option<Autosave>,
    snapshot: Option<Receiver<Session>>,
    report: IoReport,
}

impl IoWorker {
    /// A worker serving `jobs`; `commands` reaches the simulation (for autosave snapshots).
    #[must_use]
    pub fn new(jobs: Receiver<IoJob>, commands: Sender<Command>) -> Self {
        Self {
            jobs,
            commands,
            autosave: None,
            snapshot: None,
            report: IoReport::default(),
        }
    }

    /// Autosaves with `autosave` from now on.
    pub fn set_autosave(&mut self, autosave: Autosave) {
        self.autosave = Some(autosave);
    }

    /// Handles every queued job and advances autosave, without waiting. Returns `false` once
    /// the simulation has gone (its end of the job channel dropped) and nothing is queued.
    pub fn poll(&mut self, now: Instant) -> bool {
        let alive = loop {
            match self.jobs.try_recv() {
                Ok(job) => self.handle(job),
                Err(TryRecvError::Empty) => break true,
                Err(TryRecvError::Disconnected) => break false,
            }
        };
        self.autosave_step(now);
        alive
    }

    /// Serves jobs until the simulation is gone (the I/O thread's body); autosave is checked
    /// at least every `tick`.
    #[must_use]
    pub fn run(mut self, tick: Duration) -> IoReport {
        loop {
            dynaclay_loops::assert_not_in_tick("IoWorker::run waiting for jobs");
            match self.jobs.recv_timeout(tick) {
                Ok(job) => self.handle(job),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
            self.autosave_step(Instant::now());
        }
        self.report
    }

    /// What was done so far.
    #[must_use]
    pub fn report(&self) -> &IoReport {
        &self.report
    }

    fn handle(&mut self, job: IoJob) {
        match job {
            IoJob::Save(job) => {
                let result = dynaclay_core::io::check_replaceable(&job.path)
                    .map_err(SaveError::from)
                    .and_then(|()| Ok(save_session(&job.path, &job.session)?))
                    .map(|()| job.path.clone());
                match &result {
                    Ok(path) => {
                        self.report.saves += 1;
                        if job.as_session
                            && let Some(a) = self.autosave.as_mut()
                        {
                            a.follow(path);
                        }
                    }
                    Err(e) => self.report.errors.push(e.to_string()),
                }
                if let Some(reply) = job.reply {
                    let _ = reply.send(result);
                }
            }
            IoJob::Committed => {
                if let Some(a) = self.autosave.as_mut() {
                    a.note_stroke();
                }
            }
            IoJob::Follow(path) => {
                if let Some(a) = self.autosave.as_mut() {
                    a.follow(&path);
                }
            }
            #[cfg(feature = "fault-injection")]
            IoJob::InjectPanic => panic!("injected: the I/O worker panics"),
        }
    }

    fn autosave_step(&mut self, now: Instant) {
        let Some(autosave) = self.autosave.as_mut() else {
            return;
        };
        if let Some(rx) = &self.snapshot {
            match rx.try_recv() {
                Ok(session) => {
                    self.snapshot = None;
                    match autosave.save_if_due(&session, now) {
                        Ok(true) => self.report.autosaves += 1,
                        Ok(false) => {}
                        Err(e) => self.report.errors.push(e.to_string()),
                    }
                }
                Err(TryRecvError::Empty) => {}
                Err(TryRecvError::Disconnected) => self.snapshot = None,
            }
        } else if autosave.is_due(now) {
            let (tx, rx) = bounded(1);
            if self.commands.send(Command::Snapshot { reply: tx }).is_ok() {
                self.snapshot = Some(rx);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::SaveJob;
    use dynaclay_core::io::{AutosavePolicy, load_session, recovery_path_for};

    #[test]
    fn a_followed_session_gets_the_recovery_file() {
        let dir = tempfile::tempdir().unwrap();
        let (job_tx, job_rx) = crossbeam::channel::unbounded();
        let (cmd_tx, cmd_rx) = crossbeam::channel::unbounded();
        let mut worker = IoWorker::new(job_rx, cmd_tx);
        let policy = AutosavePolicy {
            every_s: 0.0,
            every_strokes: 1,
        };
        let first = dir.path().join("first.dclay");
        worker.set_autosave(Autosave::new(&first, policy, Instant::now()));
        let loaded = dir.path().join("loaded.dclay");
        job_tx.send(IoJob::Follow(loaded.clone())).unwrap();
        job_tx.send(IoJob::Committed).unwrap();
        assert!(worker.poll(Instant::now()));
        let Ok(Command::Snapshot { reply }) = cmd_rx.try_recv() else {
            panic!("no snapshot asked for");
        };
        reply.send(Session::default()).unwrap();
        assert!(worker.poll(Instant::now()));
        assert_eq!(worker.report().autosaves, 1);
        assert!(recovery_path_for(&loaded).exists());
        assert!(!recovery_path_for(&first).exists());
    }

    #[test]
    fn saves_are_written_and_autosave_asks_the_simulation_for_a_copy_beside_the_last_save() {
        let dir = tempfile::tempdir().unwrap();
        let (job_tx, job_rx) = crossbeam::channel::unbounded();
        let (cmd_tx, cmd_rx) = crossbeam::channel::unbounded();
        let mut worker = IoWorker::new(job_rx, cmd_tx);
        let session_path = dir.path().join("s.dclay");
        let policy = AutosavePolicy {
            every_s: 0.0,
            every_strokes: 2,
        };
        worker.set_autosave(Autosave::new(&session_path, policy, Instant::now()));

        let (reply_tx, reply_rx) = bounded(1);
        job_tx
            .send(IoJob::Save(Box::new(SaveJob {
                path: dir.path().join("explicit.dclay"),
                as_session: true,
                session: Session::default(),
                reply: Some(reply_tx),
            })))
            .unwrap();
        job_tx.send(IoJob::Committed).unwrap();
        assert!(worker.poll(Instant::now()));
        assert!(reply_rx.try_recv().unwrap().is_ok());
        assert!(cmd_rx.try_recv().is_err(), "one stroke is not enough");

        job_tx.send(IoJob::Committed).unwrap();
        assert!(worker.poll(Instant::now()));
        // The worker asked for a snapshot; answer as the simulation would.
        let Ok(Command::Snapshot { reply }) = cmd_rx.try_recv() else {
            panic!("no snapshot asked for");
        };
        reply.send(Session::default()).unwrap();
        drop(job_tx);
        assert!(!worker.poll(Instant::now()));
        assert_eq!(worker.report().autosaves, 1);
        assert_eq!(worker.report().saves, 1);
        // The explicit save made `explicit.dclay` the session: its recovery file is written,
        // none beside the session the autosave started with.
        let recovery = recovery_path_for(&dir.path().join("explicit.dclay"));
        assert_eq!(load_session(&recovery).unwrap(), Session::default());
        assert!(!recovery_path_for(&session_path).exists());
    }
}
