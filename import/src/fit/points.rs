//! Point clouds read from files: XYZ text (`x y z` or `x y z nx ny nz` per line) and PLY
//! (ASCII or binary, little- or big-endian; a `vertex` element with `x y z` and optionally
//! `nx ny nz`, in any order, among other properties).
//!
//! Bad input is refused with the file and the line (text) or byte offset (binary) and what is
//! wrong; a file is read through a size cap, and a declared point count is checked against
//! the file's length and [`MAX_POINTS`] before anything is allocated for it. Every coordinate
//! must be finite.

use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};

use dynaclay_core::io::bounded_read::BoundedReadError;

/// The most points a file may hold.
pub const MAX_POINTS: usize = 20_000_000;
/// The largest point file read, bytes.
pub const MAX_POINT_FILE_BYTES: u64 = 2 << 30;

/// Points, with a normal per point where the file has them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointCloud {
    /// Positions, in the file's units.
    pub points: Vec<Vec3>,
    /// Unit normals (one per point), when the file has them.
    pub normals: Option<Vec<Vec3>>,
}

/// One 8-bit sRGB colour per point.
pub type PointColours = Vec<[u8; 3]>;

/// Why a point file was refused.
#[derive(Debug, thiserror::Error)]
pub enum PointsError {
    /// The file could not be read.
    #[error("{}: {error}", file.display())]
    Read {
        /// The file.
        file: PathBuf,
        /// Why.
        error: BoundedReadError,
    },
    /// A text line is malformed.
    #[error("{}:{line}: {what}", file.display())]
    Line {
        /// The file.
        file: PathBuf,
        /// Line number, from 1.
        line: usize,
        /// What is wrong.
        what: String,
    },
    /// Binary data is malformed.
    #[error("{}: byte {offset}: {what}", file.display())]
    Byte {
        /// The file.
        file: PathBuf,
        /// Offset of the problem.
        offset: usize,
        /// What is wrong.
        what: String,
    },
    /// The file holds no points.
    #[error("{}: no points", file.display())]
    Empty {
        /// The file.
        file: PathBuf,
    },
    /// The file's extension names no format this reader knows.
    #[error(
        "{}: unknown format (expected a cloud .xyz, .txt, .pts, .ply or a mesh .obj, .stl)",
        file.display()
    )]
    UnknownFormat {
        /// The file.
        file: PathBuf,
    },
}

/// Parses XYZ text: per line three coordinates, or six (position then normal); blank lines and
/// lines starting with `#` are skipped; every line has the same count.
///
/// # Errors
/// [`PointsError::Line`] at the first malformed line.
pub fn parse_xyz(bytes: &[u8], file: &Path) -> Result<PointCloud, PointsError> {
    parse_xyz_about(bytes, file, DVec3::ZERO)
}

/// [`parse_xyz`], each position less `origin` (taken in `f64` from the text, then rounded to
/// `f32`): a cloud far from the file's origin keeps its precision. With `origin` zero, the
/// values are read straight into `f32`, as [`parse_xyz`] reads them.
///
/// # Errors
/// As [`parse_xyz`].
pub(crate) fn parse_xyz_about(
    bytes: &[u8],
    file: &Path,
    origin: DVec3,
) -> Result<PointCloud, PointsError> {
    let shifted = origin != DVec3::ZERO;
    let text = std::str::from_utf8(bytes).map_err(|e| PointsError::Byte {
        file: file.to_path_buf(),
        offset: e.valid_up_to(),
        what: "not UTF-8 text".into(),
    })?;
    let mut cloud = PointCloud::default();
    let mut columns = None;
    let mut normals = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line_no = n + 1;
        let bad = |what: String| PointsError::Line {
            file: file.to_path_buf(),
            line: line_no,
            what,
        };
        let body = line.trim();
        if body.is_empty() || body.starts_with('#') {
            continue;
        }
        let mut values = [0.0f32; 6];
        let mut count = 0;
        for token in body.split(|c: char| c.is_whitespace() || c == ',') {
            if token.is_empty() {
                continue;
            }
            if count == 6 {
                return Err(bad("more than six numbers".into()));
            }
            let v: f32 = if shifted {
                let wide: f64 = token
                    .parse()
                    .map_err(|_| bad(format!("`{token}` is not a number")))?;
                if !wide.is_finite() {
                    return Err(bad(format!("`{token}` is not a finite number")));
                }
                (if count < 3 {
                    wide - origin[count]
                } else {
                    wide
                }) as f32
            } else {
                token
                    .parse()
                    .map_err(|_| bad(format!("`{token}` is not a number")))?
            };
            if !v.is_finite() {
                return Err(bad(format!("`{token}` is not a finite number")));
            }
            values[count] = v;
            count += 1;
        }
        if count != 3 && count != 6 {
            return Err(bad(format!(
                "{count} numbers; expected x y z or x y z nx ny nz"
            )));
        }
        match columns {
            None => columns = Some(count),
            Some(c) if c != count => {
                return Err(bad(format!("{count} numbers where earlier lines have {c}")));
            }
            Some(_) => {}
        }
        if cloud.points.len() == MAX_POINTS {
            return Err(bad(format!("more than {MAX_POINTS} points")));
        }
        cloud
            .points
            .push(Vec3::new(values[0], values[1], values[2]));
        if count == 6 {
            normals.push(unit_or_zero(Vec3::new(values[3], values[4], values[5])));
        }
    }
    if columns == Some(6) {
        cloud.normals = Some(normals);
    }
    Ok(cloud)
}

fn unit_or_zero(n: Vec3) -> Vec3 {
    n.try_normalize().unwrap_or(Vec3::ZERO)
}

/// How a PLY file stores its data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PlyFormat {
    Ascii,
    BinaryLittle,
    BinaryBig,
}

/// A scalar property type's size in bytes, or `None` for an unknown type.
fn ply_type_size(name: &str) -> Option<usize> {
    Some(match name {
        "char" | "int8" | "uchar" | "uint8" => 1,
        "short" | "int16" | "ushort" | "uint16" => 2,
        "int" | "int32" | "uint" | "uint32" | "float" | "float32" => 4,
        "double" | "float64" => 8,
        _ => return None,
    })
}

/// One declared element: its name, count and scalar properties (name, type); list
/// properties are allowed only on elements after `vertex` (the reader stops there).
struct PlyElement {
    name: String,
    count: usize,
    properties: Vec<(String, String)>,
}

/// Parses a PLY file's header and its `vertex` element.
///
/// # Errors
/// [`PointsError::Line`] for a malformed header, [`PointsError::Byte`] for malformed data.
pub fn parse_ply(bytes: &[u8], file: &Path) -> Result<PointCloud, PointsError> {
    parse_ply_with_colours(bytes, file).map(|(cloud, _)| cloud)
}

/// [`parse_ply`], with each vertex's colour when the vertices have `red`, `green` and `blue`
/// (integer types are taken as 0–255, float types as 0–1, both clamped; a value that is not
/// finite reads as 0). Some but not all of the three is refused, naming the header line.
///
/// # Errors
/// As [`parse_ply`].
pub fn parse_ply_with_colours(
    bytes: &[u8],
    file: &Path,
) -> Result<(PointCloud, Option<PointColours>), PointsError> {
    parse_ply_about(bytes, file, DVec3::ZERO)
}

/// [`parse_ply_with_colours`], each position less `origin` (in `f64`, before the rounding to
/// `f32`): a cloud far from the file's origin keeps the precision its file has.
///
/// # Errors
/// As [`parse_ply`].
pub(crate) fn parse_ply_about(
    bytes: &[u8],
    file: &Path,
    origin: DVec3,
) -> Result<(PointCloud, Option<PointColours>), PointsError> {
    let line_err = |line: usize, what: String| PointsError::Line {
        file: file.to_path_buf(),
        line,
        what,
    };
    // The header is ASCII lines up to `end_header`.
    let mut at = 0;
    let mut line_no = 0;
    let mut format = None;
    let mut elements: Vec<PlyElement> = Vec::new();
    // The header line of the vertices' first colour property, to name in an error.
    loop {
        let Some(len) = bytes[at..].iter().position(|&b| b == b'\n') else {
            return Err(line_err(
                line_no + 1,
                "the header has no `end_header`".into(),
            ));
        };
        line_no += 1;
        let line = std::str::from_utf8(&bytes[at..at + len])
            .map_err(|_| line_err(line_no, "the header is not ASCII".into()))?
            .trim();
        at += len + 1;
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["ply"] if line_no == 1 => {}
            _ if line_no == 1 => return Err(line_err(1, "not a PLY file (no `ply` line)".into())),
            ["format", f, _version] => {
                format = Some(match *f {
                    "ascii" => PlyFormat::Ascii,
                    "binary_little_endian" => PlyFormat::BinaryLittle,
                    "binary_big_endian" => PlyFormat::BinaryBig,
                    other => return Err(line_err(line_no, format!("unknown format `{other}`"))),
                });
            }
            ["comment", ..] | ["obj_info", ..] | [] => {}
            ["element", name, count] => {
                let count: usize = count
                    .parse()
                    .map_err(|_| line_err(line_no, format!("element count `{count}`")))?;
                elements.push(PlyElement {
                    name: (*name).to_owned(),
                    count,
                    properties: Vec::new(),
                });
            }
            ["property", "list", ..] => {
                let Some(e) = elements.last_mut() else {
                    return Err(line_err(line_no, "a property before any element".into()));
                };
                if e.name == "vertex" {
                    return Err(line_err(
                        line_no,
                        "list properties on vertices are not supported".into(),
                    ));
                }
                e.properties.push(("list".into(), "list".into()));
            }
            ["property", ty, name] => {
                let Some(e) = elements.last_mut() else {
                    return Err(line_err(line_no, "a property before any element".into()));
                };
                if ply_type_size(ty).is_none() {
                    return Err(line_err(line_no, format!("unknown property type `{ty}`")));
                }
                e.properties.push(((*name).to_owned(), (*ty).to_owned()));
            }
            ["end_header"] => break,
            _ => {
                return Err(line_err(
                    line_no,
                    format!("unexpected header line `{line}`"),
                ));
            }
        }
    }
    let format = format.ok_or_else(|| line_err(line_no, "no `format` line".into()))?;
    // Elements before `vertex` would have to be skipped; files put vertices first.
    let Some(vertex) = elements.first().filter(|e| e.name == "vertex") else {
        return Err(line_err(
            line_no,
            "the first element must be `vertex`".into(),
        ));
    };
    let column = |name: &str| vertex.properties.iter().position(|(n, _)| n == name);
    let (Some(x), Some(y), Some(z)) = (column("x"), column("y"), column("z")) else {
        return Err(line_err(line_no, "vertices need x, y and z".into()));
    };
    let normal_columns = match (column("nx"), column("ny"), column("nz")) {
        (Some(a), Some(b), Some(c)) => Some([a, b, c]),
        _ => None,
    };
    // Colours only as red, green and blue together; one or two of them alone are other
    // properties (a scalar named `red` is valid PLY), read past like any other.
    let colour_columns = match (column("red"), column("green"), column("blue")) {
        (Some(a), Some(b), Some(c)) => Some([a, b, c]),
        _ => None,
    };
    // A float channel is 0..1, an integer one 0..255.
    let colour_scale: [f64; 3] = colour_columns.map_or([1.0; 3], |cols| {
        cols.map(|c| {
            if matches!(
                vertex.properties[c].1.as_str(),
                "float" | "float32" | "double" | "float64"
            ) {
                255.0
            } else {
                1.0
            }
        })
    });
    let count = vertex.count;
    if count > MAX_POINTS {
        return Err(line_err(
            line_no,
            format!("{count} vertices declared, more than the {MAX_POINTS} accepted"),
        ));
    }
    let data = &bytes[at..];
    let row_bytes: usize = vertex
        .properties
        .iter()
        .map(|(_, t)| ply_type_size(t).unwrap_or(0))
        .sum();
    // Every vertex takes at least `row_bytes` (binary) or two bytes (ASCII): check before
    // allocating for the declared count.
    let least = if format == PlyFormat::Ascii {
        2
    } else {
        row_bytes
    };
    if count.saturating_mul(least) > data.len() {
        return Err(PointsError::Byte {
            file: file.to_path_buf(),
            offset: bytes.len(),
            what: format!(
                "{count} vertices declared, but the file ends after {} bytes of data",
                data.len()
            ),
        });
    }
    let mut points = Vec::with_capacity(count);
    let mut normals = normal_columns.map(|_| Vec::with_capacity(count));
    let mut colours: Option<Vec<[u8; 3]>> = colour_columns.map(|_| Vec::with_capacity(count));
    let mut push_colour = |row: &[f64]| {
        if let (Some(cols), Some(out)) = (colour_columns, colours.as_mut()) {
            let mut c = [0u8; 3];
            for a in 0..3 {
                let v = row[cols[a]] * colour_scale[a];
                c[a] = if v.is_finite() {
                    v.round().clamp(0.0, 255.0) as u8
                } else {
                    0
                };
            }
            out.push(c);
        }
    };
    let mut row = vec![0.0f64; vertex.properties.len()];
    match format {
        PlyFormat::Ascii => {
            let text = std::str::from_utf8(data).map_err(|e| PointsError::Byte {
                file: file.to_path_buf(),
                offset: at + e.valid_up_to(),
                what: "the ASCII body is not text".into(),
            })?;
            let mut lines = text
                .lines()
                .enumerate()
                .filter(|(_, l)| !l.trim().is_empty());
            for _ in 0..count {
                let Some((n, line)) = lines.next() else {
                    return Err(line_err(
                        line_no + text.lines().count() + 1,
                        format!("the file ends before its {count} vertices"),
                    ));
                };
                let here = line_no + n + 1;
                let mut tokens = line.split_whitespace();
                for (slot, (name, _)) in row.iter_mut().zip(&vertex.properties) {
                    let token = tokens
                        .next()
                        .ok_or_else(|| line_err(here, format!("no value for `{name}`")))?;
                    *slot = token
                        .parse()
                        .map_err(|_| line_err(here, format!("`{token}` is not a number")))?;
                }
                push_row(
                    &row,
                    ([x, y, z], origin),
                    normal_columns,
                    &mut points,
                    normals.as_mut(),
                )
                .map_err(|what| line_err(here, what))?;
                push_colour(&row);
            }
        }
        PlyFormat::BinaryLittle | PlyFormat::BinaryBig => {
            let little = format == PlyFormat::BinaryLittle;
            for v in 0..count {
                let mut offset = v * row_bytes;
                for (slot, (_, ty)) in row.iter_mut().zip(&vertex.properties) {
                    let size = ply_type_size(ty).unwrap_or(0);
                    *slot = read_scalar(&data[offset..offset + size], ty, little);
                    offset += size;
                }
                push_row(
                    &row,
                    ([x, y, z], origin),
                    normal_columns,
                    &mut points,
                    normals.as_mut(),
                )
                .map_err(|what| PointsError::Byte {
                    file: file.to_path_buf(),
                    offset: at + v * row_bytes,
                    what: format!("vertex {v}: {what}"),
                })?;
                push_colour(&row);
            }
        }
    }
    Ok((PointCloud { points, normals }, colours))
}

/// Appends one vertex row, its position (columns `xyz`) less `origin`; refuses non-finite
/// positions.
fn push_row(
    row: &[f64],
    (xyz, origin): ([usize; 3], DVec3),
    normal_columns: Option<[usize; 3]>,
    points: &mut Vec<Vec3>,
    normals: Option<&mut Vec<Vec3>>,
) -> Result<(), String> {
    let p = Vec3::new(
        (row[xyz[0]] - origin.x) as f32,
        (row[xyz[1]] - origin.y) as f32,
        (row[xyz[2]] - origin.z) as f32,
    );
    if !p.is_finite() {
        return Err(format!("position {p} is not finite"));
    }
    points.push(p);
    if let (Some(c), Some(normals)) = (normal_columns, normals) {
        let n = Vec3::new(row[c[0]] as f32, row[c[1]] as f32, row[c[2]] as f32);
        normals.push(if n.is_finite() {
            unit_or_zero(n)
        } else {
            Vec3::ZERO
        });
    }
    Ok(())
}

/// One binary scalar of type `ty` (its size checked by the caller) as f64.
fn read_scalar(b: &[u8], ty: &str, little: bool) -> f64 {
    macro_rules! num {
        ($t:ty, $n:expr) => {{
            let mut a = [0u8; $n];
            a.copy_from_slice(&b[..$n]);
            f64::from(if little {
                <$t>::from_le_bytes(a)
            } else {
                <$t>::from_be_bytes(a)
            })
        }};
    }
    match ty {
        "char" | "int8" => num!(i8, 1),
        "uchar" | "uint8" => num!(u8, 1),
        "short" | "int16" => num!(i16, 2),
        "ushort" | "uint16" => num!(u16, 2),
        "int" | "int32" => num!(i32, 4),
        "uint" | "uint32" => num!(u32, 4),
        "float" | "float32" => num!(f32, 4),
        _ => {
            let mut a = [0u8; 8];
            a.copy_from_slice(&b[..8]);
            if little {
                f64::from_le_bytes(a)
            } else {
                f64::from_be_bytes(a)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn file() -> PathBuf {
        PathBuf::from("cloud")
    }

    #[test]
    fn xyz_reads_positions_and_normals_and_names_the_bad_line() {
        let c = parse_xyz(b"# scan\n0 0 0\n1 2 3\n\n", &file()).unwrap();
        assert_eq!(c.points, vec![Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0)]);
        assert!(c.normals.is_none());
        let c = parse_xyz(b"0 0 0 0 0 2\n1,1,1,1,0,0\n", &file()).unwrap();
        assert_eq!(c.normals.unwrap(), vec![Vec3::Z, Vec3::X]);
        for (text, line, what) in [
            (&b"0 0 0\n1 2\n"[..], 2, "2 numbers"),
            (b"0 0 0\n1 2 x\n", 2, "`x` is not a number"),
            (b"0 0 0\n0 0 0 1 0 0\n", 2, "where earlier lines have 3"),
            (b"0 0 nan\n", 1, "not a finite number"),
        ] {
            let e = parse_xyz(text, &file()).unwrap_err().to_string();
            assert!(
                e.contains(&format!("cloud:{line}:")) && e.contains(what),
                "{e}"
            );
        }
    }

    fn ply_header(format: &str, count: usize, props: &str) -> Vec<u8> {
        format!("ply\nformat {format} 1.0\ncomment test\nelement vertex {count}\n{props}element face 0\nproperty list uchar int vertex_indices\nend_header\n").into_bytes()
    }

    #[test]
    fn ply_reads_ascii_and_binary_with_normals_in_any_order() {
        let props = "property float nx\nproperty float x\nproperty float y\nproperty float z\nproperty float ny\nproperty float nz\nproperty uchar intensity\n";
        let mut ascii = ply_header("ascii", 2, props);
        ascii.extend_from_slice(b"1 0 0 0 0 0 7\n0 1 2 3 1 0 7\n");
        let c = parse_ply(&ascii, &file()).unwrap();
        assert_eq!(c.points, vec![Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0)]);
        assert_eq!(c.normals.as_deref(), Some(&[Vec3::X, Vec3::Y][..]));

        for (format, little) in [("binary_little_endian", true), ("binary_big_endian", false)] {
            let mut bin = ply_header(format, 2, props);
            for row in [
                [1.0f32, 0.0, 0.0, 0.0, 0.0, 0.0],
                [0.0, 1.0, 2.0, 3.0, 1.0, 0.0],
            ] {
                for v in row {
                    bin.extend_from_slice(&if little {
                        v.to_le_bytes()
                    } else {
                        v.to_be_bytes()
                    });
                }
                bin.push(7);
            }
            let b = parse_ply(&bin, &file()).unwrap();
            assert_eq!(b, c, "{format}");
        }
    }

    #[test]
    fn positions_far_from_the_files_origin_keep_their_precision_read_about_an_origin() {
        // Points a millimetre apart at a million metres: `f32` steps by 0.0625 there, but
        // the differences from an origin near them are exact to its precision.
        let origin = DVec3::new(1.0e6, 2.0e6, -5.0e5);
        let offsets: Vec<f64> = (0..5).map(|k| 0.001 * f64::from(k)).collect();
        let close = |c: &PointCloud| {
            for (p, &d) in c.points.iter().zip(&offsets) {
                let want = Vec3::new(d as f32, (2.0 * d) as f32, (-d) as f32);
                assert!((*p - want).abs().max_element() < 1e-7, "{p} against {want}");
            }
        };
        let mut text = String::new();
        for &d in &offsets {
            text.push_str(&format!(
                "{:.6} {:.6} {:.6} 0 0 1\n",
                origin.x + d,
                origin.y + 2.0 * d,
                origin.z - d
            ));
        }
        let about = parse_xyz_about(text.as_bytes(), &file(), origin).unwrap();
        close(&about);
        assert_eq!(about.normals.as_deref().map(<[Vec3]>::len), Some(5));
        // Read as it is, the five collapse onto one or two `f32` values.
        let plain = parse_xyz(text.as_bytes(), &file()).unwrap();
        assert!(plain.points.windows(2).any(|w| w[0] == w[1]));

        let props = "property double x\nproperty double y\nproperty double z\n";
        let mut ascii = ply_header("ascii", offsets.len(), props);
        ascii.extend_from_slice(text.replace(" 0 0 1", "").as_bytes());
        close(&parse_ply_about(&ascii, &file(), origin).unwrap().0);
        let mut binary = ply_header("binary_little_endian", offsets.len(), props);
        for &d in &offsets {
            for v in [origin.x + d, origin.y + 2.0 * d, origin.z - d] {
                binary.extend_from_slice(&v.to_le_bytes());
            }
        }
        close(&parse_ply_about(&binary, &file(), origin).unwrap().0);
        // About a zero origin, the readers are the plain ones bit for bit.
        assert_eq!(
            parse_ply_about(&binary, &file(), DVec3::ZERO).unwrap().0,
            parse_ply(&binary, &file()).unwrap()
        );
    }

    #[test]
    fn ply_refuses_bad_headers_huge_counts_and_short_data_before_allocating() {
        let props = "property float x\nproperty float y\nproperty float z\n";
        let cases: Vec<(Vec<u8>, &str)> = vec![
            (b"plx\n".to_vec(), "not a PLY file"),
            (ply_header("ascii", 1_000_000_000, props), "more than the"),
            (
                ply_header("binary_little_endian", 1000, props),
                "1000 vertices declared",
            ),
            (
                ply_header("ascii", 1, "property float x\n"),
                "need x, y and z",
            ),
            (
                b"ply\nformat ascii 1.0\nelement vertex 1\n".to_vec(),
                "no `end_header`",
            ),
        ];
        for (bytes, what) in cases {
            let e = parse_ply(&bytes, &file()).unwrap_err().to_string();
            assert!(e.contains(what), "{e}");
        }
        let mut bad = ply_header("ascii", 1, props);
        bad.extend_from_slice(b"0 inf 0\n");
        let e = parse_ply(&bad, &file()).unwrap_err().to_string();
        assert!(e.contains("not finite"), "{e}");
    }
}
