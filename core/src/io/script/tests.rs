use super::*;

#[test]
fn a_compact_rbf_step_takes_0_or_a_count_one_solve_holds() {
    let step = |n: u32| format!("version = 1\n\n[[step]]\ndo = \"compact_rbf\"\nparticles = {n}\n");
    for n in [0, 8, 400, 1000] {
        let script = parse_script(&step(n), "c.toml").unwrap();
        assert_eq!(script.steps, vec![ScriptStep::CompactRbf { particles: n }]);
    }
    for n in [3, 1001] {
        let shown = parse_script(&step(n), "c.toml").unwrap_err().to_string();
        assert!(
            shown.contains(&format!(
                "particles = {n} must be 0 (off) or between 8 and 1000"
            )),
            "{shown}"
        );
    }
}

#[test]
fn unbounded_values_are_refused_with_their_line() {
    let stroke = |field: &str| {
        format!("version = 1\n\n[[step]]\ndo = \"stroke\"\npath = [[0.1, 0.2, 0.3]]\n{field}\n")
    };
    let many: Vec<String> = (0..=MAX_POINTS).map(|_| "[0.1, 0.2, 0.3]".into()).collect();
    let cases = [
        (
            "version = 1\n\n[[step]]\ndo = \"undo\"\ncount = 4294967295\n".to_owned(),
            "count = 4294967295",
            5,
        ),
        (stroke("duration_s = 1e9"), "duration_s = 1000000000", 6),
        (stroke("start_s = 1e30"), "start_s = 1", 6),
        (
            format!(
                "version = 1\n\n[[step]]\ndo = \"tool\"\nshape = {{ kind = \"sphere\", radius_fu = 0.2 }}\naction = {{ kind = \"add\", deposit_rate_per_s = 1.0 }}\npositions = [{}]\n",
                many.join(", ")
            ),
            "positions has 10001 points",
            7,
        ),
    ];
    for (text, expected, line) in cases {
        let err = parse_script(&text, "bomb.toml").unwrap_err();
        let shown = err.to_string();
        assert!(shown.contains(expected), "{shown}");
        assert_eq!(err.line, Some(line), "{shown}");
        assert!(shown.contains("bomb.toml"), "{shown}");
    }
}

#[test]
fn a_device_or_an_oversized_file_is_not_read_as_a_script() {
    let err = load_script(std::path::Path::new("/dev/zero")).unwrap_err();
    assert!(err.to_string().contains("not a regular file"), "{err}");
    let dir = tempfile::tempdir().unwrap();
    let big = dir.path().join("big.toml");
    let file = std::fs::File::create(&big).unwrap();
    file.set_len(MAX_SCRIPT_BYTES + 1).unwrap();
    let err = load_script(&big).unwrap_err();
    assert!(err.to_string().contains("more than the"), "{err}");
}

const EXAMPLE: &str = r#"
version = 1

[[step]]
do = "tool"
shape = { kind = "sphere", radius_fu = 0.2 }
action = { kind = "add", deposit_rate_per_s = 4.0 }
positions = [[0.5, 0.5, 0.5], [0.6, 0.5, 0.5]]
duration_s = 0.5

[[step]]
do = "tool"
shape = { kind = "ellipsoid", radii_fu = [0.1, 0.2, 0.1] }
action = { kind = "stamp", s = 0.5, m = 0.15, r = 0.25, k = -2.0, n = 0.3 }
positions = [[0.5, 0.7, 0.5]]
rotation = [0.0, 0.0, 0.0, 1.0]

[[step]]
do = "tool"
shape = { kind = "capsule", radius_fu = 0.05, half_height_fu = 0.1 }
action = { kind = "contact", alpha = -2.0 }
positions = [[0.5, 0.7, 0.5]]

[[step]]
do = "stroke"
tool = { kind = "area", beta = "gaussian", radius_fu = 0.05, tracks = 5, gain = 1e6 }
path = [[0.9, 0.5, 0.5], [1.0, 0.5, 0.5]]
duration_s = 1.0

[[step]]
do = "material"
stiffness = 500.0
plasticity_per_s = 4.0

[[step]]
do = "csg"
op = "difference"
with = "other.dclay"

[[step]]
do = "undo"
count = 2

[[step]]
do = "redo"

[[step]]
do = "save"
path = "out.dclay"
"#;

#[test]
fn the_example_parses_into_every_kind_of_step() {
    let s = parse_script(EXAMPLE, "ex.toml").unwrap();
    assert_eq!(s.steps.len(), 9);
    assert!(matches!(
        s.steps[1],
        ScriptStep::Tool {
            action: ToolAction::Stamp(_),
            ..
        }
    ));
    assert_eq!(s.steps[6], ScriptStep::Undo { count: 2 });
    assert_eq!(s.steps[7], ScriptStep::Redo { count: 1 });
    let m = s.steps[4].updated_material(Material::ELASTIC);
    assert_eq!((m.stiffness, m.plasticity_per_s, m.mass), (500.0, 4.0, 1.0));
    // Round trip through the serde types (where each step is written is not carried).
    let text = toml::to_string(&s).unwrap();
    let again = parse_script(&text, "again").unwrap();
    assert_eq!(again.steps.len(), again.step_lines.len());
    assert_eq!(
        Script {
            step_lines: s.step_lines.clone(),
            ..again
        },
        s
    );
}

#[test]
fn syntax_and_type_errors_name_line_and_field() {
    let bad = "version = 1\n\n[[step]]\ndo = \"tool\"\nshape = { kind = \"sphere\", radius = 0.2 }\naction = { kind = \"remove\" }\npositions = [[0, 0, 0]]\n";
    let e = parse_script(bad, "bad.toml").unwrap_err();
    // The parser points at the step's header; the error names the field's own line.
    assert_eq!(e.line, Some(5), "{e}");
    assert!(e.message.contains("`radius`"), "{e}");
    assert!(e.to_string().starts_with("bad.toml:5"), "{e}");
    let bad = "version = 1\n[[step]]\ndo = \"undo\"\nspeed = 3\n";
    let e = parse_script(bad, "u.toml").unwrap_err();
    assert_eq!(e.line, Some(4), "{e}");
    let e = parse_script("version = \"one\"\n", "v.toml").unwrap_err();
    assert_eq!(e.line, Some(1), "{e}");

    let bad = "version = 1\n[[step]]\ndo = \"teleport\"\n";
    let e = parse_script(bad, "x").unwrap_err();
    assert!(e.message.contains("teleport"), "{e}");
    assert!(e.line.is_some());
}

#[test]
fn lines_come_from_the_parser_not_from_the_text_or_the_message() {
    // A header written with spaces, a comment that looks like one, and a value that
    // looks like the key: only the parser's spans find the right line.
    let text = "version = 1\n# [[step]] duration_s = 5\n[[ step ]]\ndo = \"stroke\"\npath = [[1, 1, 1]]\nduration_s = -2\n";
    let e = parse_script(text, "x").unwrap_err();
    assert_eq!((e.step, e.line), (Some(1), Some(6)), "{e}");
    let text = "version = 1\n[[step]]\ndo = \"save\"\npath = \"a\"\n[[step]]\ndo = \"undo\"\ncount = 4000000000\n";
    let e = parse_script(text, "x").unwrap_err();
    assert_eq!((e.step, e.line), (Some(2), Some(7)), "{e}");
    let text = "version = 1\n[autosave]\nevery_s = -1.0\n";
    assert_eq!(parse_script(text, "x").unwrap_err().line, Some(3));
}

#[test]
fn semantic_errors_name_the_step_and_its_line() {
    let bad = "version = 1\n\n[[step]]\ndo = \"undo\"\n\n[[step]]\ndo = \"tool\"\nshape = { kind = \"sphere\", radius_fu = -1.0 }\naction = { kind = \"remove\" }\npositions = [[0, 0, 0]]\n";
    let e = parse_script(bad, "x").unwrap_err();
    assert_eq!((e.step, e.line), (Some(2), Some(8)), "{e}");
    assert!(e.message.contains("radius_fu"), "{e}");
    let e = parse_script("version = 7\n", "x").unwrap_err();
    assert!(e.message.contains("version = 7"), "{e}");
    let bad = "version = 1\n[[step]]\ndo = \"stroke\"\ntool = { kind = \"chisel\", depth_fu = 0.0, radius_fu = 0.1, gain = 1.0 }\npath = []\nduration_s = 1.0\n";
    let e = parse_script(bad, "x").unwrap_err();
    assert!(e.message.contains("path"), "{e}");
    assert_eq!(e.line, Some(5), "{e}");
    // A material a session could not load back is refused here already.
    let bad = "version = 1\n[[step]]\ndo = \"material\"\ndamping = -2.0\n";
    let e = parse_script(bad, "x").unwrap_err();
    assert!(
        e.message
            .contains("damping = -2 must be finite and non-negative"),
        "{e}"
    );
}

#[test]
fn strokes_take_a_force_or_a_geometric_tool_and_optional_timing() {
    let good = r#"
version = 1
seconds = 2.5
[clay]
shape = "sphere"
resolution = 16
[autosave]
every_strokes = 1

[[step]]
do = "stroke"
path = [[1, 1, 1], [1.2, 1, 1]]
times_s = [0.0, 0.4]
buttons = 1

[[step]]
do = "stroke"
shape = { kind = "sphere", radius_fu = 0.1 }
action = { kind = "remove" }
path = [[1, 1, 1]]
start_s = 3.0
"#;
    let s = parse_script(good, "g.toml").unwrap();
    assert_eq!(s.clay.as_ref().unwrap().shape, ClayShape::Sphere);
    assert_eq!(s.autosave.unwrap().every_strokes, 1);
    assert_eq!(s.seconds, Some(2.5));
    assert_eq!(s.step_lines, vec![10, 16], "each step's table starts there");
    let text = toml::to_string(&s).unwrap();
    assert_eq!(
        Script {
            step_lines: s.step_lines.clone(),
            ..parse_script(&text, "again").unwrap()
        },
        s
    );

    let stroke = |body: &str| format!("version = 1\n[[step]]\ndo = \"stroke\"\n{body}");
    for (body, field, line) in [
        ("path = [[1, 1, 1]]\nduration_s = -2\n", "duration_s", 5),
        (
            "path = [[1, 1, 1], [2, 1, 1]]\ntimes_s = [0.0, 0.0]\n",
            "times_s[1]",
            5,
        ),
        ("path = [[1, 1, 1]]\ntimes_s = [0.0, 1.0]\n", "times_s", 5),
        ("path = [[1, 1, 1]]\nhover_m = 0\n", "hover_fu", 5),
        (
            "tool = { kind = \"push\", radius_fu = -1 }\npath = [[1, 1, 1]]\n",
            "radius_fu",
            4,
        ),
        (
            "tool = { kind = \"grab\", gain = 1 }\nshape = { kind = \"sphere\", radius_fu = 0.1 }\npath = [[1, 1, 1]]\n",
            "not both",
            4,
        ),
        (
            "shape = { kind = \"sphere\", radius_fu = 0.1 }\npath = [[1, 1, 1]]\n",
            "action",
            4,
        ),
    ] {
        let e = parse_script(&stroke(body), "s.toml").unwrap_err();
        assert!(e.message.contains(field), "{body}: {e}");
        assert_eq!(e.line, Some(line), "{body}: {e}");
    }
    let e = parse_script("version = 1\n[clay]\nresolution = 200\n", "c.toml").unwrap_err();
    assert_eq!(e.line, Some(3), "{e}");
    assert!(e.message.contains("clay.resolution"), "{e}");
}

#[test]
fn constrain_keys_must_match_their_kind() {
    let step = |keys: &str| format!("version = 1\n\n[[step]]\ndo = \"constrain\"\n{keys}\n");
    let ok = [
        "kind = \"point\"\nat = [1.0, 2.0, 3.0]",
        "kind = \"normal\"\nat = [1.0, 2.0, 3.0]",
        "kind = \"curve\"\npoints = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]",
    ];
    for keys in ok {
        parse_script(&step(keys), "pins.toml").unwrap_or_else(|e| panic!("{keys}: {e}"));
    }
    parse_script("version = 1\n\n[[step]]\ndo = \"unconstrain\"\n", "u.toml").unwrap();
    parse_script(
        "version = 1\n\n[[step]]\ndo = \"unconstrain\"\nindex = 2\n",
        "u.toml",
    )
    .unwrap();
    let bad = [
        ("kind = \"point\"", "needs at"),
        ("kind = \"curve\"\nat = [1.0, 2.0, 3.0]", "not at"),
        ("kind = \"curve\"\npoints = [[0.0, 0.0, 0.0]]", "at least 2"),
        ("kind = \"normal\"\nat = [1.0, 2.0, nan]", "not finite"),
        ("kind = \"edge\"\nat = [1.0, 2.0, 3.0]", "edge"),
    ];
    for (keys, expected) in bad {
        let err = parse_script(&step(keys), "pins.toml").unwrap_err();
        let shown = err.to_string();
        assert!(
            shown.contains(expected) && shown.contains("pins.toml"),
            "{keys}: {shown}"
        );
    }
    let err = parse_script(
        "version = 1\n\n[[step]]\ndo = \"unconstrain\"\nindex = -1\n",
        "u.toml",
    )
    .unwrap_err();
    assert_eq!(err.line, Some(5), "{err}");
}

#[test]
fn detail_steps_take_either_switch_and_name_the_step_that_sets_neither() {
    let step = |keys: &str| format!("version = 1\n\n[[step]]\ndo = \"detail\"\n{keys}\n");
    let s = parse_script(&step("force_tools = true"), "d.toml").unwrap();
    assert_eq!(
        s.steps[0],
        ScriptStep::Detail {
            automatic: None,
            force_tools: Some(true)
        }
    );
    assert_eq!(s.steps[0].name(), "detail");
    let s = parse_script(&step("automatic = false\nforce_tools = false"), "d.toml").unwrap();
    assert_eq!(
        s.steps[0],
        ScriptStep::Detail {
            automatic: Some(false),
            force_tools: Some(false)
        }
    );
    let err = parse_script(&step(""), "d.toml").unwrap_err();
    assert!(
        err.to_string()
            .contains("`automatic`, `force_tools` or both")
            && err.line == Some(3),
        "{err}"
    );
    let err = parse_script(&step("automatic = 1"), "d.toml").unwrap_err();
    assert!(err.to_string().contains("d.toml"), "{err}");
}

#[test]
fn material_steps_take_a_neighbourhood_and_paints_a_ball_or_a_box() {
    let step = |keys: &str| format!("version = 1\n\n[[step]]\n{keys}\n");
    let s = parse_script(&step("do = \"material\"\nneighbourhood = 26"), "m.toml").unwrap();
    let m = s.steps[0].updated_material(Material::PLASTIC);
    assert_eq!(m.neighbourhood, Neighbourhood::TwentySix);
    assert_eq!(m.stiffness, Material::PLASTIC.stiffness);
    let err = parse_script(&step("do = \"material\"\nneighbourhood = 12"), "m.toml").unwrap_err();
    assert!(
        err.to_string().contains("6, 18 or 26") && err.line == Some(5),
        "{err}"
    );

    let paint = |keys: &str| step(&format!("do = \"paint_material\"\n{keys}"));
    let s = parse_script(
        &paint("centre = [1.0, 1.5, 1.0]\nradius_fu = 0.2\nstiffness = 5000.0"),
        "p.toml",
    )
    .unwrap();
    assert_eq!(
        paint_request(&s.steps[0]).unwrap(),
        Some(MaterialPaint {
            region: PaintRegion::Sphere {
                centre: Vec3::new(1.0, 1.5, 1.0),
                radius_fu: 0.2
            },
            mass: None,
            damping: None,
            stiffness: Some(5000.0),
            plasticity_per_s: None,
        })
    );
    let s = parse_script(
        &paint("min = [0.0, 0.0, 0.0]\nmax = [1.0, 2.0, 3.0]\nmass = 4.0\ndamping = 0.0"),
        "p.toml",
    )
    .unwrap();
    let p = paint_request(&s.steps[0]).unwrap().unwrap();
    assert_eq!(
        (p.mass, p.damping, p.stiffness, p.plasticity_per_s),
        (Some(4.0), Some(0.0), None, None)
    );
    let s = parse_script(
        &paint("min = [0.0, 0.0, 0.0]\nmax = [1.0, 2.0, 3.0]\nplasticity_per_s = 0.0"),
        "p.toml",
    )
    .unwrap();
    let p = paint_request(&s.steps[0]).unwrap().unwrap();
    assert_eq!((p.mass, p.plasticity_per_s), (None, Some(0.0)));
    assert!(matches!(p.region, PaintRegion::Box { .. }));
    // Round trip through the serde types.
    let text = toml::to_string(&s).unwrap();
    assert_eq!(parse_script(&text, "again").unwrap(), s);
    let bad = [
        ("stiffness = 5.0", "needs a ball"),
        (
            "centre = [1.0, 1.0, 1.0]\nstiffness = 5.0",
            "also needs radius_fu",
        ),
        (
            "centre = [1.0, 1.0, 1.0]\nradius_fu = 0.2\nmin = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]\nmass = 1.0",
            "not both",
        ),
        (
            "centre = [1.0, 1.0, 1.0]\nradius_fu = 0.0\nmass = 1.0",
            "radius_fu = 0",
        ),
        (
            "min = [0.0, 2.0, 0.0]\nmax = [1.0, 1.0, 1.0]\nmass = 1.0",
            "empty",
        ),
        (
            "centre = [1.0, 1.0, 1.0]\nradius_fu = 0.2\nmass = 0.0",
            "mass must be positive",
        ),
        (
            "centre = [1.0, 1.0, 1.0]\nradius_fu = 0.2\nstiffness = -1.0",
            "stiffness = -1",
        ),
        (
            "centre = [1.0, 1.0, 1.0]\nradius_fu = 0.2\nplasticity_per_s = -2.0",
            "plasticity_per_s = -2 must be finite and non-negative",
        ),
        (
            "centre = [1.0, 1.0, 1.0]\nradius_fu = 0.2",
            "at least one of",
        ),
        (
            "centre = [1.0, nan, 1.0]\nradius_fu = 0.2\nmass = 1.0",
            "not finite",
        ),
    ];
    for (keys, expected) in bad {
        let err = parse_script(&paint(keys), "paint.toml").unwrap_err();
        let shown = err.to_string();
        assert!(
            shown.contains(expected) && shown.contains("paint.toml") && err.line.is_some(),
            "{keys}: {shown}"
        );
    }
}

#[test]
fn old_metre_keys_read_as_field_unit_keys_with_a_note_per_key() {
    let new = "version = 1\n\n[[step]]\ndo = \"tool\"\nshape = { kind = \"capsule\", radius_fu = 0.05, half_height_fu = 0.1 }\naction = { kind = \"smooth\", rate_per_s = 1.0, kernel_fu = 0.1 }\npositions = [[0, 0, 0]]\nfalloff_fu = 0.02\n\n[[step]]\ndo = \"stroke\"\ntool = { kind = \"chisel\", depth_fu = 0.03, radius_fu = 0.05, gain = 1e6 }\npath = [[1, 1, 1]]\nhover_fu = 0.2\n";
    let old = new.replace("_fu", "_m");
    let read_new = parse_script(new, "new.toml").unwrap();
    let read_old = parse_script(&old, "old.toml").unwrap();
    assert!(read_new.deprecated.is_empty());
    assert_eq!(read_old.steps, read_new.steps);
    let noted: Vec<(usize, &str, &str)> = read_old
        .deprecated
        .iter()
        .map(|d| (d.line, d.key, d.replacement))
        .collect();
    assert_eq!(
        noted,
        [
            (5, "radius_m", "radius_fu"),
            (5, "half_height_m", "half_height_fu"),
            (6, "kernel_m", "kernel_fu"),
            (8, "falloff_m", "falloff_fu"),
            (12, "depth_m", "depth_fu"),
            (12, "radius_m", "radius_fu"),
            (14, "hover_m", "hover_fu"),
        ]
    );
    let shown = read_old.deprecated[0].to_string();
    assert!(
        shown.starts_with("old.toml:5: `radius_m` is deprecated") && shown.contains("`radius_fu`"),
        "{shown}"
    );
    // A fault in an old key still names its line.
    let bad = old.replace("depth_m = 0.03", "depth_m = -1");
    let e = parse_script(&bad, "old.toml").unwrap_err();
    assert_eq!(e.line, Some(12), "{e}");
}

/// Each step's `name()` is the `do = …` key serde writes for it.
#[test]
fn a_steps_name_is_its_do_key() {
    let s = parse_script(EXAMPLE, "ex.toml").unwrap();
    for step in &s.steps {
        let text = toml::to_string(step).unwrap();
        let written = format!("do = \"{}\"", step.name());
        assert!(text.contains(&written), "{written} not in\n{text}");
    }
}

#[test]
fn mask_steps_paint_invert_and_clear_and_bad_brushes_name_their_key() {
    let step = |keys: &str| format!("version = 1\n\n[[step]]\n{keys}\n");
    let text = [
        "do = \"mask\"\npositions = [[1.0, 1.5, 1.0], [1.1, 1.5, 1.0]]\nradius_fu = 0.3",
        "do = \"mask\"\npositions = [[1.0, 1.5, 1.0]]\nradius_fu = 0.2\nstrength = 0.5\nfree = true",
        "do = \"mask_invert\"",
        "do = \"mask_clear\"",
    ]
    .map(step)
    .concat()
    .replace("version = 1\n\n", "\n");
    let s = parse_script(&format!("version = 1\n{text}"), "mask.toml").unwrap();
    let edits: Vec<MaskEdit> = s
        .steps
        .iter()
        .map(|st| mask_request(st).unwrap().unwrap())
        .collect();
    assert_eq!(
        edits[0],
        MaskEdit::Paint {
            brush: MaskBrush {
                radius_fu: 0.3,
                strength: 1.0,
                mode: MaskMode::Freeze
            },
            centres_fu: vec![Vec3::new(1.0, 1.5, 1.0), Vec3::new(1.1, 1.5, 1.0)],
        }
    );
    assert_eq!(edits[0].name(), "mask");
    let MaskEdit::Paint { brush, .. } = &edits[1] else {
        panic!("a paint, got {:?}", edits[1]);
    };
    assert_eq!((brush.strength, brush.mode), (0.5, MaskMode::Free));
    assert_eq!(edits[2..], [MaskEdit::Invert, MaskEdit::Clear]);
    assert_eq!(
        s.steps.iter().map(ScriptStep::name).collect::<Vec<_>>(),
        ["mask", "mask", "mask_invert", "mask_clear"]
    );
    let again = toml::to_string(&s).unwrap();
    assert_eq!(parse_script(&again, "again").unwrap().steps, s.steps);
    for (keys, expected) in [
        (
            "positions = [[0.0, 0.0, 0.0]]\nradius_fu = 0.0",
            "radius_fu = 0",
        ),
        (
            "positions = [[0.0, 0.0, 0.0]]\nradius_fu = 0.1\nstrength = 2.0",
            "strength = 2",
        ),
        ("positions = []\nradius_fu = 0.1", "at least one point"),
        (
            "positions = [[0.0, nan, 0.0]]\nradius_fu = 0.1",
            "not finite",
        ),
    ] {
        let err = parse_script(&step(&format!("do = \"mask\"\n{keys}")), "m.toml").unwrap_err();
        let shown = err.to_string();
        assert!(
            shown.contains(expected) && err.line.is_some(),
            "{keys}: {shown}"
        );
    }
}
