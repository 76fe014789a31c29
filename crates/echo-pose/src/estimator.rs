//! Finding people and following them from frame to frame (the rules are in the crate
//! documentation).

use echo_msgs::{CameraIntrinsics, DepthImage, Header, KeypointFrame};

use crate::image::Image;
use crate::model::{BlazePose, PoseLandmarks, AUX_HIP};
use crate::roi::{search_crops, Roi};
use crate::PoseError;

/// The estimator's settings.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatorConfig {
    /// A crop holds a person when the model's presence score reaches this (MediaPipe: 0.5).
    pub presence_threshold: f32,
    /// Search crops besides the whole image: squares of these fractions of the image's short
    /// side, overlapping by half. `[1.0]` (default) finds people who fill a good part of the
    /// frame (a 640 × 480 camera: within ~4 m); adding 0.5 finds smaller, farther people but
    /// also produces false detections (person-like objects), so it is off by default.
    pub search_levels: Vec<f32>,
    /// While tracking, search the whole image again every this many frames, for people who
    /// entered (a search also runs whenever no one is tracked).
    pub search_every: u32,
    /// Most people reported per frame.
    pub max_people: usize,
    /// Two results are the same person when their nose, shoulder centre and hip centre are on
    /// average closer than this fraction of the smaller crop.
    pub same_person: f32,
    /// Side of the face-anchored crop, in metres of the model's world scale (see the crate
    /// documentation); MediaPipe's detector gives crops of about 2–2.7 m.
    pub body_span_m: f32,
    /// Crops smaller than this (pixels) are not tried.
    pub min_crop_px: f32,
}

impl Default for EstimatorConfig {
    fn default() -> Self {
        EstimatorConfig {
            presence_threshold: 0.5,
            search_levels: vec![1.0],
            search_every: 30,
            max_people: 8,
            same_person: 0.1,
            body_span_m: 2.3,
            min_crop_px: 32.0,
        }
    }
}

/// One person in one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Person {
    /// Track id: the same person keeps it from frame to frame while tracked.
    pub id: u32,
    /// The model's output on this person's crop.
    pub landmarks: PoseLandmarks,
}

/// Head points (nose, eyes, ears, mouth): where the model is most precise whatever the crop.
const HEAD: std::ops::Range<usize> = 0..11;

/// The face-anchored crop: fit `image ≈ s · world + t` (x and y, scale and shift) on the head
/// points, project the world hip centre with it, and take a square of `span_m · s` pixels
/// there, turned like the model's alignment points. `None` when the fit is degenerate.
pub fn face_anchored_roi(lm: &PoseLandmarks, span_m: f32) -> Option<Roi> {
    let n = HEAD.len() as f32;
    let mean = |f: &dyn Fn(usize) -> f32| HEAD.map(f).sum::<f32>() / n;
    let (px, py) = (mean(&|i| lm.image[i].x), mean(&|i| lm.image[i].y));
    let (qx, qy) = (mean(&|i| lm.world[i][0]), mean(&|i| lm.world[i][1]));
    let (mut num, mut den) = (0.0, 0.0);
    for i in HEAD {
        let (dx, dy) = (lm.world[i][0] - qx, lm.world[i][1] - qy);
        num += (lm.image[i].x - px) * dx + (lm.image[i].y - py) * dy;
        den += dx * dx + dy * dy;
    }
    if den.is_nan() || den <= 1e-8 {
        return None;
    }
    let s = num / den;
    if !s.is_finite() || s <= 0.0 {
        return None;
    }
    let hip = lm.world[AUX_HIP];
    let aligned = lm.next_roi();
    let roi = Roi {
        cx: px + s * (hip[0] - qx) + 0.5,
        cy: py + s * (hip[1] - qy) + 0.5,
        size: span_m * s,
        rotation: aligned.rotation,
    };
    roi.is_usable(1.0).then_some(roi)
}

/// Whether `a` and `b` are the same person (see [`EstimatorConfig::same_person`]).
pub fn same_person(a: &PoseLandmarks, b: &PoseLandmarks, tol: f32) -> bool {
    let key = |l: &PoseLandmarks| {
        let mid = |i: usize, j: usize| {
            [
                (l.image[i].x + l.image[j].x) / 2.0,
                (l.image[i].y + l.image[j].y) / 2.0,
            ]
        };
        [[l.image[0].x, l.image[0].y], mid(11, 12), mid(23, 24)]
    };
    let (ka, kb) = (key(a), key(b));
    let d = ka
        .iter()
        .zip(&kb)
        .map(|(p, q)| (p[0] - q[0]).hypot(p[1] - q[1]))
        .sum::<f32>()
        / 3.0;
    d < tol * a.roi.size.min(b.roi.size)
}

/// BlazePose on a camera stream: finds people, follows them, and writes the bridge's frames.
pub struct PoseEstimator {
    model: BlazePose,
    cfg: EstimatorConfig,
    tracks: Vec<Person>,
    next_id: u32,
    since_search: u32,
}

impl PoseEstimator {
    /// An estimator running `model` with `cfg`.
    pub fn new(model: BlazePose, cfg: EstimatorConfig) -> PoseEstimator {
        PoseEstimator {
            model,
            cfg,
            tracks: vec![],
            next_id: 0,
            since_search: 0,
        }
    }

    /// The settings.
    pub fn config(&self) -> &EstimatorConfig {
        &self.cfg
    }

    /// The model (e.g. to run it on a crop of one's own).
    pub fn model_mut(&mut self) -> &mut BlazePose {
        &mut self.model
    }

    /// Forget every track (the next frame searches).
    pub fn reset(&mut self) {
        self.tracks.clear();
        self.since_search = 0;
    }

    /// Runs the model on `roi`; `Some` when it holds a person.
    fn try_roi(&mut self, img: &Image, roi: &Roi) -> Result<Option<PoseLandmarks>, PoseError> {
        if !roi.is_usable(self.cfg.min_crop_px) {
            return Ok(None);
        }
        let lm = self.model.run(img, roi)?;
        Ok((lm.presence >= self.cfg.presence_threshold).then_some(lm))
    }

    /// From a search crop's result to the person's own crop: the face-anchored crop, then
    /// MediaPipe's alignment rule once on that result.
    fn refine(
        &mut self,
        img: &Image,
        seed: PoseLandmarks,
    ) -> Result<Option<PoseLandmarks>, PoseError> {
        let mut cur = seed;
        if let Some(roi) = face_anchored_roi(&cur, self.cfg.body_span_m) {
            if let Some(lm) = self.try_roi(img, &roi)? {
                cur = lm;
            }
        }
        self.try_roi(img, &cur.next_roi())
    }

    /// Every person in `img`, without memory of earlier frames: runs the model on the search
    /// crops, refines each crop that holds a person (best first) unless it is someone already
    /// found, and keeps the refined results that still hold a person and are nobody already
    /// found.
    pub fn detect(&mut self, img: &Image) -> Result<Vec<PoseLandmarks>, PoseError> {
        self.search(img, &[])
    }

    /// [`PoseEstimator::detect`], skipping search crops that hold one of `known` (tracked).
    fn search(
        &mut self,
        img: &Image,
        known: &[PoseLandmarks],
    ) -> Result<Vec<PoseLandmarks>, PoseError> {
        let mut seeds = vec![];
        for roi in search_crops(img.width(), img.height(), &self.cfg.search_levels) {
            if let Some(lm) = self.try_roi(img, &roi)? {
                seeds.push(lm);
            }
        }
        seeds.sort_by(|a, b| b.presence.total_cmp(&a.presence));
        let tol = self.cfg.same_person;
        let mut found: Vec<PoseLandmarks> = vec![];
        for seed in seeds {
            if found.len() >= self.cfg.max_people {
                break;
            }
            if found
                .iter()
                .chain(known)
                .any(|f| same_person(f, &seed, tol))
            {
                continue;
            }
            if let Some(lm) = self.refine(img, seed)? {
                if !found.iter().any(|f| same_person(f, &lm, tol)) {
                    found.push(lm);
                }
            }
        }
        Ok(found)
    }

    /// The people in the next frame of a stream: each tracked person's crop follows from the
    /// last frame's alignment points (MediaPipe's tracking); a person whose crop no longer
    /// holds anyone is dropped; the whole image is searched when no one is tracked and every
    /// [`EstimatorConfig::search_every`] frames, and people not already tracked get new ids.
    pub fn track(&mut self, img: &Image) -> Result<Vec<Person>, PoseError> {
        let tol = self.cfg.same_person;
        let mut people: Vec<Person> = vec![];
        for t in std::mem::take(&mut self.tracks) {
            if let Some(lm) = self.try_roi(img, &t.landmarks.next_roi())? {
                if !people.iter().any(|p| same_person(&p.landmarks, &lm, tol)) {
                    people.push(Person {
                        id: t.id,
                        landmarks: lm,
                    });
                }
            }
        }
        self.since_search += 1;
        if people.is_empty() || self.since_search >= self.cfg.search_every {
            self.since_search = 0;
            let known: Vec<PoseLandmarks> = people.iter().map(|p| p.landmarks.clone()).collect();
            for lm in self.search(img, &known)? {
                if people.len() >= self.cfg.max_people {
                    break;
                }
                if !people.iter().any(|p| same_person(&p.landmarks, &lm, tol)) {
                    people.push(Person {
                        id: self.next_id,
                        landmarks: lm,
                    });
                    self.next_id = self.next_id.wrapping_add(1);
                }
            }
        }
        self.tracks = people.clone();
        Ok(people)
    }

    /// One camera frame to the bridge's message: checks the inputs, tracks the people in
    /// `img`, and writes their COCO-17 keypoints ([`crate::keypoints::keypoint_frame`]).
    /// `header` is used as given (its `frame_id` names the camera frame, its stamp the
    /// capture time).
    pub fn process(
        &mut self,
        header: Header,
        img: &Image,
        depth: Option<&DepthImage>,
        camera: Option<&CameraIntrinsics>,
    ) -> Result<KeypointFrame, PoseError> {
        crate::keypoints::check_inputs(img.width(), img.height(), depth, camera)?;
        let people = self.track(img)?;
        crate::keypoints::keypoint_frame(header, &people, img.width(), img.height(), depth, camera)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{Landmark, NUM_LANDMARKS};

    /// Landmarks of a front-facing person: image = 400 px/m · world + (300, 200), world hips
    /// at the origin, head 0.6 m above them, scale point 0.8 m above.
    fn person(shift_x: f32, roi_size: f32) -> PoseLandmarks {
        let mut world = vec![[0.0f32; 3]; NUM_LANDMARKS];
        for (i, w) in world.iter_mut().enumerate().take(11) {
            *w = [0.02 * (i as f32 - 5.0), -0.6 - 0.01 * (i % 3) as f32, -0.1];
        }
        world[11] = [0.18, -0.45, 0.0];
        world[12] = [-0.18, -0.45, 0.0];
        world[23] = [0.1, 0.0, 0.0];
        world[24] = [-0.1, 0.0, 0.0];
        world[34] = [0.0, -0.8, 0.0];
        let image = world
            .iter()
            .map(|w| Landmark {
                x: 300.0 + shift_x + 400.0 * w[0],
                y: 200.0 + 400.0 * w[1],
                z: 0.0,
                visibility: 1.0,
                presence: 1.0,
            })
            .collect();
        PoseLandmarks {
            roi: Roi {
                cx: 300.0,
                cy: 200.0,
                size: roi_size,
                rotation: 0.0,
            },
            presence: 0.9,
            image,
            world,
        }
    }

    #[test]
    fn face_anchored_crop_is_centred_on_the_projected_hips() {
        let mut lm = person(0.0, 500.0);
        // The model's image hips (and hip centre) pulled up towards the head, as on a crop too
        // small for a person cut off at the waist: the head fit still finds the hips.
        for i in [23, 24, 33] {
            lm.image[i].y -= 100.0;
        }
        let r = face_anchored_roi(&lm, 2.3).unwrap();
        assert!(
            (r.cx - 300.5).abs() < 1e-3 && (r.cy - 200.5).abs() < 1e-3,
            "{r:?}"
        );
        assert!((r.size - 2.3 * 400.0).abs() < 1e-2);
        // Degenerate head (every world head point the same): no crop.
        for i in 0..11 {
            lm.world[i] = [0.0, -0.6, 0.0];
        }
        assert_eq!(face_anchored_roi(&lm, 2.3), None);
    }

    #[test]
    fn same_person_tells_neighbours_apart() {
        let a = person(0.0, 800.0);
        assert!(same_person(&a, &person(20.0, 800.0), 0.1));
        // Shoulder to shoulder, 0.45 m apart at 400 px/m.
        assert!(!same_person(&a, &person(180.0, 800.0), 0.1));
    }
}
