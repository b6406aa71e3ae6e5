//! The haptic tick allocates nothing: a counting global allocator in this test binary counts
//! allocations made on the ticking thread while a tick runs, through contact, new field
//! patches, the safety filter, a force-limit change, a whole-field republication after a
//! session load, a new patch layout after a refinement, after the clay grew past its box,
//! after a fine brush refined under itself and after a broad smoothing wiped that detail and
//! its patch folded back (a smaller layout), and a device switch and a disconnect
//! while ticking (the ticks go on until the
//! switching thread is done, however late the machine runs it); and through strokes of
//! the force tools, whose reaction the tick integrates (the stroke geometry copied in, the
//! tool's vectors, their starts found again on the surface; with automatic detail for force
//! tools on, the area's fine spread refines
//! under itself during its stroke, a new layout the tick takes); through a carve with tool-shaped
//! contact (the tool's point shell resting on the clay, the press measured); and through a
//! pointer stroke fed at 2 Hz, whose path the pointer device interpolates on the haptic thread;
//! and through a Falcon's stroke on its stand-in, the driver's command and reply framing, its
//! kinematics and a stray byte on the line included.

mod common;
#[path = "../devices/tests/support/falcon_standin.rs"]
mod falcon_standin;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::time::Instant;

use dynaclay::dynamics::Distribution;
use dynaclay::engine::{Command, DeviceHandover, HeadlessSink, ToolChoice, build};
use dynaclay::io::Session;
use dynaclay::tools::{ForceTool, GeometricTool, ToolAction, ToolShape};
use dynaclay_devices::{
    Fault, FaultKind, HapticDevice, Interpolation, SafetyFilter, SimArmConfig, SimulatedArm,
    Trajectory, Waypoint,
};
use glam::Vec3;

struct Counting;

thread_local! {
    /// Whether this thread is inside a guarded tick.
    static IN_TICK: Cell<bool> = const { Cell::new(false) };
    /// Allocations this thread made inside guarded ticks (per thread, so tests running side by
    /// side do not count each other's).
    static ALLOCS_IN_TICK: Cell<u64> = const { Cell::new(0) };
}

fn allocs_in_tick() -> u64 {
    ALLOCS_IN_TICK.with(Cell::get)
}

// SAFETY: forwards every call to the system allocator unchanged; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if IN_TICK.with(Cell::get) {
            ALLOCS_IN_TICK.with(|n| n.set(n.get() + 1));
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if IN_TICK.with(Cell::get) {
            ALLOCS_IN_TICK.with(|n| n.set(n.get() + 1));
        }
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn haptic_tick_allocates_nothing() {
    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    // Recorded, with the schedule noted every tick: the recorder's encode and queue push are
    // part of the tick too.
    let dir = tempfile::tempdir().unwrap();
    let recorder =
        dynaclay_devices::RecordingDevice::create(s.arm, dir.path().join("tick.rec")).unwrap();
    let schedule = recorder.schedule_log();
    let mut stages = build(
        &s.config,
        s.field,
        Box::new(recorder),
        Box::new(HeadlessSink::default()),
        true,
    )
    .expect("stages build");
    stages.haptic.set_schedule_log(schedule.clone());
    stages.sim.set_schedule_log(schedule);
    // The guard itself works: an allocation inside it is counted.
    IN_TICK.with(|f| f.set(true));
    let probe = std::hint::black_box(vec![1u8; 16]);
    IN_TICK.with(|f| f.set(false));
    drop(probe);
    assert_eq!(allocs_in_tick(), 1);
    ALLOCS_IN_TICK.with(|n| n.set(0));

    let limit = stages.haptic.force_limit();
    let map = s.config.map;
    let mut swaps = Some(stages.device_swaps);
    let mut swapper = None;
    let mut applied_before_swap = f32::NAN;
    let mut status = stages.sim.take_status_reader().expect("status reader");
    let mut loaded = stages.sim.lattice().clone();
    loaded.coeffs.update_each(|_, c| {
        *c *= 0.999;
    });
    let mut contact_ticks = 0;
    let mut patched_ticks = 0;
    // Where the fine brush carves (the smoothing wipes it there).
    let mut fine_brush_at = None;
    // At least 1600 ticks, and on until the swapper thread is done: it runs whenever the
    // machine lets it, and the ticks must be there to take what it offers.
    let mut i = 0u64;
    loop {
        if i >= 1600
            && swapper
                .as_ref()
                .is_some_and(|h: &std::thread::JoinHandle<_>| h.is_finished())
        {
            break;
        }
        assert!(i < 10_000_000, "the swapper thread never finished");
        if i == 300 {
            limit.request(0.1).unwrap();
        }
        if i == 500 {
            // A detail patch over the clay's middle: the tick takes the new layout's copy
            // by pointer and hands its old one back.
            let (lo, hi) = stages.sim.lattice().support();
            let (c, r) = ((lo + hi) * 0.5, (hi - lo) * 0.2);
            stages
                .commands
                .send(Command::Refine {
                    lo: c - r,
                    hi: c + r,
                    level: 1,
                    reply: None,
                })
                .unwrap();
        }
        if i == 700 {
            // The session loaded must be laid out like the running clay: with its detail.
            let mut clay = stages.sim.clay().clone();
            clay.density.patches[0].lattice = loaded.clone();
            let session = Session {
                clay,
                ..Session::default()
            };
            stages
                .commands
                .send(Command::Load {
                    session: Box::new(session),
                    source: "same-lattice.dclay".into(),
                    keep_history: false,
                    reply: None,
                })
                .unwrap();
        }
        if i == 800 {
            // A lump added past the clay's box grows the base: a new layout, every coefficient
            // published again.
            let base = stages.sim.lattice();
            let last = base.node_position(base.dims[0] - 1, base.dims[1] - 1, base.dims[2] - 1);
            let middle = (base.origin + last) * 0.5;
            stages
                .commands
                .send(Command::ApplyTool {
                    tool: GeometricTool {
                        shape: ToolShape::Sphere { radius_fu: 0.3 },
                        action: ToolAction::Add {
                            deposit_rate_per_s: 4.0,
                        },
                        falloff_fu: 0.1,
                    },
                    poses: vec![dynaclay::tools::ToolPose::at(Vec3::new(
                        last.x + 0.15,
                        middle.y,
                        middle.z,
                    ))],
                    duration_s: 1.0,
                    patch: 0,
                    reply: None,
                })
                .unwrap();
        }
        if i == 850 {
            // A brush of a fifth of a knot span refines under itself: another layout.
            let base = stages.sim.lattice();
            let middle = base.node_position(base.dims[0] / 2, base.dims[1] / 2, base.dims[2] / 2);
            fine_brush_at = Some(middle);
            stages
                .commands
                .send(Command::ApplyTool {
                    tool: GeometricTool {
                        shape: ToolShape::Sphere {
                            radius_fu: 0.1 * base.spacing,
                        },
                        action: ToolAction::Remove,
                        falloff_fu: 0.05 * base.spacing,
                    },
                    poses: vec![dynaclay::tools::ToolPose::at(middle)],
                    duration_s: 0.1,
                    patch: 0,
                    reply: None,
                })
                .unwrap();
        }
        if i == 1300 {
            // After the script's stroke has let go (a fold waits for no region to be held): a
            // broad smoothing over the fine brush's cavity wipes its detail; at the step's
            // commit the detail patches under it fold back into the base, and the tick takes
            // the smaller layout.
            let at = fine_brush_at.expect("the fine brush was sent at tick 850");
            assert_eq!(
                stages.haptic.field().patches.len(),
                3,
                "before the fold, the tick holds the refined layouts"
            );
            stages
                .commands
                .send(Command::ApplyTool {
                    tool: GeometricTool {
                        shape: ToolShape::Sphere { radius_fu: 0.25 },
                        action: ToolAction::Smooth {
                            rate_per_s: 20.0,
                            kernel_fu: 0.15,
                        },
                        falloff_fu: 0.05,
                    },
                    poses: vec![dynaclay::tools::ToolPose::at(at)],
                    duration_s: 3.0,
                    patch: 0,
                    reply: None,
                })
                .unwrap();
        }
        if i == 999 {
            applied_before_swap = limit.applied_n();
        }
        if i == 1000 {
            // Another thread opens a second arm and offers it, then disconnects: the ticks
            // below take each in turn (the devices are built and closed on that thread).
            let request = swaps.take().expect("one swapper");
            swapper = Some(std::thread::spawn(move || {
                let timeout = std::time::Duration::from_secs(10);
                let arm = SimulatedArm::new(SimArmConfig::default(), Trajectory::hold(Vec3::ZERO));
                let mut device: SafetyFilter<Box<dyn HapticDevice>> =
                    SafetyFilter::new(Box::new(arm));
                device.open().expect("second arm opens");
                let handover = DeviceHandover {
                    device,
                    map,
                    connected: true,
                };
                let first = request.swap(handover, timeout).expect("switched");
                let second = request
                    .swap(DeviceHandover::parked(map), timeout)
                    .expect("parked");
                (first.connected, second.connected)
            }));
        }
        IN_TICK.with(|f| f.set(true));
        let out = stages.haptic.tick(Instant::now());
        IN_TICK.with(|f| f.set(false));
        if out.sample.in_contact {
            contact_ticks += 1;
        }
        // The simulation and graphics run outside the guard (they may allocate).
        stages.sim.apply_commands();
        let sample = stages.samples.latest().value;
        if stages.sim.step(&sample).stepped {
            patched_ticks += 1;
        }
        if i.is_multiple_of(50) {
            stages.graphics.tick();
        }
        i += 1;
    }
    assert!(
        contact_ticks > 200,
        "the tick was exercised in contact ({contact_ticks})"
    );
    assert!(
        patched_ticks > 200,
        "with fresh field patches ({patched_ticks})"
    );
    assert_eq!(
        applied_before_swap, 0.1,
        "the limit change was applied in a tick"
    );
    assert_eq!(
        (
            status.latest().value.sessions_loaded,
            stages.counters.snapshot().command_errors
        ),
        (1, 0),
        "the load was applied"
    );
    let (first_was_connected, second_was_connected) = swapper
        .expect("swapper started")
        .join()
        .expect("swapper finished");
    assert!(
        first_was_connected && second_was_connected,
        "the original arm, then the second, came back"
    );
    assert!(!stages.haptic.is_connected(), "parked by the disconnect");
    let counters = stages.counters.snapshot();
    eprintln!(
        "growths {}, auto refines {}, auto coarsenings {}; patches in the tick at the end {}",
        counters.clay_growths,
        counters.auto_refines,
        counters.auto_coarsenings,
        stages.haptic.field().patches.len()
    );
    assert_eq!(
        (counters.clay_growths, counters.auto_refines),
        (1, 1),
        "the clay grew once and refined under the fine brush once"
    );
    assert_eq!(
        counters.auto_coarsenings, 2,
        "the smoothing wiped both detail patches under it and both folded back"
    );
    assert_eq!(
        stages.haptic.field().patches.len(),
        1,
        "the tick installed the folded layout"
    );
    assert_eq!(
        stages.haptic.field().base().dims,
        stages.sim.lattice().dims,
        "the tick installed the grown layout"
    );
    assert_eq!(limit.applied_n(), 0.0, "no device, no force");
    assert_eq!(stages.counters.snapshot().device_swaps, 2);
    assert_eq!(allocs_in_tick(), 0, "haptic tick allocated");
}

#[test]
fn force_tool_strokes_tick_without_allocating() {
    let gain = 2.0e6;
    for tool in [
        ForceTool::Area {
            distribution: Distribution::Gaussian,
            radius_fu: 0.1,
            tracks: 8,
            gain,
        },
        ForceTool::Chisel {
            depth_fu: 0.02,
            radius_fu: 0.25,
            gain,
        },
        ForceTool::Bend {
            samples: 8,
            radius_fu: 0.25,
            gain,
        },
    ] {
        let mut s = common::setup(common::PUSH_SCRIPT, vec![]);
        // Force tools refine under themselves (off by default).
        s.config.sim.auto_detail_force = true;
        let top_y_m = common::block_top_y_m(&s.config);
        // Down onto the top, take hold, drag up and sideways while held, let go.
        let path = vec![
            Waypoint::with_buttons(0.0, Vec3::new(0.0, top_y_m + 0.02, 0.0), 0),
            Waypoint::with_buttons(0.3, Vec3::new(0.0, top_y_m - 0.001, 0.0), 0),
            Waypoint::with_buttons(0.35, Vec3::new(0.0, top_y_m - 0.001, 0.0), 1),
            Waypoint::with_buttons(0.9, Vec3::new(0.01, top_y_m + 0.008, 0.0), 1),
            Waypoint::with_buttons(1.2, Vec3::new(0.01, top_y_m + 0.02, 0.0), 0),
        ];
        let trajectory = Trajectory::new(path, Interpolation::Smooth).unwrap();
        let arm = SimulatedArm::new(SimArmConfig::default(), trajectory);
        let mut stages = build(
            &s.config,
            s.field,
            Box::new(arm),
            Box::new(HeadlessSink::default()),
            true,
        )
        .expect("stages build");
        stages
            .commands
            .send(Command::SetTool(ToolChoice::Force {
                tool,
                curve: Vec::new(),
                pivot: Vec3::new(0.95, 0.95, 0.95),
            }))
            .unwrap();
        let before = allocs_in_tick();
        let mut holding = 0;
        for _ in 0..1300 {
            IN_TICK.with(|f| f.set(true));
            let out = stages.haptic.tick(Instant::now());
            IN_TICK.with(|f| f.set(false));
            if out.sample.in_contact && out.sample.stroke_active {
                holding += 1;
            }
            stages.sim.apply_commands();
            let sample = stages.samples.latest().value;
            stages.sim.step(&sample);
        }
        assert!(
            holding > 200,
            "{}: the tool took hold ({holding})",
            tool.name()
        );
        // A spread narrower than three knot spans of the base (the area's) refines under
        // itself during the counted ticks: the tick takes the new layout.
        let spacing = stages.sim.lattice().spacing;
        let refines = stages.counters.snapshot().auto_refines;
        let patches = stages.haptic.field().patches.len();
        eprintln!(
            "{}: {refines} automatic refines, {patches} patches in the tick",
            tool.name()
        );
        if tool.radius_fu().is_some_and(|r| 2.0 * r < 3.0 * spacing) {
            assert!(
                refines >= 1 && patches > 1,
                "{}: refined under itself ({refines}) and the tick took it ({patches} patches)",
                tool.name()
            );
        } else {
            assert_eq!((refines, patches), (0, 1), "{}", tool.name());
        }
        assert_eq!(
            allocs_in_tick(),
            before,
            "{}: haptic tick allocated",
            tool.name()
        );
    }
}

#[test]
fn a_carve_with_tool_shaped_contact_ticks_without_allocating() {
    let mut s = common::setup(common::PUSH_SCRIPT, vec![]);
    let top_y_m = common::block_top_y_m(&s.config);
    s.config.haptics.tool_contact = true;
    // The largest preset box, turned, down onto the top and pressed firmly while held: the
    // hand 5 mm deeper than the box's half height (0.1) above the top.
    let press_y_m = top_y_m + 0.1 / s.config.map.field_per_m - 0.005;
    let path = vec![
        Waypoint::with_buttons(0.0, Vec3::new(0.0, top_y_m + 0.06, 0.0), 0),
        Waypoint::with_buttons(0.3, Vec3::new(0.0, top_y_m + 0.02, 0.0), 0),
        Waypoint::with_buttons(0.5, Vec3::new(0.0, press_y_m, 0.0), 1),
        Waypoint::with_buttons(1.0, Vec3::new(0.01, press_y_m, 0.0), 1),
        Waypoint::with_buttons(1.3, Vec3::new(0.01, top_y_m + 0.06, 0.0), 0),
    ];
    let trajectory = Trajectory::new(path, Interpolation::Smooth).unwrap();
    let arm = SimulatedArm::new(SimArmConfig::default(), trajectory);
    let mut stages = build(
        &s.config,
        s.field,
        Box::new(arm),
        Box::new(HeadlessSink::default()),
        true,
    )
    .expect("stages build");
    stages
        .commands
        .send(Command::SetTool(ToolChoice::Geometric(GeometricTool {
            shape: ToolShape::Box {
                half_extents_fu: Vec3::new(0.3, 0.1, 0.2),
            },
            action: ToolAction::Remove,
            falloff_fu: 0.2,
        })))
        .unwrap();
    let before = allocs_in_tick();
    let (mut resting, mut carving) = (0, 0);
    for _ in 0..1300 {
        IN_TICK.with(|f| f.set(true));
        let out = stages.haptic.tick(Instant::now());
        IN_TICK.with(|f| f.set(false));
        if out.sample.resting_at.is_some() {
            resting += 1;
            if out.sample.stroke_active && out.sample.press > 0.0 {
                carving += 1;
            }
        }
        stages.sim.apply_commands();
        let sample = stages.samples.latest().value;
        stages.sim.step(&sample);
    }
    assert!(
        resting > 300 && carving > 100,
        "the tool rested ({resting}) and carved ({carving})"
    );
    assert_eq!(allocs_in_tick(), before, "haptic tick allocated");
}

/// Failed reads in the middle of a held stroke (a short stall the stroke is held through, and
/// a long one that ends it) take no allocation either: the fault's zero force, the held stroke
/// and its end all run in the counted ticks.
#[test]
fn failed_reads_mid_stroke_tick_without_allocating() {
    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    let top_y_m = common::block_top_y_m(&s.config);
    let path = vec![
        Waypoint::with_buttons(0.0, Vec3::new(0.0, top_y_m + 0.02, 0.0), 0),
        Waypoint::with_buttons(0.3, Vec3::new(0.0, top_y_m - 0.002, 0.0), 1),
        Waypoint::with_buttons(1.2, Vec3::new(0.01, top_y_m - 0.002, 0.0), 1),
        Waypoint::with_buttons(1.4, Vec3::new(0.01, top_y_m + 0.02, 0.0), 0),
    ];
    let trajectory = Trajectory::new(path, Interpolation::Smooth).unwrap();
    // The arm's own clock (one read per tick): 5 ms of silence at 0.5 s, 300 ms from 0.8 s.
    let arm = SimArmConfig {
        faults: vec![
            Fault::new(0.5, 0.005, FaultKind::Stall),
            Fault::new(0.8, 0.3, FaultKind::Stall),
        ],
        ..SimArmConfig::default()
    };
    let mut stages = build(
        &s.config,
        s.field,
        Box::new(SimulatedArm::new(arm, trajectory)),
        Box::new(HeadlessSink::default()),
        true,
    )
    .expect("stages build");
    let before = allocs_in_tick();
    let (mut faulted, mut held_through_fault) = (0, 0);
    for _ in 0..1500 {
        IN_TICK.with(|f| f.set(true));
        let out = stages.haptic.tick(Instant::now());
        IN_TICK.with(|f| f.set(false));
        if out.sample.device_fault {
            faulted += 1;
            held_through_fault += u32::from(out.sample.stroke_active);
        }
        stages.sim.apply_commands();
        let sample = stages.samples.latest().value;
        stages.sim.step(&sample);
    }
    assert!(
        faulted > 100 && held_through_fault > 0,
        "faulted ticks {faulted}, of them with the stroke held {held_through_fault}"
    );
    assert_eq!(allocs_in_tick(), before, "haptic tick allocated");
}

/// The haptic loop's copy of the field is sparse: a uniform brick stays one value until an
/// update's values make it dense, and then its storage comes from the pool the simulation
/// fills. An undo that changes every coefficient of a 64³ clay (back to a loaded clay whose 512
/// bricks are all dense, twice the pool) is applied in the counted ticks without allocating:
/// the tick takes what the pool holds, waits for the simulation to top it up, and ends with the
/// simulation's field. (A load itself reaches the loops as a copy of the clay, like a new
/// layout, so the undo of a load kept in the history is what publishes every coefficient.)
#[test]
fn counted_ticks_make_uniform_bricks_dense_from_the_pool_without_allocating() {
    const BLOCK_64: &str = "version = 1\n[clay]\nshape = \"block\"\nresolution = 64\n";
    let s = common::setup(BLOCK_64, vec![]);
    let mut stages = build(
        &s.config,
        s.field,
        Box::new(s.arm),
        Box::new(HeadlessSink::default()),
        true,
    )
    .expect("stages build");
    let dense = |field: &dynaclay::field::MultiPatchField| -> usize {
        field
            .patches
            .iter()
            .map(|p| p.lattice.coeffs.dense_brick_count())
            .sum()
    };
    let bricks = stages.sim.lattice().coeffs.brick_count();
    assert_eq!(bricks, 512);
    let load = |stages: &mut dynaclay::engine::Stages, clay: dynaclay::tools::Clay, keep: bool| {
        let field = clay.density.clone();
        stages
            .commands
            .send(Command::Load {
                session: Box::new(Session {
                    clay,
                    ..Session::default()
                }),
                source: "every-brick-dense.dclay".into(),
                keep_history: keep,
                reply: None,
            })
            .unwrap();
        for _ in 0..2000 {
            if *stages.haptic.field() == field {
                return;
            }
            stages.haptic.tick(Instant::now());
            stages.sim.apply_commands();
            let sample = stages.samples.latest().value;
            stages.sim.step(&sample);
        }
        panic!("the copy never took the load");
    };
    // Every coefficient moves a little: no brick of this clay is one value.
    let start = stages.sim.clay().clone();
    let mut clay = start.clone();
    clay.density.patches[0]
        .lattice
        .coeffs
        .update_each(|n, c| *c = 0.5 * *c + 0.25 + 1e-3 * (n % 7) as f32);
    let loaded = clay.density.clone();
    load(&mut stages, clay, false);
    // The starting block again, the load kept in the history: the copy is sparse again.
    load(&mut stages, start, true);
    let dense_at_start = dense(stages.haptic.field());
    assert!(
        dense_at_start < bricks / 2,
        "the copy starts sparse: {dense_at_start} of {bricks} bricks dense"
    );
    stages.commands.send(Command::Undo).unwrap();
    let before = allocs_in_tick();
    let mut ticks = 0;
    while *stages.haptic.field() != loaded {
        assert!(ticks < 2000, "the copy never took the load");
        IN_TICK.with(|f| f.set(true));
        stages.haptic.tick(Instant::now());
        IN_TICK.with(|f| f.set(false));
        stages.sim.apply_commands();
        let sample = stages.samples.latest().value;
        stages.sim.step(&sample);
        ticks += 1;
    }
    assert_eq!(allocs_in_tick(), before, "haptic tick allocated");
    assert_eq!(
        stages.sim.clay().density,
        loaded,
        "the simulation holds the load"
    );
    assert_eq!(
        dense(stages.haptic.field()),
        bricks,
        "every brick became dense in the counted ticks"
    );
    let waited = stages.counters.snapshot().haptic_updates_awaiting_bricks;
    eprintln!(
        "dense bricks in the copy: {dense_at_start} at the start, {bricks} after {ticks} ticks, \
         {waited} of them waiting for the pool"
    );
    assert!(
        bricks - dense_at_start > dynaclay::engine::HAPTIC_SPARE_BRICKS && waited > 0,
        "the load needed more bricks than one pool holds: the tick waited ({waited} ticks)"
    );
}

#[test]
fn a_pointer_stroke_ticks_without_allocating() {
    use dynaclay_devices::pointer::{PointerConfig, pointer_device};

    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    let pointer = PointerConfig::stepped(1_000);
    let mut config = dynaclay::engine::EngineConfig::for_field(&s.field, &pointer.info());
    config.haptic_rt_priority = None;
    config.safety.soft_start_s = 0.1;
    let (device, mut handle) = pointer_device(pointer);
    let mut stages = build(
        &config,
        s.field,
        Box::new(device),
        Box::new(HeadlessSink::default()),
        true,
    )
    .expect("stages build");
    // Two frames a second: hover, press in, drag along the block's top (y = 1.425), let go.
    let frames = [
        (Vec3::new(0.75, 1.6, 0.95), false),
        (Vec3::new(0.75, 1.2, 0.95), true),
        (Vec3::new(0.95, 1.2, 0.95), true),
        (Vec3::new(1.15, 1.2, 0.95), true),
        (Vec3::new(1.15, 1.2, 0.95), false),
    ];
    let before = allocs_in_tick();
    let mut contact = 0;
    for tick in 0..3_000 {
        // The app's side, outside the guard.
        if tick % 500 == 0
            && let Some(&(p, pressed)) = frames.get(tick / 500)
        {
            handle.set(config.map.to_device(p), pressed);
        }
        IN_TICK.with(|f| f.set(true));
        let out = stages.haptic.tick(Instant::now());
        IN_TICK.with(|f| f.set(false));
        if out.sample.in_contact {
            contact += 1;
        }
        stages.sim.apply_commands();
        let sample = stages.samples.latest().value;
        stages.sim.step(&sample);
    }
    assert!(
        contact > 500,
        "the stroke pushed the clay ({contact} ticks)"
    );
    assert_eq!(allocs_in_tick(), before, "haptic tick allocated");
}

/// A stroke through a Novint Falcon on its pseudo-terminal stand-in: each tick's read (the
/// keep-alive or the reply to the last command, the status frame decoded, the encoders
/// through the delta kinematics), the force's command frame, and a stray byte on the line (a
/// failed read mid-stroke, then the soft start) all run in the counted ticks.
#[test]
fn a_falcon_stroke_ticks_without_allocating() {
    use dynaclay_devices::falcon::{Falcon, FalconOptions, SampleClock};
    use dynaclay_devices::serial_link::BaudPolicy;
    use falcon_standin::{FalconFaults, falcon_board};

    let s = common::setup(common::PUSH_SCRIPT, vec![]);
    let sysfs = tempfile::tempdir().unwrap();
    // As a lockstep run drives it: every read waits for the reply to the previous command,
    // so each tick takes the path (never a stale sample) whatever the machine's load.
    let patient = std::time::Duration::from_secs(5);
    let options = FalconOptions {
        baud_policy: BaudPolicy::Tolerant,
        homing_timeout: patient,
        handshake_timeout: patient,
        reply_wait: patient,
        stale_after: patient,
        usb_serial_sysfs: sysfs.path().to_path_buf(),
        sample_clock: SampleClock::LOCKSTEP_1KHZ,
        ..FalconOptions::default()
    };
    let info = Falcon::new("unopened", options.clone()).info();
    let mut config = dynaclay::engine::EngineConfig::for_field(&s.field, &info);
    config.haptic_rt_priority = None;
    config.safety.soft_start_s = 0.1;
    let trajectory = s.plan.trajectory(&config.map).unwrap();
    // The script's hand, one position per exchange (1 ms of script time each); a stray byte
    // before the reply of exchange 700 (in the stroke, which runs from 0.1 s to 1.1 s).
    let board = falcon_board(
        Box::new(move |k| trajectory.sample(k as f64 * 1e-3).position_m),
        FalconFaults {
            stray_byte_at: Some(700),
            hang_up_at: None,
        },
    );
    let mut stages = build(
        &config,
        s.field,
        Box::new(Falcon::new(&board.path, options)),
        Box::new(HeadlessSink::default()),
        true,
    )
    .expect("stages build");
    stages.commands.send(Command::StrokeStart).unwrap();
    let before = allocs_in_tick();
    let (mut contact, mut faulted) = (0, 0);
    for _ in 0..1200 {
        IN_TICK.with(|f| f.set(true));
        let out = stages.haptic.tick(Instant::now());
        IN_TICK.with(|f| f.set(false));
        contact += u32::from(out.sample.in_contact);
        faulted += u32::from(out.sample.device_fault);
        stages.sim.apply_commands();
        let sample = stages.samples.latest().value;
        stages.sim.step(&sample);
    }
    assert_eq!(faulted, 1, "the stray byte's read failed, and only it");
    assert!(
        contact > 300,
        "the stroke pushed the clay ({contact} ticks)"
    );
    assert_eq!(allocs_in_tick(), before, "haptic tick allocated");
}
