//! The public models of the peer comparison and the clouds sampled from them.
//!
//! A model is an OBJ triangle mesh read from `DYNACLAY_MODELS` (default `bench/models/`,
//! filled by `bench/models/get.sh`). A cloud is sampled from it area-weighted with a fixed
//! seed, each point carrying its triangle's unit normal, then disturbed: Gaussian noise along
//! every axis as a fraction of the model's bounding-box diagonal, and optionally a share of
//! outliers drawn uniformly in the box grown by a tenth of its diagonal on every side.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use glam::Vec3;

/// The four models, by file stem, with what each stands for.
pub const MODELS: [(&str, &str); 4] = [
    ("stanford-bunny", "scanned figure, open at its base"),
    ("fandisk", "CAD part with sharp edges"),
    ("rocker-arm", "genus-1 mechanical part"),
    ("spot", "closed genus-0 character"),
];

/// How a clean sample is disturbed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Disturbance {
    /// Short name for the tables.
    pub name: &'static str,
    /// Standard deviation of the Gaussian noise per axis, fraction of the diagonal.
    pub noise_of_diagonal: f32,
    /// Share of the cloud replaced by outliers (uniform in the grown box, random normals).
    pub outlier_share: f32,
}

/// The three variants every model is sampled in.
pub const DISTURBANCES: [Disturbance; 3] = [
    Disturbance {
        name: "0.25% noise",
        noise_of_diagonal: 0.0025,
        outlier_share: 0.0,
    },
    Disturbance {
        name: "1% noise",
        noise_of_diagonal: 0.01,
        outlier_share: 0.0,
    },
    Disturbance {
        name: "0.25% noise + 5% outliers",
        noise_of_diagonal: 0.0025,
        outlier_share: 0.05,
    },
];

/// An indexed triangle mesh.
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    pub positions: Vec<Vec3>,
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// Lowest and highest corner of the vertices' box.
    #[must_use]
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.positions
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            })
    }

    /// Length of the box's diagonal.
    #[must_use]
    pub fn diagonal(&self) -> f32 {
        let (lo, hi) = self.bounds();
        (hi - lo).length()
    }

    /// The corners of triangle `t`.
    #[must_use]
    pub fn corners(&self, t: [u32; 3]) -> [Vec3; 3] {
        t.map(|i| self.positions[i as usize])
    }
}

/// A cloud with one unit normal per point.
#[derive(Clone, Debug)]
pub struct OrientedCloud {
    pub points: Vec<Vec3>,
    pub normals: Vec<Vec3>,
}

/// The folder the models are read from.
#[must_use]
pub fn models_folder() -> PathBuf {
    std::env::var_os("DYNACLAY_MODELS").map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("bench/models"),
        PathBuf::from,
    )
}

/// Reads `<folder>/<stem>.obj` as triangles; `Err` says what is missing or wrong and how to
/// get the models.
pub fn load_model(folder: &Path, stem: &str) -> Result<Mesh, String> {
    let path = folder.join(format!("{stem}.obj"));
    if !path.is_file() {
        return Err(format!(
            "{} is missing: run `bench/models/get.sh {}` (it copies the models from a local \
             clone of github.com/alecjacobson/common-3d-test-models given as its second \
             argument, or downloads them), or point DYNACLAY_MODELS at a folder holding them",
            path.display(),
            folder.display()
        ));
    }
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ..tobj::LoadOptions::default()
    };
    let (models, _) =
        tobj::load_obj(&path, &options).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut mesh = Mesh::default();
    for model in &models {
        let base = u32::try_from(mesh.positions.len()).map_err(|_| "too many vertices")?;
        mesh.positions.extend(
            model
                .mesh
                .positions
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0], p[1], p[2])),
        );
        mesh.triangles.extend(
            model
                .mesh
                .indices
                .chunks_exact(3)
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
    }
    if mesh.triangles.is_empty() {
        return Err(format!("{}: no triangles", path.display()));
    }
    Ok(mesh)
}

/// A small seeded generator (SplitMix64): the same clouds on every machine.
pub struct Rng(u64);

impl Rng {
    #[must_use]
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Standard normal (Box–Muller).
    pub fn gaussian(&mut self) -> f32 {
        let u = self.unit().max(f32::MIN_POSITIVE);
        let v = self.unit();
        (-2.0 * u.ln()).sqrt() * (std::f32::consts::TAU * v).cos()
    }

    /// A uniformly random unit vector.
    pub fn direction(&mut self) -> Vec3 {
        let z = self.unit() * 2.0 - 1.0;
        let phi = self.unit() * std::f32::consts::TAU;
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

/// Picks triangles with probability proportional to their area.
pub struct AreaSampler<'a> {
    mesh: &'a Mesh,
    cumulative_area: Vec<f64>,
}

impl<'a> AreaSampler<'a> {
    #[must_use]
    pub fn new(mesh: &'a Mesh) -> Self {
        let mut total = 0.0f64;
        let cumulative_area = mesh
            .triangles
            .iter()
            .map(|&t| {
                let [a, b, c] = mesh.corners(t);
                total += f64::from((b - a).cross(c - a).length() * 0.5);
                total
            })
            .collect();
        Self {
            mesh,
            cumulative_area,
        }
    }

    /// Total area of the mesh.
    #[must_use]
    pub fn area(&self) -> f64 {
        self.cumulative_area.last().copied().unwrap_or(0.0)
    }

    /// A point uniform over the surface and its triangle's unit normal.
    pub fn sample(&self, rng: &mut Rng) -> (Vec3, Vec3) {
        let target = f64::from(rng.unit()) * self.area();
        let t = self
            .cumulative_area
            .partition_point(|&c| c <= target)
            .min(self.cumulative_area.len() - 1);
        let [a, b, c] = self.mesh.corners(self.mesh.triangles[t]);
        let (r1, r2) = (rng.unit().sqrt(), rng.unit());
        let p = a * (1.0 - r1) + b * (r1 * (1.0 - r2)) + c * (r1 * r2);
        (p, (b - a).cross(c - a).normalize_or_zero())
    }
}

/// `count` points sampled from `mesh` (seeded), disturbed as `disturbance` says.
#[must_use]
pub fn sample_cloud(
    mesh: &Mesh,
    count: usize,
    disturbance: Disturbance,
    seed: u64,
) -> OrientedCloud {
    let mut rng = Rng::new(seed);
    let sampler = AreaSampler::new(mesh);
    let diagonal = mesh.diagonal();
    let sigma = disturbance.noise_of_diagonal * diagonal;
    let outliers = (count as f32 * disturbance.outlier_share).round() as usize;
    let mut cloud = OrientedCloud {
        points: Vec::with_capacity(count),
        normals: Vec::with_capacity(count),
    };
    for _ in 0..count - outliers {
        let (p, n) = sampler.sample(&mut rng);
        let noise = Vec3::new(rng.gaussian(), rng.gaussian(), rng.gaussian()) * sigma;
        cloud.points.push(p + noise);
        cloud.normals.push(n);
    }
    let (lo, hi) = mesh.bounds();
    let grow = Vec3::splat(0.1 * diagonal);
    let (lo, hi) = (lo - grow, hi + grow);
    for _ in 0..outliers {
        let p = lo + (hi - lo) * Vec3::new(rng.unit(), rng.unit(), rng.unit());
        cloud.points.push(p);
        cloud.normals.push(rng.direction());
    }
    cloud
}

/// Which way a cloud's normals point, as written.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NormalsAs {
    /// As sampled: the model's outward face normals.
    Sampled,
    /// Every normal turned: pointing into the model.
    Inward,
    /// Each normal turned by a seeded coin toss: a plane's normal with either sign, as an
    /// unoriented estimate gives.
    EitherSign,
}

impl NormalsAs {
    /// Words for the tables (empty for [`NormalsAs::Sampled`]).
    #[must_use]
    pub fn label(self) -> &'static str {
        match self {
            Self::Sampled => "",
            Self::Inward => ", normals inward",
            Self::EitherSign => ", normals of either sign",
        }
    }

    /// Turns `cloud`'s normals as `self` says (the coin tosses seeded by `seed`).
    pub fn apply(self, cloud: &mut OrientedCloud, seed: u64) {
        let mut rng = Rng::new(seed);
        for n in &mut cloud.normals {
            let turn = match self {
                Self::Sampled => false,
                Self::Inward => true,
                Self::EitherSign => rng.unit() < 0.5,
            };
            if turn {
                *n = -*n;
            }
        }
    }
}

/// Writes the cloud as a binary little-endian PLY with `x y z nx ny nz` floats, the layout
/// both `dynaclay import` and PoissonRecon read.
pub fn write_ply(cloud: &OrientedCloud, path: &Path) -> std::io::Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\nend_header\n",
        cloud.points.len()
    )?;
    for (p, n) in cloud.points.iter().zip(&cloud.normals) {
        for v in [p.x, p.y, p.z, n.x, n.y, n.z] {
            out.write_all(&v.to_le_bytes())?;
        }
    }
    out.flush()
}
