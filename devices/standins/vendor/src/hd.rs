//! The HD API subset: device init, frames, state queries, force output, the scheduler, errors.
//!
//! Units and frame as HD's: millimetres, newtons, x right, y up, z toward the user. Reported
//! figures are the constants below (a Touch-sized arm with an off-centre usable workspace, so a
//! test can tell figures read from the library from the driver's published defaults).

use std::ffi::{CStr, c_char, c_int, c_uint, c_ulong, c_ushort, c_void};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Duration;

/// `HD_SUCCESS`.
pub const HD_SUCCESS: c_uint = 0x0000;
/// `HD_INVALID_ENUM`: a parameter this stand-in does not know.
pub const HD_INVALID_ENUM: c_uint = 0x0100;
/// `HD_INVALID_OPERATION`.
pub const HD_INVALID_OPERATION: c_uint = 0x0102;
/// `HD_BAD_HANDLE`.
pub const HD_BAD_HANDLE: c_uint = 0x0104;
/// `HD_EXCEEDED_MAX_FORCE`.
pub const HD_EXCEEDED_MAX_FORCE: c_uint = 0x0201;
/// `HD_DEVICE_FAULT`.
pub const HD_DEVICE_FAULT: c_uint = 0x0300;
/// `HD_COMM_ERROR`.
pub const HD_COMM_ERROR: c_uint = 0x0302;
/// `HD_ILLEGAL_BEGIN`: a frame begun inside a frame.
pub const HD_ILLEGAL_BEGIN: c_uint = 0x0400;
/// `HD_ILLEGAL_END`: a frame ended outside a frame.
pub const HD_ILLEGAL_END: c_uint = 0x0401;
/// `HD_INVALID_HANDLE`.
pub const HD_INVALID_HANDLE: c_uint = 0xFFFF_FFFF;

/// `HD_CURRENT_BUTTONS`.
pub const HD_CURRENT_BUTTONS: c_uint = 0x2000;
/// `HD_CURRENT_POSITION`.
pub const HD_CURRENT_POSITION: c_uint = 0x2050;
/// `HD_CURRENT_VELOCITY`.
pub const HD_CURRENT_VELOCITY: c_uint = 0x2051;
/// `HD_DEVICE_MODEL_TYPE`.
pub const HD_DEVICE_MODEL_TYPE: c_uint = 0x2501;
/// `HD_DEVICE_VENDOR`.
pub const HD_DEVICE_VENDOR: c_uint = 0x2503;
/// `HD_USABLE_WORKSPACE_DIMENSIONS`.
pub const HD_USABLE_WORKSPACE_DIMENSIONS: c_uint = 0x2551;
/// `HD_INPUT_DOF`.
pub const HD_INPUT_DOF: c_uint = 0x2553;
/// `HD_OUTPUT_DOF`.
pub const HD_OUTPUT_DOF: c_uint = 0x2554;
/// `HD_UPDATE_RATE`.
pub const HD_UPDATE_RATE: c_uint = 0x2600;
/// `HD_NOMINAL_MAX_STIFFNESS`.
pub const HD_NOMINAL_MAX_STIFFNESS: c_uint = 0x2602;
/// `HD_NOMINAL_MAX_FORCE`.
pub const HD_NOMINAL_MAX_FORCE: c_uint = 0x2603;
/// `HD_NOMINAL_MAX_CONTINUOUS_FORCE`.
pub const HD_NOMINAL_MAX_CONTINUOUS_FORCE: c_uint = 0x2604;
/// `HD_NOMINAL_MAX_DAMPING`.
pub const HD_NOMINAL_MAX_DAMPING: c_uint = 0x2609;
/// `HD_CURRENT_FORCE`.
pub const HD_CURRENT_FORCE: c_uint = 0x2700;
/// `HD_FORCE_OUTPUT`.
pub const HD_FORCE_OUTPUT: c_uint = 0x4000;
/// `HD_CALLBACK_DONE`.
pub const HD_CALLBACK_DONE: c_uint = 0;
/// `HD_CALLBACK_CONTINUE`.
pub const HD_CALLBACK_CONTINUE: c_uint = 1;

/// Model string the stand-in reports for `HD_DEVICE_MODEL_TYPE`.
pub const MODEL: &CStr = c"Touch (stand-in)";
/// `HD_NOMINAL_MAX_FORCE`, newtons.
pub const NOMINAL_MAX_FORCE_N: f64 = 3.3;
/// `HD_NOMINAL_MAX_CONTINUOUS_FORCE`, newtons.
pub const NOMINAL_MAX_CONTINUOUS_FORCE_N: f64 = 0.88;
/// `HD_NOMINAL_MAX_STIFFNESS`, newtons per millimetre.
pub const NOMINAL_MAX_STIFFNESS_N_PER_MM: f64 = 1.26;
/// `HD_NOMINAL_MAX_DAMPING`, newton-seconds per millimetre.
pub const NOMINAL_MAX_DAMPING_N_S_PER_MM: f64 = 0.003;
/// `HD_USABLE_WORKSPACE_DIMENSIONS`: min x, y, z then max x, y, z, millimetres.
pub const USABLE_WORKSPACE_MM: [f64; 6] = [-80.0, -55.0, -35.0, 80.0, 65.0, 35.0];
/// `HD_UPDATE_RATE`, hertz.
pub const UPDATE_RATE_HZ: c_int = 1000;
/// The one device handle the stand-in hands out.
pub const DEVICE_HANDLE: c_uint = 1;

/// `HDErrorInfo`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HdErrorInfo {
    /// The `HD_` error code.
    pub error_code: c_uint,
    /// The device's own code.
    pub internal_error_code: c_int,
    /// The handle current when the error occurred.
    pub hhd: c_uint,
}

/// `HDSchedulerCallback`.
pub type HdSchedulerCallback = unsafe extern "C" fn(*mut c_void) -> c_uint;

/// A scripted hand for [`standin_hd_set_hand`]: writes the arm's position (three doubles,
/// millimetres) during frame `frame` (counting from 0) to `position_mm`.
pub type HdHand = extern "C" fn(frame: u64, position_mm: *mut f64);

/// Most forces [`standin_hd_forces`] keeps (a minute of servo frames at 1 kHz); later ones
/// are counted in [`HdCalls::set_force_calls`] but not kept.
pub const FORCE_LOG_CAPACITY: usize = 60_000;

/// [`standin_hd_fail_from_frame`]'s "never".
pub const NEVER: u64 = u64::MAX;

/// What the driver has done to the stand-in, read with [`standin_hd_calls`].
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HdCalls {
    /// Servo ticks run (each runs every scheduled callback once).
    pub ticks: u64,
    /// `hdBeginFrame` calls.
    pub frames: u64,
    /// `hdSetDoublev(HD_CURRENT_FORCE)` calls.
    pub set_force_calls: u64,
    /// Of those, calls made outside a frame (the force would never reach the arm).
    pub set_force_outside_frame: u64,
    /// Most `HD_CURRENT_FORCE` writes inside one frame.
    pub max_set_force_per_frame: u32,
    /// Whether `HD_FORCE_OUTPUT` is enabled (1) or not (0).
    pub force_output_enabled: u32,
    /// The force the arm outputs: the last one set in a frame with force output enabled,
    /// newtons (zero while force output is disabled).
    pub output_force_n: [f64; 3],
    /// Forces set, in frames with force output enabled, that were not exactly zero.
    pub nonzero_forces_output: u64,
    /// `hdInitDevice` calls that succeeded.
    pub init_calls: u32,
    /// `hdDisableDevice` calls.
    pub disable_calls: u32,
    /// Whether the scheduler is running (1) or not (0).
    pub scheduler_running: u32,
    /// Callbacks currently scheduled asynchronously.
    pub scheduled_callbacks: u32,
}

struct Scheduled {
    callback: HdSchedulerCallback,
    user_data: usize,
    handle: c_ulong,
}

struct State {
    manual: bool,
    device_open: bool,
    fail_init: c_uint,
    errors: Vec<HdErrorInfo>,
    pending_fault: c_uint,
    scheduled: Vec<Scheduled>,
    next_handle: c_ulong,
    in_frame: bool,
    set_force_in_frame: u32,
    position_mm: [f64; 3],
    step_mm_per_tick: [f64; 3],
    buttons: c_int,
    hand: Option<HdHand>,
    /// Every frame from this one on (counting from 0) ends with `HD_COMM_ERROR`.
    fail_from_frame: u64,
    /// The forces set inside frames with force output enabled, in order (bounded).
    forces_n: Vec<[f64; 3]>,
    calls: HdCalls,
}

impl State {
    const fn new() -> Self {
        Self {
            manual: false,
            device_open: false,
            fail_init: HD_SUCCESS,
            errors: Vec::new(),
            pending_fault: HD_SUCCESS,
            scheduled: Vec::new(),
            next_handle: 1,
            in_frame: false,
            set_force_in_frame: 0,
            position_mm: [0.0; 3],
            step_mm_per_tick: [0.0; 3],
            buttons: 0,
            hand: None,
            fail_from_frame: NEVER,
            forces_n: Vec::new(),
            calls: HdCalls {
                ticks: 0,
                frames: 0,
                set_force_calls: 0,
                set_force_outside_frame: 0,
                max_set_force_per_frame: 0,
                force_output_enabled: 0,
                output_force_n: [0.0; 3],
                nonzero_forces_output: 0,
                init_calls: 0,
                disable_calls: 0,
                scheduler_running: 0,
                scheduled_callbacks: 0,
            },
        }
    }

    fn error(&mut self, code: c_uint) {
        self.errors.push(HdErrorInfo {
            error_code: code,
            internal_error_code: 0,
            hhd: DEVICE_HANDLE,
        });
    }
}

static STATE: Mutex<State> = Mutex::new(State::new());
static SERVO_STOP: AtomicBool = AtomicBool::new(false);
/// Held while callbacks run: HD runs every callback, synchronous or not, on its one servo
/// thread, so two never run at once; this lock gives the stand-in the same guarantee.
static SERVO_LOCK: Mutex<()> = Mutex::new(());
static SERVO_THREAD: Mutex<Option<JoinHandle<()>>> = Mutex::new(None);

fn state() -> MutexGuard<'static, State> {
    // A test that panicked while holding the lock leaves plain data behind; keep going.
    STATE
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// Runs every scheduled callback once, on the caller's thread, outside the state lock (the
/// callbacks call back into the API). Callbacks that return `HD_CALLBACK_DONE` are removed.
fn tick_once() {
    let _servo = SERVO_LOCK
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    let callbacks: Vec<(HdSchedulerCallback, usize, c_ulong)> = {
        let mut s = state();
        s.calls.ticks += 1;
        let step = s.step_mm_per_tick;
        for (p, d) in s.position_mm.iter_mut().zip(step) {
            *p += d;
        }
        s.scheduled
            .iter()
            .map(|c| (c.callback, c.user_data, c.handle))
            .collect()
    };
    for (callback, user_data, handle) in callbacks {
        // SAFETY: the callback and its user data were handed to hdScheduleAsynchronous by the
        // driver, whose contract (HD's) is that both stay valid until hdUnschedule.
        let code = unsafe { callback(user_data as *mut c_void) };
        if code == HD_CALLBACK_DONE {
            state().scheduled.retain(|c| c.handle != handle);
        }
    }
}

/// `HHD hdInitDevice(HDstring pConfigName)`: opens the one simulated arm (any name).
#[unsafe(no_mangle)]
pub extern "C" fn hdInitDevice(_config_name: *const c_char) -> c_uint {
    let mut s = state();
    if s.fail_init != HD_SUCCESS {
        let code = s.fail_init;
        s.error(code);
        return HD_INVALID_HANDLE;
    }
    s.device_open = true;
    s.calls.init_calls += 1;
    DEVICE_HANDLE
}

/// `void hdDisableDevice(HHD hHD)`.
#[unsafe(no_mangle)]
pub extern "C" fn hdDisableDevice(hhd: c_uint) {
    let mut s = state();
    if hhd != DEVICE_HANDLE || !s.device_open {
        s.error(HD_BAD_HANDLE);
        return;
    }
    s.device_open = false;
    s.calls.disable_calls += 1;
    s.calls.force_output_enabled = 0;
    s.calls.output_force_n = [0.0; 3];
}

/// `void hdMakeCurrentDevice(HHD hHD)`.
#[unsafe(no_mangle)]
pub extern "C" fn hdMakeCurrentDevice(hhd: c_uint) {
    let mut s = state();
    if hhd != DEVICE_HANDLE || !s.device_open {
        s.error(HD_BAD_HANDLE);
    }
}

/// `void hdBeginFrame(HHD hHD)`: with a scripted hand ([`standin_hd_set_hand`]), the arm
/// moves to where the hand is in this frame.
#[unsafe(no_mangle)]
pub extern "C" fn hdBeginFrame(hhd: c_uint) {
    let mut s = state();
    if hhd != DEVICE_HANDLE || !s.device_open {
        s.error(HD_BAD_HANDLE);
        return;
    }
    if s.in_frame {
        s.error(HD_ILLEGAL_BEGIN);
        return;
    }
    s.in_frame = true;
    s.set_force_in_frame = 0;
    if let Some(hand) = s.hand {
        let mut p = s.position_mm;
        hand(s.calls.frames, p.as_mut_ptr());
        s.position_mm = p;
    }
    s.calls.frames += 1;
}

/// `void hdEndFrame(HHD hHD)`: a fault injected with [`standin_hd_inject_fault`] is raised
/// here, as a device error surfaces at the end of the servo frame it happened in; so is the
/// communication error of every frame from [`standin_hd_fail_from_frame`]'s on.
#[unsafe(no_mangle)]
pub extern "C" fn hdEndFrame(_hhd: c_uint) {
    let mut s = state();
    if !s.in_frame {
        s.error(HD_ILLEGAL_END);
        return;
    }
    s.in_frame = false;
    s.calls.max_set_force_per_frame = s.calls.max_set_force_per_frame.max(s.set_force_in_frame);
    if s.pending_fault != HD_SUCCESS {
        let code = std::mem::replace(&mut s.pending_fault, HD_SUCCESS);
        s.error(code);
    }
    // `frames` already counts this frame.
    if s.calls.frames > s.fail_from_frame {
        s.error(HD_COMM_ERROR);
    }
}

/// `void hdGetDoublev(HDenum pname, HDdouble *params)`.
///
/// # Safety
/// `params` must point to as many doubles as `pname` returns (3 for positions and velocities,
/// 6 for the workspace, 1 for the nominal figures).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn hdGetDoublev(pname: c_uint, params: *mut f64) {
    let mut s = state();
    let values: &[f64] = match pname {
        HD_CURRENT_POSITION => &s.position_mm.clone(),
        HD_CURRENT_VELOCITY => &s.step_mm_per_tick.map(|d| d * f64::from(UPDATE_RATE_HZ)),
        HD_NOMINAL_MAX_FORCE => &[NOMINAL_MAX_FORCE_N],
        HD_NOMINAL_MAX_CONTINUOUS_FORCE => &[NOMINAL_MAX_CONTINUOUS_FORCE_N],
        HD_NOMINAL_MAX_STIFFNESS => &[NOMINAL_MAX_STIFFNESS_N_PER_MM],
        HD_NOMINAL_MAX_DAMPING => &[NOMINAL_MAX_DAMPING_N_S_PER_MM],
        HD_USABLE_WORKSPACE_DIMENSIONS => &USABLE_WORKSPACE_MM,
        _ => {
            s.error(HD_INVALID_ENUM);
            return;
        }
    };
    // SAFETY: the caller provides room for `values.len()` doubles for this `pname`.
    unsafe { std::ptr::copy_nonoverlapping(values.as_ptr(), params, values.len()) };
}

/// `void hdGetIntegerv(HDenum pname, HDint *params)`.
///
/// # Safety
/// `params` must point to one writable `int`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn hdGetIntegerv(pname: c_uint, params: *mut c_int) {
    let mut s = state();
    let value = match pname {
        HD_CURRENT_BUTTONS => s.buttons,
        HD_UPDATE_RATE => UPDATE_RATE_HZ,
        HD_INPUT_DOF => 6,
        HD_OUTPUT_DOF => 3,
        _ => {
            s.error(HD_INVALID_ENUM);
            return;
        }
    };
    // SAFETY: the caller provides one writable int.
    unsafe { params.write(value) };
}

/// `void hdSetDoublev(HDenum pname, const HDdouble *params)`: only `HD_CURRENT_FORCE`.
///
/// # Safety
/// `params` must point to three readable doubles.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn hdSetDoublev(pname: c_uint, params: *const f64) {
    let mut s = state();
    if pname != HD_CURRENT_FORCE {
        s.error(HD_INVALID_ENUM);
        return;
    }
    // SAFETY: the caller provides three readable doubles for HD_CURRENT_FORCE.
    let force = unsafe { [params.read(), params.add(1).read(), params.add(2).read()] };
    s.calls.set_force_calls += 1;
    if !s.in_frame {
        s.calls.set_force_outside_frame += 1;
        s.error(HD_INVALID_OPERATION);
        return;
    }
    s.set_force_in_frame += 1;
    if s.calls.force_output_enabled == 1 {
        if s.forces_n.len() < FORCE_LOG_CAPACITY {
            s.forces_n.push(force);
        }
        s.calls.output_force_n = force;
        if force != [0.0; 3] {
            s.calls.nonzero_forces_output += 1;
        }
    }
}

/// `HDstring hdGetString(HDenum pname)`.
#[unsafe(no_mangle)]
pub extern "C" fn hdGetString(pname: c_uint) -> *const c_char {
    match pname {
        HD_DEVICE_MODEL_TYPE => MODEL.as_ptr(),
        HD_DEVICE_VENDOR => c"dynaclay stand-in".as_ptr(),
        _ => {
            state().error(HD_INVALID_ENUM);
            std::ptr::null()
        }
    }
}

/// `void hdEnable(HDenum cap)`.
#[unsafe(no_mangle)]
pub extern "C" fn hdEnable(cap: c_uint) {
    let mut s = state();
    if cap == HD_FORCE_OUTPUT {
        s.calls.force_output_enabled = 1;
    } else {
        s.error(HD_INVALID_ENUM);
    }
}

/// `void hdDisable(HDenum cap)`.
#[unsafe(no_mangle)]
pub extern "C" fn hdDisable(cap: c_uint) {
    let mut s = state();
    if cap == HD_FORCE_OUTPUT {
        s.calls.force_output_enabled = 0;
        s.calls.output_force_n = [0.0; 3];
    } else {
        s.error(HD_INVALID_ENUM);
    }
}

/// `HDErrorInfo hdGetError(void)`: pops the oldest error, `HD_SUCCESS` when none.
#[unsafe(no_mangle)]
pub extern "C" fn hdGetError() -> HdErrorInfo {
    let mut s = state();
    if s.errors.is_empty() {
        HdErrorInfo::default()
    } else {
        s.errors.remove(0)
    }
}

/// `HDstring hdGetErrorString(HDerror errorCode)`.
#[unsafe(no_mangle)]
pub extern "C" fn hdGetErrorString(code: c_uint) -> *const c_char {
    match code {
        HD_SUCCESS => c"success",
        HD_INVALID_ENUM => c"invalid enum",
        HD_INVALID_OPERATION => c"invalid operation",
        HD_BAD_HANDLE => c"bad handle",
        HD_EXCEEDED_MAX_FORCE => c"exceeded max force",
        HD_DEVICE_FAULT => c"device fault",
        HD_COMM_ERROR => c"communication error",
        HD_ILLEGAL_BEGIN => c"illegal begin",
        HD_ILLEGAL_END => c"illegal end",
        _ => c"unknown error",
    }
    .as_ptr()
}

/// `void hdStartScheduler(void)`: starts the 1 kHz servo thread, or only marks the
/// scheduler running in manual mode.
#[unsafe(no_mangle)]
pub extern "C" fn hdStartScheduler() {
    let manual = {
        let mut s = state();
        if s.calls.scheduler_running == 1 {
            return;
        }
        s.calls.scheduler_running = 1;
        s.manual
    };
    if manual {
        return;
    }
    SERVO_STOP.store(false, Ordering::SeqCst);
    let thread = std::thread::spawn(|| {
        while !SERVO_STOP.load(Ordering::SeqCst) {
            tick_once();
            std::thread::sleep(Duration::from_millis(1));
        }
    });
    *SERVO_THREAD
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner) = Some(thread);
}

/// `void hdStopScheduler(void)`: stops the servo thread; no callback runs after it returns.
#[unsafe(no_mangle)]
pub extern "C" fn hdStopScheduler() {
    SERVO_STOP.store(true, Ordering::SeqCst);
    let thread = SERVO_THREAD
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
        .take();
    if let Some(t) = thread {
        let _ = t.join();
    }
    state().calls.scheduler_running = 0;
}

/// `HDSchedulerHandle hdScheduleAsynchronous(HDSchedulerCallback, void *pUserData,
/// HDushort nPriority)`: runs `callback` once per servo tick until it returns
/// `HD_CALLBACK_DONE` or is unscheduled.
#[unsafe(no_mangle)]
pub extern "C" fn hdScheduleAsynchronous(
    callback: HdSchedulerCallback,
    user_data: *mut c_void,
    _priority: c_ushort,
) -> c_ulong {
    let mut s = state();
    let handle = s.next_handle;
    s.next_handle += 1;
    s.scheduled.push(Scheduled {
        callback,
        user_data: user_data as usize,
        handle,
    });
    s.calls.scheduled_callbacks = s.scheduled.len() as u32;
    handle
}

/// `void hdScheduleSynchronous(HDSchedulerCallback, void *pUserData, HDushort nPriority)`:
/// runs `callback` until it returns `HD_CALLBACK_DONE` (at most 1000 times), on the caller's
/// thread, as one servo tick's worth of work each time.
///
/// # Safety
/// `callback` must be safe to call with `user_data`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn hdScheduleSynchronous(
    callback: HdSchedulerCallback,
    user_data: *mut c_void,
    _priority: c_ushort,
) {
    let _servo = SERVO_LOCK
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    for _ in 0..1000 {
        // SAFETY: the caller vouches for callback and user data.
        if unsafe { callback(user_data) } == HD_CALLBACK_DONE {
            return;
        }
    }
}

/// `void hdUnschedule(HDSchedulerHandle hHandle)`.
#[unsafe(no_mangle)]
pub extern "C" fn hdUnschedule(handle: c_ulong) {
    let mut s = state();
    s.scheduled.retain(|c| c.handle != handle);
    s.calls.scheduled_callbacks = s.scheduled.len() as u32;
}

/// Test hook: forgets everything (the arm at the origin, at rest; no errors; counters zero;
/// manual mode off). Stops the servo thread first.
#[unsafe(no_mangle)]
pub extern "C" fn standin_hd_reset() {
    hdStopScheduler();
    *state() = State::new();
}

/// Test hook: manual mode (`on != 0`): the scheduler starts no thread, and servo ticks run
/// only through [`standin_hd_tick`].
#[unsafe(no_mangle)]
pub extern "C" fn standin_hd_set_manual(on: c_int) {
    state().manual = on != 0;
}

/// Test hook: runs `n` servo ticks on the caller's thread; returns the total tick count.
#[unsafe(no_mangle)]
pub extern "C" fn standin_hd_tick(n: u32) -> u64 {
    for _ in 0..n {
        tick_once();
    }
    state().calls.ticks
}

/// Test hook: puts the arm at `position_mm` moving `step_mm` per servo tick.
///
/// # Safety
/// Both pointers must point to three readable doubles.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn standin_hd_set_motion(position_mm: *const f64, step_mm: *const f64) {
    // SAFETY: the caller provides three readable doubles behind each pointer.
    let (p, d) = unsafe {
        (
            std::ptr::read(position_mm.cast::<[f64; 3]>()),
            std::ptr::read(step_mm.cast::<[f64; 3]>()),
        )
    };
    let mut s = state();
    s.position_mm = p;
    s.step_mm_per_tick = d;
}

/// Test hook: the stylus buttons (bit i set while button i is pressed).
#[unsafe(no_mangle)]
pub extern "C" fn standin_hd_set_buttons(buttons: c_int) {
    state().buttons = buttons;
}

/// Test hook: the arm follows `hand` (null: stays where it is, or moves by
/// [`standin_hd_set_motion`]'s step), which places it at the start of every frame. The hand is
/// called with the stand-in's state locked: it must not call back into the library.
#[unsafe(no_mangle)]
pub extern "C" fn standin_hd_set_hand(hand: Option<HdHand>) {
    state().hand = hand;
}

/// Test hook: the arm is unplugged from frame `frame` on (counting from 0): that frame and
/// every later one end with `HD_COMM_ERROR`. [`NEVER`] plugs it back in.
#[unsafe(no_mangle)]
pub extern "C" fn standin_hd_fail_from_frame(frame: u64) {
    state().fail_from_frame = frame;
}

/// Test hook: copies up to `capacity` of the forces set in frames with force output enabled
/// (oldest first, newtons, HD frame) to `out`; returns how many were kept in all (at most
/// [`FORCE_LOG_CAPACITY`]).
///
/// # Safety
/// `out` must point to `capacity` writable `[f64; 3]`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn standin_hd_forces(out: *mut [f64; 3], capacity: usize) -> usize {
    let s = state();
    let n = s.forces_n.len().min(capacity);
    // SAFETY: the caller provides `capacity` writable entries, and n <= capacity.
    unsafe { std::ptr::copy_nonoverlapping(s.forces_n.as_ptr(), out, n) };
    s.forces_n.len()
}

/// Test hook: the next servo frame ends with error `code` (e.g. `HD_COMM_ERROR`).
#[unsafe(no_mangle)]
pub extern "C" fn standin_hd_inject_fault(code: c_uint) {
    state().pending_fault = code;
}

/// Test hook: `hdInitDevice` fails with `code` (`HD_SUCCESS` to succeed again).
#[unsafe(no_mangle)]
pub extern "C" fn standin_hd_fail_init(code: c_uint) {
    state().fail_init = code;
}

/// Test hook: copies the call record to `out`.
///
/// # Safety
/// `out` must point to a writable [`HdCalls`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn standin_hd_calls(out: *mut HdCalls) {
    let calls = state().calls;
    // SAFETY: the caller provides a writable HdCalls.
    unsafe { out.write(calls) };
}
