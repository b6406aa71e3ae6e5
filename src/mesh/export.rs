//! Mesh export to OBJ (with normals), binary little-endian PLY and binary STL.
//!
//! Every write is atomic: the bytes go to a temporary file in the target's directory, which
//! is flushed, fsynced and renamed over the target. On any error the temporary file is
//! removed, so the target is either the complete new file or untouched; errors name the path.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

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

/// A mesh could not be written to `path`.
#[derive(Debug)]
pub struct ExportError {
    pub path: PathBuf,
    /// What was being done: "create a temporary file", "write", "rename into place", ...
    pub action: &'static str,
    pub source: io::Error,
}

impl std::fmt::Display for ExportError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "cannot write mesh to {}: {} failed: {}",
            self.path.display(),
            self.action,
            self.source
        )
    }
}

impl std::error::Error for ExportError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        Some(&self.source)
    }
}

/// Writes `mesh` to `path` in `format`, atomically.
///
/// # Errors
/// When the directory cannot take a new file, a write or fsync fails, or the rename fails;
/// the error names `path` and no file is left behind.
pub fn write_mesh(path: &Path, mesh: &TriMesh, format: MeshFormat) -> Result<(), ExportError> {
    write_atomically(path, |out| match format {
        MeshFormat::Obj => encode_obj(mesh, out),
        MeshFormat::Ply => encode_ply(mesh, out),
        MeshFormat::Stl => encode_stl(mesh, out),
    })
}

/// Writes the bytes that `fill` produces to `path` atomically (temporary file in the same
/// directory, flush, fsync, rename, then fsync of the directory where supported).
///
/// # Errors
/// As [`write_mesh`]; an error from `fill` is reported with action "write".
pub fn write_atomically<W>(path: &Path, fill: W) -> Result<(), ExportError>
where
    W: FnOnce(&mut dyn Write) -> io::Result<()>,
{
    let fail = |action, source| ExportError {
        path: path.to_path_buf(),
        action,
        source,
    };
    let name = path.file_name().ok_or_else(|| {
        fail(
            "name the file",
            io::Error::new(io::ErrorKind::InvalidInput, "the path has no file name"),
        )
    })?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    // Relaxed: the counter only has to be unique, not ordered with anything.
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let temp = dir.join(format!(
        ".{}.{}-{n}.tmp",
        name.to_string_lossy(),
        std::process::id()
    ));
    let file = OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&temp)
        .map_err(|e| fail("create a temporary file beside it", e))?;

    let written = (|| {
        let mut out = BufWriter::with_capacity(1 << 16, &file);
        fill(&mut out).map_err(|e| ("write", e))?;
        out.flush().map_err(|e| ("write", e))?;
        drop(out);
        file.sync_all().map_err(|e| ("fsync", e))?;
        Ok::<(), (&'static str, io::Error)>(())
    })();
    drop(file);
    if let Err((action, e)) = written {
        let _ = fs::remove_file(&temp);
        return Err(fail(action, e));
    }
    if let Err(e) = fs::rename(&temp, path) {
        let _ = fs::remove_file(&temp);
        return Err(fail("rename into place", e));
    }
    // Make the rename durable. Not every platform can open a directory; the file itself is
    // complete either way.
    if let Ok(d) = File::open(&dir) {
        let _ = d.sync_all();
    }
    Ok(())
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
