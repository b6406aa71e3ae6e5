//! Stroke smoothing in the window (egui_kittest, no display, no GPU): a zig-zag mouse drag over
//! the clay reaches the pointer device as a straighter path, and the pressed path still ends
//! where the button was let go. The device's clock is stepped per read: no wall time.

use dynaclay_devices::device::HapticDevice;
use dynaclay_devices::pointer::{PRESS_BUTTON, PointerConfig, PointerDevice, pointer_device};
use egui_kittest::Harness;
use glam::Vec3;

use super::link::engine_link;
use super::pointer_tool::PointerTool;
use super::state::SculptApp;
use crate::engine::{EngineConfig, WorkspaceMap, build_clay};
use crate::io::ClaySpec;
use crate::render::{Camera, NamedView};

/// The pressed tips (field coordinates) the device plays back for a zig-zag drag along
/// z = 1.15 on the default block's top, ±12 screen points across it, with `strength`; and
/// the clay point under the pointer where the button was let go.
fn zig_zag_drag(strength: f32) -> (Vec<Vec3>, Vec3) {
    let field = build_clay(&ClaySpec::default()).unwrap();
    let pointer = PointerConfig::stepped(1_000);
    let config = EngineConfig::for_field(&field, &pointer.info());
    let map: WorkspaceMap = config.map;
    let (mut device, handle): (PointerDevice, _) = pointer_device(pointer);
    device.open().unwrap();

    let (link, mut end) = engine_link();
    let mut app = SculptApp::new(link);
    app.pointer = PointerTool::new(handle, map);
    app.stroke_smoothing.strength = strength;
    let mut h = Harness::builder()
        .with_size(egui::vec2(1400.0, 1000.0))
        .build_ui_state(|ui, app: &mut SculptApp| app.show(ui, None), app);
    end.field.publish_clone_of(&field.clone().into());
    h.run();
    // Looking down on the block's top face (y = 1.725; the block spans 0.575..1.725).
    let (lo, hi) = (Vec3::splat(0.575), Vec3::splat(1.725));
    h.state_mut().camera = Camera::named(NamedView::Top, lo, hi);
    h.run();
    let rect = h.state().viewport_rect.expect("the view was laid out");
    let camera = h.state().camera;
    let to_screen = |x: Vec3| {
        let c = camera
            .view_projection(rect.width() / rect.height())
            .project_point3(x);
        egui::pos2(
            rect.min.x + (c.x + 1.0) * 0.5 * rect.width(),
            rect.min.y + (1.0 - c.y) * 0.5 * rect.height(),
        )
    };
    let (from, to) = (Vec3::new(0.9, 1.725, 1.15), Vec3::new(1.4, 1.725, 1.15));
    let (start, finish) = (to_screen(from), to_screen(to));
    // Across the line on screen, unit length.
    let along = (finish - start).normalized();
    let across = egui::vec2(-along.y, along.x);
    // The device plays the path back between frames, as the haptic loop reads it.
    let mut pressed = Vec::new();
    let mut play = |device: &mut PointerDevice, reads: usize| {
        for _ in 0..reads {
            let state = device.read().unwrap();
            if state.buttons & (1 << PRESS_BUTTON) != 0 {
                pressed.push(map.to_field(state.position_m));
            }
        }
    };
    h.hover_at(start);
    h.step();
    h.drag_at(start);
    h.step();
    play(&mut device, 5);
    let steps = 40;
    for i in 1..=steps {
        let side = if i % 2 == 0 { 12.0 } else { -12.0 };
        let on_line = start + (finish - start) * (i as f32 / steps as f32);
        let jitter = if i == steps { 0.0 } else { side };
        h.hover_at(on_line + across * jitter);
        h.step();
        play(&mut device, 5);
    }
    h.drop_at(finish);
    h.step();
    play(&mut device, 500);
    let released_over = h
        .state()
        .pointer
        .pose
        .expect("the pointer is aimed")
        .surface;
    (pressed, released_over)
}

/// Largest distance of the pressed tips from the drawn line (z = 1.15), field units.
fn deviation(tips: &[Vec3]) -> f32 {
    tips.iter().map(|p| (p.z - 1.15).abs()).fold(0.0, f32::max)
}

#[test]
fn a_jittery_drag_reaches_the_clay_straighter_and_ends_where_the_button_was_let_go() {
    let (raw, raw_release) = zig_zag_drag(0.0);
    let (smooth, smooth_release) = zig_zag_drag(0.5);
    assert!(!raw.is_empty() && !smooth.is_empty(), "the drags pressed");
    let (raw_dev, smooth_dev) = (deviation(&raw), deviation(&smooth));
    eprintln!("pressed path's deviation from the line: off {raw_dev:.4}, 0.5 {smooth_dev:.4}");
    assert!(
        raw_dev > 0.01,
        "the jitter reaches the clay unsmoothed: {raw_dev}"
    );
    assert!(
        smooth_dev < 0.5 * raw_dev,
        "smoothed {smooth_dev} vs {raw_dev}"
    );
    // Both strokes end at the pointer: the last pressed tip lies under the release point.
    for (tips, release) in [(&raw, raw_release), (&smooth, smooth_release)] {
        let last = *tips.last().unwrap();
        let off = (last.x - release.x).hypot(last.z - release.z);
        eprintln!("last pressed tip {last}, released over {release}: {off:.5} apart");
        assert!(off < 0.005, "the stroke ended {off} from the release point");
    }
}
