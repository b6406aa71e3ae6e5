//! Per-brick GPU vertex and index buffers, re-uploaded only when a brick's version changes.
//!
//! [`ChunkBuffers::sync`] takes the full current set of chunks: new or changed chunks are
//! uploaded (into their existing buffers when those are large enough), unchanged ones cost a
//! map lookup, and chunks no longer present are dropped. Counters record every upload so the
//! "only dirty bricks" promise is testable.

use std::collections::HashMap;

use super::chunk::{ChunkError, MeshChunk};
use super::lod::{coarse_indices, mean_edge_length};

/// The interleaved vertex the mesh pass reads (40 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct MeshVertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
    pub color: [f32; 4],
}

/// Running totals since the store was created.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UploadStats {
    /// Chunks whose data was written to the GPU.
    pub chunk_uploads: u64,
    /// Bytes written (vertices plus indices).
    pub bytes_uploaded: u64,
    /// GPU buffers allocated (an upload that fits the old buffers allocates none).
    pub buffers_created: u64,
    /// Chunks dropped because they were absent from a sync.
    pub chunks_removed: u64,
    /// Coarse index lists built (see [`LevelOfDetail`]).
    pub coarse_builds: u64,
}

/// When a brick is drawn with its coarse index list: when its mean edge, at the brick's nearest
/// point to the eye, projects to fewer than `coarse_below_edge_px` pixels. The coarse list
/// clusters the brick's interior vertices on a grid of [`COARSE_CLUSTER_EDGES`] mean edges and
/// keeps its border (`super::lod`), so coarse and fine bricks meet without a crack.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelOfDetail {
    pub coarse_below_edge_px: f32,
}

/// The coarse grid's cell, in the brick's mean edge lengths.
pub const COARSE_CLUSTER_EDGES: f32 = 2.0;

/// A brick with fewer triangles than this gets no coarse list: its draw costs little either way.
pub const COARSE_MIN_TRIANGLES: usize = 256;

/// A coarse list is kept only when it has at most this share of the fine list's triangles.
const COARSE_MAX_SHARE: f32 = 0.7;

/// Where the eye is and how many pixels a unit length spans at unit distance: what
/// [`ChunkBuffers::draw`] needs to pick each brick's list.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DrawView {
    pub eye: [f32; 3],
    /// `viewport height / (2 tan(fov_y / 2))`.
    pub pixels_per_unit_at_unit_distance: f32,
}

/// What one [`ChunkBuffers::draw`] recorded.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DrawReport {
    /// Chunks drawn with their group's coarse index list.
    pub coarse_chunks: usize,
    /// Draw calls recorded (one per chunk, or per group of bricks with coarse lists).
    pub draw_calls: usize,
    /// Triangles the draw calls name (coarse lists counted at their own size).
    pub triangles: usize,
}

/// What one [`ChunkBuffers::sync`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SyncReport {
    pub uploaded: usize,
    pub removed: usize,
    /// Chunks held after the sync.
    pub resident: usize,
    /// Triangles that a frame will draw.
    pub triangles: usize,
}

struct GpuBuffers {
    vertex: wgpu::Buffer,
    index: wgpu::Buffer,
}

/// What the GPU holds for one slot: a single chunk, or (when coarse lists are built) a group of
/// neighbouring bricks drawn as one mesh (see [`group_key`]).
struct GpuSlot {
    /// The member chunks' ids and versions, sorted by id: the slot is re-uploaded when this
    /// changes.
    members: Vec<(u64, u64)>,
    /// The sync pass that last saw this slot.
    seen: u64,
    index_count: u32,
    buffers: Option<GpuBuffers>,
    /// The coarse index list (into the same vertices), when the store builds them and this
    /// slot is worth one.
    coarse: Option<CoarseList>,
}

struct CoarseList {
    index: wgpu::Buffer,
    index_count: u32,
    /// Centre and radius of the slot's vertices' bounding sphere.
    center: glam::Vec3,
    radius: f32,
    mean_edge: f32,
}

/// Bricks per group side, as a power of two, when coarse lists are built: 4 × 4 × 4 bricks.
const GROUP_SHIFT: u32 = 2;

/// The group of the brick whose id is [`super::brick_id`]`(coord)`: the coordinate divided by
/// 2^[`GROUP_SHIFT`] per axis. Groups are boxes of whole bricks, so the vertices where one
/// group meets another lie on its vertices' bounding box, which [`coarse_indices`] keeps.
#[must_use]
fn group_key(id: u64) -> u64 {
    let mask = (1u64 << 21) - 1;
    let axis = |k: u32| ((id >> (21 * k)) & mask) >> GROUP_SHIFT;
    axis(0) | (axis(1) << 21) | (axis(2) << 42)
}

/// The renderer's copy of the brick meshes on the GPU.
#[derive(Default)]
pub struct ChunkBuffers {
    slots: HashMap<u64, GpuSlot>,
    pass: u64,
    scratch: Vec<MeshVertex>,
    index_scratch: Vec<u32>,
    coarse_scratch: Vec<u32>,
    stats: UploadStats,
    /// Whether bricks are grouped and coarse index lists built.
    build_coarse: bool,
    /// Chunks held (members of every slot).
    chunk_count: usize,
}

/// Growth factor for a buffer that must be reallocated: room for the brick to grow a little
/// without reallocating on every stroke.
const GROWTH: f64 = 1.25;

impl ChunkBuffers {
    /// Drops every chunk's buffers (the totals stay): after a failed upload, whose buffers may
    /// be invalid, the next [`Self::sync`] uploads every chunk afresh.
    pub fn clear(&mut self) {
        self.slots.clear();
        self.chunk_count = 0;
    }

    /// Whether uploads from now on group neighbouring bricks (ids from [`super::brick_id`]) into
    /// one mesh of 4 × 4 × 4 bricks and build a coarse index list for each group, for
    /// [`Self::draw`] to use when the group is far. A change re-uploads every chunk at the next
    /// sync.
    pub fn set_build_coarse(&mut self, build: bool) {
        if build != self.build_coarse {
            self.build_coarse = build;
            self.clear();
        }
    }

    fn slot_key(&self, id: u64) -> u64 {
        if self.build_coarse { group_key(id) } else { id }
    }

    /// Makes the GPU copy match `chunks` exactly (the full set, not a delta).
    ///
    /// # Errors
    /// An id listed twice (found before anything is uploaded), or a chunk that fails
    /// [`MeshChunk::validate`]: slots before its own are already synced, and removal of absent
    /// chunks is skipped.
    pub fn sync(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        chunks: &[MeshChunk<'_>],
    ) -> Result<SyncReport, ChunkError> {
        self.pass += 1;
        let pass = self.pass;
        // Each slot's chunks, in id order.
        let mut order: Vec<usize> = (0..chunks.len()).collect();
        order.sort_unstable_by_key(|&i| (self.slot_key(chunks[i].id), chunks[i].id));
        for pair in order.windows(2) {
            if chunks[pair[0]].id == chunks[pair[1]].id {
                return Err(ChunkError::DuplicateId {
                    id: chunks[pair[0]].id,
                });
            }
        }
        let mut report = SyncReport::default();
        let mut members = Vec::new();
        // Chunks of this sync that were held before it, whatever their version.
        let mut still_held = 0;
        let mut start = 0;
        while start < order.len() {
            let key = self.slot_key(chunks[order[start]].id);
            let end = start
                + order[start..]
                    .iter()
                    .take_while(|&&i| self.slot_key(chunks[i].id) == key)
                    .count();
            let slot_chunks: Vec<&MeshChunk<'_>> =
                order[start..end].iter().map(|&i| &chunks[i]).collect();
            start = end;
            members.clear();
            members.extend(slot_chunks.iter().map(|c| (c.id, c.version)));
            if let Some(held) = self.slots.get_mut(&key) {
                held.seen = pass;
                still_held += members
                    .iter()
                    .filter(|(id, _)| {
                        held.members
                            .binary_search_by_key(id, |&(held_id, _)| held_id)
                            .is_ok()
                    })
                    .count();
                if held.members == members {
                    continue;
                }
            }
            for c in &slot_chunks {
                c.validate()?;
            }
            let changed = self.slots.get(&key).map_or(slot_chunks.len(), |held| {
                members
                    .iter()
                    .filter(|m| held.members.binary_search(m).is_err())
                    .count()
            });
            self.upload(device, queue, key, &slot_chunks, &members, pass);
            report.uploaded += changed;
            self.stats.chunk_uploads += changed as u64;
        }
        self.slots.retain(|_, s| s.seen == pass);
        report.removed = self.chunk_count - still_held;
        self.chunk_count = chunks.len();
        self.stats.chunks_removed += report.removed as u64;
        report.resident = self.chunk_count;
        report.triangles = self.triangle_count();
        Ok(report)
    }

    fn upload(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        key: u64,
        chunks: &[&MeshChunk<'_>],
        members: &[(u64, u64)],
        pass: u64,
    ) {
        let (old, old_coarse) = self
            .slots
            .remove(&key)
            .map_or((None, None), |s| (s.buffers, s.coarse));
        let mut slot = GpuSlot {
            members: members.to_vec(),
            seen: pass,
            index_count: 0,
            buffers: None,
            coarse: None,
        };
        self.scratch.clear();
        self.index_scratch.clear();
        for chunk in chunks {
            let base = u32::try_from(self.scratch.len()).unwrap_or(u32::MAX);
            self.scratch
                .extend((0..chunk.positions.len()).map(|i| MeshVertex {
                    position: chunk.positions[i],
                    normal: chunk.normals[i],
                    color: chunk.colors.get(i).copied().unwrap_or([0.0; 4]),
                }));
            self.index_scratch
                .extend(chunk.indices.iter().map(|&i| i + base));
        }
        if self.index_scratch.is_empty() {
            self.slots.insert(key, slot);
            return;
        }
        let vertex_bytes: &[u8] = bytemuck::cast_slice(&self.scratch);
        let index_bytes: &[u8] = bytemuck::cast_slice(&self.index_scratch);
        let (vertex_len, index_len) = (vertex_bytes.len(), index_bytes.len());
        let vertex = self.fit(
            device,
            old.as_ref().map(|b| &b.vertex),
            vertex_len,
            wgpu::BufferUsages::VERTEX,
            "mesh chunk vertices",
        );
        let index = self.fit(
            device,
            old.as_ref().map(|b| &b.index),
            index_len,
            wgpu::BufferUsages::INDEX,
            "mesh chunk indices",
        );
        queue.write_buffer(&vertex, 0, bytemuck::cast_slice(&self.scratch));
        queue.write_buffer(&index, 0, bytemuck::cast_slice(&self.index_scratch));
        self.stats.bytes_uploaded += (vertex_len + index_len) as u64;
        slot.index_count = u32::try_from(self.index_scratch.len()).unwrap_or(u32::MAX);
        slot.buffers = Some(GpuBuffers { vertex, index });
        // A cut piece's border with its neighbours is not on the box the clustering keeps.
        if self.build_coarse && chunks.iter().all(|c| !c.cut) {
            slot.coarse = self.upload_coarse(device, queue, old_coarse.map(|c| c.index));
        }
        self.slots.insert(key, slot);
    }

    /// Builds and uploads the coarse index list of the slot in the scratch buffers, or `None`
    /// when it is too small to gain from one or clustering removes too little.
    fn upload_coarse(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        old: Option<wgpu::Buffer>,
    ) -> Option<CoarseList> {
        let fine = self.index_scratch.len() / 3;
        if fine < COARSE_MIN_TRIANGLES {
            return None;
        }
        let positions: Vec<[f32; 3]> = self.scratch.iter().map(|v| v.position).collect();
        let normals: Vec<[f32; 3]> = self.scratch.iter().map(|v| v.normal).collect();
        let mean_edge = mean_edge_length(&positions, &self.index_scratch)?;
        let mut coarse = std::mem::take(&mut self.coarse_scratch);
        coarse_indices(
            &positions,
            &normals,
            &self.index_scratch,
            COARSE_CLUSTER_EDGES * mean_edge,
            &mut coarse,
        );
        self.stats.coarse_builds += 1;
        let kept = (coarse.len() / 3 <= (fine as f32 * COARSE_MAX_SHARE) as usize
            && !coarse.is_empty())
        .then(|| {
            let bytes: &[u8] = bytemuck::cast_slice(&coarse);
            let index = self.fit(
                device,
                old.as_ref(),
                bytes.len(),
                wgpu::BufferUsages::INDEX,
                "mesh chunk coarse indices",
            );
            queue.write_buffer(&index, 0, bytes);
            self.stats.bytes_uploaded += bytes.len() as u64;
            let (lo, hi) = positions.iter().fold(
                (glam::Vec3::splat(f32::MAX), glam::Vec3::splat(f32::MIN)),
                |(lo, hi), &p| (lo.min(p.into()), hi.max(p.into())),
            );
            CoarseList {
                index,
                index_count: u32::try_from(coarse.len()).unwrap_or(u32::MAX),
                center: 0.5 * (lo + hi),
                radius: 0.5 * lo.distance(hi),
                mean_edge,
            }
        });
        self.coarse_scratch = coarse;
        kept
    }

    /// Reuses `old` when it holds `len` bytes, else allocates a buffer with some headroom.
    fn fit(
        &mut self,
        device: &wgpu::Device,
        old: Option<&wgpu::Buffer>,
        len: usize,
        usage: wgpu::BufferUsages,
        label: &str,
    ) -> wgpu::Buffer {
        if let Some(b) = old
            && b.size() >= len as u64
        {
            return b.clone();
        }
        self.stats.buffers_created += 1;
        // Sizes stay multiples of 4, as buffer writes require.
        let size = ((len as f64 * GROWTH) as u64)
            .max(len as u64)
            .next_multiple_of(4)
            .max(4);
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: usage | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// Records one indexed draw per non-empty slot into `pass`: with its coarse index list
    /// where `lod` says the slot's edges are too small on screen to matter (seen from `view`),
    /// with every triangle otherwise.
    pub fn draw<'a>(
        &'a self,
        pass: &mut wgpu::RenderPass<'a>,
        view: &DrawView,
        lod: Option<LevelOfDetail>,
    ) -> DrawReport {
        let mut report = DrawReport::default();
        for slot in self.slots.values() {
            let Some(b) = &slot.buffers else { continue };
            pass.set_vertex_buffer(0, b.vertex.slice(..));
            match (lod, &slot.coarse) {
                (Some(lod), Some(coarse)) if coarse.edge_px(view) < lod.coarse_below_edge_px => {
                    pass.set_index_buffer(coarse.index.slice(..), wgpu::IndexFormat::Uint32);
                    pass.draw_indexed(0..coarse.index_count, 0, 0..1);
                    report.coarse_chunks += slot.members.len();
                    report.triangles += coarse.index_count as usize / 3;
                }
                _ => {
                    pass.set_index_buffer(b.index.slice(..), wgpu::IndexFormat::Uint32);
                    pass.draw_indexed(0..slot.index_count, 0, 0..1);
                    report.triangles += slot.index_count as usize / 3;
                }
            }
            report.draw_calls += 1;
        }
        report
    }

    /// Totals since creation.
    #[must_use]
    pub fn stats(&self) -> UploadStats {
        self.stats
    }

    /// Chunks currently held.
    #[must_use]
    pub fn len(&self) -> usize {
        self.chunk_count
    }

    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.chunk_count == 0
    }

    /// Triangles currently held.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.slots
            .values()
            .map(|c| c.index_count as usize / 3)
            .sum()
    }
}

impl CoarseList {
    /// The brick's mean edge in pixels at its nearest point to the eye (its bounding sphere's).
    fn edge_px(&self, view: &DrawView) -> f32 {
        let distance =
            (glam::Vec3::from(view.eye).distance(self.center) - self.radius).max(self.mean_edge);
        self.mean_edge * view.pixels_per_unit_at_unit_distance / distance
    }
}
