//! The OpenHaptics and Force Dimension drivers against the stand-in library
//! (`libdynaclay_vendor_standin.so`, built beside this test as a dev-dependency): what they
//! report, that force reaches the arm exactly once per tick, zero force on connect and after a
//! fault, the safety filter's ramp on device time, and the typed error when a library is
//! missing.
//!
//! The HD stand-in runs in manual mode: its servo ticks happen only when a test calls
//! `standin_hd_tick`, so nothing here depends on wall-clock rates. The stand-in's state is
//! process-wide, so the tests take turns through one lock.
//!
//! A counting global allocator (per thread) checks that the drivers' haptic-path calls and
//! the HD servo frame allocate nothing; the stand-in library has its own allocator, so its
//! bookkeeping is not counted.

mod common;

use common::allocations;
use std::ffi::{c_int, c_uint};
use std::path::PathBuf;
use std::sync::{Mutex, MutexGuard};

use dynaclay_devices::dhd_arm::{DhdArm, DhdConfig};
use dynaclay_devices::doctor::{self, DoctorConfig, TickClock};
use dynaclay_devices::open::{DriverOptions, build_driver};
use dynaclay_devices::openhaptics_arm::{HdServo, OpenHapticsArm, OpenHapticsConfig};
use dynaclay_devices::spec::DeviceSpec;
use dynaclay_devices::vendor_lib::{LibrarySource, VendorLibrary};
use dynaclay_devices::{DeviceError, HapticDevice, SafetyConfig, SafetyFilter, soft_start_gain};
use dynaclay_vendor_standin::{DhdCalls, HdCalls, dhd as sdhd, hd as shd};
use glam::{DVec3, Vec3};
use libloading::Library;

const STANDIN_FILE: &str = "libdynaclay_vendor_standin.so";

/// The stand-in library beside this test executable (target/<profile>/deps or its parent).
fn standin_path() -> PathBuf {
    let exe = std::env::current_exe().expect("the test executable's path");
    exe.ancestors()
        .skip(1)
        .take(2)
        .map(|dir| dir.join(STANDIN_FILE))
        .find(|p| p.exists())
        .unwrap_or_else(|| {
            panic!(
                "{STANDIN_FILE} is not beside the test executable {} (looked in its folder and \
                 the one above); build it with `cargo build --release -p \
                 dynaclay-vendor-standin` or run the tests with `cargo test -p \
                 dynaclay-devices`, which builds it as a dev-dependency",
                exe.display()
            )
        })
}

/// The stand-in's test hooks, called through the same loaded library the drivers use (the
/// loader hands back the one copy already loaded, so the state is shared).
struct Standin {
    lib: Library,
    path: PathBuf,
    _turn: MutexGuard<'static, ()>,
}

static TURN: Mutex<()> = Mutex::new(());

impl Standin {
    /// Takes the turn, loads the stand-in, resets it, puts HD in manual mode.
    fn new() -> Self {
        let turn = TURN
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let path = standin_path();
        // SAFETY: the stand-in is this workspace's own test library; its initialisers are
        // Rust's.
        let lib = unsafe { Library::new(&path) }.expect("load the stand-in");
        let s = Self {
            lib,
            path,
            _turn: turn,
        };
        s.call0("standin_hd_reset");
        s.call0("standin_dhd_reset");
        s.hd_manual();
        s
    }

    fn call0(&self, name: &str) {
        // SAFETY: the hook takes no arguments and returns nothing.
        unsafe {
            (*self
                .lib
                .get::<unsafe extern "C" fn()>(name.as_bytes())
                .unwrap())()
        }
    }

    fn hd_manual(&self) {
        // SAFETY: `void standin_hd_set_manual(int)`.
        unsafe {
            (*self
                .lib
                .get::<unsafe extern "C" fn(c_int)>(b"standin_hd_set_manual")
                .unwrap())(1);
        }
    }

    fn hd_tick(&self, n: u32) -> u64 {
        // SAFETY: `uint64_t standin_hd_tick(uint32_t)`.
        unsafe {
            (*self
                .lib
                .get::<unsafe extern "C" fn(u32) -> u64>(b"standin_hd_tick\0")
                .unwrap())(n)
        }
    }

    fn hd_calls(&self) -> HdCalls {
        let mut out = HdCalls::default();
        // SAFETY: `void standin_hd_calls(HdCalls *)`, a writable record.
        unsafe {
            (*self
                .lib
                .get::<unsafe extern "C" fn(*mut HdCalls)>(b"standin_hd_calls")
                .unwrap())(&raw mut out);
        }
        out
    }

    fn hd_motion(&self, position_mm: [f64; 3], step_mm: [f64; 3]) {
        // SAFETY: two pointers to three doubles each.
        unsafe {
            (*self
                .lib
                .get::<unsafe extern "C" fn(*const f64, *const f64)>(b"standin_hd_set_motion")
                .unwrap())(position_mm.as_ptr(), step_mm.as_ptr());
        }
    }

    /// Calls hook `name`, which takes one unsigned int. A NUL-terminated `name` is looked up
    /// without allocating.
    fn hd_u32(&self, name: &str, value: c_uint) {
        // SAFETY: the named hook takes one unsigned int.
        unsafe {
            (*self
                .lib
                .get::<unsafe extern "C" fn(c_uint)>(name.as_bytes())
                .unwrap())(value);
        }
    }

    fn dhd_calls(&self) -> DhdCalls {
        let mut out = DhdCalls::default();
        // SAFETY: `void standin_dhd_calls(DhdCalls *)`, a writable record.
        unsafe {
            (*self
                .lib
                .get::<unsafe extern "C" fn(*mut DhdCalls)>(b"standin_dhd_calls")
                .unwrap())(&raw mut out);
        }
        out
    }

    fn dhd_devices(&self, count: c_int, system_type: c_int) {
        // SAFETY: `void standin_dhd_set_devices(int, int)`.
        unsafe {
            (*self
                .lib
                .get::<unsafe extern "C" fn(c_int, c_int)>(b"standin_dhd_set_devices")
                .unwrap())(count, system_type);
        }
    }

    fn dhd_motion(&self, position_m: [f64; 3], step_m: [f64; 3]) {
        // SAFETY: two pointers to three doubles each.
        unsafe {
            (*self
                .lib
                .get::<unsafe extern "C" fn(*const f64, *const f64)>(b"standin_dhd_set_motion")
                .unwrap())(position_m.as_ptr(), step_m.as_ptr());
        }
    }

    fn touch(&self) -> OpenHapticsArm {
        OpenHapticsArm::new(OpenHapticsConfig {
            library: LibrarySource::Path(self.path.clone()),
            device_name: None,
            ..OpenHapticsConfig::default()
        })
    }

    fn dhd(&self, index: u8) -> DhdArm {
        DhdArm::new(DhdConfig {
            library: LibrarySource::Path(self.path.clone()),
            index,
        })
    }
}

fn f64s(v: Vec3) -> [f64; 3] {
    v.as_dvec3().to_array()
}

/// A filter with a ramp of `soft_start_s` and a slew limit too high to matter.
fn filtered<D: HapticDevice>(device: D, soft_start_s: f32) -> SafetyFilter<D> {
    SafetyFilter::with_config(
        device,
        SafetyConfig {
            soft_start_s,
            slew_rate_n_per_s: 1e9,
            ..SafetyConfig::default()
        },
    )
}

// ---------------------------------------------------------------------------------------
// OpenHaptics HD

#[test]
fn touch_reports_published_figures_then_the_librarys_through_the_filter() {
    let s = Standin::new();
    let arm = s.touch();
    assert_eq!(arm.info(), OpenHapticsArm::published_touch_info());
    let mut dev = filtered(arm, 0.0);
    dev.open().unwrap();
    let info = dev.info();
    assert!(info.name.contains("Touch (stand-in)"), "{}", info.name);
    // Continuous force, not the peak, bounds the output.
    assert_eq!(info.max_force_n, shd::NOMINAL_MAX_CONTINUOUS_FORCE_N as f32);
    assert_eq!(dev.max_force_n(), 0.88);
    assert_eq!(info.max_stiffness_n_per_m, 1260.0);
    assert_eq!(info.max_damping_n_s_per_m, 3.0);
    let w = shd::USABLE_WORKSPACE_MM;
    assert!(
        info.workspace_min_m
            .abs_diff_eq(DVec3::new(w[0], w[1], w[2]).as_vec3() * 1e-3, 1e-7)
    );
    assert!(
        info.workspace_max_m
            .abs_diff_eq(DVec3::new(w[3], w[4], w[5]).as_vec3() * 1e-3, 1e-7)
    );
    assert_eq!(info.sample_rate_hz, 1000.0);
    assert!(info.has_force && !info.has_orientation);
    assert_eq!(
        dev.device().loaded_from(),
        Some(s.path.display().to_string().as_str())
    );
    let calls = s.hd_calls();
    assert_eq!((calls.init_calls, calls.scheduler_running), (1, 1));
    assert_eq!(calls.scheduled_callbacks, 1);
    dev.close().unwrap();
}

#[test]
fn touch_force_is_zero_on_connect() {
    let s = Standin::new();
    let mut dev = filtered(s.touch(), 0.0);
    dev.open().unwrap();
    s.hd_tick(20);
    let calls = s.hd_calls();
    assert_eq!(calls.force_output_enabled, 1);
    // The first sample's frame at open plus the 20 ticks, each with one zero force.
    assert_eq!(calls.frames, 21);
    assert_eq!(calls.set_force_calls, 21);
    assert_eq!(calls.nonzero_forces_output, 0);
    assert_eq!(calls.output_force_n, [0.0; 3]);
}

#[test]
fn touch_force_reaches_the_arm_exactly_once_per_servo_tick_and_the_loop_never_drives_it() {
    let s = Standin::new();
    let mut dev = filtered(s.touch(), 0.0);
    dev.open().unwrap();
    let start = s.hd_calls();
    let ticks = 250u32;
    for k in 0..ticks {
        let state = dev.read().unwrap();
        assert_eq!(
            state.sequence,
            u64::from(k) + 1,
            "one fresh sample per tick"
        );
        let request = Vec3::new(0.3, -0.2, 0.1 + 0.001 * k as f32);
        dev.write_force(request).unwrap();
        // The loop's write reached no HD call: only the servo sends force.
        assert_eq!(
            s.hd_calls().set_force_calls,
            start.set_force_calls + u64::from(k)
        );
        s.hd_tick(1);
        let calls = s.hd_calls();
        assert_eq!(calls.output_force_n, f64s(dev.output_force_n()), "tick {k}");
        if k > 0 {
            // (The first write has no elapsed time to slew over, so it holds zero.)
            assert_eq!(calls.output_force_n, f64s(request), "tick {k}");
        }
    }
    let end = s.hd_calls();
    assert_eq!(end.ticks - start.ticks, u64::from(ticks));
    assert_eq!(end.frames - start.frames, u64::from(ticks));
    assert_eq!(
        end.set_force_calls - start.set_force_calls,
        u64::from(ticks)
    );
    assert_eq!(end.max_set_force_per_frame, 1);
    assert_eq!(end.set_force_outside_frame, 0);

    // Two driver writes between ticks (past the filter, which would hold the second for
    // lack of elapsed time): the newer goes out, once.
    dev.device_mut()
        .write_force(Vec3::new(0.1, 0.0, 0.0))
        .unwrap();
    dev.device_mut()
        .write_force(Vec3::new(0.0, 0.2, 0.0))
        .unwrap();
    s.hd_tick(1);
    let calls = s.hd_calls();
    assert_eq!(calls.set_force_calls, end.set_force_calls + 1);
    assert_eq!(calls.output_force_n, [0.0, f64::from(0.2f32), 0.0]);
}

#[test]
fn touch_in_lockstep_runs_one_servo_frame_per_read_and_schedules_nothing() {
    let s = Standin::new();
    // A hand moving 0.5 mm per servo tick along x: only frames move it in lockstep.
    s.hd_motion([0.0; 3], [0.5, 0.0, 0.0]);
    let mut dev = filtered(
        OpenHapticsArm::new(OpenHapticsConfig {
            library: LibrarySource::Path(s.path.clone()),
            device_name: None,
            servo: HdServo::Lockstep,
        }),
        0.0,
    );
    dev.open().unwrap();
    let opened = s.hd_calls();
    assert_eq!(opened.scheduled_callbacks, 0, "nothing runs every tick");
    assert_eq!(opened.frames, 1, "open's first sample");
    assert_eq!(opened.output_force_n, [0.0; 3], "zero force on connect");
    let ticks = 50u64;
    let mut requests = Vec::new();
    for k in 0..ticks {
        let state = dev.read().unwrap();
        // Read k ran frame k + 1, on a servo clock of those frames.
        assert_eq!(state.sequence, k + 2, "tick {k}");
        assert_eq!(state.timestamp_us, (k + 2) * 1000, "tick {k}");
        assert_eq!(s.hd_calls().frames, k + 2, "one frame per read");
        // Frame k + 1 sent what the previous tick wrote (zero before any write).
        let expected = if k == 0 {
            [0.0; 3]
        } else {
            f64s(requests[k as usize - 1])
        };
        assert_eq!(s.hd_calls().output_force_n, expected, "tick {k}");
        let request = Vec3::new(0.1, -0.05, 0.002 * k as f32);
        dev.write_force(request).unwrap();
        requests.push(dev.output_force_n());
    }
    let end = s.hd_calls();
    assert_eq!(end.ticks, 0, "the scheduler never ticked on its own");
    assert_eq!(end.set_force_calls, end.frames);
    assert_eq!(end.max_set_force_per_frame, 1);
    assert_eq!(end.set_force_outside_frame, 0);
    // A fault in a frame is that read's error; the frame after it sends zero.
    s.hd_u32("standin_hd_inject_fault", shd::HD_COMM_ERROR);
    assert!(matches!(dev.read(), Err(DeviceError::Vendor { .. })));
    dev.read().unwrap();
    assert_eq!(
        s.hd_calls().output_force_n,
        [0.0; 3],
        "zero after the fault"
    );
    dev.close().unwrap();
    let closed = s.hd_calls();
    assert_eq!(closed.scheduler_running, 0);
    assert_eq!(closed.output_force_n, [0.0; 3]);
}

#[test]
fn touch_positions_velocities_and_buttons_arrive_in_metres_on_the_servo_clock() {
    let s = Standin::new();
    s.hd_motion([10.0, 20.0, -5.0], [0.1, 0.0, -0.05]);
    s.hd_u32("standin_hd_set_buttons", 0b10);
    let mut arm = s.touch();
    arm.open().unwrap();
    let first = arm.read().unwrap();
    assert_eq!(first.sequence, 1);
    assert_eq!(first.timestamp_us, 1000);
    assert!(
        first
            .position_m
            .abs_diff_eq(Vec3::new(0.010, 0.020, -0.005), 1e-7),
        "{}",
        first.position_m
    );
    assert!(first.button(1) && !first.button(0));
    s.hd_tick(10);
    let later = arm.read().unwrap();
    assert_eq!(later.sequence, 11);
    assert_eq!(later.timestamp_us, 11_000);
    assert!(
        later
            .position_m
            .abs_diff_eq(Vec3::new(0.011, 0.020, -0.0055), 1e-7),
        "{}",
        later.position_m
    );
    // 0.1 mm per 1 ms tick is 0.1 m/s.
    assert!(
        later
            .velocity_m_per_s
            .abs_diff_eq(Vec3::new(0.1, 0.0, -0.05), 1e-6),
        "{}",
        later.velocity_m_per_s
    );
    // Nothing new without a tick: the same sample again.
    assert_eq!(arm.read().unwrap(), later);
}

#[test]
fn touch_soft_start_ramps_the_force_on_servo_time() {
    let s = Standin::new();
    let ramp_s = 0.1;
    let mut dev = filtered(s.touch(), ramp_s);
    dev.open().unwrap();
    let request = Vec3::new(0.0, 0.5, 0.0);
    let mut first_us = None;
    let mut previous = 0.0;
    for k in 0..150 {
        let state = dev.read().unwrap();
        let t0 = *first_us.get_or_insert(state.timestamp_us);
        dev.write_force(request).unwrap();
        s.hd_tick(1);
        let sent = s.hd_calls().output_force_n[1];
        let progress = (state.timestamp_us - t0) as f32 * 1e-6 / ramp_s;
        let expected = 0.5 * soft_start_gain(progress);
        assert!(
            (sent - f64::from(expected)).abs() < 1e-6,
            "tick {k}: sent {sent}, ramp gives {expected}"
        );
        assert!(sent >= previous, "tick {k}: the ramp went down");
        previous = sent;
    }
    assert!(
        (previous - 0.5).abs() < 1e-6,
        "ramp ends at the request: {previous}"
    );
}

#[test]
fn touch_fault_zeroes_the_force_at_once_and_it_ramps_back_after_a_good_sample() {
    let s = Standin::new();
    let ramp_s = 0.05;
    let mut dev = filtered(s.touch(), ramp_s);
    dev.open().unwrap();
    let request = Vec3::new(0.4, 0.0, 0.0);
    for _ in 0..100 {
        dev.read().unwrap();
        dev.write_force(request).unwrap();
        s.hd_tick(1);
    }
    assert_eq!(s.hd_calls().output_force_n[0], f64::from(0.4f32));

    // The fault surfaces at the end of a frame that still carried the force...
    s.hd_u32("standin_hd_inject_fault", shd::HD_COMM_ERROR);
    s.hd_tick(1);
    // ...and the very next frame sends zero, before the loop has even looked.
    s.hd_tick(1);
    assert_eq!(s.hd_calls().output_force_n, [0.0; 3]);

    let err = dev.read().unwrap_err();
    assert_eq!(
        err,
        DeviceError::Vendor {
            library: "OpenHaptics HD",
            code: shd::HD_COMM_ERROR,
            context: "a servo frame",
        }
    );
    assert!(err.to_string().contains("0x0302"), "{err}");
    assert!(dev.fault_latched());
    dev.write_force(request).unwrap();
    s.hd_tick(1);
    assert_eq!(s.hd_calls().output_force_n, [0.0; 3], "zero while latched");

    // A good sample clears the fault; force comes back through a fresh soft start.
    let mut sent = Vec::new();
    for _ in 0..80 {
        dev.read().unwrap();
        dev.write_force(request).unwrap();
        s.hd_tick(1);
        sent.push(s.hd_calls().output_force_n[0]);
    }
    assert!(!dev.fault_latched());
    assert_eq!(sent[0], 0.0, "the ramp restarts from zero");
    assert!(sent.windows(2).all(|w| w[1] >= w[0]), "{sent:?}");
    assert!(sent[10] > 0.0 && sent[10] < 0.2, "{}", sent[10]);
    assert_eq!(*sent.last().unwrap(), f64::from(0.4f32));
    assert_eq!(dev.counters().read_faults, 1);
    assert_eq!(dev.counters().soft_starts, 2);
}

#[test]
fn touch_close_sends_zero_then_stops_the_servo_and_releases_the_arm() {
    let s = Standin::new();
    let mut dev = filtered(s.touch(), 0.0);
    dev.open().unwrap();
    for _ in 0..10 {
        dev.read().unwrap();
        dev.write_force(Vec3::new(0.0, 0.0, 0.5)).unwrap();
        s.hd_tick(1);
    }
    assert_eq!(s.hd_calls().output_force_n[2], 0.5);
    let before = s.hd_calls();
    dev.close().unwrap();
    let after = s.hd_calls();
    assert_eq!(after.frames, before.frames + 1, "one zero frame at close");
    assert_eq!(after.output_force_n, [0.0; 3]);
    assert_eq!(after.force_output_enabled, 0);
    assert_eq!(after.scheduler_running, 0);
    assert_eq!(after.scheduled_callbacks, 0);
    assert_eq!(after.disable_calls, 1);
    assert!(!dev.is_open());
    assert_eq!(dev.read().unwrap_err(), DeviceError::NotOpen);
    // No callback left to run.
    s.hd_tick(5);
    assert_eq!(s.hd_calls().frames, after.frames);
}

#[test]
fn touch_that_does_not_initialise_is_not_found_with_hds_code() {
    let s = Standin::new();
    s.hd_u32("standin_hd_fail_init", shd::HD_COMM_ERROR);
    let mut arm = s.touch();
    let err = arm.open().unwrap_err();
    match &err {
        DeviceError::NotFound { what } => {
            assert!(
                what.contains("0x0302") && what.contains("communication error"),
                "{what}"
            );
        }
        other => panic!("expected NotFound, got {other:?}"),
    }
    assert!(!arm.is_open());
    assert_eq!(s.hd_calls().scheduler_running, 0);
}

// ---------------------------------------------------------------------------------------
// Force Dimension DHD

#[test]
fn dhd_reports_the_model_the_sdk_names_with_its_published_figures() {
    let s = Standin::new();
    let mut arm = s.dhd(0);
    arm.open().unwrap();
    let info = arm.info();
    assert!(info.name.starts_with("omega.3"), "{}", info.name);
    assert_eq!(info.max_force_n, 12.0);
    assert_eq!(info.max_stiffness_n_per_m, 5000.0);
    assert_eq!(info.workspace_max_m, Vec3::splat(0.075));
    arm.close().unwrap();

    s.dhd_devices(2, sdhd::DHD_DEVICE_FALCON);
    let mut falcon = filtered(s.dhd(1), 0.0);
    falcon.open().unwrap();
    assert!(falcon.info().name.starts_with("Novint Falcon"));
    assert_eq!(falcon.max_force_n(), 8.0);
}

#[test]
fn dhd_force_is_zero_on_connect_and_reaches_the_arm_once_per_tick() {
    let s = Standin::new();
    let mut dev = filtered(s.dhd(0), 0.0);
    dev.open().unwrap();
    let at_open = s.dhd_calls();
    assert_eq!(at_open.force_enabled, 1);
    assert_eq!(at_open.set_force_calls, 1, "one zero command at open");
    assert_eq!(at_open.last_force_n, [0.0; 3]);
    let ticks = 200u64;
    for k in 0..ticks {
        dev.read().unwrap();
        dev.write_force(Vec3::new(1.0, 2.0, 0.001 * k as f32))
            .unwrap();
        let calls = s.dhd_calls();
        assert_eq!(
            calls.last_force_n,
            [
                f64::from(dev.output_force_n().z),
                f64::from(dev.output_force_n().x),
                f64::from(dev.output_force_n().y)
            ],
            "tick {k}"
        );
        if k > 0 {
            // Device frame (x right, y up, z toward the user) to DHD's (x toward, y right,
            // z up). (The first write has no elapsed time to slew over, so it holds zero.)
            assert_eq!(
                calls.last_force_n,
                [f64::from(0.001 * k as f32), 1.0, 2.0],
                "tick {k}"
            );
        }
    }
    let end = s.dhd_calls();
    assert_eq!(end.position_reads, ticks);
    assert_eq!(end.set_force_calls - at_open.set_force_calls, ticks);
    assert_eq!(end.max_set_force_per_read, 1);
}

#[test]
fn dhd_positions_arrive_in_the_device_frame_on_the_sdk_clock() {
    let s = Standin::new();
    // DHD frame: 10 mm toward the user, 20 mm right, 30 mm up; moving 1 mm right per sample.
    s.dhd_motion([0.010, 0.020, 0.030], [0.0, 0.001, 0.0]);
    let mut arm = s.dhd(0);
    arm.open().unwrap();
    let a = arm.read().unwrap();
    assert!(
        a.position_m
            .abs_diff_eq(Vec3::new(0.020, 0.030, 0.010), 1e-7)
    );
    assert_eq!((a.sequence, a.timestamp_us), (1, 1000));
    let mut last = a;
    for _ in 0..200 {
        last = arm.read().unwrap();
    }
    assert_eq!((last.sequence, last.timestamp_us), (201, 201_000));
    // 1 mm per 1 ms sample is 1 m/s along device x (DHD y).
    assert!(
        (last.velocity_m_per_s.x - 1.0).abs() < 1e-3,
        "{}",
        last.velocity_m_per_s
    );
}

#[test]
fn dhd_failed_read_latches_zero_and_force_ramps_back() {
    let s = Standin::new();
    let mut dev = filtered(s.dhd(0), 0.02);
    dev.open().unwrap();
    let request = Vec3::new(0.0, 3.0, 0.0);
    for _ in 0..50 {
        dev.read().unwrap();
        dev.write_force(request).unwrap();
    }
    assert_eq!(s.dhd_calls().last_force_n, [0.0, 0.0, 3.0]);
    // The next position read fails with DHD_ERROR_COM.
    s.hd_u32("standin_dhd_fail_reads", 1);
    let err = dev.read().unwrap_err();
    assert_eq!(
        err,
        DeviceError::Vendor {
            library: "Force Dimension DHD",
            code: sdhd::DHD_ERROR_COM as u32,
            context: "dhdGetPosition",
        }
    );
    assert_eq!(
        s.dhd_calls().last_force_n,
        [0.0; 3],
        "zero sent at the fault"
    );
    let mut sent = Vec::new();
    for _ in 0..40 {
        dev.read().unwrap();
        dev.write_force(request).unwrap();
        sent.push(s.dhd_calls().last_force_n[2]);
    }
    assert_eq!(sent[0], 0.0);
    assert!(sent.windows(2).all(|w| w[1] >= w[0]), "{sent:?}");
    assert_eq!(*sent.last().unwrap(), 3.0);
}

#[test]
fn dhd_index_past_the_connected_devices_is_not_found() {
    let s = Standin::new();
    let err = s.dhd(1).open().unwrap_err();
    match err {
        DeviceError::NotFound { what } => {
            assert!(
                what.contains("dhd:1") && what.contains("sees 1 device"),
                "{what}"
            );
        }
        other => panic!("expected NotFound, got {other:?}"),
    }
    assert_eq!(s.dhd_calls().open_devices, 0);
}

#[test]
fn the_haptic_path_of_both_drivers_allocates_nothing_faults_included() {
    let s = Standin::new();
    let mut touch = filtered(s.touch(), 0.01);
    touch.open().unwrap();
    let mut dhd = filtered(s.dhd(0), 0.01);
    dhd.open().unwrap();
    // Warm up once (first-use paths of the test's own helpers), then count.
    for dev in [&mut touch as &mut dyn HapticDevice, &mut dhd] {
        dev.read().unwrap();
        dev.write_force(Vec3::X * 0.1).unwrap();
    }
    s.hd_tick(1);
    let before = allocations();
    for k in 0..300 {
        if k == 100 {
            s.hd_u32("standin_hd_inject_fault\0", shd::HD_EXCEEDED_MAX_FORCE);
            s.hd_u32("standin_dhd_fail_reads\0", 1);
        }
        for dev in [&mut touch as &mut dyn HapticDevice, &mut dhd] {
            let _ = dev.read();
            let _ = dev.write_force(Vec3::new(0.2, -0.1, 0.05));
        }
        s.hd_tick(1);
    }
    assert_eq!(allocations() - before, 0, "allocations on the haptic path");
    assert_eq!(touch.counters().read_faults, 1);
    assert_eq!(dhd.counters().read_faults, 1);
}

/// The lockstep read runs one servo frame through `hdScheduleSynchronous` on the haptic loop's
/// own thread (the stand-in runs a synchronous callback on its caller's thread, as HD runs it
/// while the caller waits), so the frame's work is counted here with the read's: neither
/// allocates, on good ticks, on the faulted frame or on the ramp after it.
#[test]
fn the_lockstep_touch_read_and_its_servo_frame_allocate_nothing_faults_included() {
    let s = Standin::new();
    s.hd_motion([0.0; 3], [0.01, 0.0, 0.0]);
    let mut touch = filtered(
        OpenHapticsArm::new(OpenHapticsConfig {
            library: LibrarySource::Path(s.path.clone()),
            device_name: None,
            servo: HdServo::Lockstep,
        }),
        0.01,
    );
    touch.open().unwrap();
    // Warm up once (first-use paths of the test's own helpers), then count.
    touch.read().unwrap();
    touch.write_force(Vec3::X * 0.1).unwrap();
    let frames_before = s.hd_calls().frames;
    let ticks = 300u64;
    let before = allocations();
    for k in 0..ticks {
        if k == 100 {
            s.hd_u32("standin_hd_inject_fault\0", shd::HD_EXCEEDED_MAX_FORCE);
        }
        let _ = touch.read();
        let _ = touch.write_force(Vec3::new(0.2, -0.1, 0.05));
    }
    let allocated = allocations() - before;
    let calls = s.hd_calls();
    assert_eq!(allocated, 0, "allocations on the lockstep read path");
    // The reads counted above did run the frames, one each, with nothing scheduled.
    assert_eq!(calls.frames - frames_before, ticks, "{calls:?}");
    assert_eq!(calls.scheduled_callbacks, 0, "{calls:?}");
    assert_eq!(calls.ticks, 0, "no servo tick besides the reads' frames");
    assert_eq!(touch.counters().read_faults, 1);
    assert_eq!(
        touch.counters().soft_starts,
        2,
        "open's ramp and the fault's"
    );
}

// ---------------------------------------------------------------------------------------
// Missing libraries and the specs

#[test]
fn a_missing_library_is_a_typed_error_naming_it_where_it_was_looked_for_and_the_cure() {
    let opts = DriverOptions {
        hd_library: LibrarySource::Path("/nonexistent/libHD.so".into()),
        dhd_library: LibrarySource::Path("/nonexistent/libdhd.so".into()),
        ..DriverOptions::default()
    };
    for (spec, library, path, cure) in [
        (
            "touch",
            VendorLibrary::OpenHapticsHd,
            "/nonexistent/libHD.so",
            "OpenHaptics for Linux",
        ),
        (
            "phantom",
            VendorLibrary::OpenHapticsHd,
            "/nonexistent/libHD.so",
            "Touch device driver",
        ),
        (
            "dhd",
            VendorLibrary::ForceDimensionDhd,
            "/nonexistent/libdhd.so",
            "Force Dimension SDK",
        ),
    ] {
        let spec: DeviceSpec = spec.parse().unwrap();
        let mut device = SafetyFilter::new(build_driver(&spec, &opts).unwrap());
        match device.open().unwrap_err() {
            DeviceError::LibraryMissing(missing) => {
                assert_eq!(missing.library, library, "{spec}");
                assert_eq!(missing.tried.len(), 1, "{spec}");
                assert_eq!(missing.tried[0].candidate, path, "{spec}");
                let text = missing.to_string();
                for needle in [library.label(), path, cure, library.env_var()] {
                    assert!(
                        text.contains(needle),
                        "{spec}: {needle} missing from {text}"
                    );
                }
            }
            other => panic!("{spec}: expected LibraryMissing, got {other:?}"),
        }
        assert!(!device.is_open());
    }
}

#[test]
fn the_standin_is_accepted_as_either_library_and_a_wrong_library_is_refused() {
    let s = Standin::new();
    // The C library is loaded in every process and exports neither API.
    let mut wrong = OpenHapticsArm::new(OpenHapticsConfig {
        library: LibrarySource::Path("libc.so.6".into()),
        device_name: None,
        ..OpenHapticsConfig::default()
    });
    match wrong.open().unwrap_err() {
        DeviceError::LibraryMissing(m) => {
            assert!(m.to_string().contains("no symbol `hdInitDevice`"), "{m}");
        }
        other => panic!("expected LibraryMissing, got {other:?}"),
    }
    let mut touch = s.touch();
    touch.open().unwrap();
    let mut dhd = s.dhd(0);
    dhd.open().unwrap();
    assert!(touch.is_open() && dhd.is_open());
}

/// A clock that moves only when the doctor's loop waits: each wait jumps to its deadline, so
/// the tick count and every period follow from the duration and rate alone, not from how fast
/// this machine runs.
struct SteppedClock {
    now_us: u64,
}

impl TickClock for SteppedClock {
    fn now_us(&mut self) -> u64 {
        self.now_us
    }

    fn wait_until_us(&mut self, t_us: u64) {
        self.now_us = self.now_us.max(t_us);
    }
}

#[test]
fn the_doctor_reads_a_dhd_arm_once_per_tick_and_commands_only_zero_force() {
    let s = Standin::new();
    s.dhd_motion([0.0; 3], [1.0e-5, 0.0, 0.0]);
    let config = DoctorConfig {
        duration_us: 2_000_000,
        rate_hz: Some(1000.0),
    };
    let (report, _arm) = doctor::run(s.dhd(0), config, &mut SteppedClock { now_us: 0 });
    let report = report.expect("the stand-in opens");
    let calls = s.dhd_calls();
    assert_eq!(report.ticks, 2000);
    assert_eq!((report.reads_ok, report.read_errors), (2000, 0));
    assert_eq!(
        report.fresh_samples, 2000,
        "every DHD read is a fresh exchange"
    );
    assert_eq!(calls.position_reads, 2000, "one dhdGetPosition per tick");
    assert_eq!(
        calls.set_force_calls,
        1 + 2000 + 1,
        "zero at open, one zero command per tick, zero at close"
    );
    assert_eq!(
        calls.nonzero_forces_output, 0,
        "nothing but zero reached the arm"
    );
    assert_eq!(calls.last_force_n, [0.0; 3]);
    assert_eq!(calls.open_devices, 0, "the doctor closes the arm");
    let periods = report.read_periods.expect("2000 reads give periods");
    assert_eq!((periods.p50_us, periods.max_us), (1000, 1000));
    assert!((periods.rate_hz - 1000.0).abs() < 1e-9, "{periods}");
    let text = report.to_string();
    assert!(
        text.contains("2000 ok") && text.contains("1000.0 Hz"),
        "{text}"
    );
}

#[test]
fn the_doctor_reports_an_arm_that_does_not_open_and_runs_no_loop() {
    let s = Standin::new();
    s.dhd_devices(1, 33);
    let (report, _arm) = doctor::run(
        s.dhd(3),
        DoctorConfig::default(),
        &mut SteppedClock { now_us: 0 },
    );
    assert!(
        matches!(report, Err(DeviceError::NotFound { .. })),
        "{report:?}"
    );
    assert_eq!(s.dhd_calls().position_reads, 0);
}
