//! Synthetic two-person social interactions, the choreography of one clip (whole splits:
//! [`crate::splits`]): deterministic by seed, with real dependency between the two people (the
//! reactor answers after a reaction delay, hands meet where both can reach, the mirror copies
//! with a lag, walkers avoid each other).
//!
//! Person A (index 0) acts, person B (index 1) reacts. A starts at the origin facing +x, B in
//! front of A facing A; the whole scene is then rotated and moved by a random placement.

use std::f64::consts::PI;

use echo_msgs::Interaction;
use nalgebra::{UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};

pub use crate::params::{ClipParams, ParamRanges, Split, GREETING_KINDS, KINDS, WALKING_KINDS};
use crate::posing::{arm_length, pose, to_arm_target, wrap, Intent};
use crate::skeleton::{forward, j, Body, NUM_JOINTS};
pub use crate::splits::{generate_clips, generate_split};

/// Frame rate of generated clips (the InterGen rate).
pub const FPS: f64 = 30.0;

/// Speed profile of a walk of `dist` metres at up to `v` m/s with peak acceleration `acc`:
/// raised-cosine ramps up and down (`v(τ) = v/2·(1 − cos(πτ/T))`, `T = πv/2acc`), a cruise in
/// between (none when the walk is too short to reach `v`). Position and speed `t` seconds after
/// the start, and the duration.
pub fn smooth_walk(dist: f64, v: f64, acc: f64, t: f64) -> (f64, f64, f64) {
    if dist <= 0.0 || v <= 0.0 || acc <= 0.0 {
        return (0.0, 0.0, 0.0);
    }
    let ramp_of = |v: f64| PI * v / (2.0 * acc);
    // Too short to reach v: the largest v whose two ramps cover dist (v·T = dist).
    let v = v.min((2.0 * acc * dist / PI).sqrt());
    let ta = ramp_of(v);
    let tc = ((dist - v * ta) / v).max(0.0);
    let total = 2.0 * ta + tc;
    if t <= 0.0 {
        return (0.0, 0.0, total);
    }
    if t < ta {
        let x = v / 2.0 * (t - ta / PI * (PI * t / ta).sin());
        return (x, v / 2.0 * (1.0 - (PI * t / ta).cos()), total);
    }
    if t < ta + tc {
        return (v * ta / 2.0 + v * (t - ta), v, total);
    }
    if t < total {
        let s = t - ta - tc;
        let x = v * ta / 2.0 + v * tc + v / 2.0 * (s + ta / PI * (PI * s / ta).sin());
        return (x.min(dist), v / 2.0 * (1.0 + (PI * s / ta).cos()), total);
    }
    (dist, 0.0, total)
}

/// A generated clip.
#[derive(Debug, Clone)]
pub struct Clip {
    /// Parameters it was generated from.
    pub params: ClipParams,
    /// 2–3 descriptions.
    pub texts: Vec<String>,
    /// Bodies of A and B.
    pub bodies: [Body; 2],
    /// Joint positions per frame: `[person][joint]`, world frame (z up), metres, at [`FPS`].
    pub frames: Vec<[[[f32; 3]; NUM_JOINTS]; 2]>,
}

impl Clip {
    /// Duration, seconds.
    pub fn duration(&self) -> f64 {
        self.frames.len() as f64 / FPS
    }

    /// A recorded interaction (InterGen, BVH captures): both people's joints per frame at
    /// [`FPS`], their heights; the other parameters are the training defaults of `kind`.
    pub fn recorded(
        kind: Interaction,
        texts: Vec<String>,
        heights: [f64; 2],
        a: &[[Vector3<f64>; NUM_JOINTS]],
        b: &[[Vector3<f64>; NUM_JOINTS]],
    ) -> Clip {
        let mut params = ClipParams::sample(kind, &ParamRanges::train(), 0);
        params.heights = heights;
        let f32s = |p: &[Vector3<f64>; NUM_JOINTS]| p.map(|v| [v.x as f32, v.y as f32, v.z as f32]);
        Clip {
            bodies: heights.map(Body::with_height),
            params,
            texts,
            frames: a.iter().zip(b).map(|(x, y)| [f32s(x), f32s(y)]).collect(),
        }
    }

    /// Joints of person `p` at frame `f` as vectors.
    pub fn joints(&self, f: usize, p: usize) -> [Vector3<f64>; NUM_JOINTS] {
        self.frames[f][p].map(|x| Vector3::new(x[0] as f64, x[1] as f64, x[2] as f64))
    }
}

fn smooth(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * x * (x * (6.0 * x - 15.0) + 10.0)
}

/// 0 before t0, rising to 1 at t1.
fn ramp(t: f64, t0: f64, t1: f64) -> f64 {
    smooth((t - t0) / (t1 - t0).max(1e-6))
}

/// Up over [t0, t0+rise], held, down over [t1, t1+rise].
fn pulse(t: f64, t0: f64, t1: f64, rise: f64) -> f64 {
    ramp(t, t0, t0 + rise) * (1.0 - ramp(t, t1, t1 + rise))
}

fn lerp(a: &Vector3<f64>, b: &Vector3<f64>, w: f64) -> Vector3<f64> {
    a + (b - a) * w
}

/// Smooth per-person noise: slow sways of a few centimetres.
struct Noise {
    phase: [f64; 6],
    freq: [f64; 6],
}

impl Noise {
    fn new(rng: &mut impl Rng) -> Self {
        Noise {
            phase: std::array::from_fn(|_| rng.random_range(0.0..2.0 * PI)),
            freq: std::array::from_fn(|_| rng.random_range(0.15..0.6)),
        }
    }

    fn at(&self, t: f64, k: usize) -> f64 {
        (2.0 * PI * self.freq[k] * t + self.phase[k]).sin()
    }
}

/// Step length of the gait, metres (a cadence of ≈ 1.8 steps/s at 1 m/s).
pub const STEP_M: f64 = 0.6;

/// Generate the clip for `params`.
pub fn generate(params: &ClipParams) -> Clip {
    let mut rng = rand::rngs::StdRng::seed_from_u64(params.seed ^ 0x9e37_79b9_7f4a_7c15);
    let bodies = [
        Body::with_height(params.heights[0]),
        Body::with_height(params.heights[1]),
    ];
    let noise = [Noise::new(&mut rng), Noise::new(&mut rng)];
    let scene = Scene::new(params, &bodies, &mut rng);
    let n = (scene.duration * FPS).round() as usize;
    let (px, py, pyaw) = params.placement;
    let place = UnitQuaternion::from_euler_angles(0.0, 0.0, pyaw);
    let offset = Vector3::new(px, py, 0.0);
    let mut frames = Vec::with_capacity(n);
    for f in 0..n {
        let t = f as f64 / FPS;
        let intents = scene.intents(t, &bodies);
        let mut out = [[[0f32; 3]; NUM_JOINTS]; 2];
        for p in 0..2 {
            let mut it = intents[p].clone();
            if params.locomotion {
                it.arm_swing = 1.0;
            }
            // Natural variability: a little sway of the whole body and of the hands.
            it.root_xy[0] += 0.01 * noise[p].at(t, 0);
            it.root_xy[1] += 0.01 * noise[p].at(t, 1);
            it.yaw += 0.02 * noise[p].at(t, 2);
            for (k, h) in [(3, &mut it.left_hand), (4, &mut it.right_hand)] {
                if let Some(v) = h.as_mut() {
                    v.z += 0.012 * noise[p].at(t, k);
                }
            }
            it.spine_pitch += 0.02 * noise[p].at(t, 5);
            let x = forward(&bodies[p], &pose(&bodies[p], &it));
            for (k, v) in x.iter().enumerate() {
                let w = place * v + offset;
                out[p][k] = [w.x as f32, w.y as f32, w.z as f32];
            }
        }
        frames.push(out);
    }
    Clip {
        texts: crate::text::describe(params, &mut rng),
        params: params.clone(),
        bodies,
        frames,
    }
}

/// The choreography of one clip, in the scene frame (A at the origin facing +x).
struct Scene {
    kind: Interaction,
    p: ClipParams,
    duration: f64,
    /// Kind-specific random numbers drawn once.
    r: [f64; 8],
}

impl Scene {
    fn new(p: &ClipParams, _bodies: &[Body; 2], rng: &mut impl Rng) -> Scene {
        let r: [f64; 8] = std::array::from_fn(|_| rng.random::<f64>());
        let mut duration = match p.kind {
            Interaction::WalkPast => 5.0 + 1.5 * r[7],
            Interaction::ApproachGreet | Interaction::ShoulderTap => 5.5 + 1.5 * r[7],
            Interaction::Imitation => 6.0 + 2.0 * r[7],
            _ => 4.5 + 1.5 * r[7],
        };
        if p.locomotion {
            // The longer walk comes on top of the interaction.
            duration += match p.kind {
                Interaction::WalkPast => 0.0,
                Interaction::ApproachGreet => p.distance / p.speed,
                // The walk, and a step back after the exchange.
                _ => (p.distance / 2.0) / p.speed + 1.5,
            };
        }
        Scene {
            kind: p.kind,
            p: p.clone(),
            duration,
            r,
        }
    }

    /// Where A and B stand when they meet, when they arrive, the gait amplitude and the gait
    /// phase (driven by the distance walked, so that the stance foot stays planted).
    fn approach(&self, meet: f64, t: f64) -> (f64, f64, f64, f64) {
        let d = self.p.distance.max(meet);
        let walk = (d - meet) / 2.0;
        if self.p.locomotion {
            let t0 = 0.2 + 0.3 * self.r[0];
            let acc = 0.8 + 0.5 * self.r[5];
            let (x, v, dur) = smooth_walk(walk, self.p.speed, acc, t - t0);
            let gait = (v / self.p.speed).clamp(0.0, 1.0);
            return (x, d - x, t0 + dur, gait);
        }
        let t_walk = walk / self.p.speed;
        let t0 = 0.3 + 0.4 * self.r[0];
        let w = if walk > 0.05 {
            ramp(t, t0, t0 + t_walk.max(0.3))
        } else {
            1.0
        };
        let moving = walk > 0.05 && t > t0 && t < t0 + t_walk.max(0.3);
        let xa = walk * w;
        let xb = d - walk * w;
        let gait = if moving { 1.0 } else { 0.0 };
        (
            xa,
            xb,
            t0 + if walk > 0.05 { t_walk.max(0.3) } else { 0.0 },
            gait,
        )
    }

    /// Gait phase after walking `dist` metres: one step (half a cycle) per [`STEP_M`].
    fn phase(dist: f64) -> f64 {
        PI * dist / STEP_M
    }

    fn intents(&self, t: f64, bodies: &[Body; 2]) -> [Intent; 2] {
        let p = &self.p;
        let amp = p.amplitude;
        let hand_right = p.right_handed;
        match self.kind {
            Interaction::Handshake | Interaction::HighFive | Interaction::Handover => {
                // Closer for shorter people: both must reach the meeting point.
                let reach_scale = p.heights[0].min(p.heights[1]) / 1.75;
                let meet = reach_scale
                    * match self.kind {
                        Interaction::Handshake => 0.75 + 0.12 * self.r[1],
                        Interaction::HighFive => 0.75 + 0.15 * self.r[1],
                        _ => 0.8 + 0.12 * self.r[1],
                    }
                    // Walking people stop where it suits them, not at arm's length exactly.
                    + match (p.locomotion, p.brief) {
                        (true, false) => 0.3 * self.r[3],
                        // Close enough for the hands to meet at once.
                        (true, true) => 0.1 * self.r[3],
                        _ => 0.0,
                    };
                let (mut xa, mut xb, t_arrive, mut gait) = self.approach(meet, t);
                // B answers after its reaction delay; on the way both see it coming.
                let delay_b = if p.brief { 0.25 * p.delay } else { p.delay };
                // When the hands start to rise and when they come down again.
                let (t1, t_down) = if p.brief {
                    // Raised on the way, together on arrival, held 0.1–0.8 s.
                    let t1 = t_arrive - 0.6;
                    (t1, t1 + 0.6 + 0.1 + 0.7 * self.r[2])
                } else {
                    let t1 = t_arrive + 0.2;
                    (t1, t1 + 1.9 + 0.4 * self.r[2])
                };
                if p.brief {
                    // Both step back at once as the hands come down, to 1.1–1.8 m apart.
                    let t_back = match self.kind {
                        Interaction::Handover => t_down.max(t1 + delay_b + 1.6),
                        _ => t_down,
                    } - 0.1
                        + 0.3 * self.r[6];
                    let back = ((1.1 + 0.7 * self.r[4]) - meet).max(0.1) / 2.0;
                    let v_back = 0.5 + 0.4 * self.r[5];
                    let (x, v, _) = smooth_walk(back, v_back, 1.0, t - t_back);
                    xa -= x;
                    xb += x;
                    gait = gait.max(v / v_back);
                } else if p.locomotion && self.r[6] < 0.6 {
                    // After the exchange, most step back to a social distance.
                    let t_end = t_arrive + 0.2 + 1.9 + 0.4 * self.r[2] + 0.6;
                    let back = 0.2 + 0.4 * self.r[4];
                    let (x, v, _) = smooth_walk(back, 0.5, 0.8, t - t_end);
                    xa -= x;
                    xb += x;
                    gait = gait.max(0.5 * v / 0.5);
                }
                let mut a = Intent::standing(xa, 0.0, 0.0);
                let mut b = Intent::standing(xb, 0.0, PI);
                a.gait = (Self::phase(xa), gait);
                b.gait = (Self::phase(self.p.distance.max(meet) - xb), gait);
                let ha = bodies[0].pelvis_height();
                let hb = bodies[1].pelvis_height();
                // Hands meet between them, where both reach: at the lower person's comfort height.
                let (height, lateral) = match self.kind {
                    Interaction::HighFive => (ha.min(hb) * 1.7 + 0.08 * amp, 0.0),
                    Interaction::Handover => (ha.min(hb) * 1.15, 0.0),
                    _ => (ha.min(hb) * 1.15, 0.0),
                };
                // Same-side hands of people facing each other meet between their shoulders.
                let m = Vector3::new((xa + xb) / 2.0, lateral, height);
                let ta = pulse(t, t1, t_down, 0.6);
                let tb = pulse(t, t1 + delay_b, t_down, 0.6);
                let shake = if self.kind == Interaction::Handshake {
                    0.035
                        * amp
                        * (2.0 * PI * 2.5 * t).sin()
                        * ramp(t, t1 + delay_b + 0.6, t1 + delay_b + 0.8)
                } else {
                    0.0
                };
                // Each wrist stops a hand's length short of the meeting point.
                let target = m + Vector3::new(0.0, 0.0, shake);
                let grip = Vector3::new(0.05, 0.0, 0.0);
                let rest_a = to_arm_target(&bodies[0], &a, hand_right, &(target - grip));
                let rest_b = to_arm_target(&bodies[1], &b, hand_right, &(target + grip));
                let down_a = crate::posing::arm_down(&bodies[0], hand_right);
                let down_b = crate::posing::arm_down(&bodies[1], hand_right);
                let mut hand_a = lerp(&down_a, &rest_a, ta);
                let mut hand_b = lerp(&down_b, &rest_b, tb);
                if self.kind == Interaction::Handover {
                    // The receiver takes the object, the giver lets go first.
                    let give_back = ramp(t, t1 + delay_b + 1.0, t1 + delay_b + 1.6);
                    let keep = Vector3::new(0.3, 0.0, -0.25);
                    hand_b = lerp(&lerp(&down_b, &rest_b, tb.max(give_back)), &keep, give_back);
                    hand_a = lerp(&down_a, &rest_a, pulse(t, t1, t1 + delay_b + 0.9, 0.6));
                }
                set_hand(&mut a, hand_right, hand_a);
                set_hand(&mut b, hand_right, hand_b);
                look_at_each_other(&mut a, &mut b, bodies);
                [a, b]
            }
            Interaction::Wave | Interaction::ApproachGreet => {
                let (xa, xb, t_arrive, gait) = if self.kind == Interaction::ApproachGreet {
                    let far = self.p.distance + 1.2;
                    let walk = far - 1.2;
                    let t0 = 0.3;
                    if p.locomotion {
                        let acc = 0.8 + 0.5 * self.r[5];
                        let (x, v, dur) = smooth_walk(walk, p.speed, acc, t - t0);
                        (x, far, t0 + dur, (v / p.speed).clamp(0.0, 1.0))
                    } else {
                        let t_walk = walk / p.speed;
                        let w = ramp(t, t0, t0 + t_walk);
                        (
                            walk * w,
                            far,
                            t0 + t_walk,
                            if t > t0 && t < t0 + t_walk { 1.0 } else { 0.0 },
                        )
                    }
                } else {
                    (0.0, p.distance + 0.5, 0.4 + 0.8 * self.r[0], 0.0)
                };
                let mut a = Intent::standing(xa, 0.0, 0.0);
                let mut b = Intent::standing(xb, 0.0, PI);
                a.gait = (Self::phase(xa), gait);
                let start = t_arrive
                    + if self.kind == Interaction::ApproachGreet {
                        0.1
                    } else {
                        0.0
                    };
                let dur = if self.kind == Interaction::ApproachGreet {
                    1.2
                } else {
                    1.8 + 0.6 * self.r[1]
                };
                for (it, body, t0) in [
                    (&mut a, &bodies[0], start),
                    (&mut b, &bodies[1], start + p.delay),
                ] {
                    let w = pulse(t, t0, t0 + dur, 0.45);
                    let l = arm_length(body, hand_right);
                    let side = if hand_right { -1.0 } else { 1.0 };
                    let wave = Vector3::new(
                        0.12 * l,
                        side * (0.45 * l + 0.12 * amp * (2.0 * PI * 2.0 * t).sin()),
                        0.55 * l,
                    );
                    let down = crate::posing::arm_down(body, hand_right);
                    set_hand(it, hand_right, lerp(&down, &wave, w));
                }
                look_at_each_other(&mut a, &mut b, bodies);
                [a, b]
            }
            Interaction::Hug => {
                let meet = 0.32 + 0.08 * self.r[1];
                let (xa, xb, t_arrive, gait) = self.approach(meet, t);
                let mut a = Intent::standing(xa, 0.0, 0.0);
                let mut b = Intent::standing(xb, 0.0, PI);
                a.gait = (Self::phase(xa), gait);
                b.gait = (Self::phase(self.p.distance.max(meet) - xb), gait);
                let t1 = t_arrive - 0.4;
                let hold = 1.4 + 0.6 * self.r[2];
                for (me, (it, body)) in [(&mut a, &bodies[0]), (&mut b, &bodies[1])]
                    .into_iter()
                    .enumerate()
                {
                    let t0 = t1 + if me == 1 { p.delay * 0.5 } else { 0.0 };
                    let w = pulse(t, t0, t0 + hold, 0.7);
                    let other_x = if me == 0 { xb } else { xa };
                    let chest = body.pelvis_height() * 1.38;
                    for right in [false, true] {
                        let side = if right { -1.0 } else { 1.0 };
                        let dir = if me == 0 { 1.0 } else { -1.0 };
                        // Around the partner: hands behind the partner's back.
                        let behind = Vector3::new(
                            other_x + dir * 0.12,
                            side * dir * 0.05,
                            chest - if right { 0.08 } else { 0.0 },
                        );
                        let target = to_arm_target(body, it, right, &behind);
                        let down = crate::posing::arm_down(body, right);
                        set_hand(it, right, lerp(&down, &target, w));
                    }
                }
                look_at_each_other(&mut a, &mut b, bodies);
                [a, b]
            }
            Interaction::Bow => {
                let mut a = Intent::standing(0.0, 0.0, 0.0);
                let mut b = Intent::standing(p.distance.max(1.2), 0.0, PI);
                let t0 = 0.5 + 0.6 * self.r[0];
                let hold = 0.5 + 0.4 * self.r[1];
                let depth = (0.45 + 0.25 * self.r[2]) * amp;
                a.spine_pitch = depth * pulse(t, t0, t0 + 0.8 + hold, 0.8);
                b.spine_pitch = depth
                    * (0.7 + 0.3 * self.r[3])
                    * pulse(t, t0 + p.delay, t0 + p.delay + 0.8 + hold, 0.8);
                look_at_each_other(&mut a, &mut b, bodies);
                [a, b]
            }
            Interaction::PointAndLook => {
                let mut a = Intent::standing(0.0, 0.0, 0.0);
                let mut b = Intent::standing(p.distance.max(1.2), 0.0, PI);
                let side = if hand_right { -1.0 } else { 1.0 };
                let ang = side * (0.9 + 0.8 * self.r[1]);
                let target = Vector3::new(3.0 * ang.cos(), 3.0 * ang.sin(), 0.6 + 0.8 * self.r[2]);
                let t0 = 0.4 + 0.6 * self.r[0];
                let w = pulse(t, t0, t0 + 2.2, 0.6);
                let reach = to_arm_target(&bodies[0], &a, hand_right, &target);
                let reach = reach.normalize() * arm_length(&bodies[0], hand_right) * 0.97;
                let down = crate::posing::arm_down(&bodies[0], hand_right);
                set_hand(&mut a, hand_right, lerp(&down, &reach, w));
                let head_b =
                    Vector3::new(b.root_xy[0], b.root_xy[1], bodies[1].pelvis_height() * 1.7);
                let head_a = Vector3::new(0.0, 0.0, bodies[0].pelvis_height() * 1.7);
                // A looks where it points; B follows the gaze after the delay, turning a little.
                a.look_at = Some(lerp(&head_b, &target, ramp(t, t0, t0 + 0.5)));
                let wb = ramp(t, t0 + p.delay, t0 + p.delay + 0.6);
                b.look_at = Some(lerp(&head_a, &target, wb));
                let to_target = (target.y - b.root_xy[1]).atan2(target.x - b.root_xy[0]);
                b.yaw = PI
                    + 0.35
                        * wb
                        * wrap(to_target - PI).signum()
                        * wrap(to_target - PI).abs().min(1.0);
                [a, b]
            }
            Interaction::ShoulderTap => {
                // B stands with its back to A; A walks up and taps B's shoulder; B turns around.
                let xb = p.distance.max(1.3) + 0.3;
                let stop = xb - 0.55;
                let t0 = 0.3;
                let t_walk = stop / p.speed;
                let xa = stop * ramp(t, t0, t0 + t_walk);
                let mut a = Intent::standing(xa, 0.0, 0.0);
                a.gait = (
                    Self::phase(xa),
                    if t > t0 && t < t0 + t_walk { 1.0 } else { 0.0 },
                );
                let t_tap = t0 + t_walk + 0.1;
                let turn = ramp(t, t_tap + p.delay, t_tap + p.delay + 0.9);
                let mut b = Intent::standing(
                    xb,
                    0.0,
                    PI * turn * if self.r[2] < 0.5 { 1.0 } else { -1.0 },
                );
                let shoulder_b = Vector3::new(
                    xb - 0.02,
                    if hand_right { 0.18 } else { -0.18 },
                    bodies[1].pelvis_height() * 1.5,
                );
                let tap = pulse(t, t_tap, t_tap + 0.5, 0.35) + 0.0 * (2.0 * PI * 3.0 * t).sin();
                let target = to_arm_target(&bodies[0], &a, hand_right, &shoulder_b);
                let down = crate::posing::arm_down(&bodies[0], hand_right);
                set_hand(&mut a, hand_right, lerp(&down, &target, tap));
                let head_b = Vector3::new(xb, 0.0, bodies[1].pelvis_height() * 1.7);
                a.look_at = Some(head_b);
                let head_a = Vector3::new(xa, 0.0, bodies[0].pelvis_height() * 1.7);
                b.look_at = (turn > 0.5).then_some(head_a);
                [a, b]
            }
            Interaction::Imitation => {
                let mut a = Intent::standing(0.0, 0.0, 0.0);
                let mut b = Intent::standing(p.distance.max(1.3), 0.0, PI);
                let lead = |t: f64, right: bool| -> Vector3<f64> {
                    let body = &bodies[0];
                    let l = arm_length(body, right);
                    let side = if right { -1.0 } else { 1.0 };
                    let k = if right { 0.0 } else { 1.7 };
                    let on = ramp(t, 0.5, 1.2);
                    let v = Vector3::new(
                        0.35 + 0.25 * (0.7 * t + k + 6.0 * self.r[1]).sin(),
                        side * (0.45 + 0.35 * (0.9 * t + k + 6.0 * self.r[2]).sin()),
                        -0.3 + 0.8 * amp * (0.55 * t + k + 6.0 * self.r[3]).sin(),
                    );
                    let v = v.normalize() * l * 0.9;
                    lerp(&crate::posing::arm_down(body, right), &v, on)
                };
                for right in [false, true] {
                    set_hand(&mut a, right, lead(t, right));
                    // The mirror: B's left copies A's right (and vice versa), mirrored, late.
                    let src = lead((t - p.delay).max(0.0), !right);
                    let scale = arm_length(&bodies[1], right) / arm_length(&bodies[0], !right);
                    set_hand(&mut b, right, Vector3::new(src.x, -src.y, src.z) * scale);
                }
                look_at_each_other(&mut a, &mut b, bodies);
                [a, b]
            }
            Interaction::Clap => {
                let mut a = Intent::standing(0.0, 0.0, 0.0);
                let mut b = Intent::standing(p.distance.max(1.2), 0.0, PI);
                let f = 1.6 + 0.8 * self.r[1];
                for (me, it) in [&mut a, &mut b].into_iter().enumerate() {
                    let body = &bodies[me];
                    // B joins after the delay and locks onto A's rhythm.
                    let t0 = 0.5 + if me == 1 { p.delay } else { 0.0 };
                    let on = pulse(t, t0, self.duration - 0.8, 0.4);
                    let c = 0.5 - 0.5 * (2.0 * PI * f * (t - 0.5)).cos();
                    let l = arm_length(body, true);
                    for right in [false, true] {
                        let side = if right { -1.0 } else { 1.0 };
                        // Hands meet in front of the chest (shoulders are ~0.18 m off centre).
                        let open = Vector3::new(0.45 * l, -side * 0.02, -0.2 * l);
                        let closed = Vector3::new(0.45 * l, -side * 0.17, -0.2 * l);
                        let target = lerp(&open, &closed, c);
                        let down = crate::posing::arm_down(body, right);
                        set_hand(it, right, lerp(&down, &target, on));
                    }
                }
                look_at_each_other(&mut a, &mut b, bodies);
                [a, b]
            }
            Interaction::WalkPast => {
                let lane = 0.15 + 0.3 * self.r[1];
                let start = 2.0 + p.distance;
                let v = p.speed;
                let (xa, xb) = if p.locomotion {
                    // From rest, smoothly, and on past each other without stopping.
                    let acc = 0.8 + 0.5 * self.r[5];
                    let ramp_t = PI * v / (2.0 * acc);
                    let x = |t: f64| {
                        if t <= 0.0 {
                            0.0
                        } else if t < ramp_t {
                            v / 2.0 * (t - ramp_t / PI * (PI * t / ramp_t).sin())
                        } else {
                            v * ramp_t / 2.0 + v * (t - ramp_t)
                        }
                    };
                    (x(t - 0.3), start - x(t - 0.3 - 0.4 * self.r[2]))
                } else {
                    (v * t, start - v * t)
                };
                // Each sidesteps around the crossing so that they keep ≥ 0.7 m apart.
                let t_cross = start / (2.0 * v);
                let avoid = ((0.75 - lane) / 2.0).max(0.0) * (-((t - t_cross) / 0.9).powi(2)).exp();
                let mut a = Intent::standing(xa, -lane / 2.0 - avoid, 0.0);
                let mut b = Intent::standing(xb, lane / 2.0 + avoid, PI);
                a.gait = (Self::phase(xa), 1.0);
                b.gait = (Self::phase(start - xb) + 1.0, 1.0);
                let head_b = Vector3::new(xb, b.root_xy[1], bodies[1].pelvis_height() * 1.7);
                let head_a = Vector3::new(xa, a.root_xy[1], bodies[0].pelvis_height() * 1.7);
                if t < t_cross {
                    a.look_at = Some(head_b);
                    b.look_at = Some(head_a);
                }
                [a, b]
            }
            Interaction::Idle => {
                let mut a = Intent::standing(0.0, 0.0, 0.0);
                let mut b = Intent::standing(p.distance.max(1.3), 0.0, PI);
                look_at_each_other(&mut a, &mut b, bodies);
                // Now and then one looks away.
                if self.r[1] < 0.5 && (1.5..3.0).contains(&t) {
                    a.look_at = Some(Vector3::new(1.0, 3.0 * (self.r[2] - 0.5), 1.5));
                }
                [a, b]
            }
        }
    }
}

fn set_hand(it: &mut Intent, right: bool, target: Vector3<f64>) {
    if right {
        it.right_hand = Some(target);
    } else {
        it.left_hand = Some(target);
    }
}

fn look_at_each_other(a: &mut Intent, b: &mut Intent, bodies: &[Body; 2]) {
    let head = |it: &Intent, body: &Body| {
        Vector3::new(it.root_xy[0], it.root_xy[1], body.pelvis_height() * 1.7)
    };
    a.look_at = Some(head(b, &bodies[1]));
    b.look_at = Some(head(a, &bodies[0]));
}

/// Joint index of the hand of a side.
pub fn wrist(right: bool) -> usize {
    if right {
        j::R_WRIST
    } else {
        j::L_WRIST
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn clip(kind: Interaction, seed: u64) -> Clip {
        generate(&ClipParams::sample(kind, &ParamRanges::train(), seed))
    }

    #[test]
    fn deterministic_by_seed() {
        let a = clip(Interaction::Handshake, 5);
        let b = clip(Interaction::Handshake, 5);
        assert_eq!(a.frames, b.frames);
        assert_ne!(a.frames, clip(Interaction::Handshake, 6).frames);
    }

    #[test]
    fn handshake_hands_meet() {
        for seed in 0..10 {
            let c = clip(Interaction::Handshake, seed);
            let r = c.params.right_handed;
            let best = (0..c.frames.len())
                .map(|f| (c.joints(f, 0)[wrist(r)] - c.joints(f, 1)[wrist(r)]).norm())
                .fold(f64::INFINITY, f64::min);
            // Wrists a hand's length apart: the hands grip.
            assert!(best < 0.13, "seed {seed}: hands never closer than {best}");
        }
    }

    #[test]
    fn wave_back_follows_after_the_delay() {
        for seed in 0..10 {
            let c = clip(Interaction::Wave, seed);
            let r = c.params.right_handed;
            let up = |p: usize| {
                (0..c.frames.len()).find(|&f| {
                    let x = c.joints(f, p);
                    x[wrist(r)][2] > x[j::HEAD][2] - 0.1
                })
            };
            let (ta, tb) = (up(0).unwrap(), up(1).unwrap());
            let lag = (tb as f64 - ta as f64) / FPS;
            assert!(
                (lag - c.params.delay).abs() < 0.2,
                "seed {seed}: lag {lag} vs delay {}",
                c.params.delay
            );
        }
    }

    #[test]
    fn walkers_keep_their_distance_and_bones_stay_constant() {
        for seed in 0..10 {
            let c = clip(Interaction::WalkPast, seed);
            let min = (0..c.frames.len())
                .map(|f| (c.joints(f, 0)[0] - c.joints(f, 1)[0]).xy().norm())
                .fold(f64::INFINITY, f64::min);
            assert!(min > 0.6, "seed {seed}: {min}");
            let l0: Vec<f64> = (1..NUM_JOINTS)
                .map(|k| (c.joints(0, 0)[k] - c.joints(0, 0)[crate::PARENTS[k] as usize]).norm())
                .collect();
            for f in (0..c.frames.len()).step_by(7) {
                for k in 1..NUM_JOINTS {
                    let l = (c.joints(f, 0)[k] - c.joints(f, 0)[crate::PARENTS[k] as usize]).norm();
                    assert!((l - l0[k - 1]).abs() < 1e-4);
                }
            }
        }
    }

    #[test]
    fn held_out_ranges_lie_outside_training() {
        let tr = ParamRanges::train();
        for seed in 0..200 {
            let p = ClipParams::sample(Interaction::Bow, &ParamRanges::held_out(), seed);
            assert!(p
                .heights
                .iter()
                .all(|h| *h < tr.height[0].0 || *h > tr.height[0].1));
            assert!(p.delay >= tr.delay[0].1);
        }
    }
}

#[cfg(test)]
mod bow_tests {
    use super::*;

    #[test]
    fn bows_move_the_head_forward_and_the_reactor_bows_later() {
        for seed in 0..5 {
            let c = generate(&ClipParams::sample(
                Interaction::Bow,
                &ParamRanges::train(),
                seed,
            ));
            let fwd = |f: usize, p: usize| {
                let x = c.joints(f, p);
                let other = c.joints(f, 1 - p)[0];
                let dir = (other - x[0]).xy().normalize();
                (x[j::HEAD] - x[0]).xy().dot(&dir)
            };
            let (peak_a, fa) = (0..c.frames.len())
                .map(|f| (fwd(f, 0), f))
                .fold((f64::MIN, 0), |m, x| if x.0 > m.0 { x } else { m });
            let (peak_b, fb) = (0..c.frames.len())
                .map(|f| (fwd(f, 1), f))
                .fold((f64::MIN, 0), |m, x| if x.0 > m.0 { x } else { m });
            assert!(
                peak_a - fwd(0, 0) > 0.2,
                "seed {seed}: A's head moves {:.2} m",
                peak_a - fwd(0, 0)
            );
            assert!(
                peak_b - fwd(0, 1) > 0.12,
                "seed {seed}: B's head moves {:.2} m",
                peak_b - fwd(0, 1)
            );
            // Onsets: first frame past half of each bow.
            let onset = |p: usize, peak: f64| {
                (0..c.frames.len())
                    .find(|&f| fwd(f, p) - fwd(0, p) > 0.5 * (peak - fwd(0, p)))
                    .unwrap()
            };
            let lag = (onset(1, peak_b) as f64 - onset(0, peak_a) as f64) / FPS;
            assert!(
                (lag - c.params.delay).abs() < 0.25,
                "seed {seed}: B bows {lag:.2} s after A (delay {:.2})",
                c.params.delay
            );
            let _ = (fa, fb);
        }
    }
}

#[cfg(test)]
mod walking_tests {
    use super::*;

    /// Root speeds (floor plane, over 1/15 s) and accelerations of person `p`.
    fn speeds(c: &Clip, p: usize) -> (Vec<f64>, Vec<f64>) {
        let k = 2;
        let dt = k as f64 / FPS;
        let r: Vec<Vector3<f64>> = (0..c.frames.len()).map(|f| c.joints(f, p)[0]).collect();
        let v: Vec<Vector3<f64>> = (k..r.len() - k)
            .map(|f| (r[f + k] - r[f - k]) / (2.0 * dt))
            .collect();
        let a = (k..v.len() - k)
            .map(|i| ((v[i + k] - v[i - k]) / (2.0 * dt)).xy().norm())
            .collect();
        (v.iter().map(|x| x.xy().norm()).collect(), a)
    }

    #[test]
    fn smooth_walks_reach_their_speed_and_stop_where_asked() {
        let (x, v, total) = smooth_walk(2.0, 1.0, 1.0, 100.0);
        assert!((x - 2.0).abs() < 1e-9 && v == 0.0 && total > 2.0);
        let (_, vmid, _) = smooth_walk(2.0, 1.0, 1.0, total / 2.0);
        assert!((vmid - 1.0).abs() < 1e-9, "cruise at the drawn speed");
        // Too short a walk to reach the speed: it peaks lower and still ends at the distance.
        let (x, _, t) = smooth_walk(0.3, 1.5, 1.0, 100.0);
        assert!((x - 0.3).abs() < 1e-9 && t > 0.0);
        let (_, vpeak, _) = smooth_walk(0.3, 1.5, 1.0, t / 2.0);
        assert!(vpeak < 1.5 && vpeak > 0.3);
        // Continuous position: no step larger than the speed allows.
        let mut prev = 0.0;
        for i in 0..400 {
            let (x, _, _) = smooth_walk(2.0, 1.0, 1.0, i as f64 * 0.01);
            assert!(x - prev <= 1.0 * 0.01 + 1e-9 && x >= prev - 1e-12);
            prev = x;
        }
    }

    #[test]
    fn walking_clips_walk_accelerate_and_swing_their_arms_like_people() {
        let clips = generate_clips(
            (0..12).map(|i| Split::Test.walking_clip(i)).collect(),
            2,
            &|| {},
        );
        let (mut v, mut a) = (vec![], vec![]);
        for c in &clips {
            assert!(c.params.locomotion);
            assert!(WALKING_KINDS.contains(&c.params.kind));
            for p in 0..2 {
                let (vs, acc) = speeds(c, p);
                v.extend(vs);
                a.extend(acc);
            }
        }
        let moving = v.iter().filter(|x| **x > 0.3).count() as f64 / v.len() as f64;
        let amax = a.iter().cloned().fold(0.0, f64::max);
        assert!(moving > 0.3, "walking share {moving}");
        assert!(
            amax < 3.5,
            "peak acceleration {amax} m/s²: starts and stops are smooth"
        );
        // Arms swing while walking: the hanging wrist moves along the facing direction.
        let c = clips
            .iter()
            .find(|c| c.params.kind == Interaction::WalkPast)
            .unwrap();
        let f0 = c.frames.len() / 2;
        let along: Vec<f64> = (f0..f0 + 30)
            .map(|f| {
                let j = c.joints(f, 0);
                let fwd = crate::skeleton::heading(&j) * Vector3::x();
                (j[20] - j[0]).dot(&fwd)
            })
            .collect();
        let swing = along.iter().cloned().fold(f64::MIN, f64::max)
            - along.iter().cloned().fold(f64::MAX, f64::min);
        assert!(swing > 0.1, "wrist swing {swing} m peak to peak");
        // The original splits are untouched.
        assert!(!Split::Test.clip(3).locomotion);
    }

    /// Separation of the two pelvises at frame `f`, metres (ground plane).
    fn separation(c: &Clip, f: usize) -> f64 {
        let (a, b) = (c.joints(f, 0)[0], c.joints(f, 1)[0]);
        ((a - b).xy()).norm()
    }

    #[test]
    fn greeting_clips_meet_briefly_and_step_back() {
        let clips = generate_clips(
            (0..9).map(|i| Split::Test.greeting_clip(i)).collect(),
            2,
            &|| {},
        );
        for c in &clips {
            assert!(c.params.locomotion && c.params.brief);
            assert!(GREETING_KINDS.contains(&c.params.kind));
            let n = c.frames.len();
            let (closest, at) = (0..n)
                .map(|f| (separation(c, f), f))
                .fold((f64::MAX, 0), |m, x| if x.0 < m.0 { x } else { m });
            assert!(
                closest < 1.3,
                "{:?}: they meet ({closest} m)",
                c.params.kind
            );
            // Stepped back within 2 s of the closest moment, to a social distance.
            let later = separation(c, (at + 60).min(n - 1));
            assert!(
                later > closest + 0.08 && later < 2.0,
                "{:?}: {closest} m, 2 s later {later} m",
                c.params.kind
            );
            // The hands were together: wrists within 20 cm, from 0.5 s before the closest
            // moment to 1 s after it (a handover's exchange comes later).
            let wrist = |f: usize, p: usize| {
                let j = c.joints(f, p);
                [j[20], j[21]]
            };
            let near = (at.saturating_sub(15)..(at + 30).min(n))
                .flat_map(|f| {
                    let (a, b) = (wrist(f, 0), wrist(f, 1));
                    [
                        (a[0] - b[0]).norm(),
                        (a[1] - b[1]).norm(),
                        (a[0] - b[1]).norm(),
                        (a[1] - b[0]).norm(),
                    ]
                })
                .fold(f64::MAX, f64::min);
            assert!(near < 0.2, "{:?}: hands {near} m apart", c.params.kind);
        }
        // The walking clips keep their long exchange.
        assert!(!Split::Test.walking_clip(0).brief);
    }
}
