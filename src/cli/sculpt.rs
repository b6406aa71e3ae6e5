//! The sculpt as a picture: a session's clay meshed with the brick octree and rendered
//! offscreen to a PNG, for `dynaclay render` and `dynaclay run --png`.
//!
//! The clay's density is the sum of its patches (Hua & Qin eq. (3)); one patch is meshed on
//! exactly the grid the OBJ export uses, several on a grid covering all of them at the finest
//! patch's resolution ([`SampleGrid::for_field`]). Paint comes from the clay's colour field.

use std::path::Path;

use super::args::ImageArgs;
use super::budget::{MESH_BYTES_PER_BRICK, MemoryBudget, OverBudget};
use super::error::CliError;
use crate::mesh::{BrickOctree, SampleGrid};
use crate::render::{
    RenderError, RenderOutcome, chunk_views, octree_chunks, render_to_png, scene_camera,
};
use crate::tools::{Clay, ColourField};

/// Meshes the clay's surface with `cells_per_span` marching-cubes cells per knot span, after
/// checking that the mesh fits `budget`: the bricks the mesher would sample are counted first
/// ([`BrickOctree::count_sampled_bricks`], no sampling, stopped at the budget), each taken at
/// [`MESH_BYTES_PER_BRICK`]. The bricks are built on the machine's cores
/// ([`BrickOctree::build_with_threads`]: the same bricks and meshes as on one).
///
/// NOTE: built on the calling thread alone, the meshing of a 50 000-point import (about
/// 52 000 vertices) was the import's last stage with the other core idle (bench/RESULTS.md,
/// "Import time: the idle core").
///
/// # Errors
/// [`CliError::OverBudget`] (exit 2) when the mesh would not fit; [`CliError::Output`] when
/// the clay has no density patch or its sampling grid cannot be made (a lattice with a bad
/// geometry, or a grid over [`SampleGrid::MAX_CELLS`] per axis).
pub fn mesh_clay(
    clay: &Clay,
    cells_per_span: u32,
    budget: &MemoryBudget,
) -> Result<BrickOctree, CliError> {
    let fail = |e: &dyn std::fmt::Display| CliError::output("meshing the clay", e.to_string());
    let density = &clay.density;
    let several = density.patches.len() > 1;
    let hint = if several {
        "Lower --cells-per-span, or give the patches similar spacings"
    } else {
        "Lower --cells-per-span"
    };
    if density.patches.is_empty() {
        return Err(CliError::Output(
            "meshing the clay: the session has no density patch".to_owned(),
        ));
    }
    {
        // One grid spans every patch at the finest spacing it follows (one patch: its own).
        let (lo, hi) = density.support();
        let spacing = SampleGrid::uniform_spacing(density);
        let widest = ((hi - lo) / (spacing / cells_per_span.max(1) as f32)).max_element();
        if widest.is_finite() && widest > SampleGrid::MAX_CELLS as f32 {
            return Err(CliError::OverBudget(OverBudget {
                what: format!(
                    "meshing the clay at {cells_per_span} cells per knot span needs {widest:.3e} \
                     cells along an axis (one grid over every patch at the finest spacing, \
                     {spacing}), past the mesher's {} per axis",
                    SampleGrid::MAX_CELLS
                ),
                needed_bytes: None,
                at_least: true,
                budget: *budget,
                hint,
            }));
        }
    }
    let grid = SampleGrid::for_field(density, cells_per_span).map_err(|e| fail(&e))?;
    let limit = budget.bricks();
    if BrickOctree::count_sampled_bricks(&grid, density, limit).is_none() {
        return Err(CliError::OverBudget(OverBudget {
            what: format!(
                "meshing the clay at {cells_per_span} cells per knot span ({} × {} × {} cells)",
                grid.cells[0], grid.cells[1], grid.cells[2]
            ),
            needed_bytes: Some(limit.saturating_add(1).saturating_mul(MESH_BYTES_PER_BRICK)),
            at_least: true,
            budget: *budget,
            hint,
        }));
    }
    let threads = std::thread::available_parallelism().map_or(1, std::num::NonZeroUsize::get);
    Ok(BrickOctree::build_with_threads(grid, density, threads))
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::BSplineLattice;
    use crate::field::{MultiPatchField, Patch};
    use glam::Vec3;

    fn budget() -> MemoryBudget {
        MemoryBudget::from_flag(Some(1024))
    }

    /// A ball of radius 0.6 around `origin + (1, 1, 1)` as the level set 0.5 of a ramp.
    fn ball(origin: Vec3) -> BSplineLattice {
        let mut lattice = BSplineLattice::zeros([12; 3], 0.2, origin).unwrap();
        for k in 0..12 {
            for j in 0..12 {
                for i in 0..12 {
                    let d = (lattice.node_position(i, j, k) - origin - Vec3::ONE).length() - 0.6;
                    let n = lattice.index(i, j, k);
                    lattice.coeffs.set_flat(n, (0.5 - d / 0.6).clamp(0.0, 1.0));
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
        let octree = mesh_clay(&Clay::single(lattice.clone()), 4, &budget()).unwrap();
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
        let single = mesh_clay(&Clay::single(a.clone()), 4, &budget())
            .unwrap()
            .triangle_count();
        let clay = Clay {
            density: MultiPatchField {
                patches: vec![Patch::identity(a), Patch::identity(b)],
            },
            colour: None,
            constraints: Vec::new(),
            mask: None,
        };
        let octree = mesh_clay(&clay, 4, &budget()).unwrap();
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
    fn the_mesh_on_every_core_is_the_mesh_on_one() {
        // Two overlapping balls, so the surface crosses many bricks in every thread's share.
        let clay = Clay {
            density: MultiPatchField {
                patches: vec![
                    Patch::identity(ball(Vec3::ZERO)),
                    Patch::identity(ball(Vec3::new(1.5, 0.5, 0.0))),
                ],
            },
            colour: None,
            constraints: Vec::new(),
            mask: None,
        };
        let grid = SampleGrid::for_field(&clay.density, 4).unwrap();
        let serial = BrickOctree::build(grid, &clay.density).weld();
        assert!(
            serial.triangle_count() > 1000,
            "{}",
            serial.triangle_count()
        );
        let octree = mesh_clay(&clay, 4, &budget()).unwrap();
        for threads in [1, 2, 3] {
            assert_eq!(
                octree.weld_with_threads(threads),
                serial,
                "{threads} threads"
            );
        }
    }

    #[test]
    fn clay_without_patches_is_an_error() {
        let err = mesh_clay(&Clay::default(), 4, &budget()).unwrap_err();
        assert!(err.to_string().contains("no density patch"), "{err}");
    }

    #[test]
    fn a_brick_costs_less_than_the_budget_allows() {
        // A ball of radius 10 spans: a few hundred surface bricks, so the octree's fixed
        // scratch does not dominate.
        let mut lattice = BSplineLattice::zeros([28; 3], 0.1, Vec3::ZERO).unwrap();
        for k in 0..28 {
            for j in 0..28 {
                for i in 0..28 {
                    let d = Vec3::new(i as f32, j as f32, k as f32) - Vec3::splat(13.5);
                    let n = lattice.index(i, j, k);
                    lattice
                        .coeffs
                        .set_flat(n, (1.0 - d.length() / 20.0).clamp(0.0, 1.0));
                }
            }
        }
        let octree = mesh_clay(&Clay::single(lattice.clone()), 4, &budget()).unwrap();
        let grid = SampleGrid::for_lattice(&lattice, 4).unwrap();
        let counted = BrickOctree::count_sampled_bricks(&grid, &lattice, u64::MAX).unwrap();
        let stored = octree.bricks().count() as u64;
        assert!(
            counted >= stored && stored > 0,
            "{counted} counted, {stored} stored"
        );
        // The octree, then the welded mesh and a chunk copy of it for drawing.
        let weld = octree.weld();
        let drawn = (weld.vertex_count() * 24 + weld.triangle_count() * 12) as u64;
        let bytes = octree.memory().total_bytes() as u64 + 2 * drawn;
        assert!(stored > 200, "{stored} bricks");
        assert!(
            bytes <= stored * MESH_BYTES_PER_BRICK,
            "{bytes} bytes for {stored} bricks"
        );
    }

    #[test]
    fn patches_of_very_different_spacing_are_refused_without_meshing() {
        let fine = ball(Vec3::ZERO);
        let mut coarse = BSplineLattice::zeros([4; 3], 37.0, Vec3::splat(-50.0)).unwrap();
        coarse.coeffs.fill(0.3);
        coarse.coeffs.set_flat(21, 0.9);
        let mut fine = fine;
        fine.spacing = 1e-3;
        let clay = Clay {
            density: MultiPatchField {
                patches: vec![Patch::identity(fine), Patch::identity(coarse)],
            },
            colour: None,
            constraints: Vec::new(),
            mask: None,
        };
        let err = mesh_clay(&clay, 4, &MemoryBudget::from_flag(Some(64))).unwrap_err();
        assert!(matches!(err, CliError::OverBudget(_)), "{err}");
        assert_eq!(err.exit_code(), 2);
        assert!(
            err.to_string().contains("more than the memory budget"),
            "{err}"
        );
    }
}
