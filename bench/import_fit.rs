//! Fitting a clay to point clouds of 1k to 1M points (a ball, no normals: the normals are
//! estimated and turned outward by the flood): wall time per fit, the median of three runs
//! (one for 1M), and how far the points lie from the fitted surface (checked: a fit that
//! misses its points fails the run). Run with `cargo bench --bench import_fit`.

use std::time::Instant;

use dynaclay::fit::{CloudFitOptions, PointCloud, fit_point_cloud};
use glam::Vec3;

fn ball(count: usize) -> PointCloud {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let points = (0..count)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / count as f32;
            let r = (1.0 - y * y).sqrt();
            let phi = golden * i as f32;
            Vec3::new(r * phi.cos(), y, r * phi.sin()) * 40.0
        })
        .collect();
    PointCloud {
        points,
        normals: None,
    }
}

fn main() {
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "import_fit: 32³ clay, ball clouds without normals; load average {}",
        load.trim()
    );
    println!(
        "| points | fit time (median) | mean / worst distance of the points to the surface (spans) |"
    );
    println!("| --- | --- | --- |");
    for count in [1_000usize, 10_000, 100_000, 1_000_000] {
        let cloud = ball(count);
        let runs = if count >= 1_000_000 { 1 } else { 3 };
        let mut times = Vec::new();
        let mut fit = None;
        for _ in 0..runs {
            let start = Instant::now();
            let f = fit_point_cloud(&cloud, &CloudFitOptions::default()).expect("the fit runs");
            times.push(start.elapsed().as_secs_f64());
            fit = Some(f);
        }
        times.sort_by(f64::total_cmp);
        let fit = fit.expect("one run at least");
        let (mut sum, mut worst) = (0.0f64, 0.0f32);
        for &p in &cloud.points {
            let (v, g) = fit.lattice.value_and_gradient(fit.to_field(p));
            let d = (v - fit.lattice.iso).abs() / g.length().max(1e-6) / fit.lattice.spacing;
            sum += f64::from(d);
            worst = worst.max(d);
        }
        let mean = sum / count as f64;
        assert!(
            worst < 0.25,
            "{count} points: a point lies {worst} spans off the surface"
        );
        println!(
            "| {count} | {:.3} s | {mean:.3} / {worst:.3} |",
            times[times.len() / 2]
        );
    }
}
