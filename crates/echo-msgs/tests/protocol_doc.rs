//! Every JSON example in docs/PROTOCOL.md decodes and validates as the message it is listed as.

use echo_msgs::*;

fn check(kind: &str, json: &str) -> Result<(), String> {
    let b = json.as_bytes();
    let r = match kind {
        "keypoint_frame" => decode::<KeypointFrame>(b).map(drop),
        "human_skeletons" => decode::<HumanSkeletons>(b).map(drop),
        "joint_state" => decode::<JointState>(b).map(drop),
        "interaction_intent" => decode::<InteractionIntent>(b).map(drop),
        "forecast" => decode::<Forecast>(b).map(drop),
        "robot_plan" => decode::<RobotPlan>(b).map(drop),
        "robot_command" => decode::<RobotCommand>(b).map(drop),
        "safety_status" => decode::<SafetyStatus>(b).map(drop),
        "estop" => decode::<EStop>(b).map(drop),
        "service_status" => decode::<ServiceStatus>(b).map(drop),
        other => return Err(format!("unknown message kind '{other}' in the doc")),
    };
    r.map_err(|e| format!("{kind}: {e}"))
}

#[test]
fn protocol_examples_are_valid() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/PROTOCOL.md");
    let doc = std::fs::read_to_string(&path).unwrap();
    let mut kinds = vec![];
    let mut lines = doc.lines();
    while let Some(line) = lines.next() {
        if let Some(kind) = line.strip_prefix("### ") {
            assert_eq!(lines.next(), Some("```json"), "{kind}: example must follow");
            let json: String = lines
                .by_ref()
                .take_while(|l| *l != "```")
                .collect::<Vec<_>>()
                .join("\n");
            check(kind, &json).unwrap();
            kinds.push(kind.to_string());
        }
    }
    for k in [
        KeypointFrame::KIND,
        HumanSkeletons::KIND,
        JointState::KIND,
        InteractionIntent::KIND,
        Forecast::KIND,
        RobotPlan::KIND,
        RobotCommand::KIND,
        SafetyStatus::KIND,
        EStop::KIND,
        ServiceStatus::KIND,
    ] {
        assert!(
            kinds.iter().any(|x| x == k),
            "docs/PROTOCOL.md has no example of {k}"
        );
    }
}
