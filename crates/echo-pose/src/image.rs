//! Colour images as the estimator takes them (a borrowed buffer, checked once), and the
//! person-centred crop the landmark model reads.

use crate::roi::Roi;
use crate::PoseError;

/// Pixel layouts accepted, 8 bits per channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PixelFormat {
    /// Red, green, blue.
    Rgb8,
    /// Blue, green, red (OpenCV's order).
    Bgr8,
    /// Red, green, blue, alpha (alpha ignored).
    Rgba8,
    /// Blue, green, red, alpha (alpha ignored).
    Bgra8,
    /// One grey channel (copied to red, green and blue).
    Mono8,
}

impl PixelFormat {
    /// Bytes per pixel.
    pub fn channels(self) -> usize {
        match self {
            PixelFormat::Rgb8 | PixelFormat::Bgr8 => 3,
            PixelFormat::Rgba8 | PixelFormat::Bgra8 => 4,
            PixelFormat::Mono8 => 1,
        }
    }

    /// The format named by a ROS `sensor_msgs/Image` encoding (`rgb8`, `bgr8`, `rgba8`, `bgra8`,
    /// `mono8`); anything else (16-bit, Bayer, YUV, compressed…) is
    /// [`PoseError::UnsupportedEncoding`].
    pub fn from_encoding(encoding: &str) -> Result<PixelFormat, PoseError> {
        match encoding.to_ascii_lowercase().as_str() {
            "rgb8" => Ok(PixelFormat::Rgb8),
            "bgr8" => Ok(PixelFormat::Bgr8),
            "rgba8" => Ok(PixelFormat::Rgba8),
            "bgra8" => Ok(PixelFormat::Bgra8),
            "mono8" | "8uc1" => Ok(PixelFormat::Mono8),
            _ => Err(PoseError::UnsupportedEncoding(encoding.to_string())),
        }
    }

    /// Byte offsets of red, green and blue within a pixel.
    fn rgb_offsets(self) -> [usize; 3] {
        match self {
            PixelFormat::Rgb8 | PixelFormat::Rgba8 => [0, 1, 2],
            PixelFormat::Bgr8 | PixelFormat::Bgra8 => [2, 1, 0],
            PixelFormat::Mono8 => [0, 0, 0],
        }
    }
}

/// Largest width or height accepted (a guard against nonsense sizes, not a model limit).
pub const MAX_SIDE: u32 = 1 << 15;

/// A borrowed 8-bit colour image, row-major, checked on construction.
#[derive(Debug, Clone, Copy)]
pub struct Image<'a> {
    width: u32,
    height: u32,
    format: PixelFormat,
    step: usize,
    data: &'a [u8],
}

impl<'a> Image<'a> {
    /// An image with tightly packed rows: `data` must hold exactly `width × height × channels`
    /// bytes.
    pub fn new(
        width: u32,
        height: u32,
        format: PixelFormat,
        data: &'a [u8],
    ) -> Result<Image<'a>, PoseError> {
        let step = (width as usize)
            .checked_mul(format.channels())
            .ok_or(PoseError::ImageTooLarge { width, height })?;
        Image::with_step(width, height, format, step, data)
    }

    /// An image whose rows are `step` bytes apart (ROS `sensor_msgs/Image.step`, which may pad
    /// rows): `data` must hold exactly `step × height` bytes.
    pub fn with_step(
        width: u32,
        height: u32,
        format: PixelFormat,
        step: usize,
        data: &'a [u8],
    ) -> Result<Image<'a>, PoseError> {
        if width == 0 || height == 0 {
            return Err(PoseError::EmptyImage { width, height });
        }
        if width > MAX_SIDE || height > MAX_SIDE {
            return Err(PoseError::ImageTooLarge { width, height });
        }
        let row = width as usize * format.channels();
        if step < row {
            return Err(PoseError::RowStride { step, min: row });
        }
        let expected = step
            .checked_mul(height as usize)
            .ok_or(PoseError::ImageTooLarge { width, height })?;
        if data.len() != expected {
            return Err(PoseError::BufferSize {
                expected,
                got: data.len(),
                width,
                height,
                channels: format.channels(),
            });
        }
        Ok(Image {
            width,
            height,
            format,
            step,
            data,
        })
    }

    /// Width in pixels.
    pub fn width(&self) -> u32 {
        self.width
    }

    /// Height in pixels.
    pub fn height(&self) -> u32 {
        self.height
    }

    /// Pixel layout.
    pub fn format(&self) -> PixelFormat {
        self.format
    }
}

/// Side of the square crop the landmark model reads.
pub const CROP: usize = 256;

/// Writes the crop `roi` of `img` into `out` as the model's input: `3 × 256 × 256` (NCHW, red,
/// green, blue planes), values in [0, 1]. The crop is the rotated square `roi`, sampled
/// bilinearly; what lies outside the image is black (MediaPipe's zero border).
pub(crate) fn sample_crop(img: &Image, roi: &Roi, out: &mut [f32]) {
    assert_eq!(out.len(), 3 * CROP * CROP);
    let (w, h) = (img.width as i64, img.height as i64);
    let ch = img.format.channels();
    let off = img.format.rgb_offsets();
    let (sin, cos) = roi.rotation.sin_cos();
    let scale = roi.size / CROP as f32;
    let plane = CROP * CROP;
    let texel = |x: i64, y: i64| -> [f32; 3] {
        if x < 0 || y < 0 || x >= w || y >= h {
            return [0.0; 3];
        }
        let i = y as usize * img.step + x as usize * ch;
        let p = &img.data[i..i + ch];
        [p[off[0]] as f32, p[off[1]] as f32, p[off[2]] as f32]
    };
    for r in 0..CROP {
        // Offsets from the crop centre, in image pixels, of this row's pixel centres.
        let dv = (r as f32 + 0.5) * scale - roi.size / 2.0;
        for c in 0..CROP {
            let du = (c as f32 + 0.5) * scale - roi.size / 2.0;
            // Continuous image coordinates (pixel k spans [k, k + 1]); sample at pixel centres.
            let x = roi.cx + cos * du - sin * dv - 0.5;
            let y = roi.cy + sin * du + cos * dv - 0.5;
            let (x0, y0) = (x.floor(), y.floor());
            let (fx, fy) = (x - x0, y - y0);
            let (x0, y0) = (x0 as i64, y0 as i64);
            let mut v = [0.0f32; 3];
            for (dx, dy, wgt) in [
                (0, 0, (1.0 - fx) * (1.0 - fy)),
                (1, 0, fx * (1.0 - fy)),
                (0, 1, (1.0 - fx) * fy),
                (1, 1, fx * fy),
            ] {
                if wgt > 0.0 {
                    let t = texel(x0 + dx, y0 + dy);
                    for k in 0..3 {
                        v[k] += wgt * t[k];
                    }
                }
            }
            let i = r * CROP + c;
            for k in 0..3 {
                out[k * plane + i] = v[k] / 255.0;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_and_encodings_are_checked() {
        let buf = vec![0u8; 4 * 3 * 3];
        assert!(Image::new(4, 3, PixelFormat::Rgb8, &buf).is_ok());
        assert!(matches!(
            Image::new(4, 3, PixelFormat::Rgba8, &buf),
            Err(PoseError::BufferSize {
                expected: 48,
                got: 36,
                ..
            })
        ));
        assert!(matches!(
            Image::new(0, 3, PixelFormat::Rgb8, &[]),
            Err(PoseError::EmptyImage { .. })
        ));
        assert!(matches!(
            Image::with_step(4, 3, PixelFormat::Rgb8, 10, &buf),
            Err(PoseError::RowStride { step: 10, min: 12 })
        ));
        // Padded rows (ROS step) are fine when the buffer is step × height.
        let padded = vec![0u8; 16 * 3];
        assert!(Image::with_step(4, 3, PixelFormat::Rgb8, 16, &padded).is_ok());
        assert!(matches!(
            Image::new(u32::MAX, u32::MAX, PixelFormat::Rgba8, &buf),
            Err(PoseError::ImageTooLarge { .. })
        ));
        assert_eq!(
            PixelFormat::from_encoding("BGR8").unwrap(),
            PixelFormat::Bgr8
        );
        for bad in ["16UC1", "yuv422", "bayer_rggb8", "jpeg", ""] {
            assert!(matches!(
                PixelFormat::from_encoding(bad),
                Err(PoseError::UnsupportedEncoding(_))
            ));
        }
    }

    /// A crop covering exactly the image reproduces it (here a 256 × 256 image), in every
    /// pixel format, with channels in RGB order.
    #[test]
    fn identity_crop_copies_pixels_in_rgb_order() {
        let n = CROP;
        let px = |x: usize, y: usize| [(x % 251) as u8, (y % 241) as u8, ((x + y) % 7) as u8];
        let mut rgb = vec![];
        let mut bgra = vec![];
        for y in 0..n {
            for x in 0..n {
                let [r, g, b] = px(x, y);
                rgb.extend([r, g, b]);
                bgra.extend([b, g, r, 255]);
            }
        }
        let roi = Roi {
            cx: n as f32 / 2.0,
            cy: n as f32 / 2.0,
            size: n as f32,
            rotation: 0.0,
        };
        for img in [
            Image::new(n as u32, n as u32, PixelFormat::Rgb8, &rgb).unwrap(),
            Image::new(n as u32, n as u32, PixelFormat::Bgra8, &bgra).unwrap(),
        ] {
            let mut out = vec![0.0; 3 * n * n];
            sample_crop(&img, &roi, &mut out);
            for (x, y) in [(0, 0), (17, 200), (255, 255), (128, 3)] {
                let want = px(x, y);
                for k in 0..3 {
                    let got = out[k * n * n + y * n + x] * 255.0;
                    assert!((got - want[k] as f32).abs() < 1e-3, "{x},{y},{k}: {got}");
                }
            }
        }
    }

    /// Outside the image the crop is black; a quarter turn maps rows to columns.
    #[test]
    fn border_is_black_and_rotation_turns_the_crop() {
        let n = 64usize;
        let mut grey = vec![0u8; n * n];
        for y in 0..n {
            for x in 0..n {
                grey[y * n + x] = (x * 4) as u8; // brighter to the right
            }
        }
        let img = Image::new(n as u32, n as u32, PixelFormat::Mono8, &grey).unwrap();
        let mut out = vec![0.0; 3 * CROP * CROP];
        // Twice the image: the outer ring is outside it.
        let big = Roi {
            cx: 32.0,
            cy: 32.0,
            size: 128.0,
            rotation: 0.0,
        };
        sample_crop(&img, &big, &mut out);
        assert_eq!(out[0], 0.0);
        assert_eq!(out[CROP * CROP - 1], 0.0);
        // A quarter turn clockwise: the crop's "down" is the image's "left", so brightness
        // falls from the top row to the bottom row of the crop.
        let turned = Roi {
            cx: 32.0,
            cy: 32.0,
            size: 48.0,
            rotation: std::f32::consts::FRAC_PI_2,
        };
        sample_crop(&img, &turned, &mut out);
        let at = |r: usize, c: usize| out[r * CROP + c];
        assert!(
            at(10, 128) > at(245, 128) + 0.3,
            "{} {}",
            at(10, 128),
            at(245, 128)
        );
        assert!((at(128, 10) - at(128, 245)).abs() < 0.02);
    }
}
