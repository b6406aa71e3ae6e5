//! Stroke smoothing (a lazy mouse, as Blender's Stabilize Stroke and ZBrush's LazyMouse): the
//! brush hangs on a string behind the pointer. While the pointer stays within the string's
//! length of the brush, the brush stays put; when the pointer pulls farther, the brush moves
//! straight toward it, just enough to keep the string taut. A hand's jitter shorter than the
//! string never reaches the clay, and a stroke follows the hand's intended line.
//!
//! The strength (`0..=1`) sets the string's length: 0 is no smoothing (the brush is the
//! pointer, exactly), 1 is [`MAX_STRING_PT`]. When the stroke ends the brush is drawn the rest
//! of the way to the pointer, so a stroke ends where the hand let go (no lost tail).
//!
//! Works in screen points, on the window's thread, for the pointer's strokes only (the arm's
//! haptic tick is not smoothed: its path is the hand's). Pure and allocation-free: a test
//! drives it with injected samples, no clock.

use glam::Vec2;

/// String length at full strength, screen points.
pub const MAX_STRING_PT: f32 = 80.0;

/// How far the brush's heading turns toward the string's pull per pointer sample (a
/// fraction): the brush keeps to its heading while the pointer swings from side to side
/// within the string, and comes round to a real turn of the hand within a few samples.
pub const HEADING_FOLLOW: f32 = 0.25;

/// The lazy-mouse state of the window's pointer strokes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StrokeSmoothing {
    /// Smoothing strength, `0..=1` (0: off).
    pub strength: f32,
    /// Where the brush is during a stroke (`None` between strokes).
    brush_pt: Option<Vec2>,
    /// The direction the brush moves in (unit; zero until the string first pulls).
    heading: Vec2,
}

impl StrokeSmoothing {
    /// Smoothing of `strength` (clamped to `0..=1`; not a number: off).
    #[must_use]
    pub fn new(strength: f32) -> Self {
        Self {
            strength: if strength.is_nan() {
                0.0
            } else {
                strength.clamp(0.0, 1.0)
            },
            brush_pt: None,
            heading: Vec2::ZERO,
        }
    }

    /// The string's length, screen points.
    #[must_use]
    pub fn string_length_pt(&self) -> f32 {
        if self.strength.is_nan() {
            return 0.0;
        }
        self.strength.clamp(0.0, 1.0) * MAX_STRING_PT
    }

    /// Where the brush is now, if a stroke is held.
    #[must_use]
    pub fn brush_pt(&self) -> Option<Vec2> {
        self.brush_pt
    }

    /// The pointer is at `pointer_pt` while a stroke is held: returns where the brush is. The
    /// first call of a stroke puts the brush on the pointer.
    ///
    /// When the pointer pulls the string taut, the brush moves along its heading (which turns
    /// [`HEADING_FOLLOW`] of the way toward the pull each sample) just far enough to bring the
    /// pointer back to the string's length; where its heading cannot get there (a sharp turn
    /// of the hand) it moves straight toward the pointer, as a plain lazy mouse does. Either
    /// way the brush never falls more than the string's length behind.
    pub fn follow(&mut self, pointer_pt: Vec2) -> Vec2 {
        let string = self.string_length_pt();
        let brush = match self.brush_pt {
            None => pointer_pt,
            Some(_) if string <= 0.0 => pointer_pt,
            Some(brush) => {
                let pull = pointer_pt - brush;
                let distance = pull.length();
                if distance > string {
                    let toward = pull / distance;
                    self.heading = (self.heading + HEADING_FOLLOW * (toward - self.heading))
                        .try_normalize()
                        .unwrap_or(toward);
                    along_heading(brush, self.heading, pointer_pt, string)
                        .unwrap_or(pointer_pt - toward * string)
                } else {
                    brush
                }
            }
        };
        self.brush_pt = Some(brush);
        brush
    }

    /// The stroke ends with the pointer at `pointer_pt`: the brush's last stretch, to the
    /// pointer, when it lags behind (the caller draws it before lifting), and the state
    /// cleared for the next stroke.
    pub fn finish(&mut self, pointer_pt: Vec2) -> Option<Vec2> {
        let lagging = self.brush_pt.filter(|b| *b != pointer_pt);
        self.brush_pt = None;
        self.heading = Vec2::ZERO;
        lagging.map(|_| pointer_pt)
    }

    /// Forgets the stroke without finishing it (the pointer left the view).
    pub fn cancel(&mut self) {
        self.brush_pt = None;
        self.heading = Vec2::ZERO;
    }
}

/// The nearest point ahead of `brush` along the unit `heading` that is `string` from
/// `pointer`, if the line comes that close (`brush` is farther than `string` from `pointer`).
fn along_heading(brush: Vec2, heading: Vec2, pointer: Vec2, string: f32) -> Option<Vec2> {
    let to_pointer = pointer - brush;
    let ahead = to_pointer.dot(heading);
    let off_line_sq = to_pointer.length_squared() - ahead * ahead;
    let reach_sq = string * string - off_line_sq;
    if ahead <= 0.0 || reach_sq < 0.0 {
        return None;
    }
    // The line meets the string's circle at `ahead ± √reach`; the brush stops at the first.
    let step = ahead - reach_sq.sqrt();
    (step >= 0.0).then(|| brush + heading * step)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hand drawing the line y = 0 from x = 0 to x = 400 points with a zig-zag jitter of
    /// ±`amplitude` points every 4 points along it.
    fn jittery_line(amplitude: f32) -> Vec<Vec2> {
        (0..=100)
            .map(|i| {
                let side = if i % 2 == 0 { 1.0 } else { -1.0 };
                let jitter = if i == 0 || i == 100 {
                    0.0
                } else {
                    side * amplitude
                };
                Vec2::new(4.0 * i as f32, jitter)
            })
            .collect()
    }

    /// The brush's path for `samples` with smoothing `strength`, its tail included.
    fn brush_path(samples: &[Vec2], strength: f32) -> Vec<Vec2> {
        let mut smoothing = StrokeSmoothing::new(strength);
        let mut path: Vec<Vec2> = samples.iter().map(|&p| smoothing.follow(p)).collect();
        path.extend(smoothing.finish(*samples.last().unwrap()));
        path
    }

    /// Largest distance from the intended line y = 0.
    fn deviation(path: &[Vec2]) -> f32 {
        path.iter().map(|p| p.y.abs()).fold(0.0, f32::max)
    }

    /// Total turning along the path, radians (the integral of its curvature).
    fn turning(path: &[Vec2]) -> f32 {
        let steps: Vec<Vec2> = path
            .windows(2)
            .map(|w| w[1] - w[0])
            .filter(|d| d.length() > 1e-6)
            .collect();
        steps.windows(2).map(|w| w[0].angle_to(w[1]).abs()).sum()
    }

    #[test]
    fn strength_zero_draws_the_pointers_path_exactly() {
        let samples = jittery_line(6.0);
        let path = brush_path(&samples, 0.0);
        assert_eq!(path, samples);
    }

    #[test]
    fn a_zig_zag_jitter_is_smoothed_toward_the_intended_line() {
        let samples = jittery_line(6.0);
        let raw = brush_path(&samples, 0.0);
        // A string of 16 points, longer than the jitter's 12-point swing.
        let smooth = brush_path(&samples, 0.2);
        assert!(
            deviation(&smooth) < 0.5 * deviation(&raw),
            "deviation {} vs {}",
            deviation(&smooth),
            deviation(&raw)
        );
        assert!(
            turning(&smooth) < 0.1 * turning(&raw),
            "turning {} vs {} rad",
            turning(&smooth),
            turning(&raw)
        );
        // More strength, no rougher.
        let smoother = brush_path(&samples, 0.6);
        assert!(turning(&smoother) <= turning(&smooth) + 1e-4);
    }

    #[test]
    fn the_brush_stays_within_the_string_and_ends_at_the_pointer() {
        let samples = jittery_line(6.0);
        let mut smoothing = StrokeSmoothing::new(0.5);
        for &p in &samples {
            let brush = smoothing.follow(p);
            assert!(brush.distance(p) <= smoothing.string_length_pt() + 1e-3);
        }
        let last = *samples.last().unwrap();
        assert!(
            smoothing.brush_pt().unwrap().distance(last) > 1.0,
            "lagging"
        );
        assert_eq!(smoothing.finish(last), Some(last));
        assert_eq!(smoothing.brush_pt(), None);
        // A brush already on the pointer has no tail to draw.
        let mut still = StrokeSmoothing::new(0.5);
        still.follow(Vec2::ONE);
        assert_eq!(still.finish(Vec2::ONE), None);
    }

    #[test]
    fn the_first_sample_of_each_stroke_puts_the_brush_on_the_pointer() {
        let mut smoothing = StrokeSmoothing::new(1.0);
        assert_eq!(
            smoothing.follow(Vec2::new(10.0, 10.0)),
            Vec2::new(10.0, 10.0)
        );
        smoothing.finish(Vec2::new(12.0, 10.0));
        assert_eq!(
            smoothing.follow(Vec2::new(300.0, 5.0)),
            Vec2::new(300.0, 5.0)
        );
        assert_eq!(StrokeSmoothing::new(f32::NAN).string_length_pt(), 0.0);
        assert_eq!(StrokeSmoothing::new(3.0).string_length_pt(), MAX_STRING_PT);
    }
}
