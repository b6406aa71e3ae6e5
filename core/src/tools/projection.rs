//! How an emboss's image lies on the clay (Guo & Qin 2003, §5.1): the planar, cylindrical
//! and spherical projections, the emboss's parameters and their checks, and the displacement
//! each surface point takes.

use glam::Vec3;

use super::relief::Relief;

/// How the image is laid onto the clay. Lengths are in field units, like positions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Along `axis` (pointing from the clay toward the projector) onto the faces turned toward
    /// it: a square image `size_fu` wide centred on `centre`, its top toward `up`.
    Planar {
        /// The image's centre.
        centre: Vec3,
        /// Direction the image is projected from.
        axis: Vec3,
        /// The image's up direction (made perpendicular to `axis`).
        up: Vec3,
        /// The image's width and height, field units.
        size_fu: f32,
    },
    /// Wrapped once around `axis` through `centre` (the image's centre facing `up`, reading
    /// left to right counter-clockwise about `axis`, its seam opposite), `height_fu` tall along
    /// the axis.
    Cylindrical {
        /// A point on the axis, at the image's mid-height.
        centre: Vec3,
        /// The cylinder's axis (the image's up).
        axis: Vec3,
        /// Where the image's centre faces (made perpendicular to `axis`).
        up: Vec3,
        /// The image's height along the axis, field units.
        height_fu: f32,
    },
    /// Longitude and latitude about `centre`: the image's top at the pole `up`.
    Spherical {
        /// The sphere's centre.
        centre: Vec3,
        /// The north pole's direction.
        up: Vec3,
    },
}

/// An emboss or engrave.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmbossParams {
    /// How the image lies on the clay.
    pub projection: Projection,
    /// Displacement of white, field units (black: none).
    pub depth_fu: f32,
    /// Inward (engrave) instead of outward (emboss).
    pub engrave: bool,
}

/// An orthonormal frame from an axis and a direction near the second axis.
pub(super) fn frame(axis: Vec3, up: Vec3) -> Option<(Vec3, Vec3, Vec3)> {
    let a = axis.try_normalize()?;
    let u = (up - a * up.dot(a)).try_normalize()?;
    Some((a, u, a.cross(u)))
}

/// Why emboss parameters were refused (named as in the script).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
pub enum EmbossParamsError {
    /// A length (`depth`, a planar `size`, a cylindrical `height`) is not positive and finite.
    #[error("{name} = {value} must be positive")]
    NotPositive {
        /// The parameter.
        name: &'static str,
        /// Its value.
        value: f32,
    },
    /// A planar or cylindrical projection's frame.
    #[error("axis and up must be finite, non-zero and not parallel")]
    BadAxes,
    /// A spherical projection's `up` (or its centre).
    #[error("up must be finite and non-zero")]
    BadUp,
}

impl EmbossParams {
    /// Checks the parameters.
    ///
    /// # Errors
    /// The first invalid one, named as in the script.
    pub fn validate(&self) -> Result<(), EmbossParamsError> {
        let positive = |name: &'static str, value: f32| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(EmbossParamsError::NotPositive { name, value })
            }
        };
        positive("depth", self.depth_fu)?;
        let axes = |centre: Vec3, axis: Vec3, up: Vec3| {
            if centre.is_finite() && frame(axis, up).is_some() {
                Ok(())
            } else {
                Err(EmbossParamsError::BadAxes)
            }
        };
        match self.projection {
            Projection::Planar {
                centre,
                axis,
                up,
                size_fu,
            } => positive("size", size_fu).and(axes(centre, axis, up))?,
            Projection::Cylindrical {
                centre,
                axis,
                up,
                height_fu,
            } => positive("height", height_fu).and(axes(centre, axis, up))?,
            Projection::Spherical { centre, up } => {
                if !centre.is_finite() || up.try_normalize().is_none() {
                    return Err(EmbossParamsError::BadUp);
                }
            }
        }
        Ok(())
    }

    /// The displacement of the surface point `x` with outward unit normal `normal` along
    /// that normal, field units: `±depth_fu · brightness · weight` (positive outward when
    /// embossing, inward when engraving), 0 where the image does not reach.
    #[must_use]
    pub fn displacement(&self, relief: &Relief, x: Vec3, normal: Vec3) -> f32 {
        let Some((s, t, weight)) = self.project(x, normal) else {
            return 0.0;
        };
        let Some(h) = relief.sample(s, t) else {
            return 0.0;
        };
        let sign = if self.engrave { -1.0 } else { 1.0 };
        sign * self.depth_fu * h * weight
    }

    /// The image coordinates of `x` on a surface with outward normal `normal`, and the
    /// weight of the relief there (0 to 1); `None` where the image does not reach.
    fn project(&self, x: Vec3, normal: Vec3) -> Option<(f32, f32, f32)> {
        use std::f32::consts::{PI, TAU};
        match self.projection {
            Projection::Planar {
                centre,
                axis,
                up,
                size_fu,
            } => {
                let (a, u, _) = frame(axis, up)?;
                // The image's right as the projector (at +axis, looking back) sees it.
                let r = u.cross(a);
                let facing = normal.dot(a);
                let weight = ((facing - 0.2) / 0.3).clamp(0.0, 1.0);
                let d = x - centre;
                let (s, t) = (d.dot(r) / size_fu + 0.5, 0.5 - d.dot(u) / size_fu);
                (weight > 0.0).then_some((s, t, weight))
            }
            Projection::Cylindrical {
                centre,
                axis,
                up,
                height_fu,
            } => {
                let (a, u, r) = frame(axis, up)?;
                let d = x - centre;
                let angle = d.dot(r).atan2(d.dot(u));
                let s = (angle + PI) / TAU;
                let t = 0.5 - d.dot(a) / height_fu;
                Some((s, t, 1.0))
            }
            Projection::Spherical { centre, up } => {
                let pole = up.try_normalize()?;
                let (_, u, r) = frame(pole, pole.any_orthonormal_vector())?;
                let d = (x - centre).try_normalize()?;
                let longitude = d.dot(r).atan2(d.dot(u));
                let latitude = d.dot(pole).clamp(-1.0, 1.0).acos();
                Some(((longitude + PI) / TAU, latitude / PI, 1.0))
            }
        }
    }
}
