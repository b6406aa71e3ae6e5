//! Per-brick GPU vertex and index buffers, re-uploaded only when a brick's version changes.
//!
//! [`ChunkBuffers::sync`] takes the full current set of chunks: new or changed chunks are
//! uploaded (into their existing buffers when those are large enough), unchanged ones cost a
//! map lookup, and chunks no longer present are dropped. Counters record every upload so the
//! "only dirty bricks" promise is testable.

use std::collections::HashMap;

use super::chunk::{ChunkError, MeshChunk};

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

struct GpuChunk {
    version: u64,
    /// The sync pass that last saw this chunk.
    seen: u64,
    index_count: u32,
    buffers: Option<GpuBuffers>,
}

/// The renderer's copy of the brick meshes on the GPU.
#[derive(Default)]
pub struct ChunkBuffers {
    chunks: HashMap<u64, GpuChunk>,
    pass: u64,
    scratch: Vec<MeshVertex>,
    stats: UploadStats,
}

/// Growth factor for a buffer that must be reallocated: room for the brick to grow a little
/// without reallocating on every stroke.
const GROWTH: f64 = 1.25;

impl ChunkBuffers {
    /// Drops every chunk's buffers (the totals stay): after a failed upload, whose buffers may
    /// be invalid, the next [`Self::sync`] uploads every chunk afresh.
    pub fn clear(&mut self) {
        self.chunks.clear();
    }

    /// Makes the GPU copy match `chunks` exactly (the full set, not a delta).
    ///
    /// # Errors
    /// A chunk that fails [`MeshChunk::validate`], or an id listed twice. Chunks before it in
    /// the slice are already synced; removal of absent chunks is skipped.
    pub fn sync(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        chunks: &[MeshChunk<'_>],
    ) -> Result<SyncReport, ChunkError> {
        self.pass += 1;
        let pass = self.pass;
        let mut report = SyncReport::default();
        for chunk in chunks {
            if let Some(held) = self.chunks.get_mut(&chunk.id) {
                if held.seen == pass {
                    return Err(ChunkError::DuplicateId { id: chunk.id });
                }
                held.seen = pass;
                if held.version == chunk.version {
                    continue;
                }
            }
            chunk.validate()?;
            self.upload(device, queue, chunk, pass);
            report.uploaded += 1;
        }
        let before = self.chunks.len();
        self.chunks.retain(|_, c| c.seen == pass);
        report.removed = before - self.chunks.len();
        self.stats.chunks_removed += report.removed as u64;
        report.resident = self.chunks.len();
        report.triangles = self.triangle_count();
        Ok(report)
    }

    fn upload(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        chunk: &MeshChunk<'_>,
        pass: u64,
    ) {
        let old = self.chunks.remove(&chunk.id).and_then(|c| c.buffers);
        self.stats.chunk_uploads += 1;
        if chunk.indices.is_empty() {
            self.chunks.insert(
                chunk.id,
                GpuChunk {
                    version: chunk.version,
                    seen: pass,
                    index_count: 0,
                    buffers: None,
                },
            );
            return;
        }
        self.scratch.clear();
        self.scratch
            .extend((0..chunk.positions.len()).map(|i| MeshVertex {
                position: chunk.positions[i],
                normal: chunk.normals[i],
                color: chunk.colors.get(i).copied().unwrap_or([0.0; 4]),
            }));
        let vertex_len = self.scratch.len() * size_of::<MeshVertex>();
        let index_bytes: &[u8] = bytemuck::cast_slice(chunk.indices);
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
            index_bytes.len(),
            wgpu::BufferUsages::INDEX,
            "mesh chunk indices",
        );
        let vertex_bytes: &[u8] = bytemuck::cast_slice(&self.scratch);
        queue.write_buffer(&vertex, 0, vertex_bytes);
        queue.write_buffer(&index, 0, index_bytes);
        self.stats.bytes_uploaded += (vertex_bytes.len() + index_bytes.len()) as u64;
        self.chunks.insert(
            chunk.id,
            GpuChunk {
                version: chunk.version,
                seen: pass,
                index_count: u32::try_from(chunk.indices.len()).unwrap_or(u32::MAX),
                buffers: Some(GpuBuffers { vertex, index }),
            },
        );
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

    /// Records one indexed draw per non-empty chunk into `pass`.
    pub fn draw<'a>(&'a self, pass: &mut wgpu::RenderPass<'a>) {
        for chunk in self.chunks.values() {
            if let Some(b) = &chunk.buffers {
                pass.set_vertex_buffer(0, b.vertex.slice(..));
                pass.set_index_buffer(b.index.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..chunk.index_count, 0, 0..1);
            }
        }
    }

    /// Totals since creation.
    #[must_use]
    pub fn stats(&self) -> UploadStats {
        self.stats
    }

    /// Chunks currently held.
    #[must_use]
    pub fn len(&self) -> usize {
        self.chunks.len()
    }

    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.chunks.is_empty()
    }

    /// Triangles currently held.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.chunks
            .values()
            .map(|c| c.index_count as usize / 3)
            .sum()
    }
}
