//! A USB HID device as the drivers open it: find the first node with known IDs, refuse it
//! with a clear error when this user may not open it, and open it non-blocking. Not for the
//! haptic path (it enumerates and allocates).

use hidapi::{HidApi, HidDevice};

use crate::device::DeviceError;
use crate::node_access::{Access, access};

/// Opens the first HID device whose IDs are in `ids`, checking permissions first.
///
/// # Errors
/// [`DeviceError::NotFound`] naming `what`, [`DeviceError::PermissionDenied`] with the hidraw
/// path, or [`DeviceError::Io`].
pub fn open_hid(
    ids: &[(u16, u16)],
    what: &str,
) -> Result<(HidApi, HidDevice, String), DeviceError> {
    let api = HidApi::new().map_err(|_| DeviceError::Io {
        kind: std::io::ErrorKind::Other,
        os_code: None,
        context: "HID enumeration",
    })?;
    let found = api
        .device_list()
        .find(|d| ids.contains(&(d.vendor_id(), d.product_id())))
        .map(|d| d.path().to_owned());
    let Some(path) = found else {
        return Err(DeviceError::NotFound {
            what: what.to_string(),
        });
    };
    let path_s = path.to_string_lossy().into_owned();
    if access(&path_s) == Access::Denied {
        return Err(DeviceError::PermissionDenied { path: path_s });
    }
    let dev = api.open_path(&path).map_err(|_| DeviceError::Io {
        kind: std::io::ErrorKind::Other,
        os_code: None,
        context: "open HID device",
    })?;
    dev.set_blocking_mode(false).map_err(|_| DeviceError::Io {
        kind: std::io::ErrorKind::Other,
        os_code: None,
        context: "HID non-blocking mode",
    })?;
    Ok((api, dev, path_s))
}
