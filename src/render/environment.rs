//! The environment texture: a sphere map (Ferley et al. §5) of a soft studio, made procedurally.
//!
//! A sphere map stores, at texel `m` of the unit disk, the environment seen in the direction a
//! mirror sphere reflects there: with sphere normal `n = (mx, my, √(1 − |m|²))` and the view
//! along −z, that direction is `r = (2 nz nx, 2 nz ny, 2 nz² − 1)`. The shader inverts it from
//! the view-space reflection vector. Texels are sRGB-encoded RGBA8, row 0 at the top.

use glam::Vec3;

/// A square RGBA8 (sRGB) sphere-map image.
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentMap {
    pub size_px: u32,
    /// `size_px² × 4` bytes, rows top to bottom.
    pub rgba8_srgb: Vec<u8>,
}

/// Why an environment image was refused.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "environment map of {size_px}×{size_px} pixels needs {needed} RGBA bytes, got {byte_len}",
    needed = u64::from(*size_px) * u64::from(*size_px) * 4
)]
pub struct EnvironmentSizeError {
    pub size_px: u32,
    pub byte_len: usize,
}

impl EnvironmentMap {
    /// Wraps a user image (for example a loaded matcap).
    ///
    /// # Errors
    /// When the size is zero or the byte count is not `size_px² × 4`.
    pub fn from_rgba8(size_px: u32, rgba8_srgb: Vec<u8>) -> Result<Self, EnvironmentSizeError> {
        let expected = u64::from(size_px) * u64::from(size_px) * 4;
        if size_px == 0 || rgba8_srgb.len() as u64 != expected {
            return Err(EnvironmentSizeError {
                size_px,
                byte_len: rgba8_srgb.len(),
            });
        }
        Ok(Self {
            size_px,
            rgba8_srgb,
        })
    }

    /// A neutral studio: bright sky above, dim floor below, two soft boxes for highlights.
    /// `size_px` is clamped to at least 1.
    #[must_use]
    pub fn studio(size_px: u32) -> Self {
        let n = size_px.max(1);
        let mut rgba8_srgb = Vec::with_capacity((n * n * 4) as usize);
        for row in 0..n {
            for col in 0..n {
                let mx = (col as f32 + 0.5) / n as f32 * 2.0 - 1.0;
                let my = 1.0 - (row as f32 + 0.5) / n as f32 * 2.0;
                let c = studio_radiance(sphere_map_direction(mx, my));
                for ch in [c.x, c.y, c.z] {
                    rgba8_srgb.push(linear_to_srgb8(ch));
                }
                rgba8_srgb.push(255);
            }
        }
        Self {
            size_px: n,
            rgba8_srgb,
        }
    }
}

/// Reflected view-space direction stored at disk point `(mx, my)`; points outside the disk
/// take the rim's direction (straight back at the viewer's opposite).
#[must_use]
pub fn sphere_map_direction(mx: f32, my: f32) -> Vec3 {
    let d2 = mx * mx + my * my;
    let (mx, my, nz) = if d2 >= 1.0 {
        let s = d2.sqrt();
        (mx / s, my / s, 0.0)
    } else {
        (mx, my, (1.0 - d2).sqrt())
    };
    Vec3::new(2.0 * nz * mx, 2.0 * nz * my, 2.0 * nz * nz - 1.0)
}

/// Linear radiance of the studio in view-space direction `r`.
#[must_use]
pub fn studio_radiance(r: Vec3) -> Vec3 {
    let r = r.normalize_or(Vec3::Z);
    let sky = Vec3::new(0.75, 0.8, 0.9);
    let horizon = Vec3::new(0.35, 0.33, 0.3);
    let floor = Vec3::new(0.06, 0.055, 0.05);
    let base = if r.y >= 0.0 {
        horizon.lerp(sky, r.y.powf(0.6))
    } else {
        horizon.lerp(floor, (-r.y).powf(0.4))
    };
    let soft_box = |dir: Vec3, sharpness: f32, power: f32| {
        power * ((r.dot(dir.normalize()) - 1.0) * sharpness).exp()
    };
    let key = soft_box(Vec3::new(-0.5, 0.55, 0.7), 40.0, 2.5);
    let rim = soft_box(Vec3::new(0.8, 0.2, -0.4), 25.0, 1.2);
    base + Vec3::splat(key + rim)
}

/// sRGB encoding of a linear channel value, rounded to 8 bits (values are clamped to [0, 1]).
#[must_use]
pub fn linear_to_srgb8(linear: f32) -> u8 {
    let x = if linear.is_nan() {
        0.0
    } else {
        linear.clamp(0.0, 1.0)
    };
    let s = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disk_centre_reflects_back_at_the_viewer_and_rim_points_away() {
        assert!((sphere_map_direction(0.0, 0.0) - Vec3::Z).length() < 1e-6);
        assert!((sphere_map_direction(1.0, 0.0) - Vec3::new(0.0, 0.0, -1.0)).length() < 1e-6);
        // 45° normal reflects the view ray sideways.
        let s = std::f32::consts::FRAC_1_SQRT_2;
        assert!((sphere_map_direction(s, 0.0) - Vec3::X).length() < 1e-5);
        for (x, y) in [(0.3, -0.4), (0.9, 0.1), (2.0, 2.0)] {
            assert!((sphere_map_direction(x, y).length() - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn studio_is_brighter_above_than_below_and_sized_right() {
        let map = EnvironmentMap::studio(64);
        assert_eq!(map.rgba8_srgb.len(), 64 * 64 * 4);
        assert!(studio_radiance(Vec3::Y).x > studio_radiance(-Vec3::Y).x);
        assert_eq!(EnvironmentMap::studio(0).size_px, 1);
        assert!(EnvironmentMap::from_rgba8(2, vec![0; 15]).is_err());
        assert!(EnvironmentMap::from_rgba8(2, vec![0; 16]).is_ok());
    }

    #[test]
    fn srgb_encoding_matches_reference_points() {
        assert_eq!(linear_to_srgb8(0.0), 0);
        assert_eq!(linear_to_srgb8(1.0), 255);
        assert_eq!(linear_to_srgb8(0.5), 188);
        assert_eq!(linear_to_srgb8(0.2158), 128);
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
        assert_eq!(linear_to_srgb8(7.0), 255);
    }
}
