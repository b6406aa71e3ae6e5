//! What the graphics loop hands its meshes to: the interface the GUI's renderer bridge, the
//! headless counter, the particle and point-set followers implement. It lives here, below the
//! engine, so the model modules that implement it never reach up into the engine.

use super::{BrickOctree, RefreshReport};
use crate::field::MultiPatchField;
use crate::tools::{ColourField, FreezeMask};

/// Receives the meshes after every update. Implemented by the GUI's renderer bridge and by
/// the engine's headless sink.
pub trait MeshSink: Send {
    /// Called once the octree was refreshed; `report` lists the bricks that changed.
    fn update(&mut self, octree: &BrickOctree, report: &RefreshReport);

    /// Called when the clay's paint changed (`None`: unpainted); the meshes did not. A sink
    /// that shows colour recolours its meshes; the default ignores paint.
    fn paint(&mut self, _octree: &BrickOctree, _colour: Option<&ColourField>) {}

    /// Called when the clay's freeze mask changed (`None`: no mask); the meshes did not. A
    /// sink that shows the mask re-tints its meshes; the default ignores it.
    fn mask(&mut self, _octree: &BrickOctree, _mask: Option<&FreezeMask>) {}

    /// Called with the graphics loop's field copy after each applied patch (and once at the
    /// start); a sink that picks on the clay (the GUI's pointer) keeps a copy. The default
    /// ignores it.
    fn field(&mut self, _field: &MultiPatchField) {}

    /// Called before the sink is handed to an engine on another clay (the engine's
    /// `stop_keeping_parts`): the bricks it holds belong to the old clay and are forgotten. The
    /// default holds nothing.
    fn restart(&mut self) {}

    /// Called with the graphics loop's field copy on a tick that applied no patch; a sink
    /// with work of its own to finish (particles settling on a still clay) does a bounded
    /// piece of it here. The default does nothing.
    fn idle(&mut self, _field: &MultiPatchField) {}
}
