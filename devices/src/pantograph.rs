//! Kinematics of a planar five-bar pantograph (the Haply 2DIY): two motors on the x axis, a
//! proximal link on each, two distal links meeting at the handle.
//!
//! Frame (the board's): motor 1 at the origin, motor 2 at `(d, 0)`, metres; joint angles
//! measured from +x, counter-clockwise. The handle hangs on the +y side (the side away from
//! the motors). The closed forms below are derived from the two distance constraints
//! `|P − A| = |P − B| = L`, with `A` and `B` the elbows:
//!
//! - forward: `P` is the apex over the elbow-to-elbow segment (to the left of `A → B`);
//! - Jacobian: differentiating the constraints gives `M dP = diag(a₁, a₂) dθ` with the rows of
//!   `M` the distal-link vectors, so `J = M⁻¹ diag(a₁, a₂)` and joint torques are `Jᵀ F`;
//! - inverse: each elbow is where the circle of radius `l` about its motor meets the circle of
//!   radius `L` about `P`, on the outer side (motor 1's to the left, motor 2's to the right).
//!
//! Plain data and arithmetic: no allocation, no panic; a pose that cannot be reached is `None`.

use glam::DVec2;

/// Link lengths of a pantograph, metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pantograph {
    /// Proximal (motor-side) link length.
    pub proximal_m: f64,
    /// Distal (handle-side) link length.
    pub distal_m: f64,
    /// Distance between the two motor axes.
    pub motor_spacing_m: f64,
}

/// A reachable pose: the handle position and the Jacobian `∂P/∂θ` (columns per joint).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PantographPose {
    /// Handle position, metres, board frame.
    pub handle_m: DVec2,
    /// `∂P/∂θ₁`, metres per radian.
    pub d_handle_d_theta1: DVec2,
    /// `∂P/∂θ₂`, metres per radian.
    pub d_handle_d_theta2: DVec2,
}

impl PantographPose {
    /// Joint torques (newton-metres) that put `force_n` (newtons, board frame) on the handle:
    /// `τ = Jᵀ F`.
    #[must_use]
    pub fn torques_n_m(&self, force_n: DVec2) -> [f64; 2] {
        [
            self.d_handle_d_theta1.dot(force_n),
            self.d_handle_d_theta2.dot(force_n),
        ]
    }
}

fn perp(v: DVec2) -> DVec2 {
    DVec2::new(-v.y, v.x)
}

impl Pantograph {
    /// The Haply 2DIY, third generation: 70 mm proximal links, 90 mm distal links, motor axes
    /// 38 mm apart (the figures of Haply's hAPI pantograph for hardware version 3).
    pub const TWO_DIY_V3: Self = Self {
        proximal_m: 0.07,
        distal_m: 0.09,
        motor_spacing_m: 0.038,
    };

    /// The Haply 2DIY, second generation: the same links on one motor axis.
    pub const TWO_DIY_V2: Self = Self {
        proximal_m: 0.07,
        distal_m: 0.09,
        motor_spacing_m: 0.0,
    };

    fn elbows(&self, theta1_rad: f64, theta2_rad: f64) -> (DVec2, DVec2, DVec2, DVec2) {
        let l = self.proximal_m;
        let (s1, c1) = theta1_rad.sin_cos();
        let (s2, c2) = theta2_rad.sin_cos();
        let a = DVec2::new(l * c1, l * s1);
        let b = DVec2::new(self.motor_spacing_m + l * c2, l * s2);
        // dA/dθ₁ and dB/dθ₂.
        (
            a,
            b,
            DVec2::new(-l * s1, l * c1),
            DVec2::new(-l * s2, l * c2),
        )
    }

    /// The handle position and Jacobian at joint angles `theta1_rad`, `theta2_rad`; `None`
    /// when the distal links cannot meet (elbows too far apart or coincident) or the pose is
    /// singular.
    #[must_use]
    pub fn forward(&self, theta1_rad: f64, theta2_rad: f64) -> Option<PantographPose> {
        let big_l = self.distal_m;
        let (a, b, da, db) = self.elbows(theta1_rad, theta2_rad);
        let ab = b - a;
        let h = ab.length();
        if !(h > 1e-12 && h < 2.0 * big_l) {
            return None;
        }
        let apex = (big_l * big_l - 0.25 * h * h).sqrt();
        let p = (a + b) * 0.5 + perp(ab) * (apex / h);
        // Rows of M: the distal links P − A and P − B.
        let (u, v) = (p - a, p - b);
        let det = u.x * v.y - u.y * v.x;
        if det.abs() < 1e-12 {
            return None;
        }
        let (a1, a2) = (u.dot(da), v.dot(db));
        // M⁻¹ = [v.y, −u.y; −v.x, u.x] / det; J = M⁻¹ diag(a₁, a₂).
        let col1 = DVec2::new(v.y, -v.x) * (a1 / det);
        let col2 = DVec2::new(-u.y, u.x) * (a2 / det);
        p.is_finite().then_some(PantographPose {
            handle_m: p,
            d_handle_d_theta1: col1,
            d_handle_d_theta2: col2,
        })
    }

    /// Joint angles (radians) that put the handle at `handle_m`, on the branch
    /// [`Self::forward`] uses; `None` when it is out of reach.
    #[must_use]
    pub fn inverse(&self, handle_m: DVec2) -> Option<(f64, f64)> {
        let elbow = |motor: DVec2, outward: f64| -> Option<f64> {
            let to = handle_m - motor;
            let r = to.length();
            let (l, big_l) = (self.proximal_m, self.distal_m);
            let cos_alpha = (l * l + r * r - big_l * big_l) / (2.0 * l * r);
            if !(r > 1e-12 && (-1.0..=1.0).contains(&cos_alpha)) {
                return None;
            }
            Some(to.y.atan2(to.x) + outward * cos_alpha.acos())
        };
        let t1 = elbow(DVec2::ZERO, 1.0)?;
        let t2 = elbow(DVec2::new(self.motor_spacing_m, 0.0), -1.0)?;
        Some((t1, t2))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_then_forward_returns_the_handle_across_the_workspace() {
        for pg in [Pantograph::TWO_DIY_V3, Pantograph::TWO_DIY_V2] {
            for i in 0..=10 {
                for j in 0..=10 {
                    let p = DVec2::new(
                        pg.motor_spacing_m * 0.5 - 0.06 + 0.012 * f64::from(i),
                        0.05 + 0.008 * f64::from(j),
                    );
                    let (t1, t2) = pg.inverse(p).unwrap_or_else(|| panic!("{p} reachable"));
                    let pose = pg.forward(t1, t2).unwrap();
                    assert!(
                        pose.handle_m.abs_diff_eq(p, 1e-12),
                        "{p} → {}",
                        pose.handle_m
                    );
                }
            }
        }
    }

    #[test]
    fn the_jacobian_matches_finite_differences() {
        let pg = Pantograph::TWO_DIY_V3;
        let (t1, t2) = pg.inverse(DVec2::new(0.03, 0.1)).unwrap();
        let pose = pg.forward(t1, t2).unwrap();
        let h = 1e-7;
        let d1 = (pg.forward(t1 + h, t2).unwrap().handle_m
            - pg.forward(t1 - h, t2).unwrap().handle_m)
            / (2.0 * h);
        let d2 = (pg.forward(t1, t2 + h).unwrap().handle_m
            - pg.forward(t1, t2 - h).unwrap().handle_m)
            / (2.0 * h);
        assert!(pose.d_handle_d_theta1.abs_diff_eq(d1, 1e-6), "{d1}");
        assert!(pose.d_handle_d_theta2.abs_diff_eq(d2, 1e-6), "{d2}");
        // Virtual work: τ · dθ equals F · dP for any small motion.
        let f = DVec2::new(0.7, -1.3);
        let tau = pose.torques_n_m(f);
        let dtheta = [2e-4, -1e-4];
        let dp = pose.d_handle_d_theta1 * dtheta[0] + pose.d_handle_d_theta2 * dtheta[1];
        assert!((tau[0] * dtheta[0] + tau[1] * dtheta[1] - f.dot(dp)).abs() < 1e-12);
    }

    #[test]
    fn out_of_reach_is_none() {
        let pg = Pantograph::TWO_DIY_V3;
        assert!(pg.inverse(DVec2::new(0.0, 0.5)).is_none());
        assert!(pg.inverse(DVec2::ZERO).is_none());
        // Coincident elbows (one motor axis, equal angles): no apex.
        assert!(Pantograph::TWO_DIY_V2.forward(1.0, 1.0).is_none());
        // Elbows farther apart than the two distal links reach.
        let long = Pantograph {
            motor_spacing_m: 0.1,
            ..pg
        };
        assert!(long.forward(std::f64::consts::PI, 0.0).is_none());
    }
}
