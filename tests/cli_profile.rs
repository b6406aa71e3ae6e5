//! `dynaclay profile` end to end: the report's sections, the files `--out` writes, `--compare`
//! on them, and argument errors. No figure measured here is asserted, only that it is reported.

use std::process::Command;

use dynaclay_loops::ProfileDoc;

const BIN: &str = env!("CARGO_BIN_EXE_dynaclay");

/// The width and height in a PNG's header, after decoding the whole image.
fn png_size(path: &std::path::Path) -> (u32, u32) {
    let file = std::io::BufReader::new(std::fs::File::open(path).expect("png opens"));
    let mut reader = png::Decoder::new(file).read_info().expect("png header");
    let mut buf = vec![0; reader.output_buffer_size().expect("buffer size")];
    let info = reader.next_frame(&mut buf).expect("png decodes");
    (info.width, info.height)
}

#[test]
fn profile_reports_probe_and_verdict_and_compares_its_own_json() {
    let dir = std::env::temp_dir().join(format!("dynaclay-cli-profile-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out = Command::new(BIN)
        .args(["profile", "--seconds", "0.5", "--no-rt", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for section in [
        "## Loops",
        "## Haptic loop beside the platform probe",
        "| wake-up latency p99.9 µs |",
        "host stalls (gaps ≥ 20 µs)",
        "1000 Hz: ",
        "4000 Hz: ",
        "real-time priority not granted",
    ] {
        assert!(text.contains(section), "missing {section} in\n{text}");
    }

    let json_path = dir.join("latency.json");
    let doc = ProfileDoc::from_json(&std::fs::read_to_string(&json_path).unwrap()).unwrap();
    assert!(doc.probe_before.is_some() && doc.probe_after.is_some());
    assert_eq!(doc.readiness.len(), 2);
    assert_eq!(doc.facts.as_ref().and_then(|f| f.rt_granted), Some(false));
    // The verdict took the stall probe's gaps by length and the haptic loop's own record.
    let facts = doc.facts.as_ref().unwrap();
    assert!(facts.stalls.is_some_and(|s| s.gap_counts.is_some()));
    assert_eq!(facts.haptic_loop.map(|l| l.rate_hz), Some(1000.0));
    let md = std::fs::read_to_string(dir.join("latency.md")).unwrap();
    assert!(md.contains("## Readiness"));
    let svg = std::fs::read_to_string(dir.join("latency.svg")).unwrap();
    assert!(svg.contains("haptic: over the run") && svg.contains("p99.9 "));
    // The same page as a PNG: one row of plots per loop.
    assert_eq!(
        png_size(&dir.join("latency.png")),
        dynaclay_loops::page_size(doc.loops.len())
    );

    let cmp = Command::new(BIN)
        .args(["profile", "--compare"])
        .arg(&json_path)
        .arg(&json_path)
        .output()
        .unwrap();
    let table = String::from_utf8_lossy(&cmp.stdout);
    assert!(cmp.status.success(), "{table}");
    // A file against itself: every ratio that exists is exactly 1.
    let ratios: Vec<&str> = table
        .lines()
        .filter(|l| l.starts_with("| haptic |") || l.starts_with("| probe |"))
        .map(|l| l.trim_end_matches(" |").rsplit("| ").next().unwrap_or(""))
        .collect();
    assert!(ratios.len() >= 15, "{table}");
    assert!(ratios.iter().all(|r| *r == "1.00" || *r == "—"), "{table}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_rate_and_missing_compare_file_fail_clearly() {
    let out = Command::new(BIN)
        .args(["profile", "--rate-hz", "2000"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("give 1000 or 4000"));

    let out = Command::new(BIN)
        .args([
            "profile",
            "--compare",
            "/nonexistent/a.json",
            "/nonexistent/b.json",
        ])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/a.json"));
}
