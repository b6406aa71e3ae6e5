//! Embossing and engraving an image onto the clay (Guo & Qin 2003, §5.1, on the B-spline
//! clay): the image is projected onto the surface (planar, cylindrical or spherical), its
//! brightness becomes a displacement along the surface normal (up to `depth`, outward to
//! emboss, inward to engrave), and the lattice is refitted to the displaced field.
//!
//! The displaced field is `F'(x) = F(x − d(x)·n(x))` with `n = −∇F/|∇F|` the outward normal
//! (the clay is where `F` exceeds its iso-value) and `d(x) = ±depth·h(π(x))`, `h` the image's
//! brightness in 0..1 at the projected point. Each level set near the surface moves by `d`
//! along its normal, so the surface itself moves by the image's relief; where the field is flat
//! (far inside or outside) nothing moves. A planar projection reaches only the faces turned
//! toward it (the weight `n·axis` fades in from 0.2 to 0.5), as a slide projector would.
//!
//! Bounded input: an image is read through the size cap [`MAX_IMAGE_BYTES`] and its pixel
//! count is checked against [`MAX_IMAGE_PIXELS`] before it is decoded.

use glam::Vec3;

use super::apply::{ToolError, ToolReport};
use super::clay::{Clay, FieldId};
use super::history::StepRecorder;
use crate::field::{CoeffBox, coeff_box_around, refit_box_edit};

/// Largest image file read, bytes.
pub const MAX_IMAGE_BYTES: u64 = 64 << 20;
/// Largest image decoded, pixels (4096 × 4096).
pub const MAX_IMAGE_PIXELS: u64 = 4096 * 4096;

/// Why an image could not be used as a relief.
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The file could not be read.
    #[error("{path}: {source}")]
    Read {
        /// The file.
        path: String,
        /// Why.
        source: dynaclay_files::BoundedReadError,
    },
    /// The bytes are not a PNG or JPEG image this build decodes.
    #[error("{path}: not a readable PNG or JPEG image: {reason}")]
    Decode {
        /// The file.
        path: String,
        /// The decoder's reason.
        reason: String,
    },
    /// The image has more pixels than [`MAX_IMAGE_PIXELS`].
    #[error(
        "{path}: {width}×{height} pixels is more than the {MAX_IMAGE_PIXELS} an image may have"
    )]
    TooLarge {
        /// The file.
        path: String,
        /// Width, pixels.
        width: u32,
        /// Height, pixels.
        height: u32,
    },
}

/// An image's brightness, 0 (black) to 1 (white), row by row from the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Relief {
    width: usize,
    height: usize,
    brightness: Vec<f32>,
}

impl Relief {
    /// A relief from `brightness` values (row-major, `width × height`, each clamped to 0..1).
    ///
    /// # Panics
    /// When the length is not `width × height` or either is zero (a programming error).
    #[must_use]
    pub fn new(width: usize, height: usize, brightness: Vec<f32>) -> Self {
        assert!(width > 0 && height > 0 && brightness.len() == width * height);
        let brightness = brightness
            .into_iter()
            .map(|b| {
                if b.is_finite() {
                    b.clamp(0.0, 1.0)
                } else {
                    0.0
                }
            })
            .collect();
        Self {
            width,
            height,
            brightness,
        }
    }

    /// Decodes PNG or JPEG `bytes` as their luma (Rec. 709 weights on the decoded RGB);
    /// `name` names them in errors. Reading the file is the caller's (`io::load_relief`):
    /// the tools decode what they are given and read no file.
    ///
    /// # Errors
    /// An oversized or undecodable image, naming it.
    pub fn decode(bytes: &[u8], name: &str) -> Result<Self, ImageError> {
        let decode_error = |e: image::ImageError| ImageError::Decode {
            path: name.to_string(),
            reason: e.to_string(),
        };
        let reader = image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| ImageError::Decode {
                path: name.to_string(),
                reason: e.to_string(),
            })?;
        let (width, height) = reader.into_dimensions().map_err(decode_error)?;
        if u64::from(width) * u64::from(height) > MAX_IMAGE_PIXELS || width == 0 || height == 0 {
            return Err(ImageError::TooLarge {
                path: name.to_string(),
                width,
                height,
            });
        }
        let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| ImageError::Decode {
                path: name.to_string(),
                reason: e.to_string(),
            })?;
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(width);
        limits.max_image_height = Some(height);
        limits.max_alloc = Some(MAX_IMAGE_PIXELS * 16);
        reader.limits(limits);
        let rgb = reader.decode().map_err(decode_error)?.into_rgb32f();
        let brightness = rgb
            .pixels()
            .map(|p| 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2])
            .collect();
        Ok(Self::new(width as usize, height as usize, brightness))
    }

    /// Width and height, pixels.
    #[must_use]
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Brightness at image coordinates `(u, v)` in 0..1 (u to the right, v down), bilinear
    /// between pixel centres; `None` outside the image.
    #[must_use]
    pub fn sample(&self, u: f32, v: f32) -> Option<f32> {
        if !((0.0..=1.0).contains(&u) && (0.0..=1.0).contains(&v)) {
            return None;
        }
        let x = (u * self.width as f32 - 0.5).clamp(0.0, (self.width - 1) as f32);
        let y = (v * self.height as f32 - 0.5).clamp(0.0, (self.height - 1) as f32);
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let at = |x: usize, y: usize| self.brightness[y * self.width + x];
        let top = at(x0, y0) + (at(x1, y0) - at(x0, y0)) * fx;
        let bottom = at(x0, y1) + (at(x1, y1) - at(x0, y1)) * fx;
        Some(top + (bottom - top) * fy)
    }
}

/// How the image is laid onto the clay. Lengths are in field units, like positions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Along `axis` (pointing from the clay toward the projector) onto the faces turned toward
    /// it: a square image `size` wide centred on `centre`, its top toward `up`.
    Planar {
        /// The image's centre.
        centre: Vec3,
        /// Direction the image is projected from.
        axis: Vec3,
        /// The image's up direction (made perpendicular to `axis`).
        up: Vec3,
        /// The image's width and height.
        size: f32,
    },
    /// Wrapped once around `axis` through `centre` (the image's centre facing `up`, reading
    /// left to right counter-clockwise about `axis`, its seam opposite), `height` tall along
    /// the axis.
    Cylindrical {
        /// A point on the axis, at the image's mid-height.
        centre: Vec3,
        /// The cylinder's axis (the image's up).
        axis: Vec3,
        /// Where the image's centre faces (made perpendicular to `axis`).
        up: Vec3,
        /// The image's height along the axis.
        height: f32,
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
    pub depth: f32,
    /// Inward (engrave) instead of outward (emboss).
    pub engrave: bool,
}

/// An orthonormal frame from an axis and a direction near the second axis.
fn frame(axis: Vec3, up: Vec3) -> Option<(Vec3, Vec3, Vec3)> {
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
        positive("depth", self.depth)?;
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
                size,
            } => positive("size", size).and(axes(centre, axis, up))?,
            Projection::Cylindrical {
                centre,
                axis,
                up,
                height,
            } => positive("height", height).and(axes(centre, axis, up))?,
            Projection::Spherical { centre, up } => {
                if !centre.is_finite() || up.try_normalize().is_none() {
                    return Err(EmbossParamsError::BadUp);
                }
            }
        }
        Ok(())
    }

    /// The displacement of the surface point `x` with outward unit normal `normal` along
    /// that normal, field units: `±depth · brightness · weight` (positive outward when
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
        sign * self.depth * h * weight
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
                size,
            } => {
                let (a, u, _) = frame(axis, up)?;
                // The image's right as the projector (at +axis, looking back) sees it.
                let r = u.cross(a);
                let facing = normal.dot(a);
                let weight = ((facing - 0.2) / 0.3).clamp(0.0, 1.0);
                let d = x - centre;
                let (s, t) = (d.dot(r) / size + 0.5, 0.5 - d.dot(u) / size);
                (weight > 0.0).then_some((s, t, weight))
            }
            Projection::Cylindrical {
                centre,
                axis,
                up,
                height,
            } => {
                let (a, u, r) = frame(axis, up)?;
                let d = x - centre;
                let angle = d.dot(r).atan2(d.dot(u));
                let s = (angle + PI) / TAU;
                let t = 0.5 - d.dot(a) / height;
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

/// Embosses (or engraves) `relief` onto density patch `patch` of `clay`, as one refit of the
/// coefficients the projection reaches, recorded in `recorder` for undo.
///
/// # Errors
/// [`ToolError::NoPatch`] for a missing patch, [`ToolError::Action`] for invalid parameters,
/// [`ToolError::Fit`] when the refit fails (the clay is unchanged then).
pub fn apply_emboss(
    clay: &mut Clay,
    relief: &Relief,
    params: &EmbossParams,
    patch: u16,
    samples_per_span: usize,
    recorder: Option<&mut StepRecorder>,
) -> Result<ToolReport, ToolError> {
    params.validate()?;
    let id = FieldId::Density(patch);
    let Some(lattice) = clay.field(id) else {
        return Err(ToolError::NoPatch { patch });
    };
    // Every coefficient whose support reaches the moved surface: the whole lattice, less
    // what a planar projection's square cannot reach across it.
    let (lo, hi) = lattice.support();
    let reach = match params.projection {
        Projection::Planar {
            centre,
            axis,
            up,
            size,
        } => frame(axis, up).and_then(|(_, u, r)| {
            let half = (u.abs() + r.abs()) * (0.5 * size + params.depth);
            let (a, b) = (centre - half, centre + half);
            // Along the axis the projection crosses the whole clay.
            let along = axis.normalize().abs();
            let sweep = |v: Vec3, clay: Vec3| v * (Vec3::ONE - along) + clay * along;
            let (a, b) = (sweep(a, lo).max(lo), sweep(b, hi).min(hi));
            (a.cmple(b).all()).then_some((a, b))
        }),
        _ => Some((lo, hi)),
    };
    let Some((a, b)) = reach else {
        return Ok(ToolReport::default());
    };
    let Some(region) = coeff_box_around(lattice, a, b, 2) else {
        return Ok(ToolReport::default());
    };
    // The whole clay before the edit: the relief moves the sum's surface (eq. (3)), and the
    // edited patch takes the change.
    let spacing = lattice.spacing;
    let before = clay.density.clone();
    let edited = &before.patches[usize::from(patch)];
    let others = |x: Vec3| before.value(x) - edited.value(x);
    let iso = before.iso();
    if let Some(r) = recorder {
        r.touch(clay, id, region);
    }
    let visited = std::cell::Cell::new(0usize);
    let dirtied = std::cell::Cell::new(0usize);
    let displaced = |x: Vec3, old: f32| {
        visited.set(visited.get() + 1);
        let gradient = before.value_and_gradient(x).1;
        let Some(normal) = (-gradient).try_normalize() else {
            return old;
        };
        // Only level sets near the surface carry the relief (a flat field has no normal).
        if gradient.length() < 1e-3 * (iso.abs() + 1.0) / spacing {
            return old;
        }
        let d = params.displacement(relief, x, normal);
        if d == 0.0 {
            return old;
        }
        dirtied.set(dirtied.get() + 1);
        before.value(x - d * normal) - others(x)
    };
    let lattice = clay.field_mut(id).expect("checked above");
    refit_box_edit(lattice, region.min, region.max, samples_per_span, displaced)?;
    let dirty_world = Some((
        lattice.node_position(region.min[0], region.min[1], region.min[2]),
        lattice.node_position(region.max[0], region.max[1], region.max[2]),
    ));
    Ok(ToolReport {
        patch,
        coeff_box: Some(CoeffBox {
            min: region.min,
            max: region.max,
        }),
        dirty_world,
        visited: visited.get(),
        computed: visited.get(),
        dirtied: dirtied.get(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::BSplineLattice;

    /// A ball of radius 0.6 at (1, 1, 1) on a 32³ lattice (density 1 inside, 0 outside, iso
    /// 0.5, a smooth step of about two spans).
    fn ball() -> Clay {
        let spacing = 2.0 / 29.0;
        let mut l = BSplineLattice::zeros([32, 32, 32], spacing, Vec3::splat(-spacing)).unwrap();
        l.iso = 0.5;
        let centre = Vec3::ONE;
        crate::field::refit_box(&mut l, [0; 3], [31; 3], 2, |x| {
            let r = (x - centre).length();
            (0.5 - (r - 0.6) / (4.0 * spacing)).clamp(0.0, 1.0)
        })
        .unwrap();
        Clay::single(l)
    }

    /// Distance from `centre` to the surface along `dir` (bisection on the iso-value).
    fn radius_along(l: &BSplineLattice, centre: Vec3, dir: Vec3) -> f32 {
        let (mut a, mut b) = (0.0f32, 1.0f32);
        for _ in 0..40 {
            let m = 0.5 * (a + b);
            if l.value(centre + dir * m) > l.iso {
                a = m;
            } else {
                b = m;
            }
        }
        0.5 * (a + b)
    }

    /// A relief that is white on its left half and black on its right.
    fn half_white() -> Relief {
        let (w, h) = (16, 16);
        let b = (0..w * h)
            .map(|i| if i % w < w / 2 { 1.0 } else { 0.0 })
            .collect();
        Relief::new(w, h, b)
    }

    #[test]
    fn a_planar_emboss_raises_the_white_half_by_the_depth_and_leaves_the_black_half() {
        let mut clay = ball();
        let before = clay.density.patches[0].lattice.clone();
        let centre = Vec3::ONE;
        let params = EmbossParams {
            projection: Projection::Planar {
                centre: Vec3::new(1.0, 1.6, 1.0),
                axis: Vec3::Y,
                up: Vec3::Z,
                size: 0.8,
            },
            depth: 0.06,
            engrave: false,
        };
        let mut rec = StepRecorder::new("emboss");
        let report = apply_emboss(&mut clay, &half_white(), &params, 0, 2, Some(&mut rec)).unwrap();
        assert!(report.dirtied > 0);
        let after = &clay.density.patches[0].lattice;
        // Seen from +y looking down with z up, the image's left (white) is +x.
        let white = Vec3::new(0.25, 1.0, 0.0).normalize();
        let black = Vec3::new(-0.25, 1.0, 0.0).normalize();
        let grown = radius_along(after, centre, white) - radius_along(&before, centre, white);
        let kept = radius_along(after, centre, black) - radius_along(&before, centre, black);
        assert!(
            (grown - 0.06).abs() < 0.015,
            "white raised by {grown}, depth 0.06"
        );
        assert!(kept.abs() < 0.01, "black moved by {kept}");
        // The far side, turned away from the projector, is untouched.
        let back = radius_along(after, centre, -Vec3::Y) - radius_along(&before, centre, -Vec3::Y);
        assert!(back.abs() < 1e-3, "back moved by {back}");
        // Undo restores the field bit for bit.
        let step = rec.finish(&clay).expect("the emboss changed the clay");
        let mut history = crate::tools::History::new(usize::MAX);
        history.push(step);
        history.undo(&mut clay).unwrap();
        assert_eq!(clay.density.patches[0].lattice, before);
    }

    #[test]
    fn engraving_cuts_in_by_the_depth() {
        let mut clay = ball();
        let before = clay.density.patches[0].lattice.clone();
        let params = EmbossParams {
            projection: Projection::Spherical {
                centre: Vec3::ONE,
                up: Vec3::Z,
            },
            depth: 0.05,
            engrave: true,
        };
        let white = Relief::new(2, 2, vec![1.0; 4]);
        apply_emboss(&mut clay, &white, &params, 0, 2, None).unwrap();
        for dir in [
            Vec3::X,
            Vec3::Y,
            -Vec3::Z,
            Vec3::new(1.0, 1.0, 1.0).normalize(),
        ] {
            let cut = radius_along(&before, Vec3::ONE, dir)
                - radius_along(&clay.density.patches[0].lattice, Vec3::ONE, dir);
            assert!((cut - 0.05).abs() < 0.012, "{dir}: cut {cut}");
        }
    }

    #[test]
    fn bad_parameters_and_images_are_refused_with_what_is_wrong() {
        let mut clay = ball();
        let mut params = EmbossParams {
            projection: Projection::Planar {
                centre: Vec3::ONE,
                axis: Vec3::Y,
                up: Vec3::Y,
                size: 1.0,
            },
            depth: 0.05,
            engrave: false,
        };
        let e = apply_emboss(&mut clay, &half_white(), &params, 0, 2, None).unwrap_err();
        assert!(e.to_string().contains("not parallel"), "{e}");
        params.depth = -1.0;
        assert!(params.validate().unwrap_err().to_string().contains("depth"));
        let e = Relief::decode(b"not an image", "x.png").unwrap_err();
        assert!(e.to_string().starts_with("x.png: not a readable"), "{e}");
    }

    #[test]
    fn a_png_decodes_to_its_brightness() {
        let mut png = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut png, 2, 1);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            let mut w = enc.write_header().unwrap();
            w.write_image_data(&[255, 255, 255, 0, 0, 0]).unwrap();
        }
        let relief = Relief::decode(&png, "two.png").unwrap();
        assert_eq!(relief.size(), (2, 1));
        assert!((relief.sample(0.25, 0.5).unwrap() - 1.0).abs() < 1e-6);
        assert!(relief.sample(0.75, 0.5).unwrap().abs() < 1e-6);
        assert!(relief.sample(1.5, 0.5).is_none());
    }
}
