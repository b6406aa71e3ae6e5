//! The sculpt as a picture: a session's clay meshed with the brick octree and rendered
//! offscreen to a PNG, for `dynaclay render` and `dynaclay run --png`.
//!
//! The clay's density is the sum of its patches (Hua & Qin eq. (3) with identity maps); one
//! patch is meshed on exactly the grid the OBJ export uses, several on a grid covering all of
//! them at the finest patch's resolution. Paint comes from the clay's colour field.

use std::path::Path;

use glam::Vec3;

use super::args::ImageArgs;
use super::run::CliError;
use crate::field::BSplineLattice;
use crate::mesh::{BrickOctree, SampleGrid, ScalarField};
use crate::render::{
    RenderError, RenderOutcome, chunk_views, octree_chunks, render_to_png, scene_camera,
};
use crate::tools::{Clay, ColourField};

/// Meshes the clay's surface with `cells_per_span` marching-cubes cells per knot span.
///
/// # Errors
/// [`CliError::Output`] when the clay has no density patch or its sampling grid cannot be made
/// (a lattice with a bad geometry, or a grid over [`SampleGrid::MAX_CELLS`] per axis).
pub fn mesh_clay(clay: &Clay, cells_per_span: u32) -> Result<BrickOctree, CliError> {
    let fail = |e: &dyn std::fmt::Display| CliError::Output(format!("meshing the clay: {e}"));
    match clay.patches.as_slice() {
        [] => Err(CliError::Output(
            "meshing the clay: the session has no density patch".to_owned(),
        )),
        [lattice] => {
            let grid = SampleGrid::for_lattice(lattice, cells_per_span).map_err(|e| fail(&e))?;
            Ok(BrickOctree::build(grid, lattice))
        }
        patches => {
            let field = SummedPatches { patches };
            let (mut lo, mut hi) = patches[0].support();
            let mut spacing = patches[0].spacing;
            for p in &patches[1..] {
                let (plo, phi) = p.support();
                lo = lo.min(plo);
                hi = hi.max(phi);
                spacing = spacing.min(p.spacing);
            }
            let cell = spacing / cells_per_span.max(1) as f32;
            let grid = SampleGrid::covering(lo, hi, cell).map_err(|e| fail(&e))?;
            Ok(BrickOctree::build(grid, &field))
        }
    }
}

/// Renders the meshed sculpt to a PNG at `path` (written atomically), painted from `colour`
/// when the clay has a colour field, framed from `image.view`.
///
/// # Errors
/// As [`render_to_png`]: [`RenderError::NoAdapter`] when the machine has no GPU adapter
/// (callers report it and skip), otherwise a device, readback or file error.
pub fn render_sculpt(
    octree: &BrickOctree,
    colour: Option<&ColourField>,
    image: &ImageArgs,
    path: &Path,
) -> Result<RenderOutcome, RenderError> {
    let chunks = octree_chunks(octree, colour);
    let views = chunk_views(&chunks);
    let options = image.scene_options();
    let camera = scene_camera(image.view, &views, &options);
    render_to_png(&views, &options, &camera, image.width, image.height, path)
}

/// A one-line account of a written image.
#[must_use]
pub fn describe_outcome(outcome: &RenderOutcome) -> String {
    format!(
        "wrote {} ({}×{}, {} triangles, {}× MSAA, on {})",
        outcome.path.display(),
        outcome.width,
        outcome.height,
        outcome.triangles,
        outcome.sample_count,
        outcome.adapter
    )
}

/// The summed density of several patches; the surface is at the first patch's iso-level.
struct SummedPatches<'a> {
    patches: &'a [BSplineLattice],
}

impl ScalarField for SummedPatches<'_> {
    fn iso(&self) -> f32 {
        self.patches.first().map_or(0.0, |p| p.iso)
    }

    fn value(&self, p: Vec3) -> f32 {
        self.patches.iter().map(|l| ScalarField::value(l, p)).sum()
    }

    fn value_and_gradient(&self, p: Vec3) -> (f32, Vec3) {
        self.patches.iter().fold((0.0, Vec3::ZERO), |(v, g), l| {
            let (lv, lg) = ScalarField::value_and_gradient(l, p);
            (v + lv, g + lg)
        })
    }

    fn sample_block(
        &self,
        grid: &SampleGrid,
        first: [u32; 3],
        counts: [usize; 3],
        out: &mut [f32],
        scratch: &mut Vec<f32>,
    ) {
        // Each patch's block sampler gives the same bits for a sample in any block, and the
        // patches are summed in a fixed order, so the sum keeps that guarantee.
        let n: usize = counts.iter().product();
        let out = &mut out[..n];
        out.fill(0.0);
        let mut part = vec![0.0; n];
        for lattice in self.patches {
            ScalarField::sample_block(lattice, grid, first, counts, &mut part, scratch);
            for (o, v) in out.iter_mut().zip(&part) {
                *o += v;
            }
        }
    }

    fn bounds(&self, min: Vec3, max: Vec3) -> Option<(f32, f32)> {
        self.patches.iter().try_fold((0.0, 0.0), |(lo, hi), l| {
            let (llo, lhi) = ScalarField::bounds(l, min, max)?;
            Some((lo + llo, hi + lhi))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ball of radius 0.6 around `origin + (1, 1, 1)` as the level set 0.5 of a ramp.
    fn ball(origin: Vec3) -> BSplineLattice {
        let mut lattice = BSplineLattice::zeros([12; 3], 0.2, origin).unwrap();
        for k in 0..12 {
            for j in 0..12 {
                for i in 0..12 {
                    let d = (lattice.node_position(i, j, k) - origin - Vec3::ONE).length() - 0.6;
                    let n = lattice.index(i, j, k);
                    lattice.coeffs[n] = (0.5 - d / 0.6).clamp(0.0, 1.0);
                }
            }
        }
        lattice
    }

    fn x_range(octree: &BrickOctree) -> (f32, f32) {
        octree
            .bricks()
            .flat_map(|b| b.mesh.positions.iter())
            .fold((f32::MAX, f32::MIN), |(lo, hi), p| {
                (lo.min(p.x), hi.max(p.x))
            })
    }

    #[test]
    fn one_patch_meshes_like_the_export() {
        let lattice = ball(Vec3::ZERO);
        let octree = mesh_clay(&Clay::single(lattice.clone()), 4).unwrap();
        let grid = SampleGrid::for_lattice(&lattice, 4).unwrap();
        assert_eq!(
            octree.weld(),
            BrickOctree::build(grid, &lattice).weld(),
            "same mesh as sculpt.obj"
        );
    }

    #[test]
    fn several_patches_are_summed_and_all_shown() {
        let a = ball(Vec3::ZERO);
        let b = ball(Vec3::new(3.0, 0.0, 0.0));
        let single = mesh_clay(&Clay::single(a.clone()), 4)
            .unwrap()
            .triangle_count();
        let clay = Clay {
            patches: vec![a, b],
            colour: None,
            constraints: Vec::new(),
        };
        let octree = mesh_clay(&clay, 4).unwrap();
        let (lo, hi) = x_range(&octree);
        assert!(
            (lo - 0.4).abs() < 0.05 && (hi - 4.6).abs() < 0.05,
            "{lo}..{hi}"
        );
        let both = octree.triangle_count();
        assert!(
            both.abs_diff(2 * single) * 10 < 2 * single,
            "{both} triangles for two balls of {single}"
        );
        assert!(octree.weld().is_well_formed());
    }

    #[test]
    fn clay_without_patches_is_an_error() {
        let err = mesh_clay(&Clay::default(), 4).unwrap_err();
        assert!(err.to_string().contains("no density patch"), "{err}");
    }
}
