//! A rendered frame in CPU memory, and its atomic PNG file.
//!
//! The PNG is written through the one atomic writer ([`dynaclay_files::write_atomic_with`]), so
//! a reader never sees a half-written image and a failed write leaves the old file.

use std::path::Path;

use super::error::RenderError;

/// Tightly packed RGBA8 pixels (sRGB), rows top to bottom.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub rgba8: Vec<u8>,
}

impl Image {
    /// The pixel at column `x`, row `y`, or `None` outside the image.
    #[must_use]
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 4]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = 4 * (y as usize * self.width as usize + x as usize);
        self.rgba8.get(i..i + 4).map(|p| [p[0], p[1], p[2], p[3]])
    }

    /// Encodes the image as PNG (8-bit RGBA, tagged sRGB) and writes it to `path` atomically.
    ///
    /// # Errors
    /// [`RenderError::Png`] naming the path, when the pixel count is inconsistent, the file
    /// cannot be created or written, or the rename fails.
    pub fn write_png(&self, path: &Path) -> Result<(), RenderError> {
        let fail = |message: String| RenderError::Png {
            path: path.to_path_buf(),
            message,
        };
        let expected = 4 * self.width as usize * self.height as usize;
        if self.width == 0 || self.height == 0 || self.rgba8.len() != expected {
            return Err(fail(format!(
                "{}×{} image has {} bytes, expected {expected}",
                self.width,
                self.height,
                self.rgba8.len()
            )));
        }
        dynaclay_files::write_atomic_with(path, |out| {
            let mut encoder = png::Encoder::new(out, self.width, self.height);
            encoder.set_color(png::ColorType::Rgba);
            encoder.set_depth(png::BitDepth::Eight);
            encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
            let mut writer = encoder.write_header().map_err(std::io::Error::other)?;
            writer
                .write_image_data(&self.rgba8)
                .map_err(std::io::Error::other)?;
            writer.finish().map_err(std::io::Error::other)
        })
        .map_err(|e| fail(e.to_string()))
    }

    /// Reads an 8-bit RGBA or RGB PNG (as written by [`Image::write_png`]).
    ///
    /// # Errors
    /// [`RenderError::Png`] naming the path when the file cannot be read or decoded, or has
    /// another pixel layout.
    pub fn read_png(path: &Path) -> Result<Self, RenderError> {
        let fail = |message: String| RenderError::Png {
            path: path.to_path_buf(),
            message,
        };
        // A regular file through a cap: `/dev/zero` or a FIFO is refused at once.
        let bytes =
            dynaclay_files::read_regular_file(path, 1 << 30).map_err(|e| fail(e.to_string()))?;
        let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = decoder.read_info().map_err(|e| fail(e.to_string()))?;
        let size = reader
            .output_buffer_size()
            .ok_or_else(|| fail("image too large".to_owned()))?;
        let mut buf = vec![0; size];
        let info = reader
            .next_frame(&mut buf)
            .map_err(|e| fail(e.to_string()))?;
        buf.truncate(info.buffer_size());
        let rgba8 = match (info.color_type, info.bit_depth) {
            (png::ColorType::Rgba, png::BitDepth::Eight) => buf,
            (png::ColorType::Rgb, png::BitDepth::Eight) => buf
                .chunks_exact(3)
                .flat_map(|p| [p[0], p[1], p[2], 255])
                .collect(),
            (c, d) => return Err(fail(format!("unsupported pixel layout {c:?}/{d:?}"))),
        };
        Ok(Self {
            width: info.width,
            height: info.height,
            rgba8,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checker(w: u32, h: u32) -> Image {
        let rgba8 = (0..w * h)
            .flat_map(|i| {
                let v = if (i % w + i / w).is_multiple_of(2) {
                    255
                } else {
                    0
                };
                [v, (i % 251) as u8, 255 - v, 255]
            })
            .collect();
        Image {
            width: w,
            height: h,
            rgba8,
        }
    }

    #[test]
    fn png_round_trips_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frame.png");
        let img = checker(7, 5);
        img.write_png(&path).unwrap();
        assert_eq!(Image::read_png(&path).unwrap(), img);
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("frame.png")]);
        assert_eq!(img.pixel(1, 0).unwrap()[0], 0);
        assert_eq!(img.pixel(7, 0), None);
    }

    #[test]
    fn failed_write_keeps_the_old_file_and_names_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("frame.png");
        checker(2, 2).write_png(&path).unwrap();
        let bad = Image {
            width: 3,
            height: 3,
            rgba8: vec![0; 5],
        };
        let err = bad.write_png(&path).unwrap_err();
        assert!(err.to_string().contains("frame.png"), "{err}");
        assert_eq!(Image::read_png(&path).unwrap(), checker(2, 2));
        let missing_dir = dir.path().join("nope").join("x.png");
        let err = checker(2, 2).write_png(&missing_dir).unwrap_err();
        assert!(err.to_string().contains("nope"), "{err}");
    }
}
