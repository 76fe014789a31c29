//! Every JSON example in docs/PROTOCOL.md decodes and validates as the message it is listed as,
//! and encoding the decoded message gives back the example's bytes (whitespace aside): the doc
//! shows exactly what goes on the wire, field order and number format included.

use echo_msgs::*;

/// The JSON text without the whitespace between tokens (strings kept as they are).
fn minify(json: &str) -> String {
    let mut out = String::with_capacity(json.len());
    let (mut in_string, mut escaped) = (false, false);
    for c in json.chars() {
        if in_string {
            out.push(c);
            match (escaped, c) {
                (true, _) => escaped = false,
                (false, '\\') => escaped = true,
                (false, '"') => in_string = false,
                _ => {}
            }
        } else if c == '"' {
            in_string = true;
            out.push(c);
        } else if !c.is_whitespace() {
            out.push(c);
        }
    }
    out
}

/// Decode `json` as `M`, re-encode it: the bytes the wire would carry.
fn roundtrip<M: Message>(json: &str) -> Result<Vec<u8>, DecodeError> {
    decode::<M>(json.as_bytes()).map(|m| encode(&m))
}

fn check(kind: &str, json: &str) -> Result<(), String> {
    let r = match kind {
        "keypoint_frame" => roundtrip::<KeypointFrame>(json),
        "human_skeletons" => roundtrip::<HumanSkeletons>(json),
        "joint_state" => roundtrip::<JointState>(json),
        "interaction_intent" => roundtrip::<InteractionIntent>(json),
        "forecast" => roundtrip::<Forecast>(json),
        "robot_plan" => roundtrip::<RobotPlan>(json),
        "robot_command" => roundtrip::<RobotCommand>(json),
        "safety_status" => roundtrip::<SafetyStatus>(json),
        "estop" => roundtrip::<EStop>(json),
        "service_status" => roundtrip::<ServiceStatus>(json),
        other => return Err(format!("unknown message kind '{other}' in the doc")),
    };
    let bytes = r.map_err(|e| format!("{kind}: {e}"))?;
    let (wire, doc) = (String::from_utf8_lossy(&bytes), minify(json));
    if wire != doc {
        return Err(format!(
            "{kind}: re-encoded bytes differ from the doc's example\n doc:  {doc}\n wire: {wire}"
        ));
    }
    Ok(())
}

#[test]
fn minify_keeps_strings_and_drops_layout() {
    assert_eq!(
        minify("{ \"a b\" : [1, 2],\n  \"c\": \"x \\\" y\" }"),
        "{\"a b\":[1,2],\"c\":\"x \\\" y\"}"
    );
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
