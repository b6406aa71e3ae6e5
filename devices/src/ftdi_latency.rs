//! The latency timer of an FTDI USB-serial bridge (the Novint Falcon's), through Linux's
//! `ftdi_sio` sysfs attribute `/sys/bus/usb-serial/devices/<ttyUSBn>/latency_timer`.
//!
//! The FTDI chip holds received bytes until its buffer fills or the latency timer expires
//! (16 ms by default), so at the default a 16-byte Falcon reply waits up to 16 ms and the
//! round trip caps the loop near 60 Hz. libnifalcon sets the timer to 1 ms for streaming and
//! 16 ms while the bootloader loads firmware; the Falcon driver does the same here. The
//! attribute is root-owned: without the udev rule that sets it at plug-in
//! (`devices/udev/70-dynaclay.rules`), writing it fails and [`LatencyOutcome::NotSet`] says
//! why and what the timer is. Not for the haptic path (it runs in `open`).

use std::io::Read as _;
use std::path::{Path, PathBuf};

/// Where `ftdi_sio` (and every usb-serial driver) lists its ports.
pub const USB_SERIAL_SYSFS: &str = "/sys/bus/usb-serial/devices";
/// The timer a 1 kHz round trip needs, milliseconds.
pub const STREAM_LATENCY_MS: u8 = 1;
/// The timer libnifalcon uses while loading firmware, milliseconds.
pub const BOOTLOADER_LATENCY_MS: u8 = 16;

/// Why the latency timer was not set.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum LatencyUnset {
    /// The port is not a USB-serial port (a pseudo-terminal, a built-in UART, a CDC-ACM
    /// device), so it has no FTDI latency timer.
    #[error("{port} is not a USB-serial port ({looked} does not exist)")]
    NotUsbSerial {
        /// The port as given.
        port: String,
        /// The attribute looked for.
        looked: String,
    },
    /// The attribute exists but this user may not write it.
    #[error(
        "no permission to write {file} (it reads {current_ms} ms); install the udev rules, which set it to 1 ms when the Falcon is plugged in, or run `echo 1 | sudo tee {file}`"
    )]
    PermissionDenied {
        /// The attribute.
        file: String,
        /// What it reads now, milliseconds.
        current_ms: u8,
    },
    /// Reading or writing the attribute failed otherwise, or it read back something else.
    #[error("{file}: {message}")]
    Failed {
        /// The attribute.
        file: String,
        /// What went wrong.
        message: String,
    },
}

/// What setting the latency timer did.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LatencyOutcome {
    /// Not tried yet (the port was not opened).
    NotTried,
    /// The timer now reads `now_ms` (it read `was_ms` before).
    Set {
        /// The attribute.
        file: String,
        /// Before, milliseconds.
        was_ms: u8,
        /// After (read back), milliseconds.
        now_ms: u8,
    },
    /// The timer was left as it is.
    NotSet(LatencyUnset),
}

impl std::fmt::Display for LatencyOutcome {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NotTried => write!(f, "FTDI latency timer: not tried (port not opened)"),
            Self::Set {
                file,
                was_ms,
                now_ms,
            } => write!(
                f,
                "FTDI latency timer: {now_ms} ms (was {was_ms} ms; {file})"
            ),
            Self::NotSet(why) => write!(f, "FTDI latency timer: not set: {why}"),
        }
    }
}

/// The `latency_timer` attribute of the tty `port` under `sysfs_root`, following symlinks such
/// as `/dev/serial/by-id/...` to the `ttyUSBn` node.
///
/// # Errors
/// [`LatencyUnset::NotUsbSerial`] when there is no such attribute.
pub fn latency_timer_file(sysfs_root: &Path, port: &Path) -> Result<PathBuf, LatencyUnset> {
    let node = std::fs::canonicalize(port).unwrap_or_else(|_| port.to_path_buf());
    let name = node.file_name().map(|n| n.to_string_lossy().into_owned());
    let file = sysfs_root
        .join(name.as_deref().unwrap_or("?"))
        .join("latency_timer");
    if name.is_some() && file.is_file() {
        Ok(file)
    } else {
        Err(LatencyUnset::NotUsbSerial {
            port: port.display().to_string(),
            looked: file.display().to_string(),
        })
    }
}

/// Reads a `latency_timer` attribute, milliseconds.
///
/// # Errors
/// [`LatencyUnset::Failed`] when it cannot be read or is not a number from 0 to 255.
pub fn read_latency_ms(file: &Path) -> Result<u8, LatencyUnset> {
    let failed = |message: String| LatencyUnset::Failed {
        file: file.display().to_string(),
        message,
    };
    // The attribute is a few bytes (sysfs reports every attribute as 4096 long, so the size
    // cannot be checked first); reading stops at 64.
    let mut bytes = Vec::with_capacity(64);
    std::fs::File::open(file)
        .and_then(|f| f.take(64).read_to_end(&mut bytes))
        .map_err(|e| failed(format!("cannot read: {e}")))?;
    let text = String::from_utf8_lossy(&bytes).into_owned();
    text.trim()
        .parse::<u8>()
        .map_err(|_| failed(format!("reads `{}`, not milliseconds", text.trim())))
}

/// Sets the latency timer of `port` to `ms`, with `sysfs_root` normally [`USB_SERIAL_SYSFS`],
/// and reads it back.
#[must_use]
pub fn set_latency_timer(sysfs_root: &Path, port: &Path, ms: u8) -> LatencyOutcome {
    let file = match latency_timer_file(sysfs_root, port) {
        Ok(f) => f,
        Err(e) => return LatencyOutcome::NotSet(e),
    };
    let was_ms = match read_latency_ms(&file) {
        Ok(v) => v,
        Err(e) => return LatencyOutcome::NotSet(e),
    };
    let shown = file.display().to_string();
    if was_ms != ms
        && let Err(e) = std::fs::write(&file, format!("{ms}\n"))
    {
        return LatencyOutcome::NotSet(unset_by_write_error(&e, shown, was_ms, ms));
    }
    match read_latency_ms(&file) {
        Ok(now_ms) if now_ms == ms => LatencyOutcome::Set {
            file: shown,
            was_ms,
            now_ms,
        },
        Ok(now_ms) => LatencyOutcome::NotSet(LatencyUnset::Failed {
            file: shown,
            message: format!("wrote {ms} but it reads {now_ms}"),
        }),
        Err(e) => LatencyOutcome::NotSet(e),
    }
}

/// Why writing `ms` to the attribute `file` (which read `was_ms`) failed with `e`.
fn unset_by_write_error(e: &std::io::Error, file: String, was_ms: u8, ms: u8) -> LatencyUnset {
    if e.kind() == std::io::ErrorKind::PermissionDenied {
        LatencyUnset::PermissionDenied {
            file,
            current_ms: was_ms,
        }
    } else {
        LatencyUnset::Failed {
            file,
            message: format!("cannot write {ms}: {e}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sysfs stand-in: `<root>/ttyUSB0/latency_timer` reading `value`, and a `/dev`-like
    /// folder with the node name (a regular file; only its name matters here).
    fn fake_sysfs(value: &str) -> (tempfile::TempDir, PathBuf) {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("sys/ttyUSB0")).unwrap();
        std::fs::write(dir.path().join("sys/ttyUSB0/latency_timer"), value).unwrap();
        std::fs::create_dir_all(dir.path().join("dev")).unwrap();
        let node = dir.path().join("dev/ttyUSB0");
        std::fs::write(&node, b"").unwrap();
        (dir, node)
    }

    #[test]
    fn the_timer_is_set_and_read_back() {
        let (dir, node) = fake_sysfs("16\n");
        let out = set_latency_timer(&dir.path().join("sys"), &node, 1);
        assert!(
            matches!(
                out,
                LatencyOutcome::Set {
                    was_ms: 16,
                    now_ms: 1,
                    ..
                }
            ),
            "{out:?}"
        );
        let text = std::fs::read_to_string(dir.path().join("sys/ttyUSB0/latency_timer")).unwrap();
        assert_eq!(text.trim(), "1");
        assert!(out.to_string().contains("1 ms (was 16 ms"), "{out}");
    }

    #[test]
    fn a_symlinked_port_name_finds_its_tty() {
        let (dir, node) = fake_sysfs("1\n");
        let link = dir.path().join("dev/usb-Novint_Falcon-if00-port0");
        std::os::unix::fs::symlink(&node, &link).unwrap();
        let out = set_latency_timer(&dir.path().join("sys"), &link, 1);
        assert!(
            matches!(
                out,
                LatencyOutcome::Set {
                    was_ms: 1,
                    now_ms: 1,
                    ..
                }
            ),
            "{out:?}"
        );
    }

    #[test]
    fn a_port_without_the_attribute_is_not_usb_serial() {
        let (dir, _) = fake_sysfs("16");
        let out = set_latency_timer(&dir.path().join("sys"), Path::new("/dev/pts/7"), 1);
        let LatencyOutcome::NotSet(LatencyUnset::NotUsbSerial { port, looked }) = &out else {
            panic!("{out:?}");
        };
        assert_eq!(port, "/dev/pts/7");
        assert!(looked.ends_with("sys/7/latency_timer"), "{looked}");
        assert!(out.to_string().contains("not a USB-serial port"), "{out}");
    }

    #[test]
    fn garbage_in_the_attribute_is_a_failure_that_quotes_it() {
        let (dir, node) = fake_sysfs("fast");
        let out = set_latency_timer(&dir.path().join("sys"), &node, 1);
        assert!(out.to_string().contains("reads `fast`"), "{out}");
    }

    #[test]
    fn a_refused_write_says_permission_the_current_value_and_the_fix() {
        // Tests may run as root, for whom file modes do not apply, so the refusal is given.
        let refused = std::io::Error::from(std::io::ErrorKind::PermissionDenied);
        let why = unset_by_write_error(&refused, "/sys/x/latency_timer".into(), 16, 1);
        assert_eq!(
            why,
            LatencyUnset::PermissionDenied {
                file: "/sys/x/latency_timer".into(),
                current_ms: 16
            }
        );
        let text = why.to_string();
        assert!(
            text.contains("reads 16 ms")
                && text.contains("udev rules")
                && text.contains("sudo tee"),
            "{text}"
        );
        let other = std::io::Error::other("device gone");
        assert!(
            unset_by_write_error(&other, "f".into(), 16, 1)
                .to_string()
                .contains("cannot write 1: device gone")
        );
    }
}
