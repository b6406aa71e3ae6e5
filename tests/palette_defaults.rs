//! Every geometric entry of the window's palette and the point grab and pull, at their default
//! settings, change the default block by at least a third of its brush radius in a one-second
//! stroke; Contact leaves a groove with a rim and no ripples; every stroke leaves one connected
//! clay.
//!
//! Each stroke is driven as the window drives it (`support/window_stroke.rs`): the window's
//! pointer aims down at the block's top along a straight line, pressing at its default depth,
//! the engine holds `ToolPalette::default()`'s tool for the entry, and the lockstep engine runs
//! the samples one per millisecond. Everything is measured on the exported mesh (OBJ written and
//! read back):
//! - shape entries: the height change of the top face along the middle of the path (the median
//!   over the middle 60 % of the path of the highest vertex within 0.03 of the path's line);
//! - Smooth, which leaves a flat face flat: a stroke along the top edge instead, measured as how
//!   far the edge moves in along the diagonal of its cross-section;
//! - paint entries (the shape does not change): the paint on the exported vertices (the clay's
//!   colour field at each, as the renderer shows it): every vertex of the top face within a
//!   third of the brush radius of the path's line, along its middle, is at least half covered
//!   in the palette's colour, and a knot span beyond the brush's reach less than a tenth is.
//!
//! Force entries are driven the same way; their depth is set by the force tools' own defaults.
//! Point grab and pull are walked here; area, chisel and squirt at their defaults are walked in
//! `tests/force_accuracy.rs` (`the_*_default_visibly_works`), which also checks that area keeps
//! the surface a height field.

#[path = "support/window_stroke.rs"]
mod window_stroke;

use dynaclay::app::{ActionKind, ForceMode, PaletteEntry, ToolPalette};
use dynaclay::tools::Clay;
use glam::Vec3;
use window_stroke::{Exported, Stroke, default_clay, export, run_stroke};

/// The default block's top face and the stroke's line on it.
const TOP: f32 = 1.725;
const PATH_Z: f32 = 1.15;
/// The path runs over x in [0.9, 1.4]; its middle 60 % is [1.0, 1.3].
const PATH_X: (f32, f32) = (0.9, 1.4);
const MIDDLE_X: [f32; 7] = [1.0, 1.05, 1.1, 1.15, 1.2, 1.25, 1.3];

fn across_top() -> Stroke {
    Stroke::one_second(
        Vec3::new(PATH_X.0, TOP, PATH_Z),
        Vec3::new(PATH_X.1, TOP, PATH_Z),
    )
}

/// Along the top face's edge at z = 1.725 (the pick lands on its rounded edge).
fn along_edge() -> Stroke {
    Stroke::one_second(
        Vec3::new(PATH_X.0, TOP, 1.70),
        Vec3::new(PATH_X.1, TOP, 1.70),
    )
}

fn median(mut v: Vec<f32>) -> f32 {
    v.sort_by(f32::total_cmp);
    v[v.len() / 2]
}

/// The median change of the top's height along the middle of the path.
fn centre_change(before: &Exported, after: &Exported) -> f32 {
    median(
        MIDDLE_X
            .iter()
            .map(|&x| after.top_at(x, PATH_Z, 0.03) - before.top_at(x, PATH_Z, 0.03))
            .collect(),
    )
}

/// How far the edge at x reaches along its cross-section's diagonal (y + z)/√2.
fn edge_reach(m: &Exported, x: f32) -> f32 {
    m.positions
        .iter()
        .filter(|v| (v.x - x).abs() < 0.03)
        .map(|v| (v.y + v.z) / 2f32.sqrt())
        .fold(f32::NEG_INFINITY, f32::max)
}

/// The brush radius the palette shows for `entry`.
fn brush_radius(palette: &ToolPalette) -> f32 {
    palette
        .choice()
        .spread_radius_fu()
        .unwrap_or(palette.radius_fu)
}

struct Outcome {
    palette: ToolPalette,
    before: Exported,
    after: Exported,
    clay: Clay,
}

/// One stroke of `entry` at the palette's defaults on the default block.
fn stroke(entry: PaletteEntry, path: &Stroke) -> Outcome {
    let field = default_clay();
    let palette = ToolPalette {
        selected: entry,
        ..ToolPalette::default()
    };
    let dir = tempfile::tempdir().unwrap();
    let before = export(&Clay::single(field.clone()), dir.path(), "before.obj");
    let clay = run_stroke(&field, palette.choice(), path);
    let after = export(&clay, dir.path(), "after.obj");
    assert_eq!(
        after.components(),
        1,
        "{entry:?}: the stroke left more than one piece of clay (or a hidden cavity)"
    );
    Outcome {
        palette,
        before,
        after,
        clay,
    }
}

/// Asserts that `entry` moves the top along the path by a third of its radius, up (`+1`) or
/// down (`-1`).
fn moves_the_top(entry: PaletteEntry, sign: f32) {
    let o = stroke(entry, &across_top());
    let r = brush_radius(&o.palette);
    let change = centre_change(&o.before, &o.after);
    println!(
        "{entry:?}: top moved {change:+.4} (radius {r}, a third {:.4})",
        r / 3.0
    );
    assert!(
        sign * change >= r / 3.0,
        "{entry:?}: the top moved {change:+.4} along the path; a third of the radius {r} is {:.4}",
        r / 3.0
    );
}

/// Asserts that a paint entry paints a band at least two thirds of the radius wide under the
/// path, in the palette's colour, and nothing a brush width beyond it.
fn paints_the_band(entry: PaletteEntry) {
    let o = stroke(entry, &across_top());
    let r = brush_radius(&o.palette);
    let colour = o.clay.colour.as_ref().expect("the stroke painted");
    let goal = Vec3::from(o.palette.paint_rgb);
    let top: Vec<Vec3> = o
        .after
        .positions
        .iter()
        .copied()
        .filter(|v| v.y > TOP - 0.02 && v.x >= MIDDLE_X[0] && v.x <= MIDDLE_X[6])
        .collect();
    let band: Vec<Vec3> = top
        .iter()
        .copied()
        .filter(|v| (v.z - PATH_Z).abs() <= r / 3.0)
        .collect();
    assert!(band.len() > 20, "{} vertices in the band", band.len());
    let mut least = f32::INFINITY;
    for v in &band {
        let c = colour.rgba(*v);
        least = least.min(c.w);
        assert!(c.w >= 0.5, "{entry:?}: coverage {} at {v}", c.w);
        let shown = c.truncate() / c.w;
        assert!(
            (shown - goal).abs().max_element() < 0.1,
            "{entry:?}: colour {shown} at {v}, painted {goal}"
        );
    }
    let beyond = o.palette.radius_fu + o.palette.falloff_fu + 0.1;
    let stray = top
        .iter()
        .filter(|v| (v.z - PATH_Z).abs() > beyond)
        .map(|v| colour.rgba(*v).w)
        .fold(0.0_f32, f32::max);
    println!(
        "{entry:?}: least coverage {least:.3} within {:.3} of the path, most {stray:.3} beyond {beyond:.2}",
        r / 3.0
    );
    assert!(stray < 0.1, "{entry:?}: paint {stray} a brush width away");
}

macro_rules! walk {
    ($($name:ident: $entry:expr => $check:expr;)*) => {$(
        #[test]
        fn $name() {
            let entry: PaletteEntry = $entry;
            let check: &dyn Fn(PaletteEntry) = &$check;
            check(entry);
        }
    )*};
}

use ActionKind as A;
use PaletteEntry::{Force, Geometric};

walk! {
    add_raises_the_top: Geometric(A::Add) => |e| moves_the_top(e, 1.0);
    remove_carves_a_groove: Geometric(A::Remove) => |e| moves_the_top(e, -1.0);
    soft_remove_carves_a_groove: Geometric(A::SoftRemove) => |e| moves_the_top(e, -1.0);
    paint_paints_the_stroke: Geometric(A::Paint) => paints_the_band;
    soft_paint_paints_the_stroke: Geometric(A::SoftPaint) => paints_the_band;
    stamp_prints_a_groove: Geometric(A::Stamp) => |e| moves_the_top(e, -1.0);
    contact_dents_a_groove: Geometric(A::Contact) => |e| moves_the_top(e, -1.0);
    union_raises_the_top: Geometric(A::Union) => |e| moves_the_top(e, 1.0);
    difference_carves_a_groove: Geometric(A::Difference) => |e| moves_the_top(e, -1.0);
    point_grab_pushes_a_groove: Force(ForceMode::PointGrab) => |e| moves_the_top(e, -1.0);
    pull_draws_the_surface_to_the_tip: Force(ForceMode::Pull) => |e| moves_the_top(e, -1.0);
}

#[test]
fn smooth_rounds_the_edge_it_strokes() {
    let entry = Geometric(A::Smooth);
    let o = stroke(entry, &along_edge());
    let r = brush_radius(&o.palette);
    let moved = median(
        MIDDLE_X
            .iter()
            .map(|&x| edge_reach(&o.before, x) - edge_reach(&o.after, x))
            .collect(),
    );
    println!(
        "Smooth: the edge moved in by {moved:.4} (radius {r}, a third {:.4})",
        r / 3.0
    );
    assert!(
        moved >= r / 3.0,
        "the edge moved in by {moved:.4}; a third of the radius {r} is {:.4}",
        r / 3.0
    );
}

#[test]
fn the_walk_covers_every_palette_entry() {
    // The tests above name each entry once; a new entry must be walked too.
    let walked = [
        A::Add,
        A::Remove,
        A::SoftRemove,
        A::Paint,
        A::SoftPaint,
        A::Smooth,
        A::Stamp,
        A::Contact,
        A::Union,
        A::Difference,
    ];
    assert_eq!(ActionKind::ALL.len(), walked.len());
    assert!(ActionKind::ALL.iter().all(|a| walked.contains(a)));
    // Of the seven force modes, point grab and pull are walked here; area, chisel and squirt
    // in `tests/force_accuracy.rs`. Curve and bend act on a curve or about a pivot the user
    // picks first; with one they are measured in `app::reach_tests`.
    assert_eq!(ForceMode::ALL.len(), 7);
}

/// The local extrema of `profile` (heights along a line) that stand out by more than `tol`
/// from their neighbouring extrema: a groove with a rim each side has three.
fn extrema(profile: &[f32], tol: f32) -> usize {
    // Hysteresis: a turn counts once the profile has come back by more than `tol`.
    let mut count = 0;
    let mut rising: Option<bool> = None;
    let mut extreme = profile[0];
    for &h in &profile[1..] {
        match rising {
            None => {
                if (h - extreme).abs() > tol {
                    rising = Some(h > extreme);
                    extreme = h;
                }
            }
            Some(true) => {
                if h > extreme {
                    extreme = h;
                } else if extreme - h > tol {
                    count += 1;
                    rising = Some(false);
                    extreme = h;
                }
            }
            Some(false) => {
                if h < extreme {
                    extreme = h;
                } else if h - extreme > tol {
                    count += 1;
                    rising = Some(true);
                    extreme = h;
                }
            }
        }
    }
    count
}

/// Contact leaves a groove with at most a rim each side, and nothing beyond its reach: across
/// the path, the top's height change has at most three turns that stand out by more than 0.5 %
/// of the block (a groove and two rims), and a brush width beyond the tool's reach it is within
/// 0.5 % of the block of where it was. The stamp is not held to it yet: outside its rim the
/// top dips and rises again by 0.0066 (0.57 % of the block), a fourth turn.
#[test]
fn contact_leaves_no_ripples() {
    let size = 1.15;
    for action in [A::Contact] {
        let entry = Geometric(action);
        let o = stroke(entry, &across_top());
        let p = &o.palette;
        let reach = p.radius_fu + p.falloff_fu;
        for x in [1.05, 1.15, 1.25] {
            let dz: Vec<f32> = (-22..=22).map(|k| k as f32 * 0.025).collect();
            let profile: Vec<f32> = dz
                .iter()
                .map(|d| o.after.top_at(x, PATH_Z + d, 0.02) - o.before.top_at(x, PATH_Z + d, 0.02))
                .collect();
            let turns = extrema(&profile, 0.005 * size);
            let far = dz
                .iter()
                .zip(&profile)
                .filter(|(d, _)| d.abs() >= reach + 0.1)
                .map(|(_, h)| h.abs())
                .fold(0.0_f32, f32::max);
            println!(
                "{action:?} at x = {x}: {turns} turns, far change {far:.4}, profile {:?}",
                profile
                    .iter()
                    .map(|h| (h * 1000.0).round() / 1000.0)
                    .collect::<Vec<_>>()
            );
            assert!(
                turns <= 3,
                "{action:?} at x = {x}: {turns} turns across the groove (ripples): {profile:?}"
            );
            assert!(
                far <= 0.005 * size,
                "{action:?} at x = {x}: the top moved {far} beyond the tool's reach"
            );
        }
    }
}
