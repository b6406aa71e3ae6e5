//! `dynaclay` with the vendor-library arms against the stand-in library
//! (`libdynaclay_vendor_standin.so`, a dev-dependency built beside this test).
//!
//! Lockstep sculpting sessions: the lockstep engine drives a Touch (HD, its servo run one
//! synchronous frame per engine tick) and an omega.3 (DHD, one position read and one force
//! command per tick) along the shared push script, the stand-in playing the script's hand one
//! position per servo frame (HD) or position read (DHD), so the run depends on the calls and
//! never on time. Both pass the simulated arm's checks: zero force at connect, force within the
//! arm's bound, the soft-start ramp after a fault, zero force on every fault, a disconnect in
//! the middle of the stroke that keeps the engine ticking and keeps the groove made before it;
//! and the stand-in's record proves each tick's force reached the arm once, in order.
//!
//! End to end through the command line: a headless run with `--device touch` and `--device
//! dhd`, in real time and `--lockstep`, the typed error when the library is missing, and
//! `dynaclay devices` reporting each library. The real-time runs assert what the run produced
//! and said, never rates or times.

#[path = "support/arm_session.rs"]
mod arm_session;
mod common;

use std::ffi::{c_int, c_uint};
use std::path::PathBuf;
use std::process::Command;
use std::sync::{Mutex, MutexGuard, PoisonError};

use arm_session::{DISCONNECT_AT, FAULT_AT, HandPath, Session, TICKS};
use dynaclay_devices::HapticDevice;
use dynaclay_devices::dhd_arm::{DhdArm, DhdConfig, device_to_dhd, dhd_to_device};
use dynaclay_devices::openhaptics_arm::{HdServo, OpenHapticsArm, OpenHapticsConfig};
use dynaclay_devices::vendor_lib::LibrarySource;
use dynaclay_vendor_standin::{DhdCalls, HdCalls, dhd as sdhd, hd as shd};
use glam::{DVec3, Vec3};
use libloading::Library;

const BIN: &str = env!("CARGO_BIN_EXE_dynaclay");
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
                 dynaclay-vendor-standin` (it is a dev-dependency, so `cargo test` builds it)",
                exe.display()
            )
        })
}

fn dynaclay() -> Command {
    let mut c = Command::new(BIN);
    c.env_remove("DYNACLAY_HD_LIB")
        .env_remove("DYNACLAY_DHD_LIB");
    c
}

#[test]
fn a_headless_run_sculpts_through_each_vendor_arm_on_the_standin() {
    let standin = standin_path();
    for (device, env) in [
        ("touch", "DYNACLAY_HD_LIB"),
        ("phantom", "DYNACLAY_HD_LIB"),
        ("dhd", "DYNACLAY_DHD_LIB"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        let run = dynaclay()
            .env(env, &standin)
            .args([
                "run",
                "--seconds",
                "0.5",
                "--no-rt",
                "--device",
                device,
                "--out",
            ])
            .arg(&out)
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&run.stdout);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(
            run.status.success(),
            "{device}: exit {:?}\nstdout: {stdout}\nstderr: {stderr}",
            run.status.code()
        );
        assert!(
            stdout.contains(&format!("device {device}")),
            "{device}: {stdout}"
        );
        assert!(out.join("session.dclay").is_file(), "{device}: no session");
    }
}

#[test]
fn a_missing_vendor_library_stops_the_run_naming_it_where_it_looked_and_the_cure() {
    for (device, env, library, cure) in [
        (
            "touch",
            "DYNACLAY_HD_LIB",
            "libHD.so",
            "OpenHaptics for Linux",
        ),
        (
            "dhd:1",
            "DYNACLAY_DHD_LIB",
            "libdhd.so",
            "Force Dimension SDK",
        ),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("nowhere").join(library);
        let run = dynaclay()
            .env(env, &missing)
            .args([
                "run",
                "--seconds",
                "0.5",
                "--no-rt",
                "--device",
                device,
                "--out",
            ])
            .arg(dir.path().join("out"))
            .output()
            .unwrap();
        assert_eq!(run.status.code(), Some(3), "{device}: a device failure");
        let stderr = String::from_utf8_lossy(&run.stderr);
        for needle in [library, &missing.display().to_string(), cure, env] {
            assert!(
                stderr.contains(needle),
                "{device}: {needle} missing from {stderr}"
            );
        }
    }
}

#[test]
fn devices_reports_each_vendor_library_found_or_not() {
    let standin = standin_path();
    let dir = tempfile::tempdir().unwrap();
    let out = dynaclay()
        .env("DYNACLAY_DHD_LIB", &standin)
        .env("DYNACLAY_HD_LIB", dir.path().join("libHD.so"))
        .arg("devices")
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    let line = |label: &str| {
        text.lines()
            .find(|l| l.contains(label))
            .unwrap_or_else(|| panic!("no line for {label} in:\n{text}"))
            .to_string()
    };
    let dhd = line("libdhd.so");
    assert!(
        dhd.contains(&format!("found ({})", standin.display())) && dhd.contains("--device dhd"),
        "{dhd}"
    );
    let hd = line("libHD.so)");
    assert!(
        hd.contains("not found") && hd.contains("--device touch") && hd.contains("3D Systems"),
        "{hd}"
    );
}

/// `dynaclay run --lockstep` with each vendor arm on its stand-in: the run says it ran in
/// lockstep for the asked seconds of the arm's clock (one sample per servo tick) and writes
/// the session.
#[test]
fn a_lockstep_run_sculpts_through_each_vendor_arm_on_the_standin() {
    let standin = standin_path();
    for (device, env) in [("touch", "DYNACLAY_HD_LIB"), ("dhd", "DYNACLAY_DHD_LIB")] {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        let run = dynaclay()
            .env(env, &standin)
            .args([
                "run",
                "--lockstep",
                "--seconds",
                "0.3",
                "--device",
                device,
                "--out",
            ])
            .arg(&out)
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&run.stdout);
        let stderr = String::from_utf8_lossy(&run.stderr);
        assert!(
            run.status.success(),
            "{device}: exit {:?}\nstdout: {stdout}\nstderr: {stderr}",
            run.status.code()
        );
        assert!(
            stdout.contains(&format!("300 samples of {device} in lockstep")),
            "{device}: {stdout}"
        );
        assert!(out.join("session.dclay").is_file(), "{device}: no session");
    }
}

/// Lockstep needs a device that ticks on its own clock per read: a real-time-only arm is
/// refused, naming the arms that can.
#[test]
fn lockstep_is_refused_for_an_arm_that_runs_in_real_time_only() {
    let dir = tempfile::tempdir().unwrap();
    let run = dynaclay()
        .args(["run", "--lockstep", "--device", "hid", "--out"])
        .arg(dir.path().join("out"))
        .output()
        .unwrap();
    assert_eq!(run.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        stderr.contains("--lockstep") && stderr.contains("hid") && stderr.contains("touch"),
        "{stderr}"
    );
}

#[test]
fn the_doctor_opens_each_vendor_arm_through_its_stand_in_and_reports_its_reads() {
    for (spec, var) in [("dhd", "DYNACLAY_DHD_LIB"), ("touch", "DYNACLAY_HD_LIB")] {
        let out = dynaclay()
            .env(var, standin_path())
            .args(["devices", "--doctor", spec, "--seconds", "0.2"])
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{spec}: {text}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        // Whatever rate this machine reached, the report names the period percentiles and
        // no read failed.
        assert!(text.contains("zero force every tick"), "{spec}: {text}");
        assert!(text.contains(", 0 failed"), "{spec}: {text}");
        assert!(
            text.contains("read rate:") && text.contains("p99") && text.contains("verdict:"),
            "{spec}: {text}"
        );
    }
}

#[test]
fn the_doctor_without_the_vendor_library_says_which_library_and_how_to_install_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dynaclay()
        .env("DYNACLAY_DHD_LIB", dir.path().join("libdhd.so"))
        .args(["devices", "--doctor", "dhd"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(3), "a device error");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("cannot open dhd")
            && text.contains("libdhd.so")
            && text.contains("Force Dimension SDK"),
        "{text}"
    );
}

// ---- Lockstep sculpting sessions, in this process, against the loaded stand-in ----

/// The stand-in's state is process-wide: the in-process sessions take turns.
static TURN: Mutex<()> = Mutex::new(());

/// The hand the stand-in plays, by frame (HD) or read (DHD).
static HAND: Mutex<Option<HandPath>> = Mutex::new(None);

fn hand_at(k: u64) -> Vec3 {
    let hand = HAND.lock().unwrap_or_else(PoisonError::into_inner);
    hand.as_ref().map_or(Vec3::ZERO, |h| h(k))
}

/// The stand-in's HD hand: frame `k`'s position, millimetres (HD's frame is the device's).
extern "C" fn hd_hand(frame: u64, position_mm: *mut f64) {
    let p = (hand_at(frame).as_dvec3() * 1e3).to_array();
    // SAFETY: the stand-in passes three writable doubles.
    unsafe { std::ptr::copy_nonoverlapping(p.as_ptr(), position_mm, 3) };
}

/// The stand-in's DHD hand: read `k`'s position, metres, DHD's frame.
extern "C" fn dhd_hand(read: u64, position_m: *mut f64) {
    let p = device_to_dhd(hand_at(read));
    // SAFETY: the stand-in passes three writable doubles.
    unsafe { std::ptr::copy_nonoverlapping(p.as_ptr(), position_m, 3) };
}

/// The stand-in library's test hooks, called through the copy the drivers load (the loader
/// hands back the one copy already loaded, so the state is shared).
struct Hooks {
    lib: Library,
    path: PathBuf,
    _turn: MutexGuard<'static, ()>,
}

impl Hooks {
    /// Takes the turn, loads the stand-in and resets both APIs (HD in manual mode: no servo
    /// thread; frames run only when the driver asks for one).
    fn new() -> Self {
        let turn = TURN.lock().unwrap_or_else(PoisonError::into_inner);
        let path = standin_path();
        // SAFETY: the stand-in is this workspace's own test library; its initialisers are
        // Rust's.
        let lib = unsafe { Library::new(&path) }.expect("load the stand-in");
        let hooks = Self {
            lib,
            path,
            _turn: turn,
        };
        hooks.reset();
        hooks
    }

    /// Resets both APIs (HD in manual mode) for the next session.
    fn reset(&self) {
        // SAFETY: each hook has the C signature given (devices/standins/vendor).
        unsafe {
            self.get::<unsafe extern "C" fn()>(b"standin_hd_reset")();
            self.get::<unsafe extern "C" fn()>(b"standin_dhd_reset")();
            self.get::<unsafe extern "C" fn(c_int)>(b"standin_hd_set_manual")(1);
        }
    }

    /// Hook `name` as type `F`.
    ///
    /// # Safety
    /// `F` must be the hook's C signature.
    unsafe fn get<F: Copy>(&self, name: &[u8]) -> F {
        // SAFETY: the caller vouches for the signature.
        *unsafe { self.lib.get::<F>(name) }.expect("the stand-in exports its hooks")
    }

    fn hd_calls(&self) -> HdCalls {
        let mut out = HdCalls::default();
        // SAFETY: `void standin_hd_calls(HdCalls *)`, a writable record.
        unsafe {
            self.get::<unsafe extern "C" fn(*mut HdCalls)>(b"standin_hd_calls")(&raw mut out)
        };
        out
    }

    fn dhd_calls(&self) -> DhdCalls {
        let mut out = DhdCalls::default();
        // SAFETY: `void standin_dhd_calls(DhdCalls *)`, a writable record.
        unsafe {
            self.get::<unsafe extern "C" fn(*mut DhdCalls)>(b"standin_dhd_calls")(&raw mut out);
        }
        out
    }

    /// The forces the arm received, through `hook` (`standin_hd_forces` or
    /// `standin_dhd_forces`), in the API's frame.
    fn forces(&self, hook: &[u8]) -> Vec<[f64; 3]> {
        let mut out = vec![[f64::NAN; 3]; shd::FORCE_LOG_CAPACITY];
        // SAFETY: `size_t hook(double (*)[3], size_t)` with room for `capacity` entries.
        let n = unsafe {
            self.get::<unsafe extern "C" fn(*mut [f64; 3], usize) -> usize>(hook)(
                out.as_mut_ptr(),
                out.len(),
            )
        };
        out.truncate(n);
        out
    }
}

impl Drop for Hooks {
    fn drop(&mut self) {
        *HAND.lock().unwrap_or_else(PoisonError::into_inner) = None;
    }
}

/// Stores the session's hand for the stand-in and hands back the (open) arm.
fn playing(hand: HandPath, arm: impl HapticDevice + 'static) -> Box<dyn HapticDevice> {
    *HAND.lock().unwrap_or_else(PoisonError::into_inner) = Some(hand);
    Box::new(arm)
}

/// A Touch session in lockstep on a freshly reset stand-in, unplugged from tick
/// [`DISCONNECT_AT`]; with `fault`, the servo frame of tick [`FAULT_AT`] also fails once.
fn touch_session(hooks: &Hooks, fault: bool) -> (dynaclay_devices::DeviceInfo, Session) {
    hooks.reset();
    // SAFETY: `void standin_hd_set_hand(HdHand)`.
    unsafe {
        hooks.get::<unsafe extern "C" fn(Option<shd::HdHand>)>(b"standin_hd_set_hand")(Some(
            hd_hand,
        ));
    }
    let mut arm = OpenHapticsArm::new(OpenHapticsConfig {
        library: LibrarySource::Path(hooks.path.clone()),
        device_name: None,
        servo: HdServo::Lockstep,
    });
    // Opened here for the figures the library reports (the engine's open is then a no-op).
    arm.open().expect("the stand-in opens");
    let info = arm.info();
    // SAFETY: `void standin_hd_fail_from_frame(uint64_t)`.
    let fail_from_frame =
        unsafe { hooks.get::<unsafe extern "C" fn(u64)>(b"standin_hd_fail_from_frame") };
    // SAFETY: `void standin_hd_inject_fault(unsigned)`.
    let inject_fault =
        unsafe { hooks.get::<unsafe extern "C" fn(c_uint)>(b"standin_hd_inject_fault") };
    let s = arm_session::sculpt(
        &info,
        |hand| playing(hand, arm),
        |tick| {
            // Frame 0 was `open`'s first sample; tick t's read runs frame t + 1.
            // SAFETY: the hooks' signatures above.
            unsafe {
                if tick == 0 {
                    fail_from_frame(DISCONNECT_AT + 1);
                }
                if fault && tick == FAULT_AT {
                    inject_fault(shd::HD_DEVICE_FAULT);
                }
            }
        },
    );
    (info, s)
}

#[test]
fn a_touch_sculpts_in_lockstep_one_servo_frame_per_tick_and_a_disconnect_keeps_the_sculpt() {
    let hooks = Hooks::new();
    // The same session without the failed read: what the press feels like unbroken.
    let (_, unbroken) = touch_session(&hooks, false);
    let (info, s) = touch_session(&hooks, true);
    arm_session::check_session("touch", &info, &s);
    arm_session::check_return_after_fault("touch", &s, &unbroken);

    // At the arm: no scheduled callback and no servo tick of its own; one frame per engine
    // tick (plus open's and close's), one force per frame, inside it.
    let calls = hooks.hd_calls();
    assert_eq!(calls.scheduled_callbacks, 0, "lockstep schedules nothing");
    assert_eq!(
        calls.ticks, 0,
        "no servo tick ran besides the engine's frames"
    );
    assert_eq!(calls.frames, TICKS + 2, "{calls:?}");
    assert_eq!(calls.set_force_calls, calls.frames, "{calls:?}");
    assert_eq!(calls.max_set_force_per_frame, 1, "{calls:?}");
    assert_eq!(calls.set_force_outside_frame, 0, "{calls:?}");
    let forces = hooks.forces(b"standin_hd_forces");
    assert_eq!(forces.len() as u64, calls.frames);
    // Frame 0 (open) and frame 1 (tick 0's, before anything was written) send zero; frame
    // t + 2 sends exactly what the engine sent in tick t, for every tick.
    assert_eq!(forces[0], [0.0; 3], "zero force at connect");
    assert_eq!(forces[1], [0.0; 3], "zero force at connect");
    for (t, sent) in s.sent_per_tick.iter().enumerate() {
        assert_eq!(forces[t + 2], sent.as_dvec3().to_array(), "tick {t}");
    }
    // Zero from the frame after each fault was read: the failed read's tick, every tick
    // after the disconnect, and close.
    assert_eq!(forces[FAULT_AT as usize + 2], [0.0; 3]);
    assert!(
        forces[DISCONNECT_AT as usize + 2..]
            .iter()
            .all(|f| *f == [0.0; 3])
    );
    assert!(
        forces
            .iter()
            .any(|f| DVec3::from_array(*f).length() > f64::from(arm_session::PRESSED_N)),
        "the push was felt"
    );
}

/// An omega.3 session in lockstep on a freshly reset stand-in, unplugged from read
/// [`DISCONNECT_AT`]; with `fault`, read [`FAULT_AT`] also fails once. Also hands back the
/// stand-in's record as the last tick began (before the engine closed the arm).
fn omega_session(hooks: &Hooks, fault: bool) -> (dynaclay_devices::DeviceInfo, Session, DhdCalls) {
    hooks.reset();
    // SAFETY: `void standin_dhd_set_hand(DhdHand)`.
    unsafe {
        hooks.get::<unsafe extern "C" fn(Option<sdhd::DhdHand>)>(b"standin_dhd_set_hand")(Some(
            dhd_hand,
        ));
    }
    let mut arm = DhdArm::new(DhdConfig {
        library: LibrarySource::Path(hooks.path.clone()),
        index: 0,
    });
    arm.open().expect("the stand-in opens");
    let info = arm.info();
    assert!(info.name.starts_with("omega.3"), "{}", info.name);
    // SAFETY: `void standin_dhd_disconnect_at(uint64_t)`.
    let disconnect_at =
        unsafe { hooks.get::<unsafe extern "C" fn(u64)>(b"standin_dhd_disconnect_at") };
    // SAFETY: `void standin_dhd_fail_reads(uint32_t)`.
    let fail_reads = unsafe { hooks.get::<unsafe extern "C" fn(u32)>(b"standin_dhd_fail_reads") };
    let mut before_last_tick = None;
    let s = arm_session::sculpt(
        &info,
        |hand| playing(hand, arm),
        |tick| {
            // `open` reads nothing: tick t's read is read t.
            // SAFETY: the hooks' signatures above.
            unsafe {
                if tick == 0 {
                    disconnect_at(DISCONNECT_AT);
                }
                if fault && tick == FAULT_AT {
                    fail_reads(1);
                }
            }
            if tick == TICKS - 1 {
                before_last_tick = Some(hooks.dhd_calls());
            }
        },
    );
    let calls = before_last_tick.expect("the session ran its ticks");
    (info, s, calls)
}

#[test]
fn an_omega_sculpts_in_lockstep_one_force_per_read_and_a_disconnect_keeps_the_sculpt() {
    let hooks = Hooks::new();
    let (_, unbroken, _) = omega_session(&hooks, false);
    let (info, s, before_last_tick) = omega_session(&hooks, true);
    arm_session::check_session("omega.3", &info, &s);
    arm_session::check_return_after_fault("omega.3", &s, &unbroken);

    // At the arm: one read per tick, never two forces between two ticks' reads (close's zero
    // follows the last tick's, so the bound is taken as the last tick began); the forces the
    // arm took are open's zero and one per tick until it was unplugged.
    assert_eq!(
        before_last_tick.max_set_force_per_read, 1,
        "{before_last_tick:?}"
    );
    let calls = hooks.dhd_calls();
    assert_eq!(calls.position_reads, TICKS, "{calls:?}");
    assert_eq!(
        calls.set_force_calls,
        1 + TICKS + 1,
        "open, each tick, close: {calls:?}"
    );
    let forces = hooks.forces(b"standin_dhd_forces");
    assert_eq!(forces.len() as u64, 1 + DISCONNECT_AT);
    assert_eq!(forces[0], [0.0; 3], "zero force at connect");
    for (t, sent) in s
        .sent_per_tick
        .iter()
        .take(DISCONNECT_AT as usize)
        .enumerate()
    {
        assert_eq!(forces[t + 1], device_to_dhd(*sent), "tick {t}");
    }
    assert_eq!(
        forces[FAULT_AT as usize + 1],
        [0.0; 3],
        "zero on the failed read"
    );
    assert!(
        forces
            .iter()
            .any(|f| dhd_to_device(*f).length() > arm_session::PRESSED_N),
        "the push was felt"
    );
}
