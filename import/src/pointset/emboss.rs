//! Embossing and engraving an image onto a point-set surface (Guo & Qin 2003, §5.1): each
//! point moves along its normal by the image's brightness where the projection lays it
//! ([`EmbossParams::displacement`], the same projection and relief as the clay's emboss tool),
//! then the surface is rebuilt from the moved points: normals estimated and oriented again
//! (the relief's walls turn them) and every local field refitted by eq. (4). Colours stay with
//! their points.

use glam::Vec3;

use super::error::PointSetError;
use super::surface::{PointSet, PointSetOptions};
use crate::fit::PointCloud;
use dynaclay_core::tools::{EmbossParams, Relief};

/// What an emboss did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EmbossReport {
    /// Points that moved.
    pub moved: usize,
    /// The largest displacement, field units.
    pub largest: f32,
}

/// Embosses (or engraves) `relief` onto `set` by `params`; returns the rebuilt surface.
///
/// # Errors
/// [`PointSetError::Emboss`] for invalid parameters; as [`PointSet::build`] when the moved
/// points cannot carry a surface.
pub fn emboss(
    set: &PointSet,
    relief: &Relief,
    params: &EmbossParams,
    options: &PointSetOptions,
) -> Result<(PointSet, EmbossReport), PointSetError> {
    params.validate().map_err(PointSetError::Emboss)?;
    let mut report = EmbossReport::default();
    let points: Vec<Vec3> = set
        .points
        .iter()
        .zip(&set.normals)
        .map(|(&p, &n)| {
            let d = params.displacement(relief, p, n);
            if d != 0.0 {
                report.moved += 1;
                report.largest = report.largest.max(d.abs());
            }
            p + d * n
        })
        .collect();
    let cloud = PointCloud {
        points,
        normals: None,
    };
    let (mut embossed, _) = PointSet::build(&cloud, options)?;
    embossed.colours.clone_from(&set.colours);
    Ok((embossed, report))
}

#[cfg(test)]
mod tests {
    use super::*;
    use dynaclay_core::tools::Projection;

    /// A Fibonacci sphere of `count` points, radius 1 about the origin.
    fn sphere(count: usize) -> PointCloud {
        let golden = std::f32::consts::PI * (3.0 - 5.0_f32.sqrt());
        let points = (0..count)
            .map(|i| {
                let y = 1.0 - 2.0 * (i as f32 + 0.5) / count as f32;
                let r = (1.0 - y * y).sqrt();
                let a = golden * i as f32;
                Vec3::new(r * a.cos(), y, r * a.sin())
            })
            .collect();
        PointCloud {
            points,
            normals: None,
        }
    }

    /// Where the blended surface crosses the ray from the origin along `dir` (bisection
    /// between radius 0.7 and 1.4; the field is positive inside).
    fn radius_along(set: &PointSet, dir: Vec3) -> f32 {
        let (mut inside, mut outside) = (0.7_f32, 1.4_f32);
        assert!(set.blend(dir * inside).0 > 0.0 && set.blend(dir * outside).0 < 0.0);
        for _ in 0..40 {
            let mid = 0.5 * (inside + outside);
            if set.blend(dir * mid).0 > 0.0 {
                inside = mid;
            } else {
                outside = mid;
            }
        }
        0.5 * (inside + outside)
    }

    /// An 8 × 4 checkerboard of `px`-pixel squares, white where `(column + row)` is even.
    fn checkerboard(px: usize) -> Relief {
        let (w, h) = (8 * px, 4 * px);
        let brightness = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w / px, i / w / px);
                if (x + y) % 2 == 0 { 1.0 } else { 0.0 }
            })
            .collect();
        Relief::new(w, h, brightness)
    }

    /// The direction of the centre of square (column, row) of an 8 × 4 board under the
    /// spherical projection with its pole at +y: longitude `s·2π − π` about the pole from the
    /// frame's first axis, latitude `t·π` from the pole.
    fn square_centre(column: usize, row: usize) -> Vec3 {
        use std::f32::consts::{PI, TAU};
        let (s, t) = ((column as f32 + 0.5) / 8.0, (row as f32 + 0.5) / 4.0);
        let pole = Vec3::Y;
        let u = pole.any_orthonormal_vector();
        let r = pole.cross(u);
        let (lon, lat) = (s * TAU - PI, t * PI);
        pole * lat.cos() + (u * lon.cos() + r * lon.sin()) * lat.sin()
    }

    #[test]
    fn a_checkerboard_on_a_sphere_raises_the_white_squares_by_the_depth_and_leaves_the_black() {
        let (set, _) = PointSet::build(&sphere(12_000), &PointSetOptions::default()).unwrap();
        let depth = 0.06;
        let params = EmbossParams {
            projection: Projection::Spherical {
                centre: Vec3::ZERO,
                up: Vec3::Y,
            },
            depth_fu: depth,
            engrave: false,
        };
        let board = checkerboard(16);
        let (embossed, report) =
            emboss(&set, &board, &params, &PointSetOptions::default()).unwrap();
        assert!(report.moved > 4000, "{report:?}");
        assert!((report.largest - depth).abs() < 1e-4, "{report:?}");
        assert_eq!(embossed.len(), set.len());
        // The squares of the two middle rows (the polar rows are pinched at the poles).
        let (mut white, mut black) = (Vec::new(), Vec::new());
        for row in 1..3 {
            for column in 0..8 {
                let dir = square_centre(column, row);
                let white_here = (column + row) % 2 == 0;
                // The projection puts this square here.
                let asked = params.displacement(&board, dir, dir);
                assert_eq!(asked, if white_here { depth } else { 0.0 });
                let rise = radius_along(&embossed, dir) - radius_along(&set, dir);
                if white_here {
                    white.push(rise);
                } else {
                    black.push(rise);
                }
            }
        }
        eprintln!("rise of the white squares {white:?}, of the black squares {black:?}");
        for rise in &white {
            assert!(
                (rise - depth).abs() <= 0.1 * depth,
                "a white square rose by {rise} (depth {depth}): {white:?}"
            );
        }
        for rise in &black {
            assert!(
                rise.abs() <= 0.1 * depth,
                "a black square moved by {rise}: {black:?}"
            );
        }

        // Engraving sinks the white squares instead.
        let engrave = EmbossParams {
            engrave: true,
            ..params
        };
        let (engraved, _) = emboss(&set, &board, &engrave, &PointSetOptions::default()).unwrap();
        let dir = square_centre(0, 2);
        let sink = radius_along(&engraved, dir) - radius_along(&set, dir);
        assert!((sink + depth).abs() <= 0.1 * depth, "engraved by {sink}");
    }

    #[test]
    fn bad_parameters_are_refused() {
        let (set, _) = PointSet::build(&sphere(400), &PointSetOptions::default()).unwrap();
        let params = EmbossParams {
            projection: Projection::Spherical {
                centre: Vec3::ZERO,
                up: Vec3::Y,
            },
            depth_fu: -1.0,
            engrave: false,
        };
        let e = emboss(&set, &checkerboard(2), &params, &PointSetOptions::default())
            .expect_err("a negative depth");
        assert!(e.to_string().contains("depth"), "{e}");
    }
}
