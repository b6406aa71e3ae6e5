//! Volumes (a CT or MRI scan, a simulation's density) read from files and fitted as a clay:
//! the surface is where the intensity crosses the user's iso-value.
//!
//! Files: raw 8- or 16-bit samples with the dimensions given by the caller, and NRRD with its
//! data in the same file (`encoding: raw`; types uchar, ushort, short, float; little or big
//! endian). Voxels are taken as cubes (NRRD spacings are not applied). The byte count is
//! checked against the dimensions, and the voxel count against [`MAX_VOXELS`], before any
//! allocation.

use std::path::{Path, PathBuf};

use glam::Vec3;

use super::cloud::{CloudFitError, MARGIN_SPANS};
use super::hierarchy::{FitProgress, HierarchyOptions, LevelReport, Refinement, refine};
use dynaclay_core::field::{BSplineLattice, MultiPatchField, density_profile, fit_lattice};
use dynaclay_core::io::bounded_read::{BoundedReadError, read_regular_file};

/// The most voxels a volume may hold.
pub const MAX_VOXELS: usize = 256 << 20;

/// A scalar volume, x fastest.
#[derive(Clone, Debug, PartialEq)]
pub struct Volume {
    /// Voxels per axis.
    pub dims: [usize; 3],
    /// The intensities.
    pub values: Vec<f32>,
}

/// The sample type of a raw volume.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sample {
    /// Unsigned 8-bit.
    U8,
    /// Unsigned 16-bit.
    U16,
    /// Signed 16-bit.
    I16,
    /// 32-bit float.
    F32,
}

impl Sample {
    fn bytes(self) -> usize {
        match self {
            Self::U8 => 1,
            Self::U16 | Self::I16 => 2,
            Self::F32 => 4,
        }
    }
}

/// Why a volume was refused.
#[derive(Debug, thiserror::Error)]
pub enum VolumeError {
    /// The file could not be read.
    #[error("{}: {error}", file.display())]
    Read {
        /// The file.
        file: PathBuf,
        /// Why.
        error: BoundedReadError,
    },
    /// A header line is malformed or missing.
    #[error("{}:{line}: {what}", file.display())]
    Header {
        /// The file.
        file: PathBuf,
        /// Line number, from 1.
        line: usize,
        /// What is wrong.
        what: String,
    },
    /// The data does not match the dimensions, or is not finite.
    #[error("{}: {what}", file.display())]
    Data {
        /// The file.
        file: PathBuf,
        /// What is wrong.
        what: String,
    },
}

fn voxel_count(dims: [usize; 3]) -> Option<usize> {
    dims.iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .filter(|&n| n <= MAX_VOXELS && dims.iter().all(|&d| d >= 2))
}

/// Decodes `data` as `dims` samples of `sample`, checking the byte count first.
fn decode(
    data: &[u8],
    dims: [usize; 3],
    sample: Sample,
    big_endian: bool,
    file: &Path,
) -> Result<Volume, VolumeError> {
    let bad = |what: String| VolumeError::Data {
        file: file.to_path_buf(),
        what,
    };
    let count = voxel_count(dims).ok_or_else(|| {
        bad(format!(
            "dimensions {dims:?}: each at least 2, at most {MAX_VOXELS} voxels in all"
        ))
    })?;
    let want = count * sample.bytes();
    if data.len() != want {
        return Err(bad(format!(
            "{} bytes of samples where {dims:?} of {} bytes each need {want}",
            data.len(),
            sample.bytes()
        )));
    }
    let values: Vec<f32> = data
        .chunks_exact(sample.bytes())
        .map(|c| match (sample, big_endian) {
            (Sample::U8, _) => f32::from(c[0]),
            (Sample::U16, false) => f32::from(u16::from_le_bytes([c[0], c[1]])),
            (Sample::U16, true) => f32::from(u16::from_be_bytes([c[0], c[1]])),
            (Sample::I16, false) => f32::from(i16::from_le_bytes([c[0], c[1]])),
            (Sample::I16, true) => f32::from(i16::from_be_bytes([c[0], c[1]])),
            (Sample::F32, false) => f32::from_le_bytes([c[0], c[1], c[2], c[3]]),
            (Sample::F32, true) => f32::from_be_bytes([c[0], c[1], c[2], c[3]]),
        })
        .collect();
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(bad(format!(
            "voxel {i} is {}, not a finite number",
            values[i]
        )));
    }
    Ok(Volume { dims, values })
}

/// Reads a raw volume of `dims` little-endian samples of `sample`.
///
/// # Errors
/// [`VolumeError`] naming the file: unreadable, or a byte count that does not match.
pub fn read_raw(path: &Path, dims: [usize; 3], sample: Sample) -> Result<Volume, VolumeError> {
    // Absurd dimensions are refused before the file is read or anything allocated.
    let count = voxel_count(dims).ok_or_else(|| VolumeError::Data {
        file: path.to_path_buf(),
        what: format!("dimensions {dims:?}: each at least 2, at most {MAX_VOXELS} voxels in all"),
    })?;
    let cap = (count * sample.bytes()) as u64;
    let bytes = read_regular_file(path, cap.max(1)).map_err(|error| VolumeError::Read {
        file: path.to_path_buf(),
        error,
    })?;
    decode(&bytes, dims, sample, false, path)
}

/// Reads an NRRD volume whose raw data follows its header in the same file.
///
/// # Errors
/// [`VolumeError`] naming the file and the header line, or the data's mismatch.
pub fn read_nrrd(path: &Path) -> Result<Volume, VolumeError> {
    let bytes = read_regular_file(path, (MAX_VOXELS * 4 + (1 << 16)) as u64).map_err(|error| {
        VolumeError::Read {
            file: path.to_path_buf(),
            error,
        }
    })?;
    parse_nrrd(&bytes, path)
}

/// Parses an NRRD file held in `bytes`.
///
/// # Errors
/// As [`read_nrrd`].
pub fn parse_nrrd(bytes: &[u8], file: &Path) -> Result<Volume, VolumeError> {
    let header_err = |line: usize, what: String| VolumeError::Header {
        file: file.to_path_buf(),
        line,
        what,
    };
    let (mut at, mut line_no) = (0usize, 0usize);
    let (mut sample, mut dims, mut big, mut raw) = (None, None, false, false);
    loop {
        let Some(len) = bytes[at..].iter().position(|&b| b == b'\n') else {
            return Err(header_err(
                line_no + 1,
                "the header ends without a blank line".into(),
            ));
        };
        line_no += 1;
        let line = std::str::from_utf8(&bytes[at..at + len])
            .map_err(|_| header_err(line_no, "the header is not text".into()))?
            .trim_end_matches('\r');
        at += len + 1;
        if line_no == 1 {
            if !line.starts_with("NRRD000") {
                return Err(header_err(1, "not an NRRD file (no NRRD000x magic)".into()));
            }
            continue;
        }
        if line.is_empty() {
            break;
        }
        if line.starts_with('#') || line.contains(":=") {
            continue;
        }
        let Some((key, value)) = line.split_once(':') else {
            return Err(header_err(
                line_no,
                format!("`{line}` is not `field: value`"),
            ));
        };
        let value = value.trim();
        match key.trim() {
            "type" => {
                sample = Some(match value {
                    "uchar" | "unsigned char" | "uint8" | "uint8_t" => Sample::U8,
                    "ushort" | "unsigned short" | "uint16" | "uint16_t" => Sample::U16,
                    "short" | "signed short" | "int16" | "int16_t" => Sample::I16,
                    "float" => Sample::F32,
                    other => {
                        return Err(header_err(
                            line_no,
                            format!("type `{other}` is not supported"),
                        ));
                    }
                });
            }
            "dimension" if value != "3" => {
                return Err(header_err(
                    line_no,
                    format!("dimension {value}: a volume has 3"),
                ));
            }
            "sizes" => {
                let v: Vec<usize> = value
                    .split_whitespace()
                    .map(str::parse)
                    .collect::<Result<_, _>>()
                    .map_err(|_| header_err(line_no, format!("sizes `{value}`")))?;
                let [x, y, z] = v[..] else {
                    return Err(header_err(
                        line_no,
                        format!("sizes `{value}`: three are needed"),
                    ));
                };
                dims = Some([x, y, z]);
            }
            "endian" => big = value == "big",
            "encoding" => {
                if value != "raw" {
                    return Err(header_err(
                        line_no,
                        format!("encoding `{value}`: only raw is read"),
                    ));
                }
                raw = true;
            }
            "data file" | "datafile" => {
                return Err(header_err(
                    line_no,
                    "detached data files are not read".into(),
                ));
            }
            _ => {}
        }
    }
    let sample = sample.ok_or_else(|| header_err(line_no, "no `type` field".into()))?;
    let dims = dims.ok_or_else(|| header_err(line_no, "no `sizes` field".into()))?;
    if !raw {
        return Err(header_err(line_no, "no `encoding: raw` field".into()));
    }
    decode(&bytes[at..], dims, sample, big, file)
}

impl Volume {
    /// The intensity at voxel coordinates `u` (trilinear; clamped at the edges).
    #[must_use]
    pub fn sample(&self, u: Vec3) -> f32 {
        let [nx, ny, nz] = self.dims;
        let max = Vec3::new((nx - 1) as f32, (ny - 1) as f32, (nz - 1) as f32);
        let u = u.clamp(Vec3::ZERO, max);
        let base = u.floor().min(max - Vec3::ONE).max(Vec3::ZERO);
        let t = u - base;
        let (i, j, k) = (base.x as usize, base.y as usize, base.z as usize);
        let at = |a: usize, b: usize, c: usize| self.values[a + nx * (b + ny * c)];
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let x00 = lerp(at(i, j, k), at(i + 1, j, k), t.x);
        let x10 = lerp(at(i, j + 1, k), at(i + 1, j + 1, k), t.x);
        let x01 = lerp(at(i, j, k + 1), at(i + 1, j, k + 1), t.x);
        let x11 = lerp(at(i, j + 1, k + 1), at(i + 1, j + 1, k + 1), t.x);
        lerp(lerp(x00, x10, t.y), lerp(x01, x11, t.y), t.z)
    }
}

/// A clay fitted to a volume's iso-surface, and where the volume went.
#[derive(Clone, Debug)]
pub struct VolumeFit {
    /// The fitted lattice.
    pub lattice: BSplineLattice,
    /// Field units per voxel.
    pub scale: f32,
    /// Field position of voxel (0, 0, 0).
    pub offset: Vec3,
}

impl VolumeFit {
    /// Voxel coordinates to field units.
    #[must_use]
    pub fn to_field(&self, u: Vec3) -> Vec3 {
        u * self.scale + self.offset
    }
}

/// Fits an `resolution`³ clay at `spacing` to the surface where `volume` crosses `iso`
/// (intensities above `iso` are solid). Placement as for clouds: the longest axis spans the
/// lattice less [`MARGIN_SPANS`] on each side. Each fit sample takes the intensity's signed
/// distance to first order, `(iso − I) / |∇I|` (central differences, in field units), as the
/// clay's density profile; where the gradient vanishes, only the side counts.
///
/// # Errors
/// [`CloudFitError::Options`] for a bad resolution or an iso-value the volume never crosses;
/// [`CloudFitError::Fit`] if the fit fails.
pub fn fit_volume(
    volume: &Volume,
    iso: f32,
    resolution: usize,
    spacing: f32,
) -> Result<VolumeFit, CloudFitError> {
    fit_volume_within(volume, iso, whole(volume), resolution, spacing)
}

/// The whole volume's box, voxel coordinates.
fn whole(volume: &Volume) -> [Vec3; 2] {
    let [x, y, z] = volume.dims.map(|d| d.max(1) as f32 - 1.0);
    [Vec3::ZERO, Vec3::new(x, y, z)]
}

/// [`fit_volume`], with the object in the box `object` (voxel coordinates, inside the
/// volume) instead of the whole volume: that box is placed as a cloud's is (its longest side
/// spans the lattice less [`MARGIN_SPANS`] on each side), and the rest of the volume around
/// it is fitted too where the lattice reaches.
///
/// # Errors
/// As [`fit_volume`].
pub fn fit_volume_within(
    volume: &Volume,
    iso: f32,
    object: [Vec3; 2],
    resolution: usize,
    spacing: f32,
) -> Result<VolumeFit, CloudFitError> {
    if !(12..=256).contains(&resolution) {
        return Err(CloudFitError::Options(format!(
            "resolution {resolution}: must be 12 to 256 coefficients"
        )));
    }
    let (lo, hi) = volume
        .values
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    if !(iso > lo && iso < hi) {
        return Err(CloudFitError::Options(format!(
            "iso {iso}: the volume's intensities run from {lo} to {hi}; choose a value between"
        )));
    }
    let target = VolumeTarget::new(volume, iso, object, resolution, spacing);
    let mut lattice = BSplineLattice::zeros([resolution; 3], spacing, Vec3::ZERO)
        .map_err(|e| CloudFitError::Options(e.to_string()))?;
    fit_lattice(&mut lattice, 2, |x| target.density(x))?;
    Ok(VolumeFit {
        lattice,
        scale: target.scale,
        offset: target.offset,
    })
}

/// Where a volume lies in the lattice and the density its clay is fitted to.
struct VolumeTarget<'a> {
    volume: &'a Volume,
    iso: f32,
    /// Field units per voxel.
    scale: f32,
    /// Field position of voxel (0, 0, 0).
    offset: Vec3,
    /// The volume's extent, voxels.
    size: Vec3,
    /// The density profile's width, field units.
    width: f32,
}

impl<'a> VolumeTarget<'a> {
    fn new(
        volume: &'a Volume,
        iso: f32,
        object: [Vec3; 2],
        resolution: usize,
        spacing: f32,
    ) -> Self {
        let longest = (object[1] - object[0]).max_element().max(f32::MIN_POSITIVE);
        let span_total = (resolution - 1) as f32 - 2.0 * MARGIN_SPANS;
        let scale = span_total * spacing / longest;
        let size = Vec3::new(
            (volume.dims[0] - 1) as f32,
            (volume.dims[1] - 1) as f32,
            (volume.dims[2] - 1) as f32,
        );
        let offset = Vec3::splat((resolution - 1) as f32 * spacing * 0.5)
            - (object[0] + object[1]) * 0.5 * scale;
        Self {
            volume,
            iso,
            scale,
            offset,
            size,
            width: 2.0 * spacing,
        }
    }

    /// The density at field point `x`: the profile of the intensity's signed distance to
    /// first order, empty beyond the scan.
    fn density(&self, x: Vec3) -> f32 {
        let (volume, iso, width) = (self.volume, self.iso, self.width);
        let u = (x - self.offset) / self.scale;
        let inside_volume = u.cmpge(Vec3::ZERO).all() && u.cmple(self.size).all();
        if !inside_volume {
            // Beyond the scan: empty.
            return density_profile(width, width);
        }
        let v = volume.sample(u);
        let h = 0.5;
        let g = Vec3::new(
            volume.sample(u + Vec3::X * h) - volume.sample(u - Vec3::X * h),
            volume.sample(u + Vec3::Y * h) - volume.sample(u - Vec3::Y * h),
            volume.sample(u + Vec3::Z * h) - volume.sample(u - Vec3::Z * h),
        ) / (2.0 * h * self.scale);
        let slope = g.length();
        let signed = if slope > 1e-12 {
            (iso - v) / slope
        } else if v > iso {
            -width
        } else {
            width
        };
        density_profile(signed, width)
    }
}

/// Voxels whose density lies on the profile's ramp give the hierarchy's error samples, at
/// most this many (an even subset of more).
const MAX_VOLUME_SAMPLES: usize = 600_000;

/// A volume fitted hierarchically: the base of [`fit_volume`] plus the octree of detail
/// patches of [`super::hierarchy`], refined where the fit misses the voxels near the surface.
#[derive(Clone, Debug)]
pub struct VolumeHierarchy {
    /// The base (patch 0) and the detail patches, identity maps; iso-level 0.5.
    pub field: MultiPatchField,
    /// Field units per voxel.
    pub scale: f32,
    /// Field position of voxel (0, 0, 0).
    pub offset: Vec3,
    /// RMS distance error at the samples, base alone and with every patch, fraction of the
    /// volume's size.
    pub rms_base: f32,
    /// See [`VolumeHierarchy::rms_base`].
    pub rms: f32,
    /// Per depth: nodes checked and refined.
    pub levels: Vec<LevelReport>,
    /// Whether the clay's budget stopped the refinement short of the bound.
    pub over_budget: bool,
}

/// [`fit_volume`], then detail patches where the error at the voxels near the surface (those
/// whose density lies on the profile's ramp) is above `options.error` (a fraction of the
/// volume's longest side), down to `options.max_depth` (`options.base` is not used: the
/// resolution is `resolution`). `progress` as for [`super::fit_hierarchy`].
///
/// # Errors
/// As [`fit_volume`] and [`super::hierarchy::refine`].
pub fn fit_volume_hierarchy(
    volume: &Volume,
    iso: f32,
    resolution: usize,
    spacing: f32,
    options: &HierarchyOptions,
    progress: &mut dyn FnMut(FitProgress) -> bool,
) -> Result<VolumeHierarchy, CloudFitError> {
    fit_volume_hierarchy_within(
        volume,
        iso,
        whole(volume),
        resolution,
        spacing,
        options,
        progress,
    )
}

/// [`fit_volume_hierarchy`] with the object in the box `object` (voxel coordinates), placed
/// as in [`fit_volume_within`]; the error bound and the reported errors are fractions of that
/// box's longest side, and the octree's root is its bounding cube.
///
/// # Errors
/// As [`fit_volume_hierarchy`].
pub fn fit_volume_hierarchy_within(
    volume: &Volume,
    iso: f32,
    object: [Vec3; 2],
    resolution: usize,
    spacing: f32,
    options: &HierarchyOptions,
    progress: &mut dyn FnMut(FitProgress) -> bool,
) -> Result<VolumeHierarchy, CloudFitError> {
    if !progress(FitProgress::Base) {
        return Err(CloudFitError::Interrupted);
    }
    let base = fit_volume_within(volume, iso, object, resolution, spacing)?;
    let target = VolumeTarget::new(volume, iso, object, resolution, spacing);
    let [nx, ny, nz] = volume.dims;
    let near: Vec<Vec3> = (0..nz)
        .flat_map(|k| (0..ny).flat_map(move |j| (0..nx).map(move |i| (i, j, k))))
        .map(|(i, j, k)| target.offset + Vec3::new(i as f32, j as f32, k as f32) * target.scale)
        .filter(|&x| {
            let d = target.density(x);
            d > 0.02 && d < 0.98
        })
        .collect();
    let stride = near.len().div_ceil(MAX_VOLUME_SAMPLES).max(1);
    let at: Vec<Vec3> = near.into_iter().step_by(stride).collect();
    let mut field = MultiPatchField::new(base.lattice);
    let density = |x: Vec3| target.density(x);
    let data = Refinement {
        target: &density,
        spacing,
        width: target.width,
        samples_per_span: 2,
        lo: target.offset + object[0] * target.scale,
        hi: target.offset + object[1] * target.scale,
        noise: 0.0,
    };
    let refined = refine(&mut field, &data, at, options, progress)?;
    Ok(VolumeHierarchy {
        field,
        scale: target.scale,
        offset: target.offset,
        rms_base: refined.rms_base,
        rms: refined.rms,
        levels: refined.levels,
        over_budget: refined.over_budget,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 48³ byte volume of a ball: intensity falls linearly from 255 at the centre to 0 at
    /// 24 voxels; iso 127.5 sits 12 voxels out.
    fn ball_bytes() -> Vec<u8> {
        let c = Vec3::splat(23.5);
        let mut out = Vec::new();
        for k in 0..48 {
            for j in 0..48 {
                for i in 0..48 {
                    let r = (Vec3::new(i as f32, j as f32, k as f32) - c).length();
                    out.push((255.0 * (1.0 - r / 24.0)).clamp(0.0, 255.0).round() as u8);
                }
            }
        }
        out
    }

    #[test]
    fn a_ball_volume_fits_within_one_voxel() {
        let volume = decode(&ball_bytes(), [48; 3], Sample::U8, false, Path::new("ball")).unwrap();
        let fit = fit_volume(&volume, 127.5, 32, 0.1).unwrap();
        let l = &fit.lattice;
        let centre = fit.to_field(Vec3::splat(23.5));
        let truth = 12.0 * fit.scale;
        for s in 0..100 {
            // Directions spread over the sphere (a Fibonacci lattice).
            let y = 1.0 - 2.0 * (s as f32 + 0.5) / 100.0;
            let r = (1.0 - y * y).sqrt();
            let phi = s as f32 * std::f32::consts::PI * (3.0 - 5f32.sqrt());
            let dir = Vec3::new(r * phi.cos(), y, r * phi.sin());
            let (mut a, mut b) = (0.0, 2.0 * truth);
            for _ in 0..40 {
                let m = 0.5 * (a + b);
                if l.value(centre + dir * m) > l.iso {
                    a = m;
                } else {
                    b = m;
                }
            }
            let err_voxels = (0.5 * (a + b) - truth).abs() / fit.scale;
            assert!(err_voxels < 1.0, "off by {err_voxels} voxels along {dir}");
        }
    }

    #[test]
    fn nrrd_reads_its_header_and_refuses_mismatches() {
        let mut file =
            b"NRRD0004\n# a ball\ntype: uchar\ndimension: 3\nsizes: 48 48 48\nencoding: raw\n\n"
                .to_vec();
        file.extend(ball_bytes());
        let v = parse_nrrd(&file, Path::new("ball.nrrd")).unwrap();
        assert_eq!(v.dims, [48; 3]);
        assert_eq!(v.values[0], 0.0);
        for (text, want) in [
            (&b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 48 48 48\nencoding: gzip\n\n"[..], "ball.nrrd:5: encoding `gzip`"),
            (b"NRRD0004\ntype: double\n\n", "ball.nrrd:2: type `double`"),
            (b"PNG\n", "not an NRRD file"),
            (b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n\nabc", "3 bytes of samples"),
            (b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 100000 100000 100000\nencoding: raw\n\n", "at most"),
        ] {
            let e = parse_nrrd(text, Path::new("ball.nrrd")).unwrap_err().to_string();
            assert!(e.contains(want), "{e}");
        }
        let v = decode(&ball_bytes(), [48; 3], Sample::U8, false, Path::new("b")).unwrap();
        assert!(matches!(
            fit_volume(&v, 300.0, 32, 0.1),
            Err(CloudFitError::Options(_))
        ));
    }
}
