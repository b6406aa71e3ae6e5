//! A tool made from the sculpt (Ferley §4.1.2, "a shape sculpted in the app"): the clay inside
//! a selection the user places — a box or a ball — refitted onto a lattice of its own, to be
//! used as a freeform tool shape ([`FreeformTool`]) with any geometric action (stamp, add,
//! remove, union, …).
//!
//! The tool's potential is the clay's density intersected with the selection: `min(clay,
//! window)`, where the window is the selection's own potential (one half on its boundary,
//! falling to zero one knot span outside it). So what lies inside the selection is kept as it
//! is, and the tool ends at the selection's faces. The lattice is centred on the selection's
//! centre, so a tool placed at `p` reproduces at `p` what the selection held around its centre.
//!
//! Runs off the real-time path (it allocates and fits a lattice).

use glam::Vec3;

use super::shape::{FreeformTool, density_from_distance, remap_iso};
use crate::field::{BSplineLattice, FitError, MultiPatchField, fit_lattice};

/// Most coefficients per axis of a captured tool: a larger selection is captured at a coarser
/// spacing than the clay's finest, so the lattice stays within 64³.
pub const MAX_CAPTURE_DIMS: usize = 64;

/// Where the clay to capture is, field coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Selection {
    /// An axis-aligned box.
    Box {
        /// Its centre.
        centre: Vec3,
        /// Half its size along each axis.
        half_extents_fu: Vec3,
    },
    /// A ball.
    Ball {
        /// Its centre.
        centre: Vec3,
        /// Its radius.
        radius_fu: f32,
    },
}

/// Why a tool could not be made from the sculpt.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum CaptureError {
    /// The selection's size or position is not positive and finite.
    #[error("selection: {0}")]
    BadSelection(String),
    /// No clay lies inside the selection.
    #[error("the selection around {centre} holds no clay")]
    Empty {
        /// The selection's centre.
        centre: Vec3,
    },
    /// The clay has no patch to read.
    #[error("the clay has no density patch")]
    NoClay,
    /// The lattice fit failed.
    #[error("fit: {0}")]
    Fit(#[from] FitError),
}

impl Selection {
    /// The selection's centre.
    #[must_use]
    pub fn centre(&self) -> Vec3 {
        match *self {
            Self::Box { centre, .. } | Self::Ball { centre, .. } => centre,
        }
    }

    /// Half extents of the box that holds the selection.
    #[must_use]
    pub fn half_extents(&self) -> Vec3 {
        match *self {
            Self::Box {
                half_extents_fu, ..
            } => half_extents_fu,
            Self::Ball { radius_fu, .. } => Vec3::splat(radius_fu),
        }
    }

    /// Signed distance from `x` to the selection's boundary (negative inside).
    #[must_use]
    pub fn signed_distance(&self, x: Vec3) -> f32 {
        match *self {
            Self::Box {
                centre,
                half_extents_fu,
            } => {
                let q = (x - centre).abs() - half_extents_fu;
                q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
            }
            Self::Ball { centre, radius_fu } => x.distance(centre) - radius_fu,
        }
    }

    /// Checks the centre is finite and the size positive and finite.
    ///
    /// # Errors
    /// [`CaptureError::BadSelection`] naming the value.
    pub fn validate(&self) -> Result<(), CaptureError> {
        let centre = self.centre();
        if !centre.is_finite() {
            return Err(CaptureError::BadSelection(format!(
                "centre {centre} is not finite"
            )));
        }
        let half = self.half_extents();
        if !(half.is_finite() && half.min_element() > 0.0) {
            return Err(CaptureError::BadSelection(match self {
                Self::Box { .. } => format!("half extents {half} must be positive and finite"),
                Self::Ball { radius_fu, .. } => {
                    format!("radius_fu = {radius_fu} must be positive and finite")
                }
            }));
        }
        Ok(())
    }
}

/// Makes a freeform tool (scale 1) of the clay `field` inside `selection`: a lattice at the
/// clay's finest knot spacing (coarser for a selection wider than [`MAX_CAPTURE_DIMS`] spans),
/// centred on the selection, fitted by least squares to `min(clay, window)` with both as
/// densities whose surface is one half.
///
/// # Errors
/// [`CaptureError`] for a bad selection, a selection holding no clay, or a failed fit.
pub fn capture_tool(
    field: &MultiPatchField,
    selection: &Selection,
) -> Result<FreeformTool, CaptureError> {
    selection.validate()?;
    if field.patches.is_empty() {
        return Err(CaptureError::NoClay);
    }
    let iso = field.iso();
    let half = selection.half_extents();
    // Room beyond the selection for the window's fall (one span) and the spline's support.
    let margin_spans = 3.0;
    let finest = field.finest_spacing();
    let widest = 2.0 * half.max_element();
    let h = finest.max(widest / (MAX_CAPTURE_DIMS as f32 - 1.0 - 2.0 * margin_spans));
    let dims = half.to_array().map(|e| {
        let n = (2.0 * e / h + 2.0 * margin_spans).ceil() as usize + 1;
        n.clamp(4, MAX_CAPTURE_DIMS)
    });
    let centre = selection.centre();
    let extent = Vec3::new(
        (dims[0] - 1) as f32,
        (dims[1] - 1) as f32,
        (dims[2] - 1) as f32,
    ) * h;
    // Centring the nodes on the selection centres the support: FreeformTool reads the lattice
    // around the support's middle.
    let origin = centre - 0.5 * extent;
    let mut lattice = BSplineLattice::zeros(dims, h, origin)
        .map_err(|e| CaptureError::BadSelection(e.to_string()))?;
    let falloff = h;
    let target = |x: Vec3| {
        let clay = remap_iso(field.value(x), iso);
        let window = density_from_distance(selection.signed_distance(x), falloff);
        clay.min(window)
    };
    // Anything to capture: a sample inside both the clay and the selection.
    let step = 0.5 * h;
    let n = (half / step).ceil().as_ivec3();
    let mut found = false;
    'search: for k in -n.z..=n.z {
        for j in -n.y..=n.y {
            for i in -n.x..=n.x {
                let x = centre + Vec3::new(i as f32, j as f32, k as f32) * step;
                if target(x) > 0.5 {
                    found = true;
                    break 'search;
                }
            }
        }
    }
    if !found {
        return Err(CaptureError::Empty { centre });
    }
    fit_lattice(&mut lattice, 2, target)?;
    lattice.iso = 0.5;
    Ok(FreeformTool {
        lattice,
        scale: Vec3::ONE,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Primitive, lattice_from_primitive};
    use crate::tools::ToolShape;

    fn ball_clay(centre: Vec3, radius: f32) -> MultiPatchField {
        MultiPatchField::new(
            lattice_from_primitive(
                [24; 3],
                0.1,
                Vec3::ZERO,
                &Primitive::Sphere { centre, radius },
                0.2,
                2,
            )
            .unwrap(),
        )
    }

    #[test]
    fn a_ball_captured_whole_is_the_same_ball_about_the_tools_centre() {
        let c = Vec3::splat(1.15);
        let field = ball_clay(c, 0.5);
        let tool = capture_tool(
            &field,
            &Selection::Box {
                centre: c,
                half_extents_fu: Vec3::splat(0.7),
            },
        )
        .unwrap();
        let shape = ToolShape::Freeform(tool);
        shape.validate().unwrap();
        // The tool's surface (density one half) lies where the clay's did, about its centre.
        for dir in [
            Vec3::X,
            Vec3::Y,
            Vec3::Z,
            Vec3::new(1.0, 1.0, 1.0).normalize(),
        ] {
            let mut r = 0.0;
            while shape.density(dir * (r + 0.001), 0.0) > 0.5 && r < 1.0 {
                r += 0.001;
            }
            assert!((r - 0.5).abs() < 0.02, "radius along {dir}: {r}");
        }
    }

    #[test]
    fn the_selection_cuts_the_clay_at_its_faces() {
        let c = Vec3::splat(1.15);
        let field = ball_clay(c, 0.5);
        // A box holding the ball's top cap only (y above c.y + 0.3).
        let sel = Selection::Box {
            centre: c + Vec3::Y * 0.4,
            half_extents_fu: Vec3::new(0.6, 0.1, 0.6),
        };
        let shape = ToolShape::Freeform(capture_tool(&field, &sel).unwrap());
        // In the tool's frame the cap spans y in [-0.1, 0.1]; beyond the box's faces, nothing.
        assert!(shape.density(Vec3::ZERO, 0.0) > 0.5);
        assert!(shape.density(Vec3::Y * 0.05, 0.0) > 0.5);
        assert!(shape.density(-Vec3::Y * 0.2, 0.0) < 0.5, "below the box");
        assert!(shape.density(Vec3::Y * 0.15, 0.0) < 0.5, "above the cap");
        // A ball selection keeps a ball of clay.
        let round = Selection::Ball {
            centre: c,
            radius_fu: 0.3,
        };
        let shape = ToolShape::Freeform(capture_tool(&field, &round).unwrap());
        assert!(shape.density(Vec3::X * 0.25, 0.0) > 0.5);
        assert!(shape.density(Vec3::new(0.25, 0.25, 0.0), 0.0) < 0.5);
    }

    #[test]
    fn bad_or_empty_selections_are_refused() {
        let field = ball_clay(Vec3::splat(1.15), 0.5);
        let empty = Selection::Ball {
            centre: Vec3::splat(0.3),
            radius_fu: 0.1,
        };
        assert!(matches!(
            capture_tool(&field, &empty),
            Err(CaptureError::Empty { .. })
        ));
        let flat = Selection::Box {
            centre: Vec3::ONE,
            half_extents_fu: Vec3::new(0.1, 0.0, 0.1),
        };
        let e = capture_tool(&field, &flat).unwrap_err().to_string();
        assert!(e.contains("half extents"), "{e}");
        let nan = Selection::Ball {
            centre: Vec3::NAN,
            radius_fu: 0.1,
        };
        assert!(capture_tool(&field, &nan).is_err());
    }

    #[test]
    fn a_wide_selection_is_captured_coarser_within_the_size_cap() {
        let field = ball_clay(Vec3::splat(1.15), 0.5);
        let tool = capture_tool(
            &field,
            &Selection::Box {
                centre: Vec3::splat(1.15),
                half_extents_fu: Vec3::splat(5.0),
            },
        )
        .unwrap();
        assert!(tool.lattice.dims.iter().all(|&n| n <= MAX_CAPTURE_DIMS));
        assert!(tool.lattice.spacing > 0.1);
    }
}
