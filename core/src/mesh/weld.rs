//! Welding a brick octree's meshes into one indexed mesh, on one thread or several.
//!
//! A vertex on a brick's face is shared by every brick that holds its edge; the first of
//! them in Morton order is the one with the least coordinates (Morton order grows with each
//! coordinate), so a brick *owns* the vertices not on its lower faces and finds the others
//! among the upper-face vertices its owner kept: a bit per upper-face place (459 places, 8
//! words) and the kept indices in place order, so a vertex's entry is the rank of its bit.
//! No hashing, no search, and the lists stay in cache.
//!
//! On several threads each thread welds a contiguous run of the bricks (in Morton order)
//! as the one thread welds them all, into its own part of the mesh: a prefix sum over the
//! bricks' counts of owned vertices (taken when each brick was meshed; a few thousand
//! additions on the caller) gives each brick its first welded vertex, and a vertex whose
//! owner lies in an earlier run (a brick next to the run's start) counts that owner's
//! vertices again to find its index. The result is the one-thread weld's, bit for bit.
//!
//! Allocates only when the mesh or the tree grew since the scratch's last weld (and, on
//! several threads, the list of the bricks, a few per-thread lists and the threads).

use std::collections::HashMap;
use std::hash::BuildHasherDefault;
use std::mem::MaybeUninit;

use glam::Vec3;

use super::brick::{BRICK_CELLS, BRICK_SAMPLE_COUNT, BRICK_SAMPLES, edge_from_id, prefetch_slice};
use super::octree::{Brick, BrickOctree, EdgeIdHasher, WeldPiece, morton, weld_pieces};
use super::trimesh::TriMesh;

/// Most entries in the weld's table of brick ordinals by coordinate (4 MB; a larger grid of
/// bricks searches the keys instead).
pub(super) const MAX_ORDINAL_TABLE: usize = 1 << 20;

/// Words of a bit per place on a brick's upper faces (see [`upper_slot`]).
const UPPER_WORDS: usize = 8;

/// Per place in a brick (`axis · 9³ + x + 9y + 81z`: the axis and start sample of an edge),
/// its number among the places on the brick's upper faces (an edge off its own axis at the
/// far end of the brick), or `u16::MAX` for a place not on them.
static UPPER_SLOTS: [u16; 3 * BRICK_SAMPLE_COUNT] = {
    const S: usize = BRICK_SAMPLES;
    let mut table = [u16::MAX; 3 * BRICK_SAMPLE_COUNT];
    let mut next = 0u16;
    let mut place = 0;
    while place < 3 * BRICK_SAMPLE_COUNT {
        let axis = place / BRICK_SAMPLE_COUNT;
        let l = [place % S, place / S % S, place / (S * S) % S];
        let mut a = 0;
        let mut upper = false;
        while a < 3 {
            upper |= a != axis && l[a] == S - 1;
            a += 1;
        }
        if upper {
            table[place] = next;
            next += 1;
        }
        place += 1;
    }
    assert!(next as usize <= 64 * UPPER_WORDS);
    table
};

/// The number among the upper-face places ([`UPPER_SLOTS`]) of the edge that starts at
/// global sample `corner` and runs along `axis`, in the brick whose first sample is `first`,
/// if the edge lies on that brick's upper faces.
#[inline]
fn upper_slot(corner: [u32; 3], axis: usize, first: [u32; 3]) -> Option<usize> {
    const S: u32 = BRICK_SAMPLES as u32;
    let l: [u32; 3] = std::array::from_fn(|a| corner[a].wrapping_sub(first[a]));
    let place = (axis as u32 * S * S * S)
        .wrapping_add(l[0])
        .wrapping_add(S.wrapping_mul(l[1].wrapping_add(S.wrapping_mul(l[2]))));
    let slot = *UPPER_SLOTS.get(place as usize)?;
    (slot != u16::MAX).then_some(usize::from(slot))
}

/// Where a brick's vertex lies: its edge, and which of the brick's faces hold that edge.
#[derive(Clone, Copy, Debug)]
struct VertexPlace {
    corner: [u32; 3],
    axis: usize,
    /// Bit `a` set where the edge lies on the brick's lower face across axis `a` and a brick
    /// can lie below (the grid's own lower faces do not count): the vertex's owner is the
    /// brick below across those axes. Zero for a vertex the brick owns.
    lower: usize,
    /// The edge lies on one of the brick's upper faces (kept for the bricks above).
    upper: bool,
}

/// [`VertexPlace`] of the vertex with edge id `id` in the brick whose first sample is `first`.
#[inline]
fn vertex_place(id: u64, first: [u32; 3]) -> VertexPlace {
    let (corner, axis) = edge_from_id(id);
    let axis = axis as usize;
    let mut lower = 0usize;
    let mut upper = false;
    for a in 0..3 {
        if a != axis && corner[a] % BRICK_CELLS == 0 {
            if corner[a] == first[a] {
                lower |= usize::from(corner[a] > 0) << a;
            } else {
                upper = true;
            }
        }
    }
    VertexPlace {
        corner,
        axis,
        lower,
        upper,
    }
}

/// One brick's kept upper-face vertices: a bit per upper-face place that holds one, and
/// where their entries start in a list of kept entries; the `n`-th set bit's entry is
/// `first + n`.
#[derive(Clone, Copy, Debug, Default)]
struct KeptFaces {
    bits: [u64; UPPER_WORDS],
    /// Per word of `bits`, the set bits in the words before it.
    before: [u16; UPPER_WORDS],
    first: u32,
}

impl KeptFaces {
    /// Appends the entries of the places set in `bits` (`entries[slot]` for each, in slot
    /// order) to `kept` and describes them.
    fn keep(
        bits: [u64; UPPER_WORDS],
        entries: &[u32; 64 * UPPER_WORDS],
        kept: &mut Vec<u32>,
    ) -> Self {
        let mut faces = Self {
            bits,
            before: [0; UPPER_WORDS],
            first: kept.len() as u32,
        };
        let mut count = 0u16;
        for (w, &word) in bits.iter().enumerate() {
            faces.before[w] = count;
            count += word.count_ones() as u16;
            let mut m = word;
            while m != 0 {
                kept.push(entries[64 * w + m.trailing_zeros() as usize]);
                m &= m - 1;
            }
        }
        faces
    }

    /// Where in the list of kept entries the vertex of upper-face place `slot` is, if kept
    /// (its rank among the set bits).
    #[inline]
    fn entry(&self, slot: usize) -> Option<usize> {
        let word = self.bits[slot / 64];
        let bit = slot % 64;
        (word >> bit & 1 == 1).then(|| {
            self.first as usize
                + usize::from(self.before[slot / 64])
                + (word & ((1 << bit) - 1)).count_ones() as usize
        })
    }
}

/// Working memory of [`super::BrickOctree::weld_into`] and
/// [`super::BrickOctree::weld_into_with_threads`]; keep one and reuse it.
#[derive(Clone, Debug, Default)]
pub struct WeldScratch {
    keys: Vec<u64>,
    ordinals: Vec<u32>,
    kept: Vec<u32>,
    kept_faces: Vec<KeptFaces>,
    stray: HashMap<u64, u32, BuildHasherDefault<EdgeIdHasher>>,
    local: Vec<u32>,
    /// Per brick, its first welded vertex.
    vertex_base: Vec<u32>,
    /// Per run of bricks (one per thread): its bricks' kept entries and its vertex numbers.
    runs: Vec<RunScratch>,
}

/// One thread's working memory in a weld on several threads.
#[derive(Clone, Debug, Default)]
struct RunScratch {
    /// The welded indices of the run's bricks' kept upper-face vertices.
    kept: Vec<u32>,
    local: Vec<u32>,
    /// Owner bricks of earlier runs met so far, by ordinal (sorted), and their kept
    /// upper-face vertices' welded indices.
    earlier: Vec<(usize, KeptFaces)>,
    earlier_kept: Vec<u32>,
}

/// A brick's ordinal in Morton order by its coordinate: a table over the grid of bricks
/// where that is small enough, else a search among the keys.
struct Ordinals<'a> {
    counts: [usize; 3],
    /// Per brick of the grid (x fastest), its ordinal, or `u32::MAX` where none is stored;
    /// empty when the grid is too large for a table.
    table: &'a [u32],
    /// The stored bricks' Morton keys, in order, when there is no table.
    keys: &'a [u64],
}

impl<'a> Ordinals<'a> {
    /// Fills `table` or `keys` (the other is left empty) for `bricks`, in Morton order, of a
    /// grid of `counts` bricks.
    fn new<'b>(
        bricks: impl Iterator<Item = &'b Brick>,
        counts: [u32; 3],
        table: &'a mut Vec<u32>,
        keys: &'a mut Vec<u64>,
    ) -> Self {
        let [nx, ny, nz] = counts.map(|c| c as usize);
        let by_table = nx
            .checked_mul(ny)
            .and_then(|n| n.checked_mul(nz))
            .is_some_and(|n| n <= MAX_ORDINAL_TABLE);
        table.clear();
        keys.clear();
        if by_table {
            table.resize(nx * ny * nz, u32::MAX);
            for (o, b) in bricks.enumerate() {
                let c = b.coord.map(|c| c as usize);
                if c[0] < nx && c[1] < ny && c[2] < nz {
                    table[c[0] + nx * (c[1] + ny * c[2])] = o as u32;
                }
            }
        } else {
            keys.extend(bricks.map(|b| morton(b.coord)));
        }
        Self {
            counts: [nx, ny, nz],
            table,
            keys,
        }
    }

    /// The ordinal and coordinate of the brick below `coord` across the axes set in `lower`
    /// (none at zero along them), if it is stored.
    fn below(&self, coord: [u32; 3], lower: usize) -> Option<(usize, [u32; 3])> {
        let mut c = coord;
        for (a, c) in c.iter_mut().enumerate() {
            *c -= ((lower >> a) & 1) as u32;
        }
        let o = if self.keys.is_empty() {
            let [nx, ny, _] = self.counts;
            let at = c[0] as usize + nx * (c[1] as usize + ny * c[2] as usize);
            self.table
                .get(at)
                .filter(|&&o| o != u32::MAX)
                .map(|&o| o as usize)
        } else {
            self.keys.binary_search(&morton(c)).ok()
        };
        o.map(|o| (o, c))
    }
}

/// The weld on the caller's thread: `bricks` (the tree's, in Morton order, `counts` bricks
/// per axis) into `out`, its contents replaced.
pub(super) fn weld_serial<'b, I>(
    bricks: I,
    counts: [u32; 3],
    out: &mut TriMesh,
    scratch: &mut WeldScratch,
) where
    I: Iterator<Item = &'b Brick> + Clone,
{
    let vertices: usize = bricks.clone().map(|b| b.mesh.positions.len()).sum();
    let triangles: usize = bricks.clone().map(|b| b.mesh.triangle_count()).sum();
    clear_and_reserve(out, vertices, triangles);
    let WeldScratch {
        keys,
        ordinals,
        kept,
        kept_faces,
        stray,
        local,
        ..
    } = scratch;
    let ordinals = Ordinals::new(bricks.clone(), counts, ordinals, keys);
    // Per brick (in Morton order), its upper-face vertices' welded indices.
    kept.clear();
    kept_faces.clear();
    // Vertices whose owner brick is missing or did not keep them (never, for a tree the
    // octree built; kept so that welding stays by edge id whatever the bricks hold).
    stray.clear();
    // The brick after the one being welded, whose buffers are asked into the cache
    // meanwhile (see `BrickMesh::prefetch`).
    let mut ahead = bricks.clone().skip(1);
    // The welded vertices are written straight into the room reserved above, `welded` of
    // them so far, and the lengths set once at the end (no length kept up to date in memory
    // for each vertex).
    let mut welded = 0usize;
    let positions_room = &mut out.positions.spare_capacity_mut()[..vertices];
    let normals_room = &mut out.normals.spare_capacity_mut()[..vertices];
    for brick in bricks {
        let next = ahead.next();
        // The next brick's vertices now, its triangles before this brick's (two halves).
        if let Some(next) = next {
            prefetch_slice(&next.mesh.edge_ids);
            prefetch_slice(&next.mesh.positions);
            prefetch_slice(&next.mesh.normals);
        }
        let m = &brick.mesh;
        let first = brick.coord.map(|c| c * BRICK_CELLS);
        // The bricks below, by mask of axes (looked up when first needed).
        let mut below = [None::<Option<(usize, [u32; 3])>>; 8];
        // This brick's upper-face vertices, by their number among the upper-face places.
        let mut upper_bits = [0u64; UPPER_WORDS];
        let mut upper_index = [0u32; 64 * UPPER_WORDS];
        // (Every entry is written below; no need to zero it first.)
        local.resize(m.edge_ids.len(), 0);
        for ((v, &id), local) in m.edge_ids.iter().enumerate().zip(local.iter_mut()) {
            let place = vertex_place(id, first);
            let index = if place.lower == 0 {
                let next = welded as u32;
                positions_room[welded].write(m.positions[v]);
                normals_room[welded].write(m.normals[v]);
                welded += 1;
                if place.upper
                    && let Some(slot) = upper_slot(place.corner, place.axis, first)
                {
                    upper_bits[slot / 64] |= 1 << (slot % 64);
                    upper_index[slot] = next;
                }
                next
            } else {
                let owner = *below[place.lower]
                    .get_or_insert_with(|| ordinals.below(brick.coord, place.lower));
                let found = owner.and_then(|(o, owner)| {
                    let slot =
                        upper_slot(place.corner, place.axis, owner.map(|c| c * BRICK_CELLS))?;
                    kept_faces[o].entry(slot).map(|at| kept[at])
                });
                found.unwrap_or_else(|| {
                    let next = welded as u32;
                    let index = *stray.entry(id).or_insert(next);
                    if index == next {
                        positions_room[welded].write(m.positions[v]);
                        normals_room[welded].write(m.normals[v]);
                        welded += 1;
                    }
                    index
                })
            };
            *local = index;
        }
        kept_faces.push(KeptFaces::keep(upper_bits, &upper_index, kept));
        if let Some(next) = next {
            prefetch_slice(&next.mesh.indices);
        }
        // (Through a slice, whose length stays in a register while triangles are written.)
        let local = local.as_slice();
        out.triangles.extend(m.indices.chunks_exact(3).map(|t| {
            [
                local[t[0] as usize],
                local[t[1] as usize],
                local[t[2] as usize],
            ]
        }));
    }
    // SAFETY: the first `welded` entries of both vectors' room were written above, one after
    // another (`welded` never passes `vertices`, the room reserved: the rooms are indexed
    // with bounds checks).
    unsafe {
        out.positions.set_len(welded);
        out.normals.set_len(welded);
    }
}

/// Empties `out` and gives it room for `vertices` vertices and `triangles` triangles.
fn clear_and_reserve(out: &mut TriMesh, vertices: usize, triangles: usize) {
    out.positions.clear();
    out.normals.clear();
    out.triangles.clear();
    out.positions.reserve(vertices);
    out.normals.reserve(vertices);
    out.triangles.reserve(triangles);
}

/// The weld on `threads` threads (the caller and `threads − 1` more), with the result of
/// [`weld_serial`]. False, with `out` unspecified, when some vertex has no owner that kept
/// it (never, for a tree the octree built) or a brick's count of owned vertices does not
/// match its mesh: the caller then welds on one thread, which merges such vertices by edge
/// id.
pub(super) fn weld_parallel(
    bricks: &[&Brick],
    counts: [u32; 3],
    out: &mut TriMesh,
    scratch: &mut WeldScratch,
    threads: usize,
) -> bool {
    let threads = threads.clamp(1, bricks.len().max(1));
    let vertices: usize = bricks.iter().map(|b| b.mesh.positions.len()).sum();
    let triangles: usize = bricks.iter().map(|b| b.mesh.triangle_count()).sum();
    clear_and_reserve(out, vertices, triangles);
    let WeldScratch {
        keys,
        ordinals,
        kept_faces,
        vertex_base,
        runs,
        ..
    } = scratch;
    let ordinals = Ordinals::new(bricks.iter().copied(), counts, ordinals, keys);
    // Each brick's first welded vertex, from the bricks' counts of owned vertices.
    vertex_base.clear();
    let mut welded = 0usize;
    for b in bricks {
        vertex_base.push(welded as u32);
        welded += b.owned_vertices as usize;
    }
    if welded > vertices {
        return false;
    }
    // Runs of about equal vertex counts: run `r` is bricks `starts[r] .. starts[r + 1]`.
    let mut starts = Vec::with_capacity(threads + 1);
    starts.push(0);
    let mut sum = 0usize;
    for (o, b) in bricks.iter().enumerate() {
        if sum >= vertices * starts.len() / threads && starts.len() < threads {
            starts.push(o);
        }
        sum += b.mesh.positions.len();
    }
    while starts.len() <= threads {
        starts.push(bricks.len());
    }
    let vertex_starts: Vec<usize> = starts
        .iter()
        .map(|&o| vertex_base.get(o).map_or(welded, |&v| v as usize))
        .collect();
    let mut triangle_starts = Vec::with_capacity(threads + 1);
    triangle_starts.push(0usize);
    for r in 0..threads {
        let t: usize = bricks[starts[r]..starts[r + 1]]
            .iter()
            .map(|b| b.mesh.triangle_count())
            .sum();
        triangle_starts.push(triangle_starts[r] + t);
    }
    runs.resize_with(threads, RunScratch::default);
    kept_faces.clear();
    kept_faces.resize(bricks.len(), KeptFaces::default());

    let all_written = {
        let positions = split_runs(
            &mut out.positions.spare_capacity_mut()[..welded],
            &vertex_starts,
        );
        let normals = split_runs(
            &mut out.normals.spare_capacity_mut()[..welded],
            &vertex_starts,
        );
        let tris = split_runs(
            &mut out.triangles.spare_capacity_mut()[..triangles],
            &triangle_starts,
        );
        let faces = split_runs(kept_faces, &starts);
        let shared = Shared {
            bricks,
            vertex_base,
            starts: &starts,
            ordinals: &ordinals,
        };
        let shared = &shared;
        let work = positions
            .into_iter()
            .zip(normals)
            .zip(tris)
            .zip(faces)
            .zip(runs.iter_mut())
            .enumerate()
            .map(|(r, ((((positions, normals), tris), faces), run))| {
                move || shared.weld_run(r, positions, normals, tris, faces, run)
            });
        run_on_threads(work).into_iter().all(|ok| ok)
    };
    if !all_written {
        return false;
    }
    // SAFETY: every run wrote every entry of its part of the rooms (`weld_run` returned
    // true): the parts cover the first `welded` vertices and `triangles` triangles, which
    // lie within the room reserved.
    unsafe {
        out.positions.set_len(welded);
        out.normals.set_len(welded);
        out.triangles.set_len(triangles);
    }
    true
}

/// Splits `items` at `starts` (the first entry 0, ascending, the last at most its length):
/// part `r` is `starts[r] .. starts[r + 1]`.
fn split_runs<'a, T>(mut items: &'a mut [T], starts: &[usize]) -> Vec<&'a mut [T]> {
    let mut parts = Vec::with_capacity(starts.len().saturating_sub(1));
    for w in starts.windows(2) {
        let (part, rest) = std::mem::take(&mut items).split_at_mut(w[1] - w[0]);
        parts.push(part);
        items = rest;
    }
    parts
}

/// Runs each job, the first on the caller and the others on threads of their own, and
/// returns their results in order.
fn run_on_threads<T: Send, F: FnOnce() -> T + Send>(jobs: impl Iterator<Item = F>) -> Vec<T> {
    let mut jobs = jobs;
    let Some(first) = jobs.next() else {
        return Vec::new();
    };
    std::thread::scope(|scope| {
        let helpers: Vec<_> = jobs.map(|job| scope.spawn(job)).collect();
        let mut results = vec![first()];
        for h in helpers {
            match h.join() {
                Ok(r) => results.push(r),
                Err(panic) => std::panic::resume_unwind(panic),
            }
        }
        results
    })
}

/// What every thread of a weld on several threads reads.
struct Shared<'a> {
    bricks: &'a [&'a Brick],
    /// Per brick, its first welded vertex.
    vertex_base: &'a [u32],
    starts: &'a [usize],
    ordinals: &'a Ordinals<'a>,
}

impl Shared<'_> {
    /// Welds run `r` as [`weld_serial`] welds all bricks: its owned vertices into `positions`
    /// and `normals` (the run's part of the welded vertices, from the bricks' first welded
    /// vertices) and its triangles into `tris`, its bricks' kept upper-face vertices into
    /// `faces` and `run.kept`. A vertex whose owner lies in an earlier run finds its index
    /// among the owner's vertices, counted again here (only bricks next to the run's start
    /// are such owners). False as soon as a vertex has no owner that kept it or a brick's
    /// owned vertices are not as many as it counted.
    fn weld_run(
        &self,
        r: usize,
        positions: &mut [MaybeUninit<Vec3>],
        normals: &mut [MaybeUninit<Vec3>],
        tris: &mut [MaybeUninit<[u32; 3]>],
        faces: &mut [KeptFaces],
        run: &mut RunScratch,
    ) -> bool {
        let range = self.starts[r]..self.starts[r + 1];
        let Some(&run_first) = self.vertex_base.get(range.start) else {
            return true;
        };
        let RunScratch {
            kept,
            local,
            earlier,
            earlier_kept,
        } = run;
        kept.clear();
        earlier.clear();
        earlier_kept.clear();
        let mut t = 0usize;
        for o in range.clone() {
            let brick = self.bricks[o];
            let next_brick = self.bricks[..range.end].get(o + 1);
            if let Some(next) = next_brick {
                prefetch_slice(&next.mesh.edge_ids);
                prefetch_slice(&next.mesh.positions);
                prefetch_slice(&next.mesh.normals);
            }
            let m = &brick.mesh;
            let first = brick.coord.map(|c| c * BRICK_CELLS);
            let mut below = [None::<Option<(usize, [u32; 3])>>; 8];
            let mut upper_bits = [0u64; UPPER_WORDS];
            let mut upper_index = [0u32; 64 * UPPER_WORDS];
            let mut next = self.vertex_base[o];
            local.resize(m.edge_ids.len(), 0);
            for ((v, &id), local) in m.edge_ids.iter().enumerate().zip(local.iter_mut()) {
                let place = vertex_place(id, first);
                *local = if place.lower == 0 {
                    let at = (next - run_first) as usize;
                    let (Some(p), Some(n)) = (positions.get_mut(at), normals.get_mut(at)) else {
                        return false;
                    };
                    p.write(m.positions[v]);
                    n.write(m.normals[v]);
                    if place.upper
                        && let Some(slot) = upper_slot(place.corner, place.axis, first)
                    {
                        upper_bits[slot / 64] |= 1 << (slot % 64);
                        upper_index[slot] = next;
                    }
                    next += 1;
                    next - 1
                } else {
                    let owner = *below[place.lower]
                        .get_or_insert_with(|| self.ordinals.below(brick.coord, place.lower));
                    let Some((owner, owner_coord)) = owner else {
                        return false;
                    };
                    let owner_first = owner_coord.map(|c| c * BRICK_CELLS);
                    let Some(slot) = upper_slot(place.corner, place.axis, owner_first) else {
                        return false;
                    };
                    let found = if owner >= range.start {
                        faces[owner - range.start].entry(slot).map(|at| kept[at])
                    } else {
                        let at = match earlier.binary_search_by_key(&owner, |e| e.0) {
                            Ok(at) => at,
                            Err(at) => {
                                let counted = self.keep_owned(owner, earlier_kept);
                                earlier.insert(at, (owner, counted));
                                at
                            }
                        };
                        earlier[at].1.entry(slot).map(|at| earlier_kept[at])
                    };
                    let Some(index) = found else {
                        return false;
                    };
                    index
                };
            }
            if next - self.vertex_base[o] != brick.owned_vertices {
                return false;
            }
            faces[o - range.start] = KeptFaces::keep(upper_bits, &upper_index, kept);
            if let Some(next) = next_brick {
                prefetch_slice(&next.mesh.indices);
            }
            let local = local.as_slice();
            let Some(room) = tris.get_mut(t..t + m.triangle_count()) else {
                return false;
            };
            for (room, i) in room.iter_mut().zip(m.indices.chunks_exact(3)) {
                room.write([
                    local[i[0] as usize],
                    local[i[1] as usize],
                    local[i[2] as usize],
                ]);
            }
            t += m.triangle_count();
        }
        // (Each brick wrote as many vertices as it owns, from its first welded vertex on, so
        // the run filled its part of the vertices.)
        t == tris.len()
    }

    /// The kept upper-face vertices of brick `o` (of an earlier run) with their welded
    /// indices, counted from its edge ids: its entries appended to `kept`.
    fn keep_owned(&self, o: usize, kept: &mut Vec<u32>) -> KeptFaces {
        let brick = self.bricks[o];
        let first = brick.coord.map(|c| c * BRICK_CELLS);
        let mut upper_bits = [0u64; UPPER_WORDS];
        let mut upper_index = [0u32; 64 * UPPER_WORDS];
        let mut next = self.vertex_base[o];
        for &id in &brick.mesh.edge_ids {
            let place = vertex_place(id, first);
            if place.lower == 0 {
                if place.upper
                    && let Some(slot) = upper_slot(place.corner, place.axis, first)
                {
                    upper_bits[slot / 64] |= 1 << (slot % 64);
                    upper_index[slot] = next;
                }
                next += 1;
            }
        }
        KeptFaces::keep(upper_bits, &upper_index, kept)
    }
}

/// The octree's welds (here, beside the weld they run, so the octree does not reach back).
impl BrickOctree {
    /// One welded mesh of all bricks: vertices shared between bricks merged by edge id, so
    /// there are no duplicates. Vertex and triangle order follow the bricks' Morton order.
    /// How: see [`super::weld`] (each brick owns the vertices off its lower faces and finds
    /// the others by rank among those its owner kept).
    #[must_use]
    pub fn weld(&self) -> TriMesh {
        let mut out = TriMesh::default();
        self.weld_into(&mut out, &mut WeldScratch::default());
        out
    }

    /// [`BrickOctree::weld`] on `threads` threads (1 or more): the same mesh, bit for bit.
    #[must_use]
    pub fn weld_with_threads(&self, threads: usize) -> TriMesh {
        let mut out = TriMesh::default();
        self.weld_into_with_threads(&mut out, &mut WeldScratch::default(), threads);
        out
    }

    /// [`BrickOctree::weld`] into `out` (its contents replaced), with the working memory in
    /// `scratch`: keep both and weld again after each rebuild, and after the first time the
    /// weld allocates nothing unless the mesh grew. `out` ends exactly as `weld` makes it.
    ///
    /// A [cut](BrickOctree::is_cut) octree's bricks are welded by vertex id
    /// ([`super::weld_pieces`]).
    pub fn weld_into(&self, out: &mut TriMesh, scratch: &mut WeldScratch) {
        if self.is_cut() {
            let pieces: Vec<WeldPiece<'_, Vec3>> = self
                .bricks
                .values()
                .map(|b| WeldPiece::of(&b.mesh))
                .collect();
            *out = weld_pieces(&pieces);
            return;
        }
        weld_serial(self.bricks.values(), self.brick_counts, out, scratch);
    }

    /// [`BrickOctree::weld_into`] on `threads` threads (the caller and `threads − 1` more),
    /// each welding a run of the bricks in two passes (see [`super::weld`]): `out` ends
    /// exactly as `weld` makes it. One thread welds as `weld_into` does.
    pub fn weld_into_with_threads(
        &self,
        out: &mut TriMesh,
        scratch: &mut WeldScratch,
        threads: usize,
    ) {
        if threads > 1 && self.bricks.len() > 1 && !self.is_cut() {
            let bricks: Vec<&Brick> = self.bricks.values().collect();
            if weld_parallel(&bricks, self.brick_counts, out, scratch, threads) {
                return;
            }
        }
        self.weld_into(out, scratch);
    }
}
