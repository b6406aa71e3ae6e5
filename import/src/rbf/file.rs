//! The RBF file: a small, checksummed binary format, and the way back to a clay.
//!
//! Layout (little-endian):
//!
//! ```text
//! offset  size        field
//! 0       8           magic  b"DCLYRBF\0"
//! 8       4           version (u32, 1)
//! 12      4           centre count k (u32, at most MAX_CENTRES)
//! 16      12          lattice dims (3 × u32) of the clay it came from
//! 28      4           lattice spacing (f32)
//! 32      12          lattice origin (3 × f32)
//! 44      4           iso-level (f32)
//! 48      32          polynomial a, b, c, d (4 × f64)
//! 80      32 k        centres: x, y, z, weight (4 × f64 each)
//! 80+32k  4           CRC-32 of every byte before it
//! ```
//!
//! Reads are bounded: the file must be a regular file no longer than the largest legal size,
//! and its length must match the count it declares before anything else is decoded. Writes go
//! through [`dynaclay_core::io::write_atomic`].

use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};

use super::fit::Rbf;
use dynaclay_core::field::{BSplineLattice, FitError, LatticeError, density_profile, fit_lattice};
use dynaclay_core::io::bounded_read::{BoundedReadError, read_regular_file};
use dynaclay_core::io::{SessionError, write_atomic};
use dynaclay_files::{ByteCursor, ShortRead};

/// The file's first eight bytes.
pub const MAGIC: [u8; 8] = *b"DCLYRBF\0";
/// The format version written.
pub const VERSION: u32 = 1;
/// The most centres a file may hold.
pub const MAX_CENTRES: usize = 1 << 20;
const HEADER: usize = 80;
const PER_CENTRE: usize = 32;

/// An RBF with the lattice of the clay it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct RbfFile {
    /// The function.
    pub rbf: Rbf,
    /// Dimensions of the source clay's lattice.
    pub dims: [usize; 3],
    /// Its knot spacing.
    pub spacing: f32,
    /// Its origin.
    pub origin: Vec3,
    /// Its iso-level.
    pub iso: f32,
}

/// Why an RBF file could not be read, written or turned into a clay.
#[derive(Debug, thiserror::Error)]
pub enum RbfFileError {
    /// The file could not be read (missing, not a regular file, too large).
    #[error("cannot read {path}: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: BoundedReadError,
    },
    /// The file could not be written.
    #[error(transparent)]
    Write(#[from] SessionError),
    /// The file does not start with the RBF magic.
    #[error("{path} is not a dynaclay RBF file")]
    NotRbf {
        /// The file.
        path: PathBuf,
    },
    /// A newer format version.
    #[error("{path} has RBF format version {found}; this build reads version {VERSION}")]
    UnsupportedVersion {
        /// The file.
        path: PathBuf,
        /// The version found.
        found: u32,
    },
    /// The length does not match the declared centre count.
    #[error("{path} is {len} bytes, but its header declares {centres} centres ({expected} bytes)")]
    Truncated {
        /// The file.
        path: PathBuf,
        /// Bytes in the file.
        len: usize,
        /// Centres declared.
        centres: usize,
        /// Bytes those need.
        expected: usize,
    },
    /// More centres than a file may hold.
    #[error("{centres} centres is more than the {MAX_CENTRES} a file may hold")]
    TooManyCentres {
        /// Centres declared or given.
        centres: usize,
    },
    /// The checksum does not match: the file is damaged.
    #[error("{path} is damaged (checksum mismatch)")]
    Checksum {
        /// The file.
        path: PathBuf,
    },
    /// A number in the file is not finite, or the lattice it names is invalid.
    #[error("{path} holds an invalid {what}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Which field.
        what: &'static str,
    },
    /// The lattice named in the file cannot be built.
    #[error(transparent)]
    Lattice(#[from] LatticeError),
    /// Fitting the clay to the RBF failed.
    #[error(transparent)]
    Fit(#[from] FitError),
}

/// Encode `file` (see the module docs for the layout).
///
/// # Errors
/// [`RbfFileError::TooManyCentres`] above [`MAX_CENTRES`].
pub fn encode(file: &RbfFile) -> Result<Vec<u8>, RbfFileError> {
    let k = file.rbf.centres.len();
    if k > MAX_CENTRES || file.rbf.weights.len() != k {
        return Err(RbfFileError::TooManyCentres { centres: k });
    }
    let mut out = Vec::with_capacity(HEADER + PER_CENTRE * k + 4);
    out.extend_from_slice(&MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(k as u32).to_le_bytes());
    for d in file.dims {
        out.extend_from_slice(&(d as u32).to_le_bytes());
    }
    out.extend_from_slice(&file.spacing.to_le_bytes());
    for o in file.origin.to_array() {
        out.extend_from_slice(&o.to_le_bytes());
    }
    out.extend_from_slice(&file.iso.to_le_bytes());
    for p in file.rbf.poly {
        out.extend_from_slice(&p.to_le_bytes());
    }
    for (c, w) in file.rbf.centres.iter().zip(&file.rbf.weights) {
        for v in [c.x, c.y, c.z, *w] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    Ok(out)
}

/// Decode the bytes of an RBF file; `path` names it in errors.
///
/// # Errors
/// [`RbfFileError::NotRbf`], [`RbfFileError::UnsupportedVersion`],
/// [`RbfFileError::Truncated`], [`RbfFileError::TooManyCentres`], [`RbfFileError::Checksum`],
/// [`RbfFileError::Invalid`].
pub fn decode(bytes: &[u8], path: &Path) -> Result<RbfFile, RbfFileError> {
    let path_buf = || path.to_path_buf();
    let mut cursor = ByteCursor::new(bytes);
    let not_rbf = |_: ShortRead| RbfFileError::NotRbf { path: path_buf() };
    if cursor.array::<8>().map_err(not_rbf)? != MAGIC {
        return Err(RbfFileError::NotRbf { path: path_buf() });
    }
    let version = cursor.u32().map_err(not_rbf)?;
    if version != VERSION {
        return Err(RbfFileError::UnsupportedVersion {
            path: path_buf(),
            found: version,
        });
    }
    let short = |centres: usize, expected: usize| {
        move |_: ShortRead| RbfFileError::Truncated {
            path: path_buf(),
            len: bytes.len(),
            centres,
            expected,
        }
    };
    if bytes.len() < HEADER + 4 {
        return Err(RbfFileError::Truncated {
            path: path_buf(),
            len: bytes.len(),
            centres: 0,
            expected: HEADER + 4,
        });
    }
    let k = cursor.u32().map_err(short(0, HEADER + 4))? as usize;
    if k > MAX_CENTRES {
        return Err(RbfFileError::TooManyCentres { centres: k });
    }
    let expected = HEADER + PER_CENTRE * k + 4;
    if bytes.len() != expected {
        return Err(RbfFileError::Truncated {
            path: path_buf(),
            len: bytes.len(),
            centres: k,
            expected,
        });
    }
    let (body, stored_crc) = bytes.split_at(expected - 4);
    let stored_crc = ByteCursor::new(stored_crc)
        .u32()
        .map_err(short(k, expected))?;
    if crc32fast::hash(body) != stored_crc {
        return Err(RbfFileError::Checksum { path: path_buf() });
    }
    // The length is checked: what follows cannot run short (a short read would still be an
    // error, not a panic).
    let short = short(k, expected);
    let invalid = |what| RbfFileError::Invalid {
        path: path_buf(),
        what,
    };
    let mut dims = [0usize; 3];
    for d in &mut dims {
        *d = cursor.u32().map_err(short)? as usize;
    }
    let spacing = cursor.f32().map_err(short)?;
    let origin = Vec3::new(
        cursor.f32().map_err(short)?,
        cursor.f32().map_err(short)?,
        cursor.f32().map_err(short)?,
    );
    let iso = cursor.f32().map_err(short)?;
    // Lattices larger than 512 per axis are refused: importing one would allocate gigabytes.
    if dims.iter().any(|&d| !(4..=512).contains(&d)) {
        return Err(invalid("lattice size"));
    }
    let spacing_ok = spacing.is_finite() && spacing > 0.0;
    if !spacing_ok || !origin.is_finite() || !iso.is_finite() {
        return Err(invalid("lattice geometry"));
    }
    let mut poly = [0.0f64; 4];
    for p in &mut poly {
        *p = cursor.f64().map_err(short)?;
    }
    if poly.iter().any(|p| !p.is_finite()) {
        return Err(invalid("polynomial"));
    }
    debug_assert_eq!(cursor.at(), HEADER);
    let mut centres = Vec::with_capacity(k);
    let mut weights = Vec::with_capacity(k);
    for _ in 0..k {
        let c = DVec3::new(
            cursor.f64().map_err(short)?,
            cursor.f64().map_err(short)?,
            cursor.f64().map_err(short)?,
        );
        let w = cursor.f64().map_err(short)?;
        if !(c.is_finite() && w.is_finite()) {
            return Err(invalid("centre"));
        }
        centres.push(c);
        weights.push(w);
    }
    Ok(RbfFile {
        rbf: Rbf {
            centres,
            weights,
            poly,
        },
        dims,
        spacing,
        origin,
        iso,
    })
}

/// Write `file` to `path` atomically.
///
/// # Errors
/// [`RbfFileError::TooManyCentres`], or [`RbfFileError::Write`] when the write fails (the
/// previous file at `path` is untouched).
pub fn write_rbf(path: &Path, file: &RbfFile) -> Result<(), RbfFileError> {
    let bytes = encode(file)?;
    write_atomic(path, &bytes)?;
    Ok(())
}

/// Read an RBF file (bounded: at most the size of [`MAX_CENTRES`] centres).
///
/// # Errors
/// [`RbfFileError::Read`] and the errors of [`decode`].
pub fn read_rbf(path: &Path) -> Result<RbfFile, RbfFileError> {
    let cap = (HEADER + PER_CENTRE * MAX_CENTRES + 4) as u64;
    let bytes = read_regular_file(path, cap).map_err(|source| RbfFileError::Read {
        path: path.to_path_buf(),
        source,
    })?;
    decode(&bytes, path)
}

impl RbfFile {
    /// Import the RBF back as a clay: a lattice of the recorded geometry, least-squares fitted
    /// (by [`fit_lattice`], `samples_per_span` samples per span) to the clamped density
    /// profile of the RBF's distance, `clamp(iso − (−I(x)) / width, 0, 1)` with a transition
    /// `width` of two knot spans, as the primitives are built.
    ///
    /// Each sample costs one RBF evaluation (`k` centres), so the import costs
    /// `(samples_per_span · n)³ · k` evaluations of `|r|³`.
    ///
    /// # Errors
    /// [`RbfFileError::Lattice`] or [`RbfFileError::Fit`].
    pub fn to_clay(&self, samples_per_span: usize) -> Result<BSplineLattice, RbfFileError> {
        let mut lattice = BSplineLattice::zeros(self.dims, self.spacing, self.origin)?;
        lattice.iso = self.iso;
        let width = 2.0 * f64::from(self.spacing);
        let iso = f64::from(self.iso);
        fit_lattice(&mut lattice, samples_per_span, |x| {
            let inside = self.rbf.value(x.as_dvec3());
            // density_profile(sd) = clamp(0.5 − sd/width); shifted to this iso-level.
            (density_profile((-inside / width) as f32, 1.0) - 0.5 + iso as f32).clamp(0.0, 1.0)
        })?;
        Ok(lattice)
    }
}
