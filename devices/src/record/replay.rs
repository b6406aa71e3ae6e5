//! Playing a recording back as a device, one recorded read per `read`.
//!
//! Guarantee: after loading, `read` and `write_force` allocate nothing and do O(1) work. The
//! replay is indexed by call, not by time: the n-th `read` returns the n-th recorded read
//! result and the n-th `write_force` returns the n-th recorded write result, so an engine that
//! steps its simulation in lockstep with the samples reproduces a session bit for bit. Each
//! written force is compared bit for bit with the recorded one, so divergence is measurable.

use std::path::Path;

use glam::Vec3;

use super::error::RecordError;
use super::format::{Record, Recording, ScheduleNote};
use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};

/// How far the forces written to a replay differ from the recorded ones.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ReplayDivergence {
    /// Writes compared with a recorded write.
    pub writes_compared: u64,
    /// Writes whose force was not bit-for-bit the recorded one.
    pub writes_differing: u64,
    /// Writes past the end of the recorded writes.
    pub writes_extra: u64,
    /// Largest difference between a written and the recorded force, newtons.
    pub max_difference_n: f32,
}

/// What one recorded haptic tick saw (see [`ScheduleNote::Tick`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RecordedTick {
    /// Version of the field snapshot the tick fetched, if it fetched one.
    pub snapshot_version: Option<u64>,
    /// The staleness fade it applied.
    pub fade: f32,
}

/// What one recorded simulation step took (see [`ScheduleNote::Step`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RecordedStep {
    /// Tick number of the tool sample it took (0: the idle sample before the first tick).
    pub sample_tick: u64,
    /// Commands applied since the previous step.
    pub commands: u32,
}

/// A threaded run's schedule, as its recording holds it: every haptic tick (tick `n` at index
/// `n - 1`) and every simulation step (step `n` at index `n`), in order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RecordedSchedule {
    /// The haptic ticks.
    pub ticks: Vec<RecordedTick>,
    /// The simulation steps.
    pub steps: Vec<RecordedStep>,
}

/// Why a recording's schedule cannot drive an exact replay.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ScheduleGap {
    /// The recording holds no schedule (a lockstep run, the GUI, or a version-1 file).
    #[error("the recording holds no schedule of the engine's loops")]
    Absent,
    /// The recorder dropped records, so ticks or steps are missing.
    #[error("the recorder dropped {0} record(s), so the schedule is incomplete")]
    Dropped(u64),
    /// Tick or step numbers do not follow each other.
    #[error(
        "record {record}: {what} {found} follows {expected_before} (the schedule is out of order)"
    )]
    OutOfOrder {
        /// "tick" or "step".
        what: &'static str,
        /// The number found.
        found: u64,
        /// The number before it.
        expected_before: u64,
        /// The record (0-based, in file order).
        record: usize,
    },
    /// A simulation step took the sample of a tick the schedule does not hold, or of an
    /// earlier tick than the step before it.
    #[error(
        "record {record}: simulation step {step} took the sample of haptic tick {sample_tick}, but {why}"
    )]
    BadSample {
        /// The step.
        step: u64,
        /// The tick it names.
        sample_tick: u64,
        /// What is wrong with it.
        why: SampleProblem,
        /// The record (0-based, in file order).
        record: usize,
    },
    /// The schedule holds fewer (or more) ticks than the recording holds device reads: part of
    /// it is missing, and a replay would stop short or run past the reads.
    #[error(
        "the schedule holds {ticks} haptic ticks for {reads} device reads (one tick per read; the last read may lack its tick), so part of it is missing"
    )]
    Incomplete {
        /// Ticks in the schedule.
        ticks: u64,
        /// Reads in the recording.
        reads: u64,
    },
}

/// What is wrong with the tick a recorded step names.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SampleProblem {
    /// The schedule holds fewer ticks.
    #[error("the schedule holds {ticks} ticks")]
    PastTheEnd {
        /// Ticks in the schedule.
        ticks: u64,
    },
    /// The step before took a later tick's sample (samples only move forward).
    #[error("the step before took tick {before}")]
    Backwards {
        /// The tick the step before took.
        before: u64,
    },
}

/// A recorded session played back as a [`HapticDevice`].
#[derive(Clone, Debug)]
pub struct ReplayDevice {
    info: DeviceInfo,
    reads: Vec<Result<DeviceState, DeviceError>>,
    writes: Vec<(Vec3, Result<(), DeviceError>)>,
    schedule: Result<RecordedSchedule, ScheduleGap>,
    dropped: u64,
    open: bool,
    next_read: usize,
    next_write: usize,
    divergence: ReplayDivergence,
}

/// The largest recording read, bytes: 16 M records of 64 bytes, over two hours of a 1 kHz
/// loop. Only a regular file is read (a FIFO or `/dev/zero` is refused at once).
pub const MAX_RECORDING_BYTES: u64 = 1 << 30;

impl ReplayDevice {
    /// Loads the recording at `path` (a regular file of at most [`MAX_RECORDING_BYTES`]).
    ///
    /// # Errors
    /// [`RecordError::Io`] if the file cannot be read; otherwise a format error wrapped in
    /// [`RecordError::InFile`] naming the path, byte offset and block.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, RecordError> {
        let path = path.as_ref();
        let bytes = dynaclay_files::read_regular_file(path, MAX_RECORDING_BYTES).map_err(|e| {
            RecordError::Io {
                path: path.to_path_buf(),
                action: "read recording",
                source: e.into_io(),
            }
        })?;
        let recording = Recording::parse(&bytes).map_err(|error| RecordError::InFile {
            path: path.to_path_buf(),
            error: Box::new(error),
        })?;
        Ok(Self::from_recording(recording))
    }

    /// A replay of an already decoded recording.
    #[must_use]
    pub fn from_recording(recording: Recording) -> Self {
        let mut reads = Vec::new();
        let mut writes = Vec::new();
        let mut schedule = RecordedSchedule::default();
        let mut order: Result<(), ScheduleGap> = Ok(());
        // The record of the last step note, to name it when its tick is past the end.
        let mut last_step_record = 0;
        for (index, record) in recording.records.into_iter().enumerate() {
            match record {
                Record::Read(result) => reads.push(result),
                Record::Write { force_n, result } => writes.push((force_n, result)),
                Record::Schedule(ScheduleNote::Tick {
                    tick,
                    snapshot_version,
                    fade,
                }) => {
                    let before = schedule.ticks.len() as u64;
                    if order.is_ok() && tick != before + 1 {
                        order = Err(ScheduleGap::OutOfOrder {
                            what: "tick",
                            found: tick,
                            expected_before: before,
                            record: index,
                        });
                    }
                    schedule.ticks.push(RecordedTick {
                        snapshot_version,
                        fade,
                    });
                }
                Record::Schedule(ScheduleNote::Step {
                    step,
                    sample_tick,
                    commands,
                }) => {
                    let at = schedule.steps.len() as u64;
                    if order.is_ok() && step != at {
                        order = Err(ScheduleGap::OutOfOrder {
                            what: "step",
                            found: step,
                            expected_before: at.wrapping_sub(1),
                            record: index,
                        });
                    }
                    if let Some(before) = schedule.steps.last().map(|s| s.sample_tick)
                        && order.is_ok()
                        && sample_tick < before
                    {
                        order = Err(ScheduleGap::BadSample {
                            step,
                            sample_tick,
                            why: SampleProblem::Backwards { before },
                            record: index,
                        });
                    }
                    last_step_record = index;
                    schedule.steps.push(RecordedStep {
                        sample_tick,
                        commands,
                    });
                }
            }
        }
        let ticks = schedule.ticks.len() as u64;
        // Checked whole before any of it is replayed: every step's tick is in the schedule
        // (ticks are in order, so the last step's is the largest), and there is a tick for
        // every read.
        if order.is_ok()
            && let Some(last) = schedule.steps.last()
            && last.sample_tick > ticks
        {
            order = Err(ScheduleGap::BadSample {
                step: schedule.steps.len() as u64 - 1,
                sample_tick: last.sample_tick,
                why: SampleProblem::PastTheEnd { ticks },
                record: last_step_record,
            });
        }
        let reads_count = reads.len() as u64;
        if order.is_ok() && !(ticks == reads_count || ticks + 1 == reads_count) {
            order = Err(ScheduleGap::Incomplete {
                ticks,
                reads: reads_count,
            });
        }
        let schedule = if schedule.ticks.is_empty() && schedule.steps.is_empty() {
            Err(ScheduleGap::Absent)
        } else if recording.dropped > 0 {
            Err(ScheduleGap::Dropped(recording.dropped))
        } else {
            order.map(|()| schedule)
        };
        Self {
            info: recording.info,
            reads,
            writes,
            schedule,
            dropped: recording.dropped,
            open: false,
            next_read: 0,
            next_write: 0,
            divergence: ReplayDivergence::default(),
        }
    }

    /// The engine's schedule recorded beside the device's calls by a threaded run, or why
    /// there is none usable (then a replay reproduces the session only where it ran in
    /// lockstep).
    ///
    /// # Errors
    /// The [`ScheduleGap`] that keeps the schedule from driving an exact replay.
    pub fn schedule(&self) -> Result<&RecordedSchedule, ScheduleGap> {
        self.schedule.as_ref().map_err(|gap| *gap)
    }

    /// Recorded reads (successful or not).
    #[must_use]
    pub fn read_count(&self) -> usize {
        self.reads.len()
    }

    /// Reads not yet replayed.
    #[must_use]
    pub fn reads_remaining(&self) -> usize {
        self.reads.len() - self.next_read
    }

    /// The recorded forces and write results, in order.
    pub fn recorded_writes(&self) -> &[(Vec3, Result<(), DeviceError>)] {
        &self.writes
    }

    /// Records the recorder dropped (a replay with drops is not a faithful copy).
    #[must_use]
    pub fn dropped_while_recording(&self) -> u64 {
        self.dropped
    }

    /// How the forces written so far compare with the recorded ones.
    #[must_use]
    pub fn divergence(&self) -> ReplayDivergence {
        self.divergence
    }

    /// Starts the replay over from the first record.
    pub fn rewind(&mut self) {
        self.next_read = 0;
        self.next_write = 0;
        self.divergence = ReplayDivergence::default();
    }
}

impl HapticDevice for ReplayDevice {
    /// The recorded device's info, unchanged, so limits (and the safety filter) match.
    fn info(&self) -> DeviceInfo {
        self.info.clone()
    }

    /// Opens the replay. Opening does not rewind (a reconnect during a replayed session
    /// continues where it was); use [`ReplayDevice::rewind`].
    fn open(&mut self) -> Result<(), DeviceError> {
        self.open = true;
        Ok(())
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        self.open = false;
        Ok(())
    }

    fn is_open(&self) -> bool {
        self.open
    }

    /// The next recorded read result.
    ///
    /// # Errors
    /// The recorded error, [`DeviceError::NotOpen`], or [`DeviceError::EndOfRecording`] once
    /// every recorded read has been returned.
    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        if !self.open {
            return Err(DeviceError::NotOpen);
        }
        match self.reads.get(self.next_read) {
            Some(result) => {
                self.next_read += 1;
                result.clone()
            }
            None => Err(DeviceError::EndOfRecording {
                samples: self.reads.len() as u64,
            }),
        }
    }

    /// Compares `force_n` with the next recorded force and returns the recorded result
    /// (`Ok` past the end of the recorded writes).
    ///
    /// # Errors
    /// The recorded error, or [`DeviceError::NotOpen`].
    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        if !self.open {
            return Err(DeviceError::NotOpen);
        }
        let Some((recorded_n, result)) = self.writes.get(self.next_write) else {
            self.divergence.writes_extra += 1;
            return Ok(());
        };
        self.next_write += 1;
        let d = &mut self.divergence;
        d.writes_compared += 1;
        let same_bits = force_n
            .to_array()
            .iter()
            .zip(recorded_n.to_array())
            .all(|(a, b)| a.to_bits() == b.to_bits());
        if !same_bits {
            d.writes_differing += 1;
            let diff = (force_n - *recorded_n).length();
            // A NaN difference counts as infinitely far.
            d.max_difference_n = if diff.is_nan() {
                f32::INFINITY
            } else {
                d.max_difference_n.max(diff)
            };
        }
        result.clone()
    }
}
