//! A coloured point cloud's colours as the clay's paint: the [`ColourField`] over the base
//! lattice's nodes (the layout the clay's paint brush writes), fitted by least squares to the
//! colour of the nearest points.
//!
//! The colour target at a field point is the mean colour of its [`NEIGHBOURS`] nearest cloud
//! points (a scan's colours are noisy point to point; a few neighbours smooth them without
//! blurring across more than a point spacing). Each of red, green and blue is fitted to that
//! target over the whole lattice ([`fit_lattice`], two samples per knot span), so the paint
//! on the surface is the points' colour and off it the nearest surface colour, never the
//! unpainted material. Coverage is 1 everywhere: the scan's colours cover the material's base
//! colour. Where two colours meet, the cubic fit overshoots within about a knot span; channels
//! are clamped to `[0, 1]` where they are read ([`ColourField::rgba`]).

use std::cell::RefCell;
use std::collections::HashMap;
use std::num::NonZero;

use glam::Vec3;
use kiddo::{ImmutableKdTree, SquaredEuclidean};

use super::points::PointColours;
use dynaclay_core::field::{BSplineLattice, FitError, fit_lattice};
use dynaclay_core::tools::ColourField;

/// Cloud points whose colours are averaged for each sample of the fit.
pub const NEIGHBOURS: usize = 6;

/// Why a cloud's colours could not be made into paint.
#[derive(Debug, thiserror::Error)]
pub enum PaintError {
    /// The colours do not pair one to one with the points.
    #[error("{colours} colours for {points} points: each point needs exactly one colour")]
    CountMismatch {
        /// Points in the cloud.
        points: usize,
        /// Colours given.
        colours: usize,
    },
    /// No points to take colours from.
    #[error("no points to take colours from")]
    Empty,
    /// A point is not finite, so no nearest-point index can hold it.
    #[error("point {index} is not finite: {at:?}")]
    NonFinitePoint {
        /// The point's index in the cloud.
        index: usize,
        /// Its position.
        at: Vec3,
    },
    /// The nearest-point index could not be built.
    #[error("the nearest-point index: {0}")]
    Index(String),
    /// The base lattice's geometry cannot carry a colour field, or the fit failed.
    #[error("the colour lattice: {0}")]
    Lattice(String),
    /// The least-squares fit of a channel failed.
    #[error("the colour fit: {0}")]
    Fit(#[from] FitError),
}

/// The paint of a cloud whose `points` (field units) carry `colours` (0–255), on the nodes
/// of `base` (the clay's base lattice).
///
/// # Errors
/// [`PaintError`]: colours not one per point, no points, a point that is not finite, or a
/// failed fit.
pub fn paint_from_cloud(
    base: &BSplineLattice,
    points: &[Vec3],
    colours: &PointColours,
) -> Result<ColourField, PaintError> {
    if points.len() != colours.len() {
        return Err(PaintError::CountMismatch {
            points: points.len(),
            colours: colours.len(),
        });
    }
    if points.is_empty() {
        return Err(PaintError::Empty);
    }
    if let Some((index, &at)) = points.iter().enumerate().find(|(_, p)| !p.is_finite()) {
        return Err(PaintError::NonFinitePoint { index, at });
    }
    let at: Vec<[f32; 3]> = points.iter().map(|p| p.to_array()).collect();
    let tree: ImmutableKdTree<f32, 3> =
        ImmutableKdTree::new_from_slice(&at).map_err(|e| PaintError::Index(format!("{e:?}")))?;
    let want = NonZero::new(NEIGHBOURS.min(points.len())).unwrap_or(NonZero::<usize>::MIN);
    // The three channels are fitted at the same samples: each sample's colour is found once.
    let seen: RefCell<HashMap<[u32; 3], Vec3>> = RefCell::new(HashMap::new());
    let colour_at = |x: Vec3| -> Vec3 {
        let key = x.to_array().map(f32::to_bits);
        if let Some(&c) = seen.borrow().get(&key) {
            return c;
        }
        let found = tree
            .query(&x.to_array())
            .nearest_n::<SquaredEuclidean<f32>>(want)
            .execute();
        let sum: Vec3 = found
            .iter()
            .map(|n| {
                let [r, g, b] = colours[n.item as usize];
                Vec3::new(f32::from(r), f32::from(g), f32::from(b))
            })
            .sum();
        let c = sum / (255.0 * found.len().max(1) as f32);
        seen.borrow_mut().insert(key, c);
        c
    };
    let mut paint = ColourField::matching(base).map_err(|e| PaintError::Lattice(e.to_string()))?;
    for (channel, lattice) in paint.channels.iter_mut().take(3).enumerate() {
        fit_lattice(lattice, 2, |x| colour_at(x)[channel])?;
    }
    // Coverage 1: B-spline weights sum to one, so equal coefficients are that value
    // everywhere.
    paint.channels[3].coeffs.fill(1.0);
    Ok(paint)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mismatched_or_empty_colours_are_refused() {
        let base = BSplineLattice::zeros([8; 3], 0.1, Vec3::ZERO).unwrap();
        let e = paint_from_cloud(&base, &[Vec3::ONE * 0.3], &vec![]).unwrap_err();
        assert!(
            matches!(
                e,
                PaintError::CountMismatch {
                    points: 1,
                    colours: 0
                }
            ),
            "{e}"
        );
        assert!(e.to_string().contains("0 colours for 1 points"), "{e}");
        let e = paint_from_cloud(&base, &[], &vec![]).unwrap_err();
        assert!(matches!(e, PaintError::Empty), "{e}");
        let e = paint_from_cloud(&base, &[Vec3::NAN], &vec![[1, 2, 3]]).unwrap_err();
        assert!(
            matches!(e, PaintError::NonFinitePoint { index: 0, .. }),
            "{e}"
        );
    }

    #[test]
    fn two_colour_halves_paint_the_lattice_by_their_side() {
        // Points on the plane x = 0.35 of a 0.7-wide lattice: red below y = 0.35, blue above.
        let base = BSplineLattice::zeros([8; 3], 0.1, Vec3::ZERO).unwrap();
        let mut points = Vec::new();
        let mut colours = Vec::new();
        for j in 0..40 {
            for k in 0..40 {
                let p = Vec3::new(0.35, j as f32 * 0.7 / 39.0, k as f32 * 0.7 / 39.0);
                points.push(p);
                colours.push(if p.y < 0.35 { [255, 0, 0] } else { [0, 0, 255] });
            }
        }
        let paint = paint_from_cloud(&base, &points, &colours).unwrap();
        assert!(paint.is_consistent());
        let low = paint.rgba(Vec3::new(0.35, 0.1, 0.35));
        let high = paint.rgba(Vec3::new(0.35, 0.6, 0.35));
        assert!(low.x > 0.9 && low.z < 0.1 && low.w > 0.99, "{low}");
        assert!(high.z > 0.9 && high.x < 0.1 && high.w > 0.99, "{high}");
    }
}
