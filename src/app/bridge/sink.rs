//! The graphics loop's mesh sink for the window ([`GuiMeshSink`]) and the export of its
//! published bricks as one welded mesh.

use super::*;

/// Publishes the graphics loop's brick meshes, painted, to the app.
pub struct GuiMeshSink {
    meshes: SnapshotWriter<MeshSet>,
    bricks: HashMap<[u32; 3], Arc<ChunkMesh>>,
    set: MeshSet,
    /// The latest set, for exports by the bridge thread (held only to clone the `Arc`s).
    exports: SnapshotWriter<MeshSet>,
    repaint: RepaintSignal,
    /// The clay's paint, as last handed over by the graphics stage.
    colour: Option<ColourField>,
    /// The clay's freeze mask, as last handed over by the graphics stage (drawn as a tint).
    mask: Option<FreezeMask>,
    /// The clay, for the app's pointer picking.
    field: SnapshotWriter<MultiPatchField>,
    /// Version for the next chunk made: the renderer re-uploads a chunk whose version
    /// changed, and a recoloured brick keeps its octree version, so the sink numbers chunks.
    next_version: u64,
}

impl GuiMeshSink {
    /// A sink publishing on `meshes` (and on `exports` for the bridge thread's exports), unpainted until the
    /// graphics stage hands it paint. (Public for the motion-to-photon benchmark, which draws
    /// the window's meshes offscreen.)
    #[must_use]
    pub fn new(
        meshes: SnapshotWriter<MeshSet>,
        field: SnapshotWriter<MultiPatchField>,
        exports: SnapshotWriter<MeshSet>,
        repaint: RepaintSignal,
    ) -> Self {
        Self {
            field,
            meshes,
            bricks: HashMap::new(),
            set: MeshSet::new(),
            exports,
            repaint,
            colour: None,
            mask: None,
            next_version: 0,
        }
    }

    fn chunk(&mut self, coord: [u32; 3], mesh: &crate::mesh::BrickMesh) -> Arc<ChunkMesh> {
        let colors = surface_colors(mesh, self.colour.as_ref(), self.mask.as_ref());
        self.next_version += 1;
        Arc::new(ChunkMesh::from_brick(
            coord,
            self.next_version,
            mesh,
            colors,
        ))
    }

    /// Recolours every brick whose colours (paint under the mask's tint) changed; the others
    /// keep their chunk, so the renderer uploads only those.
    fn recolour(&mut self, octree: &BrickOctree) {
        let coords: Vec<[u32; 3]> = self.bricks.keys().copied().collect();
        for c in coords {
            let Some(b) = octree.brick(c) else { continue };
            let colors = surface_colors(&b.mesh, self.colour.as_ref(), self.mask.as_ref());
            if self
                .bricks
                .get(&c)
                .is_some_and(|held| held.colors == colors)
            {
                continue;
            }
            self.next_version += 1;
            let chunk = ChunkMesh::from_brick(c, self.next_version, &b.mesh, colors);
            self.bricks.insert(c, Arc::new(chunk));
        }
        self.publish();
    }

    fn publish(&mut self) {
        self.set.clear();
        self.set.extend(self.bricks.values().cloned());
        self.meshes.publish_clone_of(&self.set);
        self.exports.publish_clone_of(&self.set);
        self.repaint.request();
    }
}

impl MeshSink for GuiMeshSink {
    fn update(&mut self, octree: &BrickOctree, report: &RefreshReport) {
        for c in &report.removed {
            self.bricks.remove(c);
        }
        for c in &report.changed {
            match octree.brick(*c) {
                Some(b) if !b.mesh.indices.is_empty() => {
                    let chunk = self.chunk(*c, &b.mesh);
                    self.bricks.insert(*c, chunk);
                }
                _ => {
                    self.bricks.remove(c);
                }
            }
        }
        self.publish();
    }

    /// Recolours every brick whose paint changed (the others keep their chunk, so the
    /// renderer uploads only the repainted ones).
    fn paint(&mut self, octree: &BrickOctree, colour: Option<&ColourField>) {
        self.colour = colour.cloned();
        self.recolour(octree);
    }

    /// Re-tints every brick whose mask changed, like [`Self::paint`] (a mask that holds
    /// nothing is no mask: no brick is tinted or evaluated).
    fn mask(&mut self, octree: &BrickOctree, mask: Option<&FreezeMask>) {
        self.mask = mask.filter(|m| m.any()).cloned();
        self.recolour(octree);
    }

    fn field(&mut self, field: &MultiPatchField) {
        self.field.publish_clone_of(field);
    }

    /// The engine restarts on another clay: its bricks go, and the app sees no meshes until
    /// the new graphics loop publishes its own.
    fn restart(&mut self) {
        self.bricks.clear();
        self.colour = None;
        self.mask = None;
        self.publish();
    }
}

/// Why [`export_chunks`] wrote nothing.
#[derive(Debug, thiserror::Error)]
pub enum ChunkExportError {
    /// The path's extension names no mesh format.
    #[error("{}: unknown mesh format (use .obj, .ply or .stl)", path.display())]
    UnknownFormat {
        /// The path asked for.
        path: PathBuf,
    },
    /// A chunk is not a consistent brick mesh (attributes, indices or edge ids).
    #[error("{}: {source}", path.display())]
    Chunk {
        /// The path asked for.
        path: PathBuf,
        /// What is wrong with the chunk.
        source: ChunkError,
    },
    /// Writing the file failed (the error names the path).
    #[error(transparent)]
    Write(#[from] ExportError),
}

/// Welds the chunks with the mesher's own welding ([`weld_pieces`]: vertices on shared brick
/// faces are merged by edge id), cuts the sheets that share an edge apart
/// ([`split_non_manifold`]: a clay with detail patches is drawn by dual contouring, whose
/// one vertex per leaf joins two sheets through an ambiguous leaf face with an edge of four
/// triangles) and writes them in the format named by `path`'s extension; returns the triangle
/// count. So the window's export is closed, oriented and edge-manifold, as a run's is.
/// Chunks are welded in id order, so the same set always writes the same file.
///
/// # Errors
/// An unknown extension, an inconsistent chunk or the writer's error, naming the path.
pub fn export_chunks(set: &MeshSet, path: &Path) -> Result<usize, ChunkExportError> {
    let format = MeshFormat::from_path(path).ok_or_else(|| ChunkExportError::UnknownFormat {
        path: path.to_path_buf(),
    })?;
    let mut chunks: Vec<&ChunkMesh> = set.iter().map(|c| &**c).collect();
    chunks.sort_by_key(|c| c.id);
    let bad = |source| ChunkExportError::Chunk {
        path: path.to_path_buf(),
        source,
    };
    for c in &chunks {
        c.as_chunk().validate().map_err(bad)?;
        if c.edge_ids.len() != c.positions.len() {
            return Err(bad(ChunkError::AttributeLength {
                id: c.id,
                attribute: "edge_ids",
                expected: c.positions.len(),
                got: c.edge_ids.len(),
            }));
        }
    }
    let pieces: Vec<WeldPiece<'_, [f32; 3]>> = chunks
        .iter()
        .map(|c| WeldPiece {
            positions: &c.positions,
            normals: &c.normals,
            edge_ids: &c.edge_ids,
            indices: &c.indices,
        })
        .collect();
    let mut mesh = weld_pieces(&pieces);
    split_non_manifold(&mut mesh);
    write_mesh(path, &mesh, format)?;
    Ok(mesh.triangles.len())
}
