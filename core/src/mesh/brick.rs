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
use super::tables::{CASES, CORNER_OFFSETS, EDGE_AXIS, EDGE_CORNERS, MAX_CASE_TRIANGLES};

/// Cells per brick along each axis.
pub const BRICK_CELLS: u32 = 8;
/// Samples per brick along each axis (corners of its cells).
pub const BRICK_SAMPLES: usize = BRICK_CELLS as usize + 1;
/// Samples stored per brick.
pub const BRICK_SAMPLE_COUNT: usize = BRICK_SAMPLES * BRICK_SAMPLES * BRICK_SAMPLES;

/// Crossing parameters are kept this far from an edge's ends, so vertices on different edges
/// never coincide (which would make degenerate triangles and merge under position welding).
const T_MARGIN: f32 = 1e-4;

/// The axis an id from [`shared_vertex_id`] carries: no grid edge runs along it.
pub const SHARED_VERTEX_AXIS: u8 = 3;

/// The id of vertex `number` of a mesh cut into bricks ([`super::AdaptiveBricks`]): every
/// brick that holds a copy of the vertex gives it this id, and a weld
/// ([`super::weld_pieces`]) merges the copies by it. It reads back through [`edge_from_id`]
/// with axis [`SHARED_VERTEX_AXIS`].
#[inline]
#[must_use]
pub fn shared_vertex_id(number: u32) -> u64 {
    u64::from(number) << 2 | u64::from(SHARED_VERTEX_AXIS)
}

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

    /// Asks the processor to start bringing this mesh's buffers into its cache, ahead of
    /// their use (only a hint; nothing at all on targets without a prefetch instruction).
    /// A weld or a rebuild walks thousands of bricks whose meshes are a few kilobytes each,
    /// every buffer its own allocation: too short for the hardware to see a stream, so
    /// without the hint each brick's first touches of each buffer wait on memory.
    #[inline]
    pub(crate) fn prefetch(&self) {
        prefetch_slice(&self.positions);
        prefetch_slice(&self.normals);
        prefetch_slice(&self.edge_ids);
        prefetch_slice(&self.indices);
    }

    /// Gives back room beyond twice what each buffer holds (plus a little), so a brick
    /// whose mesh shrank does not keep its largest mesh's memory.
    pub(crate) fn trim(&mut self) {
        fn trim<T>(v: &mut Vec<T>) {
            if v.capacity() > 2 * v.len() + 16 {
                v.shrink_to(v.len());
            }
        }
        trim(&mut self.positions);
        trim(&mut self.normals);
        trim(&mut self.edge_ids);
        trim(&mut self.indices);
    }

    /// Makes this mesh a copy of `other` in its own buffers: no allocation when they are
    /// large enough, and never more than twice the room the copy needs (plus a little).
    pub(crate) fn copy_from(&mut self, other: &Self) {
        fn copy<T: Copy>(to: &mut Vec<T>, from: &[T]) {
            to.clear();
            if to.capacity() > 2 * from.len() + 16 {
                to.shrink_to(from.len());
            }
            to.extend_from_slice(from);
        }
        copy(&mut self.positions, &other.positions);
        copy(&mut self.normals, &other.normals);
        copy(&mut self.edge_ids, &other.edge_ids);
        copy(&mut self.indices, &other.indices);
    }
}

/// [`BrickMesh::prefetch`] of any slice: a hint per cache line it spans.
#[inline]
pub(crate) fn prefetch_slice<T>(items: &[T]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        const LINE: usize = 64;
        let bytes = size_of_val(items);
        if bytes == 0 {
            return;
        }
        let start = items.as_ptr().cast::<i8>();
        let mut offset = 0;
        while offset < bytes {
            // SAFETY: a prefetch only hints at the cache; it never faults and changes no
            // memory, and the address lies inside `items`.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(start.wrapping_add(offset)) };
            offset += LINE;
        }
        // The last line, which the steps above miss when `items` does not start on a line.
        // SAFETY: as above; the last byte of `items`.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(start.wrapping_add(bytes - 1)) };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = items;
}

/// Working memory for meshing bricks; keep one and reuse it.
#[derive(Clone, Debug)]
pub struct BrickScratch {
    /// Vertex index per (axis, local start sample), `u32::MAX` when not yet made (the
    /// normals' pass resets every slot it reads, so all are `u32::MAX` between bricks).
    slots: Vec<u32>,
    pub(crate) samples: Vec<f32>,
    /// Per row of samples (index `y + 9z`), bit `x` set where the sample is inside.
    rows: [u16; BRICK_SAMPLES * BRICK_SAMPLES],
    /// The samples not taken from a neighbour's face, densely, before they are spread (for a
    /// field that samples only dense blocks).
    dense: Vec<f32>,
    /// The vertex indices of the brick being marched, before they are copied to its mesh.
    triangles: Vec<u32>,
    /// The field's gradient at each vertex of the brick being marched, a coordinate at a
    /// time (all x, all y, all z), then the gradients' lengths.
    gradients: Vec<f32>,
    pub(crate) field: Vec<f32>,
    pub(crate) mesh: BrickMesh,
    /// How many vertices of the brick just marched lie on none of its lower faces that have
    /// a brick's room below them (see [`lower_face_vertices`]).
    pub(crate) owned_vertices: u32,
}

impl Default for BrickScratch {
    fn default() -> Self {
        Self {
            slots: vec![u32::MAX; 3 * BRICK_SAMPLE_COUNT],
            samples: vec![0.0; BRICK_SAMPLE_COUNT],
            rows: [0; BRICK_SAMPLES * BRICK_SAMPLES],
            dense: Vec::new(),
            triangles: vec![0; MAX_BRICK_INDICES],
            gradients: Vec::new(),
            field: Vec::new(),
            mesh: BrickMesh::default(),
            owned_vertices: 0,
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
        rows,
        dense,
        field: field_scratch,
        ..
    } = scratch;
    // (Slices, not vectors, in the loops below: their lengths stay in registers while
    // samples are written.)
    let samples = samples.as_mut_slice();
    if counts != [S; 3] {
        // Entries beyond a partial brick's extent: zero, whatever was sampled before.
        samples.fill(0.0);
    }
    let offset = lo[0] + S * (lo[1] + S * lo[2]);
    field.sample_block_strided(
        grid,
        start,
        sub,
        &mut samples[offset..],
        [S, S * S],
        field_scratch,
        dense,
    );
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
    // The inside bits, a row at a time, and how many of the brick's samples are inside.
    let iso = field.iso();
    for (bits, row) in rows.iter_mut().zip(samples.chunks_exact(S)) {
        let mut m = 0u16;
        for (x, &v) in row.iter().enumerate() {
            m |= u16::from(v > iso) << x;
        }
        *bits = m;
    }
    let extent = (1u16 << counts[0]) - 1;
    let mut inside = 0;
    for k in 0..counts[2] {
        for &bits in &rows[S * k..S * k + counts[1]] {
            inside += (bits & extent).count_ones();
        }
    }
    inside != 0 && inside as usize != counts[0] * counts[1] * counts[2]
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

/// Per cube edge: its line of edges (see [`march_brick`]'s `lines`) relative to the line of
/// the same axis through the cell's first sample.
const EDGE_LINE: [usize; 12] = {
    let mut t = [0usize; 12];
    let mut e = 0;
    while e < 12 {
        let o = CORNER_OFFSETS[EDGE_CORNERS[e][0] as usize];
        let (u, w) = match EDGE_AXIS[e] {
            0 => (o[1], o[2]),
            1 => (o[0], o[2]),
            _ => (o[0], o[1]),
        };
        t[e] = u as usize + BRICK_SAMPLES * w as usize;
        e += 1;
    }
    t
};

/// Most vertex indices one brick's triangles can hold (five triangles in every cell).
pub(crate) const MAX_BRICK_INDICES: usize = 3 * MAX_CASE_TRIANGLES * (BRICK_CELLS as usize).pow(3);

/// Marching cubes over the brick sampled by [`sample_brick`], into `scratch.mesh`.
///
/// Each sample's inside bit is taken once, when the brick is sampled, into a bit mask per
/// row of samples; the four rows around a row of cells give, with a few bit operations, the
/// cells that are neither all inside nor all outside, and only those are visited (in
/// order of x). The cells only number their vertices (in the order they first meet them)
/// and write their triangles; each vertex's position, edge id and normal are made
/// afterwards, line by line of the grid (see [`vertex_normals`]), where the divisions of
/// many vertices overlap instead of stalling the cell loop.
pub fn march_brick<F: ScalarField + ?Sized>(
    field: &F,
    grid: &SampleGrid,
    coord: [u32; 3],
    scratch: &mut BrickScratch,
) {
    const S: usize = BRICK_SAMPLES;
    let (first, cells) = brick_extent(grid, coord);
    let BrickScratch {
        slots,
        samples,
        rows,
        triangles,
        gradients,
        mesh,
        owned_vertices,
        ..
    } = scratch;
    // Only the triangles are cleared: the per-vertex buffers are resized to the vertex count
    // later, and every vertex's entries written then, so the bytes a buffer held before (a
    // kept brick's last mesh) need no zeroing first.
    mesh.indices.clear();
    let (slots, samples) = (slots.as_mut_slice(), samples.as_slice());
    // Per axis, per line of edges along it (indexed by the other two local coordinates, the
    // lower fastest), a bit per edge that holds a vertex.
    let mut lines = [[0u16; S * S]; 3];
    let [cx, cy, cz] = cells.map(|c| c as usize);
    let cell_mask = (1u32 << cx) - 1;
    let triangles = &mut triangles[..MAX_BRICK_INDICES];
    let mut n_indices = 0usize;
    let mut n_vertices = 0u32;
    for z in 0..cz {
        for y in 0..cy {
            let row = S * (y + S * z);
            // Inside bits of the corners: (y, z), (y + 1, z), (y, z + 1), (y + 1, z + 1).
            let r = [
                u32::from(rows[y + S * z]),
                u32::from(rows[y + 1 + S * z]),
                u32::from(rows[y + S * (z + 1)]),
                u32::from(rows[y + 1 + S * (z + 1)]),
            ];
            let any = r[0] | r[1] | r[2] | r[3];
            let all = r[0] & r[1] & r[2] & r[3];
            let mut mixed = (any | any >> 1) & !(all & all >> 1) & cell_mask;
            while mixed != 0 {
                let x = mixed.trailing_zeros() as usize;
                mixed &= mixed - 1;
                // Corner `dx + 2dy + 4dz` is bit `dx` of row `dy + 2dz`.
                let case = ((r[0] >> x) & 3
                    | ((r[1] >> x) & 3) << 2
                    | ((r[2] >> x) & 3) << 4
                    | ((r[3] >> x) & 3) << 6) as usize;
                let base = row + x;
                // The cell's lines per axis, and its place along them.
                let line = [y + S * z, x + S * z, x + S * y];
                let along = [x, y, z];
                let tris = &CASES[case];
                for tri in &tris.edges[..tris.count as usize] {
                    for &e in tri {
                        let e = e as usize;
                        let slot = &mut slots[base + EDGE_SLOT[e]];
                        if *slot == u32::MAX {
                            *slot = n_vertices;
                            n_vertices += 1;
                            let axis = EDGE_AXIS[e] as usize;
                            lines[axis][line[axis] + EDGE_LINE[e]] |= 1 << along[axis];
                        }
                        triangles[n_indices] = *slot;
                        n_indices += 1;
                    }
                }
            }
        }
    }
    mesh.indices.extend_from_slice(&triangles[..n_indices]);
    *owned_vertices = n_vertices - lower_face_vertices(first, &lines);
    vertex_normals(
        field,
        grid,
        first,
        &lines,
        n_vertices as usize,
        slots,
        samples,
        gradients,
        mesh,
    );
}

/// How many of a brick's vertices lie on one of its lower faces with a brick's room below it
/// (not at the grid's own lower faces), from its lines of edges (see [`march_brick`]): a
/// weld takes those vertices from the bricks below, so the others are the ones the brick
/// owns. A line of edges along one axis lies on a lower face when its place across either
/// other axis is the brick's first; `first` is the brick's first sample.
fn lower_face_vertices(first: [u32; 3], lines: &[[u16; BRICK_SAMPLES * BRICK_SAMPLES]; 3]) -> u32 {
    const S: usize = BRICK_SAMPLES;
    let mut count = 0;
    for (axis, lines) in lines.iter().enumerate() {
        // The lines' place across `u_axis` is the lower index, across `w_axis` the upper.
        let (u_axis, w_axis) = match axis {
            0 => (1, 2),
            1 => (0, 2),
            _ => (0, 1),
        };
        for w in 0..S {
            for u in 0..S {
                if (u == 0 && first[u_axis] > 0) || (w == 0 && first[w_axis] > 0) {
                    count += lines[u + S * w].count_ones();
                }
            }
        }
    }
    count
}

/// The position, edge id and unit outward normal `−∇s / |∇s|` of every vertex of the brick
/// just marched, made along each line of edges in turn: for all the vertices on one line,
/// two of the three coordinates are the same, and the lines of one plane share one more, so
/// a field whose gradient works each coordinate out apart (as an analytic closure, inlined,
/// does) computes those parts once per line or plane, not once per vertex. A flat field
/// (zero or non-finite gradient) gets the edge's direction, from its inside end to its
/// outside end.
///
/// A vertex lies where the samples' linear interpolation crosses the iso-level, its
/// parameter kept [`T_MARGIN`] from the edge's ends; off the edge's axis it has the samples'
/// own coordinates (the same expression as [`SampleGrid::point`], so the same bits).
#[allow(clippy::too_many_arguments)]
fn vertex_normals<F: ScalarField + ?Sized>(
    field: &F,
    grid: &SampleGrid,
    first: [u32; 3],
    lines: &[[u16; BRICK_SAMPLES * BRICK_SAMPLES]; 3],
    vertices: usize,
    slots: &mut [u32],
    samples: &[f32],
    gradients: &mut Vec<f32>,
    mesh: &mut BrickMesh,
) {
    const S: usize = BRICK_SAMPLES;
    let BrickMesh {
        positions,
        normals,
        edge_ids,
        ..
    } = mesh;
    positions.resize(vertices, Vec3::ZERO);
    normals.resize(vertices, Vec3::ZERO);
    edge_ids.resize(vertices, 0);
    gradients.resize(4 * vertices, 0.0);
    let (gx, rest) = gradients.split_at_mut(vertices);
    let (gy, rest) = rest.split_at_mut(vertices);
    let (gz, lengths) = rest.split_at_mut(vertices);
    let coordinates: [[f32; S]; 3] =
        std::array::from_fn(|a| std::array::from_fn(|i| grid.coordinate(a, first[a] + i as u32)));
    let out = VertexOut {
        positions,
        normals,
        edge_ids,
        gradients: [gx, gy, gz],
    };
    let out = normals_along::<0, F>(field, first, &coordinates, &lines[0], slots, samples, out);
    let out = normals_along::<1, F>(field, first, &coordinates, &lines[1], slots, samples, out);
    let out = normals_along::<2, F>(field, first, &coordinates, &lines[2], slots, samples, out);
    // The normals from the gradients, in loops of their own, a coordinate at a time: the
    // compiler packs several vertices into each square root and division (the same bits as
    // `Vec3::length` and `-g / length` give one vertex), and none waits behind its vertex's
    // field call.
    let VertexOut {
        normals,
        gradients: [gx, gy, gz],
        ..
    } = out;
    for (((x, y), z), length) in gx
        .iter_mut()
        .zip(gy.iter_mut())
        .zip(gz.iter_mut())
        .zip(lengths.iter_mut())
    {
        let l = ((*x * *x) + (*y * *y) + (*z * *z)).sqrt();
        *length = l;
        (*x, *y, *z) = (-*x / l, -*y / l, -*z / l);
    }
    for ((n, &l), ((&x, &y), &z)) in normals
        .iter_mut()
        .zip(lengths.iter())
        .zip(gx.iter().zip(gy.iter()).zip(gz.iter()))
    {
        if l > 1e-20 && l.is_finite() {
            *n = Vec3::new(x, y, z);
        }
    }
}

/// The per-vertex buffers [`normals_along`] fills (`normals` with the flat field's normal,
/// kept where the gradient is zero or not finite).
struct VertexOut<'a> {
    positions: &'a mut [Vec3],
    normals: &'a mut [Vec3],
    edge_ids: &'a mut [u64],
    gradients: [&'a mut [f32]; 3],
}

/// [`vertex_normals`] of the vertices on edges along `AXIS` (a constant, so that the point
/// handed to the field is built from registers and its fixed parts are seen to be fixed).
fn normals_along<'a, const AXIS: usize, F: ScalarField + ?Sized>(
    field: &F,
    first: [u32; 3],
    coordinates: &[[f32; BRICK_SAMPLES]; 3],
    lines: &[u16; BRICK_SAMPLES * BRICK_SAMPLES],
    slots: &mut [u32],
    samples: &[f32],
    out: VertexOut<'a>,
) -> VertexOut<'a> {
    const S: usize = BRICK_SAMPLES;
    // The other two axes: `w` outer (one per plane), `u` inner (one per line).
    let (u_axis, w_axis) = match AXIS {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    let stride = [1, S, S * S][AXIS];
    let iso = field.iso();
    let VertexOut {
        positions,
        normals,
        edge_ids,
        gradients,
    } = out;
    let slots = &mut slots[AXIS * BRICK_SAMPLE_COUNT..(AXIS + 1) * BRICK_SAMPLE_COUNT];
    for (w, plane) in lines.chunks_exact(S).enumerate() {
        if plane.iter().all(|&m| m == 0) {
            continue;
        }
        let wc = coordinates[w_axis][w];
        for (u, &mask) in plane.iter().enumerate() {
            let uc = coordinates[u_axis][u];
            let mut m = mask;
            while m != 0 {
                let along = m.trailing_zeros() as usize;
                m &= m - 1;
                let (start, local) = match AXIS {
                    0 => (along + S * (u + S * w), [along, u, w]),
                    1 => (u + S * (along + S * w), [u, along, w]),
                    _ => (u + S * (w + S * along), [u, w, along]),
                };
                let v = std::mem::replace(&mut slots[start], u32::MAX) as usize;
                let (v0, v1) = (samples[start], samples[start + stride]);
                // v0 != v1: exactly one of them is above the iso-level.
                let t = ((iso - v0) / (v1 - v0)).clamp(T_MARGIN, 1.0 - T_MARGIN);
                let (a0, a1) = (coordinates[AXIS][along], coordinates[AXIS][along + 1]);
                let a = a0 + (a1 - a0) * t;
                let p = match AXIS {
                    0 => Vec3::new(a, uc, wc),
                    1 => Vec3::new(uc, a, wc),
                    _ => Vec3::new(uc, wc, a),
                };
                positions[v] = p;
                let corner: [u32; 3] = std::array::from_fn(|k| first[k] + local[k] as u32);
                edge_ids[v] = edge_id(corner, AXIS as u8);
                let g = field.gradient(p);
                (gradients[0][v], gradients[1][v], gradients[2][v]) = (g.x, g.y, g.z);
                let mut flat = Vec3::ZERO;
                flat[AXIS] = if v0 > v1 { 1.0 } else { -1.0 };
                normals[v] = flat;
            }
        }
    }
    VertexOut {
        positions,
        normals,
        edge_ids,
        gradients,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::source::FnField;

    /// Samples and meshes one brick; its samples and mesh, or `None` when the surface does
    /// not cross it.
    fn build_brick<F: ScalarField + ?Sized>(
        field: &F,
        grid: &SampleGrid,
        coord: [u32; 3],
        scratch: &mut BrickScratch,
    ) -> Option<(Vec<f32>, BrickMesh)> {
        if !sample_brick(field, grid, coord, scratch) {
            return None;
        }
        march_brick(field, grid, coord, scratch);
        Some((scratch.samples.clone(), scratch.mesh.clone()))
    }

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
