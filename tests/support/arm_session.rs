//! A lockstep sculpting session through a hardware driver on its stand-in, and the checks
//! every arm must pass there (the simulated arm's): zero force at connect, force within the
//! arm's bound, zero force on every fault, the soft-start ramp after a fault, a disconnect in
//! the middle of the stroke that keeps the engine ticking and keeps the groove made before it.
//!
//! The session is the shared push script, 0.2 below the block's top; the stand-in plays the
//! script's hand one position per exchange with the driver (1 ms of script time each), so the
//! run depends on the calls and never on time. Shared by `#[path]` (this folder is not a test
//! target of its own).

use dynaclay::dynamics::Material;
use dynaclay::engine::{Command, EngineConfig, HeadlessSink, Lockstep, ScriptPlan, build_clay};
use dynaclay::field::BSplineLattice;
use dynaclay::io::{Script, parse_script};
use dynaclay_devices::{DeviceInfo, HapticDevice, soft_start_gain};
use glam::Vec3;

/// Ticks of a session, the tick whose read fails once (0.4 s: the hand leaves its hover at
/// 0.1 s, has descended into the clay by 0.4 s and follows the path from there to 1.4 s, so
/// the press is under way) and the tick from which the arm is gone (0.7 s, in the middle of
/// the path).
pub const TICKS: u64 = 1300;
pub const FAULT_AT: u64 = 400;
pub const DISCONNECT_AT: u64 = 700;
/// The soft start of these sessions, seconds (100 ms).
pub const SOFT_START_S: f32 = 0.1;

/// A force this large is the tool pressing on the clay, not rounding noise (newtons).
pub const PRESSED_N: f32 = 0.01;

/// Where the hand is at the stand-in's exchange `k` (device frame, metres).
pub type HandPath = Box<dyn Fn(u64) -> Vec3 + Send>;

/// What a session did, tick by tick, and the clay it left.
pub struct Session {
    /// Each tick's force as the engine reports it sent (device frame, newtons).
    pub sent_per_tick: Vec<Vec3>,
    /// Whether each tick saw a device fault.
    pub faulted: Vec<bool>,
    /// Each tick's device time, microseconds (the clock the safety filter ramps on).
    pub device_time_us: Vec<u64>,
    /// Path points 0.05 above the hand's path the tool passed before the disconnect: the
    /// field there at the start, at the disconnect and at the end.
    pub groove_before_disconnect: Vec<(Vec3, f32, f32, f32)>,
    pub iso: f32,
    pub far_change: f32,
    pub read_faults: u64,
}

/// The sessions' script: the shared push script, its path 0.2 below the block's top (the
/// tool presses on the clay along it).
pub fn script_text() -> String {
    super::common::PUSH_SCRIPT.replace(
        "path = [[0.75, 1.3, 0.95], [1.15, 1.3, 0.95]]",
        "path = [[0.75, 1.225, 0.95], [1.15, 1.225, 0.95]]",
    )
}

/// The sessions' script, parsed.
pub fn push_script() -> Script {
    parse_script(&script_text(), "test").unwrap()
}

/// `script` planned on plastic clay, as the sessions run it.
pub fn push_plan(script: &Script) -> ScriptPlan {
    ScriptPlan::new(
        script,
        "test",
        std::path::Path::new("."),
        &[],
        Material::PLASTIC,
    )
    .unwrap()
}

/// The script's hand in the device frame of an arm described by `info`, as the engine maps
/// the script's path onto it (the script's clay fitted into the arm's workspace): where it is
/// at the stand-in's exchange `k`, 1 ms of script time each.
pub fn script_hand(info: &DeviceInfo) -> HandPath {
    let plan = push_plan(&push_script());
    let field = build_clay(&plan.clay).unwrap();
    let map = EngineConfig::for_field(&field, info).map;
    let trajectory = plan.trajectory(&map).unwrap();
    Box::new(move |k| trajectory.sample(k as f64 * 1e-3).position_m)
}

/// Runs the push script in lockstep for [`TICKS`] ticks. `start` is handed the script's hand
/// and returns the arm (its stand-in set to play that hand); `info` is the arm's figures;
/// `before_tick` runs before each tick (to break the link on cue).
pub fn sculpt(
    info: &DeviceInfo,
    start: impl FnOnce(HandPath) -> Box<dyn HapticDevice>,
    mut before_tick: impl FnMut(u64),
) -> Session {
    let script = push_script();
    let plan = push_plan(&script);
    let field = build_clay(&plan.clay).unwrap();
    let before = field.clone();
    let mut config = EngineConfig::for_field(&field, info);
    config.haptic_rt_priority = None;
    config.safety.soft_start_s = SOFT_START_S;
    config.haptics.tool_contact = plan.tool_contact;
    let device = start(script_hand(info));
    let mut engine = Lockstep::new(
        &config,
        field,
        device,
        Box::new(HeadlessSink::default()),
        16,
    )
    .expect("the engine opens the arm");
    // No button pressed: the stroke is armed by command, as the window's stroke key does.
    engine
        .commands()
        .send(Command::StrokeStart)
        .expect("the simulation takes commands");
    let mut sent_per_tick = Vec::new();
    let mut faulted = Vec::new();
    let mut device_time_us = Vec::new();
    let mut at_disconnect = None;
    for tick in 0..TICKS {
        before_tick(tick);
        engine.step();
        let t = engine.latest_tool();
        if tick == 0 {
            assert_eq!(t.device_force_n, Vec3::ZERO, "zero force at connect");
        }
        assert!(
            t.device_force_n.length() <= info.max_force_n + 1e-4,
            "tick {tick}: {} N over the arm's {} N",
            t.device_force_n.length(),
            info.max_force_n
        );
        if t.device_fault {
            assert_eq!(
                t.device_force_n,
                Vec3::ZERO,
                "tick {tick}: force during the fault"
            );
            assert!(!t.in_contact, "tick {tick}");
        }
        if tick == DISCONNECT_AT {
            at_disconnect = Some(engine.field().clone());
        }
        sent_per_tick.push(t.device_force_n);
        faulted.push(t.device_fault);
        device_time_us.push(t.device_time_us);
    }
    assert_eq!(engine.ticks(), TICKS, "the engine kept ticking");
    let report = engine.finish().expect("the run ends with its session");
    let after = &report.session.clay.density.patches[0].lattice;
    assert!(
        after.coeffs.iter().all(|c| c.is_finite()),
        "NaN in the field"
    );
    let at_disconnect: BSplineLattice = at_disconnect.expect("ran to the disconnect");
    // The groove along the part of the path the hand took well before the link went: at 0.7 s
    // the hand was 0.6 along the stroke (x = 0.99); the points up to x = 0.9 are behind it.
    let path = super::common::path_points(&script);
    let groove_before_disconnect = path
        .iter()
        .take(4)
        .skip(1)
        .map(|p| {
            let p = *p + Vec3::Y * 0.05;
            (p, before.value(p), at_disconnect.value(p), after.value(p))
        })
        .collect();
    let far = Vec3::new(0.95, 0.6, 0.95);
    Session {
        sent_per_tick,
        faulted,
        device_time_us,
        groove_before_disconnect,
        iso: before.iso,
        far_change: (after.value(far) - before.value(far)).abs(),
        read_faults: report.counters.device_read_faults,
    }
}

/// The checks every arm shares: the faulted ticks are the failed read's and every one from
/// the disconnect on; after the fault the force starts from zero and stays under the soft
/// start's bound on the device's clock; the press was felt before the fault; the groove made
/// before the disconnect is kept; nothing changed far away.
pub fn check_session(name: &str, info: &DeviceInfo, s: &Session) {
    let expected: Vec<bool> = (0..TICKS)
        .map(|t| t == FAULT_AT || t >= DISCONNECT_AT)
        .collect();
    let faulted_at: Vec<usize> = (0..TICKS as usize).filter(|t| s.faulted[*t]).collect();
    assert_eq!(
        s.faulted,
        expected,
        "{name}: faulted ticks {:?}",
        &faulted_at[..faulted_at.len().min(8)]
    );
    assert_eq!(s.read_faults, 1 + TICKS - DISCONNECT_AT, "{name}");
    // The tool was pressing when the fault came (so the ramp below has a force to hold back).
    let before_fault = s.sent_per_tick[FAULT_AT as usize - 1].length();
    assert!(
        before_fault > PRESSED_N,
        "{name}: {before_fault} N before the fault (the press was not felt)"
    );
    // The first good read after the fault starts the ramp at zero, on the device's clock.
    let first = FAULT_AT as usize + 1;
    assert_eq!(
        s.sent_per_tick[first],
        Vec3::ZERO,
        "{name}: the ramp starts at zero"
    );
    let ramp_start_us = s.device_time_us[first];
    let ramp_us = (SOFT_START_S * 1e6) as u64;
    for t in first..DISCONNECT_AT as usize {
        let elapsed_us = s.device_time_us[t] - ramp_start_us;
        if elapsed_us >= ramp_us {
            break;
        }
        let f = s.sent_per_tick[t].length();
        let bound = info.max_force_n * soft_start_gain(elapsed_us as f32 / ramp_us as f32);
        assert!(
            f <= bound + 1e-4,
            "{name}: {f} N at {elapsed_us} us into the ramp (bound {bound} N)"
        );
    }
    for (p, was, at_disconnect, at_end) in &s.groove_before_disconnect {
        assert!(*was > s.iso, "{name}: clay was there at {p}");
        // The press took the field down by a good part of its margin over the iso-level...
        assert!(
            was - at_disconnect > 0.25 * (was - s.iso),
            "{name}: no groove at {p} by the disconnect: {was} → {at_disconnect}"
        );
        // ...and what the disconnect found is what the session kept: the clay never springs
        // back up toward the untouched block, and settles on by a bounded amount once the
        // tool has gone (the press's own momentum carries on, as after any release: 0.057 to
        // 0.062 of field here, on arms that pressed 0.04 to 0.17 N).
        assert!(
            *at_end < at_disconnect + 0.05
                && at_disconnect - at_end < 0.1
                && *at_end < was - 0.25 * (was - s.iso),
            "{name}: the groove at {p} was not kept: {at_disconnect} at the disconnect, \
             {at_end} at the end"
        );
    }
    assert!(
        s.far_change < 1e-3,
        "{name}: changed far away ({})",
        s.far_change
    );
}

/// Ticks after the failed read by which the soft start (100 ms: 100 ticks of the arm's 1 kHz
/// clock) and the renderer's blend back in (20 ms) are over.
pub const RECOVERED_AFTER: u64 = 121;

/// After the soft start that follows the failed read, the arm feels what the same session
/// without that fault (`unbroken`) feels, tick by tick, up to the disconnect: one lost sample
/// costs the press nothing once the ramp is over (the stroke is not ended and restarted, so
/// the clay is carved on as without the fault).
///
/// The force before the fault is no reference: the fault comes as the descent ends, when the
/// press is a passing peak (on the Touch 0.10 N 50 ms before, 0.043 N at the fault, and
/// 0.025 N 120 ms later in a session with no fault at all), so only the unbroken session at
/// the same tick says what the hand should feel.
pub fn check_return_after_fault(name: &str, s: &Session, unbroken: &Session) {
    let window = (FAULT_AT + RECOVERED_AFTER) as usize..DISCONNECT_AT as usize;
    let pressed = window
        .clone()
        .map(|t| unbroken.sent_per_tick[t].length())
        .fold(0.0, f32::max);
    assert!(
        pressed > PRESSED_N,
        "{name}: the unbroken session did not press after the ramp ({pressed} N at most)"
    );
    for t in window {
        let (got, want) = (s.sent_per_tick[t], unbroken.sent_per_tick[t]);
        assert!(
            (got - want).length() <= RETURN_TOLERANCE * want.length() + 1e-4,
            "{name}: tick {t}: {got} N after the fault's ramp, {want} N unbroken"
        );
    }
}

/// How far the force after the fault's ramp may stray from the unbroken session's, as a share
/// of it (the failed read's tick pushes nothing, so the clay differs by one tick's push).
pub const RETURN_TOLERANCE: f32 = 0.05;
