//! Scripted hand motion: timed waypoints, interpolated, with button states.
//!
//! Guarantee: [`Trajectory::sample`] is pure, allocation-free and `O(log n)` in the number of
//! waypoints, so the simulated arm can call it on the haptic path. Construction validates the
//! script and reports the first bad waypoint by index.

use glam::{Quat, Vec3};
use serde::{Deserialize, Serialize};

/// One scripted point of the hand's path.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Waypoint {
    /// Time the hand reaches this point, seconds from the start of the script.
    pub time_s: f64,
    /// Hand position, metres in the device frame.
    pub position_m: Vec3,
    /// Buttons held from this waypoint until the next (bit `i` = button `i`; by convention
    /// bit 0 means "stroke active").
    #[serde(default)]
    pub buttons: u32,
    /// The hand's orientation here (device frame), for an arm that senses rotation; a
    /// trajectory with none reports no orientation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub orientation: Option<Quat>,
}

impl Waypoint {
    /// A waypoint with no buttons held.
    #[must_use]
    pub fn new(time_s: f64, position_m: Vec3) -> Self {
        Self {
            time_s,
            position_m,
            buttons: 0,
            orientation: None,
        }
    }

    /// A waypoint with `buttons` held from here on.
    #[must_use]
    pub fn with_buttons(time_s: f64, position_m: Vec3, buttons: u32) -> Self {
        Self {
            time_s,
            position_m,
            buttons,
            orientation: None,
        }
    }

    /// This waypoint with the hand turned to `orientation`.
    #[must_use]
    pub fn turned(self, orientation: Quat) -> Self {
        Self {
            orientation: Some(orientation),
            ..self
        }
    }
}

/// How the hand moves between waypoints.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Interpolation {
    /// Straight segments at constant speed (velocity jumps at waypoints).
    Linear,
    /// A cubic Hermite spline through the waypoints with Catmull–Rom tangents scaled for
    /// uneven timing, limited per axis so that the hand never overshoots a waypoint (monotone
    /// between waypoints on every axis, after Fritsch & Carlson), and zero velocity at the
    /// first and last waypoint: continuous velocity, like a real hand, and a stroke that comes
    /// down onto a level path stays on it instead of dipping under it.
    #[default]
    Smooth,
}

/// Where the hand is at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HandSample {
    /// Hand position, metres.
    pub position_m: Vec3,
    /// Hand velocity, metres per second.
    pub velocity_m_per_s: Vec3,
    /// Buttons held.
    pub buttons: u32,
    /// Hand orientation (`None` when the trajectory gives none): the shortest rotation between
    /// waypoints at the segment's fraction of time; a waypoint without one is unturned.
    pub orientation: Option<Quat>,
}

/// A script that is not a valid trajectory.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("trajectory waypoint {index}: {what}")]
pub struct TrajectoryError {
    /// Index of the offending waypoint.
    pub index: usize,
    /// What is wrong with it.
    pub what: &'static str,
}

/// A validated, time-ordered hand path. Before the first waypoint the hand waits at the first;
/// after the last it holds the last position and buttons.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectory {
    waypoints: Vec<Waypoint>,
    /// Tangents (velocity at each waypoint), metres per second; used by `Smooth`.
    tangents_m_per_s: Vec<Vec3>,
    interpolation: Interpolation,
}

impl Trajectory {
    /// Builds a trajectory from waypoints in time order.
    ///
    /// # Errors
    /// A [`TrajectoryError`] naming the first waypoint whose time or position is not finite,
    /// whose time is negative, or whose time does not increase strictly; index 0 with
    /// "no waypoints" for an empty list.
    pub fn new(
        waypoints: Vec<Waypoint>,
        interpolation: Interpolation,
    ) -> Result<Self, TrajectoryError> {
        if waypoints.is_empty() {
            return Err(TrajectoryError {
                index: 0,
                what: "no waypoints",
            });
        }
        for (index, w) in waypoints.iter().enumerate() {
            if !w.time_s.is_finite() {
                return Err(TrajectoryError {
                    index,
                    what: "time is not finite",
                });
            }
            if w.time_s < 0.0 {
                return Err(TrajectoryError {
                    index,
                    what: "time is negative",
                });
            }
            if !w.position_m.is_finite() {
                return Err(TrajectoryError {
                    index,
                    what: "position is not finite",
                });
            }
            if let Some(q) = w.orientation
                && !(q.is_finite() && q.length_squared() > 0.25)
            {
                return Err(TrajectoryError {
                    index,
                    what: "orientation is not a finite, non-zero quaternion",
                });
            }
            if index > 0 && w.time_s <= waypoints[index - 1].time_s {
                return Err(TrajectoryError {
                    index,
                    what: "time does not increase",
                });
            }
        }
        let tangents_m_per_s = tangents(&waypoints);
        let turned = waypoints.iter().any(|w| w.orientation.is_some());
        let waypoints = waypoints
            .into_iter()
            .map(|w| Waypoint {
                orientation: turned.then(|| w.orientation.map_or(Quat::IDENTITY, Quat::normalize)),
                ..w
            })
            .collect();
        Ok(Self {
            waypoints,
            tangents_m_per_s,
            interpolation,
        })
    }

    /// A hand that holds still at `position_m` forever.
    #[must_use]
    pub fn hold(position_m: Vec3) -> Self {
        let waypoints = vec![Waypoint::new(0.0, position_m)];
        Self {
            tangents_m_per_s: tangents(&waypoints),
            waypoints,
            interpolation: Interpolation::Linear,
        }
    }

    /// The waypoints, in time order.
    #[must_use]
    pub fn waypoints(&self) -> &[Waypoint] {
        &self.waypoints
    }

    /// The interpolation in use.
    #[must_use]
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// Whether the waypoints turn the hand (an arm following it senses orientation).
    #[must_use]
    pub fn has_orientation(&self) -> bool {
        self.waypoints.iter().any(|w| w.orientation.is_some())
    }

    /// Time of the last waypoint, seconds.
    #[must_use]
    pub fn duration_s(&self) -> f64 {
        self.waypoints.last().map_or(0.0, |w| w.time_s)
    }

    /// The hand's position, velocity and buttons at `time_s` (clamped to the script).
    #[must_use]
    pub fn sample(&self, time_s: f64) -> HandSample {
        let w = &self.waypoints;
        let first = w[0];
        let last = w[w.len() - 1];
        if time_s.is_nan() || time_s <= first.time_s {
            // Before the script (or a NaN time): the hand waits at the start.
            return HandSample {
                position_m: first.position_m,
                velocity_m_per_s: Vec3::ZERO,
                buttons: first.buttons,
                orientation: first.orientation,
            };
        }
        if time_s >= last.time_s {
            return HandSample {
                position_m: last.position_m,
                velocity_m_per_s: Vec3::ZERO,
                buttons: last.buttons,
                orientation: last.orientation,
            };
        }
        // Segment i runs from w[i] to w[i + 1]; first.time_s < time_s < last.time_s.
        let i = w.partition_point(|p| p.time_s <= time_s) - 1;
        let (a, b) = (w[i], w[i + 1]);
        let span_s = b.time_s - a.time_s;
        let u = ((time_s - a.time_s) / span_s) as f32;
        let span_s = span_s as f32;
        let (position_m, velocity_m_per_s) = match self.interpolation {
            Interpolation::Linear => (
                a.position_m.lerp(b.position_m, u),
                (b.position_m - a.position_m) / span_s,
            ),
            Interpolation::Smooth => hermite(
                a.position_m,
                self.tangents_m_per_s[i] * span_s,
                b.position_m,
                self.tangents_m_per_s[i + 1] * span_s,
                u,
                span_s,
            ),
        };
        HandSample {
            position_m,
            velocity_m_per_s,
            buttons: a.buttons,
            orientation: a
                .orientation
                .zip(b.orientation)
                .map(|(qa, qb)| qa.slerp(qb, u)),
        }
    }
}

/// Catmull–Rom tangents for uneven timing, limited per axis (Fritsch & Carlson) so that each
/// segment is monotone on every axis: zero where the axis turns back or rests at a waypoint,
/// and at most three times either neighbouring segment's slope; zero at both ends so the hand
/// starts and stops at rest.
fn tangents(w: &[Waypoint]) -> Vec<Vec3> {
    let slope = |i: usize| {
        let dt = (w[i + 1].time_s - w[i].time_s) as f32;
        (w[i + 1].position_m - w[i].position_m) / dt
    };
    (0..w.len())
        .map(|i| {
            if i == 0 || i + 1 == w.len() {
                return Vec3::ZERO;
            }
            let dt = (w[i + 1].time_s - w[i - 1].time_s) as f32;
            let catmull_rom = (w[i + 1].position_m - w[i - 1].position_m) / dt;
            let (before, after) = (slope(i - 1), slope(i));
            let limited = |m: f32, a: f32, b: f32| {
                if a * b <= 0.0 {
                    0.0
                } else {
                    m.signum() * m.abs().min(3.0 * a.abs()).min(3.0 * b.abs())
                }
            };
            Vec3::new(
                limited(catmull_rom.x, before.x, after.x),
                limited(catmull_rom.y, before.y, after.y),
                limited(catmull_rom.z, before.z, after.z),
            )
        })
        .collect()
}

/// Cubic Hermite on the unit parameter `u` with end tangents `m0`, `m1` already scaled by the
/// segment duration; returns position and velocity (per second).
fn hermite(p0: Vec3, m0: Vec3, p1: Vec3, m1: Vec3, u: f32, span_s: f32) -> (Vec3, Vec3) {
    let u2 = u * u;
    let u3 = u2 * u;
    let h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
    let h10 = u3 - 2.0 * u2 + u;
    let h01 = -2.0 * u3 + 3.0 * u2;
    let h11 = u3 - u2;
    let d00 = 6.0 * u2 - 6.0 * u;
    let d10 = 3.0 * u2 - 4.0 * u + 1.0;
    let d01 = -6.0 * u2 + 6.0 * u;
    let d11 = 3.0 * u2 - 2.0 * u;
    let position = p0 * h00 + m0 * h10 + p1 * h01 + m1 * h11;
    let velocity = (p0 * d00 + m0 * d10 + p1 * d01 + m1 * d11) / span_s;
    (position, velocity)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn path(interp: Interpolation) -> Trajectory {
        Trajectory::new(
            vec![
                Waypoint::new(0.0, Vec3::ZERO),
                Waypoint::with_buttons(1.0, Vec3::new(0.1, 0.0, 0.0), 1),
                Waypoint::new(3.0, Vec3::new(0.1, -0.04, 0.0)),
            ],
            interp,
        )
        .unwrap()
    }

    #[test]
    fn a_stroke_that_comes_down_onto_a_level_path_stays_on_it() {
        // Down from a hover onto a level path, along it, and back up: the hand never dips
        // under the path's level nor rises over the hovers, and moves on between waypoints.
        let t = Trajectory::new(
            vec![
                Waypoint::new(0.0, Vec3::new(0.0, 0.04, 0.0)),
                Waypoint::with_buttons(0.4, Vec3::new(0.0, 0.0, 0.0), 1),
                Waypoint::with_buttons(1.9, Vec3::new(0.07, 0.0, 0.0), 1),
                Waypoint::new(2.3, Vec3::new(0.07, 0.04, 0.0)),
            ],
            Interpolation::Smooth,
        )
        .unwrap();
        let mut last_x = f32::NEG_INFINITY;
        for n in 0..=230 {
            let p = t.sample(f64::from(n) * 0.01).position_m;
            assert!(
                (-1e-7..=0.04 + 1e-7).contains(&p.y),
                "at {} s the hand is at y = {}",
                f64::from(n) * 0.01,
                p.y
            );
            assert!(
                p.x >= last_x - 1e-7,
                "x turned back at {} s",
                f64::from(n) * 0.01
            );
            last_x = p.x;
        }
        // Still smooth: moving along the path in its middle.
        assert!(t.sample(1.15).velocity_m_per_s.x > 0.03);
    }

    #[test]
    fn passes_through_waypoints_and_holds_ends() {
        for interp in [Interpolation::Linear, Interpolation::Smooth] {
            let t = path(interp);
            assert_eq!(t.sample(-1.0).position_m, Vec3::ZERO);
            assert_eq!(t.sample(f64::NAN).position_m, Vec3::ZERO);
            assert!(
                t.sample(1.0)
                    .position_m
                    .abs_diff_eq(Vec3::new(0.1, 0.0, 0.0), 1e-6)
            );
            assert_eq!(t.sample(9.0).position_m, Vec3::new(0.1, -0.04, 0.0));
            assert_eq!(t.sample(9.0).velocity_m_per_s, Vec3::ZERO);
            assert_eq!(t.duration_s(), 3.0);
        }
    }

    #[test]
    fn linear_midpoint_and_velocity() {
        let t = path(Interpolation::Linear);
        let s = t.sample(0.5);
        assert!(s.position_m.abs_diff_eq(Vec3::new(0.05, 0.0, 0.0), 1e-6));
        assert!(
            s.velocity_m_per_s
                .abs_diff_eq(Vec3::new(0.1, 0.0, 0.0), 1e-6)
        );
    }

    #[test]
    fn smooth_velocity_matches_finite_difference_and_is_continuous() {
        let t = path(Interpolation::Smooth);
        for &time in &[0.2, 0.7, 1.3, 2.5] {
            let h = 1e-4;
            let fd =
                (t.sample(time + h).position_m - t.sample(time - h).position_m) / (2.0 * h) as f32;
            let v = t.sample(time).velocity_m_per_s;
            assert!(v.abs_diff_eq(fd, 1e-3), "t={time}: {v} vs {fd}");
        }
        let before = t.sample(1.0 - 1e-6).velocity_m_per_s;
        let after = t.sample(1.0 + 1e-6).velocity_m_per_s;
        assert!(before.abs_diff_eq(after, 1e-3), "{before} vs {after}");
        assert!(
            t.sample(1e-6).velocity_m_per_s.length() < 1e-3,
            "starts at rest"
        );
    }

    #[test]
    fn buttons_step_at_waypoints() {
        let t = path(Interpolation::Smooth);
        assert_eq!(t.sample(0.5).buttons, 0);
        assert_eq!(t.sample(1.5).buttons, 1);
        assert_eq!(t.sample(5.0).buttons, 0);
    }

    #[test]
    fn invalid_scripts_name_the_waypoint() {
        let e = Trajectory::new(vec![], Interpolation::Linear).unwrap_err();
        assert_eq!(e.what, "no waypoints");
        let e = Trajectory::new(
            vec![
                Waypoint::new(0.0, Vec3::ZERO),
                Waypoint::new(1.0, Vec3::ZERO),
                Waypoint::new(1.0, Vec3::X),
            ],
            Interpolation::Linear,
        )
        .unwrap_err();
        assert_eq!(e.index, 2);
        assert_eq!(
            e.to_string(),
            "trajectory waypoint 2: time does not increase"
        );
        let e = Trajectory::new(
            vec![Waypoint::new(0.0, Vec3::new(f32::NAN, 0.0, 0.0))],
            Interpolation::Smooth,
        )
        .unwrap_err();
        assert_eq!(e.what, "position is not finite");
    }

    #[test]
    fn waypoints_deserialize_from_toml() {
        #[derive(Deserialize)]
        struct Script {
            interpolation: Interpolation,
            waypoint: Vec<Waypoint>,
        }
        let s: Script = toml::from_str(
            "interpolation = \"linear\"\n\
             [[waypoint]]\ntime_s = 0.0\nposition_m = [0.0, 0.0, 0.0]\n\
             [[waypoint]]\ntime_s = 0.5\nposition_m = [0.0, -0.01, 0.0]\nbuttons = 1\n",
        )
        .unwrap();
        let t = Trajectory::new(s.waypoint, s.interpolation).unwrap();
        assert_eq!(t.sample(0.5).buttons, 1);
    }
}
