//! Which programs hold a device node open, found by scanning `/proc/*/fd` for descriptors
//! that refer to the node's character device (same `st_rdev`), so nothing is opened: opening a
//! tty to test for `EBUSY` would toggle DTR, which resets some boards and can drop the
//! Falcon into its bootloader.
//!
//! Limits, reported rather than hidden: without root, `/proc/PID/fd` of another user's process
//! cannot be read, so such a holder is counted in [`HolderScan::unreadable_processes`] but not
//! named. Linux only (elsewhere the scan finds nothing). Not for the haptic path.

use std::os::unix::fs::{FileTypeExt, MetadataExt};
use std::path::Path;

/// A process with a descriptor open on a node.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Holder {
    /// Process ID.
    pub pid: u32,
    /// Its command name (`/proc/PID/comm`), or `?` when unreadable.
    pub command: String,
}

/// What a scan found for one node.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct HolderScan {
    /// Processes holding the node open (this process included if it does).
    pub holders: Vec<Holder>,
    /// Processes whose descriptors could not be read (another user's, without root): one of
    /// them may hold the node.
    pub unreadable_processes: usize,
}

/// Longest process list a scan walks (a bound on the work, far above a desktop's count).
const MAX_PROCESSES: usize = 1 << 16;
/// Most descriptors looked at per process.
const MAX_FDS_PER_PROCESS: usize = 1 << 14;

/// The character device number of `node`, or `None` when it is not a character device.
#[must_use]
pub fn char_device_number(node: &Path) -> Option<u64> {
    let m = std::fs::metadata(node).ok()?;
    m.file_type().is_char_device().then(|| m.rdev())
}

/// Scans `proc_root` (normally `/proc`) for processes holding the character device `rdev`.
#[must_use]
pub fn scan_for(proc_root: &Path, rdev: u64) -> HolderScan {
    let mut scan = HolderScan::default();
    let Ok(entries) = std::fs::read_dir(proc_root) else {
        return scan;
    };
    for entry in entries.flatten().take(MAX_PROCESSES) {
        let Some(pid) = entry
            .file_name()
            .to_str()
            .and_then(|n| n.parse::<u32>().ok())
        else {
            continue;
        };
        let Ok(fds) = std::fs::read_dir(entry.path().join("fd")) else {
            scan.unreadable_processes += 1;
            continue;
        };
        let holds = fds.flatten().take(MAX_FDS_PER_PROCESS).any(|fd| {
            // metadata follows the descriptor's link to the file it refers to.
            std::fs::metadata(fd.path())
                .is_ok_and(|m| m.file_type().is_char_device() && m.rdev() == rdev)
        });
        if holds {
            let command = std::fs::read_to_string(entry.path().join("comm"))
                .map_or_else(|_| "?".to_string(), |c| c.trim().to_string());
            scan.holders.push(Holder { pid, command });
        }
    }
    scan.holders.sort_by_key(|h| h.pid);
    scan
}

/// Scans `/proc` for processes holding `node`; `None` when `node` is not a character device
/// (missing, or a regular file).
#[must_use]
pub fn holders_of(node: &Path) -> Option<HolderScan> {
    char_device_number(node).map(|rdev| scan_for(Path::new("/proc"), rdev))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pseudo_terminal_this_process_holds_is_found_with_its_pid() {
        // A pty's follower end is a character device; holding it open here must show this
        // process among its holders.
        use serialport::SerialPort as _;
        let pair = serialport::TTYPort::pair().expect("a pseudo-terminal pair");
        let (leader, follower) = pair;
        let name = follower.name().expect("the follower's path");
        let scan = holders_of(Path::new(&name)).expect("a pty is a character device");
        let me = std::process::id();
        assert!(scan.holders.iter().any(|h| h.pid == me), "{name}: {scan:?}");
        drop((leader, follower));
    }

    #[test]
    fn a_device_nobody_holds_has_no_holders_and_a_regular_file_is_not_scanned() {
        // /dev/null is held by many processes in general, so use a device number no node has.
        let scan = scan_for(Path::new("/proc"), u64::MAX);
        assert!(scan.holders.is_empty(), "{scan:?}");
        let f = tempfile::NamedTempFile::new().unwrap();
        assert_eq!(holders_of(f.path()), None);
        assert_eq!(holders_of(Path::new("/nonexistent/ttyUSB9")), None);
    }

    #[test]
    fn a_missing_proc_root_gives_an_empty_scan() {
        assert_eq!(
            scan_for(Path::new("/nonexistent/proc"), 1),
            HolderScan::default()
        );
    }
}
