//! dynaclay's import beside screened Poisson reconstruction on public models, in one table.
//!
//! Each model (see [`MODELS`]) is sampled as a 50 000-point cloud with normals in each of
//! [`DISTURBANCES`] (seeded), written as a binary PLY, and reconstructed by dynaclay and by
//! each peer that is present (see [`super::reconstructors`]). Every mesh is judged against the
//! clean model ([`super::surface_compare`]): the distance from the reconstruction to the model
//! and back, p50 and p99 as percent of the model's box diagonal; its pieces and the genus of
//! the largest; the wall time; the peak memory per input point. The reconstruction → model
//! distances are also given signed (positive outside the model), their mean and median: a
//! surface shifted outward or inward shows there, noise left in it does not. The last columns are dynaclay
//! over that peer, on the same cloud. A mesh that is empty fails the run at once; one that lies
//! far from the model (p50 either way over [`FAR_OFF_PERCENT`]) is marked in its row and fails
//! the run once the table is printed, so the other rows are still seen. The clouds are written
//! to a temporary folder removed at the end, or to `PEERS_CLOUDS_DIR` when it is set, where
//! they are kept (`{model}-{variant}.ply`, the variant's index in [`DISTURBANCES`]) to rerun
//! one by hand.
//!
//! Environment variables narrow or scale the run: `PEERS_POINTS` sets the points per cloud
//! (default [`CLOUD_POINTS`], at most [`MAX_CLOUD_POINTS`]; e.g. a million, to judge the import's
//! thinning of dense scans), `PEERS_MODELS` a comma-separated list of model stems to keep, and
//! `PEERS_NOISE_SCALE` a factor on every cloud's noise (see [`noise_scale`]),
//! `PEERS_NORMALS` which way the clouds' normals point (see [`normals_as`]). With
//! `PEERS_WORST` set, each row is followed by where on the model its worst 1% of distances
//! lie, either way (see [`print_worst_places`]).

use std::path::{Path, PathBuf};

use super::models::{
    DISTURBANCES, Disturbance, MODELS, Mesh, NormalsAs, OrientedCloud, load_model, models_folder,
    sample_cloud, write_ply,
};
use super::reconstructors::{
    POISSON_DEPTH, Reconstruction, dynaclay, find_poisson_recon, poisson_crate,
    poisson_crate_depth, poisson_recon,
};
use super::surface_compare::{
    TriangleIndex, one_way_distances, one_way_signed_distances, one_way_signed_samples, quantile,
    topology,
};

/// Points per cloud unless `PEERS_POINTS` says otherwise.
pub const CLOUD_POINTS: usize = 50_000;

/// The most points per cloud `PEERS_POINTS` may ask for (a cloud of this size in memory and on
/// disk is about 150 MB, and each reconstruction is judged over the whole mesh).
pub const MAX_CLOUD_POINTS: usize = 5_000_000;

/// Points per cloud: `PEERS_POINTS` when set, [`CLOUD_POINTS`] otherwise.
fn cloud_points() -> usize {
    let Some(text) = std::env::var_os("PEERS_POINTS") else {
        return CLOUD_POINTS;
    };
    let text = text.to_string_lossy();
    match text.trim().parse::<usize>() {
        Ok(points) if (1000..=MAX_CLOUD_POINTS).contains(&points) => points,
        _ => panic!(
            "PEERS_POINTS is {text:?}: expected a whole number of points from 1000 to \
             {MAX_CLOUD_POINTS}"
        ),
    }
}

/// The models to run: every one of [`MODELS`], or those `PEERS_MODELS` names.
fn chosen_models() -> Vec<(usize, &'static str, &'static str)> {
    let all = MODELS
        .iter()
        .enumerate()
        .map(|(m, &(stem, what))| (m, stem, what));
    let Some(names) = std::env::var_os("PEERS_MODELS") else {
        return all.collect();
    };
    let names = names.to_string_lossy().into_owned();
    let wanted: Vec<&str> = names.split(',').map(str::trim).collect();
    for name in &wanted {
        assert!(
            MODELS.iter().any(|&(stem, _)| stem == *name),
            "PEERS_MODELS names {name:?}, which is not one of the models: {}",
            MODELS.map(|(stem, _)| stem).join(", ")
        );
    }
    all.filter(|(_, stem, _)| wanted.contains(stem)).collect()
}

/// A reconstruction whose median distance either way is above this (percent of the diagonal)
/// is not a reconstruction of the model: the run fails.
pub const FAR_OFF_PERCENT: f32 = 2.5;

/// How a mesh compares with the model.
#[derive(Clone, Copy, Debug)]
struct Accuracy {
    /// Reconstruction → model, percent of the diagonal.
    to_model_p50: f32,
    to_model_p99: f32,
    /// Model → reconstruction, percent of the diagonal.
    from_model_p50: f32,
    from_model_p99: f32,
    /// Reconstruction → model, signed (positive outside the model): mean and median, percent
    /// of the diagonal. A surface shifted outward or inward shows here; noise left in it does
    /// not.
    to_model_signed_mean: f32,
    to_model_signed_p50: f32,
}

impl Accuracy {
    /// The larger median of the two directions.
    fn p50(&self) -> f32 {
        self.to_model_p50.max(self.from_model_p50)
    }

    /// Why this is no reconstruction of the model, if it is not.
    fn far_off(&self, label: &str) -> Option<String> {
        (self.p50() > FAR_OFF_PERCENT).then(|| {
            format!(
                "{label}: the reconstruction lies far from the model (median distance {:.2}% \
                 to it, {:.2}% from it, over {FAR_OFF_PERCENT}% of the diagonal)",
                self.to_model_p50, self.from_model_p50
            )
        })
    }

    /// The larger 99th percentile of the two directions.
    fn p99(&self) -> f32 {
        self.to_model_p99.max(self.from_model_p99)
    }
}

fn accuracy(
    model: &Mesh,
    model_index: &TriangleIndex<'_>,
    mesh: &Mesh,
    samples: usize,
    label: &str,
) -> Accuracy {
    let index = TriangleIndex::new(mesh)
        .unwrap_or_else(|| panic!("{label}: the reconstruction has no triangles"));
    let percent = 100.0 / model.diagonal();
    let mut signed = one_way_signed_distances(mesh, model_index, samples, 0x5eed_0001);
    let mut to_model: Vec<f32> = signed.iter().map(|d| d.abs()).collect();
    let mut from_model = one_way_distances(model, &index, samples, 0x5eed_0002);
    assert!(
        !to_model.is_empty(),
        "{label}: the reconstruction has no area"
    );
    Accuracy {
        to_model_p50: quantile(&mut to_model, 0.5) * percent,
        to_model_p99: quantile(&mut to_model, 0.99) * percent,
        from_model_p50: quantile(&mut from_model, 0.5) * percent,
        from_model_p99: quantile(&mut from_model, 0.99) * percent,
        to_model_signed_mean: (signed.iter().map(|&d| f64::from(d)).sum::<f64>()
            / signed.len() as f64) as f32
            * percent,
        to_model_signed_p50: quantile(&mut signed, 0.5) * percent,
    }
}

/// How a peer turns a cloud (in memory, and its PLY file) into a mesh; `Err` when it fails.
type PeerRun = Box<dyn Fn(&OrientedCloud, &Path) -> Result<Reconstruction, String>>;

/// One peer: its name and how it runs.
struct Peer {
    name: &'static str,
    run: PeerRun,
}

fn peers(scratch: &Path) -> Vec<Peer> {
    let mut list = Vec::new();
    match find_poisson_recon() {
        Ok(binary) => {
            let out = scratch.join("poissonrecon-mesh.ply");
            println!("PoissonRecon: {}", binary.display());
            list.push(Peer {
                name: "PoissonRecon",
                run: Box::new(move |_, ply| poisson_recon(&binary, ply, &out)),
            });
        }
        Err(why) => println!("PoissonRecon peer missing, its rows are skipped: {why}"),
    }
    if std::env::var_os("POISSON_CRATE_SKIP").is_some() {
        println!("poisson_reconstruction peer skipped: POISSON_CRATE_SKIP is set");
    } else {
        list.push(Peer {
            name: "poisson_reconstruction 0.4",
            run: Box::new(|cloud, _| Ok(poisson_crate(cloud))),
        });
    }
    list
}

/// The factor `PEERS_NOISE_SCALE` sets on every cloud's noise, 1 when unset. The clouds keep
/// their points and outliers, only the noise is scaled (0: none), so runs at a few factors
/// tell the fit's own error (its lattice, its smoothing) from the noise left in its surface.
fn noise_scale() -> f32 {
    let Some(text) = std::env::var_os("PEERS_NOISE_SCALE") else {
        return 1.0;
    };
    let text = text.to_string_lossy();
    match text.trim().parse::<f32>() {
        Ok(scale) if (0.0..=10.0).contains(&scale) => scale,
        _ => panic!("PEERS_NOISE_SCALE is {text:?}: expected a factor from 0 to 10"),
    }
}

/// Which way `PEERS_NORMALS` turns every cloud's normals: `inward` (all of them) or
/// `either-sign` (each by a seeded coin toss); as sampled (outward) when unset. Screened
/// Poisson takes the normals' signs as given, so its rows far from the model are marked but
/// do not fail such a run; dynaclay's still do.
fn normals_as() -> NormalsAs {
    let Some(text) = std::env::var_os("PEERS_NORMALS") else {
        return NormalsAs::Sampled;
    };
    match text.to_string_lossy().trim() {
        "inward" => NormalsAs::Inward,
        "either-sign" => NormalsAs::EitherSign,
        other => panic!("PEERS_NORMALS is {other:?}: expected inward or either-sign"),
    }
}

/// Prints the comparison; `quick` runs the first variant only, with fewer distance samples.
pub fn run(quick: bool) {
    let folder = models_folder();
    let samples = if quick { 20_000 } else { 100_000 };
    let noise_scale = noise_scale();
    let normals = normals_as();
    let points = cloud_points();
    let variants = if quick {
        &DISTURBANCES[..1]
    } else {
        &DISTURBANCES[..]
    };
    let kept = std::env::var_os("PEERS_CLOUDS_DIR").map(PathBuf::from);
    let scratch: PathBuf = kept.clone().unwrap_or_else(|| {
        std::env::temp_dir().join(format!("dynaclay-peers-{}", std::process::id()))
    });
    std::fs::create_dir_all(&scratch).expect("a temporary folder");
    println!(
        "\npeers: {points}-point clouds with normals from public models ({}), \
         reconstructed by dynaclay import (default settings, meshed as --mesh exports) and by \
         screened Poisson (PoissonRecon at depth {POISSON_DEPTH}, the crate at depth {}); distances over {samples} area-weighted \
         samples each way, % of the model's box diagonal; one run each; {} CPUs",
        folder.display(),
        poisson_crate_depth(),
        std::thread::available_parallelism().map_or(1, usize::from)
    );
    let peers = peers(&scratch);
    println!(
        "| model | cloud | method | time | peak RSS / point | rec→model p50 / p99 | rec→model signed mean / p50 | model→rec p50 / p99 | pieces, genus of largest (holes) | dynaclay ÷ this: time | RSS/pt | p50 | p99 |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |");
    let mut missing = Vec::new();
    let mut far_off = Vec::new();
    for (m, stem, what) in chosen_models() {
        let model = match load_model(&folder, stem) {
            Ok(model) => model,
            Err(why) => {
                missing.push(why);
                continue;
            }
        };
        let model_index = TriangleIndex::new(&model).expect("the model has triangles");
        println!(
            "| {stem} ({what}) | – | clean model ({} triangles) | – | – | – | – | – | {} | | | | |",
            model.triangles.len(),
            topology(&model).summary()
        );
        for (v, &variant) in variants.iter().enumerate() {
            let scaled = Disturbance {
                noise_of_diagonal: variant.noise_of_diagonal * noise_scale,
                ..variant
            };
            let variant_name = if noise_scale == 1.0 {
                format!("{}{}", variant.name, normals.label())
            } else {
                format!("{}, noise × {noise_scale}{}", variant.name, normals.label())
            };
            let seed = (m * 16 + v) as u64 + 1;
            let mut cloud = sample_cloud(&model, points, scaled, seed);
            normals.apply(&mut cloud, seed);
            let ply = scratch.join(format!("{stem}-{v}.ply"));
            write_ply(&cloud, &ply).expect("the cloud is written");
            let per_point = |bytes: f64| bytes / cloud.points.len() as f64;
            let label = |method: &str| format!("{stem}, {variant_name}, {method}");
            let ours =
                dynaclay(&ply, &scratch).unwrap_or_else(|e| panic!("{}: {e}", label("dynaclay")));
            let ours_accuracy = accuracy(
                &model,
                &model_index,
                &ours.mesh,
                samples,
                &label("dynaclay"),
            );
            let ours_far_off = ours_accuracy.far_off(&label("dynaclay"));
            let ours_name = if ours_far_off.is_some() {
                "dynaclay **far off**"
            } else {
                "dynaclay"
            };
            far_off.extend(ours_far_off);
            print_row(
                stem,
                &variant_name,
                ours_name,
                &ours,
                per_point(ours.peak_bytes),
                &ours_accuracy,
                None,
            );
            print_worst_places(&model, &model_index, &ours.mesh, samples);
            for peer in &peers {
                match (peer.run)(&cloud, &ply) {
                    Ok(theirs) => {
                        let theirs_accuracy = accuracy(
                            &model,
                            &model_index,
                            &theirs.mesh,
                            samples,
                            &label(peer.name),
                        );
                        let ratios = Ratios {
                            time: ours.seconds / theirs.seconds,
                            memory: ours.peak_bytes / theirs.peak_bytes,
                            p50: ours_accuracy.p50() / theirs_accuracy.p50(),
                            p99: ours_accuracy.p99() / theirs_accuracy.p99(),
                        };
                        let theirs_far_off = theirs_accuracy.far_off(&label(peer.name));
                        let name = if theirs_far_off.is_some() {
                            format!("{} **far off**", peer.name)
                        } else {
                            peer.name.to_owned()
                        };
                        if normals == NormalsAs::Sampled {
                            far_off.extend(theirs_far_off);
                        }
                        print_row(
                            stem,
                            &variant_name,
                            &name,
                            &theirs,
                            per_point(theirs.peak_bytes),
                            &theirs_accuracy,
                            Some(ratios),
                        );
                        print_worst_places(&model, &model_index, &theirs.mesh, samples);
                    }
                    Err(why) => println!(
                        "| {stem} | {} | {} | failed: {why} | | | | | | | | | |",
                        variant_name, peer.name
                    ),
                }
            }
        }
    }
    if kept.is_none() {
        let _ = std::fs::remove_dir_all(&scratch);
    }
    for why in &missing {
        println!("model missing, its rows are skipped: {why}");
    }
    assert!(
        far_off.is_empty(),
        "{} reconstructions far from their model:\n{}",
        far_off.len(),
        far_off.join("\n")
    );
}

/// Cells per axis of the model's box that [`print_worst_places`] counts the worst samples in.
const WORST_CELLS: usize = 6;
/// Cells [`print_worst_places`] lists per direction, at most.
const WORST_LISTED: usize = 5;

/// With `PEERS_WORST` set: where the reconstruction's worst 1% of distances lie, each way. The
/// samples over the 99th percentile are counted in a grid of [`WORST_CELLS`]³ cells over the
/// model's box; the cells holding most are printed with their centre (fractions of the box),
/// their share of the worst samples and the mean signed distance there (% of the diagonal;
/// reconstruction → model: positive where the reconstruction lies outside the model; model →
/// reconstruction: positive where the model lies outside the reconstruction, which is missing
/// or sunk there).
fn print_worst_places(model: &Mesh, model_index: &TriangleIndex<'_>, mesh: &Mesh, samples: usize) {
    if std::env::var_os("PEERS_WORST").is_none() {
        return;
    }
    let Some(index) = TriangleIndex::new(mesh) else {
        return;
    };
    let (lo, hi) = model.bounds();
    let percent = 100.0 / model.diagonal();
    let cell_of = |p: glam::Vec3| {
        let f = ((p - lo) / (hi - lo)).clamp(glam::Vec3::ZERO, glam::Vec3::splat(0.999_999));
        let c = (f * WORST_CELLS as f32).as_uvec3();
        (c.x as usize * WORST_CELLS + c.y as usize) * WORST_CELLS + c.z as usize
    };
    for (way, sampled) in [
        (
            "rec→model",
            one_way_signed_samples(mesh, model_index, samples, 0x5eed_0001),
        ),
        (
            "model→rec",
            one_way_signed_samples(model, &index, samples, 0x5eed_0002),
        ),
    ] {
        let mut magnitudes: Vec<f32> = sampled.iter().map(|&(_, d)| d.abs()).collect();
        let p99 = quantile(&mut magnitudes, 0.99);
        let worst: Vec<&(glam::Vec3, f32)> =
            sampled.iter().filter(|&&(_, d)| d.abs() > p99).collect();
        let mut cells = vec![(0usize, 0.0f64); WORST_CELLS.pow(3)];
        for &&(p, d) in &worst {
            let cell = &mut cells[cell_of(p)];
            cell.0 += 1;
            cell.1 += f64::from(d);
        }
        let mut ranked: Vec<usize> = (0..cells.len()).filter(|&c| cells[c].0 > 0).collect();
        ranked.sort_by_key(|&c| std::cmp::Reverse(cells[c].0));
        let listed: Vec<String> = ranked
            .iter()
            .take(WORST_LISTED)
            .map(|&c| {
                let (count, sum) = cells[c];
                let at = |i: usize| (i as f32 + 0.5) / WORST_CELLS as f32;
                let (x, y, z) = (
                    c / (WORST_CELLS * WORST_CELLS),
                    (c / WORST_CELLS) % WORST_CELLS,
                    c % WORST_CELLS,
                );
                format!(
                    "({:.2}, {:.2}, {:.2}): {:.0}%, {:+.3}%",
                    at(x),
                    at(y),
                    at(z),
                    100.0 * count as f64 / worst.len().max(1) as f64,
                    sum / count as f64 * f64::from(percent)
                )
            })
            .collect();
        println!(
            "|   worst 1% {way} (over {:.3}%) | {} |",
            p99 * percent,
            listed.join("; ")
        );
    }
}

/// dynaclay's figure over the peer's.
struct Ratios {
    time: f64,
    memory: f64,
    p50: f32,
    p99: f32,
}

fn print_row(
    model: &str,
    variant: &str,
    method: &str,
    result: &Reconstruction,
    bytes_per_point: f64,
    accuracy: &Accuracy,
    ratios: Option<Ratios>,
) {
    let ratios = ratios.map_or_else(
        || "– | – | – | –".to_owned(),
        |r| {
            format!(
                "{:.2} | {:.2} | {:.2} | {:.2}",
                r.time, r.memory, r.p50, r.p99
            )
        },
    );
    println!(
        "| {model} | {variant} | {method} | {:.2} s | {bytes_per_point:.0} B | {:.3}% / {:.3}% | {:+.3}% / {:+.3}% | {:.3}% / {:.3}% | {} | {ratios} |",
        result.seconds,
        accuracy.to_model_p50,
        accuracy.to_model_p99,
        accuracy.to_model_signed_mean,
        accuracy.to_model_signed_p50,
        accuracy.from_model_p50,
        accuracy.from_model_p99,
        topology(&result.mesh).summary()
    );
}
