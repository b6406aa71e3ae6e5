//! 3D Systems Touch, Touch X and Phantom arms through OpenHaptics' HD API (`libHD.so`), loaded
//! at run time (see [`crate::vendor_lib`]).
//!
//! Who ticks: HD runs its own servo thread (the scheduler, 1 kHz on these arms) and only
//! code inside a servo frame (`hdBeginFrame` … `hdEndFrame`) on that thread may read the arm
//! and command force. So dynaclay's haptic loop does not drive the device: `open` schedules one
//! callback that runs every servo tick and, inside one frame, reads position, velocity and
//! buttons, sets `HD_CURRENT_FORCE` once, ends the frame and checks `hdGetError`. The loop's
//! `read` and `write_force` only exchange the latest sample and the latest force with that
//! callback through two wait-free triple buffers and one atomic fault code: no lock, no
//! allocation, no call into HD, constant time. Each servo tick sends the newest force the loop
//! has written exactly once; a force written twice between ticks is sent once (the newer),
//! and one not renewed is sent again, as HD expects a force every frame.
//!
//! In lockstep ([`HdServo::Lockstep`], `dynaclay run --lockstep`) nothing is scheduled to run
//! every tick: `open` starts the scheduler with no asynchronous callback, and each `read` runs
//! exactly one servo frame through `hdScheduleSynchronous` (HD's documented way to run a
//! callback once in the servo thread and wait for it), so the engine's tick *is* the servo
//! tick: one frame, one position read, one `HD_CURRENT_FORCE` per engine tick, the force being
//! the one the engine wrote in its previous tick (the same one-frame delay as the scheduled
//! mode). `read` then waits for that frame (at most one servo period on a real arm), which is
//! what lockstep means: the engine runs on the device's clock. `write_force` stays a buffer
//! write. The frame, the fault code and the zero-force rules are the scheduled mode's.
//!
//! Time is the servo's: a sample's timestamp is its tick count times the servo period (from
//! `HD_UPDATE_RATE`), so the safety filter's slew limit runs on device time.
//!
//! Faults: an error reported after a servo frame (a lost connection, an exceeded force) is
//! latched in the fault code; from the next tick on the callback sends zero until the loop's
//! next `read`, which zeroes the force buffer, clears the code and returns
//! [`DeviceError::Vendor`], so the safety filter latches its own fault and ramps force back in
//! only after a good sample. On `open` the force buffer is zero, so the arm's first forces are
//! zero; `close` sends a zero frame before stopping the scheduler.
//!
//! Before `open`, [`OpenHapticsArm::info`] gives the published figures of the Touch
//! ([`OpenHapticsArm::published_touch_info`]); after it, the figures the library reports for
//! the arm actually connected.

use std::ffi::{CStr, CString, c_char, c_int, c_uint, c_ulong, c_ushort, c_void};
use std::ptr::NonNull;
use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};

use glam::{DVec3, Vec3};

use crate::device::{DeviceError, DeviceInfo, DeviceState, HapticDevice};
use crate::vendor_lib::{self, LibraryMissing, LibrarySource, LoadedLibrary, VendorLibrary};

/// Name of the library in [`DeviceError::Vendor`].
const LIBRARY: &str = "OpenHaptics HD";

// Constants of OpenHaptics' public headers (hdDefines.h, hdScheduler.h).
const HD_SUCCESS: c_uint = 0x0000;
const HD_INVALID_HANDLE: c_uint = 0xFFFF_FFFF;
const HD_CURRENT_BUTTONS: c_uint = 0x2000;
const HD_CURRENT_POSITION: c_uint = 0x2050;
const HD_CURRENT_VELOCITY: c_uint = 0x2051;
const HD_DEVICE_MODEL_TYPE: c_uint = 0x2501;
const HD_USABLE_WORKSPACE_DIMENSIONS: c_uint = 0x2551;
const HD_UPDATE_RATE: c_uint = 0x2600;
const HD_NOMINAL_MAX_STIFFNESS: c_uint = 0x2602;
const HD_NOMINAL_MAX_FORCE: c_uint = 0x2603;
const HD_NOMINAL_MAX_CONTINUOUS_FORCE: c_uint = 0x2604;
const HD_NOMINAL_MAX_DAMPING: c_uint = 0x2609;
const HD_CURRENT_FORCE: c_uint = 0x2700;
const HD_FORCE_OUTPUT: c_uint = 0x4000;
const HD_CALLBACK_DONE: c_uint = 0;
const HD_CALLBACK_CONTINUE: c_uint = 1;
/// `HD_MAX_SCHEDULER_PRIORITY` (`USHRT_MAX`): the servo callback runs before any other.
const HD_MAX_SCHEDULER_PRIORITY: c_ushort = c_ushort::MAX;
/// `HD_DEFAULT_SCHEDULER_PRIORITY`: (max + min) / 2.
const HD_DEFAULT_SCHEDULER_PRIORITY: c_ushort = c_ushort::MAX / 2;

/// `HDErrorInfo`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
struct HdErrorInfo {
    error_code: c_uint,
    internal_error_code: c_int,
    hhd: c_uint,
}

/// `HDSchedulerCallback`: `HDCallbackCode (*)(void *pUserData)`.
type HdCallback = unsafe extern "C" fn(*mut c_void) -> c_uint;

/// The HD functions the servo callback calls (plain pointers, copied out of [`HdApi`]).
#[derive(Clone, Copy)]
struct ServoFns {
    begin_frame: unsafe extern "C" fn(c_uint),
    end_frame: unsafe extern "C" fn(c_uint),
    get_doublev: unsafe extern "C" fn(c_uint, *mut f64),
    get_integerv: unsafe extern "C" fn(c_uint, *mut c_int),
    set_doublev: unsafe extern "C" fn(c_uint, *const f64),
    get_error: unsafe extern "C" fn() -> HdErrorInfo,
}

/// The loaded library and every HD function the driver calls. The function pointers are valid
/// while `library` lives, and the struct never hands them out past its own life except to the
/// servo callback, which [`HdSession`] unschedules before the library goes.
struct HdApi {
    servo: ServoFns,
    init_device: unsafe extern "C" fn(*const c_char) -> c_uint,
    disable_device: unsafe extern "C" fn(c_uint),
    make_current_device: unsafe extern "C" fn(c_uint),
    get_string: unsafe extern "C" fn(c_uint) -> *const c_char,
    enable: unsafe extern "C" fn(c_uint),
    disable: unsafe extern "C" fn(c_uint),
    get_error_string: Option<unsafe extern "C" fn(c_uint) -> *const c_char>,
    start_scheduler: unsafe extern "C" fn(),
    stop_scheduler: unsafe extern "C" fn(),
    schedule_asynchronous: unsafe extern "C" fn(HdCallback, *mut c_void, c_ushort) -> c_ulong,
    schedule_synchronous: unsafe extern "C" fn(HdCallback, *mut c_void, c_ushort),
    unschedule: unsafe extern "C" fn(c_ulong),
    library: LoadedLibrary,
}

impl HdApi {
    fn load(source: &LibrarySource) -> Result<Self, LibraryMissing> {
        let library = vendor_lib::load(VendorLibrary::OpenHapticsHd, source, "hdInitDevice")?;
        let missing = |tried| LibraryMissing {
            library: VendorLibrary::OpenHapticsHd,
            tried: vec![tried],
        };
        // SAFETY: each type below is the C declaration of the named function in OpenHaptics'
        // hd.h / hdScheduler.h (HDenum and HHD are unsigned int, HDSchedulerHandle unsigned
        // long, HDushort unsigned short; HDAPIENTRY is the C convention on Linux), and the
        // pointers live in this struct beside `library`, which outlives them.
        unsafe {
            Ok(Self {
                servo: ServoFns {
                    begin_frame: vendor_lib::function(&library, "hdBeginFrame").map_err(missing)?,
                    end_frame: vendor_lib::function(&library, "hdEndFrame").map_err(missing)?,
                    get_doublev: vendor_lib::function(&library, "hdGetDoublev").map_err(missing)?,
                    get_integerv: vendor_lib::function(&library, "hdGetIntegerv")
                        .map_err(missing)?,
                    set_doublev: vendor_lib::function(&library, "hdSetDoublev").map_err(missing)?,
                    get_error: vendor_lib::function(&library, "hdGetError").map_err(missing)?,
                },
                init_device: vendor_lib::function(&library, "hdInitDevice").map_err(missing)?,
                disable_device: vendor_lib::function(&library, "hdDisableDevice")
                    .map_err(missing)?,
                make_current_device: vendor_lib::function(&library, "hdMakeCurrentDevice")
                    .map_err(missing)?,
                get_string: vendor_lib::function(&library, "hdGetString").map_err(missing)?,
                enable: vendor_lib::function(&library, "hdEnable").map_err(missing)?,
                disable: vendor_lib::function(&library, "hdDisable").map_err(missing)?,
                get_error_string: vendor_lib::optional_function(&library, "hdGetErrorString"),
                start_scheduler: vendor_lib::function(&library, "hdStartScheduler")
                    .map_err(missing)?,
                stop_scheduler: vendor_lib::function(&library, "hdStopScheduler")
                    .map_err(missing)?,
                schedule_asynchronous: vendor_lib::function(&library, "hdScheduleAsynchronous")
                    .map_err(missing)?,
                schedule_synchronous: vendor_lib::function(&library, "hdScheduleSynchronous")
                    .map_err(missing)?,
                unschedule: vendor_lib::function(&library, "hdUnschedule").map_err(missing)?,
                library,
            })
        }
    }

    /// Pops HD's oldest error (`HD_SUCCESS` when there is none).
    fn error(&self) -> HdErrorInfo {
        // SAFETY: hdGetError takes no arguments and may be called on any thread.
        unsafe { (self.servo.get_error)() }
    }

    /// HD's text for an error code; where the library gives none (no `hdGetErrorString`, or
    /// a null answer), the code itself, so the message still names the error.
    fn error_text(&self, code: c_uint) -> String {
        // SAFETY: hdGetErrorString returns a static string or null for any code.
        let text = self.get_error_string.map(|f| unsafe { f(code) });
        match text {
            // SAFETY: a non-null return is a NUL-terminated static string.
            Some(p) if !p.is_null() => unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned(),
            _ => format!("HD error {code:#06x} (the library gives no text for it)"),
        }
    }

    /// `count` doubles of parameter `pname`, if HD reports them without error, all finite.
    fn doubles<const N: usize>(&self, pname: c_uint) -> Option<[f64; N]> {
        let mut v = [f64::NAN; N];
        // SAFETY: every parameter queried here returns exactly N doubles (HD's reference).
        unsafe { (self.servo.get_doublev)(pname, v.as_mut_ptr()) };
        (self.error().error_code == HD_SUCCESS && v.iter().all(|x| x.is_finite())).then_some(v)
    }

    fn integer(&self, pname: c_uint) -> Option<c_int> {
        let mut v: c_int = 0;
        // SAFETY: the parameters queried here return one int.
        unsafe { (self.servo.get_integerv)(pname, &raw mut v) };
        (self.error().error_code == HD_SUCCESS).then_some(v)
    }

    fn string(&self, pname: c_uint) -> Option<String> {
        // SAFETY: hdGetString returns a string owned by HD (or null) for a string parameter.
        let p = unsafe { (self.get_string)(pname) };
        if self.error().error_code != HD_SUCCESS || p.is_null() {
            return None;
        }
        // SAFETY: non-null, NUL-terminated, valid until the next HD call; copied at once.
        Some(unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned())
    }

    /// The current device's figures, each falling back to `published` where HD has none.
    fn query_info(&self, published: &DeviceInfo) -> (DeviceInfo, u64) {
        let mut info = published.clone();
        if let Some(model) = self.string(HD_DEVICE_MODEL_TYPE).filter(|m| !m.is_empty()) {
            info.name = format!("{model} (OpenHaptics)");
        }
        let positive = |v: Option<[f64; 1]>| v.map(|[x]| x).filter(|x| *x > 0.0);
        let continuous = positive(self.doubles(HD_NOMINAL_MAX_CONTINUOUS_FORCE));
        let peak = positive(self.doubles(HD_NOMINAL_MAX_FORCE));
        if let Some(f) = continuous.or(peak) {
            info.max_force_n = f as f32;
        }
        // HD's stiffness is newtons per millimetre, its damping newton-seconds per millimetre.
        if let Some(k) = positive(self.doubles(HD_NOMINAL_MAX_STIFFNESS)) {
            info.max_stiffness_n_per_m = (k * 1000.0) as f32;
        }
        if let Some(b) = positive(self.doubles(HD_NOMINAL_MAX_DAMPING)) {
            info.max_damping_n_s_per_m = (b * 1000.0) as f32;
        }
        if let Some(w) = self.doubles::<6>(HD_USABLE_WORKSPACE_DIMENSIONS) {
            let min = DVec3::new(w[0], w[1], w[2]) * 1e-3;
            let max = DVec3::new(w[3], w[4], w[5]) * 1e-3;
            if min.cmplt(max).all() {
                info.workspace_min_m = min.as_vec3();
                info.workspace_max_m = max.as_vec3();
            }
        }
        let rate_hz = self
            .integer(HD_UPDATE_RATE)
            .filter(|r| (1..=100_000).contains(r))
            .unwrap_or(1000);
        info.sample_rate_hz = rate_hz as f32;
        (info, 1_000_000 / rate_hz as u64)
    }
}

/// One servo tick's reading of the arm, HD units (millimetres).
#[derive(Clone, Copy, Debug, Default)]
struct ServoSample {
    position_mm: [f64; 3],
    velocity_mm_per_s: [f64; 3],
    buttons: c_int,
    /// Servo ticks since `open` (1 for the first sample).
    tick: u64,
}

/// State both threads touch: only atomics.
struct ServoShared {
    /// `HD_SUCCESS`, or the first HD error a servo frame reported that `read` has not yet
    /// returned. While it is set the servo sends zero force.
    fault_code: AtomicU32,
}

/// What the servo callback owns; touched only on HD's servo thread (HD runs all callbacks,
/// synchronous and asynchronous, there, one at a time).
struct ServoSide {
    fns: ServoFns,
    hhd: c_uint,
    pose_in: triple_buffer::Input<ServoSample>,
    force_out: triple_buffer::Output<[f64; 3]>,
    shared: Arc<ServoShared>,
    tick: u64,
}

impl ServoSide {
    /// One servo frame: read the arm, send the force once, check for errors, publish.
    fn run_frame(&mut self) {
        let f = self.fns;
        let mut sample = ServoSample {
            tick: self.tick + 1,
            ..ServoSample::default()
        };
        let force = if self.shared.fault_code.load(Ordering::Acquire) == HD_SUCCESS {
            // NOTE: Acquire pairs with `read`'s Release store of HD_SUCCESS, so a force zeroed
            // before the fault was cleared is the force seen here.
            *self.force_out.read()
        } else {
            [0.0; 3]
        };
        // SAFETY: called only from the servo callbacks, on HD's servo thread, while the
        // session that scheduled them lives; the pointers come from the loaded library and
        // the out-pointers are to locals of the sizes HD writes (3 doubles, 1 int).
        let error = unsafe {
            (f.begin_frame)(self.hhd);
            (f.get_doublev)(HD_CURRENT_POSITION, sample.position_mm.as_mut_ptr());
            (f.get_doublev)(HD_CURRENT_VELOCITY, sample.velocity_mm_per_s.as_mut_ptr());
            (f.get_integerv)(HD_CURRENT_BUTTONS, &raw mut sample.buttons);
            (f.set_doublev)(HD_CURRENT_FORCE, force.as_ptr());
            (f.end_frame)(self.hhd);
            (f.get_error)()
        };
        if error.error_code != HD_SUCCESS {
            // NOTE: the first unread fault wins; Release publishes it with the sample below.
            let _ = self.shared.fault_code.compare_exchange(
                HD_SUCCESS,
                error.error_code,
                Ordering::AcqRel,
                Ordering::Acquire,
            );
        }
        self.tick += 1;
        self.pose_in.write(sample);
    }
}

/// The callback HD runs every servo tick.
///
/// # Safety
/// `user_data` is the [`ServoSide`] of a live [`HdSession`], and only HD's servo thread calls
/// this (so the `&mut` is unique).
unsafe extern "C" fn servo_tick(user_data: *mut c_void) -> c_uint {
    // SAFETY: as this function's contract says.
    let servo = unsafe { &mut *user_data.cast::<ServoSide>() };
    servo.run_frame();
    HD_CALLBACK_CONTINUE
}

/// [`servo_tick`] once, for `hdScheduleSynchronous` (the first sample; the zero at close).
///
/// # Safety
/// As [`servo_tick`].
unsafe extern "C" fn servo_tick_once(user_data: *mut c_void) -> c_uint {
    // SAFETY: as this function's contract says.
    let servo = unsafe { &mut *user_data.cast::<ServoSide>() };
    servo.run_frame();
    HD_CALLBACK_DONE
}

/// The servo side, owned through a raw pointer because HD holds a copy of it as user data
/// while the scheduler runs (a `Box` would assert unique access each time it moved).
struct ServoBox(NonNull<ServoSide>);

// SAFETY: ServoSide is Send (its fields are plain function pointers, triple-buffer ends of
// Send data and an Arc of atomics); the pointer is the only owner.
unsafe impl Send for ServoBox {}

/// An open arm: the device handle, the scheduled callback and the loop's ends of the buffers.
struct HdSession {
    api: HdApi,
    hhd: c_uint,
    /// The every-tick callback's handle; `None` in lockstep, where `read` runs the frames.
    scheduled: Option<c_ulong>,
    servo: ServoBox,
    pose_out: triple_buffer::Output<ServoSample>,
    force_in: triple_buffer::Input<[f64; 3]>,
    shared: Arc<ServoShared>,
    period_us: u64,
    /// Whether `hdStartScheduler` succeeded (a synchronous call needs a running scheduler).
    scheduler_running: bool,
    shut_down: bool,
}

impl HdSession {
    fn servo_ptr(&self) -> *mut c_void {
        self.servo.0.as_ptr().cast()
    }

    /// Sends one zero-force frame, disables force output, stops the scheduler, unschedules the
    /// callback and releases the device. Idempotent.
    fn shut_down(&mut self) -> Result<(), DeviceError> {
        if self.shut_down {
            return Ok(());
        }
        self.shut_down = true;
        self.force_in.write([0.0; 3]);
        // SAFETY: the servo side is live until the end of this function; the synchronous
        // call runs the frame on HD's servo thread and returns when it is done. After
        // hdStopScheduler returns, HD runs no callback, so the servo side may be freed.
        unsafe {
            if self.scheduler_running {
                (self.api.schedule_synchronous)(
                    servo_tick_once,
                    self.servo_ptr(),
                    HD_DEFAULT_SCHEDULER_PRIORITY,
                );
            }
            // `close` may run on another thread than `open`: name the device again.
            (self.api.make_current_device)(self.hhd);
            (self.api.disable)(HD_FORCE_OUTPUT);
            (self.api.stop_scheduler)();
            if let Some(handle) = self.scheduled {
                (self.api.unschedule)(handle);
            }
            (self.api.disable_device)(self.hhd);
        }
        let error = self.api.error();
        // Drain whatever else HD queued, bounded.
        for _ in 0..16 {
            if self.api.error().error_code == HD_SUCCESS {
                break;
            }
        }
        if error.error_code == HD_SUCCESS {
            Ok(())
        } else {
            Err(DeviceError::Vendor {
                library: LIBRARY,
                code: error.error_code,
                context: "closing the device",
            })
        }
    }
}

impl Drop for HdSession {
    fn drop(&mut self) {
        let _ = self.shut_down();
        // SAFETY: the scheduler is stopped and the callback unscheduled (shut_down), so HD
        // holds no live use of the pointer; it came from Box::into_raw in `open`.
        drop(unsafe { Box::from_raw(self.servo.0.as_ptr()) });
    }
}

/// Who runs the servo frames of an [`OpenHapticsArm`] (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HdServo {
    /// HD's scheduler runs a frame every servo tick on its own thread; the haptic loop
    /// exchanges samples and forces with it through wait-free buffers (real-time runs).
    #[default]
    Scheduled,
    /// Each `read` runs one frame through `hdScheduleSynchronous` and waits for it: one servo
    /// frame per engine tick (lockstep runs).
    Lockstep,
}

/// Settings of an [`OpenHapticsArm`].
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct OpenHapticsConfig {
    /// Where `libHD.so` comes from.
    pub library: LibrarySource,
    /// The HD device configuration name (as set up in Touch_Setup); `None` opens
    /// `HD_DEFAULT_DEVICE`.
    pub device_name: Option<String>,
    /// Who runs the servo frames.
    pub servo: HdServo,
}

/// A Touch or Phantom arm through OpenHaptics' HD API; see the module docs for who ticks.
pub struct OpenHapticsArm {
    config: OpenHapticsConfig,
    info: DeviceInfo,
    session: Option<HdSession>,
    loaded_from: Option<String>,
}

impl OpenHapticsArm {
    /// An arm (not opened yet); nothing is loaded until `open`.
    #[must_use]
    pub fn new(config: OpenHapticsConfig) -> Self {
        Self {
            config,
            info: Self::published_touch_info(),
            session: None,
            loaded_from: None,
        }
    }

    /// The 3D Systems Touch's published figures, used until `open` reads the connected arm's:
    /// 0.88 N continuous force (3.3 N peak), 1.26 N/mm stiffness (x axis, the figure 3D
    /// Systems lists first), a usable workspace of 160 × 120 × 70 mm (width, height, depth)
    /// about the origin, two stylus buttons, a 1 kHz servo. The damping bound is not
    /// published: zero until HD reports `HD_NOMINAL_MAX_DAMPING`. Orientation (the gimbal)
    /// is not read: 3 degrees of freedom.
    #[must_use]
    pub fn published_touch_info() -> DeviceInfo {
        DeviceInfo {
            name: "3D Systems Touch (OpenHaptics)".into(),
            dof: 3,
            max_force_n: 0.88,
            max_stiffness_n_per_m: 1260.0,
            max_damping_n_s_per_m: 0.0,
            workspace_min_m: Vec3::new(-0.080, -0.060, -0.035),
            workspace_max_m: Vec3::new(0.080, 0.060, 0.035),
            has_orientation: false,
            has_force: true,
            button_count: 2,
            sample_rate_hz: 1000.0,
        }
    }

    /// Where `libHD.so` was loaded from by the last `open` (a path or a loader name).
    #[must_use]
    pub fn loaded_from(&self) -> Option<&str> {
        self.loaded_from.as_deref()
    }
}

impl HapticDevice for OpenHapticsArm {
    fn info(&self) -> DeviceInfo {
        self.info.clone()
    }

    fn open(&mut self) -> Result<(), DeviceError> {
        if self.session.is_some() {
            return Ok(());
        }
        let api = HdApi::load(&self.config.library)
            .map_err(|e| DeviceError::LibraryMissing(Box::new(e)))?;
        let name = match &self.config.device_name {
            None => None,
            Some(n) => Some(CString::new(n.as_str()).map_err(|_| DeviceError::Config {
                origin: "--device touch:NAME".into(),
                message: format!("device name {n:?} contains a NUL byte"),
            })?),
        };
        let name_ptr = name.as_ref().map_or(std::ptr::null(), |n| n.as_ptr());
        // SAFETY: hdInitDevice takes a NUL-terminated configuration name or null
        // (HD_DEFAULT_DEVICE); `name` outlives the call.
        let hhd = unsafe { (api.init_device)(name_ptr) };
        let error = api.error();
        if hhd == HD_INVALID_HANDLE || error.error_code != HD_SUCCESS {
            return Err(DeviceError::NotFound {
                what: format!(
                    "OpenHaptics device {}: hdInitDevice failed with {:#06x} ({}); is the arm \
                     plugged in, its driver installed and the device configured in Touch_Setup?",
                    self.config
                        .device_name
                        .as_deref()
                        .map_or("(default)".to_string(), |n| format!("`{n}`")),
                    error.error_code,
                    api.error_text(error.error_code)
                ),
            });
        }
        // SAFETY: `hhd` is the handle hdInitDevice just returned.
        unsafe { (api.make_current_device)(hhd) };
        let (info, period_us) = api.query_info(&Self::published_touch_info());

        let (pose_in, pose_out) = triple_buffer::TripleBuffer::new(&ServoSample::default()).split();
        let (force_in, force_out) = triple_buffer::TripleBuffer::new(&[0.0; 3]).split();
        let shared = Arc::new(ServoShared {
            fault_code: AtomicU32::new(HD_SUCCESS),
        });
        let servo = Box::new(ServoSide {
            fns: api.servo,
            hhd,
            pose_in,
            force_out,
            shared: Arc::clone(&shared),
            tick: 0,
        });
        let servo = ServoBox(NonNull::from(Box::leak(servo)));
        let user_data: *mut c_void = servo.0.as_ptr().cast();
        // SAFETY: the callback's contract holds: `user_data` stays valid until the session's
        // shut_down has stopped the scheduler, and HD calls it only on its servo thread.
        // In lockstep nothing runs every tick: `read` runs each frame synchronously.
        let scheduled = unsafe {
            (api.enable)(HD_FORCE_OUTPUT);
            let handle = match self.config.servo {
                HdServo::Scheduled => Some((api.schedule_asynchronous)(
                    servo_tick,
                    user_data,
                    HD_MAX_SCHEDULER_PRIORITY,
                )),
                HdServo::Lockstep => None,
            };
            (api.start_scheduler)();
            handle
        };
        let loaded_from = api.library.from.clone();
        // From here on the session owns the servo side: dropping it on any error below shuts
        // the scheduler down before freeing it.
        let mut session = HdSession {
            api,
            hhd,
            scheduled,
            servo,
            pose_out,
            force_in,
            shared,
            period_us,
            scheduler_running: false,
            shut_down: false,
        };
        let error = session.api.error();
        session.scheduler_running = error.error_code == HD_SUCCESS;
        if !session.scheduler_running {
            return Err(DeviceError::Vendor {
                library: LIBRARY,
                code: error.error_code,
                context: "starting the servo scheduler",
            });
        }
        // The first sample, taken now so `read` never returns a made-up pose.
        // SAFETY: as for the asynchronous callback; the synchronous call returns after it ran.
        unsafe {
            (session.api.schedule_synchronous)(
                servo_tick_once,
                session.servo_ptr(),
                HD_DEFAULT_SCHEDULER_PRIORITY,
            );
        }
        self.info = info;
        self.loaded_from = Some(loaded_from);
        self.session = Some(session);
        Ok(())
    }

    fn close(&mut self) -> Result<(), DeviceError> {
        match self.session.take() {
            Some(mut session) => session.shut_down(),
            None => Ok(()),
        }
    }

    fn is_open(&self) -> bool {
        self.session.is_some()
    }

    /// The servo's latest sample; a servo fault is returned once as [`DeviceError::Vendor`].
    /// Scheduled: wait-free, one atomic load and a triple-buffer read. Lockstep: first runs
    /// one servo frame through `hdScheduleSynchronous` and waits for it (no allocation, no
    /// lock of ours).
    fn read(&mut self) -> Result<DeviceState, DeviceError> {
        let s = self.session.as_mut().ok_or(DeviceError::NotOpen)?;
        if s.scheduled.is_none() {
            // SAFETY: as for the asynchronous callback: the servo side lives as long as the
            // session, and the synchronous call returns after the frame ran on HD's servo
            // thread, so nothing else touches it meanwhile.
            unsafe {
                (s.api.schedule_synchronous)(
                    servo_tick_once,
                    s.servo.0.as_ptr().cast(),
                    HD_MAX_SCHEDULER_PRIORITY,
                );
            }
        }
        let code = s.shared.fault_code.load(Ordering::Acquire);
        if code != HD_SUCCESS {
            s.force_in.write([0.0; 3]);
            // NOTE: Release, so the servo sees the zero force above before it resumes.
            s.shared.fault_code.store(HD_SUCCESS, Ordering::Release);
            return Err(DeviceError::Vendor {
                library: LIBRARY,
                code,
                context: "a servo frame",
            });
        }
        let sample = *s.pose_out.read();
        Ok(DeviceState {
            position_m: (DVec3::from_array(sample.position_mm) * 1e-3).as_vec3(),
            orientation: None,
            velocity_m_per_s: (DVec3::from_array(sample.velocity_mm_per_s) * 1e-3).as_vec3(),
            buttons: sample.buttons as u32,
            timestamp_us: sample.tick.saturating_mul(s.period_us),
            sequence: sample.tick,
        })
    }

    /// Hands `force_n` to the servo, which sends it in its next frame. Wait-free; no HD call.
    fn write_force(&mut self, force_n: Vec3) -> Result<(), DeviceError> {
        let s = self.session.as_mut().ok_or(DeviceError::NotOpen)?;
        let f = if force_n.is_finite() {
            force_n.as_dvec3()
        } else {
            DVec3::ZERO
        };
        s.force_in.write(f.to_array());
        Ok(())
    }
}

impl Drop for OpenHapticsArm {
    fn drop(&mut self) {
        let _ = self.close();
    }
}
