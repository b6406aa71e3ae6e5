//! Embossing and engraving an image onto the clay (Guo & Qin 2003, §5.1, on the B-spline
//! clay): the image is projected onto the surface (planar, cylindrical or spherical), its
//! brightness becomes a displacement along the surface normal (up to `depth`, outward to
//! emboss, inward to engrave), and the lattice is refitted to the displaced field (what the
//! freeze mask holds keeps its share of the old coefficients).
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

use super::clay::{Clay, FieldId};
use super::history::StepRecorder;
use super::mask::hold_before_edit;
use super::projection::{EmbossParams, Projection, frame};
use super::relief::Relief;
use super::report::{ToolError, ToolReport};
use crate::field::{CoeffBox, coeff_box_around, refit_box_edit};

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
            size_fu: size,
        } => frame(axis, up).and_then(|(_, u, r)| {
            let half = (u.abs() + r.abs()) * (0.5 * size + params.depth_fu);
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
    clay.check_dense_room(id, region)?;
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
    let held = hold_before_edit(clay, usize::from(patch), region)?;
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
    if let Some(held) = held {
        held.restore(lattice);
    }
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
                size_fu: 0.8,
            },
            depth_fu: 0.06,
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
            depth_fu: 0.05,
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
                size_fu: 1.0,
            },
            depth_fu: 0.05,
            engrave: false,
        };
        let e = apply_emboss(&mut clay, &half_white(), &params, 0, 2, None).unwrap_err();
        assert!(e.to_string().contains("not parallel"), "{e}");
        params.depth_fu = -1.0;
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
