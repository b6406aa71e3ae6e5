//! Malformed session files (of the current format: bricked lattices, mapped patches, material
//! grids, pins), scripts, recordings (with the engine's schedule) and point clouds (XYZ, ASCII
//! and binary PLY) are refused with a typed error, never a panic, and parsing one never takes
//! more heap than a bound on its size (see `tests/fuzz/mod.rs` for the mutations and the
//! bound). 256 cases per format here; the long
//! run of a million or more is `cargo bench --bench fuzz_inputs` (figures in bench/RESULTS.md).

mod fuzz;

use proptest::prelude::*;

#[global_allocator]
static HEAP: fuzz::PeakAlloc = fuzz::PeakAlloc;

#[test]
fn the_fixtures_themselves_parse() {
    let mut bytes = fuzz::valid_session_bytes();
    fuzz::refresh_session_checksums(&mut bytes);
    assert!(dynaclay::io::decode(&bytes, std::path::Path::new("fixture.dclay")).is_ok());
    let mut rec = fuzz::valid_recording_bytes();
    let original = rec.clone();
    fuzz::refresh_recording_checksums(&mut rec);
    assert_eq!(
        rec, original,
        "checksums recomputed as the writer made them"
    );
    let parsed = dynaclay_devices::Recording::parse(&rec).unwrap();
    // 150 reads, 150 writes, 150 ticks and 75 steps.
    assert_eq!(parsed.records.len(), 525);
    let replay = dynaclay_devices::ReplayDevice::from_recording(parsed);
    assert_eq!(replay.schedule().unwrap().steps.len(), 75);
    let session = dynaclay::io::decode(&bytes, std::path::Path::new("fixture.dclay")).unwrap();
    assert_eq!(session.clay.density.patches.len(), 2);
    assert_eq!(session.material.grids.len(), 2);
    assert_eq!(session.clay.constraints.len(), 3);
    for form in 0..3 {
        fuzz::check_cloud(form, &fuzz::valid_cloud_bytes(form)).unwrap();
    }
    fuzz::check_script(dynaclay::engine::DEFAULT_SCRIPT).unwrap();
}

#[test]
fn a_length_field_that_is_trusted_would_break_the_heap_bound() {
    // The bound is tight enough to catch a decoder that allocates what a header claims.
    let (_, peak) = fuzz::peak_heap_during(|| vec![0u8; 64 << 20]);
    assert!(peak > fuzz::heap_bound(1 << 20));
}

#[test]
fn a_bricked_lattice_claiming_a_huge_box_is_refused_before_it_is_allocated() {
    // Format 4 stores a lattice as brick records: a few bytes can claim any box. The first
    // patch's dims (the first 12 bytes of its payload, after META) set to 2^20 each, its brick
    // count to match, checksums made valid: refused against the clay's budget, within the heap
    // bound of the file's size.
    let mut bytes = fuzz::valid_session_bytes();
    let meta_len = u64::from_le_bytes(bytes[28..36].try_into().unwrap()) as usize;
    let patch = 24 + 16 + meta_len;
    assert_eq!(&bytes[patch..patch + 4], b"PTCH");
    let payload = patch + 12;
    for axis in 0..3 {
        let at = payload + 4 * axis;
        bytes[at..at + 4].copy_from_slice(&(1_u32 << 20).to_le_bytes());
    }
    let bricks_at = payload + 12 + 4 + 12 + 4;
    bytes[bricks_at..bricks_at + 8].copy_from_slice(&(1_u64 << 51).to_le_bytes());
    fuzz::refresh_session_checksums(&mut bytes);
    let (decoded, peak) =
        fuzz::peak_heap_during(|| dynaclay::io::decode(&bytes, std::path::Path::new("huge.dclay")));
    let err = decoded.unwrap_err().to_string();
    assert!(
        err.contains("huge.dclay") && err.contains("PTCH") && err.contains("at most"),
        "{err}"
    );
    assert!(
        peak <= fuzz::heap_bound(bytes.len()),
        "{peak} bytes of heap"
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn damaged_sessions_are_refused_or_load_whole(bytes in fuzz::session_case()) {
        fuzz::check_session(&bytes)?;
    }

    #[test]
    fn edited_scripts_are_refused_or_laid_out(text in fuzz::script_case()) {
        fuzz::check_script(&text)?;
    }

    #[test]
    fn damaged_recordings_are_refused_or_replayed(bytes in fuzz::recording_case()) {
        fuzz::check_recording(&bytes)?;
    }

    #[test]
    fn damaged_point_clouds_are_refused_or_read_whole((form, bytes) in fuzz::cloud_case()) {
        fuzz::check_cloud(form, &bytes)?;
    }
}
