//! The paper's Table 4 measures for a robot forecast: JPE*, AJPE*, FDE* of the robot (its
//! kinematic points: shoulders, elbows, wrists, grippers, head) against the retargeted reference,
//! F1 of contact (surfaces touch) and proximity (within 5 cm) of the forecast robot with the true
//! human against the original human pair, and the head rotation error against the reference.
//! And the model's other half, the human partner's forecast ([`human_forecast`]): its JPE and
//! AJPE against what the person did, next to zero and constant velocity ([`human_baselines`]).

use anyhow::Result;
use candle_core::Device;
use echo_eval::metrics::{head_rotation_error, Confusion};
use echo_models::model::Forecaster;
use echo_motion::sensors::{body_capsules, contact_and_proximity, part_distances};
use echo_retarget::Retargeter;
use echo_robot::collision::RobotBody;
use echo_robot::RobotModel;
use echo_text::SentenceEncoder;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::data::{decode_robot, HriWindow, OBS, PRED};
use crate::train::batch;

/// Future frames scored: 0.2, 0.53 and 1.0 s at 15 Hz.
pub const HORIZON_FRAMES: [usize; 3] = [2, 7, 14];

/// Robot points compared by JPE*.
pub const POINTS: [&str; 9] = [
    "arm_left_3_link",
    "arm_left_4_link",
    "arm_left_6_link",
    "gripper_left_grasping_frame",
    "arm_right_3_link",
    "arm_right_4_link",
    "arm_right_6_link",
    "gripper_right_grasping_frame",
    "head_2_link",
];

/// A robot forecast: joint values and base (x, y, yaw) per future frame.
#[derive(Debug, Clone)]
pub struct RobotForecast {
    /// Joint values per frame (the retargeter's joint order).
    pub q: Vec<Vec<f64>>,
    /// Base per frame.
    pub base: Vec<[f64; 3]>,
}

/// One row of the table.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct HriReport {
    /// Method.
    pub name: String,
    /// Windows.
    pub windows: usize,
    /// JPE* at the horizons, mm.
    pub jpe: Vec<f64>,
    /// AJPE* (base-relative), mm.
    pub ajpe: Vec<f64>,
    /// FDE* (base position), mm.
    pub fde: Vec<f64>,
    /// F1 of contact over all future frames.
    pub f1_contact: Option<f64>,
    /// F1 of proximity.
    pub f1_proximity: Option<f64>,
    /// Mean head rotation error (quaternion distance).
    pub head_error: f64,
}

fn pose(base: [f64; 3]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(base[0], base[1], 0.0),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), base[2]),
    )
}

/// The reference (the retargeted person B) as a forecast: the best any model can do on JPE*.
pub fn reference(ws: &[&HriWindow]) -> Vec<RobotForecast> {
    ws.iter()
        .map(|w| {
            let (q, base) = w.robot[OBS..]
                .iter()
                .map(|f| decode_robot(&w.canon, f))
                .unzip();
            RobotForecast { q, base }
        })
        .collect()
}

/// Zero velocity: the robot holds its last observed pose.
pub fn zero_velocity(ws: &[&HriWindow]) -> Vec<RobotForecast> {
    ws.iter()
        .map(|w| {
            let (q, b) = decode_robot(&w.canon, &w.robot[OBS - 1]);
            RobotForecast {
                q: vec![q; PRED],
                base: vec![b; PRED],
            }
        })
        .collect()
}

/// The model's input batch of `ws`, each window's first description as the prompt.
fn model_batch(
    model: &Forecaster,
    text: Option<&SentenceEncoder>,
    ws: &[&HriWindow],
) -> Result<crate::train::Batch> {
    let cfg = model.config();
    let txt = match (text, cfg.text_dim > 0) {
        (Some(e), true) => {
            let prompts: Vec<&str> = ws
                .iter()
                .map(|w| w.texts.first().map(|s| s.as_str()).unwrap_or(""))
                .collect();
            Some(e.embed(&prompts)?.concat())
        }
        _ => None,
    };
    Ok(batch(ws, txt, cfg.text_dim, &Device::Cpu)?)
}

/// The HRI model's forecasts (each window's first description as the prompt).
pub fn model_forecasts(
    model: &Forecaster,
    text: Option<&SentenceEncoder>,
    ws: &[&HriWindow],
    codec: Option<&crate::codec::RobotCodec>,
) -> Result<Vec<RobotForecast>> {
    let b = model_batch(model, text, ws)?;
    let out = crate::train::forecast(model, &b, codec)?;
    Ok(ws
        .iter()
        .zip(out)
        .map(|(w, frames)| {
            let (q, base) = frames.iter().map(|f| decode_robot(&w.canon, f)).unzip();
            RobotForecast { q, base }
        })
        .collect())
}

/// Score forecasts of `ws`.
pub fn evaluate(
    name: &str,
    ws: &[&HriWindow],
    forecasts: &[RobotForecast],
    r: &Retargeter,
    model: &RobotModel,
    body: &RobotBody,
) -> Result<HriReport> {
    let names: Vec<&str> = r.joint_names().iter().map(|s| s.as_str()).collect();
    let truth = reference(ws);
    let h = HORIZON_FRAMES.len();
    let (mut jpe, mut ajpe, mut fde) = (vec![0.0; h], vec![0.0; h], vec![0.0; h]);
    let (mut contact, mut proximity) = (Confusion::default(), Confusion::default());
    let mut head = 0.0;
    let mut head_n = 0usize;
    let world = |t: &Isometry3<f64>, p: &Vector3<f64>| t.transform_point(&Point3::from(*p)).coords;
    for ((w, f), tr) in ws.iter().zip(forecasts).zip(&truth) {
        for k in 0..PRED {
            let qp = model.values_from(names.iter().copied().zip(f.q[k].iter().copied()))?;
            let qt = model.values_from(names.iter().copied().zip(tr.q[k].iter().copied()))?;
            let (tp, tt) = (pose(f.base[k]), pose(tr.base[k]));
            if let Some(hi) = HORIZON_FRAMES.iter().position(|x| *x == k) {
                let (mut e, mut ea) = (0.0, 0.0);
                for p in POINTS {
                    let a = model.fk(&qp, p)?.translation.vector;
                    let b = model.fk(&qt, p)?.translation.vector;
                    e += (world(&tp, &a) - world(&tt, &b)).norm();
                    ea += (a - b).norm();
                }
                jpe[hi] += e / POINTS.len() as f64;
                ajpe[hi] += ea / POINTS.len() as f64;
                fde[hi] += (tp.translation.vector - tt.translation.vector).norm();
            }
            let robot = body.at_pose(model, &qp, &tp);
            let d = part_distances(&body_capsules(&w.human_world[k]), &robot);
            let min = d.iter().flatten().fold(f64::INFINITY, |m, x| m.min(*x));
            let (c, p) = contact_and_proximity(&w.human_world[k], &w.reference_world[k]);
            contact.add(min <= 0.0, c);
            proximity.add(min <= 0.05, p);
            let hp = tp.rotation * model.fk(&qp, "head_2_link")?.rotation;
            let ht = tt.rotation * model.fk(&qt, "head_2_link")?.rotation;
            head += head_rotation_error(&hp, &ht);
            head_n += 1;
        }
    }
    let n = ws.len().max(1) as f64;
    let mm = |v: Vec<f64>| v.into_iter().map(|x| x / n * 1e3).collect();
    Ok(HriReport {
        name: name.into(),
        windows: ws.len(),
        jpe: mm(jpe),
        ajpe: mm(ajpe),
        fde: mm(fde),
        f1_contact: contact.f1(),
        f1_proximity: proximity.f1(),
        head_error: head / head_n.max(1) as f64,
    })
}

/// The human agent's forecasts of one method, scored: mean errors in mm at [`HORIZON_FRAMES`].
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct HumanReport {
    /// Method.
    pub name: String,
    /// Windows.
    pub windows: usize,
    /// JPE of the 22 joints at the horizons, mm.
    pub jpe: Vec<f64>,
    /// AJPE (pelvis-aligned), mm.
    pub ajpe: Vec<f64>,
}

/// One person's joints (world) per future frame of a window.
type Track = Vec<[Vector3<f64>; echo_motion::skeleton::NUM_JOINTS]>;

/// The partner's true future in each window.
fn partner_truth(ws: &[&HriWindow]) -> Vec<Track> {
    use echo_models::features::decode;
    ws.iter()
        .map(|w| w.human[OBS..].iter().map(|f| decode(&w.canon, f)).collect())
        .collect()
}

/// The partner's forecast by zero velocity and by constant velocity (the last observed step
/// repeated), scored.
pub fn human_baselines(ws: &[&HriWindow]) -> Vec<HumanReport> {
    use echo_models::features::decode;
    let truth = partner_truth(ws);
    let last = |w: &HriWindow| decode(&w.canon, &w.human[OBS - 1]);
    let prev = |w: &HriWindow| decode(&w.canon, &w.human[OBS - 2]);
    let zv: Vec<Track> = ws.iter().map(|w| vec![last(w); PRED]).collect();
    let cv: Vec<Track> = ws
        .iter()
        .map(|w| {
            let (l, p) = (last(w), prev(w));
            (1..=PRED)
                .map(|k| std::array::from_fn(|j| l[j] + (l[j] - p[j]) * k as f64))
                .collect()
        })
        .collect();
    vec![
        score_human("zero-velocity", &zv, &truth),
        score_human("constant velocity", &cv, &truth),
    ]
}

/// The HRI model's forecast of the partner (its social forecast of the human agent), scored as
/// `name`; the windows go through the model 64 at a time.
pub fn human_forecast(
    name: &str,
    ws: &[&HriWindow],
    model: &Forecaster,
    text: Option<&SentenceEncoder>,
    codec: Option<&crate::codec::RobotCodec>,
) -> Result<HumanReport> {
    use echo_models::features::decode;
    let mut pred: Vec<Track> = Vec::with_capacity(ws.len());
    for chunk in ws.chunks(64) {
        let b = model_batch(model, text, chunk)?;
        let f = crate::train::forecast_human(model, &b, codec)?;
        pred.extend(chunk.iter().zip(&f).map(|(w, frames)| {
            frames
                .iter()
                .map(|x| decode(&w.canon, x))
                .collect::<Track>()
        }));
    }
    Ok(score_human(name, &pred, &partner_truth(ws)))
}

/// Mean JPE and AJPE at [`HORIZON_FRAMES`] ([`echo_eval::metrics`]).
fn score_human(name: &str, pred: &[Track], truth: &[Track]) -> HumanReport {
    use echo_eval::metrics::{ajpe, jpe};
    let h = HORIZON_FRAMES.len();
    let (mut sj, mut sa) = (vec![0.0; h], vec![0.0; h]);
    for (p, t) in pred.iter().zip(truth) {
        for (i, &k) in HORIZON_FRAMES.iter().enumerate() {
            let (p, t) = (vec![p[k]], vec![t[k]]);
            sj[i] += jpe(&p, &t);
            sa[i] += ajpe(&p, &t);
        }
    }
    let n = pred.len().max(1) as f64;
    HumanReport {
        name: name.into(),
        windows: pred.len(),
        jpe: sj.into_iter().map(|x| x / n).collect(),
        ajpe: sa.into_iter().map(|x| x / n).collect(),
    }
}

/// The human reports as a markdown table.
pub fn markdown_human(reports: &[HumanReport]) -> String {
    let mut s = String::from(
        "| method | JPE 0.2 | JPE 0.5 | JPE 1.0 | AJPE 0.2 | AJPE 0.5 | AJPE 1.0 |\n|---|---|---|---|---|---|---|\n",
    );
    let v = |x: &[f64]| {
        x.iter()
            .map(|v| format!("{v:.1}"))
            .collect::<Vec<_>>()
            .join(" | ")
    };
    for r in reports {
        s.push_str(&format!(
            "| {} | {} | {} |\n",
            r.name,
            v(&r.jpe),
            v(&r.ajpe)
        ));
    }
    s
}

/// The reports as a markdown table.
pub fn markdown(reports: &[HriReport]) -> String {
    let mut s = String::from(
        "| method | JPE* 0.2 | JPE* 0.5 | JPE* 1.0 | AJPE* 0.2 | AJPE* 0.5 | AJPE* 1.0 | FDE* 0.2 | FDE* 0.5 | FDE* 1.0 | F1 contact | F1 proximity | head error |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let f = |x: Option<f64>| x.map(|v| format!("{v:.2}")).unwrap_or_else(|| "–".into());
    for r in reports {
        let v = |x: &[f64]| {
            x.iter()
                .map(|v| format!("{v:.1}"))
                .collect::<Vec<_>>()
                .join(" | ")
        };
        s.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {:.3} |\n",
            r.name,
            v(&r.jpe),
            v(&r.ajpe),
            v(&r.fde),
            f(r.f1_contact),
            f(r.f1_proximity),
            r.head_error
        ));
    }
    s
}
