//! Tool shapes and their potential fields (Ferley §4.1): an analytic solid (sphere, ellipsoid,
//! box, cylinder, capsule) or a freeform lattice taken from a sculpted session, placed by a
//! [`ToolPose`]. A tool's potential is a density in `[0, 1]` like the clay's: 1 deep inside,
//! exactly one half on the tool's surface, 0 beyond its falloff band, C¹ throughout.
//! Evaluation is pure and allocates nothing. Lengths are in field units (`_fu`, see
//! [`crate::tools`]).

use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};

use super::falloff::FalloffCurve;
use crate::field::BSplineLattice;

/// Where a tool is: its centre in field units and its orientation.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ToolPose {
    #[serde(alias = "position_fu")]
    pub position_fu: Vec3,
    #[serde(default = "identity")]
    pub rotation: Quat,
}

fn identity() -> Quat {
    Quat::IDENTITY
}

impl ToolPose {
    /// A pose at `position_fu` with no rotation.
    #[must_use]
    pub fn at(position_fu: Vec3) -> Self {
        Self {
            position_fu,
            rotation: Quat::IDENTITY,
        }
    }

    /// World point to the tool's local frame.
    #[inline]
    #[must_use]
    pub fn to_local(&self, x: Vec3) -> Vec3 {
        self.rotation.inverse() * (x - self.position_fu)
    }

    /// World-axis-aligned bounds of a local box `-half ..= half` (Ferley Fig. 7b).
    #[must_use]
    pub fn world_bounds(&self, half: Vec3) -> (Vec3, Vec3) {
        let m = glam::Mat3::from_quat(self.rotation);
        let extent = m.x_axis.abs() * half.x + m.y_axis.abs() * half.y + m.z_axis.abs() * half.z;
        (self.position_fu - extent, self.position_fu + extent)
    }
}

/// A freeform tool: the field of a sculpted patch, scaled along its local axes (Ferley
/// §4.1.2). The patch is centred on the tool position: local point `p` reads the lattice at
/// `centre + p / scale` where `centre` is the middle of the lattice's support.
#[derive(Clone, Debug, PartialEq)]
pub struct FreeformTool {
    pub lattice: BSplineLattice,
    pub scale: Vec3,
}

/// The shape of a geometric tool, in its local frame (cylinder and capsule axes run along z).
#[derive(Clone, Debug, PartialEq)]
pub enum ToolShape {
    Sphere {
        radius_fu: f32,
    },
    Ellipsoid {
        radii_fu: Vec3,
    },
    Box {
        half_extents_fu: Vec3,
    },
    Cylinder {
        radius_fu: f32,
        half_height_fu: f32,
    },
    Capsule {
        radius_fu: f32,
        half_height_fu: f32,
    },
    Freeform(FreeformTool),
    /// A round brush whose depth from its centre to its edge follows a falloff curve: the
    /// solid `|z| ≤ radius·curve(ρ / radius)` about the local z axis ([`FalloffCurve`]).
    /// Turn the tool so that z faces the clay. With the sphere curve it is the sphere,
    /// evaluated exactly as [`ToolShape::Sphere`].
    Profiled {
        radius_fu: f32,
        curve: FalloffCurve,
    },
}

/// Why a tool shape cannot be used.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("invalid tool shape: {0}")]
pub struct ShapeError(pub String);

/// C¹ ramp from 1 (signed distance `-w`) through 1/2 (the surface) to 0 (distance `+w`).
#[inline]
#[must_use]
pub fn density_from_distance(distance_fu: f32, falloff_fu: f32) -> f32 {
    let x = ((falloff_fu - distance_fu) / (2.0 * falloff_fu)).clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

impl ToolShape {
    /// A round brush of `radius_fu` with `curve`: the sphere for the sphere curve (so the
    /// default brush is the sphere tool, bit for bit), else [`ToolShape::Profiled`].
    #[must_use]
    pub fn round(radius_fu: f32, curve: FalloffCurve) -> Self {
        if curve.is_sphere() {
            Self::Sphere { radius_fu }
        } else {
            Self::Profiled { radius_fu, curve }
        }
    }

    /// The falloff curve of a round brush (the sphere's for a sphere); `None` for the other
    /// shapes, which carry their own profile.
    #[must_use]
    pub fn falloff_curve(&self) -> Option<&FalloffCurve> {
        const SPHERE: FalloffCurve = FalloffCurve::Sphere;
        match self {
            Self::Sphere { .. } => Some(&SPHERE),
            Self::Profiled { curve, .. } => Some(curve),
            _ => None,
        }
    }

    /// Checks dimensions are positive and finite.
    ///
    /// # Errors
    /// Names the offending parameter.
    pub fn validate(&self) -> Result<(), ShapeError> {
        let positive = |name: &str, v: f32| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(ShapeError(format!(
                    "{name} must be positive and finite, got {v}"
                )))
            }
        };
        match self {
            Self::Sphere { radius_fu } => positive("radius_fu", *radius_fu),
            Self::Ellipsoid { radii_fu } => {
                (0..3).try_for_each(|a| positive("radii_fu", radii_fu[a]))
            }
            Self::Box { half_extents_fu } => {
                (0..3).try_for_each(|a| positive("half_extents_fu", half_extents_fu[a]))
            }
            Self::Cylinder {
                radius_fu,
                half_height_fu,
            }
            | Self::Capsule {
                radius_fu,
                half_height_fu,
            } => {
                positive("radius_fu", *radius_fu)?;
                positive("half_height_fu", *half_height_fu)
            }
            Self::Freeform(tool) => (0..3).try_for_each(|a| positive("scale", tool.scale[a])),
            Self::Profiled { radius_fu, curve } => {
                positive("radius_fu", *radius_fu)?;
                curve.validate().map_err(|e| ShapeError(e.to_string()))
            }
        }
    }

    /// Half extents of the local box outside which the shape's solid lies (without falloff).
    #[must_use]
    pub fn half_extents(&self) -> Vec3 {
        match self {
            Self::Sphere { radius_fu } => Vec3::splat(*radius_fu),
            Self::Ellipsoid { radii_fu } => *radii_fu,
            Self::Box { half_extents_fu } => *half_extents_fu,
            Self::Cylinder {
                radius_fu,
                half_height_fu,
            } => Vec3::new(*radius_fu, *radius_fu, *half_height_fu),
            Self::Capsule {
                radius_fu,
                half_height_fu,
            } => Vec3::new(*radius_fu, *radius_fu, half_height_fu + radius_fu),
            Self::Freeform(tool) => {
                let (lo, hi) = tool.lattice.support();
                0.5 * (hi - lo) * tool.scale
            }
            Self::Profiled { radius_fu, curve } => {
                Vec3::new(*radius_fu, *radius_fu, radius_fu * curve.max_depth())
            }
        }
    }

    /// Signed distance (negative inside) from a local point to an analytic shape's surface;
    /// for the ellipsoid a first-order estimate that is exact on the axes and on the surface.
    /// `None` for a freeform shape, which has a density but no distance.
    #[inline]
    #[must_use]
    pub fn signed_distance(&self, p: Vec3) -> Option<f32> {
        let box_distance = |q: Vec3| q.max(Vec3::ZERO).length() + q.max_element().min(0.0);
        Some(match self {
            Self::Sphere { radius_fu } => p.length() - radius_fu,
            Self::Ellipsoid { radii_fu } => {
                let k0 = (p / *radii_fu).length();
                let k1 = (p / (*radii_fu * *radii_fu)).length();
                if k1 > 0.0 {
                    k0 * (k0 - 1.0) / k1
                } else {
                    -radii_fu.min_element()
                }
            }
            Self::Box { half_extents_fu } => box_distance(p.abs() - *half_extents_fu),
            Self::Cylinder {
                radius_fu,
                half_height_fu,
            } => {
                let q = Vec3::new(
                    p.truncate().length() - radius_fu,
                    p.z.abs() - half_height_fu,
                    f32::MIN,
                );
                box_distance(q)
            }
            Self::Capsule {
                radius_fu,
                half_height_fu,
            } => {
                (p - Vec3::new(0.0, 0.0, p.z.clamp(-half_height_fu, *half_height_fu))).length()
                    - radius_fu
            }
            Self::Profiled { radius_fu, curve } => {
                if curve.is_sphere() {
                    p.length() - radius_fu
                } else {
                    curve.signed_distance(p.truncate().length(), p.z, *radius_fu)
                }
            }
            Self::Freeform(_) => return None,
        })
    }

    /// The tool's potential (density in `[0, 1]`, one half on the surface) at a local point.
    #[inline]
    #[must_use]
    pub fn density(&self, p: Vec3, falloff_fu: f32) -> f32 {
        match self {
            Self::Freeform(tool) => {
                let (lo, hi) = tool.lattice.support();
                let x = 0.5 * (lo + hi) + p / tool.scale;
                remap_iso(tool.lattice.value(x), tool.lattice.iso)
            }
            analytic => density_from_distance(
                analytic.signed_distance(p).unwrap_or(f32::INFINITY),
                falloff_fu,
            ),
        }
    }

    /// A radius around the tool's centre (local frame) beyond which an analytic shape's
    /// potential is exactly zero: its solid's farthest point plus the falloff band. `None`
    /// for the ellipsoid, whose distance is an estimate, and for freeform shapes.
    #[must_use]
    pub fn zero_beyond(&self, falloff_fu: f32) -> Option<f32> {
        let solid = match self {
            Self::Sphere { radius_fu } => *radius_fu,
            Self::Box { half_extents_fu } => half_extents_fu.length(),
            Self::Cylinder {
                radius_fu,
                half_height_fu,
            } => radius_fu.hypot(*half_height_fu),
            Self::Capsule {
                radius_fu,
                half_height_fu,
            } => radius_fu + half_height_fu,
            Self::Profiled { radius_fu, curve } => radius_fu * curve.max_reach(),
            Self::Ellipsoid { .. } | Self::Freeform(_) => return None,
        };
        Some(solid + falloff_fu)
    }

    /// Largest spacing of a stroke's applications along its path, field units: a quarter of
    /// the shape's smallest half extent (a quarter of a sphere's or capsule's radius), so
    /// that successive applications overlap into one continuous groove or bead.
    #[must_use]
    pub fn stroke_spacing_fu(&self) -> f32 {
        0.25 * self.half_extents().min_element()
    }

    /// Half extents of the local box outside which the density is exactly zero.
    #[must_use]
    pub fn influence_half_extents(&self, falloff_fu: f32) -> Vec3 {
        match self {
            Self::Freeform(_) => self.half_extents(),
            _ => self.half_extents() + Vec3::splat(falloff_fu),
        }
    }

    /// Volume of the analytic solid in cubic field units (`None` for freeform shapes).
    #[must_use]
    pub fn volume_m3(&self) -> Option<f32> {
        use std::f32::consts::PI;
        Some(match self {
            Self::Sphere { radius_fu } => 4.0 / 3.0 * PI * radius_fu.powi(3),
            Self::Ellipsoid { radii_fu } => 4.0 / 3.0 * PI * radii_fu.x * radii_fu.y * radii_fu.z,
            Self::Box { half_extents_fu } => {
                8.0 * half_extents_fu.x * half_extents_fu.y * half_extents_fu.z
            }
            Self::Cylinder {
                radius_fu,
                half_height_fu,
            } => PI * radius_fu * radius_fu * 2.0 * half_height_fu,
            Self::Capsule {
                radius_fu,
                half_height_fu,
            } => PI * radius_fu * radius_fu * (2.0 * half_height_fu + 4.0 / 3.0 * radius_fu),
            Self::Profiled { radius_fu, curve } => {
                4.0 * PI * radius_fu.powi(3) * curve.first_moment()
            }
            Self::Freeform(_) => return None,
        })
    }
}

/// Maps a freeform field so that its own iso-level lands on one half, clamped to `[0, 1]`.
#[inline]
pub(super) fn remap_iso(value: f32, iso: f32) -> f32 {
    let v = value.clamp(0.0, 1.0);
    if !(iso > 0.0 && iso < 1.0) {
        return v;
    }
    if v <= iso {
        0.5 * v / iso
    } else {
        0.5 + 0.5 * (v - iso) / (1.0 - iso)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn density_is_one_half_on_every_analytic_surface() {
        let w = 0.05;
        let cases = [
            (
                ToolShape::Sphere { radius_fu: 0.3 },
                Vec3::new(0.3, 0.0, 0.0),
            ),
            (
                ToolShape::Ellipsoid {
                    radii_fu: Vec3::new(0.3, 0.2, 0.1),
                },
                Vec3::new(0.0, 0.0, 0.1),
            ),
            (
                ToolShape::Box {
                    half_extents_fu: Vec3::new(0.3, 0.2, 0.1),
                },
                Vec3::new(0.1, 0.2, 0.0),
            ),
            (
                ToolShape::Cylinder {
                    radius_fu: 0.2,
                    half_height_fu: 0.4,
                },
                Vec3::new(0.0, 0.2, 0.1),
            ),
            (
                ToolShape::Capsule {
                    radius_fu: 0.2,
                    half_height_fu: 0.4,
                },
                Vec3::new(0.0, 0.0, 0.6),
            ),
        ];
        for (shape, surface) in cases {
            shape.validate().unwrap();
            assert!((shape.density(surface, w) - 0.5).abs() < 1e-4, "{shape:?}");
            assert!(shape.density(Vec3::ZERO, w) > 0.99);
            let far = shape.influence_half_extents(w) * 1.01;
            assert_eq!(shape.density(far, w), 0.0);
        }
    }

    #[test]
    fn the_sphere_curve_leaves_the_sphere_tool_as_it_was() {
        let w = 0.05;
        let round = ToolShape::round(0.3, FalloffCurve::Sphere);
        assert_eq!(round, ToolShape::Sphere { radius_fu: 0.3 });
        let profiled = ToolShape::Profiled {
            radius_fu: 0.3,
            curve: FalloffCurve::Sphere,
        };
        for i in 0..50 {
            let p = Vec3::new(0.013 * i as f32, -0.007 * i as f32, 0.3 - 0.011 * i as f32);
            assert_eq!(profiled.density(p, w), round.density(p, w), "{p}");
        }
        let sharp = ToolShape::round(0.3, FalloffCurve::Sharp);
        assert!(matches!(sharp, ToolShape::Profiled { .. }));
        // Its tip is on the axis at the full radius, its edge on the middle plane.
        assert!((sharp.signed_distance(Vec3::new(0.0, 0.0, 0.3)).unwrap()).abs() < 1e-6);
        assert!((sharp.signed_distance(Vec3::new(0.3, 0.0, 0.0)).unwrap()).abs() < 1e-6);
        assert!(sharp.signed_distance(Vec3::new(0.15, 0.0, 0.1)).unwrap() > 0.0);
        assert!(
            ToolShape::round(
                0.3,
                FalloffCurve::Custom(vec![[0.0, 1.0], [0.5, 2.0], [1.0, 0.0]])
            )
            .validate()
            .is_err()
        );
    }

    #[test]
    fn ramp_is_c1_and_monotone() {
        let w = 0.1;
        let mut last = 1.0;
        for s in 0..=100 {
            let d = -0.15 + 0.3 * s as f32 / 100.0;
            let t = density_from_distance(d, w);
            assert!(t <= last + 1e-7);
            last = t;
        }
        assert_eq!(density_from_distance(-w, w), 1.0);
        assert_eq!(density_from_distance(w, w), 0.0);
    }

    #[test]
    fn rotated_bounds_hold_the_rotated_box() {
        let pose = ToolPose {
            position_fu: Vec3::new(1.0, 2.0, 3.0),
            rotation: Quat::from_rotation_z(std::f32::consts::FRAC_PI_4),
        };
        let half = Vec3::new(1.0, 0.1, 0.1);
        let (lo, hi) = pose.world_bounds(half);
        let corner = pose.position_fu + pose.rotation * half;
        assert!(corner.cmpge(lo).all() && corner.cmple(hi).all());
        assert!((pose.to_local(corner) - half).length() < 1e-5);
    }

    #[test]
    fn freeform_tool_reads_its_lattice_with_iso_mapped_to_one_half() {
        let mut lattice = BSplineLattice::zeros([6, 6, 6], 1.0, Vec3::ZERO).unwrap();
        lattice.coeffs.update_each(|_, c| *c = 0.8);
        lattice.iso = 0.4;
        let tool = ToolShape::Freeform(FreeformTool {
            lattice,
            scale: Vec3::ONE,
        });
        tool.validate().unwrap();
        // The centre of the support is well inside the lattice, where the field is 0.8.
        let expected = 0.5 + 0.5 * (0.8 - 0.4) / 0.6;
        assert!((tool.density(Vec3::ZERO, 0.0) - expected).abs() < 1e-5);
        assert!(ToolShape::Sphere { radius_fu: -1.0 }.validate().is_err());
    }
}
