//! Headless frames of the whole app (egui_kittest, no display, no GPU) for how the window
//! behaves as a window: when it asks to be drawn again, what its toggles show, what the log
//! says, and that its layout holds still while the sculpt changes.

use std::time::Duration;

use egui::accesskit::{Role, Toggled};
use egui_kittest::Harness;
use egui_kittest::kittest::{NodeT, Queryable};

use super::command::EngineEvent;
use super::link::{EngineEndpoint, engine_link};
use super::redraw::POLL_PERIOD;
use super::state::{CONTROLS_WIDTH_PT, SculptApp, event_line};
use super::view::EngineView;
use crate::dynamics::Material;
use crate::field::{BSplineLattice, MultiPatchField};

fn harness() -> (Harness<'static, SculptApp>, EngineEndpoint) {
    let (link, end) = engine_link();
    let app = SculptApp::new(link);
    let h = Harness::builder()
        .with_size(egui::vec2(1400.0, 1000.0))
        .build_ui_state(|ui, app: &mut SculptApp| app.show(ui, None), app);
    (h, end)
}

/// How long after the last frame the app asked to be drawn again (`Duration::MAX`: never).
fn repaint_delay(h: &Harness<'static, SculptApp>) -> Duration {
    h.output()
        .viewport_output
        .get(&egui::ViewportId::ROOT)
        .map_or(Duration::MAX, |v| v.repaint_delay)
}

fn toggled(h: &Harness<'static, SculptApp>, label: &str) -> bool {
    let node = h.get_by_role_and_label(Role::Button, label);
    match node.accesskit_node().toggled() {
        Some(Toggled::True) => true,
        Some(Toggled::False) => false,
        other => panic!("{label} is not a toggle: {other:?}"),
    }
}

#[test]
fn an_idle_app_asks_for_no_frame_until_something_is_in_flight() {
    let (mut h, mut end) = harness();
    h.run();
    // The engine publishes a view (as it does on every bridge pass) but nothing is in flight.
    end.view.publish_clone_of(&EngineView::default());
    h.step();
    assert_eq!(
        repaint_delay(&h),
        Duration::MAX,
        "idle: no poll ({:?})",
        h.state().in_flight
    );
    h.step();
    assert_eq!(repaint_delay(&h), Duration::MAX, "still idle");

    // A stroke held in the engine: the window polls while it lasts, and stops after.
    end.view.publish_clone_of(&EngineView {
        stroke_active: true,
        ..EngineView::default()
    });
    h.step();
    assert!(h.state().in_flight.stroke);
    assert_eq!(repaint_delay(&h), POLL_PERIOD);
    end.view.publish_clone_of(&EngineView::default());
    h.step();
    assert_eq!(repaint_delay(&h), Duration::MAX, "the stroke ended");
    assert!(h.state().status_line().contains("loops haptic –"));
}

#[test]
fn the_elastic_and_plastic_toggles_show_the_material_in_effect() {
    let (mut h, mut end) = harness();
    h.run();
    end.view.publish_clone_of(&EngineView {
        material: Material::PLASTIC,
        ..EngineView::default()
    });
    h.run();
    assert!(toggled(&h, "Plastic") && !toggled(&h, "Elastic"));

    h.get_by_role_and_label(Role::Button, "Elastic").click();
    h.run();
    assert!(toggled(&h, "Elastic") && !toggled(&h, "Plastic"));
    assert_eq!(
        h.state().material,
        Material {
            neighbourhood: Material::PLASTIC.neighbourhood,
            ..Material::ELASTIC
        }
    );

    // A slider moved off the preset: neither shows selected.
    h.get_by_role_and_label(Role::Slider, "Stiffness")
        .set_value_accesskit(1234.0);
    h.run();
    assert!(!toggled(&h, "Elastic") && !toggled(&h, "Plastic"));
}

#[test]
fn a_refine_answer_names_the_command_once() {
    let (mut h, end) = harness();
    h.run();
    // As the engine words a refine (the error's own message names what it refused).
    end.events
        .send(EngineEvent::Done {
            what: "refine".into(),
            detail: "detail patch 1, 20×20×20 coefficients at knot spacing 0.025 (level 2)".into(),
        })
        .unwrap();
    end.events
        .send(EngineEvent::Failed {
            what: "refine".into(),
            error: "refine: the clay already holds 256 patches".into(),
        })
        .unwrap();
    h.run();
    let log: Vec<&str> = h.state().log.iter().map(String::as_str).collect();
    assert_eq!(
        log,
        [
            "refine: detail patch 1, 20×20×20 coefficients at knot spacing 0.025 (level 2)",
            "refine failed: the clay already holds 256 patches",
        ]
    );
    for line in log {
        assert_eq!(line.matches("refine").count(), 1, "{line}");
    }
}

#[test]
fn event_lines_drop_only_a_whole_repeated_name() {
    assert_eq!(
        event_line("save", "wrote a.dclay", false),
        "save: wrote a.dclay"
    );
    assert_eq!(event_line("refine", "refine: x", false), "refine: x");
    assert_eq!(
        event_line("make tool", "make tool \"cup\": empty selection", true),
        "make tool failed: \"cup\": empty selection"
    );
    // "pin" is not a word of "pins: …": kept whole.
    assert_eq!(event_line("pin", "pins: 3", false), "pin: pins: 3");
}

#[test]
fn pins_and_tools_move_nothing_in_the_layout() {
    let (mut h, mut end) = harness();
    h.run();
    let controls = h
        .state()
        .controls_rect
        .expect("the controls panel is drawn");
    let view = h.state().viewport_rect.expect("the view is drawn");
    assert!(
        (controls.width() - CONTROLS_WIDTH_PT).abs() < 1.0,
        "starts at its default width: {controls:?}"
    );
    let below = |h: &Harness<'static, SculptApp>| h.get_by_label("Particles on the clay").rect();
    let particles_header = below(&h);

    // Forty pins with long descriptions.
    let pins: Vec<String> = (0..40)
        .map(|i| {
            format!(
                "#{i}: curve pin through 37 points from (0.125, -0.250, 0.375) to (0.500, \
                 0.625, -0.750), weight 1.0, tolerance 0.001 field units"
            )
        })
        .collect();
    end.view.publish_clone_of(&EngineView {
        pins,
        ..EngineView::default()
    });
    h.run();
    assert_eq!(h.state().view.pins.len(), 40);
    assert_eq!(h.state().controls_rect, Some(controls), "panel width kept");
    assert_eq!(h.state().viewport_rect, Some(view), "the view did not move");
    assert_eq!(below(&h), particles_header, "the sections below stay put");

    // Every tool in turn: the sections below the tool area stay put.
    for tool in [
        "Smooth",
        "Chisel",
        "Stamp",
        "Contact",
        "Curve",
        "Point grab",
    ] {
        h.get_by_label(tool).click();
        h.run();
        assert_eq!(below(&h), particles_header, "after choosing {tool}");
        assert_eq!(
            h.state().controls_rect,
            Some(controls),
            "after choosing {tool}"
        );
    }
}

#[test]
fn mirror_planes_cross_the_clay_box_and_detail_patches_are_outlined() {
    let (mut h, mut end) = harness();
    // A 12³ clay with unit spacing from the origin, and one detail patch.
    let base = BSplineLattice::zeros([12; 3], 1.0, glam::Vec3::ZERO).unwrap();
    let mut field = MultiPatchField::new(base);
    field
        .refine(glam::Vec3::splat(3.0), glam::Vec3::splat(6.0), 1)
        .unwrap();
    end.field.publish_clone_of(&field);
    h.run();
    assert_eq!(h.state().mirror_planes(), [None; 3], "no mirroring yet");

    // The mirror switches sit with the mouse pointer (not connected in this harness).
    h.state_mut().symmetry.y = true;
    h.run();
    let planes = h.state().mirror_planes();
    assert!(planes[0].is_none() && planes[2].is_none());
    let y = planes[1].expect("the y plane is drawn");
    for c in y.corners {
        assert_eq!(c.y, 5.5, "through the clay's centre");
        assert!(
            [0.0, 11.0].contains(&c.x) && [0.0, 11.0].contains(&c.z),
            "{c}"
        );
    }
    assert_eq!(h.state().scene_options().mirror_planes, planes);

    // The camera on the clay, so every corner of the patch is in front of the eye.
    h.state_mut()
        .camera
        .frame_box(glam::Vec3::ZERO, glam::Vec3::splat(11.0));
    let rect = h.state().viewport_rect.unwrap();
    let segments = h.state_mut().detail_marks_on_screen(rect);
    assert_eq!(segments.len(), 12, "one box of twelve edges");
    h.state_mut().display.show_detail_patches = false;
    assert!(h.state_mut().detail_marks_on_screen(rect).is_empty());
}

#[test]
fn the_status_line_shows_the_last_strokes_time_from_hand_to_screen() {
    use crate::engine::{ChangeStamp, MeshStamp, StrokeStamps};
    let (mut h, _end) = harness();
    h.run();
    assert!(!h.state().status_line().contains("stroke to screen"));
    // A stroke whose first change (read at 5 ms) was drawn by the frame at 29 ms, and whose
    // shape was settled in the same snapshot.
    let change = ChangeStamp {
        sample_tick: 5,
        sample_ns: 5_000_000,
        step_ns: 5_200_000,
        snapshot_version: 6,
        snapshot_ns: 5_400_000,
    };
    let stamp = MeshStamp {
        snapshot_version: 6,
        meshed_ns: 12_000_000,
        first_change_meshed_ns: Some(12_000_000),
        settled_meshed_ns: Some(12_000_000),
        stroke: StrokeStamps {
            stroke: 1,
            first_change: Some(change),
            last_change: Some(change),
            settled: Some(change),
            hand_to_force_ticks: Some(1),
        },
    };
    h.state_mut().motion.frame(29_000_000, &stamp);
    let line = h.state().status_line();
    assert!(
        line.contains("stroke to screen 24 ms, settled 24 ms"),
        "{line}"
    );
}
