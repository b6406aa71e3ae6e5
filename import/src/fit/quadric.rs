//! The scatter of a point's neighbours across the surface with its curvature taken out: the
//! root mean square height of the neighbours off the quadric height function
//! `h = a u² + b uv + c v² + d u + e v + f` fitted to them by least squares in the point's
//! tangent frame, over `k − 6` degrees of freedom (six parameters fitted to `k` heights).
//!
//! A plane through a sparse cloud's neighbours, over the wide radius it needs to hold a
//! dozen of them, lies off the curved surface by its sag, and their scatter about it reads
//! the curvature as noise; about the quadric it reads the noise alone (on a sphere of radius
//! 1 sampled by 1 000 points, a noise of 0.005 reads 0.0049, where the planes read 0.0096).
//! Where no quadric follows the points (an edge, a corner, a thin wall within the radius),
//! the scatter is structured and larger.
//!
//! Read by the screening for a sparse cloud's noise
//! ([`super::consensus::Consensus::noise_off_quadrics`]) and by the sharpness
//! ([`super::sharpness`]), whose readings are this scatter over the noise.

use glam::{DVec3, Vec3};

/// The fewest neighbours a quadric is fitted to: six parameters, and as many degrees of
/// freedom left to read the scatter from.
pub(crate) const QUADRIC_FEWEST: usize = 9;

/// The normal equations of a quadric height function about one point, built up one
/// neighbour at a time ([`QuadricHeights::add`]) and solved once ([`QuadricHeights::scatter`]).
pub(crate) struct QuadricHeights {
    /// The point the heights are measured from.
    origin: DVec3,
    /// The tangent frame: two axes across the normal, and the normal.
    axes: [DVec3; 3],
    /// The length the coordinates are measured in (a neighbourhood's radius), so that the
    /// equations' entries are all of order one.
    unit: f64,
    /// `1 / unit`.
    per_unit: f64,
    /// `Σ rowᵀ row` over the neighbours, `row = [u², uv, v², u, v, 1]`.
    gram: [[f64; 6]; 6],
    /// `Σ rowᵀ h`.
    rhs: [f64; 6],
    /// `Σ h²`.
    heights_squared: f64,
    /// Neighbours added.
    count: usize,
}

impl QuadricHeights {
    /// Heights measured along `normal` (unit length) from `origin`, in units of `unit` (the
    /// neighbourhood's radius: positive and finite).
    pub(crate) fn about(origin: DVec3, normal: DVec3, unit: f64) -> Self {
        let (u_axis, v_axis) = normal.any_orthonormal_pair();
        Self {
            origin,
            axes: [u_axis, v_axis, normal],
            unit,
            per_unit: 1.0 / unit,
            gram: [[0.0; 6]; 6],
            rhs: [0.0; 6],
            heights_squared: 0.0,
            count: 0,
        }
    }

    /// Adds the neighbour at `at`.
    pub(crate) fn add(&mut self, at: Vec3) {
        let d = (at.as_dvec3() - self.origin) * self.per_unit;
        let [u, v, h] = self.axes.map(|axis| d.dot(axis));
        let row = [u * u, u * v, v * v, u, v, 1.0];
        for (r, gram_row) in self.gram.iter_mut().enumerate() {
            for (entry, c) in gram_row.iter_mut().zip(row) {
                *entry += row[r] * c;
            }
            self.rhs[r] += row[r] * h;
        }
        self.heights_squared += h * h;
        self.count += 1;
    }

    /// The neighbours' root mean square height off their least-squares quadric, over
    /// `count − 6` degrees of freedom, in the points' units; `None` with fewer than
    /// [`QUADRIC_FEWEST`] neighbours or where they do not fix a quadric (all on a line, or
    /// at one place).
    pub(crate) fn scatter(&self) -> Option<f64> {
        if self.count < QUADRIC_FEWEST {
            return None;
        }
        // Elimination with partial pivoting; the residual sum of squares is Σ h² − xᵀ rhs at
        // the least-squares solution x.
        let mut a = self.gram;
        let mut x = self.rhs;
        // A pivot this small against the equations' largest diagonal entry leaves the quadric
        // undetermined.
        let scale = (0..6).map(|k| self.gram[k][k]).fold(0.0f64, f64::max);
        for col in 0..6 {
            let pivot = (col..6).max_by(|&r, &s| a[r][col].abs().total_cmp(&a[s][col].abs()))?;
            if a[pivot][col].abs() <= 1e-12 * scale {
                return None;
            }
            a.swap(col, pivot);
            x.swap(col, pivot);
            let pivot_row = a[col];
            for r in col + 1..6 {
                let f = a[r][col] / pivot_row[col];
                for (entry, above) in a[r][col..].iter_mut().zip(&pivot_row[col..]) {
                    *entry -= f * above;
                }
                x[r] -= f * x[col];
            }
        }
        for col in (0..6).rev() {
            let mut s = x[col];
            for c in col + 1..6 {
                s -= a[col][c] * x[c];
            }
            x[col] = s / a[col][col];
        }
        let explained: f64 = x.iter().zip(&self.rhs).map(|(x, b)| x * b).sum();
        let residual = (self.heights_squared - explained).max(0.0);
        let scatter = (residual / (self.count - 6) as f64).sqrt() * self.unit;
        scatter.is_finite().then_some(scatter)
    }
}

/// The median of `scatters` (`None` where it is empty).
pub(crate) fn median_scatter(mut scatters: Vec<f32>) -> Option<f32> {
    if scatters.is_empty() {
        return None;
    }
    let mid = scatters.len() / 2;
    Some(*scatters.select_nth_unstable_by(mid, f32::total_cmp).1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_on_a_quadric_have_no_scatter_and_a_plane_needs_more_than_a_line() {
        // Heights exactly quadratic in the tangent plane (a saddle, tilted): no scatter.
        let mut on_quadric = QuadricHeights::about(DVec3::ZERO, DVec3::Z, 0.5);
        for i in 0..5 {
            for j in 0..5 {
                let (u, v) = (i as f32 * 0.1 - 0.2, j as f32 * 0.1 - 0.2);
                on_quadric.add(Vec3::new(
                    u,
                    v,
                    0.5 * u * u - 0.3 * v * v + 0.2 * u * v + 0.1 * u,
                ));
            }
        }
        let scatter = on_quadric.scatter().expect("25 points fix a quadric");
        assert!(scatter < 1e-5, "scatter {scatter} off an exact quadric");
        // Points on a line leave the quadric undetermined.
        let mut on_line = QuadricHeights::about(DVec3::ZERO, DVec3::Z, 0.5);
        for i in 0..20 {
            on_line.add(Vec3::new(i as f32 * 0.1, 0.0, 0.0));
        }
        assert_eq!(on_line.scatter(), None);
        // Too few neighbours: no reading.
        let mut few = QuadricHeights::about(DVec3::ZERO, DVec3::Z, 0.5);
        for i in 0..QUADRIC_FEWEST - 1 {
            few.add(Vec3::new(i as f32 * 0.1, (i * i) as f32 * 0.05, 0.0));
        }
        assert_eq!(few.scatter(), None);
        assert_eq!(median_scatter(vec![3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median_scatter(Vec::new()), None);
    }
}
