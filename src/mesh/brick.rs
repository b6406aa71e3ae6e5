//! One brick: 8³ cells of the sampling grid, its 9³ corner samples and its marching-cubes
//! mesh.
//!
//! Why 8³: an edit the size of a tool (radius ~8 cells) touches 3–4 bricks per axis, so a
//! local re-mesh redoes little beyond the edit; a brick's samples (9³ f32 = 2.9 KB) stay in L1
//! while it is meshed; and storage near a surface wastes less than with 16³ bricks (a 16³
//! brick holds 4913 samples for a surface patch only ~4× the area of an 8³ brick's 729). The
//! cost would be sampling shared faces twice (9³/8³ = 1.42 samples per cell against 1.20 for
//! 16³); a full build avoids it by taking a brick's lower faces from the bricks below it
//! (`sample_brick_sharing`), and only a local refresh samples whole bricks.
//!
//! Vertices sit on grid edges and are identified by a global edge id, so a vertex on a face
//! shared by two bricks is computed identically (same samples, same position, same normal) by
//! both, and welding by id gives a watertight mesh with no duplicates.

use glam::Vec3;

use super::grid::SampleGrid;
use super::source::ScalarField;
use super::tables::{CASES, CORNER_OFFSETS, EDGE_AXIS, EDGE_CORNERS};

/// Cells per brick along each axis.
pub const BRICK_CELLS: u32 = 8;
/// Samples per brick along each axis (corners of its cells).
pub const BRICK_SAMPLES: usize = BRICK_CELLS as usize + 1;
/// Samples stored per brick.
pub const BRICK_SAMPLE_COUNT: usize = BRICK_SAMPLES * BRICK_SAMPLES * BRICK_SAMPLES;

/// Crossing parameters are kept this far from an edge's ends, so vertices on different edges
/// never coincide (which would make degenerate triangles and merge under position welding).
const T_MARGIN: f32 = 1e-4;

/// Global id of the grid edge that starts at sample `corner` and runs along `axis`.
#[inline]
#[must_use]
pub fn edge_id(corner: [u32; 3], axis: u8) -> u64 {
    (u64::from(corner[0]) | u64::from(corner[1]) << 20 | u64::from(corner[2]) << 40) << 2
        | u64::from(axis)
}

/// The start sample and axis of a global edge id.
#[inline]
#[must_use]
pub fn edge_from_id(id: u64) -> ([u32; 3], u8) {
    let c = id >> 2;
    const MASK: u64 = (1 << 20) - 1;
    (
        [
            (c & MASK) as u32,
            ((c >> 20) & MASK) as u32,
            ((c >> 40) & MASK) as u32,
        ],
        (id & 3) as u8,
    )
}

/// A brick's triangles, in world coordinates, ready to upload.
///
/// Vertices are local to the brick (vertices on shared faces appear in both bricks, with the
/// same position, normal and edge id). Triangles wind counter-clockwise seen from outside.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BrickMesh {
    pub positions: Vec<Vec3>,
    /// Unit outward normals, `−∇s / |∇s|` from the field's analytic gradient.
    pub normals: Vec<Vec3>,
    /// Global edge id of each vertex (see [`edge_id`]); the key for welding.
    pub edge_ids: Vec<u64>,
    /// Three vertex indices per triangle.
    pub indices: Vec<u32>,
}

impl BrickMesh {
    /// Number of triangles.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Heap bytes held (capacity, not length).
    #[must_use]
    pub fn heap_bytes(&self) -> usize {
        self.positions.capacity() * size_of::<Vec3>()
            + self.normals.capacity() * size_of::<Vec3>()
            + self.edge_ids.capacity() * size_of::<u64>()
            + self.indices.capacity() * size_of::<u32>()
    }

    fn clear(&mut self) {
        self.positions.clear();
        self.normals.clear();
        self.edge_ids.clear();
        self.indices.clear();
    }

    fn shrink(&mut self) {
        self.positions.shrink_to_fit();
        self.normals.shrink_to_fit();
        self.edge_ids.shrink_to_fit();
        self.indices.shrink_to_fit();
    }
}

/// Working memory for meshing bricks; keep one and reuse it.
#[derive(Clone, Debug)]
pub struct BrickScratch {
    /// Vertex index per (axis, local start sample), `u32::MAX` when not yet made.
    slots: Vec<u32>,
    /// The slots the last marched brick filled (reset before the next).
    made: Vec<u32>,
    pub(crate) samples: Vec<f32>,
    /// The samples not taken from a neighbour's face, densely, before they are spread.
    dense: Vec<f32>,
    pub(crate) field: Vec<f32>,
    pub(crate) mesh: BrickMesh,
}

impl Default for BrickScratch {
    fn default() -> Self {
        Self {
            slots: vec![u32::MAX; 3 * BRICK_SAMPLE_COUNT],
            made: Vec::new(),
            samples: vec![0.0; BRICK_SAMPLE_COUNT],
            dense: Vec::with_capacity(BRICK_SAMPLE_COUNT),
            field: Vec::new(),
            mesh: BrickMesh::default(),
        }
    }
}

/// First sample and cell counts of brick `coord` (bricks at the far edge may be partial).
#[must_use]
pub fn brick_extent(grid: &SampleGrid, coord: [u32; 3]) -> ([u32; 3], [u32; 3]) {
    let first = coord.map(|c| c * BRICK_CELLS);
    let mut cells = [0; 3];
    for axis in 0..3 {
        cells[axis] = grid.cells[axis]
            .saturating_sub(first[axis])
            .min(BRICK_CELLS);
    }
    (first, cells)
}

/// Samples brick `coord` into `scratch.samples` (layout x fastest, stride [`BRICK_SAMPLES`])
/// and reports whether the surface crosses it (some samples inside, some not).
pub fn sample_brick<F: ScalarField + ?Sized>(
    field: &F,
    grid: &SampleGrid,
    coord: [u32; 3],
    scratch: &mut BrickScratch,
) -> bool {
    sample_brick_sharing(field, grid, coord, [None; 3], scratch)
}

/// The samples on one face of a brick: 9 × 9, the lower of the two other axes fastest.
pub(crate) type Face = [f32; BRICK_SAMPLES * BRICK_SAMPLES];

/// Index in a brick's 9³ samples of entry (`a`, `b`) of its face at `level` across `axis`.
#[inline]
fn face_index(axis: usize, level: usize, a: usize, b: usize) -> usize {
    const S: usize = BRICK_SAMPLES;
    match axis {
        0 => level + S * (a + S * b),
        1 => a + S * (level + S * b),
        _ => a + S * (b + S * level),
    }
}

/// [`sample_brick`], taking the samples on the brick's lower face across axis `a` from
/// `near[a]` where given: the upper face of the brick below along that axis, which holds the
/// same samples (a sample's bits depend only on its global index), so only the rest of the
/// brick is sampled. A brick with all three neighbours below samples 8³ points, not 9³.
pub(crate) fn sample_brick_sharing<F: ScalarField + ?Sized>(
    field: &F,
    grid: &SampleGrid,
    coord: [u32; 3],
    near: [Option<&Face>; 3],
    scratch: &mut BrickScratch,
) -> bool {
    const S: usize = BRICK_SAMPLES;
    let (first, cells) = brick_extent(grid, coord);
    let counts = cells.map(|c| c as usize + 1);
    let lo = near.map(|f| usize::from(f.is_some()));
    let sub: [usize; 3] = std::array::from_fn(|a| counts[a] - lo[a]);
    let start: [u32; 3] = std::array::from_fn(|a| first[a] + lo[a] as u32);
    let BrickScratch {
        samples,
        dense,
        field: field_scratch,
        ..
    } = scratch;
    if lo == [0; 3] && counts == [S; 3] {
        field.sample_block(grid, start, sub, samples, field_scratch);
    } else {
        let n = sub[0] * sub[1] * sub[2];
        dense.clear();
        dense.resize(n, 0.0);
        field.sample_block(grid, start, sub, dense, field_scratch);
        if counts != [S; 3] {
            // Entries beyond a partial brick's extent: zero, whatever was sampled before.
            samples.fill(0.0);
        }
        for k in 0..sub[2] {
            for j in 0..sub[1] {
                let from = sub[0] * (j + sub[1] * k);
                let to = lo[0] + S * (lo[1] + j + S * (lo[2] + k));
                samples[to..to + sub[0]].copy_from_slice(&dense[from..from + sub[0]]);
            }
        }
        for (axis, face) in near.iter().enumerate() {
            let Some(face) = face else { continue };
            let (a_axis, b_axis) = match axis {
                0 => (1, 2),
                1 => (0, 2),
                _ => (0, 1),
            };
            for b in 0..counts[b_axis] {
                for a in 0..counts[a_axis] {
                    samples[face_index(axis, 0, a, b)] = face[a + S * b];
                }
            }
        }
    }
    let iso = field.iso();
    let mut inside = 0usize;
    for k in 0..counts[2] {
        for j in 0..counts[1] {
            let row = S * (j + S * k);
            for &v in &samples[row..row + counts[0]] {
                inside += usize::from(v > iso);
            }
        }
    }
    inside != 0 && inside != counts[0] * counts[1] * counts[2]
}

/// Copies the upper face across `axis` of the brick sampled in `scratch` into `face`.
pub(crate) fn upper_face(scratch: &BrickScratch, axis: usize, face: &mut Face) {
    const S: usize = BRICK_SAMPLES;
    for b in 0..S {
        for a in 0..S {
            face[a + S * b] = scratch.samples[face_index(axis, S - 1, a, b)];
        }
    }
}

/// Spreads a column's four inside bits (bit `y + 2z` for the samples at `(y, z)` of the
/// cell's near or far x) onto the case bits of the cell's corners at x = 0 (bits 0, 2, 4, 6);
/// the corners at x = 1 are the same shifted by one.
const SPREAD: [u8; 16] = {
    let mut t = [0u8; 16];
    let mut q = 0;
    while q < 16 {
        t[q] = ((q & 1) | (q & 2) << 1 | (q & 4) << 2 | (q & 8) << 3) as u8;
        q += 1;
    }
    t
};

/// Per cube edge: its vertex slot relative to the cell's first sample (`axis · 9³` plus the
/// edge's start sample in the brick's layout).
const EDGE_SLOT: [usize; 12] = {
    let mut t = [0usize; 12];
    let mut e = 0;
    while e < 12 {
        let o = CORNER_OFFSETS[EDGE_CORNERS[e][0] as usize];
        t[e] = EDGE_AXIS[e] as usize * BRICK_SAMPLE_COUNT
            + o[0] as usize
            + BRICK_SAMPLES * (o[1] as usize + BRICK_SAMPLES * o[2] as usize);
        e += 1;
    }
    t
};

/// Marching cubes over the brick sampled by [`sample_brick`], into `scratch.mesh`.
///
/// Each sample's inside bit is taken once; a cell's case comes from the four bits of the
/// column of samples at each of its two x positions, and cells all inside or all outside
/// are passed over before any table is read.
pub fn march_brick<F: ScalarField + ?Sized>(
    field: &F,
    grid: &SampleGrid,
    coord: [u32; 3],
    scratch: &mut BrickScratch,
) {
    const S: usize = BRICK_SAMPLES;
    const STRIDE: [usize; 3] = [1, S, S * S];
    let (first, cells) = brick_extent(grid, coord);
    let iso = field.iso();
    let BrickScratch {
        slots,
        made,
        samples,
        mesh,
        ..
    } = scratch;
    // Only the slots the last brick filled are reset.
    for &slot in made.iter() {
        slots[slot as usize] = u32::MAX;
    }
    made.clear();
    mesh.clear();
    let mut inside = [0u8; BRICK_SAMPLE_COUNT];
    for (b, &v) in inside.iter_mut().zip(samples.iter()) {
        *b = u8::from(v > iso);
    }
    let [cx, cy, cz] = cells.map(|c| c as usize);
    let mut column = [0u8; S];
    for z in 0..cz {
        for y in 0..cy {
            let row = S * (y + S * z);
            let mut any = 0u8;
            let mut all = 1u8;
            for (x, q) in column[..=cx].iter_mut().enumerate() {
                let at = row + x;
                *q = inside[at]
                    | inside[at + S] << 1
                    | inside[at + S * S] << 2
                    | inside[at + S + S * S] << 3;
                any |= *q;
                all &= u8::from(*q == 15);
            }
            if any == 0 || all == 1 {
                continue;
            }
            for x in 0..cx {
                let case =
                    usize::from(SPREAD[column[x] as usize] | SPREAD[column[x + 1] as usize] << 1);
                if case == 0 || case == 255 {
                    continue;
                }
                let base = row + x;
                let tris = &CASES[case];
                for tri in &tris.edges[..tris.count as usize] {
                    for &e in tri {
                        let at = base + EDGE_SLOT[e as usize];
                        let slot = &mut slots[at];
                        if *slot == u32::MAX {
                            *slot = mesh.positions.len() as u32;
                            made.push(at as u32);
                            let axis = EDGE_AXIS[e as usize];
                            let o = CORNER_OFFSETS[EDGE_CORNERS[e as usize][0] as usize];
                            let start =
                                base + o[0] as usize + S * (o[1] as usize + S * o[2] as usize);
                            let corner = [
                                first[0] + (x as u32 + o[0]),
                                first[1] + (y as u32 + o[1]),
                                first[2] + (z as u32 + o[2]),
                            ];
                            let v0 = samples[start];
                            let v1 = samples[start + STRIDE[axis as usize]];
                            push_vertex(field, grid, corner, axis, v0, v1, mesh);
                        }
                        mesh.indices.push(*slot);
                    }
                }
            }
        }
    }
}

/// Adds the vertex where the surface crosses the edge from sample `corner` along `axis`.
fn push_vertex<F: ScalarField + ?Sized>(
    field: &F,
    grid: &SampleGrid,
    corner: [u32; 3],
    axis: u8,
    v0: f32,
    v1: f32,
    mesh: &mut BrickMesh,
) {
    let mut end = corner;
    end[axis as usize] += 1;
    let (p0, p1) = (grid.point(corner), grid.point(end));
    // v0 != v1: exactly one of them is above the iso-level.
    let t = ((field.iso() - v0) / (v1 - v0)).clamp(T_MARGIN, 1.0 - T_MARGIN);
    let p = p0 + (p1 - p0) * t;
    let gradient = field.gradient(p);
    let length = gradient.length();
    let normal = if length > 1e-20 && length.is_finite() {
        -gradient / length
    } else {
        // Flat field: fall back to the edge direction, from the inside end to the outside.
        let mut n = Vec3::ZERO;
        n[axis as usize] = if v0 > v1 { 1.0 } else { -1.0 };
        n
    };
    mesh.positions.push(p);
    mesh.normals.push(normal);
    mesh.edge_ids.push(edge_id(corner, axis));
}

/// Samples and meshes one brick; returns its samples and mesh, or `None` when the surface
/// does not cross it.
pub(crate) fn build_brick<F: ScalarField + ?Sized>(
    field: &F,
    grid: &SampleGrid,
    coord: [u32; 3],
    scratch: &mut BrickScratch,
) -> Option<(Box<[f32]>, BrickMesh)> {
    if !sample_brick(field, grid, coord, scratch) {
        return None;
    }
    Some(mesh_sampled_brick(field, grid, coord, scratch))
}

/// Meshes the brick whose samples are in `scratch` and returns copies of its samples and
/// mesh, sized to fit.
pub(crate) fn mesh_sampled_brick<F: ScalarField + ?Sized>(
    field: &F,
    grid: &SampleGrid,
    coord: [u32; 3],
    scratch: &mut BrickScratch,
) -> (Box<[f32]>, BrickMesh) {
    march_brick(field, grid, coord, scratch);
    let mut mesh = scratch.mesh.clone();
    mesh.shrink();
    (scratch.samples.clone().into_boxed_slice(), mesh)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::source::FnField;

    #[test]
    fn edge_ids_round_trip() {
        for (c, a) in [
            ([0, 0, 0], 0),
            ([5, 1_000_000, 7], 2),
            ([1 << 19, 3, 1 << 19], 1),
        ] {
            assert_eq!(edge_from_id(edge_id(c, a)), (c, a));
        }
        assert_ne!(edge_id([1, 0, 0], 0), edge_id([0, 1, 0], 0));
        assert_ne!(edge_id([1, 0, 0], 0), edge_id([1, 0, 0], 1));
    }

    #[test]
    fn plane_through_a_brick_gives_a_flat_sheet_with_outward_normals() {
        // Solid below z = 3.3 (value = 3.3 - z, inside where > 0).
        let field = FnField {
            value: |p: Vec3| 3.3 - p.z,
            gradient: |_| Vec3::NEG_Z,
            iso: 0.0,
            lipschitz: Some(1.0),
        };
        let grid = SampleGrid::new(Vec3::ZERO, 1.0, [8, 8, 8]).unwrap();
        let mut scratch = BrickScratch::default();
        let (_, mesh) = build_brick(&field, &grid, [0, 0, 0], &mut scratch).unwrap();
        assert_eq!(mesh.positions.len(), 81); // one vertex per z edge crossing
        assert_eq!(mesh.triangle_count(), 128);
        for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
            assert!((p.z - 3.3).abs() < 1e-5);
            assert_eq!(*n, Vec3::Z);
        }
        for t in mesh.indices.chunks(3) {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
            assert!((b - a).cross(c - a).z > 0.0, "triangle faces inwards");
        }
    }

    #[test]
    fn partial_bricks_at_the_far_edge_are_meshed() {
        let field = FnField {
            value: |p: Vec3| 1.0 - (p - Vec3::splat(6.5)).length() / 3.0,
            gradient: |p: Vec3| -(p - Vec3::splat(6.5)).normalize_or_zero() / 3.0,
            iso: 0.0,
            lipschitz: None,
        };
        let grid = SampleGrid::new(Vec3::ZERO, 1.0, [10, 10, 10]).unwrap();
        assert_eq!(brick_extent(&grid, [1, 1, 1]), ([8; 3], [2; 3]));
        let mut scratch = BrickScratch::default();
        let (_, mesh) = build_brick(&field, &grid, [1, 0, 0], &mut scratch).unwrap();
        assert!(mesh.triangle_count() > 0);
        assert!(mesh.positions.iter().all(|p| p.x >= 8.0 && p.x <= 10.0));
        assert!(build_brick(&field, &grid, [0, 0, 0], &mut scratch).is_some());
    }
}
