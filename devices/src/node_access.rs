//! Whether this user may open a device node, checked with `access(2)` on the node so nothing
//! is opened (opening a tty toggles DTR, which resets some boards). Not for the haptic path.

use std::ffi::CString;

/// Whether this user may open a node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    /// Readable and writable.
    Ok,
    /// The node exists but is not readable and writable by this user.
    Denied,
    /// The node is not there (enumeration raced an unplug) or the path is not a file path.
    Missing,
}

/// Checks whether this user may read and write `path`, without opening it.
#[must_use]
pub fn access(path: &str) -> Access {
    let Ok(c) = CString::new(path) else {
        return Access::Missing;
    };
    // SAFETY: `c` is a valid NUL-terminated string that outlives the call; access(2) only
    // reads it.
    let rw = unsafe { libc::access(c.as_ptr(), libc::R_OK | libc::W_OK) };
    if rw == 0 {
        Access::Ok
    } else if std::path::Path::new(path).exists() {
        Access::Denied
    } else {
        Access::Missing
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn access_tells_denied_from_missing() {
        assert_eq!(access("/nonexistent/hidraw9"), Access::Missing);
        assert_eq!(access("bad\0path"), Access::Missing);
        let f = tempfile::NamedTempFile::new().unwrap();
        assert_eq!(access(f.path().to_str().unwrap()), Access::Ok);
    }
}
