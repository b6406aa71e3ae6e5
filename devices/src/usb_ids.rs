//! The one table of USB devices dynaclay drives: vendor and product IDs, how the kernel
//! presents each (hidraw, tty or raw USB), the `--device` spec that opens it and what else it
//! needs (a vendor library, the Falcon's firmware file).
//!
//! Enumeration ([`crate::enumerate`]), the SpaceMouse driver and the shipped udev rules
//! (`devices/udev/70-dynaclay.rules`, checked against this table by `tests/udev_rules.rs`) all
//! read it, so a new arm is added here once. Plain data; nothing here does I/O.

use crate::vendor_lib::VendorLibrary;

/// USB IDs handled as SpaceMice: the Logitech-era (0x046d) and 3Dconnexion (0x256f) families.
pub const SPACEMOUSE_IDS: [(u16, u16); 20] = [
    (0x046d, 0xc603), // SpaceMouse Plus XT
    (0x046d, 0xc605), // CADman
    (0x046d, 0xc606), // SpaceMouse Classic
    (0x046d, 0xc621), // SpaceBall 5000
    (0x046d, 0xc623), // SpaceTraveler
    (0x046d, 0xc625), // SpacePilot
    (0x046d, 0xc626), // SpaceNavigator
    (0x046d, 0xc627), // SpaceExplorer
    (0x046d, 0xc628), // SpaceNavigator for Notebooks
    (0x046d, 0xc629), // SpacePilot Pro
    (0x046d, 0xc62b), // SpaceMouse Pro
    (0x046d, 0xc640), // NuLOOQ
    (0x256f, 0xc62e), // SpaceMouse Wireless (cable)
    (0x256f, 0xc62f), // SpaceMouse Wireless (receiver)
    (0x256f, 0xc631), // SpaceMouse Pro Wireless (cable)
    (0x256f, 0xc632), // SpaceMouse Pro Wireless (receiver)
    (0x256f, 0xc633), // SpaceMouse Enterprise
    (0x256f, 0xc635), // SpaceMouse Compact
    (0x256f, 0xc636), // SpaceMouse Module
    (0x256f, 0xc652), // Universal Receiver
];

/// USB IDs of the Novint Falcon's FTDI bridge.
pub const FALCON_ID: (u16, u16) = (0x0403, 0xcb48);
/// USB IDs of the WoodenHaptics / Polhem HID firmware (mbed's USBHID defaults).
pub const WOODENHAPTICS_ID: (u16, u16) = (0x1234, 0x0006);
/// USB IDs of the Cartesian HID reference firmware (pid.codes test ID).
pub const CARTESIAN_HID_ID: (u16, u16) = (0x1209, 0x0001);
/// USB vendor ID of 3D Systems (Touch, Touch X over USB; seen as 2988:0302 and 2988:0304).
pub const THREE_D_SYSTEMS_VENDOR: u16 = 0x2988;
/// USB vendor ID of Force Dimension (omega.x seen as 1451:0402, sigma as 1451:0403).
pub const FORCE_DIMENSION_VENDOR: u16 = 0x1451;

/// Which products of a vendor an entry covers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProductMatch {
    /// One product ID.
    Exact(u16),
    /// Every product of the vendor (vendors whose product IDs vary by model and revision and
    /// whose arms are all driven by one library).
    AnyFromVendor,
}

/// How the kernel presents the device node dynaclay (or the vendor library) opens.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NodeKind {
    /// A `/dev/hidraw*` node.
    Hidraw,
    /// A `/dev/ttyUSB*` or `/dev/ttyACM*` node.
    Tty,
    /// The raw USB device `/dev/bus/usb/BBB/DDD` (the vendor library talks USB itself).
    RawUsb,
}

/// What a device needs besides access to its node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Needs {
    /// Nothing else.
    Nothing,
    /// A vendor library loaded at run time.
    Library(VendorLibrary),
    /// The Novint firmware image, loaded at open when none answers (named by
    /// `--falcon-firmware FILE`, `DYNACLAY_FALCON_FIRMWARE` or a profile's `firmware`).
    FalconFirmware,
}

/// One kind of supported USB device.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SupportedUsb {
    /// What it is, for people.
    pub name: &'static str,
    /// USB vendor ID.
    pub vendor_id: u16,
    /// Which of the vendor's products.
    pub product: ProductMatch,
    /// The node that is opened.
    pub node: NodeKind,
    /// The `--device` spec, with `{path}` standing for the node's path.
    pub spec: &'static str,
    /// What else opening it needs.
    pub needs: Needs,
}

impl SupportedUsb {
    /// Whether a device with these IDs is this entry.
    #[must_use]
    pub fn matches(&self, vendor_id: u16, product_id: u16) -> bool {
        vendor_id == self.vendor_id
            && match self.product {
                ProductMatch::Exact(p) => p == product_id,
                ProductMatch::AnyFromVendor => true,
            }
    }

    /// The `--device` spec for the device at `path`.
    #[must_use]
    pub fn spec_for(&self, path: &str) -> String {
        self.spec.replace("{path}", path)
    }
}

const fn entry(
    name: &'static str,
    (vendor_id, product_id): (u16, u16),
    node: NodeKind,
    spec: &'static str,
    needs: Needs,
) -> SupportedUsb {
    SupportedUsb {
        name,
        vendor_id,
        product: ProductMatch::Exact(product_id),
        node,
        spec,
        needs,
    }
}

const fn spacemouse(i: usize) -> SupportedUsb {
    entry(
        "3Dconnexion SpaceMouse",
        SPACEMOUSE_IDS[i],
        NodeKind::Hidraw,
        "spacemouse",
        Needs::Nothing,
    )
}

/// Every supported USB device. The arms come first; a device matching several entries is the
/// first.
pub const SUPPORTED_USB: [SupportedUsb; 25] = [
    entry(
        "Novint Falcon",
        FALCON_ID,
        NodeKind::Tty,
        "falcon:{path}",
        Needs::FalconFirmware,
    ),
    entry(
        "WoodenHaptics / Polhem",
        WOODENHAPTICS_ID,
        NodeKind::Hidraw,
        "hid:woodenhaptics",
        Needs::Nothing,
    ),
    entry(
        "Cartesian HID reference arm",
        CARTESIAN_HID_ID,
        NodeKind::Hidraw,
        "hid:cartesian-hid",
        Needs::Nothing,
    ),
    SupportedUsb {
        name: "3D Systems Touch / Touch X",
        vendor_id: THREE_D_SYSTEMS_VENDOR,
        product: ProductMatch::AnyFromVendor,
        node: NodeKind::Tty,
        spec: "touch",
        needs: Needs::Library(VendorLibrary::OpenHapticsHd),
    },
    SupportedUsb {
        name: "Force Dimension omega / delta / sigma / lambda",
        vendor_id: FORCE_DIMENSION_VENDOR,
        product: ProductMatch::AnyFromVendor,
        node: NodeKind::RawUsb,
        spec: "dhd",
        needs: Needs::Library(VendorLibrary::ForceDimensionDhd),
    },
    spacemouse(0),
    spacemouse(1),
    spacemouse(2),
    spacemouse(3),
    spacemouse(4),
    spacemouse(5),
    spacemouse(6),
    spacemouse(7),
    spacemouse(8),
    spacemouse(9),
    spacemouse(10),
    spacemouse(11),
    spacemouse(12),
    spacemouse(13),
    spacemouse(14),
    spacemouse(15),
    spacemouse(16),
    spacemouse(17),
    spacemouse(18),
    spacemouse(19),
];

/// The table entry for a USB device, if dynaclay supports it.
#[must_use]
pub fn lookup(vendor_id: u16, product_id: u16) -> Option<&'static SupportedUsb> {
    SUPPORTED_USB
        .iter()
        .find(|e| e.matches(vendor_id, product_id))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_spacemouse_id_is_in_the_table_once() {
        for (vid, pid) in SPACEMOUSE_IDS {
            let hits: Vec<_> = SUPPORTED_USB
                .iter()
                .filter(|e| e.matches(vid, pid))
                .collect();
            assert_eq!(hits.len(), 1, "{vid:04x}:{pid:04x}");
            assert_eq!(hits[0].spec, "spacemouse");
        }
    }

    #[test]
    fn vendor_wide_entries_match_any_product_of_their_vendor_only() {
        let touch = lookup(0x2988, 0x0302).unwrap();
        assert_eq!(touch.spec, "touch");
        assert_eq!(lookup(0x2988, 0x0304).unwrap().spec, "touch");
        let fd = lookup(0x1451, 0x0402).unwrap();
        assert_eq!(fd.needs, Needs::Library(VendorLibrary::ForceDimensionDhd));
        assert_eq!(
            lookup(0x0403, 0x6001),
            None,
            "a plain FTDI cable is not a Falcon"
        );
        assert_eq!(
            lookup(0x0403, 0xcb48).unwrap().spec_for("/dev/ttyUSB3"),
            "falcon:/dev/ttyUSB3"
        );
    }

    #[test]
    fn every_spec_template_parses_as_a_device_spec() {
        for e in SUPPORTED_USB {
            let spec = e.spec_for("/dev/ttyUSB0");
            assert!(
                spec.parse::<crate::spec::DeviceSpec>().is_ok(),
                "{}: {spec}",
                e.name
            );
        }
    }
}
