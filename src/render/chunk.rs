//! The renderer's input: one triangle mesh per octree brick, borrowed from its owner.
//!
//! A [`MeshChunk`] is a view, not a copy: the engine keeps its brick meshes and hands the
//! renderer slices of them. The renderer reads a chunk's data only when its `version` changed
//! since the last upload, so handing over every chunk every frame costs one map lookup each.

/// One brick's triangle mesh, as slices borrowed from the mesher's output.
///
/// Positions and normals are in world units (the field lattice's coordinates). `colors` holds
/// the paint per vertex as linear RGBA, where alpha is the paint's coverage: the shaded albedo is
/// `mix(material colour, rgb, a)`, so unpainted clay is `[0, 0, 0, 0]`. An empty `colors`
/// slice means the whole chunk is unpainted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MeshChunk<'a> {
    /// Stable identity of the brick (for example its octree key).
    pub id: u64,
    /// Bumped by the owner whenever the brick's mesh changes.
    pub version: u64,
    pub positions: &'a [[f32; 3]],
    pub normals: &'a [[f32; 3]],
    pub colors: &'a [[f32; 4]],
    /// Triangle list: three vertex indices per triangle, counter-clockwise seen from outside.
    pub indices: &'a [u32],
    /// A piece of a mesh cut along brick bounds (a clay with detail patches, see
    /// `dynaclay_core::mesh::AdaptiveBricks`), not the marching cubes of its brick: where it
    /// meets its neighbours is not on its vertices' bounding box, so the far bricks' coarse
    /// index lists ([`super::coarse_indices`], which keep that box) are not built for it.
    pub cut: bool,
}

/// Why a chunk cannot be drawn.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum ChunkError {
    /// `normals` (or non-empty `colors`) does not have one entry per position.
    #[error(
        "mesh chunk {id}: {attribute} has {got} entries, expected {expected} (one per position)"
    )]
    AttributeLength {
        id: u64,
        attribute: &'static str,
        expected: usize,
        got: usize,
    },
    /// The index count is not a multiple of three.
    #[error("mesh chunk {id}: {index_count} indices is not a whole number of triangles")]
    PartialTriangle { id: u64, index_count: usize },
    /// An index points past the last vertex.
    #[error(
        "mesh chunk {id}: index {index} at position {at} is out of range ({vertex_count} vertices)"
    )]
    IndexOutOfRange {
        id: u64,
        at: usize,
        index: u32,
        vertex_count: usize,
    },
    /// The same id appears twice in one set of chunks.
    #[error("mesh chunk id {id} appears more than once in one frame")]
    DuplicateId { id: u64 },
}

impl MeshChunk<'_> {
    /// Number of triangles in the chunk.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// Checks that the slices describe a drawable triangle list.
    ///
    /// # Errors
    /// Returns the first inconsistency found: an attribute of the wrong length, a partial
    /// triangle, or an index past the last vertex.
    pub fn validate(&self) -> Result<(), ChunkError> {
        let n = self.positions.len();
        if self.normals.len() != n {
            return Err(ChunkError::AttributeLength {
                id: self.id,
                attribute: "normals",
                expected: n,
                got: self.normals.len(),
            });
        }
        if !self.colors.is_empty() && self.colors.len() != n {
            return Err(ChunkError::AttributeLength {
                id: self.id,
                attribute: "colors",
                expected: n,
                got: self.colors.len(),
            });
        }
        if !self.indices.len().is_multiple_of(3) {
            return Err(ChunkError::PartialTriangle {
                id: self.id,
                index_count: self.indices.len(),
            });
        }
        if let Some((at, &index)) = self
            .indices
            .iter()
            .enumerate()
            .find(|&(_, &i)| i as usize >= n)
        {
            return Err(ChunkError::IndexOutOfRange {
                id: self.id,
                at,
                index,
                vertex_count: n,
            });
        }
        Ok(())
    }

    /// Axis-aligned bounds of the positions, or `None` for an empty chunk.
    #[must_use]
    pub fn bounds(&self) -> Option<(glam::Vec3, glam::Vec3)> {
        bounds_of(std::slice::from_ref(self))
    }
}

/// Axis-aligned bounds of every position in `chunks`, or `None` when there are none.
#[must_use]
pub fn bounds_of(chunks: &[MeshChunk<'_>]) -> Option<(glam::Vec3, glam::Vec3)> {
    let mut points = chunks
        .iter()
        .flat_map(|c| c.positions.iter())
        .map(|&p| glam::Vec3::from(p));
    let first = points.next()?;
    Some(points.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
}

#[cfg(test)]
mod tests {
    use super::*;

    const P: [[f32; 3]; 3] = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 2.0, -1.0]];
    const N: [[f32; 3]; 3] = [[0.0, 0.0, 1.0]; 3];

    fn chunk<'a>(indices: &'a [u32], colors: &'a [[f32; 4]]) -> MeshChunk<'a> {
        MeshChunk {
            id: 7,
            version: 1,
            positions: &P,
            normals: &N,
            colors,
            indices,
            cut: false,
        }
    }

    #[test]
    fn valid_chunk_passes_and_reports_bounds() {
        let c = chunk(&[0, 1, 2], &[]);
        assert_eq!(c.validate(), Ok(()));
        assert_eq!(c.triangle_count(), 1);
        let (lo, hi) = c.bounds().unwrap();
        assert_eq!(lo, glam::Vec3::new(0.0, 0.0, -1.0));
        assert_eq!(hi, glam::Vec3::new(1.0, 2.0, 0.0));
    }

    #[test]
    fn inconsistent_chunks_are_rejected_with_their_cause() {
        assert!(matches!(
            chunk(&[0, 1], &[]).validate(),
            Err(ChunkError::PartialTriangle {
                id: 7,
                index_count: 2
            })
        ));
        let err = chunk(&[0, 1, 3], &[]).validate().unwrap_err();
        assert_eq!(
            err,
            ChunkError::IndexOutOfRange {
                id: 7,
                at: 2,
                index: 3,
                vertex_count: 3
            }
        );
        assert!(err.to_string().contains("index 3"));
        let colors = [[1.0; 4]; 2];
        assert!(matches!(
            chunk(&[0, 1, 2], &colors).validate(),
            Err(ChunkError::AttributeLength {
                attribute: "colors",
                ..
            })
        ));
    }

    #[test]
    fn bounds_of_nothing_is_none() {
        assert_eq!(bounds_of(&[]), None);
    }
}
