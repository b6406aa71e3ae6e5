//! `dynaclay` with the vendor-library arms, end to end through the command line: a headless run
//! with `--device touch` and `--device dhd` against the stand-in library
//! (`libdynaclay_vendor_standin.so`, a dev-dependency built beside this test), the typed error
//! when the library is missing, `dynaclay devices` reporting each library, and `--lockstep`
//! refused for them.
//!
//! The runs are real-time sessions (the stand-in's HD scheduler runs its own servo thread, as
//! OpenHaptics does); the tests assert what the run produced and said, never rates or times.

use std::path::PathBuf;
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_dynaclay");
const STANDIN_FILE: &str = "libdynaclay_vendor_standin.so";

/// The stand-in library beside this test executable (target/<profile>/deps or its parent).
fn standin_path() -> PathBuf {
    let exe = std::env::current_exe().expect("the test executable's path");
    exe.ancestors()
        .skip(1)
        .take(2)
        .map(|dir| dir.join(STANDIN_FILE))
        .find(|p| p.exists())
        .unwrap_or_else(|| {
            panic!(
                "{STANDIN_FILE} is not beside the test executable {} (looked in its folder and \
                 the one above); build it with `cargo build --release -p \
                 dynaclay-vendor-standin` (it is a dev-dependency, so `cargo test` builds it)",
                exe.display()
            )
        })
}

fn dynaclay() -> Command {
    let mut c = Command::new(BIN);
    c.env_remove("DYNACLAY_HD_LIB")
        .env_remove("DYNACLAY_DHD_LIB");
    c
}

#[test]
fn a_headless_run_sculpts_through_each_vendor_arm_on_the_standin() {
    let standin = standin_path();
    for (device, env) in [
        ("touch", "DYNACLAY_HD_LIB"),
        ("phantom", "DYNACLAY_HD_LIB"),
        ("dhd", "DYNACLAY_DHD_LIB"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        let run = dynaclay()
            .env(env, &standin)
            .args([
                "run",
                "--seconds",
                "0.5",
                "--no-rt",
                "--device",
                device,
                "--out",
            ])
            .arg(&out)
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&run.stdout);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(
            run.status.success(),
            "{device}: exit {:?}\nstdout: {stdout}\nstderr: {stderr}",
            run.status.code()
        );
        assert!(
            stdout.contains(&format!("device {device}")),
            "{device}: {stdout}"
        );
        assert!(out.join("session.dclay").is_file(), "{device}: no session");
    }
}

#[test]
fn a_missing_vendor_library_stops_the_run_naming_it_where_it_looked_and_the_cure() {
    for (device, env, library, cure) in [
        (
            "touch",
            "DYNACLAY_HD_LIB",
            "libHD.so",
            "OpenHaptics for Linux",
        ),
        (
            "dhd:1",
            "DYNACLAY_DHD_LIB",
            "libdhd.so",
            "Force Dimension SDK",
        ),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("nowhere").join(library);
        let run = dynaclay()
            .env(env, &missing)
            .args([
                "run",
                "--seconds",
                "0.5",
                "--no-rt",
                "--device",
                device,
                "--out",
            ])
            .arg(dir.path().join("out"))
            .output()
            .unwrap();
        assert_eq!(run.status.code(), Some(3), "{device}: a device failure");
        let stderr = String::from_utf8_lossy(&run.stderr);
        for needle in [library, &missing.display().to_string(), cure, env] {
            assert!(
                stderr.contains(needle),
                "{device}: {needle} missing from {stderr}"
            );
        }
    }
}

#[test]
fn devices_reports_each_vendor_library_found_or_not() {
    let standin = standin_path();
    let dir = tempfile::tempdir().unwrap();
    let out = dynaclay()
        .env("DYNACLAY_DHD_LIB", &standin)
        .env("DYNACLAY_HD_LIB", dir.path().join("libHD.so"))
        .arg("devices")
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    let line = |label: &str| {
        text.lines()
            .find(|l| l.contains(label))
            .unwrap_or_else(|| panic!("no line for {label} in:\n{text}"))
            .to_string()
    };
    let dhd = line("libdhd.so");
    assert!(
        dhd.contains(&format!("found ({})", standin.display())) && dhd.contains("--device dhd"),
        "{dhd}"
    );
    let hd = line("libHD.so)");
    assert!(
        hd.contains("not found") && hd.contains("--device touch") && hd.contains("3D Systems"),
        "{hd}"
    );
}

#[test]
fn lockstep_is_refused_for_the_vendor_arms() {
    let dir = tempfile::tempdir().unwrap();
    let run = dynaclay()
        .env("DYNACLAY_HD_LIB", standin_path())
        .args(["run", "--lockstep", "--device", "touch", "--out"])
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("--lockstep") && stderr.contains("touch"),
        "{stderr}"
    );
}

#[test]
fn the_doctor_opens_each_vendor_arm_through_its_stand_in_and_reports_its_reads() {
    for (spec, var) in [("dhd", "DYNACLAY_DHD_LIB"), ("touch", "DYNACLAY_HD_LIB")] {
        let out = dynaclay()
            .env(var, standin_path())
            .args(["devices", "--doctor", spec, "--seconds", "0.2"])
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{spec}: {text}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        // Whatever rate this machine reached, the report names the period percentiles and
        // no read failed.
        assert!(text.contains("zero force every tick"), "{spec}: {text}");
        assert!(text.contains(", 0 failed"), "{spec}: {text}");
        assert!(
            text.contains("read rate:") && text.contains("p99") && text.contains("verdict:"),
            "{spec}: {text}"
        );
    }
}

#[test]
fn the_doctor_without_the_vendor_library_says_which_library_and_how_to_install_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dynaclay()
        .env("DYNACLAY_DHD_LIB", dir.path().join("libdhd.so"))
        .args(["devices", "--doctor", "dhd"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(3), "a device error");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("cannot open dhd")
            && text.contains("libdhd.so")
            && text.contains("Force Dimension SDK"),
        "{text}"
    );
}
