//! Pictures of interactions: both skeletons from a fixed three-quarter view, ground truth in
//! solid colours and a prediction in light colours, a floor grid, and the time stamp, as PNG
//! frames or an animated GIF. Self-contained raster drawing (no fonts needed: a 3 × 5 digit font).

use std::path::Path;

use image::{Rgb, RgbImage};
use nalgebra::Vector3;

use crate::metrics::Frame;

const BONES: [(usize, usize); 21] = [
    (0, 1),
    (0, 2),
    (0, 3),
    (1, 4),
    (2, 5),
    (3, 6),
    (4, 7),
    (5, 8),
    (6, 9),
    (7, 10),
    (8, 11),
    (9, 12),
    (9, 13),
    (9, 14),
    (12, 15),
    (13, 16),
    (14, 17),
    (16, 18),
    (17, 19),
    (18, 20),
    (19, 21),
];
const TRUTH: [Rgb<u8>; 2] = [Rgb([30, 90, 200]), Rgb([220, 110, 20])];
const PRED: [Rgb<u8>; 2] = [Rgb([140, 190, 255]), Rgb([255, 190, 120])];

/// Image size and view.
#[derive(Debug, Clone, Copy)]
pub struct View {
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// Camera azimuth relative to the line between the two people, radians (0: side view).
    pub azimuth: f64,
    /// Elevation, radians.
    pub elevation: f64,
}

impl Default for View {
    fn default() -> Self {
        View {
            width: 480,
            height: 360,
            azimuth: -0.35,
            elevation: 0.3,
        }
    }
}

struct Projector {
    view: View,
    centre: Vector3<f64>,
    scale: f64,
}

impl Projector {
    fn fit(view: View, frames: &[&Frame]) -> Projector {
        let mut lo = Vector3::repeat(f64::INFINITY);
        let mut hi = Vector3::repeat(f64::NEG_INFINITY);
        for f in frames {
            for p in f.iter() {
                for x in p.iter() {
                    lo = lo.inf(x);
                    hi = hi.sup(x);
                }
            }
        }
        let centre = (lo + hi) / 2.0;
        let extent = (hi - lo).norm().max(1.0);
        // Look across the line between the two people (three-quarter view), so they never
        // hide each other.
        let mut view = view;
        if let Some(f) = frames.first().filter(|f| f.len() >= 2) {
            let axis = f[1][0] - f[0][0];
            if axis.xy().norm() > 1e-6 {
                view.azimuth += axis.y.atan2(axis.x);
            }
        }
        Projector {
            view,
            centre,
            scale: 0.85 * view.height.min(view.width) as f64 / extent,
        }
    }

    fn project(&self, p: &Vector3<f64>) -> (f64, f64) {
        let d = p - self.centre;
        let (sa, ca) = self.view.azimuth.sin_cos();
        let x = ca * d.x + sa * d.y;
        let y = -sa * d.x + ca * d.y;
        let (se, ce) = self.view.elevation.sin_cos();
        let up = d.z * ce - y * se;
        (
            self.view.width as f64 / 2.0 + x * self.scale,
            self.view.height as f64 / 2.0 - up * self.scale,
        )
    }
}

fn line(img: &mut RgbImage, a: (f64, f64), b: (f64, f64), c: Rgb<u8>, width: i32) {
    let n = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as i32).max(1);
    for i in 0..=n {
        let t = i as f64 / n as f64;
        let (x, y) = (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1));
        for dx in -width / 2..=width / 2 {
            for dy in -width / 2..=width / 2 {
                let (px, py) = (x.round() as i32 + dx, y.round() as i32 + dy);
                if px >= 0 && py >= 0 && (px as u32) < img.width() && (py as u32) < img.height() {
                    img.put_pixel(px as u32, py as u32, c);
                }
            }
        }
    }
}

/// 3 × 5 glyphs for digits, '.', 's'.
fn glyph(c: char) -> [u8; 5] {
    match c {
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [7, 1, 7, 4, 7],
        '3' => [7, 1, 7, 1, 7],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 7, 1, 7],
        '6' => [7, 4, 7, 5, 7],
        '7' => [7, 1, 1, 1, 1],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 7],
        '.' => [0, 0, 0, 0, 2],
        's' => [0, 3, 4, 1, 6],
        _ => [0; 5],
    }
}

fn text(img: &mut RgbImage, s: &str, x0: u32, y0: u32, px: u32) {
    for (i, c) in s.chars().enumerate() {
        let g = glyph(c);
        for (row, bits) in g.iter().enumerate() {
            for col in 0..3 {
                if bits & (4 >> col) != 0 {
                    for dx in 0..px {
                        for dy in 0..px {
                            let x = x0 + (i as u32 * 4 + col) * px + dx;
                            let y = y0 + row as u32 * px + dy;
                            if x < img.width() && y < img.height() {
                                img.put_pixel(x, y, Rgb([20, 20, 20]));
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Draw one frame: `truth` solid, `pred` (if any) light, time stamp `t` seconds.
fn draw(proj: &Projector, truth: &Frame, pred: Option<&Frame>, t: f64) -> RgbImage {
    let v = proj.view;
    let mut img = RgbImage::from_pixel(v.width, v.height, Rgb([250, 250, 250]));
    // Floor grid at z = 0, 0.5 m spacing around the centre.
    let c = proj.centre;
    for k in -6..=6 {
        let o = k as f64 * 0.5;
        let g = Rgb([215, 215, 215]);
        line(
            &mut img,
            proj.project(&Vector3::new(c.x + o, c.y - 3.0, 0.0)),
            proj.project(&Vector3::new(c.x + o, c.y + 3.0, 0.0)),
            g,
            0,
        );
        line(
            &mut img,
            proj.project(&Vector3::new(c.x - 3.0, c.y + o, 0.0)),
            proj.project(&Vector3::new(c.x + 3.0, c.y + o, 0.0)),
            g,
            0,
        );
    }
    if let Some(p) = pred {
        for (i, person) in p.iter().enumerate() {
            for (a, b) in BONES {
                line(
                    &mut img,
                    proj.project(&person[a]),
                    proj.project(&person[b]),
                    PRED[i % 2],
                    2,
                );
            }
        }
    }
    for (i, person) in truth.iter().enumerate() {
        for (a, b) in BONES {
            line(
                &mut img,
                proj.project(&person[a]),
                proj.project(&person[b]),
                TRUTH[i % 2],
                2,
            );
        }
        let (hx, hy) = proj.project(&person[15]);
        for r in 0..5 {
            line(
                &mut img,
                (hx - r as f64, hy - 5.0),
                (hx - r as f64, hy + 5.0),
                TRUTH[i % 2],
                1,
            );
            line(
                &mut img,
                (hx + r as f64, hy - 5.0),
                (hx + r as f64, hy + 5.0),
                TRUTH[i % 2],
                1,
            );
        }
    }
    text(&mut img, &format!("{t:.2}s"), 8, 8, 3);
    img
}

/// Render frames (truth, optional prediction aligned to the same frames) at `fps` into `path`:
/// an animated GIF if it ends in `.gif`, otherwise numbered PNGs `<path>_NNN.png`.
pub fn render(
    path: &Path,
    truth: &[Frame],
    pred: Option<&[Frame]>,
    fps: f64,
    view: View,
) -> Result<Vec<std::path::PathBuf>, String> {
    let all: Vec<&Frame> = truth.iter().chain(pred.unwrap_or(&[]).iter()).collect();
    if all.is_empty() {
        return Err("nothing to render".into());
    }
    let proj = Projector::fit(view, &all);
    let images: Vec<RgbImage> = truth
        .iter()
        .enumerate()
        .map(|(k, f)| draw(&proj, f, pred.and_then(|p| p.get(k)), k as f64 / fps))
        .collect();
    if path.extension().is_some_and(|e| e == "gif") {
        let file = std::fs::File::create(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let mut enc = image::codecs::gif::GifEncoder::new_with_speed(file, 10);
        enc.set_repeat(image::codecs::gif::Repeat::Infinite)
            .map_err(|e| e.to_string())?;
        let delay = image::Delay::from_numer_denom_ms((1000.0 / fps).round() as u32, 1);
        for img in images {
            let rgba = image::DynamicImage::ImageRgb8(img).to_rgba8();
            enc.encode_frame(image::Frame::from_parts(rgba, 0, 0, delay))
                .map_err(|e| e.to_string())?;
        }
        Ok(vec![path.to_path_buf()])
    } else {
        let mut out = vec![];
        for (k, img) in images.iter().enumerate() {
            let p = path.with_file_name(format!(
                "{}_{k:03}.png",
                path.file_stem().and_then(|s| s.to_str()).unwrap_or("frame")
            ));
            img.save(&p).map_err(|e| format!("{}: {e}", p.display()))?;
            out.push(p);
        }
        Ok(out)
    }
}

/// A strip of `n` frames side by side (one PNG), for documents.
pub fn strip(
    path: &Path,
    truth: &[Frame],
    pred: Option<&[Frame]>,
    fps: f64,
    n: usize,
    view: View,
) -> Result<(), String> {
    let all: Vec<&Frame> = truth.iter().chain(pred.unwrap_or(&[]).iter()).collect();
    if all.is_empty() || n == 0 {
        return Err("nothing to render".into());
    }
    let proj = Projector::fit(view, &all);
    let mut out = RgbImage::new(view.width * n as u32, view.height);
    for i in 0..n {
        let k = if n == 1 {
            0
        } else {
            i * (truth.len() - 1) / (n - 1)
        };
        let img = draw(
            &proj,
            &truth[k],
            pred.and_then(|p| p.get(k)),
            k as f64 / fps,
        );
        image::imageops::overlay(&mut out, &img, (i as u32 * view.width) as i64, 0);
    }
    out.save(path)
        .map_err(|e| format!("{}: {e}", path.display()))
}
