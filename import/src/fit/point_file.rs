//! Reading a point cloud from a file of any kind the importer takes, chosen by its extension:
//! XYZ text and PLY ([`super::points`]), or an OBJ or STL mesh sampled into points
//! ([`super::mesh`]). The file is read through the size cap [`MAX_POINT_FILE_BYTES`].

use std::path::Path;

use glam::{DVec3, Vec3};

use super::mesh::{parse_mesh, sample_triangles};
use super::points::{
    MAX_POINT_FILE_BYTES, PointCloud, PointColours, PointsError, parse_ply_about, parse_xyz_about,
};
use dynaclay_core::io::bounded_read::read_regular_file;

/// Reads the point cloud at `path`, by its extension: `.xyz`, `.txt`, `.pts` (text) or `.ply`;
/// or a mesh, `.obj` or `.stl`, sampled into points ([`super::mesh`]).
///
/// # Errors
/// [`PointsError`] naming the file and, where it applies, the line or byte.
pub fn read_points(path: &Path) -> Result<PointCloud, PointsError> {
    read_points_with_colours(path).map(|(cloud, _)| cloud)
}

/// [`read_points`], with the points' colours when the file has them (a PLY file with `red`,
/// `green` and `blue` vertex properties).
///
/// # Errors
/// As [`read_points`].
pub fn read_points_with_colours(
    path: &Path,
) -> Result<(PointCloud, Option<PointColours>), PointsError> {
    let (bytes, ext) = read_point_file(path)?;
    parse_by_extension(&bytes, ext.as_deref(), path, DVec3::ZERO)
}

/// A text or PLY cloud farther than this many times its size from the file's origin is read
/// relative to the centre of its box ([`read_points_about_their_centre`]): `f32`'s step at
/// its coordinates would otherwise be over `2⁻²³ × 256 ≈ 3·10⁻⁵` of its size (a scan in
/// georeferenced coordinates, metres at 10⁵–10⁶, loses millimetres or more).
pub const FAR_FROM_ORIGIN_SIZES: f32 = 256.0;

/// [`read_points_with_colours`], but a text or PLY cloud lying farther than
/// [`FAR_FROM_ORIGIN_SIZES`] times its size from the file's origin is read again in `f64`
/// less the centre of its box, which is returned: the file's coordinates are the points plus
/// it (zero where the cloud was read as it is).
///
/// # Errors
/// As [`read_points`].
pub fn read_points_about_their_centre(
    path: &Path,
) -> Result<(PointCloud, Option<PointColours>, DVec3), PointsError> {
    let (bytes, ext) = read_point_file(path)?;
    let (cloud, colours) = parse_by_extension(&bytes, ext.as_deref(), path, DVec3::ZERO)?;
    let is_mesh = matches!(ext.as_deref(), Some("obj" | "stl"));
    let (lo, hi) = cloud
        .points
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    let farthest = lo.abs().max(hi.abs()).max_element();
    let size = (hi - lo).max_element();
    if is_mesh || farthest <= FAR_FROM_ORIGIN_SIZES * size {
        return Ok((cloud, colours, DVec3::ZERO));
    }
    let centre = (lo.as_dvec3() + hi.as_dvec3()) * 0.5;
    // The first reading goes before the second is made (a cloud's worth of memory less).
    drop((cloud, colours));
    let (cloud, colours) = parse_by_extension(&bytes, ext.as_deref(), path, centre)?;
    Ok((cloud, colours, centre))
}

/// The bytes of the point file at `path` (through the size cap) and its extension, lower
/// case.
fn read_point_file(path: &Path) -> Result<(Vec<u8>, Option<String>), PointsError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let file = path.to_path_buf();
    let bytes = match ext.as_deref() {
        Some("xyz" | "txt" | "pts" | "ply" | "obj" | "stl") => {
            read_regular_file(path, MAX_POINT_FILE_BYTES).map_err(|error| PointsError::Read {
                file: file.clone(),
                error,
            })?
        }
        _ => return Err(PointsError::UnknownFormat { file }),
    };
    Ok((bytes, ext))
}

/// The cloud in `bytes`, parsed by the file's extension `ext`, text and PLY positions less
/// `origin` (a mesh's samples as they are).
fn parse_by_extension(
    bytes: &[u8],
    ext: Option<&str>,
    path: &Path,
    origin: DVec3,
) -> Result<(PointCloud, Option<PointColours>), PointsError> {
    let file = path.to_path_buf();
    let mut colours = None;
    let cloud = match ext {
        Some("ply") => {
            let (cloud, c) = parse_ply_about(bytes, &file, origin)?;
            colours = c;
            cloud
        }
        Some("obj" | "stl") => {
            let (vertices, triangles) = parse_mesh(bytes, &file)?;
            // Read as points, a mesh's samples leave its winding behind: the readers of
            // points (the point-set surfaces, scripts) take given normals as they are, and a
            // triangle soup's winding need not agree from one triangle to the next.
            PointCloud {
                normals: None,
                ..sample_triangles(&vertices, &triangles, &file)?
            }
        }
        _ => parse_xyz_about(bytes, &file, origin)?,
    };
    if cloud.points.is_empty() {
        return Err(PointsError::Empty { file });
    }
    Ok((cloud, colours))
}
