//! Haply Inverse3 through Haply's Inverse Service, the local program that owns the arm and
//! speaks JSON on a WebSocket (`ws://localhost:10001` by default; messages in
//! [`crate::codec::haply_service`]).
//!
//! Who ticks: the haptic loop. The service answers each message with one state message and
//! sends nothing unasked, so every [`HapticDevice::write_force`] asks for exactly one exchange
//! (the force command out, the state back), and a `read` with no write since the previous one
//! asks for a keep-alive exchange with the last force, so the arm always gets a command. The
//! exchange itself allocates (a JSON string, tungstenite's frames) and blocks on the socket, so
//! it runs on the driver's own I/O thread: `write_force` puts the force in a wait-free triple
//! buffer, bumps an atomic request counter and unparks the thread; the thread sends the
//! newest force once per request it sees (two writes between its exchanges go out as one, the
//! newer), reads the reply, and publishes the sample through a second triple buffer and an
//! atomic "answered" counter. `read` spins at most [`Inverse3Config::reply_wait`] for the
//! reply to the last request, then returns the newest sample (the same one again if the reply
//! is late). Neither call allocates or takes a lock.
//!
//! Safety: `open` sends zero force as its first command and returns only after the reply to
//! it. Any fault on the I/O thread (the socket closed, a message that breaks the protocol, no
//! reply within [`Inverse3Config::reply_timeout`]) is published as a [`DeviceError`] that
//! every later `read` and `write_force` returns; before the thread gives up it sends one more
//! zero-force command if the socket still takes one. `close` sends zero and closes the socket.
//! The safety filter around the driver sends zero while the fault lasts; the engine runs on.
//!
//! Frames and time: Haply's frame (+x right, +y away from the user, +z up) is rotated into the
//! device frame (+x right, +y up, +z toward the user); timestamps are the host's monotonic
//! clock when the I/O thread received each reply, microseconds since `open`.

use std::io;
use std::net::{TcpStream, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use glam::Vec3;
use tungstenite::protocol::WebSocketConfig;
use tungstenite::{Message, WebSocket};

use crate::codec::haply_service::{
    self as service, DEFAULT_SERVICE_URL, Inverse3Report, MAX_MESSAGE_BYTES, ServiceMessageError,
};
use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};

/// Settings of an [`Inverse3`].
#[derive(Clone, Debug, PartialEq)]
pub struct Inverse3Config {
    /// The service's simulation channel, `ws://HOST:PORT[/PATH]`.
    pub url: String,
    /// The arm to drive, by the service's device id; `None` drives the first one listed.
    pub device_id: Option<String>,
    /// Longest wait to connect and for each message during `open`.
    pub connect_timeout: Duration,
    /// Longest the I/O thread waits for the reply to a command before it reports a fault.
    pub reply_timeout: Duration,
    /// Longest `read` spins for the reply to the newest command before returning the previous
    /// sample again (0: never wait).
    pub reply_wait: Duration,
}

impl Default for Inverse3Config {
    fn default() -> Self {
        Self {
            url: DEFAULT_SERVICE_URL.into(),
            device_id: None,
            connect_timeout: Duration::from_secs(2),
            reply_timeout: Duration::from_millis(100),
            reply_wait: Duration::from_micros(500),
        }
    }
}

/// One reply, as the I/O thread hands it to the loop (device frame).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Sample {
    position_m: Vec3,
    velocity_m_per_s: Vec3,
    buttons: u32,
    received_us: u64,
    /// Replies since `open` (1 for the reply to the opening zero force).
    replies: u64,
}

/// Fault codes in [`Shared::fault`].
mod fault {
    pub const NONE: u32 = 0;
    pub const DISCONNECTED: u32 = 1;
    pub const TIMEOUT: u32 = 2;
    pub const PROTOCOL: u32 = 3;
    pub const IO: u32 = 4;
}

/// What the two threads share: atomics only, plus the fault's words behind a lock that the
/// haptic path never takes.
struct Shared {
    /// Exchanges the loop has asked for.
    requested: AtomicU64,
    /// The request count the newest published sample answers.
    answered: AtomicU64,
    /// Force commands sent (requests coalesced by a busy thread count once).
    commands_sent: AtomicU64,
    /// A `fault::` code; set once, by the I/O thread, after `fault_what`/`fault_value`.
    fault: AtomicU32,
    /// The protocol fault's fixed description, as an index into [`PROTOCOL_WHATS`].
    fault_what: AtomicU32,
    /// The protocol fault's byte offset, the timeout's wait (µs) or the OS error code.
    fault_value: AtomicU64,
    /// The fault in full (field path, parser words), for `open`'s errors and diagnostics.
    fault_detail: Mutex<Option<String>>,
    stop: AtomicBool,
}

/// Fixed descriptions a protocol fault can carry (indexed by [`Shared::fault_what`]).
const PROTOCOL_WHATS: [&str; 10] = [
    "Inverse Service message too large",
    "Inverse Service sent a binary message",
    "Inverse Service message is not JSON",
    "Inverse Service message lacks a field",
    "Inverse Service message field of the wrong type",
    "Inverse Service message number not finite",
    "Inverse Service lists no Inverse3",
    "Inverse3 no longer listed by the service",
    "Inverse Service device id too long",
    "WebSocket protocol violation",
];

impl Shared {
    fn new() -> Self {
        Self {
            requested: AtomicU64::new(0),
            answered: AtomicU64::new(0),
            commands_sent: AtomicU64::new(0),
            fault: AtomicU32::new(fault::NONE),
            fault_what: AtomicU32::new(0),
            fault_value: AtomicU64::new(0),
            fault_detail: Mutex::new(None),
            stop: AtomicBool::new(false),
        }
    }

    /// Records the first fault (later ones are dropped): its words, then its code.
    fn set_fault(&self, code: u32, what: u32, value: u64, detail: String) {
        if self.fault.load(Ordering::Acquire) != fault::NONE {
            return;
        }
        if let Ok(mut d) = self.fault_detail.lock() {
            *d = Some(detail);
        }
        self.fault_what.store(what, Ordering::Relaxed);
        self.fault_value.store(value, Ordering::Relaxed);
        // NOTE: Release, so a reader that sees the code sees `what` and `value` above.
        self.fault.store(code, Ordering::Release);
    }

    fn protocol_fault(&self, e: &ServiceMessageError) {
        let what = PROTOCOL_WHATS
            .iter()
            .position(|w| *w == e.what())
            .unwrap_or(PROTOCOL_WHATS.len() - 1) as u32;
        self.set_fault(fault::PROTOCOL, what, e.offset() as u64, e.to_string());
    }

    /// The published fault as a value (allocation-free).
    fn error(&self) -> Option<DeviceError> {
        let code = self.fault.load(Ordering::Acquire);
        let value = self.fault_value.load(Ordering::Relaxed);
        match code {
            fault::NONE => None,
            fault::DISCONNECTED => Some(DeviceError::Disconnected),
            fault::TIMEOUT => Some(DeviceError::Timeout { waited_us: value }),
            fault::PROTOCOL => Some(DeviceError::Protocol {
                what: PROTOCOL_WHATS
                    .get(self.fault_what.load(Ordering::Relaxed) as usize)
                    .copied()
                    .unwrap_or("WebSocket protocol violation"),
                offset: value as usize,
            }),
            _ => {
                let os = i32::try_from(value).ok().filter(|c| *c != 0);
                Some(DeviceError::Io {
                    kind: os.map_or(io::ErrorKind::Other, |c| {
                        io::Error::from_raw_os_error(c).kind()
                    }),
                    os_code: os,
                    context: "Inverse Service socket",
                })
            }
        }
    }
}

type Socket = WebSocket<TcpStream>;

/// The I/O thread's state: the socket and its ends of the buffers.
struct Link {
    socket: Socket,
    quoted_id: String,
    device_id: String,
    force_out: triple_buffer::Output<[f64; 3]>,
    sample_in: triple_buffer::Input<Sample>,
    shared: Arc<Shared>,
    started: Instant,
    replies: u64,
    text: String,
}

/// How an exchange failed.
enum ExchangeError {
    /// The socket is gone or broken: nothing more can be sent.
    Lost(tungstenite::Error),
    /// No reply in time.
    Silent(Duration),
    /// A reply that breaks the protocol: the socket may still take a zero force.
    Bad(ServiceMessageError),
}

impl Link {
    /// Sends `force` (Haply frame) and waits for the state message that answers it.
    fn exchange(&mut self, force: [f64; 3]) -> Result<Inverse3Report, ExchangeError> {
        service::encode_force(&self.quoted_id, force, &mut self.text);
        self.socket
            .send(Message::text(self.text.as_str()))
            .map_err(ExchangeError::Lost)?;
        self.shared.commands_sent.fetch_add(1, Ordering::Relaxed);
        let asked = Instant::now();
        loop {
            match self.socket.read() {
                Ok(Message::Text(t)) => {
                    return service::parse_state(t.as_str(), Some(&self.device_id))
                        .map_err(ExchangeError::Bad);
                }
                Ok(Message::Binary(b)) => {
                    return Err(ExchangeError::Bad(ServiceMessageError::Binary {
                        bytes: b.len(),
                    }));
                }
                // Pings are answered by tungstenite on the next write; keep waiting.
                Ok(Message::Ping(_) | Message::Pong(_) | Message::Frame(_)) => {}
                Ok(Message::Close(_)) => {
                    return Err(ExchangeError::Lost(tungstenite::Error::ConnectionClosed));
                }
                Err(tungstenite::Error::Io(e))
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                    ) =>
                {
                    return Err(ExchangeError::Silent(asked.elapsed()));
                }
                Err(e) => return Err(ExchangeError::Lost(e)),
            }
        }
    }

    fn publish(&mut self, report: &Inverse3Report, answers: u64) {
        self.replies += 1;
        self.sample_in.write(Sample {
            position_m: service::haply_to_device(report.cursor_position_m),
            velocity_m_per_s: service::haply_to_device(report.cursor_velocity_m_per_s),
            buttons: report.buttons,
            received_us: self.started.elapsed().as_micros() as u64,
            replies: self.replies,
        });
        // NOTE: Release, so the loop that sees `answers` reads the sample written above.
        self.shared.answered.store(answers, Ordering::Release);
    }

    /// Records a failed exchange as the session's fault; sends a last zero force when the
    /// socket may still take one.
    fn fail(&mut self, e: ExchangeError) {
        use tungstenite::error::ProtocolError;
        match e {
            ExchangeError::Silent(waited) => {
                self.shared.set_fault(
                    fault::TIMEOUT,
                    0,
                    waited.as_micros() as u64,
                    format!("the Inverse Service did not answer within {waited:?}"),
                );
                self.last_zero();
            }
            ExchangeError::Bad(e) => {
                self.shared.protocol_fault(&e);
                self.last_zero();
            }
            // The peer went away: nothing more can be sent.
            ExchangeError::Lost(
                e @ (tungstenite::Error::ConnectionClosed
                | tungstenite::Error::AlreadyClosed
                | tungstenite::Error::Protocol(ProtocolError::ResetWithoutClosingHandshake)),
            ) => self.disconnected(&e),
            ExchangeError::Lost(tungstenite::Error::Io(io))
                if matches!(
                    io.kind(),
                    io::ErrorKind::BrokenPipe
                        | io::ErrorKind::ConnectionReset
                        | io::ErrorKind::ConnectionAborted
                        | io::ErrorKind::UnexpectedEof
                        | io::ErrorKind::NotConnected
                ) =>
            {
                self.disconnected(&io);
            }
            ExchangeError::Lost(tungstenite::Error::Io(io)) => {
                self.shared.set_fault(
                    fault::IO,
                    0,
                    io.raw_os_error().map_or(0, |c| c as u64),
                    format!("Inverse Service socket: {io}"),
                );
            }
            // A message that broke WebSocket framing or the size bound: the socket may still
            // take a zero force.
            ExchangeError::Lost(tungstenite::Error::Capacity(c)) => {
                self.shared.set_fault(
                    fault::PROTOCOL,
                    0,
                    MAX_MESSAGE_BYTES as u64,
                    format!("Inverse Service message refused: {c}"),
                );
                self.last_zero();
            }
            ExchangeError::Lost(tungstenite::Error::Protocol(p)) => {
                self.shared.set_fault(
                    fault::PROTOCOL,
                    (PROTOCOL_WHATS.len() - 1) as u32,
                    0,
                    format!("WebSocket protocol violation: {p}"),
                );
                self.last_zero();
            }
            ExchangeError::Lost(other) => self.disconnected(&other),
        }
    }

    fn disconnected(&self, why: &dyn std::fmt::Display) {
        self.shared.set_fault(
            fault::DISCONNECTED,
            0,
            0,
            format!("the Inverse Service connection ended ({why})"),
        );
    }

    /// One zero-force command, its reply awaited, then the socket closed; failures ignored
    /// (this runs when the session is ending anyway).
    fn last_zero(&mut self) -> bool {
        let sent = matches!(self.exchange([0.0; 3]), Ok(_) | Err(ExchangeError::Bad(_)));
        let _ = self.socket.close(None);
        let _ = self.socket.flush();
        sent
    }

    /// The I/O thread: one exchange per request, newest force, until stopped or faulted.
    fn run(mut self) {
        let mut answered = self.shared.answered.load(Ordering::Acquire);
        loop {
            if self.shared.stop.load(Ordering::Acquire) {
                self.last_zero();
                return;
            }
            // NOTE: Acquire pairs with the loop's Release increment, which follows its write
            // of the force: the force read below is at least that new.
            let want = self.shared.requested.load(Ordering::Acquire);
            if want == answered {
                std::thread::park_timeout(Duration::from_millis(20));
                continue;
            }
            let force = *self.force_out.read();
            match self.exchange(force) {
                Ok(report) => {
                    self.publish(&report, want);
                    answered = want;
                }
                Err(e) => {
                    self.fail(e);
                    return;
                }
            }
        }
    }
}

/// The loop's side of an open session.
struct Session {
    force_in: triple_buffer::Input<[f64; 3]>,
    sample_out: triple_buffer::Output<Sample>,
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
    /// Whether a force was written since the last `read` (else `read` asks for a keep-alive).
    written_since_read: bool,
}

impl Session {
    fn request(&mut self) {
        // NOTE: Release, so the I/O thread that sees the new count sees the force written
        // before it.
        self.shared.requested.fetch_add(1, Ordering::Release);
        if let Some(t) = &self.thread {
            t.thread().unpark();
        }
    }

    /// Stops the I/O thread (which sends zero and closes the socket) and waits for it.
    fn shut_down(&mut self) {
        self.force_in.write([0.0; 3]);
        self.shared.stop.store(true, Ordering::Release);
        if let Some(t) = self.thread.take() {
            t.thread().unpark();
            let _ = t.join();
        }
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        self.shut_down();
    }
}

/// A Haply Inverse3 through the Inverse Service; see the module docs for who ticks.
pub struct Inverse3 {
    config: Inverse3Config,
    session: Option<Session>,
    device_id: Option<String>,
}

/// `ws://HOST:PORT[/PATH]` split into what the socket and the handshake need.
fn socket_address(url: &str) -> Result<String, String> {
    if url.starts_with("wss://") {
        return Err(
            "wss:// is not supported: the Inverse Service listens on plain ws:// on this \
                    machine"
                .into(),
        );
    }
    let rest = url
        .strip_prefix("ws://")
        .ok_or_else(|| format!("`{}` is not a ws:// URL", url.escape_debug()))?;
    let authority = rest.split('/').next().unwrap_or_default();
    if authority.is_empty() {
        return Err(format!("`{}` names no host", url.escape_debug()));
    }
    if authority.contains(':') {
        Ok(authority.to_string())
    } else {
        Ok(format!("{authority}:80"))
    }
}

impl Inverse3 {
    /// The arm's figures as Haply publishes them, until the service is reached: 4 N over 80 %
    /// of the workspace (10 N peak; the continuous 4 N bounds the output), 1 N/mm stiffness, a
    /// workspace 460 mm wide, 510 mm high and 230 mm deep. The box is centred on the rest
    /// position in the service's documented snapshot (Haply (0, −0.12, 0.15) m, so 15 cm up
    /// and 12 cm toward the user), an estimate: the service reports no workspace. Damping is
    /// not published (0). One sample per command, so the haptic loop's 1 kHz is its rate.
    #[must_use]
    pub fn published_info() -> DeviceInfo {
        let centre = service::haply_to_device([0.0, -0.12, 0.15]);
        let half = Vec3::new(0.230, 0.255, 0.115);
        DeviceInfo {
            name: "Haply Inverse3 (Inverse Service)".into(),
            dof: 3,
            max_force_n: 4.0,
            max_stiffness_n_per_m: 1000.0,
            max_damping_n_s_per_m: 0.0,
            workspace_min_m: centre - half,
            workspace_max_m: centre + half,
            has_orientation: false,
            has_force: true,
            button_count: 3,
            sample_rate_hz: 1000.0,
        }
    }

    /// An arm (not connected yet).
    #[must_use]
    pub fn new(config: Inverse3Config) -> Self {
        Self {
            config,
            session: None,
            device_id: None,
        }
    }

    /// The service's id of the arm this session drives (after `open`).
    #[must_use]
    pub fn device_id(&self) -> Option<&str> {
        self.device_id.as_deref()
    }

    /// Force commands sent to the service since `open` (the opening zero included).
    #[must_use]
    pub fn commands_sent(&self) -> u64 {
        self.session
            .as_ref()
            .map_or(0, |s| s.shared.commands_sent.load(Ordering::Relaxed))
    }

    /// The session's fault in full words (the field path, the parser's message), if any.
    /// Takes a lock: not for the haptic path.
    #[must_use]
    pub fn fault_detail(&self) -> Option<String> {
        self.session
            .as_ref()
            .and_then(|s| s.shared.fault_detail.lock().ok()?.clone())
    }

    fn config_error(&self, message: String) -> DeviceError {
        DeviceError::Config {
            origin: format!("--device inverse3:{}", self.config.url),
            message,
        }
    }

    fn connect(&self) -> Result<(Socket, Inverse3Report), DeviceError> {
        let url = &self.config.url;
        let address = socket_address(url).map_err(|m| self.config_error(m))?;
        let not_running = |why: String| DeviceError::NotFound {
            what: format!(
                "Haply Inverse Service at {url}: {why}; is the Haply Hub (or \
                 haply-inverse-service) running and the Inverse3 plugged in?"
            ),
        };
        let addrs: Vec<_> = address
            .to_socket_addrs()
            .map_err(|e| not_running(format!("cannot resolve {address} ({e})")))?
            .collect();
        let mut last = None;
        let mut stream = None;
        for a in &addrs {
            match TcpStream::connect_timeout(a, self.config.connect_timeout) {
                Ok(s) => {
                    stream = Some(s);
                    break;
                }
                Err(e) => last = Some(e),
            }
        }
        let stream = stream.ok_or_else(|| {
            not_running(last.map_or("no address".into(), |e| format!("cannot connect ({e})")))
        })?;
        let io_err = |e: &io::Error| DeviceError::io(e, "setting up the Inverse Service socket");
        stream.set_nodelay(true).map_err(|e| io_err(&e))?;
        stream
            .set_read_timeout(Some(self.config.connect_timeout))
            .map_err(|e| io_err(&e))?;
        stream
            .set_write_timeout(Some(self.config.connect_timeout))
            .map_err(|e| io_err(&e))?;
        let ws_config = WebSocketConfig::default()
            .max_message_size(Some(MAX_MESSAGE_BYTES))
            .max_frame_size(Some(MAX_MESSAGE_BYTES));
        let (mut socket, _) =
            tungstenite::client::client_with_config(url.as_str(), stream, Some(ws_config))
                .map_err(|e| not_running(format!("the WebSocket handshake failed ({e})")))?;
        // The snapshot the service sends on connect.
        let snapshot = loop {
            match socket.read() {
                Ok(Message::Text(t)) => {
                    break service::parse_state(t.as_str(), self.config.device_id.as_deref())
                        .map_err(|e| {
                            self.config_error(format!("the service's first message: {e}"))
                        })?;
                }
                Ok(Message::Binary(b)) => {
                    return Err(self.config_error(format!(
                        "the service's first message: {}",
                        ServiceMessageError::Binary { bytes: b.len() }
                    )));
                }
                Ok(Message::Close(_)) => {
                    return Err(not_running("the service closed the connection".into()));
                }
                Ok(_) => {}
                Err(e) => {
                    return Err(not_running(format!(
                        "no first message from the service ({e})"
                    )));
                }
            }
        };
        if let Some(p) = &snapshot.basis_permutation
            && p != "XYZ"
            && p != "+X+Y+Z"
        {
            return Err(self.config_error(format!(
                "the service's basis for Inverse3 `{}` is `{p}`; dynaclay expects Haply's own \
                 frame (`XYZ`): reset the basis in the Haply Hub",
                snapshot.device_id
            )));
        }
        socket
            .get_mut()
            .set_read_timeout(Some(self.config.reply_timeout))
            .map_err(|e| io_err(&e))?;
        Ok((socket, snapshot))
    }
}

impl HapticDevice for Inverse3 {
    fn info(&self) -> DeviceInfo {
        Self::published_info()
    }

    fn open(&mut self) -> Result<(), DeviceError> {
        if self.session.is_some() {
            return Ok(());
        }
        let (socket, snapshot) = self.connect()?;
        let (force_in, force_out) = triple_buffer::TripleBuffer::new(&[0.0; 3]).split();
        let (sample_in, sample_out) = triple_buffer::TripleBuffer::new(&Sample::default()).split();
        let shared = Arc::new(Shared::new());
        let link = Link {
            socket,
            quoted_id: service::quoted_device_id(&snapshot.device_id),
            device_id: snapshot.device_id.clone(),
            force_out,
            sample_in,
            shared: Arc::clone(&shared),
            started: Instant::now(),
            replies: 0,
            text: String::with_capacity(256),
        };
        let thread = std::thread::Builder::new()
            .name("inverse3-io".into())
            .spawn(move || link.run())
            .map_err(|e| DeviceError::io(&e, "starting the Inverse3 I/O thread"))?;
        let mut session = Session {
            force_in,
            sample_out,
            shared,
            thread: Some(thread),
            written_since_read: false,
        };
        // The first command: zero force; its reply is the first sample.
        session.request();
        let asked = Instant::now();
        while session.shared.answered.load(Ordering::Acquire) < 1 {
            if let Some(e) = session.shared.error() {
                let detail = session
                    .shared
                    .fault_detail
                    .lock()
                    .ok()
                    .and_then(|d| d.clone())
                    .unwrap_or_else(|| e.to_string());
                return Err(self.config_error(format!("the first exchange failed: {detail}")));
            }
            if asked.elapsed() > self.config.connect_timeout {
                return Err(DeviceError::Timeout {
                    waited_us: asked.elapsed().as_micros() as u64,
                });
            }
            std::thread::sleep(Duration::from_micros(100));
        }
        self.device_id = Some(snapshot.device_id);
        self.session = Some(session);
        Ok(())
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        match self.session.take() {
            None => Ok(()),
            Some(mut s) => {
                let faulted = s.shared.error();
                s.shut_down();
                match faulted {
                    Some(DeviceError::Disconnected) | None => Ok(()),
                    Some(e) => Err(e),
                }
            }
        }
    }

    fn is_open(&self) -> bool {
        self.session.is_some()
    }

    /// The reply to the newest command (waiting at most `reply_wait` for it), else the newest
    /// sample again; the session's fault once one happened. Wait-free apart from that bounded
    /// spin.
    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        let s = self.session.as_mut().ok_or(DeviceError::NotOpen)?;
        if let Some(e) = s.shared.error() {
            return Err(e);
        }
        if !s.written_since_read {
            s.request();
        }
        s.written_since_read = false;
        let want = s.shared.requested.load(Ordering::Relaxed);
        let start = Instant::now();
        // NOTE: Acquire pairs with the I/O thread's Release store after it wrote the sample.
        while s.shared.answered.load(Ordering::Acquire) < want {
            if let Some(e) = s.shared.error() {
                return Err(e);
            }
            if start.elapsed() >= self.config.reply_wait {
                break;
            }
            std::hint::spin_loop();
            std::thread::yield_now();
        }
        let sample = *s.sample_out.read();
        Ok(DeviceState {
            position_m: sample.position_m,
            orientation: None,
            velocity_m_per_s: sample.velocity_m_per_s,
            buttons: sample.buttons,
            timestamp_us: sample.received_us,
            sequence: sample.replies,
        })
    }

    /// Hands `force_n` to the I/O thread, which sends it in one command. Wait-free.
    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        let s = self.session.as_mut().ok_or(DeviceError::NotOpen)?;
        if let Some(e) = s.shared.error() {
            return Err(e);
        }
        let f = if force_n.is_finite() {
            force_n
        } else {
            Vec3::ZERO
        };
        s.force_in.write(service::device_to_haply(f));
        s.written_since_read = true;
        s.request();
        Ok(())
    }
}

impl Drop for Inverse3 {
    fn drop(&mut self) {
        let _ = self.close();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urls_give_socket_addresses_or_say_why_not() {
        assert_eq!(
            socket_address("ws://localhost:10001").unwrap(),
            "localhost:10001"
        );
        assert_eq!(socket_address("ws://127.0.0.1:9/x").unwrap(), "127.0.0.1:9");
        assert_eq!(socket_address("ws://host").unwrap(), "host:80");
        assert!(
            socket_address("wss://host:1")
                .unwrap_err()
                .contains("wss://")
        );
        assert!(
            socket_address("http://host:1")
                .unwrap_err()
                .contains("not a ws://")
        );
        assert!(socket_address("ws:///x").unwrap_err().contains("no host"));
    }

    #[test]
    fn published_figures_hold_the_documented_rest_position() {
        let info = Inverse3::published_info();
        let rest = service::haply_to_device([0.0, -0.12, 0.15]);
        assert!(rest.cmpge(info.workspace_min_m).all() && rest.cmple(info.workspace_max_m).all());
        assert!(
            info.workspace_size_m()
                .abs_diff_eq(Vec3::new(0.46, 0.51, 0.23), 1e-6)
        );
        assert_eq!(info.max_force_n, 4.0);
    }

    #[test]
    fn a_service_that_is_not_there_is_not_found_naming_the_url() {
        // A port the OS just handed out and took back: nothing listens there.
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let url = format!("ws://127.0.0.1:{port}");
        let mut arm = Inverse3::new(Inverse3Config {
            url: url.clone(),
            ..Inverse3Config::default()
        });
        match arm.open().unwrap_err() {
            DeviceError::NotFound { what } => {
                assert!(what.contains(&url) && what.contains("Haply Hub"), "{what}");
            }
            other => panic!("expected NotFound, got {other:?}"),
        }
        assert!(!arm.is_open());
        assert_eq!(arm.read().unwrap_err(), DeviceError::NotOpen);
    }
}
