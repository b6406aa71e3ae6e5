//! The shipped udev rules cover every USB device in the table of supported devices, on the
//! subsystem of the node its driver opens, and tag it for the logged-in user early enough.

use dynaclay_devices::enumerate::UDEV_RULES;
use dynaclay_devices::usb_ids::{NodeKind, ProductMatch, SUPPORTED_USB};

/// Rule lines (comments and blank lines dropped).
fn rules() -> Vec<&'static str> {
    UDEV_RULES
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .collect()
}

#[test]
fn the_rules_file_in_the_repository_is_the_one_the_binary_prints() {
    let on_disk = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/udev/70-dynaclay.rules"
    ))
    .unwrap();
    assert_eq!(on_disk, UDEV_RULES);
}

#[test]
fn udev_rules_grant_access_to_every_supported_device_on_its_node() {
    let rules = rules();
    for e in SUPPORTED_USB {
        let node_match = match e.node {
            NodeKind::Hidraw => "KERNEL==\"hidraw*\"",
            NodeKind::Tty => "SUBSYSTEM==\"tty\"",
            NodeKind::RawUsb => "SUBSYSTEM==\"usb\"",
        };
        let vendor = format!("ATTRS{{idVendor}}==\"{:04x}\"", e.vendor_id);
        let covered = rules.iter().any(|l| {
            l.contains(node_match)
                && l.contains(&vendor)
                && l.contains("TAG+=\"uaccess\"")
                && match e.product {
                    ProductMatch::Exact(pid) => l.contains(&format!("{pid:04x}")),
                    ProductMatch::AnyFromVendor => !l.contains("idProduct"),
                }
        });
        assert!(
            covered,
            "no {node_match} rule for {} ({:04x}:{:?})",
            e.name, e.vendor_id, e.product
        );
    }
}

#[test]
fn the_falcon_latency_timer_is_set_to_one_millisecond_at_plug_in() {
    assert!(
        rules()
            .iter()
            .any(|l| l.contains("SUBSYSTEM==\"usb-serial\"")
                && l.contains("ATTRS{idProduct}==\"cb48\"")
                && l.contains("ATTR{latency_timer}=\"1\"")),
        "{UDEV_RULES}"
    );
}
