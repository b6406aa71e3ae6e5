//! The contact tool leaves one connected clay at every α its control allows: for α across
//! `[-MAX_ALPHA, MAX_ALPHA]` (the window's slider and the scripts' validation), a one-second
//! contact stroke driven as the window drives it (`support/window_stroke.rs`) at the palette's
//! other defaults leaves an exported mesh of exactly one connected piece (no specks of clay in
//! the air, no cavity sealed under a rim), and it did change the clay.

#[path = "support/window_stroke.rs"]
mod window_stroke;

use dynaclay::app::{ActionKind, PaletteEntry, ToolPalette};
use dynaclay::tools::{Clay, ContactParams};
use glam::Vec3;
use window_stroke::{Stroke, default_clay, export, run_stroke};

const TOP: f32 = 1.725;

fn connected_after_contact(alpha: f32) {
    let field = default_clay();
    let palette = ToolPalette {
        selected: PaletteEntry::Geometric(ActionKind::Contact),
        contact_alpha: alpha,
        ..ToolPalette::default()
    };
    let stroke = Stroke::one_second(Vec3::new(0.9, TOP, 1.15), Vec3::new(1.4, TOP, 1.15));
    let clay = run_stroke(&field, palette.choice(), &stroke);
    let dir = tempfile::tempdir().unwrap();
    let before = export(&Clay::single(field), dir.path(), "before.obj");
    let after = export(&clay, dir.path(), "after.obj");
    let moved = [1.0, 1.15, 1.3]
        .iter()
        .map(|&x| (after.top_at(x, 1.15, 0.03) - before.top_at(x, 1.15, 0.03)).abs())
        .fold(0.0_f32, f32::max);
    let pieces = after.components();
    println!("alpha {alpha:+.2}: {pieces} piece(s), top moved up to {moved:.4}");
    assert_eq!(pieces, 1, "alpha {alpha}: {pieces} pieces of clay");
    assert!(
        moved > 0.01,
        "alpha {alpha}: the stroke did nothing ({moved})"
    );
}

#[test]
fn denting_contacts_leave_one_connected_clay() {
    let max = ContactParams::MAX_ALPHA;
    for alpha in [-max, -2.0, -1.0, -0.5, -0.1] {
        connected_after_contact(alpha);
    }
}

#[test]
fn bulging_contacts_leave_one_connected_clay() {
    let max = ContactParams::MAX_ALPHA;
    for alpha in [0.1, 0.5, 1.0, 2.0, max] {
        connected_after_contact(alpha);
    }
}
