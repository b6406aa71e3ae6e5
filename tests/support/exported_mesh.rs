//! The clay as it is exported (meshed, welded, written as OBJ and read back) and probed along
//! vertical lines: the measuring stick of the stroke and tool-size tests. Shared by `#[path]`
//! (this folder is not a test target of its own).

use std::path::Path;

use dynaclay::field::MultiPatchField;
use dynaclay::mesh::{BrickOctree, MeshFormat, SampleGrid, write_mesh};
use glam::{Vec2, Vec3, Vec3Swizzles};

/// An exported mesh read back from its file.
pub struct Exported {
    pub vertices: Vec<Vec3>,
    pub triangles: Vec<[usize; 3]>,
}

/// Meshes `field` at four cells per finest knot span, welds it, writes it as OBJ to
/// `dir/name` and reads the file back.
pub fn export(field: &MultiPatchField, dir: &Path, name: &str) -> Exported {
    let grid = SampleGrid::for_field(field, 4).unwrap();
    let mesh = BrickOctree::build(grid, field).weld();
    let path = dir.join(name);
    write_mesh(&path, &mesh, MeshFormat::Obj).unwrap();
    read_obj(&path)
}

/// Reads an OBJ file the exporter wrote (vertices and triangles).
pub fn read_obj(path: &Path) -> Exported {
    let name = path.display();
    let text = std::fs::read_to_string(path).unwrap();
    let numbers = |l: &str| -> Vec<f32> {
        l.split_whitespace()
            .map(|x| x.split('/').next().unwrap().parse().unwrap())
            .collect()
    };
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    for line in text.lines() {
        if let Some(v) = line.strip_prefix("v ") {
            let v = numbers(v);
            vertices.push(Vec3::new(v[0], v[1], v[2]));
        } else if let Some(f) = line.strip_prefix("f ") {
            let f = numbers(f);
            triangles.push([f[0] as usize - 1, f[1] as usize - 1, f[2] as usize - 1]);
        }
    }
    assert!(!triangles.is_empty(), "{name}: an empty mesh");
    Exported {
        vertices,
        triangles,
    }
}

impl Exported {
    /// Where the line `from + t · dir` crosses the triangles (Möller–Trumbore), as `t`s.
    pub fn crossings(&self, from: Vec3, dir: Vec3) -> Vec<f32> {
        let mut out = Vec::new();
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| self.vertices[i]);
            let (e1, e2) = (b - a, c - a);
            let p = dir.cross(e2);
            let det = e1.dot(p);
            if det.abs() < 1e-12 {
                continue;
            }
            let s = from - a;
            let u = s.dot(p) / det;
            let q = s.cross(e1);
            let v = dir.dot(q) / det;
            if u < 0.0 || v < 0.0 || u + v > 1.0 {
                continue;
            }
            out.push(e2.dot(q) / det);
        }
        out
    }

    /// The surface's height along the line from `from` to `to` (xz), at `n + 1` points.
    pub fn profile(&self, from: Vec2, to: Vec2, n: usize) -> Vec<(Vec2, f32)> {
        // Only the triangles whose shadow's box meets the line's box can be hit.
        let (lo, hi) = (from.min(to) - 1e-4, from.max(to) + 1e-4);
        let near: Vec<[usize; 3]> = self
            .triangles
            .iter()
            .filter(|t| {
                let xz = t.map(|i| self.vertices[i].xz());
                let (a, b) = (xz[0].min(xz[1]).min(xz[2]), xz[0].max(xz[1]).max(xz[2]));
                a.cmple(hi).all() && b.cmpge(lo).all()
            })
            .copied()
            .collect();
        (0..=n)
            .map(|i| {
                let p = from.lerp(to, i as f32 / n as f32);
                let top = top_among(&self.vertices, &near, p).expect("the line meets the clay");
                (p, top)
            })
            .collect()
    }
}

/// The highest point of `triangles` over `p` (xz).
fn top_among(vertices: &[Vec3], triangles: &[[usize; 3]], p: Vec2) -> Option<f32> {
    let mut top: Option<f32> = None;
    for t in triangles {
        let [a, b, c] = t.map(|i| vertices[i]);
        let (a2, b2, c2) = (a.xz(), b.xz(), c.xz());
        let area = (b2 - a2).perp_dot(c2 - a2);
        if area.abs() < 1e-12 {
            continue;
        }
        // Barycentric coordinates of p in the triangle's shadow on the xz plane.
        let u = (b2 - p).perp_dot(c2 - p) / area;
        let v = (c2 - p).perp_dot(a2 - p) / area;
        let w = 1.0 - u - v;
        if u < -1e-6 || v < -1e-6 || w < -1e-6 {
            continue;
        }
        let y = u * a.y + v * b.y + w * c.y;
        top = Some(top.map_or(y, |t| t.max(y)));
    }
    top
}
