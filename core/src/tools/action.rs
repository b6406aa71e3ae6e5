//! What a geometric tool does with its potential `t` where it meets the clay's density `f`
//! (Ferley §4.2–4.3, Guo & Qin Table 1, Zhang §3). Each action is a pure per-point rule; the
//! progressive ones (toothpaste add, soft remove, soft paint, smooth) scale with the time the
//! tool dwells, so a stroke deposits at a set speed.

use serde::{Deserialize, Serialize};

use super::deform::{ContactParams, StampParams};

/// A tool action, with its parameters. Rates are per second of tool dwell time.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ToolAction {
    /// Toothpaste: `f + min(1, rate·dt)·t`, up to the tool's potential `t` (where that is
    /// above the clay): a held tool fills its own shape and no more, like a union reached
    /// progressively (Ferley's deposit grows without bound, so a bead would land wider the
    /// longer it dwells).
    Add { deposit_rate_per_s: f32 },
    /// Carve the tool's shape out: `min(f, 1 − t)` (CSG difference with the tool).
    Remove,
    /// Progressive eraser: `f − min(1, rate·dt)·t`, down to `1 − t` (where that is below the
    /// clay): a held tool empties its own shape and no more, a remove reached progressively.
    SoftRemove { rate_per_s: f32 },
    /// Paint the tool's colour where the tool reaches (full coverage inside the tool).
    Paint { rgb: [f32; 3] },
    /// Progressive paint, weighted by the tool's potential and the clay's presence.
    SoftPaint { rgb: [f32; 3], rate_per_s: f32 },
    /// Low-pass the field under the tool: blend towards a local average whose 27 taps lie
    /// `kernel_fu` apart (at least one knot span is used).
    Smooth {
        rate_per_s: f32,
        #[serde(alias = "kernel_m")]
        kernel_fu: f32,
    },
    /// Print the tool's shape with Ferley's deformation function.
    Stamp(StampParams),
    /// Zhang's contact deformation `h = f + β·g`.
    Contact(ContactParams),
    /// Guo & Qin Table 1: clay ∪ tool (`max(f, t)`).
    Union,
    /// Clay ∩ other clay (`min(f, t)`): a CSG operation with another sculpt only
    /// ([`super::apply_csg`]). As a brush it would clear the whole clay outside the tool, so
    /// [`ToolAction::validate`] refuses it for a tool.
    Intersection,
    /// Clay − tool (`min(f, 2·iso − t)`).
    Difference,
}

/// Why an intersection is refused as a tool's action, and what to use instead.
pub const INTERSECTION_IS_CSG: &str = "intersection is a CSG operation with another clay, not a \
     brush (as a brush it would delete the whole clay outside the tool): use a `csg` step \
     (op = \"intersection\", with = \"other.dclay\"), or CSG with a session in the window";

/// Why an action's parameters were rejected.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("invalid tool action: {0}")]
pub struct ActionError(pub String);

impl ToolAction {
    /// Short name for menus and undo labels.
    #[must_use]
    pub fn name(&self) -> &'static str {
        match self {
            Self::Add { .. } => "add",
            Self::Remove => "remove",
            Self::SoftRemove { .. } => "soft remove",
            Self::Paint { .. } => "paint",
            Self::SoftPaint { .. } => "soft paint",
            Self::Smooth { .. } => "smooth",
            Self::Stamp(_) => "stamp",
            Self::Contact(_) => "contact",
            Self::Union => "union",
            Self::Intersection => "intersection",
            Self::Difference => "difference",
        }
    }

    /// Whether the action can put clay where there was none (so an application past the
    /// clay's box should grow the clay first, see [`crate::tools::Clay::grow_to_cover`]).
    #[must_use]
    pub fn can_add_clay(&self) -> bool {
        matches!(
            self,
            Self::Add { .. }
                | Self::Smooth { .. }
                | Self::Stamp(_)
                | Self::Contact(_)
                | Self::Union
        )
    }

    /// Whether the action writes the colour field rather than the density.
    #[must_use]
    pub fn paints(&self) -> bool {
        matches!(self, Self::Paint { .. } | Self::SoftPaint { .. })
    }

    /// Whether the action shapes the clay within the tool's falloff band itself (the stamp's
    /// rim and the contact deformation are functions of the band's potential, and the RBF
    /// clay evaluates the contact with the user's band as it is), so the band is the user's
    /// setting and is not widened to the lattice's floor ([`crate::tools::MIN_FALLOFF_SPANS`]).
    /// Widened, a stamp's print shrinks (its wall is read at the band's three-quarter mark):
    /// the stamp keeps the user's band for `def` and tends its print to the lattice's floor
    /// band apart ([`crate::tools::StampParams::apply`]).
    #[must_use]
    pub fn shapes_its_band(&self) -> bool {
        matches!(self, Self::Stamp(_) | Self::Contact(_))
    }

    /// Checks rates, colours and stamp parameters, and that the action is one a tool may
    /// hold: intersection is a CSG operation with another clay, never a brush.
    ///
    /// # Errors
    /// Names the parameter that is out of range, or says what to use instead of an
    /// intersection brush.
    pub fn validate(&self) -> Result<(), ActionError> {
        let rate = |name: &str, v: f32| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(ActionError(format!(
                    "{name} must be positive and finite, got {v}"
                )))
            }
        };
        let colour = |rgb: &[f32; 3]| {
            if rgb.iter().all(|c| (0.0..=1.0).contains(c)) {
                Ok(())
            } else {
                Err(ActionError(format!("rgb {rgb:?} must be within [0, 1]")))
            }
        };
        match self {
            Self::Add { deposit_rate_per_s } => rate("deposit_rate_per_s", *deposit_rate_per_s),
            Self::SoftRemove { rate_per_s } => rate("rate_per_s", *rate_per_s),
            Self::Smooth {
                rate_per_s,
                kernel_fu,
            } => {
                rate("rate_per_s", *rate_per_s)?;
                rate("kernel_fu", *kernel_fu)
            }
            Self::Paint { rgb } => colour(rgb),
            Self::SoftPaint { rgb, rate_per_s } => {
                colour(rgb)?;
                rate("rate_per_s", *rate_per_s)
            }
            Self::Stamp(p) => p.validate().map_err(|e| ActionError(e.0)),
            Self::Contact(c) if c.alpha.is_nan() || c.alpha.abs() > ContactParams::MAX_ALPHA => {
                Err(ActionError(format!(
                    "alpha = {} must be between -{max} and {max}",
                    c.alpha,
                    max = ContactParams::MAX_ALPHA
                )))
            }
            Self::Contact(c) if !(c.rate_per_s.is_finite() && c.rate_per_s > 0.0) => {
                Err(ActionError(format!(
                    "rate_per_s must be positive and finite, got {}",
                    c.rate_per_s
                )))
            }
            Self::Intersection => Err(ActionError(INTERSECTION_IS_CSG.into())),
            _ => Ok(()),
        }
    }

    /// The new density at a point with clay density `clay` and tool potential `tool`, for a
    /// dwell of `dt_s`. Smoothing needs the local average too (`blurred`); other actions
    /// ignore it. Painting actions leave the density unchanged.
    #[inline]
    #[must_use]
    pub fn density(&self, clay: f32, tool: f32, blurred: f32, iso: f32, dt_s: f32) -> f32 {
        self.density_with_print(clay, tool, tool, blurred, iso, dt_s)
    }

    /// [`Self::density`] with the potential a stamp's print tends to (`print`) apart from the
    /// one its deformation function reads (`tool`).
    #[inline]
    #[must_use]
    pub fn density_with_print(
        &self,
        clay: f32,
        tool: f32,
        print: f32,
        blurred: f32,
        iso: f32,
        dt_s: f32,
    ) -> f32 {
        let amount = |rate: f32| (rate * dt_s).clamp(0.0, 1.0);
        match *self {
            Self::Add { deposit_rate_per_s } => (clay + amount(deposit_rate_per_s) * tool)
                .min(tool.max(clay))
                .min(1.0)
                .max(clay),
            Self::Remove => clay.min(1.0 - tool),
            Self::SoftRemove { rate_per_s } => (clay - amount(rate_per_s) * tool)
                .max((1.0 - tool).min(clay))
                .max(0.0)
                .min(clay),
            Self::Paint { .. } | Self::SoftPaint { .. } => clay,
            Self::Smooth { rate_per_s, .. } => {
                let w = amount(rate_per_s) * (2.0 * tool).min(1.0);
                clay + w * (blurred - clay)
            }
            Self::Stamp(p) => p.apply(clay, tool, print, iso, dt_s),
            Self::Contact(c) => c.apply(clay, tool, iso, dt_s),
            Self::Union => clay.max(tool),
            Self::Intersection => clay.min(tool),
            Self::Difference => clay.min((2.0 * iso - tool).clamp(0.0, 1.0)),
        }
    }

    /// The weight (in `[0, 1]`) with which the tool's colour replaces the clay's colour at a
    /// point; zero for actions that do not paint.
    #[inline]
    #[must_use]
    pub fn paint_weight(&self, clay: f32, tool: f32, iso: f32, dt_s: f32) -> f32 {
        match *self {
            // Full coverage inside the tool's surface, fading over its falloff band.
            Self::Paint { .. } => (2.0 * tool).min(1.0),
            // Progressive, and only where there is clay to take the paint (Ferley: the
            // corner's own field value is taken into account).
            Self::SoftPaint { rate_per_s, .. } => {
                let presence = (clay / iso.max(f32::EPSILON)).min(1.0);
                (rate_per_s * dt_s).clamp(0.0, 1.0) * tool * presence
            }
            _ => 0.0,
        }
    }

    /// The tool's colour for painting actions.
    #[must_use]
    pub fn rgb(&self) -> Option<[f32; 3]> {
        match *self {
            Self::Paint { rgb } | Self::SoftPaint { rgb, .. } => Some(rgb),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csg_rules_follow_table_1_classification() {
        let iso = 0.5;
        // (clay inside?, tool inside?) → inside after the operation?
        for (f, t) in [(0.9, 0.9), (0.9, 0.1), (0.1, 0.9), (0.1, 0.1)] {
            let (a, b) = (f > iso, t > iso);
            assert_eq!(ToolAction::Union.density(f, t, 0.0, iso, 0.0) > iso, a || b);
            assert_eq!(
                ToolAction::Intersection.density(f, t, 0.0, iso, 0.0) > iso,
                a && b
            );
            assert_eq!(
                ToolAction::Difference.density(f, t, 0.0, iso, 0.0) > iso,
                a && !b
            );
        }
    }

    #[test]
    fn progressive_actions_scale_with_dwell_time() {
        let add = ToolAction::Add {
            deposit_rate_per_s: 2.0,
        };
        assert_eq!(add.density(0.0, 1.0, 0.0, 0.5, 0.1), 0.2);
        assert_eq!(add.density(0.0, 1.0, 0.0, 0.5, 10.0), 1.0);
        assert_eq!(add.density(0.7, 0.0, 0.0, 0.5, 1.0), 0.7);
        let erase = ToolAction::SoftRemove { rate_per_s: 1.0 };
        assert!((erase.density(0.8, 0.5, 0.0, 0.5, 0.2) - 0.7).abs() < 1e-6);
        // Held long, they stop at the tool's shape: a union, a remove.
        assert_eq!(add.density(0.1, 0.3, 0.0, 0.5, 10.0), 0.3);
        assert_eq!(add.density(0.6, 0.3, 0.0, 0.5, 10.0), 0.6);
        assert_eq!(erase.density(0.9, 0.3, 0.0, 0.5, 10.0), 0.7);
        assert_eq!(erase.density(0.2, 0.3, 0.0, 0.5, 10.0), 0.2);
        let smooth = ToolAction::Smooth {
            rate_per_s: 1.0,
            kernel_fu: 0.1,
        };
        assert_eq!(smooth.density(1.0, 1.0, 0.5, 0.5, 1.0), 0.5);
        assert_eq!(smooth.density(1.0, 0.0, 0.5, 0.5, 1.0), 1.0);
    }

    #[test]
    fn intersection_is_refused_as_a_brush_and_says_what_to_use() {
        let e = ToolAction::Intersection.validate().unwrap_err();
        assert!(e.0.contains("csg") && e.0.contains("not a brush"), "{e}");
        assert!(ToolAction::Union.validate().is_ok());
        assert!(ToolAction::Difference.validate().is_ok());
    }

    #[test]
    fn paint_weights_and_validation() {
        let paint = ToolAction::Paint {
            rgb: [1.0, 0.0, 0.0],
        };
        assert_eq!(paint.paint_weight(0.0, 0.6, 0.5, 0.0), 1.0);
        assert_eq!(paint.paint_weight(0.0, 0.0, 0.5, 0.0), 0.0);
        let soft = ToolAction::SoftPaint {
            rgb: [0.0, 1.0, 0.0],
            rate_per_s: 1.0,
        };
        assert_eq!(
            soft.paint_weight(0.0, 1.0, 0.5, 1.0),
            0.0,
            "no clay, no paint"
        );
        assert!(soft.paint_weight(1.0, 1.0, 0.5, 0.5) > 0.4);
        assert!(
            ToolAction::Paint {
                rgb: [2.0, 0.0, 0.0]
            }
            .validate()
            .is_err()
        );
        assert!(
            ToolAction::Add {
                deposit_rate_per_s: 0.0
            }
            .validate()
            .is_err()
        );
    }
}
