//! A turned hand turns the tool: a script stroke's `rotations` reach the simulated arm, which
//! reports them, and the engine applies the geometric tool turned. A long box drawn along its
//! length cuts a narrow groove; the same box turned a quarter turn about the vertical cuts a
//! wide one. Measured on the simulation's field after the run.

use dynaclay::dynamics::surface_point_on_ray;
use dynaclay::engine::ScriptDriver;
use dynaclay::field::MultiPatchField;
use glam::Vec3;

#[path = "support/lockstep.rs"]
mod lockstep;

use lockstep::{Scripted, scripted};

/// A box 0.6 long (x), 0.2 wide and 0.2 high drawn along x over the block's top, 0.1 deep;
/// `rotations` is spliced in as the stroke's `rotations` line (or nothing).
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
path = [[0.6, 1.3, 0.95], [1.3, 1.3, 0.95]]
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

/// The clay's top at `(x, z)`.
fn top(field: &MultiPatchField, x: f32, z: f32) -> f32 {
    surface_point_on_ray(field, Vec3::new(x, 0.8, z), Vec3::Y, 1.0, 0.005).map_or(f32::NAN, |p| p.y)
}

/// The groove's width across the path at its middle (x 0.95, z 0.95): the run of z around the
/// path over which the top is more than 0.05 below the untouched top.
fn groove_width(field: &MultiPatchField, untouched: f32) -> f32 {
    let (x, z0, step) = (0.95, 0.95, 0.005);
    let cut = |z: f32| top(field, x, z) < untouched - 0.05;
    let reach = |dir: f32| {
        let mut k = 0;
        while k < 200 && cut(z0 + dir * step * (k + 1) as f32) {
            k += 1;
        }
        k as f32 * step
    };
    if cut(z0) {
        reach(1.0) + reach(-1.0)
    } else {
        0.0
    }
}

#[test]
fn a_quarter_turned_box_cuts_a_groove_as_wide_as_it_is_long() {
    let untouched = {
        let dir = tempfile::tempdir().unwrap();
        let s = scripted(&script(""), "plain.toml", dir.path());
        top(s.run.density(), 0.95, 0.95)
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
