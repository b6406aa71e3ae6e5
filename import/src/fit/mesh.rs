//! Triangle meshes (OBJ, binary or ASCII STL): read, and, for an open mesh, sampled into a
//! point cloud: each triangle is sampled evenly at a spacing tied to the mesh's size, so the
//! mesh is fitted like a scan. The samples carry no normals: an open mesh's winding is often
//! inconsistent, and the cloud fit estimates and orients normals itself. (A closed mesh is
//! fitted from its signed distance instead: [`super::watertight`], [`super::sdf`].)
//!
//! Bad input is refused with the file and the line (OBJ, ASCII STL) or byte (binary STL);
//! counts are checked against the file's length and the sample total against
//! [`super::MAX_POINTS`] before allocating.

use std::path::Path;

use glam::Vec3;

use super::points::{MAX_POINT_FILE_BYTES, PointCloud, PointsError};
use dynaclay_core::io::bounded_read::read_regular_file;

/// Samples along the mesh's longest side (the sampling spacing is its size over this).
pub const SAMPLES_ACROSS: f32 = 256.0;

/// Reads the mesh at `path` (`.obj` or `.stl`, by its extension): its vertices and triangles.
///
/// # Errors
/// [`PointsError`] naming the file and the line or byte; [`PointsError::UnknownFormat`] for
/// another extension.
pub fn read_mesh(path: &Path) -> Result<(Vec<Vec3>, Vec<[u32; 3]>), PointsError> {
    let file = path.to_path_buf();
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !matches!(ext.as_deref(), Some("obj" | "stl")) {
        return Err(PointsError::UnknownFormat { file });
    }
    let bytes =
        read_regular_file(path, MAX_POINT_FILE_BYTES).map_err(|error| PointsError::Read {
            file: file.clone(),
            error,
        })?;
    parse_mesh(&bytes, &file)
}

/// Parses `bytes` as the mesh format `file`'s extension names (`.stl`, otherwise OBJ).
///
/// # Errors
/// As [`parse_obj`] and [`parse_stl`].
pub fn parse_mesh(bytes: &[u8], file: &Path) -> Result<(Vec<Vec3>, Vec<[u32; 3]>), PointsError> {
    let stl = file
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("stl"));
    if stl {
        parse_stl(bytes, file)
    } else {
        parse_obj(bytes, file)
    }
}

/// Parses an OBJ file's vertices and faces (polygons are fanned into triangles; `v/vt/vn`
/// references and negative indices are read; other statements are skipped).
///
/// # Errors
/// [`PointsError::Line`] at the first malformed statement.
pub fn parse_obj(bytes: &[u8], file: &Path) -> Result<(Vec<Vec3>, Vec<[u32; 3]>), PointsError> {
    let text = std::str::from_utf8(bytes).map_err(|e| PointsError::Byte {
        file: file.to_path_buf(),
        offset: e.valid_up_to(),
        what: "not UTF-8 text".into(),
    })?;
    let (mut vertices, mut triangles) = (Vec::new(), Vec::new());
    for (n, line) in text.lines().enumerate() {
        let bad = |what: String| PointsError::Line {
            file: file.to_path_buf(),
            line: n + 1,
            what,
        };
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let mut p = [0.0f32; 3];
                for slot in &mut p {
                    let w = words
                        .next()
                        .ok_or_else(|| bad("a vertex needs x y z".into()))?;
                    *slot = w
                        .parse()
                        .ok()
                        .filter(|v: &f32| v.is_finite())
                        .ok_or_else(|| bad(format!("`{w}` is not a finite number")))?;
                }
                if vertices.len() == super::MAX_POINTS {
                    return Err(bad(format!("more than {} vertices", super::MAX_POINTS)));
                }
                vertices.push(Vec3::from(p));
            }
            Some("f") => {
                let mut corners = Vec::new();
                for w in words {
                    let first = w.split('/').next().unwrap_or("");
                    let i: i64 = first
                        .parse()
                        .map_err(|_| bad(format!("`{w}` is not a vertex reference")))?;
                    let index = if i > 0 {
                        i - 1
                    } else {
                        vertices.len() as i64 + i
                    };
                    if index < 0 || index >= vertices.len() as i64 {
                        return Err(bad(format!(
                            "vertex {i} does not exist ({} so far)",
                            vertices.len()
                        )));
                    }
                    corners.push(index as u32);
                }
                if corners.len() < 3 {
                    return Err(bad("a face needs three vertices".into()));
                }
                for k in 1..corners.len() - 1 {
                    triangles.push([corners[0], corners[k], corners[k + 1]]);
                }
            }
            _ => {}
        }
    }
    Ok((vertices, triangles))
}

/// Parses an STL file, binary or ASCII (told apart by the binary size rule: 84 bytes plus 50
/// per triangle).
///
/// # Errors
/// [`PointsError::Byte`] or [`PointsError::Line`] at the first malformed part.
pub fn parse_stl(bytes: &[u8], file: &Path) -> Result<(Vec<Vec3>, Vec<[u32; 3]>), PointsError> {
    let binary_count = (bytes.len() >= 84)
        .then(|| u32::from_le_bytes([bytes[80], bytes[81], bytes[82], bytes[83]]) as usize);
    if let Some(count) = binary_count.filter(|&c| 84 + c.saturating_mul(50) == bytes.len()) {
        if count > super::MAX_POINTS {
            return Err(PointsError::Byte {
                file: file.to_path_buf(),
                offset: 80,
                what: format!("{count} triangles, more than {}", super::MAX_POINTS),
            });
        }
        let mut vertices = Vec::with_capacity(3 * count);
        let mut triangles = Vec::with_capacity(count);
        for t in 0..count {
            let at = 84 + 50 * t;
            for corner in 0..3 {
                let o = at + 12 + 12 * corner;
                let f = |k: usize| {
                    f32::from_le_bytes([
                        bytes[o + 4 * k],
                        bytes[o + 4 * k + 1],
                        bytes[o + 4 * k + 2],
                        bytes[o + 4 * k + 3],
                    ])
                };
                let p = Vec3::new(f(0), f(1), f(2));
                if !p.is_finite() {
                    return Err(PointsError::Byte {
                        file: file.to_path_buf(),
                        offset: o,
                        what: format!("triangle {t}: vertex {p} is not finite"),
                    });
                }
                vertices.push(p);
            }
            let base = 3 * t as u32;
            triangles.push([base, base + 1, base + 2]);
        }
        return Ok((vertices, triangles));
    }
    let text = std::str::from_utf8(bytes).map_err(|_| PointsError::Byte {
        file: file.to_path_buf(),
        offset: 80,
        what: "neither a binary STL (its size does not match its triangle count) nor ASCII".into(),
    })?;
    if !text.trim_start().starts_with("solid") {
        return Err(PointsError::Line {
            file: file.to_path_buf(),
            line: 1,
            what: "an ASCII STL starts with `solid`".into(),
        });
    }
    let (mut vertices, mut triangles) = (Vec::new(), Vec::new());
    let mut corner = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() != Some("vertex") {
            continue;
        }
        let bad = |what: String| PointsError::Line {
            file: file.to_path_buf(),
            line: n + 1,
            what,
        };
        let mut p = [0.0f32; 3];
        for slot in &mut p {
            let w = words
                .next()
                .ok_or_else(|| bad("a vertex needs x y z".into()))?;
            *slot = w
                .parse()
                .ok()
                .filter(|v: &f32| v.is_finite())
                .ok_or_else(|| bad(format!("`{w}` is not a finite number")))?;
        }
        if vertices.len() >= 3 * super::MAX_POINTS {
            return Err(bad(format!("more than {} triangles", super::MAX_POINTS)));
        }
        corner.push(vertices.len() as u32);
        vertices.push(Vec3::from(p));
        if corner.len() == 3 {
            triangles.push([corner[0], corner[1], corner[2]]);
            corner.clear();
        }
    }
    Ok((vertices, triangles))
}

/// Points sampled evenly over `triangles`, each with its triangle's normal (by its winding,
/// `(b − a) × (c − a)`): the spacing is the mesh's longest side over [`SAMPLES_ACROSS`]; each
/// triangle gets a barycentric grid fine enough for that spacing (its corners, edges and
/// inside), at least its corners. Triangles without area are left out (the triangles around
/// them cover their points). The import checks the normals as any file's: a mesh whose
/// winding is not consistent has them set aside, one wound inside out has them turned.
///
/// # Errors
/// [`PointsError::Empty`] for no triangles; [`PointsError::Line`] (line 0) when the samples
/// would pass [`super::MAX_POINTS`] or no triangle has an area.
pub fn sample_triangles(
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    file: &Path,
) -> Result<PointCloud, PointsError> {
    if triangles.is_empty() {
        return Err(PointsError::Empty {
            file: file.to_path_buf(),
        });
    }
    let (lo, hi) = vertices
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), &p| {
            (a.min(p), b.max(p))
        });
    let spacing = ((hi - lo).max_element() / SAMPLES_ACROSS).max(f32::MIN_POSITIVE);
    let steps = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|i| vertices[i as usize]);
        let longest = (b - a).length().max((c - b).length()).max((a - c).length());
        ((longest / spacing).ceil() as usize).clamp(1, 4096)
    };
    let total: usize = triangles
        .iter()
        .map(|t| {
            let s = steps(t);
            (s + 1) * (s + 2) / 2
        })
        .sum();
    if total > super::MAX_POINTS {
        return Err(PointsError::Line {
            file: file.to_path_buf(),
            line: 0,
            what: format!(
                "sampling the mesh would make {total} points, more than {}",
                super::MAX_POINTS
            ),
        });
    }
    let mut points = Vec::with_capacity(total);
    let mut normals = Vec::with_capacity(total);
    for t in triangles {
        let [a, b, c] = t.map(|i| vertices[i as usize]);
        // A triangle without area has no normal; the triangles around it cover its points.
        let Some(normal) = (b - a).cross(c - a).try_normalize() else {
            continue;
        };
        let s = steps(t);
        for i in 0..=s {
            for j in 0..=s - i {
                let (u, v) = (i as f32 / s as f32, j as f32 / s as f32);
                points.push(a + (b - a) * u + (c - a) * v);
                normals.push(normal);
            }
        }
    }
    if points.is_empty() {
        return Err(PointsError::Line {
            file: file.to_path_buf(),
            line: 0,
            what: "no triangle of the mesh has an area".into(),
        });
    }
    Ok(PointCloud {
        points,
        normals: Some(normals),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file() -> std::path::PathBuf {
        "mesh".into()
    }

    /// A unit cube as OBJ quads.
    const CUBE_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
        f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";

    #[test]
    fn obj_and_stl_read_the_same_cube() {
        let (v, t) = parse_obj(CUBE_OBJ.as_bytes(), &file()).unwrap();
        assert_eq!((v.len(), t.len()), (8, 12));
        let mut stl = vec![0u8; 80];
        stl.extend_from_slice(&12u32.to_le_bytes());
        let mut ascii = String::from("solid cube\n");
        for tri in &t {
            stl.extend_from_slice(&[0u8; 12]);
            ascii.push_str("facet normal 0 0 0\nouter loop\n");
            for &i in tri {
                for c in v[i as usize].to_array() {
                    stl.extend_from_slice(&c.to_le_bytes());
                }
                let p = v[i as usize];
                ascii.push_str(&format!("vertex {} {} {}\n", p.x, p.y, p.z));
            }
            stl.extend_from_slice(&[0u8; 2]);
            ascii.push_str("endloop\nendfacet\n");
        }
        for parsed in [
            parse_stl(&stl, &file()).unwrap(),
            parse_stl(ascii.as_bytes(), &file()).unwrap(),
        ] {
            assert_eq!(parsed.1.len(), 12);
            let area = |(vs, ts): &(Vec<Vec3>, Vec<[u32; 3]>)| -> f32 {
                ts.iter()
                    .map(|t| {
                        let [a, b, c] = t.map(|i| vs[i as usize]);
                        0.5 * (b - a).cross(c - a).length()
                    })
                    .sum()
            };
            assert!((area(&parsed) - 6.0).abs() < 1e-5);
        }
        let cloud = sample_triangles(&v, &t, &file()).unwrap();
        assert!(cloud.points.len() > 10_000, "{}", cloud.points.len());
        let (lo, hi) = (Vec3::splat(-1e-5), Vec3::splat(1.0 + 1e-5));
        assert!(
            cloud
                .points
                .iter()
                .all(|p| p.cmpge(lo).all() && p.cmple(hi).all())
        );
    }

    #[test]
    fn bad_meshes_are_refused_with_where() {
        for (text, want) in [
            ("v 0 0 0\nf 1 2 3\n", "mesh:2: vertex 2 does not exist"),
            ("v 0 0 x\n", "mesh:1: `x` is not a finite number"),
            ("v 0 0 0\nv 1 0 0\nf 1 2\n", "needs three vertices"),
        ] {
            let e = parse_obj(text.as_bytes(), &file()).unwrap_err().to_string();
            assert!(e.contains(want), "{e}");
        }
        let e = parse_stl(b"hello", &file()).unwrap_err().to_string();
        assert!(e.contains("starts with `solid`"), "{e}");
        let mut short = vec![0u8; 80];
        short.extend_from_slice(&1000u32.to_le_bytes());
        let e = parse_stl(&short, &file()).unwrap_err().to_string();
        assert!(
            e.contains("neither a binary STL") || e.contains("`solid`"),
            "{e}"
        );
        let e = sample_triangles(&[], &[], &file()).unwrap_err().to_string();
        assert!(e.contains("no points"), "{e}");
        let flat = [Vec3::ZERO, Vec3::X, Vec3::X * 2.0];
        let e = sample_triangles(&flat, &[[0, 1, 2]], &file())
            .unwrap_err()
            .to_string();
        assert!(e.contains("no triangle of the mesh has an area"), "{e}");
    }

    #[test]
    fn samples_carry_their_triangles_normal_by_its_winding() {
        // The unit cube: each face's samples take its outward normal; a triangle without area
        // added to it gives no samples.
        let (mut v, mut t) = parse_obj(CUBE_OBJ.as_bytes(), &file()).unwrap();
        let whole = sample_triangles(&v, &t, &file()).unwrap();
        v.extend([Vec3::ZERO, Vec3::splat(0.5), Vec3::ONE]);
        t.push([8, 9, 10]);
        let cloud = sample_triangles(&v, &t, &file()).unwrap();
        assert_eq!(cloud.points.len(), whole.points.len());
        let normals = cloud.normals.expect("normals by the winding");
        let centre = Vec3::splat(0.5);
        for (&p, &n) in cloud.points.iter().zip(&normals) {
            assert!((n.length() - 1.0).abs() < 1e-5);
            // Each is a face's axis, pointing away from the cube's centre.
            assert!(n.abs().max_element() > 0.999, "{n}");
            assert!((p - centre).dot(n) > 0.49, "{p} {n}");
        }
    }
}
