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
        '7' => [7, 1, 2, 2, 2],
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

/// One curve of a [`Panel`]: points (x, y) and an RGB colour.
pub struct Curve {
    /// Points, in x order.
    pub points: Vec<(f64, f64)>,
    /// Colour.
    pub rgb: [u8; 3],
}

/// A line chart panel; its axis ranges fit the data and their ends are labelled with numbers.
pub struct Panel {
    /// Curves.
    pub curves: Vec<Curve>,
}

/// Draw panels side by side (each 360 × 240 px) into a PNG.
pub fn chart(path: &Path, panels: &[Panel]) -> Result<(), String> {
    let (pw, ph) = (360u32, 240u32);
    let mut img = RgbImage::from_pixel(pw * panels.len().max(1) as u32, ph, Rgb([255, 255, 255]));
    for (i, p) in panels.iter().enumerate() {
        let pts = p.curves.iter().flat_map(|c| c.points.iter());
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for &(x, y) in pts.filter(|(x, y)| x.is_finite() && y.is_finite()) {
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
        if x0 > x1 {
            continue;
        }
        let (x1, y1) = (x1.max(x0 + 1e-9), y1.max(y0 + 1e-9));
        let ox = i as u32 * pw;
        let (l, r, t, b) = (
            ox as f64 + 44.0,
            (ox + pw) as f64 - 12.0,
            12.0,
            ph as f64 - 24.0,
        );
        let axis = Rgb([90, 90, 90]);
        line(&mut img, (l, b), (r, b), axis, 1);
        line(&mut img, (l, t), (l, b), axis, 1);
        let map = |x: f64, y: f64| {
            (
                l + (x - x0) / (x1 - x0) * (r - l),
                b - (y - y0) / (y1 - y0) * (b - t),
            )
        };
        for c in &p.curves {
            for w in c.points.windows(2) {
                line(
                    &mut img,
                    map(w[0].0, w[0].1),
                    map(w[1].0, w[1].1),
                    Rgb(c.rgb),
                    2,
                );
            }
        }
        let num = |v: f64| {
            if (v - v.round()).abs() < 1e-9 || v.abs() >= 100.0 {
                format!("{v:.0}")
            } else if v.abs() >= 1.0 {
                format!("{v:.1}")
            } else {
                format!("{v:.3}")
            }
        };
        text(&mut img, &num(y1), ox + 2, t as u32, 2);
        text(&mut img, &num(y0), ox + 2, b as u32 - 10, 2);
        text(&mut img, &num(x0), l as u32, b as u32 + 6, 2);
        let xs = num(x1);
        text(
            &mut img,
            &xs,
            r as u32 - 8 * xs.len() as u32,
            b as u32 + 6,
            2,
        );
    }
    img.save(path)
        .map_err(|e| format!("{}: {e}", path.display()))
}

/// A stick figure: line segments in one colour.
pub struct Figure {
    /// Segments (metres, z up).
    pub segments: Vec<(Vector3<f64>, Vector3<f64>)>,
    /// Colour.
    pub rgb: [u8; 3],
}

/// Panels of stick figures seen from the front (camera on +x looking back, z up), all at one
/// scale (`px_per_m`), each panel 2.4 m wide and 2.0 m tall, ground at the bottom.
pub fn front_views(path: &Path, panels: &[Vec<Figure>], px_per_m: f64) -> Result<(), String> {
    let (pw, ph) = ((2.4 * px_per_m) as u32, (2.0 * px_per_m) as u32);
    let mut img = RgbImage::from_pixel(pw * panels.len().max(1) as u32, ph, Rgb([255, 255, 255]));
    for (i, figs) in panels.iter().enumerate() {
        let ox = i as f64 * pw as f64 + pw as f64 / 2.0;
        // A slight elevation so depth is readable.
        let proj = |p: &Vector3<f64>| {
            (
                ox - p.y * px_per_m - 0.15 * p.x * px_per_m,
                ph as f64 - 8.0 - (p.z - 0.1 * p.x) * px_per_m,
            )
        };
        line(
            &mut img,
            (i as f64 * pw as f64, ph as f64 - 8.0),
            ((i + 1) as f64 * pw as f64, ph as f64 - 8.0),
            Rgb([200, 200, 200]),
            1,
        );
        for f in figs {
            for (a, b) in &f.segments {
                line(&mut img, proj(a), proj(b), Rgb(f.rgb), 3);
            }
        }
    }
    img.save(path)
        .map_err(|e| format!("{}: {e}", path.display()))
}

/// The segments of a 22-joint skeleton.
pub fn skeleton_segments(p: &[Vector3<f64>; 22]) -> Vec<(Vector3<f64>, Vector3<f64>)> {
    BONES.iter().map(|(a, b)| (p[*a], p[*b])).collect()
}

#[cfg(test)]
mod chart_tests {
    use super::*;

    #[test]
    fn chart_draws_each_curve_in_its_colour() {
        let scratch = tempfile::tempdir().unwrap();
        let p = scratch.path().join("chart.png");
        let up = Curve {
            points: (0..10).map(|i| (i as f64, i as f64)).collect(),
            rgb: [200, 0, 0],
        };
        let down = Curve {
            points: (0..10).map(|i| (i as f64, 9.0 - i as f64)).collect(),
            rgb: [0, 0, 200],
        };
        chart(
            &p,
            &[
                Panel {
                    curves: vec![up, down],
                },
                Panel { curves: vec![] },
            ],
        )
        .unwrap();
        let img = image::open(&p).unwrap().to_rgb8();
        assert_eq!(img.dimensions(), (720, 240));
        let count = |c: [u8; 3]| img.pixels().filter(|px| px.0 == c).count();
        assert!(count([200, 0, 0]) > 200 && count([0, 0, 200]) > 200);
    }
}
