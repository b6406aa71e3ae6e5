//! Record a simulated-arm session through the lockstep engine, then replay the recording
//! twice: both replays end with the recorded run's field, bit for bit.

mod common;

use dynaclay::engine::{HeadlessSink, Lockstep};
use dynaclay::field::BSplineLattice;
use dynaclay_devices::HapticDevice;
use dynaclay_devices::record::{RecordingDevice, ReplayDevice};

fn run(
    config: &dynaclay::engine::EngineConfig,
    field: BSplineLattice,
    device: Box<dyn HapticDevice>,
    ticks: usize,
) -> BSplineLattice {
    let mut ls = Lockstep::new(config, field, device, Box::new(HeadlessSink::default()), 64)
        .expect("lockstep starts");
    for _ in 0..ticks {
        ls.step();
    }
    let report = ls.finish().expect("lockstep finishes");
    report.session.clay.density.patches[0].lattice.clone()
}

#[test]
fn replaying_a_recording_reproduces_the_field_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("push.rec");
    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    let start = s.field.clone();
    let recorder = RecordingDevice::create(s.arm, &path).expect("recording starts");
    let ticks = 1500;
    // The recording device finishes its file when the lockstep run drops it.
    let recorded = run(&s.config, s.field, Box::new(recorder), ticks);
    assert_ne!(recorded, start, "the session sculpted something");

    let replay = ReplayDevice::load(&path).expect("recording loads");
    assert_eq!(replay.read_count(), ticks);
    let first = run(&s.config, start.clone(), Box::new(replay), ticks);
    let second = run(
        &s.config,
        start,
        Box::new(ReplayDevice::load(&path).unwrap()),
        ticks,
    );
    let bits = |l: &BSplineLattice| l.coeffs.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&first), bits(&second), "two replays differ");
    assert_eq!(
        bits(&first),
        bits(&recorded),
        "replay differs from the recorded run"
    );
}

/// A pointer (mouse) session: the app's hand-over is driven tick by tick along a drag over the
/// block's top, recorded, and replayed; the replay ends with the recorded field bit for bit.
#[test]
fn a_recorded_pointer_session_replays_bit_for_bit() {
    use dynaclay_devices::pointer::{PointerConfig, pointer_device};
    use glam::Vec3;

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pointer.rec");
    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    let start = s.field.clone();
    let pointer = PointerConfig::stepped(1_000);
    let mut config = dynaclay::engine::EngineConfig::for_field(&start, &pointer.info());
    config.haptic_rt_priority = None;
    config.safety.soft_start_s = 0.1;
    let (device, mut handle) = pointer_device(pointer);
    let recorder = RecordingDevice::create(device, &path).expect("recording starts");
    let mut ls = Lockstep::new(
        &config,
        start.clone(),
        Box::new(recorder),
        Box::new(HeadlessSink::default()),
        64,
    )
    .expect("lockstep starts");
    let ticks = 1400;
    // Hover above the path, press down onto it, drag along x, lift.
    let tip = |tick: usize| -> (Vec3, bool) {
        let t = tick as f32;
        match tick {
            0..200 => (Vec3::new(0.75, 1.6, 0.95), false),
            200..300 => (Vec3::new(0.75, 1.6 - 0.3 * (t - 200.0) / 100.0, 0.95), true),
            300..1300 => (
                Vec3::new(0.75 + 0.4 * (t - 300.0) / 1000.0, 1.3, 0.95),
                true,
            ),
            _ => (Vec3::new(1.15, 1.6, 0.95), false),
        }
    };
    for tick in 0..ticks {
        let (p, pressed) = tip(tick);
        handle.set(config.map.to_device(p), pressed);
        ls.step();
    }
    let recorded = ls
        .finish()
        .expect("lockstep finishes")
        .session
        .clay
        .density
        .patches[0]
        .lattice
        .clone();
    let iso = start.iso;
    let mid = Vec3::new(0.95, 1.35, 0.95);
    assert!(
        start.value(mid) > iso && recorded.value(mid) < iso,
        "the drag dented the top: {} → {}",
        start.value(mid),
        recorded.value(mid)
    );

    let replay = ReplayDevice::load(&path).expect("recording loads");
    assert_eq!(replay.read_count(), ticks);
    let replayed = run(&config, start, Box::new(replay), ticks);
    let bits = |l: &BSplineLattice| l.coeffs.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
    assert_eq!(
        bits(&replayed),
        bits(&recorded),
        "replay differs from the recorded pointer session"
    );
}

/// A script with every kind of input the engine's outcome depends on: a geometric tool step
/// (a command), a contact push (tool samples), an undo (a command between strokes) and a
/// pull with a force tool.
const MIXED_SCRIPT: &str = r#"
version = 1

[clay]
shape = "block"
resolution = 20

[[step]]
do = "tool"
shape = { kind = "sphere", radius_fu = 0.15 }
action = { kind = "add", deposit_rate_per_s = 10.0 }
positions = [[1.15, 1.75, 1.15]]
duration_s = 0.3
falloff_fu = 0.1

[[step]]
do = "stroke"
path = [[0.75, 1.3, 0.95], [1.1, 1.3, 0.95]]
duration_s = 0.6
hover_fu = 0.3

[[step]]
do = "undo"

[[step]]
do = "stroke"
tool = { kind = "pull", beta = "gaussian", radius_fu = 0.15, gain = 2e6 }
path = [[1.3, 1.4, 1.3], [1.3, 1.55, 1.3]]
duration_s = 0.4
hover_fu = 0.2
"#;

/// A threaded run, recorded with its schedule while two threads load the machine, replays to
/// the live run's final field bit for bit: whatever interleaving the threads had, the replay
/// gives each haptic tick the snapshot and fade it saw, and each step its sample and commands.
#[test]
fn a_threaded_run_under_load_replays_to_the_live_field_bit_for_bit() {
    use std::sync::Arc;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::time::{Duration, Instant};

    use dynaclay::engine::{Engine, ScheduledReplay, ScriptDriver, StartOptions};

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("live.rec");
    let s = common::setup(MIXED_SCRIPT, vec![]);
    let start = s.field.clone();
    // A queue that holds the whole run: no record can be dropped, however little CPU the
    // recorder's writer thread gets beside the load.
    let recorder = RecordingDevice::with_config(
        s.arm,
        &path,
        dynaclay_devices::RecorderConfig {
            queue_capacity: 1 << 20,
            ..Default::default()
        },
    )
    .expect("recording starts");
    let schedule = recorder.schedule_log();

    // Two spinning threads compete with the loops for the machine's cores.
    let stop_load = Arc::new(AtomicBool::new(false));
    let load: Vec<_> = (0..2)
        .map(|_| {
            let stop = Arc::clone(&stop_load);
            std::thread::spawn(move || {
                let mut x = 1u64;
                while !stop.load(Ordering::Relaxed) {
                    x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
                    std::hint::black_box(x);
                }
            })
        })
        .collect();
    let mut engine = Engine::start_with(
        &s.config,
        s.field,
        Box::new(recorder),
        Box::new(HeadlessSink::default()),
        StartOptions {
            autosave: None,
            schedule: Some(schedule),
        },
    )
    .expect("engine starts");
    let mut driver = ScriptDriver::new(&s.plan);
    let commands = engine.commands();
    // The run lasts as long as the script on the arm's clock, however slowly the machine
    // runs it; the wall-clock bound only keeps a broken engine from hanging the test.
    let started = Instant::now();
    while !(driver.is_done() && engine.latest_tool().device_time_us as f64 > s.plan.end_s * 1e6)
        && started.elapsed() < Duration::from_secs(600)
    {
        let sample = engine.latest_tool();
        driver.dispatch(&sample, &commands);
        std::thread::sleep(Duration::from_millis(2));
    }
    drop(commands);
    let live = engine.stop().expect("engine stops");
    stop_load.store(true, Ordering::Relaxed);
    for t in load {
        t.join().unwrap();
    }
    assert!(driver.failures().is_empty(), "{:?}", driver.failures());
    let live_field = live.session.clay.density.patches[0].lattice.clone();
    assert_ne!(live_field, start, "the live run sculpted something");

    let device = ReplayDevice::load(&path).expect("recording loads");
    let schedule = device.schedule().expect("the recording holds its schedule");
    assert_eq!(schedule.ticks.len(), device.read_count());
    assert!(!schedule.steps.is_empty());
    let mut replay = ScheduledReplay::new(
        &s.config,
        start,
        device,
        Box::new(HeadlessSink::default()),
        16,
    )
    .expect("replay starts");
    let mut driver = ScriptDriver::new(&s.plan);
    let commands = replay.commands();
    while replay
        .tick()
        .expect("the replay follows the schedule")
        .is_some()
    {
        driver.dispatch(&replay.latest_tool(), &commands);
    }
    let replayed = replay.finish().expect("replay finishes");
    assert!(driver.failures().is_empty(), "{:?}", driver.failures());
    let bits = |l: &BSplineLattice| l.coeffs.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
    let replayed_field = &replayed.session.clay.density.patches[0].lattice;
    let differing = live_field
        .coeffs
        .iter()
        .zip(&replayed_field.coeffs)
        .filter(|(a, b)| a.to_bits() != b.to_bits())
        .count();
    assert_eq!(
        bits(replayed_field),
        bits(&live_field),
        "the replay differs from the live run in {differing} coefficients"
    );
    assert_eq!(
        replayed.counters.sim_steps, live.counters.sim_steps,
        "as many steps as the live run"
    );
}

/// A recording whose schedule was cut short (the recorder dropped records) is refused as a
/// schedule, with the reason; it still replays in lockstep.
#[test]
fn a_recording_without_a_usable_schedule_says_why() {
    use dynaclay_devices::record::{Record, Recording, ScheduleGap, ScheduleNote};

    let info = common::setup(common::PUSH_SCRIPT, vec![]).arm.info();
    let none = ReplayDevice::from_recording(Recording {
        info: info.clone(),
        records: Vec::new(),
        dropped: 0,
    });
    assert_eq!(none.schedule().unwrap_err(), ScheduleGap::Absent);
    let tick = |tick| {
        Record::Schedule(ScheduleNote::Tick {
            tick,
            snapshot_version: Some(0),
            fade: 1.0,
        })
    };
    let dropped = ReplayDevice::from_recording(Recording {
        info: info.clone(),
        records: vec![tick(1), tick(2)],
        dropped: 1,
    });
    assert_eq!(dropped.schedule().unwrap_err(), ScheduleGap::Dropped(1));
    let gap = ReplayDevice::from_recording(Recording {
        info,
        records: vec![tick(1), tick(3)],
        dropped: 0,
    });
    let e = gap.schedule().unwrap_err();
    assert!(e.to_string().contains("tick 3 follows 1"), "{e}");
}
