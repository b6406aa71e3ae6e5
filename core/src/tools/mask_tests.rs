//! The freeze mask against the tools, the dynamics and the history: held clay keeps its bits,
//! free clay changes, a half hold moves half as far.

use glam::Vec3;

use super::*;
use crate::dynamics::{Distribution, Material, RegionState, Simulator, StepParams, ToolForce};
use crate::field::{BSplineLattice, Primitive, RegionSnapshot, lattice_from_primitive};

/// Where the masked and the free carve land on the bar's top face.
const HELD_AT: Vec3 = Vec3::new(3.0, 0.95, 1.5);
const FREE_AT: Vec3 = Vec3::new(0.9, 0.95, 1.5);

/// A bar from x = 0.4 to 3.6 (1.1 thick), long enough that a mask at one end misses the other.
fn bar() -> Clay {
    let bar = Primitive::Box {
        centre: Vec3::new(2.0, 0.95, 0.95),
        half_extents: Vec3::new(1.6, 0.55, 0.55),
    };
    Clay::single(lattice_from_primitive([42, 20, 20], 0.1, Vec3::ZERO, &bar, 0.2, 2).unwrap())
}

/// A brush that holds everything within 0.6 of `HELD_AT` fully (radius 1.2).
fn hold_brush(strength: f32) -> MaskBrush {
    MaskBrush {
        radius_fu: 1.2,
        strength,
        mode: MaskMode::Freeze,
    }
}

fn carve(clay: &mut Clay, at: Vec3) {
    let tool = GeometricTool {
        shape: ToolShape::Sphere { radius_fu: 0.2 },
        action: ToolAction::Remove,
        falloff_fu: 0.1,
    };
    let pose = ToolPose {
        position_fu: at,
        rotation: glam::Quat::IDENTITY,
    };
    apply_tool(clay, &tool, &pose, 0.1, &ApplyOptions::default(), None).unwrap();
}

/// Points within 0.2 of `at` (every coefficient they read lies within 0.55 of it).
fn around(at: Vec3) -> Vec<Vec3> {
    let mut points = Vec::new();
    for k in -2..=2 {
        for j in -2..=2 {
            for i in -2..=2 {
                points.push(at + 0.05 * Vec3::new(i as f32, j as f32, k as f32));
            }
        }
    }
    points
}

#[test]
fn a_carve_leaves_masked_clay_bit_for_bit_and_cuts_the_free_clay() {
    let mut clay = bar();
    let before = clay.clone();
    paint_mask(&mut clay, &hold_brush(1.0), HELD_AT, None).unwrap();
    carve(&mut clay, HELD_AT);
    carve(&mut clay, FREE_AT);
    let l = clay.base();
    for x in around(HELD_AT) {
        assert_eq!(
            l.value(x).to_bits(),
            before.base().value(x).to_bits(),
            "held clay moved at {x}"
        );
    }
    // The free cut is as deep as on a clay never masked.
    let mut plain = bar();
    carve(&mut plain, FREE_AT);
    assert!(before.base().value(FREE_AT - Vec3::Z * 0.1) > l.iso);
    assert!(
        l.value(FREE_AT - Vec3::Z * 0.1) < l.iso,
        "the free carve cut"
    );
    for x in around(FREE_AT) {
        assert!((l.value(x) - plain.base().value(x)).abs() < 1e-6, "at {x}");
    }
}

/// Under a soft-edged mask one wide carve moves the clay at each point at most `1 − tint` of
/// what the same carve moves it on the clay never masked (the carve only lowers coefficients,
/// so that is the bound the dilated hold promises): fully tinted clay keeps its bits, the
/// brush's soft edge holds as firmly as it is tinted, and clay the tint does not reach is cut.
#[test]
fn clay_under_a_soft_mask_moves_at_most_its_untinted_share() {
    let mut clay = bar();
    paint_mask(&mut clay, &hold_brush(1.0), HELD_AT, None).unwrap();
    let mask = clay.mask.clone().unwrap();
    let before = clay.base().clone();
    let mut plain = bar();
    // A ball from x = 1.3 to 2.9 on the top: under untinted, soft-edged and fully tinted clay.
    let wide = GeometricTool {
        shape: ToolShape::Sphere { radius_fu: 0.8 },
        action: ToolAction::Remove,
        falloff_fu: 0.1,
    };
    let pose = ToolPose {
        position_fu: Vec3::new(2.1, 0.95, 1.5),
        rotation: glam::Quat::IDENTITY,
    };
    for c in [&mut clay, &mut plain] {
        apply_tool(c, &wide, &pose, 0.1, &ApplyOptions::default(), None).unwrap();
    }
    let (mut full, mut soft, mut cut) = (0, 0, 0);
    for i in 0..=34 {
        for j in 0..=6 {
            for k in 0..=8 {
                let x = Vec3::new(
                    1.2 + 0.05 * i as f32,
                    0.7 + 0.05 * j as f32,
                    1.1 + 0.1 * k as f32,
                );
                let tint = mask.value_at(x);
                let free = plain.base().value(x) - before.value(x);
                let moved = clay.base().value(x) - before.value(x);
                if free.abs() < 1e-3 {
                    continue;
                }
                assert!(
                    moved.abs() <= (1.0 - tint) * free.abs() + 1e-5,
                    "at {x} tinted {tint}: moved {moved} of the free {free}"
                );
                if tint >= 1.0 {
                    assert_eq!(moved, 0.0, "fully tinted clay moved at {x}");
                    full += 1;
                } else if tint > 0.05 {
                    soft += 1;
                } else if tint == 0.0 && moved.abs() >= 0.5 * free.abs() {
                    cut += 1;
                }
            }
        }
    }
    assert!(full > 20, "{full} fully tinted points the carve reached");
    assert!(
        soft > 20,
        "{soft} points on the soft edge the carve reached"
    );
    assert!(
        cut > 20,
        "{cut} untinted points cut at least half as deep as the plain clay"
    );
}

#[test]
fn a_half_hold_moves_the_clay_half_as_far() {
    let mut clay = bar();
    let brush = MaskBrush {
        radius_fu: 8.0,
        strength: 0.5,
        mode: MaskMode::Freeze,
    };
    let report = paint_mask(&mut clay, &brush, HELD_AT, None).unwrap();
    assert_eq!(report.changed, 42 * 20 * 20);
    let before = clay.base().clone();
    let mut free = bar();
    carve(&mut clay, HELD_AT);
    carve(&mut free, HELD_AT);
    let mut compared = 0;
    for x in around(HELD_AT) {
        let (full, half) = (
            free.base().value(x) - before.value(x),
            clay.base().value(x) - before.value(x),
        );
        if full.abs() > 1e-3 {
            assert!((half - 0.5 * full).abs() < 1e-4, "{half} against {full}");
            compared += 1;
        }
    }
    assert!(compared > 20, "the carve reached {compared} points");
}

#[test]
fn invert_holds_the_free_clay_and_clear_frees_everything() {
    let mut clay = bar();
    paint_mask(&mut clay, &hold_brush(1.0), HELD_AT, None).unwrap();
    invert_mask(&mut clay, None).unwrap();
    let mask = &clay.mask.as_ref().unwrap().patches[0];
    let l = clay.base();
    let node = |x: Vec3| {
        let u = ((x - l.origin) / l.spacing).round();
        l.index(u.x as usize, u.y as usize, u.z as usize)
    };
    assert_eq!(mask.coeffs[node(HELD_AT)], 0.0);
    assert_eq!(mask.coeffs[node(FREE_AT)], 1.0);
    let before = clay.clone();
    carve(&mut clay, FREE_AT);
    carve(&mut clay, HELD_AT);
    for x in around(FREE_AT) {
        assert_eq!(
            clay.base().value(x).to_bits(),
            before.base().value(x).to_bits()
        );
    }
    assert!(clay.base().value(HELD_AT - Vec3::Z * 0.1) < clay.base().iso);

    // Cleared, the clay carves as if it had never been masked.
    let mut plain = clay.clone();
    plain.mask = None;
    let report = clear_mask(&mut clay, None).unwrap();
    assert!(report.changed > 0);
    assert!(!clay.mask.as_ref().unwrap().any());
    carve(&mut clay, FREE_AT);
    carve(&mut plain, FREE_AT);
    assert_eq!(clay.base().coeffs, plain.base().coeffs);

    // Inverting a clay without a mask holds all of it.
    let mut whole = bar();
    invert_mask(&mut whole, None).unwrap();
    let before = whole.base().clone();
    carve(&mut whole, FREE_AT);
    assert_eq!(whole.base().coeffs, before.coeffs);
}

#[test]
fn bad_brushes_are_refused_and_change_nothing() {
    let mut clay = bar();
    for (brush, at) in [
        (
            MaskBrush {
                radius_fu: 0.0,
                ..hold_brush(1.0)
            },
            HELD_AT,
        ),
        (hold_brush(1.5), HELD_AT),
        (hold_brush(f32::NAN), HELD_AT),
        (hold_brush(1.0), Vec3::new(f32::NAN, 0.0, 0.0)),
    ] {
        let e = paint_mask(&mut clay, &brush, at, None).unwrap_err();
        assert!(!e.to_string().is_empty());
    }
    assert!(clay.mask.is_none());
}

#[test]
fn a_mask_stroke_undoes_and_redoes_bit_for_bit() {
    let mut clay = bar();
    let mut history = History::default();
    let mut rec = StepRecorder::new("mask");
    for n in 0..5 {
        let at = HELD_AT - Vec3::X * (0.1 * n as f32);
        paint_mask(&mut clay, &hold_brush(0.7), at, Some(&mut rec)).unwrap();
    }
    let painted = clay.mask.clone().unwrap();
    assert!(history.commit(rec, &clay));
    assert_eq!(history.undo(&mut clay).unwrap().as_deref(), Some("mask"));
    assert!(
        !clay.mask.as_ref().unwrap().any(),
        "undo frees the clay again"
    );
    history.redo(&mut clay).unwrap();
    assert_eq!(clay.mask.as_ref().unwrap(), &painted);
    // An invert is one step too.
    let mut rec = StepRecorder::new("invert mask");
    invert_mask(&mut clay, Some(&mut rec)).unwrap();
    assert!(history.commit(rec, &clay));
    history.undo(&mut clay).unwrap();
    assert_eq!(clay.mask.as_ref().unwrap(), &painted);
}

#[test]
fn the_mask_grows_with_the_clay_and_follows_a_new_patch() {
    let mut clay = bar();
    paint_mask(&mut clay, &hold_brush(1.0), HELD_AT, None).unwrap();
    let held_before = clay.mask.as_ref().unwrap().value_at(HELD_AT);
    assert_eq!(held_before, 1.0);
    clay.grow([8, 0, 0]).unwrap();
    let mask = clay.mask.as_ref().unwrap();
    assert_eq!(mask.patches[0].dims, clay.base().dims);
    assert_eq!(mask.value_at(HELD_AT), 1.0);
    assert_eq!(mask.value_at(FREE_AT), 0.0);
    // A detail patch added since takes the base's holds at its nodes.
    clay.density
        .add_detail(HELD_AT - Vec3::splat(0.3), HELD_AT + Vec3::splat(0.3), 1)
        .unwrap();
    ensure_mask(&mut clay).unwrap();
    let mask = clay.mask.as_ref().unwrap();
    assert_eq!(mask.patches.len(), 2);
    let detail = &mask.patches[1];
    assert_eq!(detail.dims, clay.density.patches[1].lattice.dims);
    let centre = detail.to_lattice(HELD_AT).round();
    let at = detail.index(centre.x as usize, centre.y as usize, centre.z as usize);
    assert!(
        detail.coeffs[at] > 0.999,
        "held over the detail: {}",
        detail.coeffs[at]
    );
    assert!(detail.coeffs.iter().all(|&h| (0.0..=1.0).contains(&h)));
}

/// A grab pulling the top face up at `at`, 0.15 above it.
fn pull(at: Vec3) -> ToolForce {
    ToolForce {
        start: at,
        end: at + Vec3::Z * 0.15,
        distribution: Distribution::Constant,
        radius: 0.15,
        gain: 1e6,
    }
}

/// The coefficients over the bar's top, both force spots included.
fn top_region() -> CoeffBox {
    CoeffBox {
        min: [5, 6, 12],
        max: [36, 13, 18],
    }
}

/// Steps the region of `clay` under both pulls `steps` times; returns the lattice after.
fn pulled(clay: &Clay, steps: usize) -> BSplineLattice {
    let mut lattice = clay.base().clone();
    let region = top_region();
    let n = region.dims();
    let mut state =
        RegionState::new(&lattice, region, [n[0], n[1], n[2]], Material::PLASTIC).unwrap();
    region_holds(clay, 0, region, &mut state.held);
    let mut sim = Simulator::new(StepParams::default());
    let mut snapshot = RegionSnapshot::default();
    let forces = [pull(HELD_AT), pull(FREE_AT)];
    for _ in 0..steps {
        sim.step(&mut state, &mut lattice, &forces, &mut snapshot)
            .unwrap();
    }
    lattice
}

#[test]
fn a_force_stroke_leaves_held_coefficients_bit_for_bit_and_moves_the_free_ones() {
    let mut clay = bar();
    paint_mask(&mut clay, &hold_brush(1.0), HELD_AT, None).unwrap();
    let after = pulled(&clay, 60);
    let mask = &clay.mask.as_ref().unwrap().patches[0];
    let before = clay.base();
    let (mut held, mut free_moved) = (0, 0.0_f32);
    for (n, (&a, &b)) in after.coeffs.iter().zip(&before.coeffs).enumerate() {
        if mask.coeffs[n] == 1.0 {
            assert_eq!(a.to_bits(), b.to_bits(), "held coefficient {n} moved");
            held += 1;
        } else if mask.coeffs[n] == 0.0 {
            free_moved = free_moved.max((a - b).abs());
        }
    }
    assert!(held > 100, "{held} coefficients held");
    assert!(free_moved > 1e-3, "the free pull moved {free_moved}");
    // Where it was held the surface did not rise; where free it did.
    let above = Vec3::Z * 0.1;
    assert_eq!(
        after.value(HELD_AT + above).to_bits(),
        before.value(HELD_AT + above).to_bits()
    );
    assert!(after.value(FREE_AT + above) > before.value(FREE_AT + above) + 1e-3);
}

#[test]
fn a_half_hold_slows_the_dynamics_to_about_half() {
    let mut half = bar();
    let brush = MaskBrush {
        radius_fu: 8.0,
        strength: 0.5,
        mode: MaskMode::Freeze,
    };
    paint_mask(&mut half, &brush, HELD_AT, None).unwrap();
    let free = bar();
    let steps = 6;
    let (moved_half, moved_free) = (pulled(&half, steps), pulled(&free, steps));
    let rise = |l: &BSplineLattice| {
        l.value(FREE_AT + Vec3::Z * 0.1) - free.base().value(FREE_AT + Vec3::Z * 0.1)
    };
    let ratio = rise(&moved_half) / rise(&moved_free);
    assert!(rise(&moved_free) > 0.0);
    assert!(
        (0.35..0.65).contains(&ratio),
        "half hold moved {ratio} as far"
    );
}

/// One painted coefficient holds exactly the box of coefficients within
/// [`HOLD_REACH_NODES`] nodes of it, whatever region
/// is asked for (one reaching past the lattice's border included), and nothing else.
#[test]
fn one_painted_coefficient_holds_the_box_its_support_reaches() {
    let clay = bar();
    let mut mask = FreezeMask::matching(&clay.density).unwrap();
    let l = clay.base();
    let painted = [2_usize, 10, 9];
    mask.patches[0]
        .coeffs
        .set_flat(l.index(painted[0], painted[1], painted[2]), 0.75);
    let reach = HOLD_REACH_NODES;
    for region in [
        CoeffBox {
            min: [0, 0, 0],
            max: [l.dims[0] - 1, l.dims[1] - 1, l.dims[2] - 1],
        },
        CoeffBox {
            min: [0, 8, 11],
            max: [7, 13, 19],
        },
    ] {
        let mut holds = Vec::new();
        mask.support_holds(0, l, region, &mut holds);
        assert_eq!(holds.len(), region.count());
        let mut at = 0;
        for k in region.min[2]..=region.max[2] {
            for j in region.min[1]..=region.max[1] {
                for i in region.min[0]..=region.max[0] {
                    let near = [i, j, k]
                        .iter()
                        .zip(&painted)
                        .all(|(&a, &b)| a.abs_diff(b) <= reach);
                    let want = if near { 0.75 } else { 0.0 };
                    assert_eq!(holds[at], want, "({i}, {j}, {k}) in {region:?}");
                    at += 1;
                }
            }
        }
    }
    // A region the hold does not reach gets none, and a region off the lattice none either.
    let mut holds = vec![1.0];
    let far = CoeffBox {
        min: [20, 0, 0],
        max: [30, 5, 5],
    };
    mask.support_holds(0, l, far, &mut holds);
    assert!(holds.is_empty());
    let off = CoeffBox {
        min: [40, 0, 0],
        max: [50, 5, 5],
    };
    mask.support_holds(0, l, off, &mut holds);
    assert!(holds.is_empty());
}
