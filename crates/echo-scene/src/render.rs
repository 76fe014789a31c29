//! Pictures of scenes: a perspective view from a fixed camera beside the interaction and
//! slightly above it, a floor with a grid, the scene's primitives drawn far to near (capsules
//! and spheres shaded, ghosts blended by their opacity), the time and the captions on top;
//! frames written as an animated GIF with one palette chosen from the pictures.

use std::io::Write;
use std::path::Path;

use nalgebra::Vector3;

use crate::builder::{SceneBuilder, SceneOptions};
use crate::font::{glyph, text_width, GLYPH_H, GLYPH_W};
use crate::scene::{EntityKind, Primitive, Rgba, Scene};
use crate::{style, SceneError};

/// Where the picture is taken from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraView {
    /// Camera position in the scene frame, m.
    pub eye: [f64; 3],
    /// The point at the centre of the picture.
    pub target: [f64; 3],
    /// Vertical field of view, degrees.
    pub fov_y_deg: f64,
}

impl Default for CameraView {
    /// On the robot's right, 4.3 m out and 2.1 m up, looking at the space between the robot and
    /// a partner about 1.5 m in front of it.
    fn default() -> Self {
        CameraView {
            eye: [0.9, -4.3, 2.1],
            target: [0.9, 0.0, 0.8],
            fov_y_deg: 40.0,
        }
    }
}

/// A pinhole projection of [`CameraView`] onto a `width × height` picture.
#[derive(Debug, Clone)]
pub struct Projector {
    eye: Vector3<f64>,
    right: Vector3<f64>,
    up: Vector3<f64>,
    forward: Vector3<f64>,
    focal_px: f64,
    width: u32,
    height: u32,
}

/// Points nearer to the camera than this are not drawn, m.
const NEAR: f64 = 0.05;

impl Projector {
    /// The projection for `view` (z up; the view must not look straight up or down).
    pub fn new(view: &CameraView, width: u32, height: u32) -> Projector {
        let eye = Vector3::from(view.eye);
        let forward = (Vector3::from(view.target) - eye)
            .try_normalize(1e-9)
            .unwrap_or_else(Vector3::x);
        let right = forward
            .cross(&Vector3::z())
            .try_normalize(1e-9)
            .unwrap_or_else(|| -Vector3::y());
        let up = right.cross(&forward);
        let fov = view.fov_y_deg.clamp(1.0, 170.0).to_radians();
        Projector {
            eye,
            right,
            up,
            forward,
            focal_px: height as f64 / 2.0 / (fov / 2.0).tan(),
            width,
            height,
        }
    }

    /// `p` in camera coordinates: (right, up, depth along the view).
    fn camera(&self, p: &Vector3<f64>) -> Vector3<f64> {
        let d = p - self.eye;
        Vector3::new(d.dot(&self.right), d.dot(&self.up), d.dot(&self.forward))
    }

    fn pixel(&self, c: &Vector3<f64>) -> (f64, f64) {
        (
            self.width as f64 / 2.0 + self.focal_px * c.x / c.z,
            self.height as f64 / 2.0 - self.focal_px * c.y / c.z,
        )
    }

    /// Pixel column and row (the centre of pixel (i, j) is at (i + 0.5, j + 0.5)) and depth (m)
    /// of a point, or `None` behind the camera.
    pub fn project(&self, p: [f64; 3]) -> Option<(f64, f64, f64)> {
        let c = self.camera(&Vector3::from(p));
        if c.z < NEAR {
            return None;
        }
        let (x, y) = self.pixel(&c);
        Some((x, y, c.z))
    }

    /// Pixels per metre at `depth`.
    fn scale(&self, depth: f64) -> f64 {
        self.focal_px / depth
    }

    /// The row of the horizon (where the floor meets the sky).
    fn horizon_row(&self) -> f64 {
        let flat = Vector3::new(self.forward.x, self.forward.y, 0.0);
        match flat.try_normalize(1e-9) {
            Some(d) => {
                let c = Vector3::new(d.dot(&self.right), d.dot(&self.up), d.dot(&self.forward));
                if c.z > 1e-6 {
                    self.pixel(&c).1
                } else {
                    f64::NEG_INFINITY
                }
            }
            None => f64::NEG_INFINITY,
        }
    }

    /// The part of segment `a–b` in front of the near plane, projected.
    fn segment(&self, a: [f64; 3], b: [f64; 3]) -> Option<Projected> {
        let (mut ca, mut cb) = (self.camera(&a.into()), self.camera(&b.into()));
        if ca.z < NEAR && cb.z < NEAR {
            return None;
        }
        if ca.z < NEAR {
            ca = ca + (cb - ca) * ((NEAR - ca.z) / (cb.z - ca.z));
        } else if cb.z < NEAR {
            cb = cb + (ca - cb) * ((NEAR - cb.z) / (ca.z - cb.z));
        }
        Some((self.pixel(&ca), ca.z, self.pixel(&cb), cb.z))
    }
}

/// A projected segment: (pixel a, depth a, pixel b, depth b).
type Projected = ((f64, f64), f64, (f64, f64), f64);

/// An RGB picture, rows top to bottom.
#[derive(Debug, Clone, PartialEq)]
pub struct Picture {
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// `width × height` RGB triples.
    pub rgb: Vec<[u8; 3]>,
}

impl Picture {
    fn new(width: u32, height: u32, fill: [u8; 3]) -> Picture {
        Picture {
            width,
            height,
            rgb: vec![fill; width as usize * height as usize],
        }
    }

    /// The colour at column `x`, row `y` (`None` outside).
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        (x < self.width && y < self.height)
            .then(|| self.rgb[y as usize * self.width as usize + x as usize])
    }

    fn blend(&mut self, x: i64, y: i64, c: [f32; 3], a: f32) {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return;
        }
        let px = &mut self.rgb[y as usize * self.width as usize + x as usize];
        for k in 0..3 {
            let v = px[k] as f32 * (1.0 - a) + c[k] * 255.0 * a;
            px[k] = v.round().clamp(0.0, 255.0) as u8;
        }
    }

    /// A filled 2D capsule from `a` (radius `ra`) to `b` (radius `rb`), in pixels; `shade`
    /// darkens towards the rim like a lit cylinder.
    fn capsule(
        &mut self,
        a: (f64, f64),
        ra: f64,
        b: (f64, f64),
        rb: f64,
        color: Rgba,
        shade: bool,
    ) {
        let r = ra.max(rb);
        let x0 = (a.0.min(b.0) - r).floor().max(0.0) as i64;
        let x1 = (a.0.max(b.0) + r).ceil().min(self.width as f64 - 1.0) as i64;
        let y0 = (a.1.min(b.1) - r).floor().max(0.0) as i64;
        let y1 = (a.1.max(b.1) + r).ceil().min(self.height as f64 - 1.0) as i64;
        if x0 > x1 || y0 > y1 {
            return;
        }
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let len2 = dx * dx + dy * dy;
        let c = [color.r, color.g, color.b];
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                let t = if len2 > 1e-12 {
                    (((px - a.0) * dx + (py - a.1) * dy) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let (qx, qy) = (a.0 + t * dx - px, a.1 + t * dy - py);
                let d2 = qx * qx + qy * qy;
                let rad = ra + t * (rb - ra);
                if d2 <= rad * rad {
                    let k = if shade {
                        1.0 - 0.4 * (d2 / (rad * rad)) as f32
                    } else {
                        1.0
                    };
                    self.blend(x, y, [c[0] * k, c[1] * k, c[2] * k], color.a);
                }
            }
        }
    }

    /// Text with its top-left corner at (x, y), `scale` pixels per font pixel, with a halo of
    /// `halo` (when given) so it reads on any background.
    fn text(
        &mut self,
        x: i64,
        y: i64,
        text: &str,
        scale: usize,
        color: Rgba,
        halo: Option<[u8; 3]>,
    ) {
        let s = scale as i64;
        let c = [color.r, color.g, color.b];
        for pass in 0..2 {
            if pass == 0 && halo.is_none() {
                continue;
            }
            for (i, ch) in text.chars().enumerate() {
                let gx = x + i as i64 * (GLYPH_W as i64 + 1) * s;
                for (row, bits) in glyph(ch).iter().enumerate() {
                    for col in 0..GLYPH_W {
                        if bits & (1 << (GLYPH_W - 1 - col)) == 0 {
                            continue;
                        }
                        let (px, py) = (gx + col as i64 * s, y + row as i64 * s);
                        for yy in 0..s {
                            for xx in 0..s {
                                if pass == 0 {
                                    let h = halo.unwrap_or([255; 3]);
                                    let hc = [
                                        h[0] as f32 / 255.0,
                                        h[1] as f32 / 255.0,
                                        h[2] as f32 / 255.0,
                                    ];
                                    for (ox, oy) in [(-1, 0), (1, 0), (0, -1), (0, 1)] {
                                        self.blend(px + xx + ox, py + yy + oy, hc, 1.0);
                                    }
                                } else {
                                    self.blend(px + xx, py + yy, c, color.a);
                                }
                            }
                        }
                    }
                }
            }
        }
    }
}

const SKY: [u8; 3] = [248, 248, 246];
const FLOOR: [u8; 3] = [232, 231, 225];
const GRID: Rgba = Rgba::rgb8(200, 199, 192);
const GRID_AXIS: Rgba = Rgba::rgb8(170, 169, 160);

/// One thing to draw, in pixels, with its depth for ordering.
enum Item<'a> {
    Round {
        a: (f64, f64),
        ra: f64,
        b: (f64, f64),
        rb: f64,
        color: Rgba,
        shade: bool,
    },
    Label {
        at: (f64, f64),
        text: &'a str,
        scale: usize,
        color: Rgba,
    },
}

/// Draw `scene` as seen through `projector`; `elapsed_s` is printed as the time.
pub fn draw(scene: &Scene, projector: &Projector, elapsed_s: f64) -> Picture {
    let (w, h) = (projector.width, projector.height);
    let mut pic = Picture::new(w, h, SKY);
    let horizon = projector.horizon_row();
    let first_floor_row = horizon.ceil().clamp(0.0, h as f64) as usize;
    for px in &mut pic.rgb[first_floor_row * w as usize..] {
        *px = FLOOR;
    }
    // Floor grid, every 0.5 m.
    for i in -2..=8 {
        let x = i as f64 * 0.5;
        floor_line(
            &mut pic,
            projector,
            [x, -2.5, 0.0],
            [x, 2.5, 0.0],
            if i == 0 { GRID_AXIS } else { GRID },
        );
    }
    for i in -5..=5 {
        let y = i as f64 * 0.5;
        floor_line(
            &mut pic,
            projector,
            [-1.0, y, 0.0],
            [4.0, y, 0.0],
            if i == 0 { GRID_AXIS } else { GRID },
        );
    }
    let mut items: Vec<(f64, Item)> = vec![];
    for e in &scene.entities {
        for p in &e.primitives {
            // The safety label is the first caption: drawn once, in the overlay.
            if e.kind == EntityKind::Safety && matches!(p, Primitive::Text { .. }) {
                continue;
            }
            push_items(&mut items, projector, p);
        }
    }
    // Far to near; labels last.
    items.sort_by(|(da, a), (db, b)| {
        let la = matches!(a, Item::Label { .. });
        let lb = matches!(b, Item::Label { .. });
        la.cmp(&lb).then(db.total_cmp(da))
    });
    let halo = Some(SKY);
    for (_, item) in &items {
        match item {
            Item::Round {
                a,
                ra,
                b,
                rb,
                color,
                shade,
            } => pic.capsule(*a, *ra, *b, *rb, *color, *shade),
            Item::Label {
                at,
                text,
                scale,
                color,
            } => {
                let tw = text_width(text, *scale) as f64;
                let th = (GLYPH_H * scale) as f64;
                pic.text(
                    (at.0 - tw / 2.0) as i64,
                    (at.1 - th / 2.0) as i64,
                    text,
                    *scale,
                    *color,
                    halo,
                );
            }
        }
    }
    // Overlay: time, captions, legend.
    let scale = if w >= 480 { 2 } else { 1 };
    let line = ((GLYPH_H + 3) * scale) as i64;
    let max_chars = (w as usize).saturating_sub(16) / ((GLYPH_W + 1) * scale);
    pic.text(
        8,
        8,
        &format!("t = {elapsed_s:.1} s"),
        scale,
        style::TEXT,
        halo,
    );
    for (i, c) in scene.captions.iter().enumerate() {
        let text: String = c.text.chars().take(max_chars).collect();
        pic.text(8, 8 + line * (i as i64 + 1), &text, scale, c.color, halo);
    }
    let mut x = 8i64;
    let y = h as i64 - 8 - (GLYPH_H * scale) as i64;
    for (name, color) in [
        ("partner", style::PARTNER),
        ("forecast", style::FORECAST),
        ("robot", style::ROBOT_TORSO),
        ("arms", style::ROBOT_ARM_LEFT),
        ("camera", style::CAMERA),
    ] {
        let s = (GLYPH_H * scale) as f64;
        let c = (x as f64 + s / 2.0, y as f64 + s / 2.0);
        pic.capsule(c, s / 2.0, c, s / 2.0, color, false);
        x += s as i64 + 4;
        pic.text(x, y, name, scale, style::TEXT, None);
        x += text_width(name, scale) as i64 + 10;
    }
    pic
}

fn floor_line(pic: &mut Picture, projector: &Projector, a: [f64; 3], b: [f64; 3], color: Rgba) {
    if let Some((pa, _, pb, _)) = projector.segment(a, b) {
        pic.capsule(pa, 0.6, pb, 0.6, color, false);
    }
}

fn push_items<'a>(items: &mut Vec<(f64, Item<'a>)>, projector: &Projector, p: &'a Primitive) {
    match p {
        Primitive::Sphere {
            centre,
            radius,
            color,
        } => {
            if let Some((x, y, d)) = projector.project(*centre) {
                let r = (radius * projector.scale(d)).max(1.0);
                items.push((
                    d,
                    Item::Round {
                        a: (x, y),
                        ra: r,
                        b: (x, y),
                        rb: r,
                        color: *color,
                        shade: true,
                    },
                ));
            }
        }
        Primitive::Capsule {
            a,
            b,
            radius,
            color,
        } => {
            if let Some((pa, da, pb, db)) = projector.segment(*a, *b) {
                let ra = (radius * projector.scale(da)).max(1.0);
                let rb = (radius * projector.scale(db)).max(1.0);
                items.push((
                    (da + db) / 2.0,
                    Item::Round {
                        a: pa,
                        ra,
                        b: pb,
                        rb,
                        color: *color,
                        shade: true,
                    },
                ));
            }
        }
        Primitive::LineStrip {
            points,
            width,
            color,
        } => {
            for s in points.windows(2) {
                if let Some((pa, da, pb, db)) = projector.segment(s[0], s[1]) {
                    let ra = (width / 2.0 * projector.scale(da)).max(0.75);
                    let rb = (width / 2.0 * projector.scale(db)).max(0.75);
                    items.push((
                        (da + db) / 2.0,
                        Item::Round {
                            a: pa,
                            ra,
                            b: pb,
                            rb,
                            color: *color,
                            shade: false,
                        },
                    ));
                }
            }
        }
        Primitive::Text {
            position,
            text,
            size,
            color,
        } => {
            if let Some((x, y, d)) = projector.project(*position) {
                let scale = (size * projector.scale(d) / GLYPH_H as f64)
                    .round()
                    .clamp(1.0, 3.0) as usize;
                items.push((
                    d,
                    Item::Label {
                        at: (x, y),
                        text,
                        scale,
                        color: *color,
                    },
                ));
            }
        }
    }
}

/// How a recording is rendered.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderOptions {
    /// Frames per second of the GIF (at most 50). Default 10.
    pub fps: f64,
    /// Width, px. Default 640.
    pub width: u32,
    /// Height, px (default: ¾ of the width).
    pub height: Option<u32>,
    /// The view.
    pub camera: CameraView,
    /// How scenes are built.
    pub scene: SceneOptions,
    /// Most frames rendered; a longer recording is an error (lower `fps`). Default 6000.
    pub max_frames: usize,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            fps: 10.0,
            width: 640,
            height: None,
            camera: CameraView::default(),
            scene: SceneOptions::default(),
            max_frames: 6000,
        }
    }
}

impl RenderOptions {
    /// Width and height, checked.
    fn size(&self) -> Result<(u32, u32), SceneError> {
        let h = self.height.unwrap_or(self.width * 3 / 4);
        for (name, v) in [("width", self.width), ("height", h)] {
            if !(16..=4096).contains(&v) {
                return Err(SceneError::Option {
                    name,
                    message: format!("{v} px is outside 16–4096"),
                });
            }
        }
        Ok((self.width, h))
    }

    fn check_fps(&self) -> Result<(), SceneError> {
        if self.fps.is_finite() && self.fps > 0.0 && self.fps <= 50.0 {
            Ok(())
        } else {
            Err(SceneError::Option {
                name: "fps",
                message: format!(
                    "{} is outside (0, 50] (GIF delays are in 1/100 s)",
                    self.fps
                ),
            })
        }
    }
}

/// What a render produced.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderSummary {
    /// Frames in the GIF.
    pub frames: usize,
    /// Its playing time, s (the sum of the frame delays).
    pub duration_s: f64,
    /// The span of the recording, s (first to last message).
    pub recording_s: f64,
    /// Picture width, px.
    pub width: u32,
    /// Picture height, px.
    pub height: u32,
    /// Messages read.
    pub messages: usize,
    /// Messages refused as malformed or invalid (ignored).
    pub rejected: u64,
}

/// Frames for a span of `span_ns` at `fps`: one at the start and one every `1/fps` after it,
/// up to and including the end.
pub fn frame_count(span_ns: u64, fps: f64) -> usize {
    (span_ns as f64 / 1e9 * fps + 1e-9).floor() as usize + 1
}

/// Render an MCAP recording of the bus (echo-record's format) into an animated GIF: one frame
/// every `1/fps` s of recording time from its first message to its last.
pub fn render_recording(
    mcap_path: &Path,
    gif_path: &Path,
    opts: &RenderOptions,
) -> Result<RenderSummary, SceneError> {
    opts.check_fps()?;
    let (width, height) = opts.size()?;
    let records = echo_record::read_recording(mcap_path)?;
    let (Some(first), Some(last)) = (records.first(), records.last()) else {
        return Err(SceneError::Empty(mcap_path.to_path_buf()));
    };
    let (t0, t1) = (first.log_time_ns, last.log_time_ns);
    let n = frame_count(t1 - t0, opts.fps);
    if n > opts.max_frames {
        return Err(SceneError::Option {
            name: "fps",
            message: format!(
                "{:.1} s at {} fps is {n} frames, more than the limit of {}",
                (t1 - t0) as f64 / 1e9,
                opts.fps,
                opts.max_frames
            ),
        });
    }
    let projector = Projector::new(&opts.camera, width, height);
    let frame_time = |k: usize| t0 + (k as f64 * 1e9 / opts.fps).round() as u64;
    let builder =
        || SceneBuilder::with_model(echo_robot::RobotModel::tiago_dual(), opts.scene.clone());
    // Pass 1: a few pictures spread over the recording choose the palette.
    let samples: Vec<usize> = (0..n)
        .step_by(n.div_ceil(12).max(1))
        .chain([n - 1])
        .collect();
    let mut b = builder()?;
    let mut next = 0;
    let mut pictures = vec![];
    for k in samples {
        let t = frame_time(k);
        while next < records.len() && records[next].log_time_ns <= t {
            let r = &records[next];
            b.on_message_at(&r.key, &r.payload, Some(r.log_time_ns));
            next += 1;
        }
        pictures.push(draw(&b.scene(t), &projector, (t - t0) as f64 / 1e9));
    }
    let palette = Palette::from_pictures(&pictures);
    drop(pictures);
    // Pass 2: every frame.
    let mut gif = GifWriter::create(gif_path, width, height, palette)?;
    let mut b = builder()?;
    let mut next = 0;
    for k in 0..n {
        let t = frame_time(k);
        while next < records.len() && records[next].log_time_ns <= t {
            let r = &records[next];
            b.on_message_at(&r.key, &r.payload, Some(r.log_time_ns));
            next += 1;
        }
        let pic = draw(&b.scene(t), &projector, (t - t0) as f64 / 1e9);
        gif.push(&pic, gif_delay(k, opts.fps))?;
    }
    let duration_s = gif.finish()?;
    Ok(RenderSummary {
        frames: n,
        duration_s,
        recording_s: (t1 - t0) as f64 / 1e9,
        width,
        height,
        messages: records.len(),
        rejected: b.stats().rejected_total(),
    })
}

/// Delay of frame `k` in 1/100 s, so that the delays add up to the frame times (at least 2:
/// viewers show shorter delays as 1/10 s).
fn gif_delay(k: usize, fps: f64) -> u16 {
    let at = |k: usize| (k as f64 * 100.0 / fps).round() as i64;
    (at(k + 1) - at(k)).clamp(2, u16::MAX as i64) as u16
}

/// Write `pictures` (all of one size) as an animated GIF at `fps`; returns its playing time, s.
pub fn write_gif(path: &Path, pictures: &[Picture], fps: f64) -> Result<f64, SceneError> {
    let opts = RenderOptions {
        fps,
        ..RenderOptions::default()
    };
    opts.check_fps()?;
    let Some(first) = pictures.first() else {
        return Err(SceneError::Option {
            name: "pictures",
            message: "no pictures to write".into(),
        });
    };
    let mut gif = GifWriter::create(
        path,
        first.width,
        first.height,
        Palette::from_pictures(pictures),
    )?;
    for (k, p) in pictures.iter().enumerate() {
        if (p.width, p.height) != (first.width, first.height) {
            return Err(SceneError::Option {
                name: "pictures",
                message: format!(
                    "picture {k} is {}×{}, not {}×{}",
                    p.width, p.height, first.width, first.height
                ),
            });
        }
        gif.push(p, gif_delay(k, fps))?;
    }
    gif.finish()
}

/// A 256-colour palette chosen by median cut over 5-bit colour cells, with a cache from cell
/// to palette index.
struct Palette {
    colors: Vec<[u8; 3]>,
    lut: Vec<u16>,
}

const UNSET: u16 = u16::MAX;

fn cell(c: [u8; 3]) -> usize {
    ((c[0] as usize >> 3) << 10) | ((c[1] as usize >> 3) << 5) | (c[2] as usize >> 3)
}

impl Palette {
    fn from_pictures(pictures: &[Picture]) -> Palette {
        // Per cell: count and colour sums.
        let mut count = vec![0u64; 1 << 15];
        let mut sum = vec![[0u64; 3]; 1 << 15];
        for p in pictures {
            for c in &p.rgb {
                let i = cell(*c);
                count[i] += 1;
                for k in 0..3 {
                    sum[i][k] += c[k] as u64;
                }
            }
        }
        // (mean colour, weight) per occupied cell; rare colours (text, thin lines) keep weight.
        let cells: Vec<([f64; 3], f64)> = (0..1 << 15)
            .filter(|i| count[*i] > 0)
            .map(|i| {
                let n = count[i] as f64;
                (
                    [
                        sum[i][0] as f64 / n,
                        sum[i][1] as f64 / n,
                        sum[i][2] as f64 / n,
                    ],
                    n.sqrt(),
                )
            })
            .collect();
        let mut boxes: Vec<Vec<([f64; 3], f64)>> = vec![cells];
        while boxes.len() < 256 {
            // Split the box with the widest channel range.
            let widest = boxes
                .iter()
                .enumerate()
                .filter(|(_, b)| b.len() > 1)
                .map(|(i, b)| (i, channel_range(b)))
                .max_by(|a, b| a.1 .1.total_cmp(&b.1 .1));
            let Some((i, (axis, range))) = widest else {
                break;
            };
            if range <= 0.0 {
                break;
            }
            let mut b = boxes.swap_remove(i);
            b.sort_by(|x, y| x.0[axis].total_cmp(&y.0[axis]));
            let total: f64 = b.iter().map(|x| x.1).sum();
            let mut acc = 0.0;
            let mut cut = 1;
            for (j, x) in b.iter().enumerate() {
                acc += x.1;
                if acc >= total / 2.0 {
                    cut = (j + 1).clamp(1, b.len() - 1);
                    break;
                }
            }
            let rest = b.split_off(cut);
            boxes.push(b);
            boxes.push(rest);
        }
        let colors = boxes
            .iter()
            .filter(|b| !b.is_empty())
            .map(|b| {
                let w: f64 = b.iter().map(|x| x.1).sum();
                let m = |k: usize| (b.iter().map(|x| x.0[k] * x.1).sum::<f64>() / w).round() as u8;
                [m(0), m(1), m(2)]
            })
            .collect::<Vec<_>>();
        let colors = if colors.is_empty() {
            vec![[0, 0, 0]]
        } else {
            colors
        };
        Palette {
            colors,
            lut: vec![UNSET; 1 << 15],
        }
    }

    fn index(&mut self, c: [u8; 3]) -> u8 {
        let i = cell(c);
        if self.lut[i] == UNSET {
            let centre = [
                (c[0] & !7) as i32 + 4,
                (c[1] & !7) as i32 + 4,
                (c[2] & !7) as i32 + 4,
            ];
            let best = self
                .colors
                .iter()
                .enumerate()
                .min_by_key(|(_, p)| {
                    let d = |k: usize| (p[k] as i32 - centre[k]).pow(2);
                    d(0) + d(1) + d(2)
                })
                .map_or(0, |(j, _)| j);
            self.lut[i] = best as u16;
        }
        self.lut[i] as u8
    }

    /// `r, g, b, …` padded to a power of two.
    fn rgb_table(&self) -> Vec<u8> {
        let n = self.colors.len().next_power_of_two().max(2);
        let mut t: Vec<u8> = self.colors.iter().flatten().copied().collect();
        t.resize(n * 3, 0);
        t
    }
}

fn channel_range(b: &[([f64; 3], f64)]) -> (usize, f64) {
    (0..3)
        .map(|k| {
            let lo = b.iter().map(|x| x.0[k]).fold(f64::INFINITY, f64::min);
            let hi = b.iter().map(|x| x.0[k]).fold(f64::NEG_INFINITY, f64::max);
            (k, hi - lo)
        })
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((0, 0.0))
}

/// Streams frames into a GIF, each as the rectangle that changed since the previous one.
struct GifWriter {
    path: std::path::PathBuf,
    encoder: gif::Encoder<std::io::BufWriter<std::fs::File>>,
    palette: Palette,
    previous: Option<Vec<u8>>,
    width: u32,
    height: u32,
    centiseconds: u64,
}

impl GifWriter {
    fn create(
        path: &Path,
        width: u32,
        height: u32,
        palette: Palette,
    ) -> Result<GifWriter, SceneError> {
        let file = std::fs::File::create(path).map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let gif_err = |e: gif::EncodingError| SceneError::Gif {
            path: path.to_path_buf(),
            message: e.to_string(),
        };
        let mut encoder = gif::Encoder::new(
            std::io::BufWriter::new(file),
            width as u16,
            height as u16,
            &palette.rgb_table(),
        )
        .map_err(gif_err)?;
        encoder.set_repeat(gif::Repeat::Infinite).map_err(gif_err)?;
        Ok(GifWriter {
            path: path.to_path_buf(),
            encoder,
            palette,
            previous: None,
            width,
            height,
            centiseconds: 0,
        })
    }

    fn push(&mut self, pic: &Picture, delay: u16) -> Result<(), SceneError> {
        let idx: Vec<u8> = pic.rgb.iter().map(|c| self.palette.index(*c)).collect();
        let (w, h) = (self.width as usize, self.height as usize);
        // The rectangle that differs from the previous frame (all of it for the first).
        let (mut x0, mut y0, mut x1, mut y1) = (0, 0, w - 1, h - 1);
        if let Some(prev) = &self.previous {
            let (mut a, mut b, mut c, mut d) = (w, h, 0, 0);
            for y in 0..h {
                let row = &idx[y * w..(y + 1) * w];
                let prow = &prev[y * w..(y + 1) * w];
                if row == prow {
                    continue;
                }
                let first = row.iter().zip(prow).position(|(p, q)| p != q).unwrap_or(0);
                let last = w
                    - 1
                    - row
                        .iter()
                        .rev()
                        .zip(prow.iter().rev())
                        .position(|(p, q)| p != q)
                        .unwrap_or(0);
                a = a.min(first);
                c = c.max(last);
                b = b.min(y);
                d = d.max(y);
            }
            if a > c {
                (x0, y0, x1, y1) = (0, 0, 0, 0);
            } else {
                (x0, y0, x1, y1) = (a, b, c, d);
            }
        }
        let (fw, fh) = (x1 - x0 + 1, y1 - y0 + 1);
        let mut buf = Vec::with_capacity(fw * fh);
        for y in y0..=y1 {
            buf.extend_from_slice(&idx[y * w + x0..=y * w + x1]);
        }
        let mut frame = gif::Frame::from_indexed_pixels(fw as u16, fh as u16, buf, None);
        frame.left = x0 as u16;
        frame.top = y0 as u16;
        frame.delay = delay;
        self.encoder
            .write_frame(&frame)
            .map_err(|e| SceneError::Gif {
                path: self.path.clone(),
                message: e.to_string(),
            })?;
        self.centiseconds += delay as u64;
        self.previous = Some(idx);
        Ok(())
    }

    fn finish(self) -> Result<f64, SceneError> {
        let path = self.path.clone();
        let mut w = self.encoder.into_inner().map_err(|e| SceneError::Gif {
            path: path.clone(),
            message: e.to_string(),
        })?;
        w.flush()
            .map_err(|source| SceneError::Io { path, source })?;
        Ok(self.centiseconds as f64 / 100.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projection_centres_the_target_and_keeps_up_up() {
        let view = CameraView::default();
        let p = Projector::new(&view, 640, 480);
        let (x, y, d) = p.project(view.target).unwrap();
        assert!((x - 320.0).abs() < 1e-9 && (y - 240.0).abs() < 1e-9 && d > 4.0);
        let above = [view.target[0], view.target[1], view.target[2] + 0.5];
        assert!(p.project(above).unwrap().1 < 240.0);
        // The robot's front (+x) is on the right of the picture, seen from its right side.
        let ahead = [view.target[0] + 0.5, view.target[1], view.target[2]];
        assert!(p.project(ahead).unwrap().0 > 320.0);
        assert!(p.project(view.eye).is_none());
    }

    #[test]
    fn frame_counts_and_delays_add_up() {
        assert_eq!(frame_count(0, 10.0), 1);
        assert_eq!(frame_count(2_000_000_000, 10.0), 21);
        assert_eq!(frame_count(1_999_999_999, 10.0), 20);
        let total: u64 = (0..15).map(|k| gif_delay(k, 15.0) as u64).sum();
        assert_eq!(total, 100);
    }

    #[test]
    fn palette_keeps_few_colours_exactly() {
        let mut pic = Picture::new(4, 4, [10, 20, 30]);
        pic.rgb[5] = [200, 100, 0];
        let mut pal = Palette::from_pictures(&[pic]);
        let i = pal.index([200, 100, 0]) as usize;
        assert_eq!(pal.colors[i], [200, 100, 0]);
        let j = pal.index([10, 20, 30]) as usize;
        assert_eq!(pal.colors[j], [10, 20, 30]);
    }
}
