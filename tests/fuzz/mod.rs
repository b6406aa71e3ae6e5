//! Mutation fuzzing of dynaclay's three input formats — session files, scripts and device
//! recordings — shared by the CI test (`tests/inputs_never_panic.rs`, a few hundred cases per
//! format) and the long run (`bench/fuzz_inputs.rs`, a million cases or more).
//!
//! Each case starts from a valid file and applies one to five mutations: a bit flip, a byte
//! set, a truncation, a splice of a slice of the file elsewhere in it, or a huge number (binary:
//! `u32::MAX`, `u64::MAX`, NaN or infinity bits at an aligned offset; text: `4294967295`,
//! `1e300`, `nan`, … over a number). Binary formats have their checksums recomputed after the
//! mutation, so the section decoders see the damage instead of the checksum check alone.
//!
//! A case passes when the parser returns `Ok` or its typed error — no panic (proptest catches
//! and reports one) — and its peak heap use on the calling thread stays within
//! [`heap_bound`]. The heap is measured by [`PeakAlloc`], which the including crate installs
//! as its global allocator.

#![allow(dead_code)] // each including crate uses its part

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

use dynaclay::dynamics::Material;
use dynaclay::dynamics::{Constraint, MaterialGrid};
use dynaclay::engine::{DEFAULT_SCRIPT, ScriptPlan};
use dynaclay::field::BSplineLattice;
use dynaclay::fit::{parse_ply, parse_xyz};
use dynaclay::io::MaterialFields;
use dynaclay::io::{Session, ToolPreset, decode, encode, parse_script};
use dynaclay::tools::{Clay, ColourField, ToolAction, ToolShape};
use dynaclay_devices::record::ScheduleNote;
use dynaclay_devices::record::format::{BlockWriter, encode_read, encode_schedule, encode_write};
use dynaclay_devices::{DeviceState, Recording, ReplayDevice, SimArmConfig};
use glam::{Quat, Vec3};
use proptest::prelude::*;
use proptest::sample::Index;
use proptest::test_runner::TestCaseError;

// ---------------------------------------------------------------------------------------
// Heap measurement.

thread_local! {
    // Const-initialised cells without destructors: safe to touch from inside the allocator.
    static LIVE: Cell<i64> = const { Cell::new(0) };
    static PEAK: Cell<i64> = const { Cell::new(0) };
}

fn note(delta: i64) {
    let _ = LIVE.try_with(|live| {
        let now = live.get() + delta;
        live.set(now);
        let _ = PEAK.try_with(|peak| {
            if now > peak.get() {
                peak.set(now);
            }
        });
    });
}

/// The system allocator, counting the bytes each thread has live and its peak.
pub struct PeakAlloc;

// SAFETY: every call forwards to `System` with the caller's arguments unchanged; the counting
// only touches this thread's cells.
unsafe impl GlobalAlloc for PeakAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: forwarded with the caller's layout (the caller upholds alloc's contract).
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            note(layout.size() as i64);
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as `alloc`.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            note(layout.size() as i64);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from this allocator (so from `System`) with `layout`.
        unsafe { System.dealloc(ptr, layout) };
        note(-(layout.size() as i64));
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: `ptr` came from `System` with `layout`; the caller upholds the rest.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            note(new_size as i64 - layout.size() as i64);
        }
        p
    }
}

/// Runs `f` and returns its result with the most heap it had live above the starting level on
/// this thread, bytes.
pub fn peak_heap_during<T>(f: impl FnOnce() -> T) -> (T, u64) {
    let start = LIVE.with(Cell::get);
    PEAK.with(|p| p.set(start));
    let value = f();
    let peak = PEAK.with(Cell::get) - start;
    (value, u64::try_from(peak).unwrap_or(0))
}

/// The most heap one parse of an `input_len`-byte input may take: 32 bytes per input byte
/// plus 4 MiB. A decoder that trusts a length or count field allocates far more, and fails.
#[must_use]
pub fn heap_bound(input_len: usize) -> u64 {
    32 * input_len as u64 + (4 << 20)
}

/// Cases each check accepted (parsed `Ok`), by format: sessions, scripts, recordings. The
/// rest were refused with a typed error.
pub static ACCEPTED: [AtomicU64; 4] = [
    AtomicU64::new(0),
    AtomicU64::new(0),
    AtomicU64::new(0),
    AtomicU64::new(0),
];

fn accepted(format: usize) {
    // NOTE: Relaxed: a statistic, read once after the runner threads are joined.
    ACCEPTED[format].fetch_add(1, Ordering::Relaxed);
}

// ---------------------------------------------------------------------------------------
// Mutations.

/// One change to an input.
#[derive(Clone, Debug)]
pub enum Mutation {
    /// Flip bit `bit` of the byte at the index.
    FlipBit(Index, u8),
    /// Set the byte at the index.
    SetByte(Index, u8),
    /// Cut the input at the index.
    Truncate(Index),
    /// Copy `len` bytes from `from` over the input at `to` (inserting when `insert`).
    Splice {
        from: Index,
        len: u16,
        to: Index,
        insert: bool,
    },
    /// Write huge number `which` at the index (aligned to 4 bytes in binary input).
    Huge(Index, u8),
}

/// One to five mutations.
pub fn mutations() -> impl Strategy<Value = Vec<Mutation>> {
    let one = prop_oneof![
        3 => (any::<Index>(), 0u8..8).prop_map(|(i, b)| Mutation::FlipBit(i, b)),
        2 => (any::<Index>(), any::<u8>()).prop_map(|(i, v)| Mutation::SetByte(i, v)),
        1 => any::<Index>().prop_map(Mutation::Truncate),
        1 => (any::<Index>(), 0u16..512, any::<Index>(), any::<bool>())
            .prop_map(|(from, len, to, insert)| Mutation::Splice { from, len, to, insert }),
        2 => (any::<Index>(), any::<u8>()).prop_map(|(i, w)| Mutation::Huge(i, w)),
    ];
    proptest::collection::vec(one, 1..6)
}

const HUGE_BINARY: [u64; 8] = [
    u32::MAX as u64,
    u64::MAX,
    0x7fff_ffff,
    0x8000_0000,
    0x7f80_0000, // f32 infinity
    0x7fc0_0000, // f32 NaN
    0xff80_0000, // f32 -infinity
    1 << 40,
];

const HUGE_TEXT: [&str; 12] = [
    "4294967295",
    "18446744073709551615",
    "99999999999999999999999999",
    "1e300",
    "-1e300",
    "1e-300",
    "nan",
    "inf",
    "-inf",
    "1e9",
    "-2147483648",
    "0",
];

fn splice(bytes: &mut Vec<u8>, from: &Index, len: u16, to: &Index, insert: bool) {
    if bytes.is_empty() {
        return;
    }
    let a = from.index(bytes.len());
    let b = (a + usize::from(len)).min(bytes.len());
    let piece = bytes[a..b].to_vec();
    let at = to.index(bytes.len() + 1).min(bytes.len());
    if insert {
        bytes.splice(at..at, piece);
    } else {
        let end = (at + piece.len()).min(bytes.len());
        bytes.splice(at..end, piece);
    }
}

/// Applies `mutations` to binary input.
pub fn mutate_bytes(bytes: &mut Vec<u8>, mutations: &[Mutation]) {
    for m in mutations {
        if bytes.is_empty() {
            return;
        }
        let n = bytes.len();
        match m {
            Mutation::FlipBit(i, bit) => bytes[i.index(n)] ^= 1 << bit,
            Mutation::SetByte(i, v) => bytes[i.index(n)] = *v,
            Mutation::Truncate(i) => bytes.truncate(i.index(n)),
            Mutation::Splice {
                from,
                len,
                to,
                insert,
            } => splice(bytes, from, *len, to, *insert),
            Mutation::Huge(i, which) => {
                let v = HUGE_BINARY[usize::from(*which) % HUGE_BINARY.len()].to_le_bytes();
                let width = if *which & 0x80 == 0 { 4 } else { 8 };
                let at = i.index(n) / 4 * 4;
                let end = (at + width).min(n);
                bytes[at..end].copy_from_slice(&v[..end - at]);
            }
        }
    }
}

/// Applies `mutations` to text: byte edits that break UTF-8 are mapped back to text by lossy
/// decoding; `Huge` replaces the run of number characters at the index.
pub fn mutate_text(text: &str, mutations: &[Mutation]) -> String {
    let mut bytes = text.as_bytes().to_vec();
    for m in mutations {
        if bytes.is_empty() {
            break;
        }
        match m {
            Mutation::Huge(i, which) => {
                let n = bytes.len();
                let number = |b: u8| b.is_ascii_digit() || b"+-.eE_".contains(&b);
                // The number at or after the index (or the index itself when none follows).
                let mut a = i.index(n);
                while a < n && !bytes[a].is_ascii_digit() {
                    a += 1;
                }
                if a == n {
                    a = i.index(n);
                }
                while a > 0 && number(bytes[a - 1]) {
                    a -= 1;
                }
                let mut b = a;
                while b < n && number(bytes[b]) {
                    b += 1;
                }
                let v = HUGE_TEXT[usize::from(*which) % HUGE_TEXT.len()];
                bytes.splice(a..b, v.bytes());
            }
            other => mutate_bytes(&mut bytes, std::slice::from_ref(other)),
        }
    }
    String::from_utf8_lossy(&bytes).into_owned()
}

// ---------------------------------------------------------------------------------------
// Sessions.

/// A small session of the current format with every section: a base patch and a detail
/// patch under a turned map, colour, a material with painted stiffness and plasticity grids,
/// pins of each kind and a tool.
#[must_use]
pub fn valid_session_bytes() -> Vec<u8> {
    let mut lattice = BSplineLattice::zeros([4, 5, 4], 0.25, Vec3::new(0.5, -1.0, 0.0)).unwrap();
    lattice.coeffs.update_each(|i, c| {
        *c = (i as f32 * 0.3).sin();
    });
    let mut colour = ColourField::matching(&lattice).unwrap();
    colour.channels[3].coeffs.fill(0.5);
    let mut density = dynaclay::field::MultiPatchField::new(lattice);
    let mut detail = BSplineLattice::zeros([4, 4, 4], 0.125, Vec3::new(0.6, -0.9, 0.1)).unwrap();
    detail.coeffs.set_flat(21, 0.25);
    density.push(
        detail,
        glam::Affine3A::from_rotation_translation(
            Quat::from_rotation_z(0.3),
            Vec3::new(0.1, 0.0, -0.2),
        ),
    );
    let session = Session {
        clay: Clay {
            density,
            colour: Some(colour),
            constraints: vec![
                Constraint::Point {
                    at: Vec3::new(0.6, -0.5, 0.3),
                },
                Constraint::Curve {
                    points: vec![Vec3::new(0.6, -0.5, 0.3), Vec3::new(0.9, -0.5, 0.3)],
                },
                Constraint::Normal {
                    at: Vec3::new(0.7, -0.4, 0.2),
                    normal: Vec3::Y,
                },
            ],
            mask: None,
        },
        material: MaterialFields {
            uniform: Material::PLASTIC,
            grids: vec![
                MaterialGrid {
                    name: "stiffness".into(),
                    dims: [2, 2, 2],
                    values: vec![
                        900.0, 1000.0, 1100.0, 1200.0, 1300.0, 1400.0, 1500.0, 1600.0,
                    ],
                },
                MaterialGrid {
                    name: "plasticity".into(),
                    dims: [1, 2, 1],
                    values: vec![0.0, 8.0],
                },
            ],
        },
        tools: vec![ToolPreset {
            name: "blob".into(),
            shape: ToolShape::Sphere { radius_fu: 0.2 },
            action: ToolAction::Paint {
                rgb: [0.2, 0.4, 0.6],
            },
            falloff_fu: 0.1,
        }],
        ..Session::default()
    };
    encode(&session).expect("encodes")
}

/// Recomputes the header's and every reachable section's CRC in place (the layout is in
/// `src/io/format.rs`: a 24-byte header, then tag, u64 length, payload, CRC32).
pub fn refresh_session_checksums(bytes: &mut [u8]) {
    if bytes.len() < 24 {
        return;
    }
    let crc = crc32fast::hash(&bytes[..20]);
    bytes[20..24].copy_from_slice(&crc.to_le_bytes());
    let mut pos = 24;
    while pos + 12 <= bytes.len() {
        let len = u64::from_le_bytes(bytes[pos + 4..pos + 12].try_into().unwrap());
        let Some(end) = usize::try_from(len)
            .ok()
            .and_then(|l| (pos + 12).checked_add(l))
        else {
            return;
        };
        if end + 4 > bytes.len() {
            return;
        }
        let crc = crc32fast::hash(&bytes[pos..end]);
        bytes[end..end + 4].copy_from_slice(&crc.to_le_bytes());
        pos = end + 4;
    }
}

/// Decodes a damaged session: an error naming the file, or a session that is whole (finite
/// coefficients, a usable material, and it encodes again); within the heap bound.
///
/// # Errors
/// A failed check.
pub fn check_session(bytes: &[u8]) -> Result<(), TestCaseError> {
    let (decoded, peak) = peak_heap_during(|| decode(bytes, Path::new("damaged.dclay")));
    prop_assert!(
        peak <= heap_bound(bytes.len()),
        "decoding {} bytes took {peak} bytes of heap",
        bytes.len()
    );
    match decoded {
        Err(e) => {
            let text = e.to_string();
            prop_assert!(
                text.contains("damaged.dclay"),
                "the error names the file: {text}"
            );
        }
        Ok(session) => {
            let lattices = session
                .clay
                .density
                .patches
                .iter()
                .map(|p| &p.lattice)
                .chain(session.clay.colour.iter().flat_map(|c| c.channels.iter()));
            for l in lattices {
                prop_assert!(l.coeffs.iter().all(|c| c.is_finite()));
            }
            prop_assert!(session.material.uniform.validate().is_ok());
            prop_assert!(encode(&session).is_ok());
            accepted(0);
        }
    }
    Ok(())
}

/// A damaged session file: the fixture mutated, its checksums recomputed (or, for one case in
/// eight, left as they are so the checksum and header checks are fuzzed too).
pub fn session_case() -> impl Strategy<Value = Vec<u8>> {
    (mutations(), 0u8..8).prop_map(|(m, keep_crc)| {
        let mut bytes = valid_session_bytes();
        mutate_bytes(&mut bytes, &m);
        if keep_crc != 0 {
            refresh_session_checksums(&mut bytes);
        }
        bytes
    })
}

// ---------------------------------------------------------------------------------------
// Scripts.

/// A damaged copy of the built-in script.
pub fn script_case() -> impl Strategy<Value = String> {
    mutations().prop_map(|m| mutate_text(DEFAULT_SCRIPT, &m))
}

/// Parses and lays out a damaged script: an error at `edited.toml…`, or a plan; within the
/// heap bound.
///
/// # Errors
/// A failed check.
pub fn check_script(text: &str) -> Result<(), TestCaseError> {
    let (outcome, peak) = peak_heap_during(|| {
        parse_script(text, "edited.toml").map(|script| {
            ScriptPlan::new(
                &script,
                "edited.toml",
                Path::new("."),
                &[],
                Material::PLASTIC,
            )
            .map(|_| ())
        })
    });
    prop_assert!(
        peak <= heap_bound(text.len()),
        "a {}-byte script took {peak} bytes of heap",
        text.len()
    );
    match outcome {
        Err(e) | Ok(Err(e)) => {
            prop_assert!(e.to_string().starts_with("edited.toml"), "{e}");
        }
        Ok(Ok(())) => accepted(1),
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Recordings.

/// A recording of 150 reads and 150 writes in blocks of 64, with one error of each kind, and the
/// engine's schedule beside them (a tick per read, a step every other tick).
#[must_use]
pub fn valid_recording_bytes() -> Vec<u8> {
    let info = SimArmConfig::default().info;
    let mut w = BlockWriter::new(Vec::new(), &info, 64).expect("header");
    for i in 0..150u64 {
        let t = i as f32 * 1e-3;
        let read = if i == 70 {
            Err(dynaclay_devices::DeviceError::Timeout { waited_us: 1500 })
        } else {
            Ok(DeviceState {
                position_m: Vec3::new(t.sin() * 0.05, t.cos() * 0.05, t),
                orientation: (i % 3 == 0).then_some(Quat::from_rotation_z(t)),
                velocity_m_per_s: Vec3::new(0.1, -0.2, t),
                buttons: (i % 5) as u32,
                timestamp_us: i * 1000,
                sequence: i,
            })
        };
        w.push(&encode_read(&read, i + 1)).expect("read");
        let force = Vec3::new(t, -t, 0.5);
        w.push(&encode_write(force, &Ok(()), i + 1, i * 1000))
            .expect("write");
        w.push(&encode_schedule(&ScheduleNote::Tick {
            tick: i + 1,
            snapshot_version: Some(i / 2),
            fade: 1.0,
        }))
        .expect("tick");
        if i % 2 == 0 {
            w.push(&encode_schedule(&ScheduleNote::Step {
                step: i / 2,
                sample_tick: i,
                commands: u32::from(i == 0),
            }))
            .expect("step");
        }
    }
    // No drops, so a whole schedule is what the mutations start from.
    w.finish(0).expect("end").0
}

/// Recomputes the header's, every block's and the end marker's CRC (layout at the top of
/// `devices/src/record/format.rs`), as far as the lengths in the file can be followed.
pub fn refresh_recording_checksums(bytes: &mut [u8]) {
    let n = bytes.len();
    if n < 14 {
        return;
    }
    let info_len = u32::from_le_bytes(bytes[10..14].try_into().unwrap()) as usize;
    let Some(crc_at) = 14usize.checked_add(info_len) else {
        return;
    };
    if crc_at + 4 > n {
        return;
    }
    let crc = crc32fast::hash(&bytes[8..crc_at]);
    bytes[crc_at..crc_at + 4].copy_from_slice(&crc.to_le_bytes());
    let mut pos = crc_at + 4;
    while pos + 4 <= n {
        match &bytes[pos..pos + 4] {
            b"DCBK" if pos + 20 <= n => {
                let len = u32::from_le_bytes(bytes[pos + 12..pos + 16].try_into().unwrap());
                let end = pos + 20 + len as usize;
                if end > n {
                    return;
                }
                let mut h = crc32fast::Hasher::new();
                h.update(&bytes[pos + 4..pos + 16]);
                h.update(&bytes[pos + 20..end]);
                bytes[pos + 16..pos + 20].copy_from_slice(&h.finalize().to_le_bytes());
                pos = end;
            }
            b"DCEN" if pos + 28 <= n => {
                let crc = crc32fast::hash(&bytes[pos + 4..pos + 24]);
                bytes[pos + 24..pos + 28].copy_from_slice(&crc.to_le_bytes());
                return;
            }
            _ => return,
        }
    }
}

/// A damaged recording: the fixture mutated, checksums recomputed (one case in eight left).
pub fn recording_case() -> impl Strategy<Value = Vec<u8>> {
    (mutations(), 0u8..8).prop_map(|(m, keep_crc)| {
        let mut bytes = valid_recording_bytes();
        mutate_bytes(&mut bytes, &m);
        if keep_crc != 0 {
            refresh_recording_checksums(&mut bytes);
        }
        bytes
    })
}

/// Parses a damaged recording and builds a replay from it; within the heap bound.
///
/// # Errors
/// A failed check.
pub fn check_recording(bytes: &[u8]) -> Result<(), TestCaseError> {
    let (outcome, peak) = peak_heap_during(|| {
        Recording::parse(bytes).map(|r| {
            let replay = ReplayDevice::from_recording(r);
            // A schedule that is accepted is whole: every step's sample is in it.
            if let Ok(schedule) = replay.schedule() {
                let ticks = schedule.ticks.len() as u64;
                assert!(schedule.steps.iter().all(|s| s.sample_tick <= ticks));
            }
            replay.read_count()
        })
    });
    prop_assert!(
        peak <= heap_bound(bytes.len()),
        "parsing {} bytes took {peak} bytes of heap",
        bytes.len()
    );
    match outcome {
        Err(e) => prop_assert!(!e.to_string().is_empty()),
        Ok(_) => accepted(2),
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Point clouds.

/// A small cloud in each text and binary form the importer reads: XYZ with normals, ASCII
/// PLY and binary little-endian PLY, with normals and colours.
#[must_use]
pub fn valid_cloud_bytes(form: u8) -> Vec<u8> {
    let points: Vec<[f32; 6]> = (0..40)
        .map(|i| {
            let t = i as f32 * 0.37;
            [t.sin(), t.cos(), t * 0.1, t.sin(), t.cos(), 0.0]
        })
        .collect();
    match form % 3 {
        0 => points
            .iter()
            .map(|p| format!("{} {} {} {} {} {}\n", p[0], p[1], p[2], p[3], p[4], p[5]))
            .collect::<String>()
            .into_bytes(),
        1 => {
            let mut text = format!(
                "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
                 property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
                 property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
                points.len()
            );
            for p in &points {
                text += &format!(
                    "{} {} {} {} {} {} 200 100 50\n",
                    p[0], p[1], p[2], p[3], p[4], p[5]
                );
            }
            text.into_bytes()
        }
        _ => {
            let mut bytes = format!(
                "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
                 property float y\nproperty float z\nproperty float nx\nproperty float ny\n\
                 property float nz\nend_header\n",
                points.len()
            )
            .into_bytes();
            for p in &points {
                for v in p {
                    bytes.extend_from_slice(&v.to_le_bytes());
                }
            }
            bytes
        }
    }
}

/// A damaged point cloud: one of the three forms, mutated.
pub fn cloud_case() -> impl Strategy<Value = (u8, Vec<u8>)> {
    (mutations(), 0u8..3).prop_map(|(m, form)| {
        let mut bytes = valid_cloud_bytes(form);
        mutate_bytes(&mut bytes, &m);
        (form, bytes)
    })
}

/// Parses a damaged cloud as its form says: an error naming the file, or a cloud whose
/// points (and normals, when it has them) are all finite; within the heap bound.
///
/// # Errors
/// A failed check.
pub fn check_cloud(form: u8, bytes: &[u8]) -> Result<(), TestCaseError> {
    let file = Path::new("damaged.ply");
    let (parsed, peak) = peak_heap_during(|| {
        if form.is_multiple_of(3) {
            parse_xyz(bytes, file)
        } else {
            parse_ply(bytes, file)
        }
    });
    prop_assert!(
        peak <= heap_bound(bytes.len()),
        "parsing {} bytes took {peak} bytes of heap",
        bytes.len()
    );
    match parsed {
        Err(e) => {
            let text = e.to_string();
            prop_assert!(
                text.contains("damaged.ply"),
                "the error names the file: {text}"
            );
        }
        Ok(cloud) => {
            prop_assert!(cloud.points.iter().all(|p| p.is_finite()));
            accepted(3);
        }
    }
    Ok(())
}
