//! The recording file format: a pure codec over byte slices, no I/O.
//!
//! Guarantee: [`Recording::parse`] never panics on any input; it accepts exactly the files
//! [`BlockWriter`] produces and names the byte offset (and block) of the first fault otherwise.
//! [`encode_record`] is allocation-free, so the recorder runs it on the haptic thread.
//!
//! Layout, all integers little-endian (version 2; version 1 files, which hold no schedule
//! records, are read as well):
//!
//! ```text
//! header   magic "DCLYREC\x1a" (8) | version u16 | info_len u32 | info (info_len)
//!          | crc32 u32 over version..info
//! info     name_len u16 | name UTF-8 | dof u8 | flags u8 (1 = orientation, 2 = force)
//!          | button_count u8 | 0u8 | max_force_n f32 | max_stiffness_n_per_m f32
//!          | max_damping_n_s_per_m f32 | sample_rate_hz f32 | workspace_min_m 3×f32
//!          | workspace_max_m 3×f32
//! block*   "DCBK" | block_index u32 (0, 1, 2, …) | record_count u32 | payload_len u32
//!          | crc32 u32 over block_index..payload | payload (record_count × 64 bytes)
//! end      "DCEN" | block_count u32 | record_count u64 | dropped u64 | crc32 u32 over the
//!          20 bytes before it; nothing may follow
//! record   kind u8 (1 read ok, 2 read error, 3 write ok, 4 write error) | flags u8
//!          (1 = orientation present, 2 = OS error code present) | error_code u16
//!          | buttons u32 (or OS or vendor error code) | timestamp_us u64 (or error detail;
//!          for a vendor-library error (code 11) the library: 0 OpenHaptics, 1 DHD, 2 other)
//!          | sequence u64 | vec3 A (position or force, 3×f32) | vec3 B (velocity, 3×f32)
//!          | quat (x, y, z, w as f32)
//! tick     kind u8 = 5 | flags u8 (1 = a field snapshot was fetched) | 0u16 | fade f32
//!          | snapshot version u64 | tick u64 | zeros (40)
//! step     kind u8 = 6 | 0u8 | 0u16 | commands applied before the step u32
//!          | sample tick u64 | step u64 | zeros (40)
//! ```
//!
//! Tick and step records are the engine's schedule (see [`ScheduleNote`]): which field
//! snapshot each haptic tick saw and how faded, and which tool sample and how many commands
//! each simulation step took. They let a replay reproduce a threaded session bit for bit.
//!
//! Floats are stored as their exact bits, so a round trip is bit for bit.

use std::io::{self, Write};

use dynaclay_files::ByteCursor;
use glam::{Quat, Vec3};

use super::error::RecordError;
use crate::device::{DeviceError, DeviceInfo, DeviceState};

/// First eight bytes of every recording.
pub const MAGIC: [u8; 8] = *b"DCLYREC\x1a";
/// The format version this build writes and reads.
pub const FORMAT_VERSION: u16 = 2;
/// The oldest format version this build reads.
pub const OLDEST_READ_VERSION: u16 = 1;
/// Size of one encoded record, bytes.
pub const RECORD_SIZE: usize = 64;
const BLOCK_MAGIC: [u8; 4] = *b"DCBK";
const END_MAGIC: [u8; 4] = *b"DCEN";
const BLOCK_HEADER_SIZE: usize = 20;
const END_SIZE: usize = 28;
/// Largest block the parser accepts, records (bounds memory on hostile input).
pub const MAX_RECORDS_PER_BLOCK: u32 = 1 << 16;

const KIND_READ: u8 = 1;
const KIND_READ_ERROR: u8 = 2;
const KIND_WRITE: u8 = 3;
const KIND_WRITE_ERROR: u8 = 4;
const KIND_TICK: u8 = 5;
const KIND_STEP: u8 = 6;
const FLAG_FETCHED: u8 = 1;
const FLAG_ORIENTATION: u8 = 1;
const FLAG_OS_CODE: u8 = 2;

/// One event of a device session, in the order it happened.
#[derive(Clone, Debug, PartialEq)]
pub enum Record {
    /// A call to `read` and what it returned.
    Read(Result<DeviceState, DeviceError>),
    /// A call to `write_force`: the force passed in and what the device returned.
    Write {
        /// Force passed to the device, newtons.
        force_n: Vec3,
        /// The device's answer.
        result: Result<(), DeviceError>,
    },
    /// A note of the engine's schedule, recorded beside the device calls.
    Schedule(ScheduleNote),
}

/// What the engine's outcome depended on besides the device: recorded by a threaded run so
/// that a replay can interleave its loops exactly as they ran.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ScheduleNote {
    /// One haptic tick.
    Tick {
        /// The haptic stage's tick number (1, 2, …).
        tick: u64,
        /// Version of the field snapshot the tick fetched (`None`: it fetched none, as on a
        /// failed read).
        snapshot_version: Option<u64>,
        /// The staleness fade the tick applied to its forces (0 to 1).
        fade: f32,
    },
    /// One simulation step.
    Step {
        /// The simulation's step number (0, 1, …).
        step: u64,
        /// Tick number of the tool sample the step took (0: the idle sample before any tick).
        sample_tick: u64,
        /// Commands applied since the previous step, in arrival order.
        commands: u32,
    },
}

/// A whole recording, decoded.
#[derive(Clone, Debug, PartialEq)]
pub struct Recording {
    /// The recorded device's description.
    pub info: DeviceInfo,
    /// Every read and write, in order.
    pub records: Vec<Record>,
    /// Records the recorder had to drop because its writer fell behind (0 for a complete
    /// recording; a replay of a recording with drops is not a faithful copy of the session).
    pub dropped: u64,
}

// ---------------------------------------------------------------------------------------
// Errors as codes.

const IO_KINDS: [io::ErrorKind; 13] = [
    io::ErrorKind::Other,
    io::ErrorKind::NotFound,
    io::ErrorKind::PermissionDenied,
    io::ErrorKind::ConnectionReset,
    io::ErrorKind::BrokenPipe,
    io::ErrorKind::TimedOut,
    io::ErrorKind::UnexpectedEof,
    io::ErrorKind::Interrupted,
    io::ErrorKind::WouldBlock,
    io::ErrorKind::InvalidData,
    io::ErrorKind::InvalidInput,
    io::ErrorKind::NotConnected,
    io::ErrorKind::ConnectionAborted,
];

/// `what` of a replayed protocol error (the original text is not stored).
pub const REPLAYED_PROTOCOL_ERROR: &str = "protocol error (replayed)";
/// `context` of a replayed I/O error.
pub const REPLAYED_IO_CONTEXT: &str = "device I/O (replayed)";
/// `what` of a replayed `Unsupported` error.
pub const REPLAYED_UNSUPPORTED: &str = "an operation (replayed)";
/// `library` of a replayed `Vendor` error, by its stored index; the last stands for any other.
pub const REPLAYED_VENDOR_LIBRARIES: [&str; 3] =
    ["OpenHaptics HD", "Force Dimension DHD", "a vendor library"];
/// `context` of a replayed `Vendor` error.
pub const REPLAYED_VENDOR_CONTEXT: &str = "a device call (replayed)";

/// (code, flags, extra u32, detail u64) for an error.
fn encode_error(err: &DeviceError) -> (u16, u8, u32, u64) {
    match err {
        DeviceError::NotOpen => (1, 0, 0, 0),
        DeviceError::Disconnected => (2, 0, 0, 0),
        DeviceError::Timeout { waited_us } => (3, 0, 0, *waited_us),
        DeviceError::Protocol { offset, .. } => (4, 0, 0, *offset as u64),
        DeviceError::Io { kind, os_code, .. } => {
            let kind_code = IO_KINDS.iter().position(|k| k == kind).unwrap_or(0) as u64;
            match os_code {
                Some(code) => (5, FLAG_OS_CODE, *code as u32, kind_code),
                None => (5, 0, 0, kind_code),
            }
        }
        DeviceError::EndOfRecording { samples } => (6, 0, 0, *samples),
        DeviceError::PermissionDenied { .. } => (7, 0, 0, 0),
        DeviceError::NotFound { .. } => (8, 0, 0, 0),
        DeviceError::Config { .. } => (9, 0, 0, 0),
        DeviceError::Unsupported { .. } => (10, 0, 0, 0),
        DeviceError::Vendor { library, code, .. } => {
            let which = REPLAYED_VENDOR_LIBRARIES
                .iter()
                .position(|l| l == library)
                .unwrap_or(REPLAYED_VENDOR_LIBRARIES.len() - 1) as u64;
            (11, 0, *code, which)
        }
        // Only `open` returns it, which is never recorded; replayed as the not-found it is.
        DeviceError::LibraryMissing(_) => (8, 0, 0, 0),
    }
}

fn decode_error(code: u16, flags: u8, extra: u32, detail: u64) -> Option<DeviceError> {
    Some(match code {
        1 => DeviceError::NotOpen,
        2 => DeviceError::Disconnected,
        3 => DeviceError::Timeout { waited_us: detail },
        4 => DeviceError::Protocol {
            what: REPLAYED_PROTOCOL_ERROR,
            offset: usize::try_from(detail).ok()?,
        },
        5 => DeviceError::Io {
            kind: *IO_KINDS.get(usize::try_from(detail).ok()?)?,
            os_code: (flags & FLAG_OS_CODE != 0).then_some(extra as i32),
            context: REPLAYED_IO_CONTEXT,
        },
        6 => DeviceError::EndOfRecording { samples: detail },
        // Empty strings do not allocate, so replaying these stays allocation-free.
        7 => DeviceError::PermissionDenied {
            path: String::new(),
        },
        8 => DeviceError::NotFound {
            what: String::new(),
        },
        9 => DeviceError::Config {
            origin: String::new(),
            message: String::new(),
        },
        10 => DeviceError::Unsupported {
            what: REPLAYED_UNSUPPORTED,
        },
        11 => DeviceError::Vendor {
            library: REPLAYED_VENDOR_LIBRARIES.get(usize::try_from(detail).ok()?)?,
            code: extra,
            context: REPLAYED_VENDOR_CONTEXT,
        },
        _ => return None,
    })
}

// ---------------------------------------------------------------------------------------
// Records.

fn put_vec3(out: &mut [u8], v: Vec3) {
    for (i, c) in v.to_array().into_iter().enumerate() {
        out[i * 4..i * 4 + 4].copy_from_slice(&c.to_le_bytes());
    }
}

fn get_f32(b: &[u8], at: usize) -> f32 {
    f32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn get_vec3(b: &[u8], at: usize) -> Vec3 {
    Vec3::new(get_f32(b, at), get_f32(b, at + 4), get_f32(b, at + 8))
}

fn get_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn get_u64(b: &[u8], at: usize) -> u64 {
    let mut w = [0; 8];
    w.copy_from_slice(&b[at..at + 8]);
    u64::from_le_bytes(w)
}

/// Encodes one record into its fixed 64-byte form. `read_count` and `last_timestamp_us` are
/// stored with writes and read errors (for people reading a dump; the replay ignores them).
#[must_use]
pub fn encode_record(
    record: &Record,
    read_count: u64,
    last_timestamp_us: u64,
) -> [u8; RECORD_SIZE] {
    match record {
        Record::Read(result) => encode_read(result, read_count),
        Record::Write { force_n, result } => {
            encode_write(*force_n, result, read_count, last_timestamp_us)
        }
        Record::Schedule(note) => encode_schedule(note),
    }
}

/// Encodes a note of the engine's schedule (see [`encode_record`]). Allocation-free.
#[must_use]
pub fn encode_schedule(note: &ScheduleNote) -> [u8; RECORD_SIZE] {
    let mut b = [0u8; RECORD_SIZE];
    match *note {
        ScheduleNote::Tick {
            tick,
            snapshot_version,
            fade,
        } => {
            b[0] = KIND_TICK;
            if let Some(v) = snapshot_version {
                b[1] = FLAG_FETCHED;
                b[8..16].copy_from_slice(&v.to_le_bytes());
            }
            b[4..8].copy_from_slice(&fade.to_le_bytes());
            b[16..24].copy_from_slice(&tick.to_le_bytes());
        }
        ScheduleNote::Step {
            step,
            sample_tick,
            commands,
        } => {
            b[0] = KIND_STEP;
            b[4..8].copy_from_slice(&commands.to_le_bytes());
            b[8..16].copy_from_slice(&sample_tick.to_le_bytes());
            b[16..24].copy_from_slice(&step.to_le_bytes());
        }
    }
    b
}

/// Encodes a `read` and its result (see [`encode_record`]).
#[must_use]
pub fn encode_read(
    result: &Result<DeviceState, DeviceError>,
    read_count: u64,
) -> [u8; RECORD_SIZE] {
    let mut b = [0u8; RECORD_SIZE];
    match result {
        Ok(s) => {
            b[0] = KIND_READ;
            if let Some(q) = s.orientation {
                b[1] = FLAG_ORIENTATION;
                for (i, c) in q.to_array().into_iter().enumerate() {
                    b[48 + i * 4..52 + i * 4].copy_from_slice(&c.to_le_bytes());
                }
            }
            b[4..8].copy_from_slice(&s.buttons.to_le_bytes());
            b[8..16].copy_from_slice(&s.timestamp_us.to_le_bytes());
            b[16..24].copy_from_slice(&s.sequence.to_le_bytes());
            put_vec3(&mut b[24..36], s.position_m);
            put_vec3(&mut b[36..48], s.velocity_m_per_s);
        }
        Err(e) => {
            b[0] = KIND_READ_ERROR;
            b[16..24].copy_from_slice(&read_count.to_le_bytes());
            put_error(&mut b, e);
        }
    }
    b
}

/// Encodes a `write_force` and its result (see [`encode_record`]).
#[must_use]
pub fn encode_write(
    force_n: Vec3,
    result: &Result<(), DeviceError>,
    read_count: u64,
    last_timestamp_us: u64,
) -> [u8; RECORD_SIZE] {
    let mut b = [0u8; RECORD_SIZE];
    b[0] = if result.is_ok() {
        KIND_WRITE
    } else {
        KIND_WRITE_ERROR
    };
    b[8..16].copy_from_slice(&last_timestamp_us.to_le_bytes());
    b[16..24].copy_from_slice(&read_count.to_le_bytes());
    put_vec3(&mut b[24..36], force_n);
    if let Err(e) = result {
        put_error(&mut b, e);
    }
    b
}

fn put_error(b: &mut [u8; RECORD_SIZE], e: &DeviceError) {
    let (code, flags, extra, detail) = encode_error(e);
    b[1] |= flags;
    b[2..4].copy_from_slice(&code.to_le_bytes());
    b[4..8].copy_from_slice(&extra.to_le_bytes());
    b[8..16].copy_from_slice(&detail.to_le_bytes());
}

/// Decodes one 64-byte record; `Err` names what is wrong (the caller adds the offset).
///
/// # Errors
/// A static description of the invalid field.
pub fn decode_record(b: &[u8; RECORD_SIZE]) -> Result<Record, &'static str> {
    let kind = b[0];
    let flags = b[1];
    let code = u16::from_le_bytes([b[2], b[3]]);
    let extra = get_u32(b, 4);
    let detail = get_u64(b, 8);
    let error = |allowed_flags: u8| -> Result<DeviceError, &'static str> {
        if flags & !allowed_flags != 0 {
            return Err("unknown record flags");
        }
        decode_error(code, flags, extra, detail).ok_or("unknown device error code")
    };
    match kind {
        KIND_READ => {
            if flags & !FLAG_ORIENTATION != 0 {
                return Err("unknown record flags");
            }
            if code != 0 {
                return Err("error code on a successful read");
            }
            let orientation = (flags & FLAG_ORIENTATION != 0).then(|| {
                Quat::from_xyzw(
                    get_f32(b, 48),
                    get_f32(b, 52),
                    get_f32(b, 56),
                    get_f32(b, 60),
                )
            });
            Ok(Record::Read(Ok(DeviceState {
                position_m: get_vec3(b, 24),
                orientation,
                velocity_m_per_s: get_vec3(b, 36),
                buttons: extra,
                timestamp_us: detail,
                sequence: get_u64(b, 16),
            })))
        }
        KIND_READ_ERROR => Ok(Record::Read(Err(error(FLAG_OS_CODE)?))),
        KIND_WRITE => {
            if flags != 0 || code != 0 {
                return Err("error fields on a successful write");
            }
            Ok(Record::Write {
                force_n: get_vec3(b, 24),
                result: Ok(()),
            })
        }
        KIND_WRITE_ERROR => Ok(Record::Write {
            force_n: get_vec3(b, 24),
            result: Err(error(FLAG_OS_CODE)?),
        }),
        KIND_TICK | KIND_STEP => {
            if code != 0 || b[24..].iter().any(|&x| x != 0) {
                return Err("non-zero padding in a schedule record");
            }
            if kind == KIND_TICK {
                if flags & !FLAG_FETCHED != 0 {
                    return Err("unknown record flags");
                }
                let fade = f32::from_bits(extra);
                if !(0.0..=1.0).contains(&fade) {
                    return Err("tick fade outside 0 to 1");
                }
                let fetched = flags & FLAG_FETCHED != 0;
                if !fetched && detail != 0 {
                    return Err("snapshot version on a tick that fetched none");
                }
                Ok(Record::Schedule(ScheduleNote::Tick {
                    tick: get_u64(b, 16),
                    snapshot_version: fetched.then_some(detail),
                    fade,
                }))
            } else {
                if flags != 0 {
                    return Err("unknown record flags");
                }
                Ok(Record::Schedule(ScheduleNote::Step {
                    step: get_u64(b, 16),
                    sample_tick: detail,
                    commands: extra,
                }))
            }
        }
        _ => Err("unknown record kind"),
    }
}

// ---------------------------------------------------------------------------------------
// Header.

fn encode_info(info: &DeviceInfo) -> Vec<u8> {
    // A name longer than a u16 can count is cut at a character boundary.
    let mut name_len = info.name.len().min(usize::from(u16::MAX));
    while !info.name.is_char_boundary(name_len) {
        name_len -= 1;
    }
    let mut out = Vec::with_capacity(46 + name_len);
    out.extend_from_slice(&(name_len as u16).to_le_bytes());
    out.extend_from_slice(&info.name.as_bytes()[..name_len]);
    let flags = u8::from(info.has_orientation) | (u8::from(info.has_force) << 1);
    out.extend_from_slice(&[info.dof, flags, info.button_count, 0]);
    for v in [
        info.max_force_n,
        info.max_stiffness_n_per_m,
        info.max_damping_n_s_per_m,
        info.sample_rate_hz,
    ] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in info
        .workspace_min_m
        .to_array()
        .into_iter()
        .chain(info.workspace_max_m.to_array())
    {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// Encodes the file header for `info`.
#[must_use]
pub fn encode_header(info: &DeviceInfo) -> Vec<u8> {
    let body = encode_info(info);
    let mut out = Vec::with_capacity(18 + body.len());
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    out.extend_from_slice(&(body.len() as u32).to_le_bytes());
    out.extend_from_slice(&body);
    let crc = crc32fast::hash(&out[8..]);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

// ---------------------------------------------------------------------------------------
// Writing.

/// Writes a recording to any `Write`: the header at construction, records grouped into
/// checksummed blocks, and the end marker at [`BlockWriter::finish`]. Used by the recorder's
/// writer thread; blocking I/O, never on the haptic thread.
pub struct BlockWriter<W: Write> {
    out: W,
    payload: Vec<u8>,
    records_in_block: u32,
    records_per_block: u32,
    blocks: u32,
    records: u64,
    bytes: u64,
}

impl<W: Write> BlockWriter<W> {
    /// Writes the header for `info` and returns a writer that closes a block every
    /// `records_per_block` records (clamped to `1..=MAX_RECORDS_PER_BLOCK`).
    ///
    /// # Errors
    /// Any error from writing the header.
    pub fn new(mut out: W, info: &DeviceInfo, records_per_block: u32) -> io::Result<Self> {
        let header = encode_header(info);
        out.write_all(&header)?;
        let records_per_block = records_per_block.clamp(1, MAX_RECORDS_PER_BLOCK);
        Ok(Self {
            out,
            payload: Vec::with_capacity(records_per_block as usize * RECORD_SIZE),
            records_in_block: 0,
            records_per_block,
            blocks: 0,
            records: 0,
            bytes: header.len() as u64,
        })
    }

    /// Appends one encoded record, writing the block out when it is full.
    ///
    /// # Errors
    /// Any error from writing a full block.
    pub fn push(&mut self, record: &[u8; RECORD_SIZE]) -> io::Result<()> {
        self.payload.extend_from_slice(record);
        self.records_in_block += 1;
        self.records += 1;
        if self.records_in_block >= self.records_per_block {
            self.flush_block()?;
        }
        Ok(())
    }

    /// Writes the records pushed so far as a block (nothing if there are none).
    ///
    /// # Errors
    /// Any error from the underlying writer.
    pub fn flush_block(&mut self) -> io::Result<()> {
        if self.records_in_block == 0 {
            return Ok(());
        }
        let mut head = [0u8; BLOCK_HEADER_SIZE];
        head[..4].copy_from_slice(&BLOCK_MAGIC);
        head[4..8].copy_from_slice(&self.blocks.to_le_bytes());
        head[8..12].copy_from_slice(&self.records_in_block.to_le_bytes());
        head[12..16].copy_from_slice(&(self.payload.len() as u32).to_le_bytes());
        let mut crc = crc32fast::Hasher::new();
        crc.update(&head[4..16]);
        crc.update(&self.payload);
        head[16..20].copy_from_slice(&crc.finalize().to_le_bytes());
        self.out.write_all(&head)?;
        self.out.write_all(&self.payload)?;
        self.out.flush()?;
        self.bytes += (BLOCK_HEADER_SIZE + self.payload.len()) as u64;
        self.blocks += 1;
        self.payload.clear();
        self.records_in_block = 0;
        Ok(())
    }

    /// Records written (or pending in the open block).
    #[must_use]
    pub fn records(&self) -> u64 {
        self.records
    }

    /// Writes the last block and the end marker, noting `dropped` records, and returns the
    /// writer with the totals.
    ///
    /// # Errors
    /// Any error from the underlying writer.
    pub fn finish(mut self, dropped: u64) -> io::Result<(W, WriteSummary)> {
        self.flush_block()?;
        let mut end = [0u8; END_SIZE];
        end[..4].copy_from_slice(&END_MAGIC);
        end[4..8].copy_from_slice(&self.blocks.to_le_bytes());
        end[8..16].copy_from_slice(&self.records.to_le_bytes());
        end[16..24].copy_from_slice(&dropped.to_le_bytes());
        let crc = crc32fast::hash(&end[4..24]);
        end[24..28].copy_from_slice(&crc.to_le_bytes());
        self.out.write_all(&end)?;
        self.out.flush()?;
        self.bytes += END_SIZE as u64;
        let summary = WriteSummary {
            blocks: self.blocks,
            records: self.records,
            dropped,
            bytes: self.bytes,
        };
        Ok((self.out, summary))
    }
}

/// Totals of a finished recording.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WriteSummary {
    /// Blocks written.
    pub blocks: u32,
    /// Records written.
    pub records: u64,
    /// Records dropped because the writer fell behind.
    pub dropped: u64,
    /// File size, bytes.
    pub bytes: u64,
}

// ---------------------------------------------------------------------------------------
// Parsing.

/// The shared bounds-checked cursor, with the block being read: every short read is a
/// `Truncated` error naming the offset, the block and what was being read.
struct Cursor<'a> {
    bytes: ByteCursor<'a>,
    block: Option<u32>,
}

impl<'a> Cursor<'a> {
    fn at(&self) -> usize {
        self.bytes.at()
    }

    fn remaining(&self) -> usize {
        self.bytes.remaining()
    }

    fn take(&mut self, n: usize, what: &'static str) -> Result<&'a [u8], RecordError> {
        self.bytes.take(n).map_err(|short| RecordError::Truncated {
            offset: short.offset as u64,
            block: self.block,
            what,
            needed: short.needed as u64,
            available: short.available as u64,
        })
    }

    fn malformed(&self, at: usize, what: &'static str) -> RecordError {
        RecordError::Malformed {
            offset: at as u64,
            block: self.block,
            what,
        }
    }
}

fn parse_info(body: &[u8], base: usize) -> Result<DeviceInfo, RecordError> {
    let bad = |at: usize, what| RecordError::Malformed {
        offset: (base + at) as u64,
        block: None,
        what,
    };
    if body.len() < 2 {
        return Err(bad(0, "device info too short for its name length"));
    }
    let name_len = usize::from(u16::from_le_bytes([body[0], body[1]]));
    if body.len() != 46 + name_len {
        return Err(bad(0, "device info length does not match its name length"));
    }
    let name = std::str::from_utf8(&body[2..2 + name_len])
        .map_err(|_| bad(2, "device name is not UTF-8"))?
        .to_owned();
    let rest = &body[2 + name_len..];
    let flags = rest[1];
    if flags & !3 != 0 || rest[3] != 0 {
        return Err(bad(2 + name_len + 1, "unknown device info flags"));
    }
    Ok(DeviceInfo {
        name,
        dof: rest[0],
        has_orientation: flags & 1 != 0,
        has_force: flags & 2 != 0,
        button_count: rest[2],
        max_force_n: get_f32(rest, 4),
        max_stiffness_n_per_m: get_f32(rest, 8),
        max_damping_n_s_per_m: get_f32(rest, 12),
        sample_rate_hz: get_f32(rest, 16),
        workspace_min_m: get_vec3(rest, 20),
        workspace_max_m: get_vec3(rest, 32),
    })
}

impl Recording {
    /// Decodes a whole recording.
    ///
    /// # Errors
    /// [`RecordError::BadMagic`], [`RecordError::UnsupportedVersion`], or a
    /// [`RecordError::Truncated`], [`RecordError::Checksum`] or [`RecordError::Malformed`]
    /// naming the byte offset and block of the first fault. A file without its end marker
    /// counts as truncated.
    pub fn parse(bytes: &[u8]) -> Result<Self, RecordError> {
        let mut c = Cursor {
            bytes: ByteCursor::new(bytes),
            block: None,
        };
        let magic = c
            .take(MAGIC.len(), "magic")
            .map_err(|_| RecordError::BadMagic)?;
        if magic != MAGIC {
            return Err(RecordError::BadMagic);
        }
        let version_at = c.at();
        let version = c.take(2, "format version")?;
        let version = u16::from_le_bytes([version[0], version[1]]);
        if !(OLDEST_READ_VERSION..=FORMAT_VERSION).contains(&version) {
            return Err(RecordError::UnsupportedVersion {
                found: version,
                oldest: OLDEST_READ_VERSION,
                supported: FORMAT_VERSION,
            });
        }
        let len = get_u32(c.take(4, "header length")?, 0) as usize;
        let info_at = c.at();
        let body = c.take(len, "device info")?;
        let crc_at = c.at();
        let stored = get_u32(c.take(4, "header checksum")?, 0);
        let computed = crc32fast::hash(&bytes[version_at..crc_at]);
        if stored != computed {
            return Err(RecordError::Checksum {
                offset: version_at as u64,
                block: None,
                stored,
                computed,
            });
        }
        let info = parse_info(body, info_at)?;

        let mut records = Vec::new();
        let mut blocks: u32 = 0;
        loop {
            c.block = Some(blocks);
            let start = c.at();
            if c.remaining() == 0 {
                return Err(RecordError::Truncated {
                    offset: start as u64,
                    block: Some(blocks),
                    what: "block or end marker",
                    needed: 4,
                    available: 0,
                });
            }
            let tag = c.take(4, "block tag")?;
            if tag == END_MAGIC {
                c.block = None;
                let end = c.take(END_SIZE - 4, "end marker")?;
                let stored = get_u32(end, 20);
                let computed = crc32fast::hash(&end[..20]);
                if stored != computed {
                    return Err(RecordError::Checksum {
                        offset: start as u64,
                        block: None,
                        stored,
                        computed,
                    });
                }
                if get_u32(end, 0) != blocks {
                    return Err(c.malformed(start + 4, "end marker block count disagrees"));
                }
                if get_u64(end, 4) != records.len() as u64 {
                    return Err(c.malformed(start + 8, "end marker record count disagrees"));
                }
                if c.remaining() != 0 {
                    return Err(c.malformed(c.at(), "bytes after the end marker"));
                }
                return Ok(Self {
                    info,
                    records,
                    dropped: get_u64(end, 12),
                });
            }
            if tag != BLOCK_MAGIC {
                return Err(c.malformed(start, "expected a block or the end marker"));
            }
            let head = c.take(BLOCK_HEADER_SIZE - 4, "block header")?;
            let index = get_u32(head, 0);
            let count = get_u32(head, 4);
            let payload_len = get_u32(head, 8) as usize;
            let stored = get_u32(head, 12);
            if index != blocks {
                return Err(c.malformed(start + 4, "block index out of sequence"));
            }
            if count == 0 || count > MAX_RECORDS_PER_BLOCK {
                return Err(c.malformed(start + 8, "block record count out of range"));
            }
            if payload_len != count as usize * RECORD_SIZE {
                return Err(c.malformed(start + 12, "block length disagrees with record count"));
            }
            let payload_at = c.at();
            let payload = c.take(payload_len, "block payload")?;
            let mut crc = crc32fast::Hasher::new();
            crc.update(&head[..12]);
            crc.update(payload);
            let computed = crc.finalize();
            if stored != computed {
                return Err(RecordError::Checksum {
                    offset: start as u64,
                    block: Some(blocks),
                    stored,
                    computed,
                });
            }
            for (i, chunk) in payload.chunks_exact(RECORD_SIZE).enumerate() {
                let mut raw = [0u8; RECORD_SIZE];
                raw.copy_from_slice(chunk);
                let record = decode_record(&raw)
                    .map_err(|what| c.malformed(payload_at + i * RECORD_SIZE, what))?;
                records.push(record);
            }
            blocks = blocks
                .checked_add(1)
                .ok_or_else(|| c.malformed(start, "too many blocks"))?;
        }
    }

    /// Encodes the recording as a file image, `records_per_block` records per block.
    #[must_use]
    pub fn to_bytes(&self, records_per_block: u32) -> Vec<u8> {
        let mut w = match BlockWriter::new(Vec::new(), &self.info, records_per_block) {
            Ok(w) => w,
            Err(_) => unreachable!("writing to a Vec cannot fail"),
        };
        let mut reads = 0u64;
        let mut last_us = 0u64;
        for r in &self.records {
            if let Record::Read(result) = r {
                reads += 1;
                if let Ok(s) = result {
                    last_us = s.timestamp_us;
                }
            }
            let raw = encode_record(r, reads, last_us);
            if w.push(&raw).is_err() {
                unreachable!("writing to a Vec cannot fail");
            }
        }
        match w.finish(self.dropped) {
            Ok((bytes, _)) => bytes,
            Err(_) => unreachable!("writing to a Vec cannot fail"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn info() -> DeviceInfo {
        DeviceInfo {
            name: "test arm ü".into(),
            dof: 6,
            max_force_n: 7.5,
            max_stiffness_n_per_m: 2500.0,
            max_damping_n_s_per_m: 12.0,
            workspace_min_m: Vec3::new(-0.1, -0.05, -0.08),
            workspace_max_m: Vec3::new(0.1, 0.12, 0.08),
            has_orientation: true,
            has_force: true,
            button_count: 2,
            sample_rate_hz: 1000.0,
        }
    }

    fn sample(i: u64) -> DeviceState {
        DeviceState {
            position_m: Vec3::new(i as f32 * 1e-4, -0.01, 0.003),
            orientation: i
                .is_multiple_of(2)
                .then(|| Quat::from_rotation_y(i as f32 * 0.01)),
            velocity_m_per_s: Vec3::new(0.1, f32::MIN_POSITIVE, -0.0),
            buttons: (i % 4) as u32,
            timestamp_us: i * 1000,
            sequence: i + 1,
        }
    }

    /// Every record shape, including each error code.
    fn all_kinds() -> Recording {
        let mut records = Vec::new();
        for i in 0..10 {
            records.push(Record::Read(Ok(sample(i))));
            records.push(Record::Write {
                force_n: Vec3::new(0.5, -1.0, i as f32),
                result: Ok(()),
            });
        }
        for e in [
            DeviceError::NotOpen,
            DeviceError::Disconnected,
            DeviceError::Timeout { waited_us: 1234 },
            DeviceError::Protocol {
                what: REPLAYED_PROTOCOL_ERROR,
                offset: 13,
            },
            DeviceError::Io {
                kind: io::ErrorKind::BrokenPipe,
                os_code: Some(32),
                context: REPLAYED_IO_CONTEXT,
            },
            DeviceError::Io {
                kind: io::ErrorKind::TimedOut,
                os_code: None,
                context: REPLAYED_IO_CONTEXT,
            },
            DeviceError::EndOfRecording { samples: 99 },
            DeviceError::Vendor {
                library: REPLAYED_VENDOR_LIBRARIES[0],
                code: 0x0302,
                context: REPLAYED_VENDOR_CONTEXT,
            },
            DeviceError::Vendor {
                library: REPLAYED_VENDOR_LIBRARIES[1],
                code: 2,
                context: REPLAYED_VENDOR_CONTEXT,
            },
        ] {
            records.push(Record::Read(Err(e.clone())));
            records.push(Record::Write {
                force_n: Vec3::ZERO,
                result: Err(e),
            });
        }
        for (i, fetched) in [None, Some(0), Some(u64::MAX)].into_iter().enumerate() {
            records.push(Record::Schedule(ScheduleNote::Tick {
                tick: i as u64 + 1,
                snapshot_version: fetched,
                fade: [1.0, 0.0, 0.375][i],
            }));
            records.push(Record::Schedule(ScheduleNote::Step {
                step: i as u64,
                sample_tick: [0, 7, u64::MAX][i],
                commands: [0, 1, u32::MAX][i],
            }));
        }
        Recording {
            info: info(),
            records,
            dropped: 3,
        }
    }

    #[test]
    fn round_trip_is_exact() {
        let rec = all_kinds();
        for per_block in [1, 5, 256] {
            let bytes = rec.to_bytes(per_block);
            assert_eq!(
                Recording::parse(&bytes).unwrap(),
                rec,
                "{per_block} per block"
            );
        }
    }

    #[test]
    fn schedule_records_refuse_what_the_engine_never_writes() {
        let tick = |fade: f32| {
            encode_schedule(&ScheduleNote::Tick {
                tick: 1,
                snapshot_version: Some(4),
                fade,
            })
        };
        assert!(decode_record(&tick(0.5)).is_ok());
        assert_eq!(decode_record(&tick(1.5)), Err("tick fade outside 0 to 1"));
        assert_eq!(
            decode_record(&tick(f32::NAN)),
            Err("tick fade outside 0 to 1")
        );
        let mut raw = tick(0.5);
        raw[1] = 0;
        assert_eq!(
            decode_record(&raw),
            Err("snapshot version on a tick that fetched none")
        );
        let mut raw = tick(0.5);
        raw[40] = 1;
        assert_eq!(
            decode_record(&raw),
            Err("non-zero padding in a schedule record")
        );
    }

    #[test]
    fn float_bits_survive() {
        let weird = DeviceState {
            position_m: Vec3::new(f32::from_bits(0x7fc0_1234), -0.0, f32::INFINITY),
            ..sample(0)
        };
        let raw = encode_read(&Ok(weird), 1);
        let Ok(Record::Read(Ok(back))) = decode_record(&raw) else {
            panic!("decode failed")
        };
        assert_eq!(back.position_m.x.to_bits(), 0x7fc0_1234);
        assert_eq!(back.position_m.y.to_bits(), (-0.0f32).to_bits());
    }

    #[test]
    fn open_time_errors_keep_their_variant_but_not_their_text() {
        let raw = encode_read(&Err(DeviceError::NotFound { what: "x".into() }), 1);
        let empty = DeviceError::NotFound {
            what: String::new(),
        };
        assert_eq!(decode_record(&raw), Ok(Record::Read(Err(empty))));
    }

    fn header_len() -> usize {
        encode_header(&info()).len()
    }

    #[test]
    fn bad_magic_and_version() {
        let mut bytes = all_kinds().to_bytes(4);
        bytes[0] = b'X';
        assert!(matches!(
            Recording::parse(&bytes),
            Err(RecordError::BadMagic)
        ));
        assert!(matches!(
            Recording::parse(b"DC"),
            Err(RecordError::BadMagic)
        ));
        let mut bytes = all_kinds().to_bytes(4);
        bytes[8] = 3;
        let e = Recording::parse(&bytes).unwrap_err();
        assert!(matches!(
            e,
            RecordError::UnsupportedVersion {
                found: 3,
                oldest: 1,
                supported: 2
            }
        ));
        assert!(e.to_string().contains("version 3"), "{e}");
        assert!(e.to_string().contains("reads versions 1 to 2"), "{e}");
        bytes[8] = 0;
        assert!(matches!(
            Recording::parse(&bytes),
            Err(RecordError::UnsupportedVersion { found: 0, .. })
        ));
    }

    #[test]
    fn header_corruption_is_a_header_checksum_error() {
        let mut bytes = all_kinds().to_bytes(4);
        bytes[20] ^= 0x40; // inside the device name
        let e = Recording::parse(&bytes).unwrap_err();
        assert!(
            matches!(
                e,
                RecordError::Checksum {
                    offset: 8,
                    block: None,
                    ..
                }
            ),
            "{e}"
        );
    }

    #[test]
    fn payload_corruption_names_block_and_offset() {
        let bytes = all_kinds().to_bytes(4);
        let block_size = BLOCK_HEADER_SIZE + 4 * RECORD_SIZE;
        let block2 = header_len() + 2 * block_size;
        let mut bad = bytes.clone();
        bad[block2 + BLOCK_HEADER_SIZE + 70] ^= 1;
        let e = Recording::parse(&bad).unwrap_err();
        assert!(
            matches!(e, RecordError::Checksum { block: Some(2), .. }),
            "{e}"
        );
        assert_eq!(e.offset(), Some(block2 as u64));
        assert!(
            e.to_string()
                .contains(&format!("at byte {block2} in block 2")),
            "{e}"
        );
    }

    #[test]
    fn truncation_anywhere_is_rejected_with_offset() {
        let bytes = all_kinds().to_bytes(4);
        for cut in 0..bytes.len() {
            let e = Recording::parse(&bytes[..cut]).unwrap_err();
            match e {
                RecordError::BadMagic => assert!(cut < MAGIC.len()),
                RecordError::Truncated {
                    offset, available, ..
                } => {
                    assert!(offset as usize <= cut, "cut {cut}: {e}");
                    assert_eq!(offset + available, cut as u64, "cut {cut}: {e}");
                }
                other => panic!("cut {cut}: unexpected {other}"),
            }
        }
        // Cut exactly after a whole block: the missing end marker is reported there.
        let cut = header_len() + BLOCK_HEADER_SIZE + 4 * RECORD_SIZE;
        let e = Recording::parse(&bytes[..cut]).unwrap_err();
        assert_eq!(e.offset(), Some(cut as u64));
        assert_eq!(e.block(), Some(1));
        assert!(e.to_string().contains("block or end marker"), "{e}");
    }

    #[test]
    fn trailing_bytes_and_reordered_blocks_rejected() {
        let mut bytes = all_kinds().to_bytes(4);
        bytes.push(0);
        let e = Recording::parse(&bytes).unwrap_err();
        assert!(e.to_string().contains("after the end marker"), "{e}");

        // Swap blocks 0 and 1 (same size): each checksum is intact, the order is not.
        let bytes = all_kinds().to_bytes(4);
        let h = header_len();
        let size = BLOCK_HEADER_SIZE + 4 * RECORD_SIZE;
        let mut swapped = bytes.clone();
        swapped[h..h + size].copy_from_slice(&bytes[h + size..h + 2 * size]);
        swapped[h + size..h + 2 * size].copy_from_slice(&bytes[h..h + size]);
        let e = Recording::parse(&swapped).unwrap_err();
        assert!(e.to_string().contains("out of sequence"), "{e}");
        assert_eq!(e.block(), Some(0));
    }

    #[test]
    fn invalid_record_with_valid_checksum_names_its_offset() {
        let mut rec = all_kinds();
        rec.records.truncate(4);
        let mut bytes = rec.to_bytes(4);
        let payload = header_len() + BLOCK_HEADER_SIZE;
        let record2 = payload + 2 * RECORD_SIZE;
        bytes[record2] = 9; // unknown kind
        // Re-seal the block so only the record itself is wrong.
        let crc = crc32fast::hash(&bytes[header_len() + 4..header_len() + 16]);
        let mut h = crc32fast::Hasher::new_with_initial(crc);
        h.update(&bytes[payload..payload + 4 * RECORD_SIZE]);
        let sealed = h.finalize();
        bytes[header_len() + 16..header_len() + 20].copy_from_slice(&sealed.to_le_bytes());
        let e = Recording::parse(&bytes).unwrap_err();
        assert_eq!(e.offset(), Some(record2 as u64), "{e}");
        assert!(e.to_string().contains("unknown record kind"), "{e}");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]

        #[test]
        fn parser_never_panics_on_arbitrary_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
            let _ = Recording::parse(&bytes);
        }

        #[test]
        fn parser_never_panics_on_mutated_recordings(
            flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..8),
            cut in any::<usize>(),
        ) {
            let mut bytes = all_kinds().to_bytes(3);
            for (at, x) in flips {
                let n = bytes.len();
                bytes[at % n] ^= x;
            }
            let n = bytes.len();
            let cut = cut % (n + 1);
            let _ = Recording::parse(&bytes[..cut]);
            let _ = Recording::parse(&bytes);
        }

        #[test]
        fn any_record_round_trips(
            kind in 0u8..4, flags in any::<u8>(), code in 0u16..12, extra in any::<u32>(),
            detail in any::<u64>(), rest in proptest::array::uniform32(any::<u8>()),
            more in proptest::array::uniform16(any::<u8>()),
        ) {
            // Whatever decodes must encode back to the same bytes, except the informational
            // fields of writes and read errors.
            let mut raw = [0u8; RECORD_SIZE];
            raw[0] = kind + 1;
            raw[1] = flags & 3;
            raw[2..4].copy_from_slice(&code.to_le_bytes());
            raw[4..8].copy_from_slice(&extra.to_le_bytes());
            raw[8..16].copy_from_slice(&(detail % 16).to_le_bytes());
            raw[16..48].copy_from_slice(&rest);
            raw[48..64].copy_from_slice(&more);
            if let Ok(record) = decode_record(&raw) {
                // Compared as bytes: NaN payloads must survive, and NaN != NaN.
                let again = encode_record(&record, 0, 0);
                let decoded = decode_record(&again);
                prop_assert!(decoded.is_ok());
                if let Ok(decoded) = decoded {
                    prop_assert_eq!(encode_record(&decoded, 0, 0), again);
                }
            }
        }
    }
}
