//! Mesh export to OBJ (with normals), binary little-endian PLY and binary STL.
//!
//! Every write goes through the one atomic writer ([`dynaclay_files::write_atomic_with`]): the
//! bytes go to a temporary file in the target's directory, which is flushed, fsynced and
//! renamed over the target. On any error the temporary file is removed, so the target is either
//! the complete new file or untouched; errors name the path.

use std::io::{self, Write};
use std::path::Path;

use dynaclay_files::{WriteError, write_atomic_with};

use super::trimesh::TriMesh;

/// A mesh file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ, text, with `vn` normals and `f a//a` faces.
    Obj,
    /// Stanford PLY, binary little-endian: float x y z nx ny nz, uchar/uint faces.
    Ply,
    /// Binary STL: facet normals, unshared vertices.
    Stl,
}

impl MeshFormat {
    /// The format named by a path's extension (`obj`, `ply`, `stl`, any case).
    #[must_use]
    pub fn from_path(path: &Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "obj" => Some(Self::Obj),
            "ply" => Some(Self::Ply),
            "stl" => Some(Self::Stl),
            _ => None,
        }
    }
}

/// A mesh could not be written (the previous file at the path is untouched).
#[derive(Debug, thiserror::Error)]
#[error("cannot write mesh: {0}")]
pub struct ExportError(#[from] pub WriteError);

/// Writes `mesh` to `path` in `format`, atomically (through [`write_atomic_with`]).
///
/// # Errors
/// When the target is not a regular file, the directory cannot take a new file, a write or
/// fsync fails, or the rename fails; the error names `path` and no file is left behind.
pub fn write_mesh(path: &Path, mesh: &TriMesh, format: MeshFormat) -> Result<(), ExportError> {
    Ok(write_atomic_with(path, |out| match format {
        MeshFormat::Obj => encode_obj(mesh, out),
        MeshFormat::Ply => encode_ply(mesh, out),
        MeshFormat::Stl => encode_stl(mesh, out),
    })?)
}

/// OBJ text: `v`, `vn` per vertex, `f a//a b//b c//c` per triangle (1-based).
///
/// # Errors
/// When the writer fails.
pub fn encode_obj(mesh: &TriMesh, out: &mut dyn Write) -> io::Result<()> {
    writeln!(out, "# dynaclay mesh")?;
    writeln!(
        out,
        "# {} vertices, {} triangles",
        mesh.vertex_count(),
        mesh.triangle_count()
    )?;
    for p in &mesh.positions {
        writeln!(out, "v {} {} {}", p.x, p.y, p.z)?;
    }
    for n in &mesh.normals {
        writeln!(out, "vn {} {} {}", n.x, n.y, n.z)?;
    }
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| i + 1);
        writeln!(out, "f {a}//{a} {b}//{b} {c}//{c}")?;
    }
    Ok(())
}

/// Binary little-endian PLY with per-vertex normals.
///
/// # Errors
/// When the writer fails.
pub fn encode_ply(mesh: &TriMesh, out: &mut dyn Write) -> io::Result<()> {
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\ncomment dynaclay mesh\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         element face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        mesh.vertex_count(),
        mesh.triangle_count()
    )?;
    let mut buf = Vec::with_capacity(24);
    for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
        buf.clear();
        for v in [p.x, p.y, p.z, n.x, n.y, n.z] {
            buf.extend_from_slice(&v.to_le_bytes());
        }
        out.write_all(&buf)?;
    }
    for t in &mesh.triangles {
        buf.clear();
        buf.push(3u8);
        for i in t {
            buf.extend_from_slice(&i.to_le_bytes());
        }
        out.write_all(&buf)?;
    }
    Ok(())
}

/// Binary STL: 80-byte header, triangle count, then normal + three vertices per facet.
///
/// # Errors
/// When the writer fails, or the mesh has more than `u32::MAX` triangles.
pub fn encode_stl(mesh: &TriMesh, out: &mut dyn Write) -> io::Result<()> {
    let count = u32::try_from(mesh.triangle_count()).map_err(|_| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            "binary STL holds at most 4294967295 triangles",
        )
    })?;
    let mut header = [b' '; 80];
    let tag = b"dynaclay mesh (binary STL)";
    header[..tag.len()].copy_from_slice(tag);
    out.write_all(&header)?;
    out.write_all(&count.to_le_bytes())?;
    let mut buf = Vec::with_capacity(50);
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        let normal = (b - a).cross(c - a).normalize_or_zero();
        buf.clear();
        for v in [normal, a, b, c] {
            for x in [v.x, v.y, v.z] {
                buf.extend_from_slice(&x.to_le_bytes());
            }
        }
        buf.extend_from_slice(&0u16.to_le_bytes());
        out.write_all(&buf)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{BrickOctree, FnField, MeshStats, SampleGrid};
    use glam::Vec3;
    use std::collections::HashMap;
    use std::fs;

    fn sphere_mesh() -> TriMesh {
        let field = FnField {
            value: |p: Vec3| 0.3 - (p - Vec3::splat(0.5)).length(),
            gradient: |p: Vec3| -(p - Vec3::splat(0.5)).normalize_or_zero(),
            iso: 0.0,
            lipschitz: Some(1.0),
        };
        let grid = SampleGrid::new(Vec3::ZERO, 1.0 / 24.0, [24; 3]).unwrap();
        BrickOctree::build(grid, &field).weld()
    }

    fn read_obj(bytes: &[u8]) -> TriMesh {
        let text = std::str::from_utf8(bytes).unwrap();
        let mut mesh = TriMesh::default();
        let floats = |rest: &str| -> Vec3 {
            let v: Vec<f32> = rest
                .split_whitespace()
                .map(|x| x.parse().unwrap())
                .collect();
            Vec3::new(v[0], v[1], v[2])
        };
        for line in text.lines() {
            if let Some(rest) = line.strip_prefix("v ") {
                mesh.positions.push(floats(rest));
            } else if let Some(rest) = line.strip_prefix("vn ") {
                mesh.normals.push(floats(rest));
            } else if let Some(rest) = line.strip_prefix("f ") {
                let idx: Vec<u32> = rest
                    .split_whitespace()
                    .map(|t| {
                        let (v, n) = t.split_once("//").unwrap();
                        assert_eq!(v, n);
                        v.parse::<u32>().unwrap() - 1
                    })
                    .collect();
                mesh.triangles.push([idx[0], idx[1], idx[2]]);
            }
        }
        mesh
    }

    fn read_ply(bytes: &[u8]) -> TriMesh {
        let end = b"end_header\n";
        let at = bytes.windows(end.len()).position(|w| w == end).unwrap() + end.len();
        let header = std::str::from_utf8(&bytes[..at]).unwrap();
        assert!(header.starts_with("ply\nformat binary_little_endian 1.0\n"));
        let count = |name: &str| -> usize {
            let line = header
                .lines()
                .find(|l| l.starts_with(&format!("element {name} ")))
                .unwrap();
            line.rsplit(' ').next().unwrap().parse().unwrap()
        };
        let (nv, nf) = (count("vertex"), count("face"));
        let mut body = &bytes[at..];
        let mut f32_le = || {
            let v = f32::from_le_bytes(body[..4].try_into().unwrap());
            body = &body[4..];
            v
        };
        let mut mesh = TriMesh::default();
        for _ in 0..nv {
            let v: Vec<f32> = (0..6).map(|_| f32_le()).collect();
            mesh.positions.push(Vec3::new(v[0], v[1], v[2]));
            mesh.normals.push(Vec3::new(v[3], v[4], v[5]));
        }
        for _ in 0..nf {
            assert_eq!(body[0], 3);
            let i = |k: usize| u32::from_le_bytes(body[1 + 4 * k..5 + 4 * k].try_into().unwrap());
            mesh.triangles.push([i(0), i(1), i(2)]);
            body = &body[13..];
        }
        assert!(body.is_empty(), "{} trailing bytes", body.len());
        mesh
    }

    /// Reads binary STL and welds vertices by exact position.
    fn read_stl(bytes: &[u8]) -> TriMesh {
        let n = u32::from_le_bytes(bytes[80..84].try_into().unwrap()) as usize;
        assert_eq!(bytes.len(), 84 + 50 * n);
        let mut mesh = TriMesh::default();
        let mut ids: HashMap<[u32; 3], u32> = HashMap::new();
        for t in 0..n {
            let rec = &bytes[84 + 50 * t..84 + 50 * (t + 1)];
            let f = |k: usize| f32::from_le_bytes(rec[4 * k..4 * k + 4].try_into().unwrap());
            let normal = Vec3::new(f(0), f(1), f(2));
            let mut tri = [0u32; 3];
            for (v, slot) in tri.iter_mut().enumerate() {
                let p = Vec3::new(f(3 + 3 * v), f(4 + 3 * v), f(5 + 3 * v));
                *slot = *ids
                    .entry(p.to_array().map(f32::to_bits))
                    .or_insert_with(|| {
                        mesh.positions.push(p);
                        mesh.normals.push(normal);
                        (mesh.positions.len() - 1) as u32
                    });
            }
            mesh.triangles.push(tri);
        }
        mesh
    }

    #[test]
    fn exported_files_read_back_with_the_same_counts() {
        let mesh = sphere_mesh();
        let stats = MeshStats::of(&mesh);
        assert!(stats.is_closed_manifold() && stats.triangles > 500);
        let dir = tempfile::tempdir().unwrap();
        for format in [MeshFormat::Obj, MeshFormat::Ply, MeshFormat::Stl] {
            let path = dir.path().join(format!("sphere.{format:?}").to_lowercase());
            assert_eq!(MeshFormat::from_path(&path), Some(format));
            write_mesh(&path, &mesh, format).unwrap();
            let bytes = fs::read(&path).unwrap();
            let back = match format {
                MeshFormat::Obj => read_obj(&bytes),
                MeshFormat::Ply => read_ply(&bytes),
                MeshFormat::Stl => read_stl(&bytes),
            };
            let s = MeshStats::of(&back);
            assert_eq!(
                (s.vertices, s.triangles, s.edges),
                (stats.vertices, stats.triangles, stats.edges),
                "{format:?}"
            );
            assert_eq!(s.euler_characteristic, 2, "{format:?}");
            assert!(s.is_closed_manifold(), "{format:?}");
            assert!((s.volume - stats.volume).abs() < 1e-6 * stats.volume);
            if format != MeshFormat::Stl {
                // OBJ prints shortest round-trip decimals; PLY is raw bits: both exact.
                assert_eq!(back, mesh, "{format:?}");
            }
        }
        // Only the three files: no temporary files left over.
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 3);
    }

    #[test]
    fn unwritable_path_names_the_path_and_leaves_no_file() {
        let mesh = sphere_mesh();
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("no_such_dir").join("mesh.obj");
        let err = write_mesh(&missing, &mesh, MeshFormat::Obj).unwrap_err();
        assert!(
            err.to_string().contains(&missing.display().to_string()),
            "{err}"
        );
        assert!(!missing.exists());

        // A parent that is a regular file.
        let blocker = dir.path().join("file");
        fs::write(&blocker, b"x").unwrap();
        let under_file = blocker.join("mesh.stl");
        let err = write_mesh(&under_file, &mesh, MeshFormat::Stl).unwrap_err();
        assert!(err.to_string().contains("mesh.stl"), "{err}");

        // The target is a directory: the rename fails after the bytes were written.
        let target_dir = dir.path().join("taken.ply");
        fs::create_dir(&target_dir).unwrap();
        fs::write(target_dir.join("inner"), b"keep").unwrap();
        let err = write_mesh(&target_dir, &mesh, MeshFormat::Ply).unwrap_err();
        assert!(matches!(err.0, WriteError::NotRegular { .. }), "{err}");
        assert!(err.to_string().contains("taken.ply"), "{err}");
        let names: Vec<_> = fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 2, "left behind: {names:?}");
    }

    #[test]
    fn a_failing_encoder_leaves_the_old_file_untouched() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("mesh.obj");
        fs::write(&path, b"previous").unwrap();
        let err = write_atomic_with(&path, |out| {
            out.write_all(&[b'x'; 100_000])?;
            Err(io::Error::other("encoder gave up"))
        })
        .unwrap_err();
        assert!(matches!(err, WriteError::Io { op: "write", .. }), "{err}");
        assert!(err.to_string().contains("encoder gave up"));
        assert_eq!(fs::read(&path).unwrap(), b"previous");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
    }
}
