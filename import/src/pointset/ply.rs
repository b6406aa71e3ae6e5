//! Export of a point set as binary little-endian PLY: one `vertex` element with `x y z`,
//! `nx ny nz` (float) and `red green blue` (uchar), no faces, written atomically.

use std::io::{self, Write};
use std::path::Path;

use dynaclay_files::{WriteError, write_atomic_with};
use glam::Vec3;

/// Encodes points, normals and colours (equal lengths) as binary PLY.
///
/// # Errors
/// What `out` returns.
///
/// # Panics
/// When the slices differ in length.
pub fn encode_point_ply(
    points: &[Vec3],
    normals: &[Vec3],
    colours: &[[u8; 3]],
    out: &mut dyn Write,
) -> io::Result<()> {
    assert!(points.len() == normals.len() && points.len() == colours.len());
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\ncomment dynaclay point set\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
        points.len()
    )?;
    let mut buf = Vec::with_capacity(27 * 4096);
    for ((p, n), c) in points.iter().zip(normals).zip(colours) {
        for v in [p.x, p.y, p.z, n.x, n.y, n.z] {
            buf.extend_from_slice(&v.to_le_bytes());
        }
        buf.extend_from_slice(c);
        if buf.len() >= 27 * 4000 {
            out.write_all(&buf)?;
            buf.clear();
        }
    }
    out.write_all(&buf)
}

/// Writes points, normals and colours to `path` as binary PLY, atomically.
///
/// # Errors
/// When the file cannot be written.
pub fn write_point_ply(
    path: &Path,
    points: &[Vec3],
    normals: &[Vec3],
    colours: &[[u8; 3]],
) -> Result<(), WriteError> {
    write_atomic_with(path, |out| encode_point_ply(points, normals, colours, out))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::points::{parse_ply, parse_ply_with_colours};

    #[test]
    fn the_readers_read_back_positions_normals_and_colours() {
        let points = vec![Vec3::new(1.0, 2.0, 3.0), Vec3::new(-0.5, 0.25, 8.0)];
        let normals = vec![Vec3::X, Vec3::new(0.0, 0.6, 0.8)];
        let colours = vec![[1, 2, 3], [200, 100, 50]];
        let mut bytes = Vec::new();
        encode_point_ply(&points, &normals, &colours, &mut bytes).unwrap();
        let back = parse_ply(&bytes, Path::new("t.ply")).unwrap();
        assert_eq!(back.points, points);
        assert_eq!(back.normals.unwrap(), normals);
        let (_, back) = parse_ply_with_colours(&bytes, Path::new("t.ply")).unwrap();
        assert_eq!(back, Some(colours));
        // Float channels are 0..1; no colour properties, no colours.
        let text = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
                    property float z\nproperty float red\nproperty float green\n\
                    property float blue\nend_header\n0 0 0 1 0.5 0\n";
        let (_, back) = parse_ply_with_colours(text.as_bytes(), Path::new("f.ply")).unwrap();
        assert_eq!(back, Some(vec![[255, 128, 0]]));
        let text = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
                    property float z\nend_header\n0 0 0\n";
        let (_, back) = parse_ply_with_colours(text.as_bytes(), Path::new("g.ply")).unwrap();
        assert_eq!(back, None);
    }
}
