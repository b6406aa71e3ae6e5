//! Live detail patches (Hua & Qin eq. (3)): after `Command::Refine` over a box of the block's
//! top, a press inside the box is simulated on the finer patch and leaves a dent narrower than
//! the base lattice can hold; the same press without the refinement leaves a wider one. The
//! haptic loop's copy follows the new layout, and the saved session keeps both patches.

use dynaclay::engine::{
    Command, EngineConfig, HeadlessSink, Lockstep, PushTool, ToolChoice, build_clay,
};
use dynaclay::field::MultiPatchField;
use dynaclay::io::ClaySpec;
use dynaclay_devices::pointer::{PointerConfig, pointer_device};
use glam::Vec3;

/// The default block's top face (y) and the press point on it.
const TOP_Y: f32 = 1.725;
const PRESS: Vec3 = Vec3::new(1.15, TOP_Y, 1.15);

/// Runs a straight press 0.12 into the top of the default block (with a push of a quarter
/// knot span's radius), after refining a box around the press point `refine` levels deep (0:
/// no refinement), with automatic detail for force tools on or off; returns the final density,
/// the base spacing and the number of patches the haptic loop's copy holds.
fn press(refine: u32, auto_detail_force: bool) -> (MultiPatchField, f32, usize) {
    let start = build_clay(&ClaySpec::default()).unwrap();
    let spacing = start.spacing;
    let pointer = PointerConfig::stepped(1_000);
    let mut config = EngineConfig::for_field(&start, &pointer.info());
    config.haptic_rt_priority = None;
    config.safety.soft_start_s = 0.05;
    // The refinement compared is the one asked for: the narrow push would otherwise refine
    // under itself (three levels down) in both runs.
    config.sim.auto_detail_force = auto_detail_force;
    let (device, mut handle) = pointer_device(pointer);
    let mut run = Lockstep::new(
        &config,
        start,
        Box::new(device),
        Box::new(HeadlessSink::default()),
        64,
    )
    .unwrap();
    let commands = run.commands();
    commands
        .send(Command::SetTool(ToolChoice::Push(PushTool {
            radius_fu: 0.25 * spacing,
            ..PushTool::default()
        })))
        .unwrap();
    if refine > 0 {
        let (tx, rx) = crossbeam::channel::bounded(1);
        let half = Vec3::splat(2.5 * spacing);
        commands
            .send(Command::Refine {
                lo: PRESS - half,
                hi: PRESS + half,
                level: refine,
                reply: Some(tx),
            })
            .unwrap();
        run.step();
        let said = rx.try_recv().unwrap().unwrap();
        assert!(said.contains("detail patch 1"), "{said}");
    }
    let depth = 1.2 * spacing;
    let tip = |tick: usize| -> (Vec3, bool) {
        let t = tick as f32;
        match tick {
            0..100 => (PRESS + Vec3::Y * 0.2, false),
            100..400 => (
                PRESS + Vec3::Y * (0.2 - (0.2 + depth) * (t - 100.0) / 300.0),
                true,
            ),
            400..1200 => (PRESS - Vec3::Y * depth, true),
            _ => (PRESS + Vec3::Y * 0.2, false),
        }
    };
    for tick in 0..2000 {
        let (p, pressed) = tip(tick);
        handle.set(config.map.to_device(p), pressed);
        run.step();
    }
    let haptic_patches = run.haptic_density().patches.len();
    (run.density().clone(), spacing, haptic_patches)
}

/// Width of the dent along x, 0.3 knot spans below the top: the length of the run of outside
/// points through the press point.
fn dent_width(field: &MultiPatchField, spacing: f32) -> f32 {
    let y = TOP_Y - 0.3 * spacing;
    let step = spacing / 64.0;
    let outside = |dx: f32| !field.is_inside(Vec3::new(PRESS.x + dx, y, PRESS.z));
    assert!(
        outside(0.0),
        "the press dented the top below the press point"
    );
    let mut right = 0.0;
    while outside(right + step) && right < 4.0 * spacing {
        right += step;
    }
    let mut left = 0.0;
    while outside(-left - step) && left < 4.0 * spacing {
        left += step;
    }
    left + right
}

#[test]
fn a_press_inside_a_detail_patch_leaves_a_dent_finer_than_the_base_lattice_holds() {
    // The refinement compared is the one asked for: the narrow push would otherwise refine
    // under itself (three levels down) in both runs.
    let (coarse, spacing, coarse_patches) = press(0, false);
    let (fine, _, fine_patches) = press(2, false);
    assert_eq!(
        (coarse_patches, fine_patches),
        (1, 2),
        "the haptic copy follows the layout"
    );
    assert_eq!(fine.patches.len(), 2);
    // The press was simulated on the detail patch: the base patch did not move.
    let start = build_clay(&ClaySpec::default()).unwrap();
    assert_eq!(
        fine.patches[0].lattice, start,
        "the base patch is unchanged"
    );
    let (dc, df) = (depth(&coarse), depth(&fine));
    eprintln!("dent depth {dc:.4} / {df:.4} (base / detail; spacing {spacing})");
    let (wc, wf) = (dent_width(&coarse, spacing), dent_width(&fine, spacing));
    eprintln!("dent width {wc:.4} / {wf:.4} (base / detail)");
    assert!(
        (df - dc).abs() <= 0.25 * dc,
        "the refined dent is as deep as the base's: {df} vs {dc}"
    );
    assert!(
        wf < 0.5 * wc,
        "the refined dent ({wf}) is much narrower than the base's ({wc})"
    );
    assert!(
        wf < 0.5 * spacing,
        "the refined dent ({wf}) is narrower than half a base knot span ({spacing})"
    );
}

/// With automatic detail for force tools on, the narrow push refines under itself (three
/// levels down, with or without a level-2 patch under it) and the press dents as deep as on
/// the base, within a quarter, and narrower than half a base span.
#[test]
fn a_narrow_press_with_automatic_detail_refines_under_itself_and_dents_as_deep_as_on_the_base() {
    let (base, spacing, _) = press(0, false);
    let dc = depth(&base);
    for refine in [0, 2] {
        let (fine, _, haptic_patches) = press(refine, true);
        let finest = fine
            .patches
            .iter()
            .map(|p| p.lattice.spacing)
            .fold(f32::INFINITY, f32::min);
        assert!(
            (finest - spacing / 8.0).abs() < 1e-6,
            "refined three levels down under the push: {finest}"
        );
        assert_eq!(
            haptic_patches,
            fine.patches.len(),
            "the haptic copy follows"
        );
        let df = depth(&fine);
        let wf = dent_width(&fine, spacing);
        eprintln!("over refine {refine}: dent {df:.4} deep, {wf:.4} wide (base {dc:.4} deep)");
        assert!(
            (df - dc).abs() <= 0.25 * dc,
            "the automatic patch's dent is as deep as the base's: {df} vs {dc}"
        );
        assert!(wf < 0.5 * spacing, "and narrow: {wf}");
    }
}

/// The depth of the dent under the press point below the block's top.
fn depth(field: &MultiPatchField) -> f32 {
    TOP_Y - surface_y(field, PRESS)
}

/// The height of the clay's top above `x` (scanning down from above the block).
fn surface_y(field: &MultiPatchField, x: Vec3) -> f32 {
    let mut y = TOP_Y + 0.3;
    while y > TOP_Y - 0.6 && !field.is_inside(Vec3::new(x.x, y, x.z)) {
        y -= 0.001;
    }
    y
}
