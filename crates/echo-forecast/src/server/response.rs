//! Response decoding: the model's output for one scene of the batch back into the partner's
//! forecast (the average of its symmetric copies, each mapped back) and the robot's plan.

use super::*;
use echo_models::features::Canonical;
use echo_models::model::ForecasterConfig;
use echo_motion::symmetry::Symmetry;

/// Person A's forecast frames of scene `i` (rows `i·|group|` …): one row decoded as it is, or
/// the copies' two people mapped back through their symmetries and person A's averaged.
pub(super) fn people(
    cfg: &ForecasterConfig,
    out: &[f32],
    canon: &[Canonical],
    group: &[Symmetry],
    i: usize,
) -> Vec<Vec<[f64; 3]>> {
    let [fa, fb] = cfg.agent_features;
    let per = cfg.pred * (fa + fb);
    let copies = group.len();
    let c = &canon[i * copies];
    match copies {
        1 => (0..cfg.pred)
            .map(|k| {
                let o = i * per + k * FEATURES;
                decode(c, &out[o..o + FEATURES])
                    .iter()
                    .map(|p| [p.x, p.y, p.z])
                    .collect()
            })
            .collect(),
        _ => (0..cfg.pred)
            .map(|k| {
                // Each copy's two forecast people, mapped back; person A's average.
                let mut sum = [Vector3::zeros(); NUM_JOINTS];
                for (gi, g) in group.iter().enumerate() {
                    let n = i * copies + gi;
                    let (oa, ob) = (n * per + k * fa, n * per + cfg.pred * fa + k * fb);
                    let pair = [
                        decode(&canon[n], &out[oa..oa + FEATURES]),
                        decode(&canon[n], &out[ob..ob + FEATURES]),
                    ];
                    for (s, p) in sum.iter_mut().zip(g(&pair)[0]) {
                        *s += p / copies as f64;
                    }
                }
                sum.iter().map(|p| [p.x, p.y, p.z]).collect()
            })
            .collect(),
    }
}

/// The robot's plan of scene `i` of a robot-agent model (one row per scene): the measured
/// joints first, then the forecast frames at `rate_hz`.
#[allow(clippy::too_many_arguments)]
pub(super) fn plan(
    cfg: &ForecasterConfig,
    out: &[f32],
    c: &Canonical,
    i: usize,
    measured: &[f64; ROBOT_STATE],
    header: Header,
    names: &[String],
    rate_hz: f64,
) -> RobotPlan {
    let [fa, fb] = cfg.agent_features;
    let per = cfg.pred * (fa + fb);
    let mut points = vec![PlanPoint {
        t: 0.0,
        positions: measured.to_vec(),
        base: None,
    }];
    for k in 0..cfg.pred {
        let o = i * per + cfg.pred * fa + k * fb;
        let (q, _) = decode_robot(c, &out[o..o + fb]);
        points.push(PlanPoint {
            t: (k + 1) as f64 / rate_hz,
            positions: q,
            base: None,
        });
    }
    RobotPlan {
        header,
        mode: ControlMode::Forecast,
        joint_names: names.to_vec(),
        points,
    }
}
