//! The bridge from the mesher to the renderer: octree bricks become [`MeshChunk`]s, with the
//! paint of the clay's colour field sampled at every vertex, and the freeze mask laid over it
//! as a dark tint.
//!
//! The mask's tint goes through the paint's own per-vertex colour: the shaders take
//! `mix(clay, rgb, a)` as the albedo, and a tint of opacity `k` composited over paint `(p, a)`
//! is again such a colour, `a' = k + a(1 − k)`, `rgb' = (k·T + a(1 − k)·p) / a'`; so the
//! masked clay is drawn darker by exactly `mix(albedo, T, k)` with no extra attribute or shader
//! work on either render profile.
//!
//! One owned [`ChunkMesh`] per brick, keyed by a stable [`brick_id`] and versioned by the
//! octree generation that last rebuilt it, so a renderer re-uploads only bricks that changed.
//! The offscreen commands (`dynaclay render`, `dynaclay run --png`) and the interactive app
//! use the same conversion. Not real-time: it allocates one copy of each brick's mesh.

use crate::mesh::{Brick, BrickMesh, BrickOctree};
use crate::tools::{ColourField, FreezeMask};

use super::chunk::MeshChunk;

/// Paint coverage below which a vertex counts as unpainted; a brick whose vertices are all
/// below it is handed over without colours (the renderer then skips the attribute).
pub const MIN_PAINT_COVERAGE: f32 = 1.0 / 512.0;

/// The colour masked clay is tinted toward (linear RGB): a dark slate, so masked clay reads
/// as darker and a little cool under any paint, as sculpting apps draw their masks.
pub const MASK_TINT_RGB: [f32; 3] = [0.05, 0.06, 0.09];

/// How far fully masked clay is tinted toward [`MASK_TINT_RGB`] (a hold `m` tints by `m`
/// times this): dark enough to see at a glance, light enough that the shape stays readable.
pub const MASK_TINT_OPACITY: f32 = 0.6;

/// A brick coordinate packed into a stable chunk id: 21 bits per axis, x lowest.
///
/// Distinct for every coordinate below 2²¹ per axis (an octree of 8-cell bricks never comes
/// near that).
#[must_use]
pub fn brick_id(coord: [u32; 3]) -> u64 {
    let m = (1u64 << 21) - 1;
    (u64::from(coord[0]) & m)
        | ((u64::from(coord[1]) & m) << 21)
        | ((u64::from(coord[2]) & m) << 42)
}

/// One brick's mesh, owned, in the renderer's vertex layout.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ChunkMesh {
    /// Stable brick identity ([`brick_id`]).
    pub id: u64,
    /// The octree generation of the brick's last rebuild: changes whenever the mesh does.
    pub version: u64,
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    /// Paint per vertex, linear RGBA with coverage in alpha; empty when unpainted.
    pub colors: Vec<[f32; 4]>,
    pub indices: Vec<u32>,
    /// Global edge id of each vertex ([`crate::mesh::edge_id`]): the key that welds chunks
    /// ([`crate::mesh::weld_pieces`]).
    pub edge_ids: Vec<u64>,
}

impl ChunkMesh {
    /// Copies a brick's mesh; `colors` is the per-vertex paint (see [`paint_colors`]) or
    /// empty.
    #[must_use]
    pub fn from_brick(
        coord: [u32; 3],
        version: u64,
        mesh: &BrickMesh,
        colors: Vec<[f32; 4]>,
    ) -> Self {
        Self {
            id: brick_id(coord),
            version,
            positions: mesh.positions.iter().map(|p| p.to_array()).collect(),
            normals: mesh.normals.iter().map(|n| n.to_array()).collect(),
            colors,
            indices: mesh.indices.clone(),
            edge_ids: mesh.edge_ids.clone(),
        }
    }

    /// Copies an octree brick, painting it from `colour` when the clay has a colour field.
    #[must_use]
    pub fn from_octree_brick(brick: &Brick, colour: Option<&ColourField>) -> Self {
        let colors = colour.map_or_else(Vec::new, |c| paint_colors(&brick.mesh, c));
        Self::from_brick(brick.coord, brick.version, &brick.mesh, colors)
    }

    /// Whether this is a piece of a cut multi-level mesh: its vertices carry shared vertex
    /// ids ([`crate::mesh::shared_vertex_id`]) rather than grid edge ids.
    #[must_use]
    pub fn is_cut(&self) -> bool {
        self.edge_ids
            .first()
            .is_some_and(|&id| crate::mesh::edge_from_id(id).1 == crate::mesh::SHARED_VERTEX_AXIS)
    }

    /// A borrowed view for the renderer.
    #[must_use]
    pub fn as_chunk(&self) -> MeshChunk<'_> {
        MeshChunk {
            id: self.id,
            version: self.version,
            positions: &self.positions,
            normals: &self.normals,
            colors: &self.colors,
            indices: &self.indices,
            cut: self.is_cut(),
        }
    }
}

/// The paint at each vertex of `mesh`, as linear RGBA with coverage in alpha, or an empty
/// vector when no vertex carries coverage of at least [`MIN_PAINT_COVERAGE`].
#[must_use]
pub fn paint_colors(mesh: &BrickMesh, colour: &ColourField) -> Vec<[f32; 4]> {
    let colors: Vec<[f32; 4]> = mesh
        .positions
        .iter()
        .map(|&p| colour.rgba(p).to_array())
        .collect();
    if colors.iter().any(|c| c[3] >= MIN_PAINT_COVERAGE) {
        colors
    } else {
        Vec::new()
    }
}

/// `paint` (linear RGBA, coverage in alpha) with the mask's tint for a hold of `hold`
/// composited over it (see the module's note).
#[must_use]
pub fn tinted(paint: [f32; 4], hold: f32) -> [f32; 4] {
    let k = MASK_TINT_OPACITY * hold.clamp(0.0, 1.0);
    let a = paint[3].clamp(0.0, 1.0);
    let alpha = k + a * (1.0 - k);
    if alpha <= 0.0 {
        return paint;
    }
    let under = a * (1.0 - k);
    let mix = |c: usize| (k * MASK_TINT_RGB[c] + under * paint[c]) / alpha;
    [mix(0), mix(1), mix(2), alpha]
}

/// The colour of each vertex of `mesh`: the paint of `colour` ([`paint_colors`]) with the
/// tint of `mask` over it ([`tinted`]); empty when neither leaves a vertex coloured (the
/// renderer then skips the attribute). A mask costs one evaluation per vertex: a caller with
/// a mask that holds nothing passes `None`.
#[must_use]
pub fn surface_colors(
    mesh: &BrickMesh,
    colour: Option<&ColourField>,
    mask: Option<&FreezeMask>,
) -> Vec<[f32; 4]> {
    let paint = colour.map_or_else(Vec::new, |c| paint_colors(mesh, c));
    let Some(mask) = mask else {
        return paint;
    };
    let colors: Vec<[f32; 4]> = mesh
        .positions
        .iter()
        .enumerate()
        .map(|(i, &p)| {
            let under = paint.get(i).copied().unwrap_or([0.0; 4]);
            tinted(under, mask.value_at(p))
        })
        .collect();
    if colors.iter().any(|c| c[3] >= MIN_PAINT_COVERAGE) {
        colors
    } else {
        Vec::new()
    }
}

/// Every brick of `octree` as a chunk, in the octree's (Morton) order.
#[must_use]
pub fn octree_chunks(octree: &BrickOctree, colour: Option<&ColourField>) -> Vec<ChunkMesh> {
    octree
        .bricks()
        .map(|b| ChunkMesh::from_octree_brick(b, colour))
        .collect()
}

/// Borrowed views of `chunks`, for [`super::render_to_png`] or a renderer's `sync_chunks`.
#[must_use]
pub fn chunk_views(chunks: &[ChunkMesh]) -> Vec<MeshChunk<'_>> {
    chunks.iter().map(ChunkMesh::as_chunk).collect()
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::field::BSplineLattice;
    use crate::mesh::SampleGrid;

    /// Level set 0.5 of a clamped distance ramp: a ball of radius 0.6 around (1, 1, 1).
    fn ball() -> BSplineLattice {
        let mut lattice = BSplineLattice::zeros([12; 3], 0.2, Vec3::ZERO).unwrap();
        for k in 0..12 {
            for j in 0..12 {
                for i in 0..12 {
                    let d = (lattice.node_position(i, j, k) - Vec3::ONE).length() - 0.6;
                    let n = lattice.index(i, j, k);
                    lattice.coeffs.set_flat(n, (0.5 - d / 0.6).clamp(0.0, 1.0));
                }
            }
        }
        lattice
    }

    #[test]
    fn brick_ids_are_distinct_per_axis() {
        let ids = [[1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, 0], [5, 9, 1]].map(brick_id);
        for (i, a) in ids.iter().enumerate() {
            for b in &ids[i + 1..] {
                assert_ne!(a, b);
            }
        }
    }

    /// A piece of a cut multi-level mesh is marked cut (no coarse list is built for it); a
    /// marching-cubes brick is not.
    #[test]
    fn pieces_of_a_cut_mesh_are_marked_and_marching_cubes_bricks_are_not() {
        let lattice = ball();
        let octree = BrickOctree::build(SampleGrid::for_lattice(&lattice, 4).unwrap(), &lattice);
        let brick = octree.bricks().next().expect("the ball has bricks");
        let marched = ChunkMesh::from_octree_brick(brick, None);
        assert!(!marched.is_cut() && !marched.as_chunk().cut);
        let mut piece = brick.mesh.clone();
        for (n, id) in piece.edge_ids.iter_mut().enumerate() {
            *id = crate::mesh::shared_vertex_id(n as u32);
        }
        let cut = ChunkMesh::from_brick(brick.coord, 1, &piece, Vec::new());
        assert!(cut.is_cut() && cut.as_chunk().cut);
    }

    #[test]
    fn octree_bricks_become_valid_chunks_with_their_versions() {
        let lattice = ball();
        let octree = BrickOctree::build(SampleGrid::for_lattice(&lattice, 4).unwrap(), &lattice);
        let chunks = octree_chunks(&octree, None);
        assert_eq!(chunks.len(), octree.brick_count());
        let views = chunk_views(&chunks);
        let mut ids = std::collections::HashSet::new();
        for (chunk, brick) in views.iter().zip(octree.bricks()) {
            assert_eq!(chunk.validate(), Ok(()));
            assert!(ids.insert(chunk.id), "duplicate id");
            assert_eq!(chunk.id, brick_id(brick.coord));
            assert_eq!(chunk.version, brick.version);
            assert!(chunk.colors.is_empty());
        }
        let triangles: usize = views.iter().map(MeshChunk::triangle_count).sum();
        assert_eq!(triangles, octree.triangle_count());
        let (lo, hi) = super::super::bounds_of(&views).unwrap();
        assert!((lo - Vec3::splat(0.4)).abs().max_element() < 0.05, "{lo}");
        assert!((hi - Vec3::splat(1.6)).abs().max_element() < 0.05, "{hi}");
    }

    /// The renderer's software profile culls back faces: every triangle the mesher makes must
    /// be counter-clockwise seen from outside (its geometric normal along its vertex normals).
    #[test]
    fn octree_triangles_wind_counter_clockwise_seen_from_outside() {
        let lattice = ball();
        let octree = BrickOctree::build(SampleGrid::for_lattice(&lattice, 4).unwrap(), &lattice);
        let (mut outward, mut inward) = (0, 0);
        for chunk in octree_chunks(&octree, None) {
            for tri in chunk.indices.chunks_exact(3) {
                let [a, b, c] = [0, 1, 2].map(|k| Vec3::from(chunk.positions[tri[k] as usize]));
                let n: Vec3 = [0, 1, 2]
                    .map(|k| Vec3::from(chunk.normals[tri[k] as usize]))
                    .into_iter()
                    .sum();
                let geometric = (b - a).cross(c - a);
                if geometric.length_squared() < 1e-14 {
                    continue;
                }
                if geometric.dot(n) > 0.0 {
                    outward += 1;
                } else {
                    inward += 1;
                }
                // And outward from the ball's centre.
                assert!(geometric.dot((a + b + c) / 3.0 - Vec3::ONE) > 0.0);
            }
        }
        assert!(outward > 500, "{outward} triangles");
        assert_eq!(inward, 0, "{inward} of {} wound inward", outward + inward);
    }

    #[test]
    fn paint_is_sampled_per_vertex_and_unpainted_bricks_carry_no_colours() {
        let lattice = ball();
        let octree = BrickOctree::build(SampleGrid::for_lattice(&lattice, 4).unwrap(), &lattice);
        // Paint the +x half red with full coverage.
        let mut colour = ColourField::matching(&lattice).unwrap();
        for k in 0..12 {
            for j in 0..12 {
                for i in 6..12 {
                    let n = lattice.index(i, j, k);
                    colour.channels[0].coeffs.set_flat(n, 1.0);
                    colour.channels[3].coeffs.set_flat(n, 1.0);
                }
            }
        }
        let chunks = octree_chunks(&octree, Some(&colour));
        let (mut painted, mut bare) = (0, 0);
        for c in &chunks {
            assert_eq!(c.as_chunk().validate(), Ok(()));
            if c.colors.is_empty() {
                bare += 1;
                assert!(c.positions.iter().all(|p| p[0] < 1.0), "bare brick on +x");
                continue;
            }
            painted += 1;
            for (p, rgba) in c.positions.iter().zip(&c.colors) {
                let expect = colour.rgba(Vec3::from(*p)).to_array();
                assert_eq!(*rgba, expect);
                if p[0] > 1.4 {
                    assert!(rgba[0] > 0.99 && rgba[3] > 0.99, "{p:?}: {rgba:?}");
                    assert!(rgba[1] < 0.01, "{p:?}: {rgba:?}");
                }
            }
        }
        assert!(painted > 0 && bare > 0, "painted {painted}, bare {bare}");
    }
}
