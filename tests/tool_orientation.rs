//! A turned hand turns the tool: a script stroke's `rotations` reach the simulated arm, which
//! reports them, and the engine applies the geometric tool turned. A long box drawn along its
//! length cuts a narrow groove; the same box turned a quarter turn about the vertical cuts a
//! wide one. Measured on the exported mesh (meshed, welded, written as OBJ and read back).

use dynaclay::engine::ScriptDriver;
use dynaclay::field::MultiPatchField;
use glam::Vec2;

#[path = "support/lockstep.rs"]
mod lockstep;

#[path = "support/exported_mesh.rs"]
#[allow(dead_code)] // shared: this test probes profiles, not crossings
mod exported_mesh;

use lockstep::{Scripted, scripted};

/// A box 0.6 long (x), 0.2 wide and 0.2 high drawn along x through the block's top (at
/// 1.425: the box's bottom is 0.175 below it, its top 0.025 above); `rotations` is spliced in
/// as the stroke's `rotations` line (or nothing).
fn script(rotations: &str) -> String {
    format!(
        r#"
version = 1

[clay]
shape = "block"
resolution = 20

[[step]]
do = "stroke"
shape = {{ kind = "box", half_extents_fu = [0.3, 0.1, 0.1] }}
action = {{ kind = "remove" }}
falloff_fu = 0.15
path = [[0.6, 1.35, 0.95], [1.3, 1.35, 0.95]]
{rotations}
duration_s = 1.5
hover_fu = 0.4
"#
    )
}

/// Runs the script and returns the clay at the end.
fn run(text: &str) -> MultiPatchField {
    let dir = tempfile::tempdir().unwrap();
    let Scripted { plan, mut run, .. } = scripted(text, "turned.toml", dir.path());
    let mut driver = ScriptDriver::new(&plan);
    let commands = run.commands();
    for _ in 0..(plan.seconds * 1000.0) as usize {
        let sample = run.latest_tool();
        driver.dispatch(&sample, &commands);
        run.step();
    }
    assert!(driver.is_done(), "steps left: {:?}", driver.unsent_steps());
    assert!(driver.failures().is_empty(), "{:?}", driver.failures());
    run.density().clone()
}

/// The exported clay's top along z at x 0.95, from z 0.55 to 1.35 in steps of 0.005.
fn tops_across(field: &MultiPatchField) -> Vec<f32> {
    let dir = tempfile::tempdir().unwrap();
    let mesh = exported_mesh::export(field, dir.path(), "clay.obj");
    mesh.profile(Vec2::new(0.95, 0.55), Vec2::new(0.95, 1.35), 160)
        .into_iter()
        .map(|(_, y)| y)
        .collect()
}

/// The groove's width across the path at its middle (x 0.95, z 0.95, index 80 of
/// [`tops_across`]): the run of z around the path over which the top is more than 0.05 below
/// the untouched top.
fn groove_width(field: &MultiPatchField, untouched: f32) -> f32 {
    let tops = tops_across(field);
    let cut = |i: usize| tops[i] < untouched - 0.05;
    if !cut(80) {
        return 0.0;
    }
    let up = (81..tops.len()).take_while(|&i| cut(i)).count();
    let down = (0..80).rev().take_while(|&i| cut(i)).count();
    (up + down) as f32 * 0.005
}

#[test]
fn a_quarter_turned_box_cuts_a_groove_as_wide_as_it_is_long() {
    let untouched = {
        let dir = tempfile::tempdir().unwrap();
        let s = scripted(&script(""), "plain.toml", dir.path());
        tops_across(s.run.density())[80]
    };
    let along = run(&script(""));
    // A quarter turn about y: the box's length now runs across the path (along z).
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let across = run(&script(&format!(
        "rotations = [[0.0, {s}, 0.0, {s}], [0.0, {s}, 0.0, {s}]]"
    )));
    let (narrow, wide) = (
        groove_width(&along, untouched),
        groove_width(&across, untouched),
    );
    eprintln!("groove width: along the path {narrow:.3}, turned across it {wide:.3}");
    // The box is 0.2 wide and 0.6 long; the falloff widens both cuts alike.
    assert!(
        narrow > 0.1 && narrow < 0.35,
        "unturned groove {narrow} wide"
    );
    assert!(
        wide > narrow + 0.3,
        "turned groove {wide} wide, unturned {narrow}"
    );
}

#[test]
fn rotations_must_match_the_path_and_be_rotations() {
    for (rotations, says) in [
        (
            "rotations = [[0.0, 0.0, 0.0, 1.0]]",
            "rotations has 1 entries but path has 2",
        ),
        (
            "rotations = [[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 0.0]]",
            "rotations[1]",
        ),
        (
            "rotations = [[0.0, 0.0, 0.0, 1.0], [0.0, nan, 0.0, 1.0]]",
            "rotations[1]",
        ),
    ] {
        let e = dynaclay::io::parse_script(&script(rotations), "bad.toml").unwrap_err();
        let text = e.to_string();
        assert!(text.contains(says), "{text}");
        assert!(text.contains("bad.toml"), "names the file: {text}");
    }
}
