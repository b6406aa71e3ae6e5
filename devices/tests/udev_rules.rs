//! The shipped udev rules cover every USB ID the drivers recognise.

use dynaclay_devices::enumerate::{CARTESIAN_HID_ID, FALCON_ID, WOODENHAPTICS_ID};
use dynaclay_devices::spacemouse::SPACEMOUSE_IDS;

#[test]
fn udev_rules_list_every_supported_id() {
    let rules = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/udev/99-dynaclay.rules")).unwrap();
    let mut ids: Vec<(u16, u16)> = SPACEMOUSE_IDS.to_vec();
    ids.extend([WOODENHAPTICS_ID, CARTESIAN_HID_ID, FALCON_ID]);
    for (vid, pid) in ids {
        let covered = rules.lines().filter(|l| !l.trim_start().starts_with('#')).any(|l| {
            l.contains(&format!("ATTRS{{idVendor}}==\"{vid:04x}\"")) && l.contains(&format!("{pid:04x}"))
        });
        assert!(covered, "no udev rule for {vid:04x}:{pid:04x}");
    }
}
