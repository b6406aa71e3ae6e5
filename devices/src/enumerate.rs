//! What is connected: HID devices and serial ports, which of them dynaclay supports, and
//! whether this user may open them.
//!
//! HID enumeration reads sysfs through hidapi (no permission needed); serial enumeration uses
//! serialport's sysfs scan. Access is checked with `access(2)` on the device node, so nothing
//! is opened (opening a tty would toggle DTR and reset some boards). Arms reached through a
//! vendor library (OpenHaptics, Force Dimension) are not enumerated here; [`vendor_report`]
//! says whether each library loads. Not for the haptic path.

use std::fmt::Write as _;

pub use crate::node_access::{Access, access};
use crate::spacemouse::SPACEMOUSE_IDS;
use crate::vendor_lib::{LibraryMissing, VendorLibrary};

/// USB IDs of the Novint Falcon's FTDI bridge.
pub const FALCON_ID: (u16, u16) = (0x0403, 0xcb48);
/// USB IDs of the WoodenHaptics / Polhem HID firmware (mbed's USBHID defaults).
pub const WOODENHAPTICS_ID: (u16, u16) = (0x1234, 0x0006);
/// USB IDs of the Cartesian HID reference firmware (pid.codes test ID).
pub const CARTESIAN_HID_ID: (u16, u16) = (0x1209, 0x0001);

/// How the device is attached.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transport {
    /// A hidraw node.
    Hid,
    /// A tty.
    Serial,
}

/// One connected device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Connected {
    /// HID or serial.
    pub transport: Transport,
    /// Device node, e.g. `/dev/hidraw3` or `/dev/ttyUSB0`.
    pub path: String,
    /// USB vendor ID (0 when not a USB device).
    pub vendor_id: u16,
    /// USB product ID.
    pub product_id: u16,
    /// Product string, if the device gives one.
    pub product: Option<String>,
    /// What dynaclay would open it as, as a `--device` spec, if supported.
    pub spec: Option<String>,
    /// Permission to open the node.
    pub access: Access,
}

/// The `--device` spec for a supported USB device.
#[must_use]
pub fn supported_spec(transport: Transport, vid: u16, pid: u16, path: &str) -> Option<String> {
    match transport {
        Transport::Hid if SPACEMOUSE_IDS.contains(&(vid, pid)) => Some("spacemouse".into()),
        Transport::Hid if (vid, pid) == WOODENHAPTICS_ID => Some("hid:woodenhaptics".into()),
        Transport::Hid if (vid, pid) == CARTESIAN_HID_ID => Some("hid:cartesian-hid".into()),
        Transport::Serial if (vid, pid) == FALCON_ID => Some(format!("falcon:{path}")),
        _ => None,
    }
}

/// Lists HID devices (one entry per hidraw node).
///
/// # Errors
/// The hidapi error text when HID enumeration itself fails.
pub fn list_hid() -> Result<Vec<Connected>, String> {
    let api = hidapi::HidApi::new().map_err(|e| format!("HID enumeration failed: {e}"))?;
    let mut out: Vec<Connected> = Vec::new();
    for d in api.device_list() {
        let path = d.path().to_string_lossy().into_owned();
        if out.iter().any(|c| c.path == path) {
            continue;
        }
        let (vid, pid) = (d.vendor_id(), d.product_id());
        out.push(Connected {
            transport: Transport::Hid,
            spec: supported_spec(Transport::Hid, vid, pid, &path),
            access: access(&path),
            path,
            vendor_id: vid,
            product_id: pid,
            product: d.product_string().map(str::to_string),
        });
    }
    Ok(out)
}

/// Lists serial ports.
///
/// # Errors
/// The serialport error text when enumeration fails.
pub fn list_serial() -> Result<Vec<Connected>, String> {
    let ports = serialport::available_ports()
        .map_err(|e| format!("serial port enumeration failed: {e}"))?;
    Ok(ports
        .into_iter()
        .map(|p| {
            let (vid, pid, product) = match &p.port_type {
                serialport::SerialPortType::UsbPort(u) => (u.vid, u.pid, u.product.clone()),
                _ => (0, 0, None),
            };
            Connected {
                transport: Transport::Serial,
                spec: supported_spec(Transport::Serial, vid, pid, &p.port_name),
                access: access(&p.port_name),
                path: p.port_name,
                vendor_id: vid,
                product_id: pid,
                product,
            }
        })
        .collect())
}

/// Lists everything; enumeration failures become notes instead of errors.
#[must_use]
pub fn list_all() -> (Vec<Connected>, Vec<String>) {
    let mut all = Vec::new();
    let mut notes = Vec::new();
    for r in [list_hid(), list_serial()] {
        match r {
            Ok(v) => all.extend(v),
            Err(e) => notes.push(e),
        }
    }
    (all, notes)
}

/// Human-readable report for `dynaclay devices`: one line per device, supported ones marked,
/// and a clear explanation when permissions are missing.
#[must_use]
pub fn report(devices: &[Connected], notes: &[String]) -> String {
    let mut s = String::new();
    if devices.is_empty() {
        s.push_str("No HID devices or serial ports found.\n");
    }
    let mut denied = Vec::new();
    for d in devices {
        let kind = match d.transport {
            Transport::Hid => "hid   ",
            Transport::Serial => "serial",
        };
        let ids = if d.vendor_id == 0 && d.product_id == 0 {
            "---------".to_string()
        } else {
            format!("{:04x}:{:04x}", d.vendor_id, d.product_id)
        };
        let access = match d.access {
            Access::Ok => "",
            Access::Denied => "  [permission denied]",
            Access::Missing => "  [node missing]",
        };
        let supported = d
            .spec
            .as_deref()
            .map(|spec| format!("  supported: --device {spec}"))
            .unwrap_or_default();
        let _ = writeln!(
            s,
            "{kind} {ids} {:<16} {}{supported}{access}",
            d.path,
            d.product.as_deref().unwrap_or("")
        );
        if d.access == Access::Denied && d.spec.is_some() {
            denied.push(d.path.as_str());
        }
    }
    if !denied.is_empty() {
        let _ = writeln!(
            s,
            "\nPermission missing: this user cannot read and write {}.\n\
             Install the udev rules: sudo cp devices/udev/99-dynaclay.rules /etc/udev/rules.d/ \
             && sudo udevadm control --reload-rules && sudo udevadm trigger, then replug the device.",
            denied.join(", ")
        );
    }
    for n in notes {
        let _ = writeln!(s, "note: {n}");
    }
    s
}

/// Whether each vendor library loads from where its `--device` spec would look (loading it
/// runs its initialisers; no device is opened).
#[must_use]
pub fn vendor_libraries() -> Vec<(VendorLibrary, Result<String, LibraryMissing>)> {
    crate::vendor_lib::probe_all()
}

/// Human-readable lines for `dynaclay devices`: per vendor library, where it was found and the
/// spec that uses it, or that it was not found, where it was looked for and how to install it.
#[must_use]
pub fn vendor_report(libraries: &[(VendorLibrary, Result<String, LibraryMissing>)]) -> String {
    let mut s = String::new();
    for (library, found) in libraries {
        match found {
            Ok(from) => {
                let _ = writeln!(
                    s,
                    "vendor {}: found ({from}); arms through it: --device {}",
                    library.label(),
                    library.spec()
                );
            }
            Err(missing) => {
                let _ = writeln!(
                    s,
                    "vendor {}: not found; --device {} needs it ({missing})",
                    library.label(),
                    library.spec()
                );
            }
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn supported_ids_map_to_specs() {
        assert_eq!(
            supported_spec(Transport::Hid, 0x046d, 0xc626, "/dev/hidraw0").as_deref(),
            Some("spacemouse")
        );
        assert_eq!(
            supported_spec(Transport::Hid, 0x256f, 0xc635, "/dev/hidraw0").as_deref(),
            Some("spacemouse")
        );
        assert_eq!(
            supported_spec(Transport::Hid, 0x1234, 0x0006, "/dev/hidraw1").as_deref(),
            Some("hid:woodenhaptics")
        );
        assert_eq!(
            supported_spec(Transport::Serial, 0x0403, 0xcb48, "/dev/ttyUSB0").as_deref(),
            Some("falcon:/dev/ttyUSB0")
        );
        assert_eq!(
            supported_spec(Transport::Serial, 0x0403, 0x6001, "/dev/ttyUSB0"),
            None
        );
    }

    #[test]
    fn report_explains_missing_permissions() {
        let d = Connected {
            transport: Transport::Hid,
            path: "/dev/hidraw7".into(),
            vendor_id: 0x256f,
            product_id: 0xc635,
            product: Some("SpaceMouse Compact".into()),
            spec: Some("spacemouse".into()),
            access: Access::Denied,
        };
        let r = report(&[d], &[]);
        assert!(
            r.contains("256f:c635") && r.contains("--device spacemouse"),
            "{r}"
        );
        assert!(
            r.contains("[permission denied]")
                && r.contains("99-dynaclay.rules")
                && r.contains("/dev/hidraw7"),
            "{r}"
        );
        assert!(report(&[], &["x".into()]).contains("No HID devices"));
    }

    #[test]
    fn the_vendor_report_says_found_or_where_it_looked_and_how_to_install() {
        use crate::vendor_lib::TriedCandidate;
        let found = (
            VendorLibrary::OpenHapticsHd,
            Ok("/usr/lib/libHD.so".to_string()),
        );
        let missing = (
            VendorLibrary::ForceDimensionDhd,
            Err(LibraryMissing {
                library: VendorLibrary::ForceDimensionDhd,
                tried: vec![TriedCandidate {
                    candidate: "libdhd.so".into(),
                    reason: "cannot open shared object file".into(),
                }],
            }),
        );
        let r = vendor_report(&[found, missing]);
        let lines: Vec<&str> = r.lines().collect();
        assert_eq!(lines.len(), 2, "{r}");
        assert!(
            lines[0].contains("libHD.so")
                && lines[0].contains("found (/usr/lib/libHD.so)")
                && lines[0].contains("--device touch"),
            "{r}"
        );
        assert!(
            lines[1].contains("not found")
                && lines[1].contains("--device dhd")
                && lines[1].contains("cannot open shared object file")
                && lines[1].contains("Force Dimension SDK"),
            "{r}"
        );
    }

    #[test]
    fn this_machine_gets_one_vendor_line_per_library() {
        let libs = vendor_libraries();
        assert_eq!(libs.len(), VendorLibrary::ALL.len());
        let r = vendor_report(&libs);
        for (library, found) in &libs {
            let line = r
                .lines()
                .find(|l| l.contains(library.label()))
                .unwrap_or_else(|| panic!("{} missing from:\n{r}", library.label()));
            assert_eq!(line.contains(": found ("), found.is_ok(), "{line}");
        }
    }

    #[test]
    fn listing_this_machine_gives_a_line_per_device_and_a_spec_for_each_supported_one() {
        // Whatever this machine has connected (often nothing): the report has one line per
        // device naming its path, or says there are none, and every device the listing marks
        // as supported carries the spec `supported_spec` gives for its ids.
        let (devices, notes) = list_all();
        let text = report(&devices, &notes);
        if devices.is_empty() {
            assert!(
                text.starts_with("No HID devices or serial ports found."),
                "{text}"
            );
        }
        for d in &devices {
            assert!(text.contains(&d.path), "{} missing from:\n{text}", d.path);
            assert_eq!(
                d.spec,
                supported_spec(d.transport, d.vendor_id, d.product_id, &d.path),
                "{}",
                d.path
            );
        }
        assert_eq!(text.matches("note: ").count(), notes.len());
    }
}
