//! A serial port as the drivers use it: bounded, allocation-free reads into a fixed buffer,
//! errors mapped to [`DeviceError`], and a baud-rate policy that tolerates ports which cannot
//! change speed.
//!
//! On the haptic path [`SerialLink::read_available`] asks the OS how many bytes are queued
//! (`FIONREAD`) and reads only those, optionally spinning for a bounded time first, so it never
//! blocks in the kernel and never builds an `io::Error` for "nothing yet". A wait longer than
//! [`SPIN_WAIT_LIMIT`] is off the real-time path (a lockstep run's reply wait, `open`'s
//! exchanges) and sleeps in the kernel instead, so the other side has the CPU it needs to
//! answer. Writes wait at most the port timeout set at open. Error paths may allocate (the OS
//! error is wrapped once).

use std::io::{Read, Write};
use std::time::{Duration, Instant};

use serialport::{ClearBuffer, SerialPort};

use crate::device::DeviceError;

/// Size of the read buffer: well over what 1 ms of a 1.5 Mbaud link can carry.
pub const READ_BUF: usize = 512;

/// The longest wait [`SerialLink::read_available`] spends spinning: the real-time reply waits
/// (a few hundred microseconds inside a 1 ms tick) are below it and spin, as a missed wake-up
/// would cost the tick. A longer wait sleeps in the kernel until a byte comes: a spinning
/// wait takes a CPU from whatever has to answer (the device's other end, the kernel's tty
/// worker that moves a pseudo-terminal's bytes across), and on a loaded machine that kept
/// replies away for seconds, past a lockstep run's whole reply wait.
pub const SPIN_WAIT_LIMIT: Duration = Duration::from_millis(2);

/// What to do when the port refuses a baud rate.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BaudPolicy {
    /// Fail the operation (real hardware: a wrong rate means garbage).
    #[default]
    Strict,
    /// Note the refusal and go on. For pseudo-terminals and USB CDC ports, where the rate is
    /// meaningless and some kernels reject non-standard values.
    Tolerant,
}

/// An open serial port with its path and a fixed read buffer.
pub struct SerialLink {
    port: Box<dyn SerialPort>,
    path: String,
    buf: [u8; READ_BUF],
    policy: BaudPolicy,
    /// Baud changes (or modem-line changes) the port refused under [`BaudPolicy::Tolerant`].
    pub refused_settings: u32,
}

fn map_serial_error(e: &serialport::Error, path: &str) -> DeviceError {
    match e.kind() {
        serialport::ErrorKind::NoDevice => DeviceError::NotFound {
            what: format!("serial port {path}"),
        },
        serialport::ErrorKind::Io(std::io::ErrorKind::PermissionDenied) => {
            DeviceError::PermissionDenied {
                path: path.to_string(),
            }
        }
        serialport::ErrorKind::Io(std::io::ErrorKind::NotFound) => DeviceError::NotFound {
            what: format!("serial port {path}"),
        },
        // Another program opened the port exclusively (TIOCEXCL, as serialport and most
        // serial programs do): EBUSY.
        serialport::ErrorKind::Io(std::io::ErrorKind::ResourceBusy) => DeviceError::Io {
            kind: std::io::ErrorKind::ResourceBusy,
            os_code: None,
            context: "open serial port: busy, another program holds it open exclusively",
        },
        serialport::ErrorKind::InvalidInput => DeviceError::Config {
            origin: path.to_string(),
            message: e.description.clone(),
        },
        // The node opened but would not take serial settings: not a serial port (a file,
        // `/dev/null`, a non-tty device), or a driver that refused them.
        serialport::ErrorKind::Io(_) | serialport::ErrorKind::Unknown => DeviceError::Config {
            origin: path.to_string(),
            message: format!(
                "cannot set it up as a serial port ({}); is it a serial device such as /dev/ttyACM0?",
                e.description
            ),
        },
    }
}

/// Maps an I/O error on an open port: a vanished peer or device is `Disconnected`.
#[must_use]
pub fn map_io_error(e: &std::io::Error, context: &'static str) -> DeviceError {
    use std::io::ErrorKind as K;
    // EIO (5), ENXIO (6), ENODEV (19): the tty's other side or the USB device is gone.
    if matches!(
        e.kind(),
        K::BrokenPipe | K::UnexpectedEof | K::ConnectionReset | K::NotConnected
    ) || matches!(e.raw_os_error(), Some(5 | 6 | 19))
        || (e.kind() == K::Other && e.to_string().contains("I/O error"))
    {
        DeviceError::Disconnected
    } else {
        DeviceError::io(e, context)
    }
}

impl SerialLink {
    /// Opens `path` at `baud`, 8N1, no flow control, with `write_timeout` as the longest wait
    /// for the OS to accept a write.
    ///
    /// # Errors
    /// [`DeviceError::NotFound`], [`DeviceError::PermissionDenied`] or [`DeviceError::Io`].
    pub fn open(
        path: &str,
        baud: u32,
        policy: BaudPolicy,
        write_timeout: Duration,
    ) -> Result<Self, DeviceError> {
        let port = match serialport::new(path, baud).timeout(write_timeout).open() {
            Ok(p) => p,
            Err(e)
                if policy == BaudPolicy::Tolerant
                    && e.kind() == serialport::ErrorKind::InvalidInput =>
            {
                // Some ports reject the rate at open; open at a standard one and carry on.
                serialport::new(path, 115_200)
                    .timeout(write_timeout)
                    .open()
                    .map_err(|e| map_serial_error(&e, path))?
            }
            Err(e) => return Err(map_serial_error(&e, path)),
        };
        Ok(Self {
            port,
            path: path.to_string(),
            buf: [0; READ_BUF],
            policy,
            refused_settings: 0,
        })
    }

    /// Wraps an already open port (a test's pseudo-terminal end, a port opened elsewhere).
    #[must_use]
    pub fn from_port(port: Box<dyn SerialPort>, policy: BaudPolicy) -> Self {
        let path = port.name().unwrap_or_else(|| "<unnamed port>".into());
        Self {
            port,
            path,
            buf: [0; READ_BUF],
            policy,
            refused_settings: 0,
        }
    }

    /// The port's path.
    #[must_use]
    pub fn path(&self) -> &str {
        &self.path
    }

    /// Changes the baud rate, subject to the [`BaudPolicy`].
    ///
    /// # Errors
    /// Under [`BaudPolicy::Strict`], the port's refusal as [`DeviceError::Config`]/[`DeviceError::Io`].
    pub fn set_baud(&mut self, baud: u32) -> Result<(), DeviceError> {
        match self.port.set_baud_rate(baud) {
            Ok(()) => Ok(()),
            Err(_) if self.policy == BaudPolicy::Tolerant => {
                self.refused_settings += 1;
                Ok(())
            }
            Err(e) => Err(map_serial_error(&e, &self.path)),
        }
    }

    /// Sets the DTR and RTS lines (a bootloader reset), subject to the [`BaudPolicy`].
    ///
    /// # Errors
    /// Under [`BaudPolicy::Strict`], the port's refusal.
    pub fn set_lines(&mut self, dtr: bool, rts: bool) -> Result<(), DeviceError> {
        let r = self
            .port
            .write_data_terminal_ready(dtr)
            .and_then(|()| self.port.write_request_to_send(rts));
        match r {
            Ok(()) => Ok(()),
            Err(_) if self.policy == BaudPolicy::Tolerant => {
                self.refused_settings += 1;
                Ok(())
            }
            Err(e) => Err(map_serial_error(&e, &self.path)),
        }
    }

    /// Drops whatever input is queued.
    pub fn clear_input(&mut self) {
        let _ = self.port.clear(ClearBuffer::Input);
        // Drain too: a pseudo-terminal may ignore the flush.
        while let Ok(n) = self.port.bytes_to_read() {
            if n == 0 {
                break;
            }
            let want = (n as usize).min(READ_BUF);
            if self.port.read(&mut self.buf[..want]).is_err() {
                break;
            }
        }
    }

    /// Writes all of `bytes`.
    ///
    /// # Errors
    /// [`DeviceError::Disconnected`] when the other side is gone, else [`DeviceError::Io`].
    pub fn write_all(&mut self, bytes: &[u8]) -> Result<(), DeviceError> {
        self.port
            .write_all(bytes)
            .map_err(|e| map_io_error(&e, "serial write"))
    }

    /// Returns the bytes queued now, waiting up to `max_wait` for the first one: by spinning
    /// up to [`SPIN_WAIT_LIMIT`], asleep in the kernel for a longer wait. Reads at most
    /// [`READ_BUF`] bytes; call again for more.
    ///
    /// # Errors
    /// [`DeviceError::Disconnected`] (a sleeping wait also reports a hang-up at once), or
    /// [`DeviceError::Io`].
    pub fn read_available(&mut self, max_wait: Duration) -> Result<&[u8], DeviceError> {
        if max_wait > SPIN_WAIT_LIMIT {
            return self.read_available_asleep(max_wait);
        }
        let start = Instant::now();
        let queued = loop {
            // The time is taken before the port is asked, so the last look always comes after
            // the wait is over: a thread descheduled past the deadline still sees a byte that
            // arrived meanwhile instead of reporting silence.
            let waited_out = start.elapsed() >= max_wait;
            let n = self
                .port
                .bytes_to_read()
                .map_err(|e| map_serial_error(&e, &self.path))? as usize;
            if n > 0 || waited_out {
                break n;
            }
            std::hint::spin_loop();
            std::thread::yield_now();
        };
        if queued == 0 {
            return Ok(&self.buf[..0]);
        }
        let want = queued.min(READ_BUF);
        let got = self
            .port
            .read(&mut self.buf[..want])
            .map_err(|e| map_io_error(&e, "serial read"))?;
        if got == 0 {
            return Err(DeviceError::Disconnected);
        }
        Ok(&self.buf[..got])
    }

    /// [`SerialLink::read_available`] for a wait off the real-time path: the port's own read,
    /// its timeout set to `max_wait`, sleeps in `poll` until a byte is queued, the other side
    /// hangs up or the wait is over (the kernel looks at the port once more after the timer
    /// fires, so a byte that came while this thread waited for a CPU is still seen), then
    /// reads what is queued. The port's timeout (the write timeout) is put back.
    // NOTE: a wait that ends in silence allocates (serialport builds an `io::Error` for its
    // timeout); that is a missed reply off the real-time path, never a tick's "nothing yet".
    // `tests/haptic_no_alloc.rs` runs a lockstep Falcon through this path with no allocation.
    fn read_available_asleep(&mut self, max_wait: Duration) -> Result<&[u8], DeviceError> {
        let saved = self.port.timeout();
        let set = self.port.set_timeout(max_wait);
        let read = match set {
            Ok(()) => self.port.read(&mut self.buf),
            Err(e) => Err(std::io::Error::other(e)),
        };
        let _ = self.port.set_timeout(saved);
        match read {
            Ok(0) => Err(DeviceError::Disconnected),
            Ok(got) => Ok(&self.buf[..got]),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => Ok(&self.buf[..0]),
            Err(e) => Err(map_io_error(&e, "serial read")),
        }
    }

    /// Checks the line when nothing has arrived for a while: a zero-length wait on the port
    /// reports a hang-up as [`DeviceError::Disconnected`]. Returns `Ok` if the line looks alive.
    ///
    /// # Errors
    /// [`DeviceError::Disconnected`] when the other side has hung up.
    pub fn probe_hangup(&mut self) -> Result<(), DeviceError> {
        let saved = self.port.timeout();
        let _ = self.port.set_timeout(Duration::ZERO);
        let r = self.port.read(&mut self.buf[..0]);
        let _ = self.port.set_timeout(saved);
        match r {
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => Ok(()),
            Err(e) => Err(map_io_error(&e, "serial read")),
            Ok(_) => Ok(()),
        }
    }

    /// Reads exactly `out.len()` bytes within `timeout` (bootloader handshakes; not for the
    /// haptic path).
    ///
    /// # Errors
    /// [`DeviceError::Timeout`] with the time waited, or a link error.
    pub fn read_exact_within(
        &mut self,
        out: &mut [u8],
        timeout: Duration,
    ) -> Result<(), DeviceError> {
        let start = Instant::now();
        let mut have = 0;
        while have < out.len() {
            let left = timeout.saturating_sub(start.elapsed());
            if left.is_zero() {
                return Err(DeviceError::Timeout {
                    waited_us: start.elapsed().as_micros() as u64,
                });
            }
            let n = self
                .port
                .bytes_to_read()
                .map_err(|e| map_serial_error(&e, &self.path))? as usize;
            if n == 0 {
                std::thread::sleep(Duration::from_micros(200).min(left));
                continue;
            }
            let want = n.min(out.len() - have);
            let got = self
                .port
                .read(&mut out[have..have + want])
                .map_err(|e| map_io_error(&e, "serial read"))?;
            if got == 0 {
                return Err(DeviceError::Disconnected);
            }
            have += got;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use serialport::TTYPort;

    use super::*;

    /// A link on one end of a pseudo-terminal pair; the other end plays the device.
    fn link_on_pty() -> (SerialLink, TTYPort) {
        let (device, host) = TTYPort::pair().expect("pseudo-terminal pair");
        let link = SerialLink::from_port(Box::new(host), BaudPolicy::Tolerant);
        (link, device)
    }

    #[test]
    fn a_long_wait_sleeps_until_the_bytes_come_and_keeps_the_write_timeout() {
        let (mut link, mut device) = link_on_pty();
        let write_timeout = link.port.timeout();
        let wait = Duration::from_secs(60);
        assert!(wait > SPIN_WAIT_LIMIT);
        let writer = std::thread::spawn(move || {
            device.write_all(b"<reply>").unwrap();
            device
        });
        // The bytes may come in pieces: a wait ends with the first of them.
        let mut got = Vec::new();
        while got.len() < 7 {
            let bytes = link.read_available(wait).unwrap();
            assert!(!bytes.is_empty(), "a 60 s wait ended without the bytes");
            got.extend_from_slice(bytes);
        }
        assert_eq!(got, b"<reply>");
        assert_eq!(
            link.port.timeout(),
            write_timeout,
            "the write timeout is back"
        );
        drop(writer.join().unwrap());
    }

    #[test]
    fn a_hang_up_ends_a_long_wait_as_a_disconnect() {
        let (mut link, device) = link_on_pty();
        drop(device);
        // Spinning on the queued count would wait the whole minute and report silence; the
        // sleeping wait sees the hang-up.
        assert_eq!(
            link.read_available(Duration::from_secs(60))
                .map(<[u8]>::len),
            Err(DeviceError::Disconnected)
        );
    }

    #[test]
    fn a_port_held_exclusively_elsewhere_opens_as_busy_not_as_a_bad_port() {
        let e = serialport::Error::new(
            serialport::ErrorKind::Io(std::io::ErrorKind::ResourceBusy),
            "Device or resource busy",
        );
        let mapped = map_serial_error(&e, "/dev/ttyUSB0");
        assert!(
            matches!(
                mapped,
                DeviceError::Io {
                    kind: std::io::ErrorKind::ResourceBusy,
                    ..
                }
            ),
            "{mapped:?}"
        );
        assert!(mapped.to_string().contains("another program"), "{mapped}");
    }
}
