//! What is connected: every supported arm and SpaceMouse by its USB IDs (the table in
//! [`crate::usb_ids`]), every other HID device and serial port, and for each whether this
//! user can open it and, if not, why: no permission (with the udev rules to install), the node
//! held by another program, a missing vendor library, no kernel node.
//!
//! HID enumeration reads sysfs through hidapi (no permission needed); serial enumeration uses
//! serialport's sysfs scan; arms a vendor library talks to over raw USB (Force Dimension) are
//! found in `/sys/bus/usb/devices`. Access is checked with `access(2)` on the node and holders
//! are found by scanning `/proc/*/fd` ([`crate::node_holders`]), so nothing is opened
//! (opening a tty would toggle DTR and reset some boards). Whether a Falcon's firmware answers
//! is only known by talking to it: `dynaclay devices --doctor falcon:PATH` does. Not for the
//! haptic path.

use std::fmt::Write as _;
use std::path::Path;

use crate::ftdi_latency;
pub use crate::node_access::{Access, access};
use crate::node_holders::{Holder, holders_of};
pub use crate::usb_ids::{CARTESIAN_HID_ID, FALCON_ID, WOODENHAPTICS_ID};
use crate::usb_ids::{Needs, NodeKind, SupportedUsb, lookup};
use crate::vendor_lib::{LibraryMissing, VendorLibrary};

/// The shipped udev rules (`devices/udev/70-dynaclay.rules`), printed by
/// `dynaclay devices --udev-rules`.
pub const UDEV_RULES: &str = include_str!("../udev/70-dynaclay.rules");
/// Where the udev rules are installed. The number must stay below 73: systemd-logind's
/// `73-seat-late.rules` applies the `uaccess` tag, so a later file's tag is ignored.
pub const UDEV_RULES_INSTALLED: &str = "/etc/udev/rules.d/70-dynaclay.rules";
/// The command that installs the udev rules and applies them to what is plugged in.
pub const UDEV_INSTALL_COMMAND: &str = "dynaclay devices --udev-rules | sudo tee /etc/udev/rules.d/70-dynaclay.rules >/dev/null && sudo udevadm control --reload-rules && sudo udevadm trigger";

/// Where Linux lists USB devices.
pub const USB_SYSFS: &str = "/sys/bus/usb/devices";
/// Most entries read from a sysfs folder (a bound far above any machine's USB device count).
const MAX_SYSFS_ENTRIES: usize = 4096;

/// How the device is attached.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transport {
    /// A hidraw node.
    Hid,
    /// A tty.
    Serial,
    /// A raw USB device node (`/dev/bus/usb/BBB/DDD`).
    Usb,
}

/// Why a connected device cannot be opened (or may not be).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Problem {
    /// This user may not read and write the node: the udev rules fix it.
    PermissionDenied,
    /// The node vanished between enumeration and the check (unplugged).
    NodeMissing,
    /// Other programs hold the node open (found in `/proc/*/fd`).
    HeldBy(Vec<Holder>),
    /// The vendor library the arm is driven through does not load.
    LibraryMissing(LibraryMissing),
    /// The USB device is there but the kernel made no node of the kind its driver opens (the
    /// kernel driver is not bound, e.g. `ftdi_sio` for the Falcon).
    NoKernelNode {
        /// The kind of node expected.
        expected: NodeKind,
    },
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::PermissionDenied => {
                write!(f, "permission denied: install the udev rules (see below)")
            }
            Self::NodeMissing => write!(f, "the node is gone (unplugged?)"),
            Self::HeldBy(holders) => {
                write!(f, "held open by another program (found in /proc/*/fd):")?;
                for h in holders {
                    write!(f, " pid {} ({})", h.pid, h.command)?;
                }
                write!(f, "; close it first")
            }
            Self::LibraryMissing(m) => write!(f, "{m}"),
            Self::NoKernelNode { expected } => {
                let (what, driver) = match expected {
                    NodeKind::Hidraw => ("hidraw node", "usbhid"),
                    NodeKind::Tty => ("tty", "its serial driver (ftdi_sio, cdc_acm)"),
                    NodeKind::RawUsb => ("USB node", "usbfs"),
                };
                write!(
                    f,
                    "no {what}: the kernel has not bound {driver} to it (check `dmesg`)"
                )
            }
        }
    }
}

/// One connected device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Connected {
    /// HID, serial or raw USB.
    pub transport: Transport,
    /// Device node, e.g. `/dev/hidraw3`, `/dev/ttyUSB0` or `/dev/bus/usb/001/005`.
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
    /// What stands in the way of opening it (empty: nothing found).
    pub problems: Vec<Problem>,
    /// Things worth knowing that do not stop it opening (the FTDI latency timer, firmware).
    pub notes: Vec<String>,
}

/// The table entry for a device seen on `transport`, if its node is the one its driver opens.
#[must_use]
pub fn supported_entry(transport: Transport, vid: u16, pid: u16) -> Option<&'static SupportedUsb> {
    let entry = lookup(vid, pid)?;
    let opened_here = matches!(
        (transport, entry.node),
        (Transport::Hid, NodeKind::Hidraw)
            | (Transport::Serial, NodeKind::Tty)
            | (Transport::Usb, NodeKind::RawUsb)
    );
    opened_here.then_some(entry)
}

/// The `--device` spec for a supported USB device.
#[must_use]
pub fn supported_spec(transport: Transport, vid: u16, pid: u16, path: &str) -> Option<String> {
    supported_entry(transport, vid, pid).map(|e| e.spec_for(path))
}

fn connected(
    transport: Transport,
    path: String,
    vendor_id: u16,
    product_id: u16,
    product: Option<String>,
) -> Connected {
    Connected {
        transport,
        spec: supported_spec(transport, vendor_id, product_id, &path),
        access: access(&path),
        path,
        vendor_id,
        product_id,
        product,
        problems: Vec::new(),
        notes: Vec::new(),
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
        out.push(connected(
            Transport::Hid,
            path,
            d.vendor_id(),
            d.product_id(),
            d.product_string().map(str::to_string),
        ));
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
            connected(Transport::Serial, p.port_name, vid, pid, product)
        })
        .collect())
}

/// One USB device as sysfs describes it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UsbDevice {
    /// Bus number.
    pub bus: u16,
    /// Device number on the bus.
    pub device: u16,
    /// Vendor ID.
    pub vendor_id: u16,
    /// Product ID.
    pub product_id: u16,
    /// Product string.
    pub product: Option<String>,
}

impl UsbDevice {
    /// Its usbfs node, `/dev/bus/usb/BBB/DDD`.
    #[must_use]
    pub fn node(&self) -> String {
        format!("/dev/bus/usb/{:03}/{:03}", self.bus, self.device)
    }
}

fn sysfs_attr(dir: &Path, name: &str) -> Option<String> {
    use std::io::Read as _;
    let mut text = String::new();
    std::fs::File::open(dir.join(name))
        .ok()?
        .take(256)
        .read_to_string(&mut text)
        .ok()?;
    Some(text.trim().to_string())
}

/// Lists the USB devices (not interfaces) under `sysfs_root`, normally [`USB_SYSFS`].
#[must_use]
pub fn list_usb_at(sysfs_root: &Path) -> Vec<UsbDevice> {
    let Ok(entries) = std::fs::read_dir(sysfs_root) else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for e in entries.flatten().take(MAX_SYSFS_ENTRIES) {
        let dir = e.path();
        let hex = |name| sysfs_attr(&dir, name).and_then(|t| u16::from_str_radix(&t, 16).ok());
        let dec = |name| sysfs_attr(&dir, name).and_then(|t| t.parse::<u16>().ok());
        // Interfaces (`1-1:1.0`) have no idVendor; root hubs do and are kept (harmless).
        if let (Some(vendor_id), Some(product_id), Some(bus), Some(device)) = (
            hex("idVendor"),
            hex("idProduct"),
            dec("busnum"),
            dec("devnum"),
        ) {
            out.push(UsbDevice {
                bus,
                device,
                vendor_id,
                product_id,
                product: sysfs_attr(&dir, "product"),
            });
        }
    }
    out.sort_by_key(|d| (d.bus, d.device));
    out
}

/// Supported USB devices that the HID and serial lists do not already show: arms a vendor
/// library drives over raw USB, and supported devices whose kernel node is missing.
#[must_use]
pub fn supported_usb_entries(usb: &[UsbDevice], shown: &[Connected]) -> Vec<Connected> {
    let mut out = Vec::new();
    for d in usb {
        let Some(entry) = lookup(d.vendor_id, d.product_id) else {
            continue;
        };
        let mut c = connected(
            Transport::Usb,
            d.node(),
            d.vendor_id,
            d.product_id,
            d.product.clone(),
        );
        if entry.node != NodeKind::RawUsb {
            let has_node = shown
                .iter()
                .any(|s| s.vendor_id == d.vendor_id && s.product_id == d.product_id);
            if has_node {
                continue;
            }
            c.problems.push(Problem::NoKernelNode {
                expected: entry.node,
            });
        }
        out.push(c);
    }
    out
}

/// Fills in the problems found without opening: access and holders of each supported
/// device's node, and the Falcon's latency timer.
pub fn diagnose(devices: &mut [Connected]) {
    for d in devices.iter_mut().filter(|d| d.spec.is_some()) {
        match d.access {
            Access::Ok => {}
            Access::Denied => d.problems.push(Problem::PermissionDenied),
            Access::Missing => d.problems.push(Problem::NodeMissing),
        }
        if let Some(scan) = holders_of(Path::new(&d.path))
            && !scan.holders.is_empty()
        {
            d.problems.push(Problem::HeldBy(scan.holders));
        }
        if (d.vendor_id, d.product_id) == FALCON_ID && d.transport == Transport::Serial {
            d.notes.push(falcon_latency_note(&d.path));
            d.notes.push(
                "firmware: checked when opened; if none answers, name the Novint firmware file with --falcon-firmware FILE (or DYNACLAY_FALCON_FIRMWARE); `--doctor` tells"
                    .into(),
            );
        }
    }
}

fn falcon_latency_note(path: &str) -> String {
    let sysfs = Path::new(ftdi_latency::USB_SERIAL_SYSFS);
    match ftdi_latency::latency_timer_file(sysfs, Path::new(path))
        .and_then(|f| ftdi_latency::read_latency_ms(&f))
    {
        Ok(ms) if ms <= ftdi_latency::STREAM_LATENCY_MS => {
            format!("FTDI latency timer {ms} ms (1 kHz round trips possible)")
        }
        Ok(ms) => format!(
            "FTDI latency timer {ms} ms: replies wait up to {ms} ms; dynaclay sets 1 ms at open if it may (the udev rules let it)"
        ),
        Err(e) => format!("FTDI latency timer unknown: {e}"),
    }
}

/// Adds a [`Problem::LibraryMissing`] to each device whose vendor library did not load.
pub fn diagnose_libraries(
    devices: &mut [Connected],
    libraries: &[(VendorLibrary, Result<String, LibraryMissing>)],
) {
    for d in devices.iter_mut() {
        let Some(entry) = supported_entry(d.transport, d.vendor_id, d.product_id) else {
            continue;
        };
        let Needs::Library(needed) = entry.needs else {
            continue;
        };
        if let Some((_, Err(missing))) = libraries.iter().find(|(l, _)| *l == needed) {
            d.problems.push(Problem::LibraryMissing(missing.clone()));
        }
    }
}

/// Lists everything with the problems found without opening; enumeration failures become
/// notes instead of errors.
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
    let usb = list_usb_at(Path::new(USB_SYSFS));
    let extra = supported_usb_entries(&usb, &all);
    all.extend(extra);
    diagnose(&mut all);
    (all, notes)
}

/// Human-readable report for `dynaclay devices`: one line per device, supported ones marked
/// with their spec, then for each supported one what stands in the way of opening it, and the
/// udev rules' install command when permission is missing.
#[must_use]
pub fn report(devices: &[Connected], notes: &[String]) -> String {
    let mut s = String::new();
    if devices.is_empty() {
        s.push_str("No HID devices, serial ports or supported USB devices found.\n");
    }
    let mut denied = Vec::new();
    for d in devices {
        let kind = match d.transport {
            Transport::Hid => "hid   ",
            Transport::Serial => "serial",
            Transport::Usb => "usb   ",
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
        let supported = match (&d.spec, lookup(d.vendor_id, d.product_id)) {
            (Some(spec), _) => format!("  supported: --device {spec}"),
            (None, Some(entry)) => format!("  supported: {}", entry.name),
            (None, None) => String::new(),
        };
        let _ = writeln!(
            s,
            "{kind} {ids} {:<16} {}{supported}{access}",
            d.path,
            d.product.as_deref().unwrap_or("")
        );
        if d.spec.is_some() || !d.problems.is_empty() {
            if d.problems.is_empty() {
                let _ = writeln!(
                    s,
                    "       can be opened: no problem found without opening it"
                );
            }
            for p in &d.problems {
                let _ = writeln!(s, "       cannot open: {p}");
            }
            for n in &d.notes {
                let _ = writeln!(s, "       note: {n}");
            }
        }
        if d.problems.contains(&Problem::PermissionDenied) {
            denied.push(d.path.as_str());
        }
    }
    if !denied.is_empty() {
        let _ = writeln!(
            s,
            "\nPermission missing: this user cannot read and write {}.\n\
             Install the udev rules ({UDEV_RULES_INSTALLED}), then unplug and replug the device:\n  \
             {UDEV_INSTALL_COMMAND}\n\
             (from a source checkout: sudo cp devices/udev/70-dynaclay.rules /etc/udev/rules.d/)",
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
        assert_eq!(
            supported_spec(Transport::Serial, 0x2988, 0x0302, "/dev/ttyACM0").as_deref(),
            Some("touch")
        );
        assert_eq!(
            supported_spec(Transport::Usb, 0x1451, 0x0402, "/dev/bus/usb/001/002").as_deref(),
            Some("dhd")
        );
        assert_eq!(
            supported_spec(Transport::Usb, 0x0403, 0xcb48, "/dev/bus/usb/001/002"),
            None,
            "the Falcon is opened through its tty, not the raw USB node"
        );
    }

    fn device(transport: Transport, path: &str, ids: (u16, u16)) -> Connected {
        Connected {
            transport,
            path: path.into(),
            vendor_id: ids.0,
            product_id: ids.1,
            product: Some("a product".into()),
            spec: supported_spec(transport, ids.0, ids.1, path),
            access: Access::Ok,
            problems: Vec::new(),
            notes: Vec::new(),
        }
    }

    #[test]
    fn report_explains_missing_permissions_with_the_install_command() {
        let mut d = device(Transport::Hid, "/dev/hidraw7", (0x256f, 0xc635));
        d.access = Access::Denied;
        d.problems.push(Problem::PermissionDenied);
        let r = report(&[d], &[]);
        assert!(
            r.contains("256f:c635") && r.contains("--device spacemouse"),
            "{r}"
        );
        assert!(
            r.contains("[permission denied]")
                && r.contains("cannot open: permission denied")
                && r.contains(UDEV_INSTALL_COMMAND)
                && r.contains("/dev/hidraw7"),
            "{r}"
        );
        assert!(report(&[], &["x".into()]).contains("No HID devices"));
    }

    #[test]
    fn report_names_the_programs_holding_a_node_and_says_when_nothing_is_in_the_way() {
        let mut held = device(Transport::Serial, "/dev/ttyUSB0", FALCON_ID);
        held.problems.push(Problem::HeldBy(vec![Holder {
            pid: 4242,
            command: "minicom".into(),
        }]));
        let fine = device(Transport::Hid, "/dev/hidraw2", WOODENHAPTICS_ID);
        let unsupported = device(Transport::Serial, "/dev/ttyS0", (0, 0));
        let r = report(&[held, fine, unsupported], &[]);
        let lines: Vec<&str> = r.lines().collect();
        assert!(lines[0].contains("--device falcon:/dev/ttyUSB0"), "{r}");
        assert!(
            lines[1].contains("cannot open: held open by another program")
                && lines[1].contains("pid 4242 (minicom)"),
            "{r}"
        );
        assert!(lines[2].contains("--device hid:woodenhaptics"), "{r}");
        assert!(lines[3].contains("can be opened"), "{r}");
        assert!(
            lines[4].contains("/dev/ttyS0") && !lines[4].contains("supported"),
            "{r}"
        );
        assert_eq!(
            lines.len(),
            5,
            "an unsupported device gets no diagnosis: {r}"
        );
        assert!(
            !r.contains("udev"),
            "no permission problem, no install text: {r}"
        );
    }

    /// A sysfs stand-in with one USB device folder per `(name, vid, pid, bus, dev, product)`
    /// and an interface folder (no IDs) that must be skipped.
    fn fake_usb_sysfs(devices: &[(&str, &str, &str, &str, &str, &str)]) -> tempfile::TempDir {
        let root = tempfile::tempdir().unwrap();
        for (name, vid, pid, bus, dev, product) in devices {
            let d = root.path().join(name);
            std::fs::create_dir_all(&d).unwrap();
            for (attr, value) in [
                ("idVendor", vid),
                ("idProduct", pid),
                ("busnum", bus),
                ("devnum", dev),
                ("product", product),
            ] {
                std::fs::write(d.join(attr), format!("{value}\n")).unwrap();
            }
        }
        std::fs::create_dir_all(root.path().join("1-1:1.0")).unwrap();
        root
    }

    #[test]
    fn usb_sysfs_gives_raw_usb_arms_and_flags_supported_devices_without_a_kernel_node() {
        let root = fake_usb_sysfs(&[
            ("1-2", "1451", "0402", "1", "5", "omega.x haptic device"),
            ("1-3", "0403", "cb48", "1", "7", "FALCON HAPTIC"),
            ("2-1", "256f", "c635", "2", "3", "SpaceMouse Compact"),
            ("2-2", "046d", "c52b", "2", "4", "a receiver"),
        ]);
        let usb = list_usb_at(root.path());
        assert_eq!(usb.len(), 4, "{usb:?}");
        assert_eq!(usb[0].node(), "/dev/bus/usb/001/005");
        // The SpaceMouse has its hidraw node listed already; the Falcon's tty is missing.
        let shown = vec![device(Transport::Hid, "/dev/hidraw1", (0x256f, 0xc635))];
        let extra = supported_usb_entries(&usb, &shown);
        assert_eq!(extra.len(), 2, "{extra:?}");
        assert_eq!(extra[0].spec.as_deref(), Some("dhd"));
        assert_eq!(extra[0].path, "/dev/bus/usb/001/005");
        assert!(extra[0].problems.is_empty(), "{extra:?}");
        assert_eq!(extra[1].spec, None, "a Falcon is opened through its tty");
        assert_eq!(
            extra[1].problems,
            vec![Problem::NoKernelNode {
                expected: NodeKind::Tty
            }]
        );
        assert!(
            extra[1].problems[0].to_string().contains("ftdi_sio"),
            "{}",
            extra[1].problems[0]
        );
        let r = report(&extra, &[]);
        assert!(
            r.contains("supported: Novint Falcon") && r.contains("cannot open: no tty"),
            "{r}"
        );
        assert!(list_usb_at(Path::new("/nonexistent/usb")).is_empty());
    }

    #[test]
    fn an_arm_whose_library_is_missing_says_which_library_and_how_to_install_it() {
        use crate::vendor_lib::TriedCandidate;
        let mut devices = vec![
            device(Transport::Usb, "/dev/bus/usb/001/005", (0x1451, 0x0403)),
            device(Transport::Serial, "/dev/ttyACM0", (0x2988, 0x0302)),
        ];
        let missing = LibraryMissing {
            library: VendorLibrary::ForceDimensionDhd,
            tried: vec![TriedCandidate {
                candidate: "libdhd.so".into(),
                reason: "cannot open shared object file".into(),
            }],
        };
        let libraries = vec![
            (VendorLibrary::OpenHapticsHd, Ok("/usr/lib/libHD.so".into())),
            (VendorLibrary::ForceDimensionDhd, Err(missing.clone())),
        ];
        diagnose_libraries(&mut devices, &libraries);
        assert_eq!(devices[0].problems, vec![Problem::LibraryMissing(missing)]);
        assert!(devices[1].problems.is_empty(), "libHD loads: {devices:?}");
        let r = report(&devices, &[]);
        assert!(
            r.contains("--device dhd")
                && r.contains("libdhd.so")
                && r.contains("Force Dimension SDK"),
            "{r}"
        );
        assert!(r.contains("--device touch"), "{r}");
    }

    #[test]
    fn diagnosing_finds_a_node_this_process_holds() {
        use serialport::SerialPort as _;
        let (leader, follower) = serialport::TTYPort::pair().expect("a pseudo-terminal");
        let path = follower.name().unwrap();
        // A pty presented as a supported HID node: only its spec matters to `diagnose`.
        let mut d = device(Transport::Hid, &path, WOODENHAPTICS_ID);
        d.access = access(&path);
        let mut devices = vec![d];
        diagnose(&mut devices);
        let me = std::process::id();
        assert!(
            devices[0]
                .problems
                .iter()
                .any(|p| matches!(p, Problem::HeldBy(h) if h.iter().any(|h| h.pid == me))),
            "{devices:?}"
        );
        drop((leader, follower));
    }

    #[test]
    fn the_shipped_rules_are_the_file_the_install_command_names() {
        assert!(
            UDEV_RULES.contains("70-dynaclay.rules"),
            "the header names the file"
        );
        assert!(UDEV_RULES_INSTALLED.ends_with("/70-dynaclay.rules"));
        assert!(UDEV_INSTALL_COMMAND.contains(UDEV_RULES_INSTALLED));
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
                text.starts_with("No HID devices, serial ports or supported USB devices found."),
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
