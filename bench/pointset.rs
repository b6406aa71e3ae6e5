//! The point-set surface against Guo & Qin's tables (run with `cargo bench --bench pointset`).
//!
//! - Table 2, construction time against point count (674 points in 2.85 s, 35,947 in 170 s on
//!   a 1.4 GHz Pentium IV): Fibonacci spheres of the same counts, no normals, so every stage
//!   runs (k-d tree and neighbours, plane normals, MST orientation, the weighted least-squares
//!   fit of each local field); the median of three builds, and the stages of the last one.
//! - Table 3, update time per step on a 40×40×40 mass grid with 225 / 450 / 910 points inside
//!   (67 / 169 / 381 ms): one sculpting step under a pull, split into the density-spring step
//!   on the grid, the local-domain update (eight-corner blend and eq. 4) and the point motion
//!   (eq. 9); the median over 200 steps after 20 to warm up. The paper's figure includes the
//!   whole update; ours are given apart and together.
//!
//! - The live follower (no table in the paper): a point set on a clay lattice follows it in
//!   the GUI's graphics loop (`PointFollower::update`: eq. 9 as Newton steps on the clay, then
//!   at most 256 insertions or removals); one update on a still clay, and the updates after a
//!   push until the points settle.
//!
//! Optimistic where: the clouds are clean spheres (no noise, no duplicates), and the update
//! runs on one thread with the region already set up.

use std::time::Instant;

use dynaclay::dynamics::{Distribution, Material, ToolForce, surface_point_on_ray};
use dynaclay::field::{BSplineLattice, MultiPatchField, fit_lattice};
use dynaclay::fit::PointCloud;
use dynaclay::pointset::{
    FollowedPoints, PointFollower, PointSet, PointSetOptions, PointSetSculpt, SculptOptions,
};
use glam::Vec3;

fn sphere(count: usize, radius: f32) -> PointCloud {
    let points = (0..count)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / count as f32;
            let r = (1.0 - z * z).sqrt();
            let a = i as f32 * 2.399_963;
            radius * Vec3::new(r * a.cos(), r * a.sin(), z)
        })
        .collect();
    PointCloud {
        points,
        normals: None,
    }
}

/// CPU time of this process (all threads, user and system), seconds, from `/proc/self/stat`
/// (clock ticks of 10 ms); `None` where that file is missing.
fn cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the parenthesised name; utime and stime are the 14th and 15th overall.
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn construction() {
    println!("\n### Construction (Table 2)\n");
    println!(
        "| points | paper | ours (median of 3) | paper ÷ ours | CPU per build (mean of 3) | neighbours | normals | MST | fits |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    for (count, paper_s) in [
        (674usize, 2.8528f64),
        (4348, 19.277),
        (6542, 26.85),
        (8171, 37.79),
        (35947, 169.803),
    ] {
        let cloud = sphere(count, 1.0);
        let mut runs = Vec::new();
        let mut last = None;
        let cpu0 = cpu_seconds();
        for _ in 0..3 {
            let t = Instant::now();
            let (set, times) =
                PointSet::build(&cloud, &PointSetOptions::default()).expect("builds");
            runs.push(t.elapsed().as_secs_f64());
            assert_eq!(set.len(), count);
            last = Some(times);
        }
        let cpu = match (cpu0, cpu_seconds()) {
            (Some(a), Some(b)) => format!("{:.0} ms", (b - a) / 3.0 * 1e3),
            _ => "n/a".to_owned(),
        };
        let times = last.expect("three runs");
        let ours = median(runs);
        let ms = |ns: u64| format!("{:.1} ms", ns as f64 * 1e-6);
        println!(
            "| {count} | {paper_s:.2} s | {:.1} ms | {:.0}× | {cpu} | {} | {} | {} | {} |",
            ours * 1e3,
            paper_s / ours,
            ms(times.neighbours_ns),
            ms(times.normals_ns),
            ms(times.orient_ns),
            ms(times.fit_ns)
        );
    }
}

fn update() {
    println!("\n### Update per step (Table 3), 40×40×40 mass points\n");
    println!(
        "| points inside | paper | ours, whole step (median) | paper ÷ ours | grid step | domains (eq. 4) | points (eq. 9) |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- |");
    // A sphere of radius 0.5; the region is a cube on the +x cap whose lattice has 20³
    // coefficients (40³ mass points). The cloud's density is chosen so that about 225 / 450 /
    // 910 points fall inside, from a pilot count.
    let side = 0.36f32;
    let spacing = side / 16.9;
    let lo = Vec3::new(0.5 - side * 0.5, -side * 0.5, -side * 0.5);
    let hi = lo + Vec3::splat(side);
    let mut opts = SculptOptions::for_spacing(spacing);
    opts.material = Material {
        yield_density: 0.0,
        ..Material::PLASTIC
    };
    let pilot_count = 8000usize;
    let (pilot, _) =
        PointSet::build(&sphere(pilot_count, 0.5), &PointSetOptions::default()).expect("builds");
    let pilot_inside = PointSetSculpt::new(&pilot, lo, hi, &opts)
        .expect("region")
        .member_count()
        .max(1);
    for (want, paper_ms) in [(225usize, 66.838f64), (450, 169.078), (910, 381.281)] {
        let count = pilot_count * want / pilot_inside;
        let cloud = sphere(count, 0.5);
        let (mut set, _) = PointSet::build(&cloud, &PointSetOptions::default()).expect("builds");
        let mut sculpt = PointSetSculpt::new(&set, lo, hi, &opts).expect("region");
        assert_eq!(sculpt.state.grid.dims, [40, 40, 40]);
        let inside = sculpt.member_count();
        let cursor = Vec3::new(0.62, 0.0, 0.0);
        let mut whole = Vec::new();
        let mut parts = Vec::new();
        for step in 0..220 {
            let x0 = surface_point_on_ray(&sculpt.lattice, Vec3::ZERO, Vec3::X, 1.0, 0.005)
                .unwrap_or(Vec3::new(0.5, 0.0, 0.0));
            let f = ToolForce {
                start: x0,
                end: cursor,
                distribution: Distribution::Gaussian,
                radius: 0.08,
                gain: 5e6,
            };
            let t = Instant::now();
            sculpt.step(&mut set, &[f]).expect("step");
            let dt = t.elapsed().as_secs_f64();
            if step >= 20 {
                whole.push(dt);
                parts.push(sculpt.times);
            }
        }
        let ms = |v: Vec<f64>| median(v) * 1e3;
        let ours = ms(whole);
        let sim = ms(parts.iter().map(|p| p.simulate_ns as f64 * 1e-9).collect());
        let dom = ms(parts
            .iter()
            .map(|p| p.update_domains_ns as f64 * 1e-9)
            .collect());
        let mov = ms(parts
            .iter()
            .map(|p| p.move_points_ns as f64 * 1e-9)
            .collect());
        println!(
            "| {inside} (paper {want}) | {paper_ms:.0} ms | {ours:.3} ms | {:.0}× | {sim:.3} ms | {dom:.3} ms | {mov:.3} ms |",
            paper_ms / ours
        );
    }
}

fn main() {
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "pointset: Guo & Qin's Tables 2 and 3; {} threads available; load average {}",
        std::thread::available_parallelism().map_or(1, |n| n.get()),
        load.trim()
    );
    construction();
    update();
    follow();
}

/// A clay lattice over `± 2` (35³ coefficients) whose surface is `|x| = radius(x / |x|)`.
fn radial_clay(radius: impl Fn(Vec3) -> f32) -> MultiPatchField {
    let spacing = 0.125;
    let mut lattice =
        BSplineLattice::zeros([35; 3], spacing, Vec3::splat(-2.0 - spacing)).expect("lattice");
    fit_lattice(&mut lattice, 2, |x| {
        let dir = x.try_normalize().unwrap_or(Vec3::X);
        (0.5 - (x.length() - radius(dir)) / 0.3).clamp(0.0, 1.0)
    })
    .expect("fit");
    lattice.iso = 0.5;
    MultiPatchField::from(lattice)
}

fn follow() {
    println!("\n### The live follower (graphics loop), unit sphere on a 35³ clay lattice\n");
    println!(
        "| points | still clay, per update (median of 20) | after a push: updates to settle | \
         slowest update | inserted | points after |"
    );
    println!("| --- | --- | --- | --- | --- | --- |");
    let still = radial_clay(|_| 1.0);
    let pushed = radial_clay(|d| 1.0 + 0.35 * (-(d - Vec3::X).length_squared() / 0.25).exp());
    for count in [4348usize, 35_947] {
        let (set, _) =
            PointSet::build(&sphere(count, 1.0), &PointSetOptions::default()).expect("builds");
        let points = FollowedPoints::of_set(&set);
        let options = points.options.expect("options");
        let mut f = PointFollower::new(points, options).expect("follower");
        for _ in 0..50 {
            if f.update(&still).expect("update").settled {
                break;
            }
        }
        let mut times = Vec::new();
        for _ in 0..20 {
            let t = Instant::now();
            f.update(&still).expect("update");
            times.push(t.elapsed().as_secs_f64());
        }
        let (mut updates, mut slowest, mut inserted) = (0, 0.0f64, 0);
        for _ in 0..500 {
            let t = Instant::now();
            let r = f.update(&pushed).expect("update");
            slowest = slowest.max(t.elapsed().as_secs_f64());
            updates += 1;
            inserted += r.inserted;
            if r.settled {
                break;
            }
        }
        println!(
            "| {count} | {:.2} ms | {updates} | {:.2} ms | {inserted} | {} |",
            median(times) * 1e3,
            slowest * 1e3,
            f.positions().len()
        );
    }
}
