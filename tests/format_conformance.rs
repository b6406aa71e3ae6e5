//! The import readers (`fit::points`, `fit::mesh`) against well-kept reference readers:
//! `ply-rs-bw` for PLY, `tobj` for OBJ and `stl_io` for STL.
//!
//! dynaclay keeps its own readers because they name the line or byte of a fault and bound
//! every declared count by the file's length before allocating (see the user guide's `docs/src/import.md`);
//! these tests hold them to the reference crates on the same files, in every encoding the
//! import accepts: PLY ASCII, binary little- and big-endian with float and double
//! coordinates and extra properties; OBJ with `v/vt/vn` references, negative indices and
//! polygons; binary and ASCII STL.

use std::io::Cursor;
use std::path::Path;

use dynaclay::fit::mesh::{parse_obj, parse_stl};
use dynaclay::fit::points::parse_ply;
use glam::Vec3;
use ply_rs_bw::ply::{
    Addable, DefaultElement, ElementDef, Encoding, Ply, Property, PropertyDef, PropertyType,
    ScalarType,
};

/// A small deterministic generator (xorshift), so the files are the same on every run.
struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }

    fn point(&mut self, scale: f32) -> Vec3 {
        Vec3::new(self.unit() - 0.5, self.unit() - 0.5, self.unit() - 0.5) * scale
    }

    fn below(&mut self, n: usize) -> usize {
        ((self.unit() * n as f32) as usize).min(n - 1)
    }
}

fn file() -> &'static Path {
    Path::new("conformance")
}

/// A cloud with unit normals and a colour per point, as a reference-written PLY.
fn ply_cloud(
    encoding: Encoding,
    coords: ScalarType,
    count: usize,
) -> (Vec<u8>, Vec<Vec3>, Vec<Vec3>) {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15 ^ count as u64);
    let mut ply = Ply::<DefaultElement>::new();
    ply.header.encoding = encoding;
    let mut vertex = ElementDef::new("vertex".to_string());
    // Colour first and normals before positions, so the readers must go by name.
    vertex.properties.add(PropertyDef::new(
        "red".into(),
        PropertyType::Scalar(ScalarType::UChar),
    ));
    for name in ["nx", "ny", "nz", "x", "y", "z"] {
        let ty = if name.starts_with('n') {
            ScalarType::Float
        } else {
            coords.clone()
        };
        vertex
            .properties
            .add(PropertyDef::new(name.into(), PropertyType::Scalar(ty)));
    }
    vertex.properties.add(PropertyDef::new(
        "confidence".into(),
        PropertyType::Scalar(ScalarType::Short),
    ));
    ply.header.elements.add(vertex);
    let (mut points, mut normals, mut rows) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..count {
        let p = rng.point(40.0);
        let n = rng.point(2.0).try_normalize().unwrap_or(Vec3::Z);
        let mut row = DefaultElement::new();
        row.insert("red".into(), Property::UChar((i % 256) as u8));
        for (name, v) in ["nx", "ny", "nz"].into_iter().zip(n.to_array()) {
            row.insert(name.into(), Property::Float(v));
        }
        for (name, v) in ["x", "y", "z"].into_iter().zip(p.to_array()) {
            let value = match coords {
                ScalarType::Double => Property::Double(f64::from(v)),
                _ => Property::Float(v),
            };
            row.insert(name.into(), value);
        }
        row.insert("confidence".into(), Property::Short(-(i as i16)));
        rows.push(row);
        points.push(p);
        normals.push(n);
    }
    ply.payload.insert("vertex".into(), rows);
    let mut bytes = Vec::new();
    ply_rs_bw::writer::Writer::new()
        .write_ply(&mut bytes, &mut ply)
        .expect("the reference writer writes the cloud");
    (bytes, points, normals)
}

/// The reference reader's positions and normals.
fn reference_ply(bytes: &[u8]) -> (Vec<Vec3>, Vec<Vec3>) {
    let ply = ply_rs_bw::parser::Parser::<DefaultElement>::new()
        .read_ply(&mut Cursor::new(bytes))
        .expect("the reference reader reads the cloud");
    let scalar = |row: &DefaultElement, name: &str| match row.get(name) {
        Some(Property::Float(v)) => *v,
        Some(Property::Double(v)) => *v as f32,
        other => panic!("property {name}: {other:?}"),
    };
    let rows = &ply.payload["vertex"];
    let vec = |row: &DefaultElement, names: [&str; 3]| {
        Vec3::new(
            scalar(row, names[0]),
            scalar(row, names[1]),
            scalar(row, names[2]),
        )
    };
    (
        rows.iter().map(|r| vec(r, ["x", "y", "z"])).collect(),
        rows.iter().map(|r| vec(r, ["nx", "ny", "nz"])).collect(),
    )
}

#[test]
fn ply_clouds_read_as_the_reference_reads_them_in_every_encoding() {
    for encoding in [
        Encoding::Ascii,
        Encoding::BinaryLittleEndian,
        Encoding::BinaryBigEndian,
    ] {
        for coords in [ScalarType::Float, ScalarType::Double] {
            let label = format!("{encoding:?} with {coords:?} coordinates");
            let (bytes, points, normals) = ply_cloud(encoding, coords, 777);
            let (ref_points, ref_normals) = reference_ply(&bytes);
            let ours = parse_ply(&bytes, file()).unwrap_or_else(|e| panic!("{label}: {e}"));
            assert_eq!(ours.points.len(), 777, "{label}");
            assert_eq!(ref_points.len(), 777, "{label}");
            let ours_normals = ours
                .normals
                .as_ref()
                .unwrap_or_else(|| panic!("{label}: normals"));
            for i in 0..777 {
                // Binary files round-trip exactly; ASCII within the text's printed precision.
                let tolerance = if encoding == Encoding::Ascii {
                    1e-5
                } else {
                    0.0
                };
                assert!(
                    (ours.points[i] - ref_points[i]).abs().max_element() <= tolerance * 40.0,
                    "{label}: point {i}: {} against the reference's {}",
                    ours.points[i],
                    ref_points[i]
                );
                assert!((ref_points[i] - points[i]).abs().max_element() <= tolerance * 40.0);
                // The import keeps unit normals; the reference reads what the file holds.
                assert!(
                    (ours_normals[i] - ref_normals[i].normalize()).length() <= 1e-5,
                    "{label}: normal {i}: {} against {}",
                    ours_normals[i],
                    ref_normals[i]
                );
                assert!((ref_normals[i] - normals[i]).length() <= 1e-5);
            }
        }
    }
}

/// A mesh of triangles and quads over random vertices, as OBJ text with the reference forms:
/// plain, `v/vt`, `v//vn`, `v/vt/vn` and negative (relative) indices.
fn obj_mesh() -> (String, usize) {
    let mut rng = Rng(0x2545_f491_4f6c_dd1d);
    let mut text = String::from("# conformance mesh\nmtllib none.mtl\n");
    let vertex_count = 300;
    for _ in 0..vertex_count {
        let p = rng.point(10.0);
        text += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    text += "vt 0.5 0.5\nvn 0 0 1\n";
    let mut faces = 0;
    for f in 0..400 {
        let corners = if f % 3 == 0 { 4 } else { 3 };
        let mut line = String::from("f");
        for c in 0..corners {
            let v = rng.below(vertex_count);
            let reference = match (f + c) % 5 {
                0 => format!(" {}", v + 1),
                1 => format!(" {}/1", v + 1),
                2 => format!(" {}//1", v + 1),
                3 => format!(" {}/1/1", v + 1),
                _ => format!(" {}", v as i64 - vertex_count as i64),
            };
            line += &reference;
        }
        text += &line;
        text += "\n";
        faces += corners - 2;
    }
    (text, faces)
}

#[test]
fn obj_meshes_read_as_the_reference_reads_them() {
    let (text, triangles) = obj_mesh();
    let (vertices, faces) = parse_obj(text.as_bytes(), file()).expect("our reader reads it");
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ..tobj::LoadOptions::default()
    };
    let (models, _) = tobj::load_obj_buf(&mut Cursor::new(text.as_bytes()), &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .expect("the reference reads it");
    assert_eq!(models.len(), 1);
    let mesh = &models[0].mesh;
    let position = |i: u32| {
        let i = i as usize * 3;
        Vec3::new(
            mesh.positions[i],
            mesh.positions[i + 1],
            mesh.positions[i + 2],
        )
    };
    assert_eq!(faces.len(), triangles);
    assert_eq!(mesh.indices.len(), 3 * triangles);
    // Both fan each polygon from its first corner, so the triangles agree in order.
    for (t, face) in faces.iter().enumerate() {
        for c in 0..3 {
            let ours = vertices[face[c] as usize];
            let theirs = position(mesh.indices[3 * t + c]);
            assert_eq!(ours, theirs, "triangle {t}, corner {c}");
        }
    }
}

fn stl_triangles() -> Vec<stl_io::Triangle> {
    let mut rng = Rng(0x0123_4567_89ab_cdef);
    (0..500)
        .map(|_| {
            let corners = [rng.point(20.0), rng.point(20.0), rng.point(20.0)];
            let normal = (corners[1] - corners[0])
                .cross(corners[2] - corners[0])
                .try_normalize()
                .unwrap_or(Vec3::Z);
            stl_io::Triangle {
                normal: stl_io::Vector::new(normal.to_array()),
                vertices: corners.map(|c| stl_io::Vector::new(c.to_array())),
            }
        })
        .collect()
}

fn ascii_stl(triangles: &[stl_io::Triangle]) -> String {
    let mut text = String::from("solid conformance\n");
    for t in triangles {
        let n = t.normal.0;
        text += &format!(
            "  facet normal {:e} {:e} {:e}\n    outer loop\n",
            n[0], n[1], n[2]
        );
        for v in &t.vertices {
            text += &format!("      vertex {:e} {:e} {:e}\n", v[0], v[1], v[2]);
        }
        text += "    endloop\n  endfacet\n";
    }
    text + "endsolid conformance\n"
}

#[test]
fn stl_meshes_read_as_the_reference_reads_them_binary_and_ascii() {
    let triangles = stl_triangles();
    let mut binary = Vec::new();
    stl_io::write_stl(&mut binary, triangles.iter()).expect("the reference writes binary STL");
    for (label, bytes) in [
        ("binary", binary),
        ("ASCII", ascii_stl(&triangles).into_bytes()),
    ] {
        let (vertices, faces) =
            parse_stl(&bytes, file()).unwrap_or_else(|e| panic!("{label}: {e}"));
        let reference = stl_io::read_stl(&mut Cursor::new(&bytes))
            .unwrap_or_else(|e| panic!("{label}: the reference: {e}"));
        assert_eq!(faces.len(), triangles.len(), "{label}");
        assert_eq!(reference.faces.len(), triangles.len(), "{label}");
        for (t, (face, theirs)) in faces.iter().zip(&reference.faces).enumerate() {
            for c in 0..3 {
                let ours = vertices[face[c] as usize];
                let theirs = Vec3::from_array(reference.vertices[theirs.vertices[c]].0);
                assert_eq!(ours, theirs, "{label}: triangle {t}, corner {c}");
            }
        }
    }
}

#[test]
fn a_truncated_binary_file_is_refused_by_ours_with_its_place() {
    // The reference reader refuses it too, but names no place; ours names the line and why.
    let (mut bytes, _, _) = ply_cloud(Encoding::BinaryLittleEndian, ScalarType::Float, 50);
    bytes.truncate(bytes.len() - 7);
    assert!(
        ply_rs_bw::parser::Parser::<DefaultElement>::new()
            .read_ply(&mut Cursor::new(&bytes))
            .is_err()
    );
    let ours = parse_ply(&bytes, file()).expect_err("a truncated file is refused");
    let message = ours.to_string();
    // The header's last line (the count is checked against the data before allocating).
    assert!(message.starts_with("conformance:"), "{message}");
    assert!(
        message.contains("50 vertices declared, but the file ends after"),
        "{message}"
    );
}
