//! The DHD API subset: device count, open/close, system type and name, force enable, position,
//! force, buttons, the device clock and the last error.
//!
//! Units and frame as DHD's: metres, newtons, x toward the user, y right, z up, origin at the
//! workspace centre. DHD has no scheduler: each `dhdGetPosition` is one fresh sample, and the
//! device clock (`dhdGetTime`) advances one millisecond per sample, so time is scripted too.

use std::ffi::{CStr, c_char, c_int, c_uchar, c_uint};
use std::sync::{Mutex, MutexGuard};

/// `DHD_DEVICE_OMEGA3`.
pub const DHD_DEVICE_OMEGA3: c_int = 33;
/// `DHD_DEVICE_FALCON`.
pub const DHD_DEVICE_FALCON: c_int = 60;
/// `DHD_DEVICE_DELTA3`.
pub const DHD_DEVICE_DELTA3: c_int = 63;
/// `DHD_ERROR_COM` (the `dhd_errors` enum's third member).
pub const DHD_ERROR_COM: c_int = 2;
/// `DHD_ERROR_NO_DEVICE_FOUND`.
pub const DHD_ERROR_NO_DEVICE_FOUND: c_int = 5;
/// `DHD_ERROR_INVALID_INDEX`.
pub const DHD_ERROR_INVALID_INDEX: c_int = 15;
/// Seconds the device clock advances per position sample.
pub const SAMPLE_PERIOD_S: f64 = 0.001;
/// Most forces [`standin_dhd_forces`] keeps (a minute of samples at 1 kHz); later ones are
/// counted in [`DhdCalls::set_force_calls`] but not kept.
pub const FORCE_LOG_CAPACITY: usize = 60_000;
/// [`standin_dhd_disconnect_at`]'s "never".
pub const NEVER: u64 = u64::MAX;

/// A scripted hand for [`standin_dhd_set_hand`]: writes the arm's position (three doubles,
/// metres, DHD frame) at position read `read` (counting from 0) to `position_m`.
pub type DhdHand = extern "C" fn(read: u64, position_m: *mut f64);

/// What the driver has done to the stand-in, read with [`standin_dhd_calls`].
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DhdCalls {
    /// `dhdGetPosition` calls (samples taken), failed ones included.
    pub position_reads: u64,
    /// `dhdSetForce` calls.
    pub set_force_calls: u64,
    /// Most `dhdSetForce` calls between two position reads.
    pub max_set_force_per_read: u32,
    /// Whether force output is enabled (1) or not (0).
    pub force_enabled: u32,
    /// The last force set, newtons, DHD frame.
    pub last_force_n: [f64; 3],
    /// Forces set while force output was enabled that were not exactly zero.
    pub nonzero_forces_output: u64,
    /// Devices open now.
    pub open_devices: u32,
    /// `dhdClose` calls.
    pub close_calls: u32,
}

struct State {
    device_count: c_int,
    system_type: c_int,
    open: [bool; 4],
    last_error: c_int,
    fail_reads: u32,
    set_force_since_read: u32,
    position_m: [f64; 3],
    step_m_per_read: [f64; 3],
    buttons: c_uint,
    hand: Option<DhdHand>,
    /// From this position read on (counting from 0) the arm is gone: reads and force
    /// commands fail with `DHD_ERROR_COM`.
    disconnect_at_read: u64,
    /// Forces accepted while force output was enabled, in order (bounded), DHD frame.
    forces_n: Vec<[f64; 3]>,
    calls: DhdCalls,
}

impl State {
    const fn new() -> Self {
        Self {
            device_count: 1,
            system_type: DHD_DEVICE_OMEGA3,
            open: [false; 4],
            last_error: 0,
            fail_reads: 0,
            set_force_since_read: 0,
            position_m: [0.0; 3],
            step_m_per_read: [0.0; 3],
            buttons: 0,
            hand: None,
            disconnect_at_read: NEVER,
            forces_n: Vec::new(),
            calls: DhdCalls {
                position_reads: 0,
                set_force_calls: 0,
                max_set_force_per_read: 0,
                force_enabled: 0,
                last_force_n: [0.0; 3],
                nonzero_forces_output: 0,
                open_devices: 0,
                close_calls: 0,
            },
        }
    }

    /// The device `id` names (`-1`: the first open one), if it is open.
    fn disconnected(&self) -> bool {
        self.calls.position_reads > self.disconnect_at_read
    }

    fn device(&mut self, id: c_char) -> Option<usize> {
        let index = if id < 0 {
            self.open.iter().position(|o| *o)
        } else {
            Some(id as usize)
        };
        match index {
            Some(i) if i < self.open.len() && self.open[i] => Some(i),
            _ => {
                self.last_error = DHD_ERROR_INVALID_INDEX;
                None
            }
        }
    }
}

static STATE: Mutex<State> = Mutex::new(State::new());

fn state() -> MutexGuard<'static, State> {
    STATE
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// `int dhdGetDeviceCount()`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdGetDeviceCount() -> c_int {
    state().device_count
}

/// `int dhdOpenID(char ID)`: opens device `id`; returns its ID, or -1.
#[unsafe(no_mangle)]
pub extern "C" fn dhdOpenID(id: c_char) -> c_int {
    let mut s = state();
    if id < 0 || c_int::from(id) >= s.device_count || id as usize >= s.open.len() {
        s.last_error = DHD_ERROR_NO_DEVICE_FOUND;
        return -1;
    }
    if !s.open[id as usize] {
        s.open[id as usize] = true;
        s.calls.open_devices += 1;
    }
    c_int::from(id)
}

/// `int dhdOpen()`: opens the first device.
#[unsafe(no_mangle)]
pub extern "C" fn dhdOpen() -> c_int {
    dhdOpenID(0)
}

/// `int dhdClose(char ID)`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdClose(id: c_char) -> c_int {
    let mut s = state();
    let Some(i) = s.device(id) else { return -1 };
    s.open[i] = false;
    s.calls.open_devices -= 1;
    s.calls.close_calls += 1;
    s.calls.force_enabled = 0;
    0
}

/// `int dhdGetSystemType(char ID)`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdGetSystemType(id: c_char) -> c_int {
    let mut s = state();
    match s.device(id) {
        Some(_) => s.system_type,
        None => -1,
    }
}

/// `const char* dhdGetSystemName(char ID)`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdGetSystemName(id: c_char) -> *const c_char {
    let mut s = state();
    if s.device(id).is_none() {
        return std::ptr::null();
    }
    let name: &CStr = match s.system_type {
        DHD_DEVICE_OMEGA3 => c"omega.3",
        DHD_DEVICE_FALCON => c"Falcon",
        DHD_DEVICE_DELTA3 => c"delta.3",
        _ => c"unknown",
    };
    name.as_ptr()
}

/// `int dhdEnableForce(uchar val, char ID)`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdEnableForce(val: c_uchar, id: c_char) -> c_int {
    let mut s = state();
    if s.device(id).is_none() {
        return -1;
    }
    s.calls.force_enabled = u32::from(val != 0);
    0
}

/// `int dhdGetComMode(char ID)`: always `DHD_COM_MODE_SYNC` (0).
#[unsafe(no_mangle)]
pub extern "C" fn dhdGetComMode(id: c_char) -> c_int {
    let mut s = state();
    if s.device(id).is_none() {
        return -1;
    }
    0
}

/// `int dhdGetPosition(double *px, double *py, double *pz, char ID)`: one fresh sample (where
/// the scripted hand is, if there is one); the arm then steps along its scripted line. Fails
/// (-1, `DHD_ERROR_COM`) while reads are set to fail with [`standin_dhd_fail_reads`], and
/// for good once the arm is disconnected ([`standin_dhd_disconnect_at`]).
///
/// # Safety
/// The three pointers must each point to a writable double.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn dhdGetPosition(
    px: *mut f64,
    py: *mut f64,
    pz: *mut f64,
    id: c_char,
) -> c_int {
    let mut s = state();
    if s.device(id).is_none() {
        return -1;
    }
    let read = s.calls.position_reads;
    s.calls.position_reads += 1;
    s.calls.max_set_force_per_read = s.calls.max_set_force_per_read.max(s.set_force_since_read);
    s.set_force_since_read = 0;
    if s.disconnected() {
        s.last_error = DHD_ERROR_COM;
        return -1;
    }
    if s.fail_reads > 0 {
        s.fail_reads -= 1;
        s.last_error = DHD_ERROR_COM;
        return -1;
    }
    if let Some(hand) = s.hand {
        let mut p = s.position_m;
        hand(read, p.as_mut_ptr());
        s.position_m = p;
    }
    let p = s.position_m;
    let step = s.step_m_per_read;
    for (q, d) in s.position_m.iter_mut().zip(step) {
        *q += d;
    }
    // SAFETY: the caller provides three writable doubles.
    unsafe {
        px.write(p[0]);
        py.write(p[1]);
        pz.write(p[2]);
    }
    0
}

/// `int dhdSetForce(double fx, double fy, double fz, char ID)`: fails (-1, `DHD_ERROR_COM`)
/// once the arm is disconnected.
#[unsafe(no_mangle)]
pub extern "C" fn dhdSetForce(fx: f64, fy: f64, fz: f64, id: c_char) -> c_int {
    let mut s = state();
    if s.device(id).is_none() {
        return -1;
    }
    s.calls.set_force_calls += 1;
    s.set_force_since_read += 1;
    s.calls.max_set_force_per_read = s.calls.max_set_force_per_read.max(s.set_force_since_read);
    if s.disconnected() {
        s.last_error = DHD_ERROR_COM;
        return -1;
    }
    s.calls.last_force_n = [fx, fy, fz];
    if s.calls.force_enabled == 1 {
        if s.forces_n.len() < FORCE_LOG_CAPACITY {
            s.forces_n.push([fx, fy, fz]);
        }
        if [fx, fy, fz] != [0.0; 3] {
            s.calls.nonzero_forces_output += 1;
        }
    }
    0
}

/// `uint dhdGetButtonMask(char ID)`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdGetButtonMask(id: c_char) -> c_uint {
    let mut s = state();
    if s.device(id).is_none() {
        return 0;
    }
    s.buttons
}

/// `double dhdGetTime()`: the device clock, seconds: one sample period per position read.
#[unsafe(no_mangle)]
pub extern "C" fn dhdGetTime() -> f64 {
    state().calls.position_reads as f64 * SAMPLE_PERIOD_S
}

/// `int dhdErrorGetLast()`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdErrorGetLast() -> c_int {
    state().last_error
}

/// `const char* dhdErrorGetLastStr()`.
#[unsafe(no_mangle)]
pub extern "C" fn dhdErrorGetLastStr() -> *const c_char {
    match state().last_error {
        0 => c"no error",
        DHD_ERROR_COM => c"communication error between the host and the haptic device",
        DHD_ERROR_NO_DEVICE_FOUND => c"no compatible Force Dimension device found",
        DHD_ERROR_INVALID_INDEX => c"invalid index",
        _ => c"undocumented error",
    }
    .as_ptr()
}

/// Test hook: forgets everything (one omega.3, closed, at the origin, at rest).
#[unsafe(no_mangle)]
pub extern "C" fn standin_dhd_reset() {
    *state() = State::new();
}

/// Test hook: `count` connected devices (at most 4), all of DHD system type `system_type`.
#[unsafe(no_mangle)]
pub extern "C" fn standin_dhd_set_devices(count: c_int, system_type: c_int) {
    let mut s = state();
    s.device_count = count.clamp(0, 4);
    s.system_type = system_type;
}

/// Test hook: puts the arm at `position_m` moving `step_m` per position read (DHD frame).
///
/// # Safety
/// Both pointers must point to three readable doubles.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn standin_dhd_set_motion(position_m: *const f64, step_m: *const f64) {
    // SAFETY: the caller provides three readable doubles behind each pointer.
    let (p, d) = unsafe {
        (
            std::ptr::read(position_m.cast::<[f64; 3]>()),
            std::ptr::read(step_m.cast::<[f64; 3]>()),
        )
    };
    let mut s = state();
    s.position_m = p;
    s.step_m_per_read = d;
}

/// Test hook: the buttons (bit i set while button i is pressed).
#[unsafe(no_mangle)]
pub extern "C" fn standin_dhd_set_buttons(buttons: c_uint) {
    state().buttons = buttons;
}

/// Test hook: the arm follows `hand` (null: stays where it is, or moves by
/// [`standin_dhd_set_motion`]'s step), which places it at every position read. The hand is
/// called with the stand-in's state locked: it must not call back into the library.
#[unsafe(no_mangle)]
pub extern "C" fn standin_dhd_set_hand(hand: Option<DhdHand>) {
    state().hand = hand;
}

/// Test hook: the arm is unplugged at position read `read` (counting from 0): that read and
/// every later one, and every force command after it, fail with `DHD_ERROR_COM`. [`NEVER`]
/// plugs it back in.
#[unsafe(no_mangle)]
pub extern "C" fn standin_dhd_disconnect_at(read: u64) {
    state().disconnect_at_read = read;
}

/// Test hook: copies up to `capacity` of the forces accepted with force output enabled
/// (oldest first, newtons, DHD frame) to `out`; returns how many were kept in all (at most
/// [`FORCE_LOG_CAPACITY`]).
///
/// # Safety
/// `out` must point to `capacity` writable `[f64; 3]`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn standin_dhd_forces(out: *mut [f64; 3], capacity: usize) -> usize {
    let s = state();
    let n = s.forces_n.len().min(capacity);
    // SAFETY: the caller provides `capacity` writable entries, and n <= capacity.
    unsafe { std::ptr::copy_nonoverlapping(s.forces_n.as_ptr(), out, n) };
    s.forces_n.len()
}

/// Test hook: the next `n` position reads fail with `DHD_ERROR_COM`.
#[unsafe(no_mangle)]
pub extern "C" fn standin_dhd_fail_reads(n: u32) {
    state().fail_reads = n;
}

/// Test hook: copies the call record to `out`.
///
/// # Safety
/// `out` must point to a writable [`DhdCalls`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn standin_dhd_calls(out: *mut DhdCalls) {
    let calls = state().calls;
    // SAFETY: the caller provides a writable DhdCalls.
    unsafe { out.write(calls) };
}
