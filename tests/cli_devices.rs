//! `dynaclay devices` through the command line: the listing, the udev rules it prints, and
//! the doctor on the simulated arm. Nothing here asserts a rate: the doctor's statistics are
//! checked on injected timestamps in the devices crate.

use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_dynaclay");

#[test]
fn the_listing_succeeds_and_says_how_to_measure_a_device() {
    let out = Command::new(BIN).arg("devices").output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("--device sim"), "{text}");
    assert!(text.contains("--doctor SPEC"), "{text}");
    assert!(text.contains("vendor OpenHaptics"), "{text}");
}

#[test]
fn udev_rules_prints_the_shipped_rules_file() {
    let out = Command::new(BIN)
        .args(["devices", "--udev-rules"])
        .output()
        .unwrap();
    assert!(out.status.success());
    let shipped = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/devices/udev/70-dynaclay.rules"
    ))
    .unwrap();
    assert_eq!(String::from_utf8_lossy(&out.stdout), shipped);
}

#[test]
fn the_doctor_runs_the_simulated_arm_and_reports_rate_and_period_percentiles() {
    let out = Command::new(BIN)
        .args(["devices", "--doctor", "sim", "--seconds", "0.1"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");
    assert!(
        text.contains("simulated arm:") && text.contains("zero force every tick"),
        "{text}"
    );
    assert!(text.contains(", 0 failed"), "{text}");
    for field in [
        "read rate:",
        "fresh-sample rate:",
        "p50",
        "p99",
        "max",
        "verdict:",
    ] {
        assert!(text.contains(field), "{field} missing from {text}");
    }
}

#[test]
fn the_doctor_refuses_what_is_not_a_device_and_bad_specs() {
    for (spec, code) in [("replay:x.dcrec", 2), ("mouse", 2), ("usb:3", 2)] {
        let out = Command::new(BIN)
            .args(["devices", "--doctor", spec])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(code), "{spec}");
    }
    let out = Command::new(BIN)
        .args(["devices", "--doctor", "sim", "--seconds", "600"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "the duration is bounded");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("0.05 ≤ N ≤ 60"), "{stderr}");
}
