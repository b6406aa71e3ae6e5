//! Closed triangle meshes with known surfaces, and writers for the import's mesh formats,
//! shared by the import tests and benchmarks (`#[path]`-included: this folder is not a test
//! target of its own).

use std::collections::HashMap;
use std::path::Path;

use glam::Vec3;

/// Vertices and triangles (indices into the vertices).
pub type Mesh = (Vec<Vec3>, Vec<[u32; 3]>);

/// An icosahedron subdivided `levels` times, its vertices pushed onto the unit sphere, wound
/// outward.
pub fn icosphere(levels: u32) -> Mesh {
    let g = (1.0 + 5f32.sqrt()) / 2.0;
    let mut v: Vec<Vec3> = [
        (-1.0, g, 0.0),
        (1.0, g, 0.0),
        (-1.0, -g, 0.0),
        (1.0, -g, 0.0),
        (0.0, -1.0, g),
        (0.0, 1.0, g),
        (0.0, -1.0, -g),
        (0.0, 1.0, -g),
        (g, 0.0, -1.0),
        (g, 0.0, 1.0),
        (-g, 0.0, -1.0),
        (-g, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
    .collect();
    let mut t: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(4 * t.len());
        for tri in &t {
            let mut m = [0u32; 3];
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                m[k] = *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    v.push((v[a as usize] + v[b as usize]).normalize());
                    (v.len() - 1) as u32
                });
            }
            next.extend([
                [tri[0], m[0], m[2]],
                [tri[1], m[1], m[0]],
                [tri[2], m[2], m[1]],
                m,
            ]);
        }
        t = next;
    }
    (v, t)
}

/// A torus around the y axis (ring radius `ring`, tube `tube`), `around` × `across` quads,
/// wound outward.
pub fn torus(ring: f32, tube: f32, around: u32, across: u32) -> Mesh {
    let tau = std::f32::consts::TAU;
    let mut v = Vec::new();
    for i in 0..around {
        let a = tau * i as f32 / around as f32;
        for j in 0..across {
            let b = tau * j as f32 / across as f32;
            let r = ring + tube * b.cos();
            v.push(Vec3::new(r * a.cos(), tube * b.sin(), r * a.sin()));
        }
    }
    let at = |i: u32, j: u32| (i % around) * across + (j % across);
    let mut t = Vec::new();
    for i in 0..around {
        for j in 0..across {
            let (p, q, r, s) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            t.push([p, r, q]);
            t.push([p, s, r]);
        }
    }
    (v, t)
}

/// Writes the mesh as OBJ text.
pub fn write_obj(path: &Path, (v, t): &Mesh) {
    let mut text = String::new();
    for p in v {
        text.push_str(&format!("v {} {} {}\n", p.x, p.y, p.z));
    }
    for tri in t {
        text.push_str(&format!("f {} {} {}\n", tri[0] + 1, tri[1] + 1, tri[2] + 1));
    }
    std::fs::write(path, text).unwrap();
}

/// The mesh as binary STL bytes (zero normals: readers take the winding).
pub fn binary_stl((v, t): &Mesh) -> Vec<u8> {
    let mut bytes = vec![0u8; 80];
    bytes.extend_from_slice(&(t.len() as u32).to_le_bytes());
    for tri in t {
        bytes.extend_from_slice(&[0u8; 12]);
        for &i in tri {
            for c in v[i as usize].to_array() {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
        }
        bytes.extend_from_slice(&[0u8; 2]);
    }
    bytes
}

/// Writes the mesh as binary STL.
pub fn write_binary_stl(path: &Path, mesh: &Mesh) {
    std::fs::write(path, binary_stl(mesh)).unwrap();
}

/// Writes the mesh as ASCII STL.
pub fn write_ascii_stl(path: &Path, (v, t): &Mesh) {
    let mut text = String::from("solid torus\n");
    for tri in t {
        text.push_str("facet normal 0 0 0\nouter loop\n");
        for &i in tri {
            let p = v[i as usize];
            text.push_str(&format!("vertex {} {} {}\n", p.x, p.y, p.z));
        }
        text.push_str("endloop\nendfacet\n");
    }
    text.push_str("endsolid torus\n");
    std::fs::write(path, text).unwrap();
}
