//! Reading a point cloud from a file of any kind the importer takes, chosen by its extension:
//! XYZ text and PLY ([`super::points`]), or an OBJ or STL mesh sampled into points
//! ([`super::mesh`]). The file is read through the size cap [`MAX_POINT_FILE_BYTES`].

use std::path::Path;

use super::mesh::{parse_mesh, sample_triangles};
use super::points::{
    MAX_POINT_FILE_BYTES, PointCloud, PointColours, PointsError, parse_ply_with_colours, parse_xyz,
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
    let mut colours = None;
    let cloud = match ext.as_deref() {
        Some("ply") => {
            let (cloud, c) = parse_ply_with_colours(&bytes, &file)?;
            colours = c;
            cloud
        }
        Some("obj" | "stl") => {
            let (vertices, triangles) = parse_mesh(&bytes, &file)?;
            sample_triangles(&vertices, &triangles, &file)?
        }
        _ => parse_xyz(&bytes, &file)?,
    };
    if cloud.points.is_empty() {
        return Err(PointsError::Empty { file });
    }
    Ok((cloud, colours))
}
