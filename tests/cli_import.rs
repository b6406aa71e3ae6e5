//! `dynaclay import`: a point cloud or a volume becomes a session whose clay is fitted to it,
//! with a mesh to check; bad files and arguments are refused with what and where.

use std::path::Path;
use std::process::Command;

use dynaclay::io::load_session;

const BIN: &str = env!("CARGO_BIN_EXE_dynaclay");

/// A torus's samples (ring radius 30, tube radius 10, file units): 150 × 60 points, each with
/// its outward normal.
fn torus_samples() -> Vec<([f32; 3], [f32; 3])> {
    let mut samples = Vec::with_capacity(150 * 60);
    for i in 0..150 {
        for j in 0..60 {
            let (u, v) = (
                i as f32 / 150.0 * std::f32::consts::TAU,
                j as f32 / 60.0 * std::f32::consts::TAU,
            );
            let r = 30.0 + 10.0 * v.cos();
            samples.push((
                [r * u.cos(), 10.0 * v.sin(), r * u.sin()],
                [v.cos() * u.cos(), v.sin(), v.cos() * u.sin()],
            ));
        }
    }
    samples
}

/// The torus of [`torus_samples`] as XYZ text, without normals.
fn write_torus_xyz(path: &Path) {
    let mut text = String::from("# torus\n");
    for ([x, y, z], _) in torus_samples() {
        text.push_str(&format!("{x} {y} {z}\n"));
    }
    std::fs::write(path, text).unwrap();
}

/// The torus of [`torus_samples`] with a normal per point (`x y z nx ny nz`): the outward
/// normal times `sign(i)` for point `i`.
fn write_torus_xyz_with_normals(path: &Path, sign: impl Fn(usize) -> f32) {
    let mut text = String::from("# torus with normals\n");
    for (i, ([x, y, z], normal)) in torus_samples().into_iter().enumerate() {
        let [nx, ny, nz] = normal.map(|c| c * sign(i));
        text.push_str(&format!("{x} {y} {z} {nx} {ny} {nz}\n"));
    }
    std::fs::write(path, text).unwrap();
}

/// `dynaclay import INPUT --out SESSION --mesh MESH EXTRA…`.
fn import(input: &Path, session: &Path, mesh: &Path, extra: &[&str]) -> std::process::Output {
    Command::new(BIN)
        .arg("import")
        .arg(input)
        .arg("--out")
        .arg(session)
        .arg("--mesh")
        .arg(mesh)
        .args(extra)
        .output()
        .unwrap()
}

/// [`import`], which must succeed: its log (stdout).
fn import_ok(input: &Path, session: &Path, mesh: &Path, extra: &[&str]) -> String {
    let out = import(input, session, mesh, extra);
    let said = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{said}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    said
}

/// Counts the OBJ mesh's vertices, faces and its Euler characteristic `V − E + F`, and whether
/// every edge has two faces (closed).
fn obj_topology(path: &Path) -> (usize, usize, i64, bool) {
    let text = std::fs::read_to_string(path).unwrap();
    let (mut v, mut faces) = (0usize, Vec::new());
    for line in text.lines() {
        let mut it = line.split_whitespace();
        match it.next() {
            Some("v") => v += 1,
            Some("f") => faces.push(
                it.map(|t| t.split('/').next().unwrap().parse::<usize>().unwrap())
                    .collect::<Vec<_>>(),
            ),
            _ => {}
        }
    }
    let mut edges = std::collections::HashMap::new();
    for f in &faces {
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_insert(0u32) += 1;
        }
    }
    let closed = edges.values().all(|&n| n == 2);
    let euler = v as i64 - edges.len() as i64 + faces.len() as i64;
    (v, faces.len(), euler, closed)
}

#[test]
fn a_torus_cloud_imports_as_a_closed_genus_one_clay() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("torus.xyz");
    write_torus_xyz(&input);
    let (session, mesh) = (dir.path().join("torus.dclay"), dir.path().join("torus.obj"));
    let out = import(&input, &session, &mesh, &["--timings"]);
    let said = String::from_utf8_lossy(&out.stdout);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{said}{err}");
    assert!(said.contains("9000 points"), "{said}");
    // `--timings` lists the stages on stderr, the signing's own indented under the fit's.
    for stage in [
        " ms  reading",
        " ms      screening",
        " ms    signing",
        " ms  fit",
        " ms  meshing beside the session's encoding",
        " ms  writing",
    ] {
        assert!(err.contains(stage), "{stage:?} in {err}");
    }
    assert!(
        !said.contains(" ms  "),
        "the log on stdout is unchanged: {said}"
    );
    let loaded = load_session(&session).expect("the session loads");
    assert_eq!(loaded.clay.density.patches[0].lattice.dims, [32; 3]);
    assert!(
        said.contains("depth 1:"),
        "the octree's first level is reported: {said}"
    );
    let (v, f, euler, closed) = obj_topology(&mesh);
    assert!(v > 1000 && f > 2000, "{v} vertices, {f} faces");
    assert!(closed, "the fitted surface is closed");
    assert_eq!(euler, 0, "a torus has genus one (V − E + F = 0)");
}

#[test]
fn normals_pointing_in_are_turned_and_normals_of_either_sign_give_way_to_the_flood() {
    let dir = tempfile::tempdir().unwrap();
    for (name, sign, said_wanted, signed_by) in [
        (
            "inward",
            (|_| -1.0) as fn(usize) -> f32,
            "the file's normals point inward (9000 of the 9000 points that show a side): \
             turned them all outward",
            "signed by the normals",
        ),
        (
            "either",
            |i| if (i * 7) % 3 == 0 { -1.0 } else { 1.0 },
            "the file's normals disagree on which side is out",
            "signed by flood tagging",
        ),
    ] {
        let input = dir.path().join(format!("{name}.xyz"));
        write_torus_xyz_with_normals(&input, sign);
        let (session, mesh) = (
            dir.path().join(format!("{name}.dclay")),
            dir.path().join(format!("{name}.obj")),
        );
        let said = import_ok(&input, &session, &mesh, &[]);
        assert!(said.contains("9000 points with normals"), "{name}: {said}");
        assert!(said.contains(said_wanted), "{name}: {said}");
        assert!(said.contains(signed_by), "{name}: {said}");
        let (_, _, euler, closed) = obj_topology(&mesh);
        assert!(closed, "{name}: the fitted surface is closed");
        assert_eq!(euler, 0, "{name}: one torus, genus one (V − E + F = 0)");
    }
}

#[test]
fn one_view_of_a_torus_without_normals_closes_round_its_hole() {
    // The torus seen from above (the points whose outward normal leans up by more than
    // 0.2), without normals, as one pass of a depth camera gives it: the flood goes round
    // the open sheet, whose points' sides are guesses; oriented by their neighbours', the
    // sheet closes into one clay with the torus's hole through it.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("view.xyz");
    let mut text = String::from("# the top of a torus\n");
    for ([x, y, z], [_, ny, _]) in torus_samples() {
        if ny > 0.2 {
            text.push_str(&format!("{x} {y} {z}\n"));
        }
    }
    std::fs::write(&input, text).unwrap();
    let (session, mesh) = (dir.path().join("view.dclay"), dir.path().join("view.obj"));
    let said = import_ok(&input, &session, &mesh, &[]);
    assert!(said.contains("signed by flood tagging"), "{said}");
    assert!(said.contains("points lie on open sheets"), "{said}");
    let (_, _, euler, closed) = obj_topology(&mesh);
    assert!(closed, "the fitted surface is closed");
    assert_eq!(
        euler, 0,
        "one piece with the torus's hole, genus one (V − E + F = 0)"
    );
}

#[test]
fn a_torus_with_one_side_sampled_sparsely_keeps_that_sides_points_and_says_so() {
    // A noisy torus (tube 10, ring 30, noise 0.2 along the normal) whose side with x < 0
    // keeps one point in ten, as the side of a scan away from the scanner: those points
    // have a tenth of the typical count of neighbours, and by the count alone 438 of its
    // 1 500 were dropped as isolated.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("sparse_side.xyz");
    let mut seed = 12_345_u32;
    let mut uniform = || {
        seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
        seed as f32 / 2f32.powi(32)
    };
    let mut text = String::from("# a torus, one side sparse\n");
    for i in 0..300 {
        for j in 0..100 {
            let (u, v) = (
                (i as f32 + 0.5) / 300.0 * std::f32::consts::TAU,
                (j as f32 + 0.5) / 100.0 * std::f32::consts::TAU,
            );
            let tube = 10.0 + 0.2 * ((0..12).map(|_| uniform()).sum::<f32>() - 6.0);
            let r = 30.0 + tube * v.cos();
            let [x, y, z] = [r * u.cos(), tube * v.sin(), r * u.sin()];
            if x < 0.0 && (i * 100 + j) % 10 != 0 {
                continue;
            }
            let [nx, ny, nz] = [v.cos() * u.cos(), v.sin(), v.cos() * u.sin()];
            text.push_str(&format!("{x} {y} {z} {nx} {ny} {nz}\n"));
        }
    }
    std::fs::write(&input, text).unwrap();
    let (session, mesh) = (
        dir.path().join("sparse.dclay"),
        dir.path().join("sparse.obj"),
    );
    let said = import_ok(&input, &session, &mesh, &[]);
    let dropped: usize = said
        .split("dropped ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .and_then(|n| n.parse().ok())
        .expect("the log says how many points were dropped as isolated");
    assert!(dropped < 50, "{said}");
    assert!(
        said.contains("points of sparsely sampled areas"),
        "the log says how many points were kept by their nearest neighbours: {said}"
    );
    let (_, _, euler, closed) = obj_topology(&mesh);
    assert!(closed, "the fitted surface is closed");
    assert_eq!(euler, 0, "one torus, genus one (V − E + F = 0)");
}

#[test]
fn a_hole_a_little_wider_than_the_gap_is_closed_by_the_widest_where_the_normals_are_given() {
    // A sphere of radius 1 with its outward normals, 40 000 points, open through a hole of
    // half-angle 10.5° at its bottom: about six knot spans across, wider than the default
    // gap closes (5), narrower than the widest (7). The outside gets in and lies on both
    // sides of nearly every point; at the default gap the clay dipped 16% into the hole.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("holed.xyz");
    let (count, golden) = (40_000, std::f64::consts::PI * (3.0 - 5f64.sqrt()));
    let mut text = String::from("# a sphere open at its bottom\n");
    for i in 0..count {
        let y = 1.0 - 2.0 * (i as f64 + 0.5) / count as f64;
        let ring = (1.0 - y * y).sqrt();
        let (x, z) = (
            ring * (golden * i as f64).cos(),
            ring * (golden * i as f64).sin(),
        );
        if -y > 10.5f64.to_radians().cos() {
            continue;
        }
        text.push_str(&format!("{x} {y} {z} {x} {y} {z}\n"));
    }
    std::fs::write(&input, text).unwrap();
    let (session, mesh) = (dir.path().join("holed.dclay"), dir.path().join("holed.obj"));
    let said = import_ok(&input, &session, &mesh, &[]);
    assert!(
        said.contains("closed gaps up to 3.5 spans instead"),
        "the log says the gap was widened: {said}"
    );
    let (_, _, euler, closed) = obj_topology(&mesh);
    assert!(closed && euler == 2, "one closed ball: V − E + F = {euler}");
    // The mesh's vertices about their centroid: within 5% of their median radius all round,
    // the hole's cap included.
    let vertices: Vec<glam::Vec3> = std::fs::read_to_string(&mesh)
        .unwrap()
        .lines()
        .filter_map(|line| line.strip_prefix("v "))
        .map(|rest| {
            let c: Vec<f32> = rest
                .split_whitespace()
                .map(|v| v.parse().unwrap())
                .collect();
            glam::Vec3::new(c[0], c[1], c[2])
        })
        .collect();
    let centre = vertices.iter().copied().sum::<glam::Vec3>() / vertices.len() as f32;
    let mut radii: Vec<f32> = vertices.iter().map(|v| (*v - centre).length()).collect();
    radii.sort_by(f32::total_cmp);
    let median = radii[radii.len() / 2];
    let (least, most) = (radii[0] / median, radii[radii.len() - 1] / median);
    assert!(
        least > 0.95 && most < 1.05,
        "radii {least}–{most} of the median"
    );
}

#[test]
fn one_view_of_a_torus_as_an_open_mesh_is_fitted_with_its_windings_normals() {
    // The torus's top (the grid's quads whose outward normal leans up by more than 0.2) as an
    // OBJ mesh, wound outward, and the same wound inward: too open to cap, each is fitted as
    // points sampled from its triangles with their winding's normals. The open band shows no
    // side of the exterior, so either winding is kept: the band closes into a shell on the
    // side its normals point away from, round the torus's hole either way.
    let dir = tempfile::tempdir().unwrap();
    let (rows, columns) = (150usize, 60usize);
    let vertex = |i: usize, j: usize| (i % rows) * columns + (j % columns) + 1;
    for (name, inward) in [("out", false), ("in", true)] {
        let mut text = String::new();
        for ([x, y, z], _) in torus_samples() {
            text.push_str(&format!("v {x} {y} {z}\n"));
        }
        for i in 0..rows {
            for j in 0..columns {
                let v = (j as f32 + 0.5) / columns as f32 * std::f32::consts::TAU;
                if v.sin() <= 0.2 {
                    continue;
                }
                let mut quad = [
                    vertex(i, j),
                    vertex(i, j + 1),
                    vertex(i + 1, j + 1),
                    vertex(i + 1, j),
                ];
                if inward {
                    quad.reverse();
                }
                let [a, b, c, d] = quad;
                text.push_str(&format!("f {a} {b} {c} {d}\n"));
            }
        }
        let input = dir.path().join(format!("{name}.obj"));
        std::fs::write(&input, text).unwrap();
        let (session, mesh) = (
            dir.path().join(format!("{name}.dclay")),
            dir.path().join(format!("{name}_fit.obj")),
        );
        let said = import_ok(&input, &session, &mesh, &[]);
        assert!(
            said.contains("fitting it as a point cloud sampled from its triangles"),
            "{name}: {said}"
        );
        assert!(said.contains("points with normals"), "{name}: {said}");
        assert!(said.contains("signed by the normals"), "{name}: {said}");
        let (_, _, euler, closed) = obj_topology(&mesh);
        assert!(closed, "{name}: the fitted surface is closed");
        assert_eq!(
            euler, 0,
            "{name}: genus one round the torus's hole (V − E + F = 0)"
        );
    }
}

#[test]
fn a_cloud_far_from_the_files_origin_is_read_about_its_centre() {
    // The torus (outer radius 40) placed at georeferenced coordinates, metres at a few
    // million, where `f32` steps by a quarter of a metre: read as it is, it is lumpy; read
    // about its centre, it is the torus.
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("site.xyz");
    let mut text = String::new();
    for ([x, y, z], _) in torus_samples() {
        let at = [
            512_345.6 + f64::from(x),
            5_234_567.8 + f64::from(y),
            120.0 + f64::from(z),
        ];
        text.push_str(&format!("{:.4} {:.4} {:.4}\n", at[0], at[1], at[2]));
    }
    std::fs::write(&input, text).unwrap();
    let (session, mesh) = (dir.path().join("site.dclay"), dir.path().join("site.obj"));
    let said = import_ok(&input, &session, &mesh, &[]);
    assert!(
        said.contains("read in double precision relative to (512345."),
        "{said}"
    );
    let (_, _, euler, closed) = obj_topology(&mesh);
    assert!(closed, "the fitted surface is closed");
    assert_eq!(euler, 0, "one torus, genus one (V − E + F = 0)");
}

#[test]
fn bad_point_files_and_arguments_are_refused_with_where_and_why() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.xyz");
    std::fs::write(&bad, "0 0 0\n1 2 x\n").unwrap();
    let empty = dir.path().join("empty.xyz");
    std::fs::write(&empty, "# nothing\n").unwrap();
    let huge = dir.path().join("huge.ply");
    std::fs::write(
        &huge,
        "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
    )
    .unwrap();
    let nan = dir.path().join("nan.xyz");
    std::fs::write(&nan, "0 0 0\n1 1 1\n2 nan 2\n").unwrap();
    let nan_voxel = dir.path().join("nan.raw");
    let mut voxels: Vec<u8> = Vec::new();
    for n in 0..8 {
        let v = if n == 5 { f32::NAN } else { n as f32 };
        voxels.extend(v.to_le_bytes());
    }
    std::fs::write(&nan_voxel, &voxels).unwrap();
    // Five points far apart: each alone, no surface between them.
    let scattered = dir.path().join("scattered.xyz");
    std::fs::write(&scattered, "0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 1 1\n").unwrap();
    // Points spread over 10³⁸ units: past the fit's arithmetic (once a panic).
    let vast = dir.path().join("vast.xyz");
    std::fs::write(&vast, "1e38 0 0\n-1e38 0 0\n0 1e38 0\n0 0 1e38\n").unwrap();
    // A closed octahedron 2·10²⁰ across: its weld's diagonal overflowed `f32` and every
    // vertex welded to one (the error then blamed the triangles' count).
    let vast_mesh = dir.path().join("vast.obj");
    let mut octahedron = String::new();
    for v in [
        "1e20 0 0",
        "-1e20 0 0",
        "0 1e20 0",
        "0 -1e20 0",
        "0 0 1e20",
        "0 0 -1e20",
    ] {
        octahedron.push_str(&format!("v {v}\n"));
    }
    octahedron.push_str("f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n");
    std::fs::write(&vast_mesh, &octahedron).unwrap();
    // The same octahedron 2·10⁻⁴⁰ across: its coordinates are subnormal.
    let speck_mesh = dir.path().join("speck.obj");
    std::fs::write(&speck_mesh, octahedron.replace("1e20", "1e-40")).unwrap();
    let stl = dir.path().join("huge.stl");
    let mut header = vec![0u8; 80];
    header.extend(4_000_000_000u32.to_le_bytes());
    std::fs::write(&stl, &header).unwrap();
    let out_ok = dir.path().join("out.dclay");
    let volume_args = |path: &'static str| -> Vec<&'static std::ffi::OsStr> {
        ["--iso", "1", "--sample", "f32", "--dims", path]
            .iter()
            .map(|s| std::ffi::OsStr::new(*s))
            .collect()
    };
    let mut nan_volume = vec![nan_voxel.as_os_str()];
    nan_volume.extend(volume_args("2,2,2"));
    let mut huge_volume = vec![nan_voxel.as_os_str()];
    huge_volume.extend(volume_args("100000,100000,100000"));
    let cases: Vec<(Vec<&std::ffi::OsStr>, &str)> = vec![
        (
            vec![nan.as_os_str()],
            "nan.xyz:3: `nan` is not a finite number",
        ),
        (nan_volume, "voxel 5 is NaN"),
        (huge_volume, "dimensions [100000, 100000, 100000]"),
        (vec![stl.as_os_str()], "huge.stl"),
        (vec![bad.as_os_str()], "bad.xyz:2: `x` is not a number"),
        (vec![empty.as_os_str()], "empty.xyz: no points"),
        (
            vec![scattered.as_os_str()],
            "scattered.xyz: the 5 points do not sample a surface",
        ),
        (vec![huge.as_os_str()], "4000000000 vertices declared"),
        (
            vec![vast.as_os_str()],
            "vast.xyz: the cloud spans 2e38 units",
        ),
        (
            vec![vast_mesh.as_os_str()],
            "vast.obj: the mesh spans 2e20 units",
        ),
        (vec![speck_mesh.as_os_str()], "speck.obj: the mesh spans"),
        (vec!["/dev/zero".as_ref()], "unknown format"),
    ];
    for (args, want) in cases {
        let out = Command::new(BIN)
            .arg("import")
            .args(&args)
            .arg("--out")
            .arg(&out_ok)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.contains(want), "{err}");
        assert!(!out_ok.exists(), "nothing written for a refused file");
    }
    let torus = dir.path().join("t.xyz");
    write_torus_xyz(&torus);
    for (flag, value, want) in [
        ("--out", "x.txt", "written as .dclay"),
        ("--resolution", "4", "resolution 4"),
        ("--gap", "5", "gap 5 spans"),
        ("--error", "0", "error bound 0"),
        ("--max-depth", "9", "max depth 9"),
    ] {
        let mut cmd = Command::new(BIN);
        cmd.arg("import").arg(&torus);
        if flag != "--out" {
            cmd.arg("--out").arg(&out_ok);
        }
        let out = cmd.arg(flag).arg(value).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{flag}: {err}");
        assert!(err.contains(want), "{flag}: {err}");
    }
}

#[test]
fn a_raw_volume_imports_at_its_iso_value_as_a_closed_ball() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("ball.raw");
    // 40³ unsigned bytes: 255 at the centre falling to 0 twenty voxels out.
    let mut bytes = Vec::new();
    for k in 0..40 {
        for j in 0..40 {
            for i in 0..40 {
                let d = ((i as f32 - 19.5).powi(2)
                    + (j as f32 - 19.5).powi(2)
                    + (k as f32 - 19.5).powi(2))
                .sqrt();
                bytes.push((255.0 * (1.0 - d / 20.0)).clamp(0.0, 255.0) as u8);
            }
        }
    }
    std::fs::write(&input, &bytes).unwrap();
    let session = dir.path().join("ball.dclay");
    let run = |extra: &[&str]| {
        Command::new(BIN)
            .arg("import")
            .arg(&input)
            .arg("--out")
            .arg(&session)
            .args(extra)
            .output()
            .unwrap()
    };
    let out = run(&["--dims", "40,40,40"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--iso"));
    let out = run(&["--iso", "128", "--dims", "40,40,41"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("64000 bytes of samples"), "{err}");

    let obj = dir.path().join("ball.obj");
    let out = run(&["--iso", "128", "--dims", "40,40,40", "--mesh"]);
    assert_eq!(out.status.code(), Some(2), "--mesh needs a file");
    let out = Command::new(BIN)
        .arg("import")
        .arg(&input)
        .args(["--iso", "128", "--dims", "40,40,40", "--out"])
        .arg(&session)
        .arg("--mesh")
        .arg(&obj)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(load_session(&session).is_ok());
    let (_, _, euler, closed) = obj_topology(&obj);
    assert!(closed);
    assert_eq!(euler, 2, "a ball has genus zero");
}

#[test]
fn a_cube_mesh_imports_as_a_closed_clay_near_its_faces() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("cube.obj");
    // A 20-unit cube as quads (its winding does not matter: normals are estimated).
    std::fs::write(
        &input,
        "v 0 0 0\nv 20 0 0\nv 20 20 0\nv 0 20 0\nv 0 0 20\nv 20 0 20\nv 20 20 20\nv 0 20 20\n\
         f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n",
    )
    .unwrap();
    let (session, mesh) = (
        dir.path().join("cube.dclay"),
        dir.path().join("cube.obj.out.obj"),
    );
    import_ok(&input, &session, &mesh, &[]);
    let (_, _, euler, closed) = obj_topology(&mesh);
    assert!(closed);
    assert_eq!(euler, 2, "a cube has genus zero");
    // The fitted clay's box: 24 spans wide (the lattice less four spans each side), so its
    // faces sit 11.5 spans from the centre; rounded edges pull in, faces stay within a span.
    let lattice = &load_session(&session).unwrap().clay.density.patches[0].lattice;
    let centre = glam::Vec3::splat(15.5 * lattice.spacing);
    for dir in [glam::Vec3::X, glam::Vec3::NEG_Y, glam::Vec3::Z] {
        let (mut a, mut b) = (0.0f32, 20.0 * lattice.spacing);
        for _ in 0..40 {
            let m = 0.5 * (a + b);
            if lattice.value(centre + dir * m) > lattice.iso {
                a = m;
            } else {
                b = m;
            }
        }
        let spans = 0.5 * (a + b) / lattice.spacing;
        assert!(
            (spans - 11.5).abs() < 0.5,
            "face along {dir} at {spans} spans"
        );
    }
}

#[test]
fn a_script_starts_from_an_imported_session() {
    let dir = tempfile::tempdir().unwrap();
    let cloud = dir.path().join("torus.xyz");
    write_torus_xyz(&cloud);
    let session = dir.path().join("scan.dclay");
    let out = Command::new(BIN)
        .arg("import")
        .arg(&cloud)
        .arg("--out")
        .arg(&session)
        .output()
        .unwrap();
    assert!(out.status.success());
    let script = dir.path().join("start.toml");
    std::fs::write(
        &script,
        "version = 1\nseconds = 0.2\n[clay]\nsession = \"scan.dclay\"\n",
    )
    .unwrap();
    let results = dir.path().join("out");
    let out = Command::new(BIN)
        .args(["run", "--lockstep", "--script"])
        .arg(&script)
        .arg("--out")
        .arg(&results)
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{said}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(said.contains("starting from"), "{said}");
    let imported = load_session(&session).unwrap();
    let written = load_session(&results.join("session.dclay")).unwrap();
    assert_eq!(
        written.clay.density.patches[0].lattice.dims, imported.clay.density.patches[0].lattice.dims,
        "the run sculpted the imported clay"
    );
    // A missing session is an argument error naming it.
    std::fs::write(
        &script,
        "version = 1\nseconds = 0.2\n[clay]\nsession = \"nowhere.dclay\"\n",
    )
    .unwrap();
    let out = Command::new(BIN)
        .args(["run", "--lockstep", "--script"])
        .arg(&script)
        .arg("--out")
        .arg(&results)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("nowhere.dclay"));
}

#[test]
fn a_mesh_over_the_memory_budget_is_refused_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("torus.xyz");
    write_torus_xyz(&input);
    let (session, mesh) = (dir.path().join("torus.dclay"), dir.path().join("torus.obj"));
    let out = import(&input, &session, &mesh, &["--memory-budget-mib", "1"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("memory budget of 1.0 MiB"), "{err}");
    assert!(err.contains("--resolution"), "{err}");
    assert!(!session.exists() && !mesh.exists());
}

#[test]
fn ctrl_c_during_a_fit_exits_130_and_writes_nothing() {
    use std::io::{BufRead, BufReader};
    let dir = tempfile::tempdir().unwrap();
    // A binary PLY of 1.5M points on a sphere: the signing alone takes a while.
    let input = dir.path().join("big.ply");
    let count = 1_500_000usize;
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {count}\nproperty float x\n\
         property float y\nproperty float z\nend_header\n"
    )
    .into_bytes();
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    for i in 0..count {
        let y = 1.0 - 2.0 * (i as f32 + 0.5) / count as f32;
        let r = (1.0 - y * y).sqrt();
        for c in [
            r * (golden * i as f32).cos(),
            y,
            r * (golden * i as f32).sin(),
        ] {
            bytes.extend(c.to_le_bytes());
        }
    }
    std::fs::write(&input, bytes).unwrap();
    let (session, mesh) = (dir.path().join("big.dclay"), dir.path().join("big.obj"));
    let mut child = Command::new(BIN)
        .arg("import")
        .arg(&input)
        .arg("--out")
        .arg(&session)
        .arg("--mesh")
        .arg(&mesh)
        .args(["--resolution", "96"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // The first line is said once the file is read, just before the fit starts.
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    assert!(line.contains("1500000 points"), "{line}");
    let sent = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted"), "{err}");
    assert!(!session.exists() && !mesh.exists(), "nothing written");
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| n != "big.ply")
        .collect();
    assert!(
        leftovers.is_empty(),
        "no temporary files left: {leftovers:?}"
    );
}

#[test]
fn a_tight_error_bound_adds_detail_patches_at_finer_spacings_to_the_session() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("cube.obj");
    // A cube's sharp edges are more than a 32³ base can hold at a tenth of a percent.
    std::fs::write(
        &input,
        "v 0 0 0\nv 20 0 0\nv 20 20 0\nv 0 20 0\nv 0 0 20\nv 20 0 20\nv 20 20 20\nv 0 20 20\n\
         f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n",
    )
    .unwrap();
    let run = |depth: &str, name: &str| {
        let (session, mesh) = (
            dir.path().join(format!("{name}.dclay")),
            dir.path().join(format!("{name}.obj")),
        );
        let said = import_ok(
            &input,
            &session,
            &mesh,
            &["--error", "0.1", "--max-depth", depth],
        );
        (load_session(&session).unwrap(), obj_topology(&mesh), said)
    };
    let (flat, _, _) = run("0", "flat");
    assert_eq!(
        flat.clay.density.patches.len(),
        1,
        "depth 0 is the base alone"
    );
    let (deep, (_, _, euler, closed), said) = run("2", "deep");
    assert!(deep.clay.density.patches.len() > 1, "{said}");
    assert!(said.contains("depth 1:"), "{said}");
    let base = deep.clay.base().spacing;
    for p in &deep.clay.density.patches[1..] {
        let ratio = base / p.lattice.spacing;
        assert!(
            (ratio - 2.0).abs() < 1e-4 || (ratio - 4.0).abs() < 1e-4,
            "a detail patch at 1/{ratio} of the base spacing"
        );
    }
    assert!(closed, "the summed surface is closed");
    assert_eq!(euler, 2);
}

#[test]
fn the_mesh_lies_over_the_cloud_in_the_clouds_own_coordinates() {
    // A sphere of radius 5 about (20, −3, 7), 4 000 points with outward normals: the clay is
    // fitted in its own lattice, and `--mesh` writes the surface back where the points are.
    // Every vertex lies within 2% of the radius of the sphere; far from the file's origin
    // (the same sphere 10⁴ along x, over 256 sizes away: read about its centre) too.
    let dir = tempfile::tempdir().unwrap();
    for (name, centre) in [("near", [20.0, -3.0, 7.0]), ("far", [1.0e4, -3.0, 7.0])] {
        let centre = glam::DVec3::from_array(centre);
        let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
        let mut text = String::new();
        for i in 0..4000 {
            let y = 1.0 - 2.0 * (f64::from(i) + 0.5) / 4000.0;
            let ring = (1.0 - y * y).sqrt();
            let n = glam::DVec3::new(
                ring * (golden * f64::from(i)).cos(),
                y,
                ring * (golden * f64::from(i)).sin(),
            );
            let p = centre + n * 5.0;
            text.push_str(&format!(
                "{} {} {} {} {} {}\n",
                p.x, p.y, p.z, n.x, n.y, n.z
            ));
        }
        let input = dir.path().join(format!("{name}.xyz"));
        std::fs::write(&input, text).unwrap();
        let (session, mesh) = (
            dir.path().join(format!("{name}.dclay")),
            dir.path().join(format!("{name}.obj")),
        );
        import_ok(&input, &session, &mesh, &[]);
        let mut count = 0;
        for line in std::fs::read_to_string(&mesh).unwrap().lines() {
            let Some(rest) = line.strip_prefix("v ") else {
                continue;
            };
            let c: Vec<f64> = rest
                .split_whitespace()
                .map(|v| v.parse().unwrap())
                .collect();
            let r = (glam::DVec3::new(c[0], c[1], c[2]) - centre).length();
            assert!(
                (r - 5.0).abs() < 0.1,
                "{name}: a vertex {r} from the centre (radius 5)"
            );
            count += 1;
        }
        assert!(count > 1000, "{name}: {count} vertices");
    }
}
