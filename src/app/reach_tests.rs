//! The window's tool library, curve and bend, pulling outward, CSG and emboss: headless
//! frames of the app (egui_kittest) for what the panels send, and the lockstep engine for what
//! the sent commands do to the clay, measured on its exported mesh.

use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use glam::Vec3;

use dynaclay_devices::pointer::{PointerConfig, pointer_device};

use super::command::{CsgOperand, EngineCommand, EngineEvent, ForceMode};
use super::csg_panel::CsgPanel;
use super::edit_requests::edit_command;
use super::emboss_panel::{BrushFrame, EmbossPanel};
use super::force_path_panel::ForcePathPanel;
use super::library_panel::LibraryPanel;
use super::link::{EngineEndpoint, engine_link};
use super::palette::{PaletteEntry, ShapeKind, ToolPalette};
use super::pointer_tool::PointerTool;
use super::state::SculptApp;
use crate::engine::{Command, EngineConfig, HeadlessSink, Lockstep, ToolChoice, build_clay};
use crate::field::{BSplineLattice, MultiPatchField};
use crate::io::{ClaySpec, MaterialFields};
use crate::mesh::{BrickOctree, MeshFormat, SampleGrid, write_mesh};
use crate::render::{Camera, NamedView};
use crate::tools::{ForceTool, ToolAction, ToolPose, ToolShape};

/// The default block (resolution 24) spans [0.575, 1.725] on each axis; its top is y = 1.725.
const TOP: f32 = 1.725;
const LO: Vec3 = Vec3::splat(0.575);
const HI: Vec3 = Vec3::splat(1.725);

fn harness() -> (Harness<'static, SculptApp>, EngineEndpoint) {
    let (link, end) = engine_link();
    let app = SculptApp::new(link);
    let h = Harness::builder()
        .with_size(egui::vec2(1400.0, 3000.0))
        .build_ui_state(|ui, app: &mut SculptApp| app.show(ui, None), app);
    (h, end)
}

fn drain(end: &EngineEndpoint) -> Vec<EngineCommand> {
    end.commands.try_iter().collect()
}

fn block() -> BSplineLattice {
    build_clay(&ClaySpec::default()).unwrap()
}

/// A lockstep engine on `field` with the pointer as its device, plastic clay.
fn engine_on(
    field: BSplineLattice,
) -> (
    Lockstep,
    dynaclay_devices::pointer::PointerHandle,
    EngineConfig,
) {
    // A clock stepped a millisecond per read: the pointer plays its samples on the engine's
    // time, so the run is deterministic.
    let pointer = PointerConfig::stepped(1_000);
    let mut config = EngineConfig::for_field(&field, &pointer.info());
    config.haptic_rt_priority = None;
    config.safety.soft_start_s = 0.05;
    config.sim.material = MaterialFields::default().uniform;
    let (device, handle) = pointer_device(pointer);
    let engine = Lockstep::new(
        &config,
        field,
        Box::new(device),
        Box::new(HeadlessSink::default()),
        64,
    )
    .unwrap();
    (engine, handle, config)
}

/// `field`'s mesh written as OBJ and read back: its vertex positions.
fn exported_vertices(field: &BSplineLattice, name: &str) -> Vec<Vec3> {
    let dir = tempfile::tempdir().unwrap();
    let mut octree = BrickOctree::new(SampleGrid::for_lattice(field, 4).unwrap());
    octree.rebuild(field);
    let path = dir.path().join(name);
    write_mesh(&path, &octree.weld(), MeshFormat::Obj).unwrap();
    std::fs::read_to_string(&path)
        .unwrap()
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let v: Vec<f32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            Vec3::new(v[0], v[1], v[2])
        })
        .collect()
}

/// Highest vertex within `r` of the vertical line through (x, z).
fn top_at(vertices: &[Vec3], x: f32, z: f32, r: f32) -> f32 {
    vertices
        .iter()
        .filter(|v| (v.x - x).hypot(v.z - z) < r)
        .map(|v| v.y)
        .fold(f32::NEG_INFINITY, f32::max)
}

/// Looking down on the block from far enough that its top fits the harness's tall, narrow
/// view across as well as up and down (the named view frames the height only).
fn top_camera() -> Camera {
    let mut camera = Camera::named(NamedView::Top, LO, HI);
    camera.distance *= 3.0;
    camera
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

fn click_at(h: &mut Harness<'static, SculptApp>, p: egui::Pos2) {
    h.hover_at(p);
    h.run();
    h.drag_at(p);
    h.run();
    h.drop_at(p);
    h.run();
}

#[test]
fn a_tool_made_from_the_selection_is_stored_and_held_as_the_freeform_shape() {
    let (mut h, mut end) = harness();
    end.field.publish_clone_of(&MultiPatchField::new(block()));
    h.run();
    drain(&end);
    h.get_by_label("Tool library").click();
    h.run();
    // No brush point yet: the button is disabled.
    h.get_by_label("Make tool from selection").click();
    h.run();
    assert!(drain(&end).is_empty());
    let at = Vec3::new(1.15, TOP, 1.15);
    h.state_mut().refine_at = Some(at);
    h.state_mut().camera = Camera::named(NamedView::Front, LO, HI);
    h.run();
    h.get_by_label("Make tool from selection").click();
    h.run();
    let sent = drain(&end);
    let [
        EngineCommand::AddTool(preset),
        EngineCommand::SelectTool(ToolChoice::Geometric(tool)),
    ] = sent.as_slice()
    else {
        panic!("expected the library entry then the tool, got {sent:?}");
    };
    assert_eq!(preset.name, "tool 1");
    assert!(matches!(preset.shape, ToolShape::Freeform(_)));
    assert_eq!(tool.shape, preset.shape);
    assert!(matches!(tool.action, ToolAction::Stamp(_)));
    assert_eq!(h.state().palette.shape, ShapeKind::Freeform);
    // The selection box is drawn over the view: its twelve edges.
    let rect = h.state().viewport_rect.unwrap();
    assert_eq!(h.state_mut().sculpt_marks_on_screen(rect).len(), 12);
    h.get_by_label("Use tool 1");
    // A loaded session's library replaces the window's; without the tool, back to a sphere.
    end.events.send(EngineEvent::Library(Vec::new())).unwrap();
    h.run();
    assert_eq!(h.state().palette.shape, ShapeKind::Sphere);
    assert!(h.state().library.tools.is_empty());
}

#[test]
fn curve_points_and_the_pivot_are_clicked_on_the_clay_and_sent_with_the_tool() {
    let (mut h, mut end) = harness();
    let field = MultiPatchField::new(block());
    end.field.publish_clone_of(&field);
    h.run();
    h.state_mut().camera = top_camera();
    h.get_by_label("Curve and pivot").click();
    h.run();
    h.get_by_label("Click curve points").click();
    h.run();
    assert_eq!(
        h.state().palette.selected,
        PaletteEntry::Force(ForceMode::Curve)
    );
    drain(&end);
    let (a, b) = (Vec3::new(0.9, TOP, 1.1), Vec3::new(1.4, TOP, 1.2));
    let camera = h.state().camera;
    let (pa, pb) = (screen_of(&h, a), screen_of(&h, b));
    click_at(&mut h, pa);
    click_at(&mut h, pb);
    assert_eq!(h.state().camera, camera, "picking does not orbit");
    let sent = drain(&end);
    let Some(EngineCommand::SelectTool(ToolChoice::Force {
        tool: ForceTool::Curve { .. },
        curve,
        ..
    })) = sent.last()
    else {
        panic!("expected the curve tool, got {sent:?}");
    };
    assert_eq!(curve.len(), 2);
    assert!((curve[0] - a).length() < 0.02 && (curve[1] - b).length() < 0.02);
    // The curve is drawn while the curve tool is in hand.
    let rect = h.state().viewport_rect.unwrap();
    assert!(!h.state_mut().sculpt_marks_on_screen(rect).is_empty());
    h.get_by_label("Click curve points").click();
    h.run();
    h.get_by_label("Click the pivot").click();
    h.run();
    let p = Vec3::new(0.8, TOP, 1.15);
    let pp = screen_of(&h, p);
    click_at(&mut h, pp);
    assert!(!h.state().force_path.picking(), "one click sets the pivot");
    let sent = drain(&end);
    let Some(EngineCommand::SelectTool(ToolChoice::Force {
        tool: ForceTool::Bend { .. },
        pivot,
        ..
    })) = sent.last()
    else {
        panic!("expected the bend tool, got {sent:?}");
    };
    assert!((*pivot - p).length() < 0.02, "pivot {pivot}");
}

#[test]
fn the_csg_panel_applies_a_solid_at_the_brush_and_asks_before_an_intersection() {
    let (mut h, end) = harness();
    h.run();
    h.get_by_label("CSG").click();
    h.run();
    drain(&end);
    let at = Vec3::new(1.15, TOP, 1.15);
    h.state_mut().refine_at = Some(at);
    h.run();
    h.get_by_label("Apply CSG").click();
    h.run();
    let sent = drain(&end);
    let [
        EngineCommand::Csg {
            op: ToolAction::Difference,
            operand: CsgOperand::Solid { pose, .. },
        },
    ] = sent.as_slice()
    else {
        panic!("expected a difference with a solid, got {sent:?}");
    };
    assert_eq!(pose.position_fu, at);
    h.get_by_label("Intersect with operand").click();
    h.run();
    h.get_by_label("Apply CSG").click();
    h.run();
    assert!(drain(&end).is_empty(), "an intersection asks first");
    h.get_by_label("Confirm: keep only the clay inside").click();
    h.run();
    let sent = drain(&end);
    assert!(
        matches!(
            sent.as_slice(),
            [EngineCommand::Csg {
                op: ToolAction::Intersection,
                ..
            }]
        ),
        "{sent:?}"
    );
    h.get_by_label("a session file").click();
    h.run();
    h.get_by_label("Union with operand").click();
    h.run();
    h.get_by_label("Apply CSG").click();
    h.run();
    assert_eq!(
        drain(&end),
        vec![EngineCommand::Csg {
            op: ToolAction::Union,
            operand: CsgOperand::Session("other.dclay".into()),
        }]
    );
}

#[test]
fn the_emboss_panel_sends_the_image_with_a_projection_at_the_brush() {
    let (mut h, mut end) = harness();
    end.field.publish_clone_of(&MultiPatchField::new(block()));
    h.run();
    h.get_by_label("Emboss").click();
    h.run();
    drain(&end);
    let at = Vec3::new(1.15, TOP, 1.15);
    h.state_mut().refine_at = Some(at);
    h.state_mut().brush_normal = Some(Vec3::Y);
    h.run();
    h.get_by_label("Emboss at the brush point").click();
    h.run();
    let sent = drain(&end);
    let [EngineCommand::Emboss { image, params }] = sent.as_slice() else {
        panic!("expected an emboss, got {sent:?}");
    };
    assert_eq!(image, &std::path::PathBuf::from("logo.png"));
    assert!(!params.engrave);
    assert!(matches!(
        params.projection,
        crate::tools::Projection::Planar { centre, axis, .. } if centre == at && axis == Vec3::Y
    ));
}

/// Runs `engine` `ticks` steps with the pointer at `tip`, pressed or not.
fn hold(
    engine: &mut Lockstep,
    handle: &mut dynaclay_devices::pointer::PointerHandle,
    config: &EngineConfig,
    tip: Vec3,
    pressed: bool,
    ticks: usize,
) {
    for _ in 0..ticks {
        handle.set(config.map.to_device(tip), pressed);
        engine.step();
    }
}

#[test]
fn a_negative_press_depth_pulls_the_clay_out_to_the_tip() {
    let start = block();
    let (mut engine, handle, config) = engine_on(start.clone());
    let (link, mut end) = engine_link();
    let mut app = SculptApp::new(link);
    app.pointer = PointerTool::new(handle, config.map);
    let mut h = Harness::builder()
        .with_size(egui::vec2(1400.0, 1000.0))
        .build_ui_state(|ui, app: &mut SculptApp| app.show(ui, None), app);
    end.field.publish_clone_of(engine.density());
    h.run();
    h.state_mut().camera = top_camera();
    // 1.5 knot spans above the surface: the point grab becomes a pull.
    h.state_mut().pointer.depth_spans = -1.5;
    let commands = engine.commands();
    let mut frame = |h: &mut Harness<'static, SculptApp>, engine: &mut Lockstep| {
        h.step();
        for c in drain(&end) {
            if let EngineCommand::SelectTool(choice) = c {
                commands.send(Command::SetTool(choice)).unwrap();
            }
        }
        for _ in 0..20 {
            engine.step();
        }
        end.field.publish_clone_of(engine.density());
    };
    let at = Vec3::new(1.15, TOP, 1.15);
    let p = screen_of(&h, at);
    h.hover_at(p);
    frame(&mut h, &mut engine);
    assert!(matches!(
        engine.sim().tool(),
        ToolChoice::Force {
            tool: ForceTool::Pull { .. },
            ..
        }
    ));
    h.drag_at(p);
    for _ in 0..100 {
        h.hover_at(p);
        frame(&mut h, &mut engine);
    }
    let tip = h.state().pointer.last_sample().unwrap();
    assert!(tip.pressed);
    h.drop_at(p);
    for _ in 0..20 {
        frame(&mut h, &mut engine);
    }
    let before = exported_vertices(&start, "before.obj");
    let after = exported_vertices(engine.field(), "after.obj");
    let target = 1.5 * 0.1;
    let rise = top_at(&after, at.x, at.z, 0.03) - top_at(&before, at.x, at.z, 0.03);
    eprintln!("pulled out: {rise:.4} of {target} asked");
    assert!(
        rise > 0.5 * target && rise < 1.1 * target,
        "the top rose by {rise}, the tip was {target} above it"
    );
    // Far from the pointer the top stays.
    let far = top_at(&after, 0.7, 0.7, 0.03) - top_at(&before, 0.7, 0.7, 0.03);
    assert!(far.abs() < 0.01, "far from the pull: {far}");
}

#[test]
fn a_csg_difference_from_the_panel_leaves_a_spherical_cavity_of_its_radius() {
    let start = block();
    let centre = Vec3::new(1.15, TOP, 1.15);
    let radius = 0.3;
    for operand in ["solid", "session"] {
        let (mut engine, mut handle, config) = engine_on(start.clone());
        let mut panel = CsgPanel::default();
        panel.size_fu = radius;
        let dir = tempfile::tempdir().unwrap();
        if operand == "session" {
            // The other clay: a ball of the same radius on the same lattice, saved as a session.
            let ball = crate::field::lattice_from_primitive(
                start.dims,
                start.spacing,
                start.origin,
                &crate::field::Primitive::Sphere { centre, radius },
                2.0 * start.spacing,
                2,
            )
            .unwrap();
            let path = dir.path().join("ball.dclay");
            let session = crate::io::Session {
                clay: crate::tools::Clay::single(ball),
                ..crate::io::Session::default()
            };
            crate::io::save_session(&path, &session).unwrap();
            panel.operand = super::csg_panel::OperandKind::Session;
            panel.session_path = path.display().to_string();
        }
        let request = panel.command(Some(centre)).unwrap();
        let (cmd, answer) = edit_command(request).unwrap().unwrap();
        engine.commands().send(cmd).unwrap();
        hold(
            &mut engine,
            &mut handle,
            &config,
            Vec3::splat(3.0),
            false,
            20,
        );
        answer.try_answer().unwrap().unwrap();
        let after = exported_vertices(engine.field(), "csg.obj");
        // The cavity's wall: vertices below the top face near the centre.
        // (the block's bottom face lies 1.15 below: nearer than 0.45 is the cavity's)
        let wall: Vec<f32> = after
            .iter()
            .filter(|v| v.y < TOP - 0.05 && v.distance(centre) < radius + 0.15)
            .map(|v| v.distance(centre))
            .collect();
        assert!(wall.len() > 50, "{} wall vertices", wall.len());
        let mean = wall.iter().sum::<f32>() / wall.len() as f32;
        let worst = wall
            .iter()
            .map(|d| (d - radius).abs())
            .fold(0.0f32, f32::max);
        // The rim: how far the mesh strays from the sharp CSG surface (flat top minus ball)
        // within a knot span of the rim circle.
        let rim = after
            .iter()
            .filter(|v| {
                let r = (v.x - centre.x).hypot(v.z - centre.z);
                (r - radius).abs() < 0.1 && (v.y - TOP).abs() < 0.1
            })
            .map(|v| {
                let exact = (v.y - TOP).max(radius - v.distance(centre));
                exact.abs()
            })
            .fold(0.0f32, f32::max);
        eprintln!(
            "csg difference with a {operand}: cavity radius {mean:.4} (asked {radius}), worst \
             wall error {worst:.4}, rim off the sharp edge by up to {rim:.4}"
        );
        assert!(
            (mean - radius).abs() < 0.05 * radius,
            "{operand}: mean radius {mean}"
        );
        assert!(worst < 0.1 * radius, "{operand}: worst {worst}");
        // Undo takes it back.
        engine.commands().send(Command::Undo).unwrap();
        hold(
            &mut engine,
            &mut handle,
            &config,
            Vec3::splat(3.0),
            false,
            5,
        );
        assert_eq!(engine.field().coeffs, start.coeffs, "{operand}: undone");
    }
}

/// A 16 × 16 PNG, white on the left half (x < 8), black on the right.
fn half_white_png(path: &std::path::Path) {
    let mut png = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut png, 16, 16);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().unwrap();
        let pixels: Vec<u8> = (0..256).map(|i| if i % 16 < 8 { 255 } else { 0 }).collect();
        w.write_image_data(&pixels).unwrap();
    }
    std::fs::write(path, png).unwrap();
}

#[test]
fn an_image_embossed_from_the_panel_raises_its_white_half_by_the_depth() {
    let start = block();
    let (mut engine, mut handle, config) = engine_on(start.clone());
    let dir = tempfile::tempdir().unwrap();
    let image = dir.path().join("half.png");
    half_white_png(&image);
    let depth = 0.06;
    let panel = EmbossPanel {
        image: image.display().to_string(),
        size_fu: 0.8,
        depth_fu: depth,
        ..EmbossPanel::default()
    };
    let at = Vec3::new(1.15, TOP, 1.15);
    let params = panel.params(
        BrushFrame {
            at,
            normal: Vec3::Y,
            view_up: -Vec3::Z,
        },
        crate::engine::clay_centre(&start),
    );
    let request = EngineCommand::Emboss {
        image: image.clone(),
        params,
    };
    let (cmd, answer) = edit_command(request).unwrap().unwrap();
    engine.commands().send(cmd).unwrap();
    hold(
        &mut engine,
        &mut handle,
        &config,
        Vec3::splat(3.0),
        false,
        20,
    );
    answer.try_answer().unwrap().unwrap();
    let before = exported_vertices(&start, "before.obj");
    let after = exported_vertices(engine.field(), "after.obj");
    let rise = |x: f32| top_at(&after, x, at.z, 0.03) - top_at(&before, x, at.z, 0.03);
    // The image is 0.8 wide about x = 1.15: one half covers x in [0.75, 1.15], the other
    // [1.15, 1.55]; which is white depends on the projection's frame, so take the higher.
    let (left, right) = (rise(0.95), rise(1.35));
    let (white, black) = if left > right {
        (left, right)
    } else {
        (right, left)
    };
    eprintln!("embossed {depth}: white half rose {white:.4}, black half {black:.4}");
    assert!(
        (white - depth).abs() < 0.15 * depth,
        "white rose {white} for {depth}"
    );
    assert!(black.abs() < 0.15 * depth, "black moved {black}");
}

#[test]
fn the_windows_curve_and_bend_move_the_clay_by_the_cursors_displacement() {
    let lift = 0.1;
    for mode in [ForceMode::Curve, ForceMode::Bend] {
        let start = block();
        let (mut engine, mut handle, config) = engine_on(start.clone());
        let mut palette = ToolPalette {
            selected: PaletteEntry::Force(mode),
            ..ToolPalette::default()
        };
        palette.force.radius_fu = 0.1;
        let z = 1.15;
        // The curve: a stroke's path along the top, as the window records it.
        let mut path = ForcePathPanel::default();
        for i in 0..=60 {
            path.record(Vec3::new(0.85 + 0.01 * i as f32, TOP, z), 0.1);
        }
        path.end_recording();
        palette.curve_fu.clone_from(&path.last_stroke);
        // The pivot: a click at the path's left end.
        let pivot = Vec3::new(0.85, TOP, z);
        palette.pivot_fu = Some(pivot);
        engine
            .commands()
            .send(Command::SetTool(palette.choice()))
            .unwrap();
        let probe = Vec3::new(1.15, TOP + 0.05, z);
        let probe_before = engine.field().value(probe);
        // Where the stroke takes hold: the curve's middle, or the bend's far end.
        let grab = match mode {
            ForceMode::Curve => Vec3::new(1.15, TOP, z),
            _ => Vec3::new(1.35, TOP, z),
        };
        hold(
            &mut engine,
            &mut handle,
            &config,
            grab + Vec3::Y * 0.3,
            false,
            100,
        );
        hold(&mut engine, &mut handle, &config, grab, false, 100);
        hold(&mut engine, &mut handle, &config, grab, true, 20);
        for k in 1..=200 {
            let tip = grab + Vec3::Y * lift * k as f32 / 200.0;
            hold(&mut engine, &mut handle, &config, tip, true, 1);
        }
        hold(
            &mut engine,
            &mut handle,
            &config,
            grab + Vec3::Y * lift,
            true,
            2000,
        );
        hold(
            &mut engine,
            &mut handle,
            &config,
            grab + Vec3::Y * 0.3,
            false,
            300,
        );
        eprintln!(
            "{mode:?}: the field 0.05 above the top went {probe_before} → {}; tool {:?}",
            engine.field().value(probe),
            engine.sim().tool().name()
        );
        let before = exported_vertices(&start, "before.obj");
        let after = exported_vertices(engine.field(), "after.obj");
        let rise = |x: f32, z: f32| top_at(&after, x, z, 0.03) - top_at(&before, x, z, 0.03);
        let away = rise(1.15, z + 0.4);
        match mode {
            ForceMode::Curve => {
                let rises = [rise(0.95, z), rise(1.15, z), rise(1.35, z)];
                eprintln!("curve lifted {lift}: the curve rose {rises:?}, 0.4 away {away:.4}");
                for r in rises {
                    assert!(
                        r > 0.6 * lift && r < 1.15 * lift,
                        "curve rose {rises:?} for a lift of {lift}"
                    );
                }
            }
            _ => {
                // The arm turns about the pivot: the rise grows with the distance from it.
                let (near, mid, end) = (rise(0.95, z), rise(1.1, z), rise(1.35, z));
                eprintln!(
                    "bend lifted {lift} at 0.5 from the pivot: rose {near:.4} at 0.1, {mid:.4} \
                     at 0.25, {end:.4} at 0.5; 0.4 away {away:.4}"
                );
                assert!(near < mid && mid < end, "{near} {mid} {end}");
                assert!(
                    end > 0.6 * lift && end < 1.15 * lift,
                    "the bend's end rose {end} for {lift}"
                );
                assert!(
                    (mid / end - 0.5).abs() < 0.2,
                    "half way along the arm: {mid} of {end}"
                );
            }
        }
        assert!(away.abs() < 0.25 * lift, "0.4 from the curve: {away}");
    }
}

#[test]
fn a_tool_made_in_the_window_reproduces_its_bump_elsewhere_and_is_kept_in_the_session() {
    // A bump on the top face at `a`, made with a union of a ball.
    let mut clay = crate::tools::Clay::single(block());
    let a = Vec3::new(0.95, TOP, 0.95);
    let bump = crate::tools::GeometricTool {
        shape: ToolShape::Sphere { radius_fu: 0.15 },
        action: ToolAction::Union,
        falloff_fu: 0.05,
    };
    crate::tools::apply_tool(
        &mut clay,
        &bump,
        &ToolPose::at(a),
        0.0,
        &crate::tools::ApplyOptions::default(),
        None,
    )
    .unwrap();
    let sculpt = clay.density.patches[0].lattice.clone();
    let (mut engine, mut handle, config) = engine_on(sculpt.clone());
    // The brush at the bump's top: the selection box (half size 0.25) around it.
    let mut panel = LibraryPanel::default();
    panel.half_fu = 0.25;
    let mut palette = ToolPalette {
        selected: PaletteEntry::Geometric(super::palette::ActionKind::Union),
        ..ToolPalette::default()
    };
    let brush = a + Vec3::Y * 0.1;
    let add = panel
        .make_tool(engine.density(), brush, &mut palette)
        .unwrap();
    let EngineCommand::AddTool(preset) = add else {
        panic!("expected AddTool");
    };
    let (tx, rx) = crossbeam::channel::bounded(1);
    engine
        .commands()
        .send(Command::AddTool {
            preset: preset.clone(),
            reply: Some(tx),
        })
        .unwrap();
    // The palette's tool (union with the captured shape) applied with its centre 0.4 across.
    let ToolChoice::Geometric(tool) = palette.choice() else {
        panic!("expected a geometric tool");
    };
    // Four knot spans across, on the flat top (the captured flat slab under the bump would
    // square off a rounded edge of the block).
    let offset = Vec3::new(0.4, 0.0, 0.4);
    engine
        .commands()
        .send(Command::ApplyTool {
            tool,
            poses: vec![ToolPose::at(brush + offset)],
            duration_s: 0.0,
            patch: 0,
            reply: None,
        })
        .unwrap();
    hold(
        &mut engine,
        &mut handle,
        &config,
        Vec3::splat(3.0),
        false,
        20,
    );
    assert!(rx.try_recv().unwrap().unwrap().contains("\"tool 1\" added"));
    let after = exported_vertices(engine.field(), "copied.obj");
    let height = top_at(&after, a.x, a.z, 0.03) - TOP;
    // The copy's peak against the source's, and the flat top a bump's reach beyond it
    // untouched (the surfaces are compared whole in `tests/script_reach.rs`).
    let copy = top_at(&after, a.x + offset.x, a.z + offset.z, 0.03) - TOP;
    let beyond = [(0.25, 0.0), (0.0, 0.25), (-0.25, 0.0), (0.0, -0.25)]
        .map(|(dx, dz)| {
            (top_at(&after, a.x + offset.x + dx, a.z + offset.z + dz, 0.03) - TOP).abs()
        })
        .into_iter()
        .fold(0.0f32, f32::max);
    eprintln!("bump {height:.4} high copied: {copy:.4} high, the top beside it moved {beyond:.4}");
    assert!(height > 0.1, "the source bump is {height} high");
    assert!(
        (copy - height).abs() < 0.05 * height,
        "copy {copy} of {height}"
    );
    assert!(beyond < 0.005, "the top beside the copy moved {beyond}");
    let report = engine.finish().unwrap();
    assert_eq!(report.session.tools.len(), 1);
    assert_eq!(report.session.tools[0], *preset);
}
