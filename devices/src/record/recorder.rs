//! Recording a device session to a file without blocking the haptic loop.
//!
//! Guarantee: on the haptic thread, [`RecordingDevice::read`] and
//! [`RecordingDevice::write_force`] add one fixed-size encode and one lock-free push into a
//! bounded queue (crossbeam's `ArrayQueue`) to the wrapped device's call: no allocation, no lock,
//! no I/O. A writer thread drains the queue into checksummed blocks. If the writer falls
//! behind and the queue is full, the record is dropped and counted, never waited for; the
//! count is stored in the file's end marker. The writer thread owns and frees the file.
//!
//! The file appears at its path only when it is complete: the writer fills a temporary file
//! beside it ([`dynaclay_files::AtomicFile`]) and renames it into place after the end marker
//! is written and synced. A write that fails (a full disk) leaves whatever was at the path
//! before, and the error is reported by [`RecordingDevice::finish`] and by `close`.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use crossbeam::queue::ArrayQueue;
use glam::Vec3;

use super::error::RecordError;
use super::format::{
    BlockWriter, RECORD_SIZE, ScheduleNote, WriteSummary, encode_read, encode_schedule,
    encode_write,
};
use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};
use dynaclay_files::{AtomicFile, WriteError};

/// Settings of a [`RecordingDevice`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RecorderConfig {
    /// Queue capacity between the haptic thread and the writer, records (two per tick at
    /// 1 kHz, about four with the engine's schedule notes, so the default, 4 MiB, holds some
    /// sixteen seconds of a writer thread that gets no CPU).
    pub queue_capacity: usize,
    /// Records per checksummed block.
    pub records_per_block: u32,
    /// Longest time a partly filled block waits before it is written, milliseconds.
    pub flush_interval_ms: u64,
}

impl Default for RecorderConfig {
    fn default() -> Self {
        Self {
            queue_capacity: 65536,
            records_per_block: 256,
            flush_interval_ms: 100,
        }
    }
}

/// State shared between the haptic side and the writer thread.
struct Shared {
    queue: ArrayQueue<[u8; RECORD_SIZE]>,
    dropped: AtomicU64,
    stop: AtomicBool,
    writer_failed: AtomicBool,
}

/// Wraps a device and records every `read` and `write_force` (arguments and results) to a
/// file; otherwise behaves exactly like the wrapped device.
///
/// The header (with the device's info) is written when the device is first opened, so
/// drivers that learn their limits during `open` record the right ones. Call
/// [`RecordingDevice::finish`] to close the file cleanly and learn its totals; dropping the
/// recorder also finishes the file, ignoring errors.
pub struct RecordingDevice<D: HapticDevice> {
    device: D,
    recorder: Recorder,
}

/// The file side of a [`RecordingDevice`]; finishing the file on drop lives here so the
/// device can be moved out.
struct Recorder {
    path: PathBuf,
    config: RecorderConfig,
    /// The temporary file until the writer thread takes it at the first `open`.
    file: Option<AtomicFile>,
    shared: Arc<Shared>,
    writer: Option<JoinHandle<Result<WriteSummary, RecordError>>>,
    reads: u64,
    last_timestamp_us: u64,
}

impl<D: HapticDevice> RecordingDevice<D> {
    /// Wraps `device` and starts the recording for `path` (a temporary file beside it, renamed
    /// over `path` when the recording is finished whole).
    ///
    /// # Errors
    /// [`RecordError::Io`] if the file cannot be created, or `path` is a link, a device, a FIFO
    /// or a directory (never written through or replaced).
    pub fn create(device: D, path: impl AsRef<Path>) -> Result<Self, RecordError> {
        Self::with_config(device, path, RecorderConfig::default())
    }

    /// As [`RecordingDevice::create`], with `config`.
    ///
    /// # Errors
    /// [`RecordError::Io`] if the file cannot be created.
    pub fn with_config(
        device: D,
        path: impl AsRef<Path>,
        config: RecorderConfig,
    ) -> Result<Self, RecordError> {
        let path = path.as_ref().to_path_buf();
        let file = AtomicFile::create(&path).map_err(|e| write_error(e, "create recording"))?;
        Ok(Self {
            device,
            recorder: Recorder {
                path,
                config,
                file: Some(file),
                shared: Arc::new(Shared {
                    queue: ArrayQueue::new(config.queue_capacity.max(1)),
                    dropped: AtomicU64::new(0),
                    stop: AtomicBool::new(false),
                    writer_failed: AtomicBool::new(false),
                }),
                writer: None,
                reads: 0,
                last_timestamp_us: 0,
            },
        })
    }

    /// The wrapped device.
    #[must_use]
    pub fn device(&self) -> &D {
        &self.device
    }

    /// The recording's path.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.recorder.path
    }

    /// A handle through which the engine notes its schedule (see [`ScheduleNote`]) into this
    /// recording, from any thread, beside the device's calls.
    #[must_use]
    pub fn schedule_log(&self) -> ScheduleLog {
        ScheduleLog {
            shared: Arc::clone(&self.recorder.shared),
        }
    }

    /// Records dropped so far because the queue was full.
    #[must_use]
    pub fn dropped(&self) -> u64 {
        self.recorder.shared.dropped.load(Ordering::Relaxed)
    }

    /// Whether the writer thread has hit an I/O error (later records are dropped;
    /// [`RecordingDevice::finish`] returns the error).
    #[must_use]
    pub fn writer_failed(&self) -> bool {
        self.recorder.shared.writer_failed.load(Ordering::Relaxed)
    }

    /// Stops the writer after it has drained the queue, writes the end marker and syncs the
    /// file, and returns the device (open or closed as it was) with the file's totals.
    ///
    /// # Errors
    /// The writer's I/O error, if it had one (the file is then incomplete and will not load).
    pub fn finish(mut self) -> Result<(D, WriteSummary), RecordError> {
        if self.recorder.file.is_some() {
            // Never opened: still leave a valid, empty recording.
            let info = self.device.info();
            self.recorder
                .start_writer(&info)
                .map_err(|e| RecordError::Io {
                    path: self.recorder.path.clone(),
                    action: "write",
                    source: std::io::Error::other(e.to_string()),
                })?;
        }
        let summary = self.recorder.stop_writer()?;
        Ok((self.device, summary))
    }
}

/// Where the engine notes its schedule into a recording (see
/// [`RecordingDevice::schedule_log`]).
///
/// Guarantee: [`ScheduleLog::note`] is one fixed-size encode and one lock-free push into the
/// recorder's bounded queue: no allocation, no lock, no I/O, so the haptic and simulation
/// threads call it every tick and step. A full queue drops the note and counts it, as for
/// the device's own records. Notes pushed after the recording was finished go nowhere.
#[derive(Clone)]
pub struct ScheduleLog {
    shared: Arc<Shared>,
}

impl ScheduleLog {
    /// Queues `note` for the recording.
    pub fn note(&self, note: &ScheduleNote) {
        self.shared.push(encode_schedule(note));
    }
}

impl std::fmt::Debug for ScheduleLog {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ScheduleLog").finish_non_exhaustive()
    }
}

impl Shared {
    /// Queues one encoded record; a full queue drops it (counted), never waits.
    fn push(&self, raw: [u8; RECORD_SIZE]) {
        if self.queue.push(raw).is_err() {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }
}

impl Recorder {
    /// Queues one encoded record; a full queue drops it (counted), never waits.
    fn push(&self, raw: [u8; RECORD_SIZE]) {
        self.shared.push(raw);
    }

    fn start_writer(&mut self, info: &DeviceInfo) -> Result<(), DeviceError> {
        let Some(file) = self.file.take() else {
            return Ok(());
        };
        let writer = BlockWriter::new(file, info, self.config.records_per_block)
            .map_err(|e| DeviceError::io(&e, "write recording header"))?;
        let shared = Arc::clone(&self.shared);
        let path = self.path.clone();
        let flush = Duration::from_millis(self.config.flush_interval_ms);
        let handle = thread::Builder::new()
            .name("dynaclay-recorder".to_owned())
            .spawn(move || writer_loop(writer, &shared, &path, flush))
            .map_err(|e| DeviceError::io(&e, "start recording thread"))?;
        self.writer = Some(handle);
        Ok(())
    }

    fn stop_writer(&mut self) -> Result<WriteSummary, RecordError> {
        // Must be Release: pairs with the writer's Acquire load so every record pushed before
        // this store is visible to the writer's final drain.
        self.shared.stop.store(true, Ordering::Release);
        match self.writer.take() {
            Some(handle) => handle.join().unwrap_or_else(|_| {
                Err(RecordError::Io {
                    path: self.path.clone(),
                    action: "finish",
                    source: std::io::Error::other("recording thread panicked"),
                })
            }),
            None => Ok(WriteSummary::default()),
        }
    }
}

/// A failed step of the atomic writer as a [`RecordError::Io`] (`action` names the step when
/// the writer was refused before it did any I/O).
fn write_error(e: WriteError, action: &'static str) -> RecordError {
    let path = e.path().to_path_buf();
    let action = match &e {
        WriteError::Io { op, .. } => op,
        WriteError::NotRegular { .. } => action,
    };
    RecordError::Io {
        path,
        action,
        source: e.into_io(),
    }
}

fn writer_loop(
    mut writer: BlockWriter<AtomicFile>,
    shared: &Shared,
    path: &Path,
    flush_interval: Duration,
) -> Result<WriteSummary, RecordError> {
    let io_err = |action: &'static str| {
        let path = path.to_path_buf();
        move |source| RecordError::Io {
            path,
            action,
            source,
        }
    };
    let fail = |e: RecordError| {
        shared.writer_failed.store(true, Ordering::Relaxed);
        e
    };
    let mut last_flush = Instant::now();
    loop {
        // Acquire: see the Release store in `stop_writer` (and every push before it).
        let stopping = shared.stop.load(Ordering::Acquire);
        let mut wrote = false;
        while let Some(raw) = shared.queue.pop() {
            writer
                .push(&raw)
                .map_err(io_err("write recording"))
                .map_err(fail)?;
            wrote = true;
        }
        if stopping {
            break;
        }
        if last_flush.elapsed() >= flush_interval {
            writer
                .flush_block()
                .map_err(io_err("write recording"))
                .map_err(fail)?;
            last_flush = Instant::now();
        }
        if !wrote {
            thread::sleep(Duration::from_millis(1));
        }
    }
    let dropped = shared.dropped.load(Ordering::Relaxed);
    let (out, summary) = writer
        .finish(dropped)
        .map_err(io_err("finish recording"))
        .map_err(fail)?;
    out.commit()
        .map_err(|e| write_error(e, "finish recording"))
        .map_err(fail)?;
    Ok(summary)
}

impl Drop for Recorder {
    fn drop(&mut self) {
        // A recorder dropped without `finish` still ends its file properly; errors have
        // nowhere to go here.
        let _ = self.stop_writer();
    }
}

impl<D: HapticDevice> HapticDevice for RecordingDevice<D> {
    fn info(&self) -> DeviceInfo {
        self.device.info()
    }

    /// Opens the device; the first successful open writes the header and starts the writer.
    fn open(&mut self) -> Result<(), DeviceError> {
        self.device.open()?;
        if self.recorder.file.is_some() {
            let info = self.device.info();
            self.recorder.start_writer(&info)?;
        }
        Ok(())
    }

    /// Closes the device, then ends the recording (drains the queue, writes the end marker,
    /// syncs the file). A recording that could not be written whole (a full disk, a lost
    /// mount) is reported as the close's I/O error, so the caller learns the file is
    /// incomplete; the device's own close error comes first.
    fn close(&mut self) -> Result<(), DeviceError> {
        let closed = self.device.close();
        let recorded = self.recorder.stop_writer();
        closed?;
        recorded.map(|_| ()).map_err(|e| {
            let (kind, os_code) = match &e {
                RecordError::Io { source, .. } => (source.kind(), source.raw_os_error()),
                _ => (std::io::ErrorKind::Other, None),
            };
            DeviceError::Io {
                kind,
                os_code,
                context: "write the recording (the file is incomplete)",
            }
        })
    }

    fn is_open(&self) -> bool {
        self.device.is_open()
    }

    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        let result = self.device.read();
        let r = &mut self.recorder;
        r.reads += 1;
        if let Ok(s) = &result {
            r.last_timestamp_us = s.timestamp_us;
        }
        r.push(encode_read(&result, r.reads));
        result
    }

    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        let result = self.device.write_force(force_n);
        let r = &self.recorder;
        r.push(encode_write(force_n, &result, r.reads, r.last_timestamp_us));
        result
    }
}
