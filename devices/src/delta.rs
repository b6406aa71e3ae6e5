//! Delta-robot kinematics of the Novint Falcon, both ways, with the Jacobian.
//!
//! Each leg `i` has its own frame, turned by the leg's azimuth `φ` about z:
//! `U = x cos φ + y sin φ − r + c`, `V = −x sin φ + y cos φ − s + f`, `W = z`. The motor turns an
//! upper arm of length `a` in the U–W plane to the elbow `(a cos θ, a sin θ)`. The parallelogram
//! (length `b`) leans by `V` along the motor axis, so in the U–W plane the elbow-to-effector
//! distance is `L(V) = d + e + √(b² − V²)`. Each leg therefore satisfies
//! `g(θ, p) = (U − a cos θ)² + (W − a sin θ)² − L(V)² = 0` (Stamper's model of the Falcon).
//!
//! Inverse kinematics solves each leg in closed form; the Jacobian `∂θ/∂p` follows from the
//! implicit function theorem (`−g_p / g_θ`), and forward kinematics is a bounded Newton
//! iteration on it, warm-started from the last position. Allocation-free.

use glam::{DMat3, DVec3};

use crate::kinematics_error::KinematicsError;
use crate::profile::Geometry;

/// Newton iterations allowed in [`Delta::forward`].
pub const MAX_ITERATIONS: u32 = 30;
/// Joint residual at which [`Delta::forward`] stops, rad.
pub const TOLERANCE_RAD: f64 = 1e-11;

/// Falcon-type delta geometry (metres, radians).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Delta {
    /// Upper arm `a`.
    pub a: f64,
    /// Parallelogram length `b`.
    pub b: f64,
    /// Pivot offset `c`.
    pub c: f64,
    /// Elbow plus effector hinge offsets `d + e`.
    pub de: f64,
    /// Axial offset `f`.
    pub f: f64,
    /// Leg radius `r`.
    pub r: f64,
    /// Leg side offset `s`.
    pub s: f64,
    /// `(cos φ, sin φ)` of each leg.
    pub legs: [(f64, f64); 3],
    /// A position inside the workspace to start the first forward solve from.
    pub home_guess_m: DVec3,
}

impl Delta {
    /// Builds the delta from a profile's geometry; `None` unless it is `Geometry::Delta`.
    #[must_use]
    pub fn from_geometry(g: &Geometry) -> Option<Self> {
        let Geometry::Delta {
            upper_arm_m,
            parallel_m,
            pivot_offset_m,
            elbow_offset_m,
            effector_offset_m,
            axial_offset_m,
            leg_radius_m,
            leg_side_m,
            leg_azimuth_rad,
        } = *g
        else {
            return None;
        };
        let mut d = Self {
            a: upper_arm_m,
            b: parallel_m,
            c: pivot_offset_m,
            de: elbow_offset_m + effector_offset_m,
            f: axial_offset_m,
            r: leg_radius_m,
            s: leg_side_m,
            legs: leg_azimuth_rad.map(|phi| (phi.cos(), phi.sin())),
            home_guess_m: DVec3::ZERO,
        };
        // Straight out along z from the base, about as far as the arms reach comfortably.
        d.home_guess_m = DVec3::new(0.0, 0.0, d.a + 0.5 * d.b);
        Some(d)
    }

    /// The leg-frame coordinates `(U, V, W)` of `p` for leg `i`.
    fn leg_frame(&self, i: usize, p: DVec3) -> (f64, f64, f64) {
        let (c, s) = self.legs[i];
        (
            p.x * c + p.y * s - self.r + self.c,
            -p.x * s + p.y * c - self.s + self.f,
            p.z,
        )
    }

    /// Joint angles for a tool position.
    ///
    /// # Errors
    /// [`KinematicsError::Unreachable`] when some leg cannot reach `p`.
    pub fn inverse(&self, p: DVec3) -> Result<DVec3, KinematicsError> {
        let unreachable = KinematicsError::Unreachable {
            position_m: p.to_array(),
        };
        if !p.is_finite() {
            return Err(unreachable);
        }
        let mut q = [0.0; 3];
        for (i, qi) in q.iter_mut().enumerate() {
            let (u, v, w) = self.leg_frame(i, p);
            let lean = self.b * self.b - v * v;
            if lean <= 0.0 {
                return Err(unreachable);
            }
            let l = self.de + lean.sqrt();
            let rho = u.hypot(w);
            let k = (u * u + w * w + self.a * self.a - l * l) / (2.0 * self.a);
            if rho < 1e-12 || k.abs() > rho {
                return Err(unreachable);
            }
            // U cos θ + W sin θ = K; the branch with the elbow below the U–W line to p.
            *qi = w.atan2(u) - (k / rho).acos();
        }
        Ok(DVec3::from_array(q))
    }

    /// `∂θ/∂p` (rows are legs) at angles `q` and position `p`.
    ///
    /// # Errors
    /// [`KinematicsError::Unreachable`] at a leg singularity (`g_θ = 0` or a fully leaning
    /// parallelogram).
    pub fn angle_jacobian(&self, q: DVec3, p: DVec3) -> Result<DMat3, KinematicsError> {
        let singular = KinematicsError::Unreachable {
            position_m: p.to_array(),
        };
        let mut rows = [DVec3::ZERO; 3];
        for (i, row) in rows.iter_mut().enumerate() {
            let (u, v, w) = self.leg_frame(i, p);
            let (st, ct) = q[i].sin_cos();
            let lean = self.b * self.b - v * v;
            if lean <= 0.0 {
                return Err(singular);
            }
            let root = lean.sqrt();
            let l = self.de + root;
            let g_theta = 2.0 * self.a * (u * st - w * ct);
            if g_theta.abs() < 1e-12 {
                return Err(singular);
            }
            let g_u = 2.0 * (u - self.a * ct);
            let g_w = 2.0 * (w - self.a * st);
            let g_v = 2.0 * l * v / root;
            let (c, s) = self.legs[i];
            // Chain rule through U = x c + y s + …, V = −x s + y c + …, W = z.
            let g_p = DVec3::new(g_u * c - g_v * s, g_u * s + g_v * c, g_w);
            *row = -g_p / g_theta;
        }
        Ok(DMat3::from_cols(rows[0], rows[1], rows[2]).transpose())
    }

    /// `∂p/∂θ` (columns are joints) at angles `q` and position `p`.
    ///
    /// # Errors
    /// [`KinematicsError::Unreachable`] at a singular pose.
    pub fn jacobian(&self, q: DVec3, p: DVec3) -> Result<DMat3, KinematicsError> {
        let jq = self.angle_jacobian(q, p)?;
        let det = jq.determinant();
        if !det.is_finite() || det.abs() < 1e-12 {
            return Err(KinematicsError::Unreachable {
                position_m: p.to_array(),
            });
        }
        Ok(jq.inverse())
    }

    /// Tool position for joint angles by Newton iteration from `guess`.
    ///
    /// # Errors
    /// [`KinematicsError::NoConvergence`] after [`MAX_ITERATIONS`] without reaching
    /// [`TOLERANCE_RAD`].
    pub fn forward(&self, q: DVec3, guess: DVec3) -> Result<DVec3, KinematicsError> {
        let mut p = if self.inverse(guess).is_ok() {
            guess
        } else {
            self.home_guess_m
        };
        let mut residual = f64::INFINITY;
        for it in 0..MAX_ITERATIONS {
            let qp = self.inverse(p)?;
            let err = q - qp;
            residual = err.abs().max_element();
            if residual < TOLERANCE_RAD {
                return Ok(p);
            }
            let step = self.jacobian(qp, p)? * err;
            // Halve the step until the new point is reachable and no worse (bounded: 8 halvings).
            let mut t = 1.0;
            let mut next = p + step;
            for _ in 0..8 {
                if let Ok(qn) = self.inverse(next)
                    && (q - qn).abs().max_element() < residual
                {
                    break;
                }
                t *= 0.5;
                next = p + step * t;
            }
            p = next;
            if it + 1 == MAX_ITERATIONS {
                break;
            }
        }
        Err(KinematicsError::NoConvergence {
            iterations: MAX_ITERATIONS,
            residual_rad: residual,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::profile::DeviceProfile;

    fn falcon() -> Delta {
        Delta::from_geometry(&DeviceProfile::built_in("falcon").unwrap().geometry).unwrap()
    }

    fn workspace_points() -> Vec<DVec3> {
        let mut v = Vec::new();
        for x in [-0.04, 0.0, 0.035] {
            for y in [-0.04, 0.0, 0.03] {
                for z in [0.09, 0.12, 0.15] {
                    v.push(DVec3::new(x, y, z));
                }
            }
        }
        v
    }

    #[test]
    fn home_is_reachable_with_plausible_angles() {
        let d = falcon();
        let q = d.inverse(d.home_guess_m).unwrap();
        // Arms between their stops: roughly −40° .. 100°.
        assert!(q.to_array().iter().all(|a| (-0.7..1.75).contains(a)), "{q}");
        // Symmetric pose on the axis: all three legs at one angle.
        assert!((q.x - q.y).abs() < 1e-9 && (q.y - q.z).abs() < 1e-9);
    }

    #[test]
    fn inverse_then_forward_recovers_positions() {
        let d = falcon();
        for p in workspace_points() {
            let q = d.inverse(p).unwrap_or_else(|e| panic!("{p}: {e}"));
            let back = d.forward(q, d.home_guess_m).unwrap();
            assert!((back - p).length() < 1e-9, "{p} -> {back}");
        }
    }

    #[test]
    fn angle_jacobian_matches_finite_differences() {
        let d = falcon();
        let h = 1e-7;
        for p in workspace_points() {
            let q = d.inverse(p).unwrap();
            let j = d.angle_jacobian(q, p).unwrap();
            for k in 0..3 {
                let mut dp = DVec3::ZERO;
                dp[k] = h;
                let fd = (d.inverse(p + dp).unwrap() - d.inverse(p - dp).unwrap()) / (2.0 * h);
                let col = j.col(k);
                assert!(
                    (fd - col).abs().max_element() < 1e-5 * (1.0 + col.abs().max_element()),
                    "{p} axis {k}: {fd} vs {col}"
                );
            }
        }
    }

    #[test]
    fn position_jacobian_inverts_the_angle_jacobian() {
        let d = falcon();
        let p = DVec3::new(0.01, -0.02, 0.11);
        let q = d.inverse(p).unwrap();
        let prod = d.angle_jacobian(q, p).unwrap() * d.jacobian(q, p).unwrap();
        assert!(
            (prod - DMat3::IDENTITY)
                .abs()
                .to_cols_array()
                .iter()
                .all(|e| *e < 1e-9)
        );
    }

    #[test]
    fn unreachable_positions_are_errors_not_nans() {
        let d = falcon();
        assert!(d.inverse(DVec3::new(0.0, 0.0, 1.0)).is_err());
        assert!(d.inverse(DVec3::splat(f64::NAN)).is_err());
        assert!(d.forward(DVec3::splat(5.0), d.home_guess_m).is_err());
    }
}
