//! An RGBA8 image read back from the GPU.

use std::{fs::File, io::BufWriter, path::Path};

use crate::RenderError;

/// A `width × height` image, rows top to bottom, 4 bytes per pixel (sRGB colour, alpha).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height * 4` bytes, row-major from the top-left pixel.
    pub rgba: Vec<u8>,
}

impl Image {
    /// The pixel in column `x`, row `y` (0 at the top).
    ///
    /// # Panics
    /// If `x >= width` or `y >= height`.
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        assert!(
            x < self.width && y < self.height,
            "pixel ({x}, {y}) outside {}x{}",
            self.width,
            self.height
        );
        let i = 4 * (y as usize * self.width as usize + x as usize);
        [
            self.rgba[i],
            self.rgba[i + 1],
            self.rgba[i + 2],
            self.rgba[i + 3],
        ]
    }

    /// Writes the image as an 8-bit RGBA PNG.
    pub fn save_png(&self, path: impl AsRef<Path>) -> Result<(), RenderError> {
        let path = path.as_ref();
        let err = |source| RenderError::Png {
            path: path.display().to_string(),
            source,
        };
        let file = File::create(path).map_err(|e| err(png::EncodingError::IoError(e)))?;
        let mut encoder = png::Encoder::new(BufWriter::new(file), self.width, self.height);
        encoder.set_color(png::ColorType::Rgba);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
        let mut writer = encoder.write_header().map_err(err)?;
        writer.write_image_data(&self.rgba).map_err(err)?;
        writer.finish().map_err(err)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixel_indexes_rows_from_the_top() {
        let mut img = Image {
            width: 3,
            height: 2,
            rgba: vec![0; 24],
        };
        img.rgba[4 * (3 + 2)..4 * (3 + 2) + 4].copy_from_slice(&[1, 2, 3, 4]);
        assert_eq!(img.pixel(2, 1), [1, 2, 3, 4]);
        assert_eq!(img.pixel(0, 0), [0; 4]);
    }

    #[test]
    fn png_round_trips() {
        let dir = std::env::temp_dir().join(format!("render-png-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.png");
        let img = Image {
            width: 2,
            height: 2,
            rgba: (0..16).map(|i| i * 15).collect(),
        };
        img.save_png(&path).unwrap();
        let decoder = png::Decoder::new(File::open(&path).unwrap());
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (2, 2));
        assert_eq!(&buf[..info.buffer_size()], &img.rgba[..]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn unwritable_path_is_an_error() {
        let img = Image {
            width: 1,
            height: 1,
            rgba: vec![0; 4],
        };
        let e = img.save_png("/nonexistent-dir/x.png").unwrap_err();
        assert!(e.to_string().contains("/nonexistent-dir/x.png"), "{e}");
    }
}
