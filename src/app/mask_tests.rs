//! The Mask tool in the window (egui_kittest, no display, no GPU) driving the lockstep engine:
//! a mask painted by dragging over the clay holds it under a later Remove stroke while the
//! clay beside it is carved, and Invert and Clear turn the engine's mask over and empty it.
//! The pointer device plays on the engine's stepped clock: no wall time.

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use glam::Vec3;

use dynaclay_devices::pointer::{PointerConfig, PointerHandle, pointer_device};

use super::command::EngineCommand;
use super::link::{EngineEndpoint, engine_link};
use super::pointer_tool::PointerTool;
use super::state::SculptApp;
use crate::engine::{Command, EngineConfig, HeadlessSink, Lockstep, build_clay};
use crate::field::MultiPatchField;
use crate::io::{ClaySpec, MaterialFields};
use crate::mesh::{BrickOctree, SampleGrid};
use crate::render::{Camera, NamedView};
use crate::tools::FreezeMask;

/// The default block spans [0.575, 1.725] on each axis; its top is y = 1.725.
const TOP: f32 = 1.725;
/// Where the mask is painted, and where the stroke also passes without the mask.
const MASKED: Vec3 = Vec3::new(0.85, TOP, 1.15);
const FREE: Vec3 = Vec3::new(1.5, TOP, 1.15);

/// The app with the pointer feeding a lockstep engine on the default block (plastic clay),
/// looking down on the block's top.
fn app_and_engine() -> (Harness<'static, SculptApp>, EngineEndpoint, Lockstep) {
    let field = build_clay(&ClaySpec::default()).unwrap();
    let pointer = PointerConfig::stepped(1_000);
    let mut config = EngineConfig::for_field(&field, &pointer.info());
    config.haptic_rt_priority = None;
    config.safety.soft_start_s = 0.05;
    config.sim.material = MaterialFields::default().uniform;
    let (device, handle): (_, PointerHandle) = pointer_device(pointer);
    let engine = Lockstep::new(
        &config,
        field,
        Box::new(device),
        Box::new(HeadlessSink::default()),
        64,
    )
    .unwrap();
    let (link, mut end) = engine_link();
    let mut app = SculptApp::new(link);
    app.pointer = PointerTool::new(handle, config.map);
    let mut h = Harness::builder()
        .with_size(egui::vec2(1400.0, 1000.0))
        .build_ui_state(|ui, app: &mut SculptApp| app.show(ui, None), app);
    end.field.publish_clone_of(engine.density());
    h.run();
    let mut camera = Camera::named(NamedView::Top, Vec3::splat(0.575), Vec3::splat(1.725));
    camera.distance *= 1.5;
    h.state_mut().camera = camera;
    h.run();
    (h, end, engine)
}

/// One frame: the app's commands go to the engine as the bridge sends them, the engine runs
/// 20 steps, and the app sees the clay it left.
fn frame(h: &mut Harness<'static, SculptApp>, end: &mut EngineEndpoint, engine: &mut Lockstep) {
    h.step();
    let commands = engine.commands();
    for c in end.commands.try_iter() {
        let sent = match c {
            EngineCommand::SelectTool(choice) => Command::SetTool(choice),
            EngineCommand::Mask(edit) => Command::Mask { edit, reply: None },
            _ => continue,
        };
        commands.send(sent).unwrap();
    }
    for _ in 0..20 {
        engine.step();
    }
    end.field.publish_clone_of(engine.density());
}

/// Screen point of a world point in the harness's view.
fn screen_of(h: &Harness<'static, SculptApp>, x: Vec3) -> egui::Pos2 {
    let rect = h.state().viewport_rect.expect("the view was laid out");
    let c = h
        .state()
        .camera
        .view_projection(rect.width() / rect.height())
        .project_point3(x);
    egui::pos2(
        rect.min.x + (c.x + 1.0) * 0.5 * rect.width(),
        rect.min.y + (1.0 - c.y) * 0.5 * rect.height(),
    )
}

/// A left drag from `from` to `to` (world points on the top) in `steps` frames, then the
/// release and a few frames for the clay to settle.
fn drag(
    h: &mut Harness<'static, SculptApp>,
    end: &mut EngineEndpoint,
    engine: &mut Lockstep,
    from: Vec3,
    to: Vec3,
    steps: usize,
) {
    let start = screen_of(h, from);
    h.hover_at(start);
    frame(h, end, engine);
    h.drag_at(start);
    frame(h, end, engine);
    for i in 1..=steps {
        let p = screen_of(h, from.lerp(to, i as f32 / steps as f32));
        h.hover_at(p);
        frame(h, end, engine);
    }
    h.drop_at(screen_of(h, to));
    for _ in 0..20 {
        frame(h, end, engine);
    }
}

/// The highest meshed vertex of the clay (every patch) within 0.03 of `at` across the top.
fn top_at(field: &MultiPatchField, at: Vec3) -> f32 {
    let mut octree = BrickOctree::new(SampleGrid::for_field(field, 4).unwrap());
    octree.rebuild(field);
    octree
        .bricks()
        .flat_map(|b| b.mesh.positions.iter().copied())
        .filter(|v| (v.x - at.x).hypot(v.z - at.z) < 0.03)
        .map(|v| v.y)
        .fold(f32::NEG_INFINITY, f32::max)
}

/// The engine's mask (made by the first mask edit).
fn engine_mask(engine: &Lockstep) -> FreezeMask {
    engine.sim().clay().mask.clone().expect("a mask was made")
}

/// Paints the mask around `MASKED` with a brush of radius 0.6 through the Mask tool: a short
/// drag on the clay, as a user masks a spot.
fn mask_a_spot(
    h: &mut Harness<'static, SculptApp>,
    end: &mut EngineEndpoint,
    engine: &mut Lockstep,
) {
    h.state_mut().palette.radius_fu = 0.6;
    // The Mask section starts closed (the panels below it keep their places).
    h.get_by_label("Mask").click();
    frame(h, end, engine);
    h.get_by_label("Paint mask with the brush").click();
    frame(h, end, engine);
    assert!(h.state().mask.active);
    drag(
        h,
        end,
        engine,
        MASKED - Vec3::X * 0.02,
        MASKED + Vec3::X * 0.02,
        3,
    );
    h.get_by_label("Paint mask with the brush").click();
    frame(h, end, engine);
    assert!(!h.state().mask.active);
}

#[test]
fn a_mask_painted_with_the_pointer_holds_the_clay_under_a_later_stroke() {
    let (mut h, mut end, mut engine) = app_and_engine();
    let start = engine.density().clone();
    mask_a_spot(&mut h, &mut end, &mut engine);
    let mask = engine_mask(&engine);
    assert!(
        mask.value_at(MASKED) > 0.9,
        "masked: {}",
        mask.value_at(MASKED)
    );
    assert_eq!(mask.value_at(FREE), 0.0);
    // Painting the mask moved no clay.
    assert_eq!(engine.density(), &start);

    // A Remove stroke of a ball two and a half knot spans wide (no detail patch) across both
    // points, its centre half a knot span (0.05) under the top: it cuts 0.3 deep.
    h.state_mut().palette.radius_fu = 0.25;
    h.state_mut().palette.falloff_fu = 0.05;
    h.state_mut().pointer.depth_spans = 0.5;
    h.get_by_label("Remove").click();
    frame(&mut h, &mut end, &mut engine);
    drag(&mut h, &mut end, &mut engine, MASKED, FREE, 25);
    let after = engine.density().clone();
    assert_eq!(after.patches.len(), 1, "the stroke is made on the base");
    let held = top_at(&after, MASKED) - top_at(&start, MASKED);
    let carved = top_at(&start, FREE) - top_at(&after, FREE);
    eprintln!("under the mask the top moved {held:.4}; beside it the stroke carved {carved:.4}");
    assert!(
        carved > 0.1,
        "the free clay is carved 0.3 deep by the ball: {carved}"
    );
    assert!(held.abs() < 0.005, "the masked clay stays: {held}");
}

#[test]
fn invert_and_clear_turn_the_engines_mask_over_and_empty_it() {
    let (mut h, mut end, mut engine) = app_and_engine();
    mask_a_spot(&mut h, &mut end, &mut engine);
    let painted = engine_mask(&engine);
    h.get_by_label("Invert mask").click();
    frame(&mut h, &mut end, &mut engine);
    let inverted = engine_mask(&engine);
    for (patch, (a, b)) in painted.patches.iter().zip(&inverted.patches).enumerate() {
        for (i, (&m, &n)) in a.coeffs.iter().zip(&b.coeffs).enumerate() {
            assert!(
                (m + n - 1.0).abs() < 1e-6,
                "patch {patch} coefficient {i}: {m} inverted to {n}"
            );
        }
    }
    assert!(inverted.value_at(MASKED) < 0.1);
    assert!(inverted.value_at(FREE) > 0.99);
    h.get_by_label("Clear mask").click();
    frame(&mut h, &mut end, &mut engine);
    let cleared = engine_mask(&engine);
    assert!(!cleared.any(), "nothing is held after Clear");
    // Each is one undo step: undo brings the inverted mask back.
    engine.commands().send(Command::Undo).unwrap();
    frame(&mut h, &mut end, &mut engine);
    assert_eq!(engine_mask(&engine), inverted);
}
