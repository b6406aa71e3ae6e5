//! The image an emboss lays onto the clay: a brightness grid decoded from a PNG or JPEG,
//! bounded before it is decoded ([`MAX_IMAGE_BYTES`], [`MAX_IMAGE_PIXELS`]), and sampled with
//! bilinear interpolation.

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
