//! The retargeter's loop with scripted inputs and no network, and the batch request parser.

use std::time::Instant;

use echo_bus::{Received, Stats};
use echo_motion::synth::{generate, Split};
use echo_msgs::{
    ControlMode, Header, HumanSkeletons, HumanTrack, Interaction, InteractionIntent, JointState,
    RobotPlan,
};
use echo_retarget::imitation::{ImitationConfig, Imitator};
use echo_retarget::Retargeter;
use echo_robot::RobotModel;
use futures::StreamExt;
use retargeter::{answer, run, Input, Output};

#[derive(Default)]
struct Collect(Vec<RobotPlan>);

impl Output for Collect {
    async fn plan(&mut self, plan: RobotPlan) -> anyhow::Result<()> {
        self.0.push(plan);
        Ok(())
    }
}

fn shipped() -> Retargeter {
    let stem = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/retargeter");
    Retargeter::load(&stem, RobotModel::tiago_dual()).unwrap()
}

fn rx<M>(msg: M) -> Received<M> {
    Received {
        msg,
        at: Instant::now(),
    }
}

fn skeletons(k: u64) -> HumanSkeletons {
    let clip = generate(&Split::Test.clip(9)); // imitation game
    let joints: Vec<[f64; 3]> = clip
        .joints(10 + k as usize, 0)
        .iter()
        .map(|p| [p.x, p.y, p.z])
        .collect();
    let mut header = Header::new("r", "test", "base_footprint");
    header.stamp_ns = 1_000_000_000 + k * 66_666_667;
    HumanSkeletons {
        header,
        rate_hz: 15.0,
        tracks: vec![HumanTrack::from_joints(4, joints)],
        partner_id: Some(4),
    }
}

fn home_state() -> JointState {
    let home = echo_robot::home_pose();
    let mut name: Vec<String> = home.iter().map(|(n, _)| n.clone()).collect();
    let mut position: Vec<f64> = home.iter().map(|(_, v)| *v).collect();
    name.extend(["head_1_joint".to_string(), "head_2_joint".into()]);
    position.extend([0.0, 0.0]);
    JointState {
        header: Header::new("r", "test", "base_footprint"),
        name,
        position,
        velocity: vec![],
        base: None,
    }
}

fn prompt(mode: ControlMode) -> InteractionIntent {
    InteractionIntent {
        header: Header::new("r", "test", ""),
        text: "Imitate me.".into(),
        interaction: Interaction::Imitation,
        mode,
    }
}

#[tokio::test]
async fn plans_only_in_imitation_mode_starting_at_the_measured_state() {
    let model = RobotModel::tiago_dual();
    let imitator = Imitator::new(
        std::sync::Arc::new(shipped()),
        model.clone(),
        ImitationConfig::default(),
    );
    let inputs = vec![
        Input::Skeletons(rx(skeletons(0))), // no state yet, forecast mode: ignored
        Input::Prompt(rx(prompt(ControlMode::Imitation))),
        Input::Skeletons(rx(skeletons(1))), // no joint state: counted
        Input::JointState(rx(home_state())),
        Input::Skeletons(rx(skeletons(2))),
        Input::Skeletons(rx(skeletons(3))),
        Input::Prompt(rx(prompt(ControlMode::Forecast))),
        Input::Skeletons(rx(skeletons(4))), // not imitating any more
    ];
    let stats = Stats::new("retargeter");
    let mut out = Collect::default();
    run(
        futures::stream::iter(inputs).boxed(),
        &mut out,
        imitator,
        &stats,
        false,
    )
    .await
    .unwrap();
    assert_eq!(out.0.len(), 2);
    assert_eq!(stats.rejected_count("humans", "no_state"), 1);
    let home = home_state();
    for plan in &out.0 {
        assert_eq!(plan.mode, ControlMode::Imitation);
        assert_eq!(plan.points.len(), 2);
        assert!(plan.points[1].t >= 0.3);
        for (k, n) in plan.joint_names.iter().enumerate() {
            assert_eq!(plan.points[0].positions[k], home.position_of(n).unwrap());
            let l = model.limits(n).unwrap();
            let v = plan.points[1].positions[k];
            assert!(v >= l.soft_lower && v <= l.soft_upper, "{n} = {v}");
        }
    }
}

#[test]
fn batch_requests_are_checked() {
    let r = shipped();
    assert!(answer(&r, b"{not json").unwrap_err().contains("malformed"));
    assert!(answer(&r, br#"{"poses": [[[0,0,0]]]}"#)
        .unwrap_err()
        .contains("expected 22"));
    let clip = generate(&Split::Test.clip(0));
    let pose: Vec<[f64; 3]> = clip.joints(5, 1).iter().map(|p| [p.x, p.y, p.z]).collect();
    let ok = serde_json::json!({ "poses": [pose, vec![[0.0, 0.0, 1.0]; 22]] });
    let reply = answer(&r, ok.to_string().as_bytes()).unwrap();
    assert_eq!(reply.joint_names.len(), 17);
    assert_eq!(reply.poses[0].as_ref().unwrap().len(), 17);
    assert!(
        reply.poses[1].is_none(),
        "coincident shoulders cannot be retargeted"
    );
    // JSON has no NaN; numbers too large for f64 are rejected by the parser.
    let huge = serde_json::json!({ "poses": [vec![[0.0, 0.0, 1.0]; 22]] })
        .to_string()
        .replace("1.0", "1e400");
    assert!(answer(&r, huge.as_bytes()).is_err());
}
