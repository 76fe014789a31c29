//! SceneBuilder: what each input turns into, and what it refuses.

mod common;

use common::*;
use echo_msgs::SafetyState;
use echo_robot::collision::RobotBody;
use echo_robot::RobotModel;
use echo_scene::{style, EntityKind, Input, Primitive, SceneBuilder};
use nalgebra::{Point3, Vector3};

fn builder_with_walk_inputs(t: u64, x: f64) -> SceneBuilder {
    let mut b = SceneBuilder::new();
    assert_eq!(
        b.on_message(
            &key("humans"),
            &humans(
                t,
                vec![track(7, person(x, 0.0)), track(9, person(2.5, 1.5))],
                Some(7)
            )
        ),
        Some(Input::Humans)
    );
    assert_eq!(
        b.on_message(&key("robot/state"), &home_state(t)),
        Some(Input::RobotState)
    );
    assert_eq!(
        b.on_message(&key("forecast"), &forecast(t, 7, x)),
        Some(Input::Forecast)
    );
    assert_eq!(
        b.on_message(
            &key("safety/status"),
            &safety(t, SafetyState::Limiting, Some(0.8))
        ),
        Some(Input::SafetyStatus)
    );
    b
}

#[test]
fn every_input_becomes_entities_in_the_base_frame() {
    let b = builder_with_walk_inputs(T0, 1.5);
    let s = b.scene(T0);
    assert_eq!(s.frame_id, "base_footprint");
    assert_eq!(s.time_ns, T0);
    // The partner and the bystander, a capsule per bone (21) and a head.
    let partner = s.entity("partner").expect("partner");
    assert_eq!(partner.kind, EntityKind::Partner);
    assert_eq!(partner.primitives.len(), 22);
    let bystander = s.entity("person/9").expect("bystander");
    assert_eq!(bystander.kind, EntityKind::Person);
    let Primitive::Sphere { centre, color, .. } = partner.primitives.last().unwrap() else {
        panic!("the head is a sphere");
    };
    // (JSON keeps floats to within an ulp or so.)
    assert!((Vector3::from(*centre) - Vector3::from(person(1.5, 0.0)[15])).norm() < 1e-12);
    assert_eq!(*color, style::PARTNER);

    // The robot: echo-robot's 14 capsules at the measured joints, coloured by part.
    let robot = s.entity("robot").expect("robot");
    assert_eq!(robot.primitives.len(), 14);
    let model = RobotModel::tiago_dual();
    let q = model
        .values_from(
            echo_robot::home_pose()
                .iter()
                .map(|(n, v)| (n.as_str(), *v)),
        )
        .unwrap();
    let expected = RobotBody::tiago(&model).unwrap().at(&model, &q);
    for (p, (part, c)) in robot.primitives.iter().zip(&expected) {
        let Primitive::Capsule {
            a,
            b,
            radius,
            color,
        } = p
        else {
            panic!("robot parts are capsules");
        };
        assert_eq!((*a, *b, *radius), (c.a.into(), c.b.into(), c.radius));
        assert_eq!(*color, style::robot_part(*part));
    }

    // The forecast ghost fades: later frames more transparent.
    let ghost = s.entity("forecast").expect("forecast");
    let alphas: Vec<f32> = ghost
        .primitives
        .iter()
        .map(|p| match p {
            Primitive::LineStrip { color, .. } => color.a,
            _ => panic!("ghosts are lines"),
        })
        .collect();
    assert_eq!(alphas.len(), 5 * 5, "5 ghosts of 5 chains");
    assert!(alphas.windows(2).all(|w| w[0] >= w[1]) && alphas[0] > alphas[24] + 0.3);

    // The camera frustum's apex is the URDF's head camera.
    let cam = model.fk(&q, "head_front_camera_optical_frame").unwrap();
    let Primitive::LineStrip { points, .. } = &s.entity("camera").unwrap().primitives[1] else {
        panic!("frustum lines");
    };
    assert!((Vector3::from(points[1]) - cam.translation.vector).norm() < 1e-12);
    // Its far corners lie in front of the camera (optical z).
    let local = cam.inverse() * Point3::from(points[0]);
    assert!((local.z - 1.0).abs() < 1e-9);

    // Safety: colour and text from the status.
    let safety = s.entity("safety").unwrap();
    let Primitive::Text { text, color, .. } = &safety.primitives[1] else {
        panic!("safety label");
    };
    assert_eq!(text, "LIMITING 50%, separation 0.80 m");
    assert_eq!(*color, style::safety(SafetyState::Limiting));
    assert_eq!(s.captions[0].text, *text);
}

#[test]
fn the_separation_line_joins_the_closest_surface_points() {
    let b = builder_with_walk_inputs(T0, 1.2);
    let s = b.scene(T0);
    let sep = s.entity("separation").expect("separation line");
    let Primitive::LineStrip { points, .. } = &sep.primitives[0] else {
        panic!("a line");
    };
    let Primitive::Text { text, .. } = &sep.primitives[1] else {
        panic!("a label");
    };
    let drawn = (Vector3::from(points[1]) - Vector3::from(points[0])).norm();
    // Independently: the smallest capsule surface distance over both people and every part.
    let model = RobotModel::tiago_dual();
    let robot = RobotBody::tiago(&model)
        .unwrap()
        .at(&model, b.joint_values());
    let mut best = f64::INFINITY;
    for joints in [person(1.2, 0.0), person(2.5, 1.5)] {
        let j: Vec<Vector3<f64>> = joints.iter().map(|p| Vector3::from(*p)).collect();
        for (_, h) in echo_motion::sensors::body_capsules(&j) {
            for (_, r) in &robot {
                best = best.min(r.distance(&h));
            }
        }
    }
    assert!(best > 0.05, "the person does not touch the robot: {best}");
    assert!((drawn - best).abs() < 1e-9, "drawn {drawn} vs {best}");
    assert_eq!(*text, format!("{best:.2} m"));
    // The robot end is on the robot's side, the person's end on the partner's.
    assert!(points[0][0] < points[1][0]);
}

#[test]
fn malformed_payloads_are_counted_and_ignored() {
    let mut b = builder_with_walk_inputs(T0, 1.5);
    let before = b.scene(T0);
    let nan = String::from_utf8(humans(T0, vec![track(7, person(1.5, 0.0))], Some(7)))
        .unwrap()
        .replacen("1.5", "1e999", 1);
    let bad: Vec<(String, Vec<u8>)> = vec![
        (key("humans"), b"not json".to_vec()),
        (key("humans"), nan.into_bytes()),
        (key("robot/state"), br#"{"header":{"schema":99}}"#.to_vec()),
        (key("forecast"), vec![0xff, 0xfe, 0x00]),
        (key("safety/status"), b"{}".to_vec()),
        (key("prompt"), b"[1,2,3]".to_vec()),
        (
            key("humans"),
            humans(T0, vec![track(7, person(1.5, 0.0))], Some(8)),
        ),
    ];
    for (k, p) in &bad {
        assert_eq!(b.on_message(k, p), None, "{k}");
    }
    // Not scene inputs, or another robot: ignored, not refused.
    assert_eq!(b.on_message("echo/r1/status/safety", b"{}"), None);
    assert_eq!(
        b.on_message("echo/other/humans", &humans(T0, vec![], None)),
        None
    );
    assert_eq!(b.on_message("garbage", b""), None);
    let stats = b.stats();
    assert_eq!(stats.rejected_total(), bad.len() as u64);
    assert_eq!(stats.rejected["humans"], 3);
    assert_eq!(stats.ignored, 3);
    assert!(stats
        .last_error
        .as_deref()
        .unwrap()
        .contains("partner_id 8"));
    // The last good inputs still make the same scene.
    assert_eq!(b.scene(T0), before);
}

#[test]
fn old_inputs_leave_the_scene_but_the_robot_stays() {
    let mut b = builder_with_walk_inputs(T0, 1.5);
    let later = T0 + 2_000_000_000;
    let s = b.scene(later);
    assert!(s.entity("partner").is_none() && s.entity("forecast").is_none());
    assert!(s.entity("separation").is_none());
    assert!(s.entity("robot").is_some() && s.entity("camera").is_some());
    assert_eq!(s.captions[0].text, "safety: no recent status");
    // Arrival time decides, not the sender's stamp (a recording replayed with old stamps).
    b.on_message_at(
        &key("humans"),
        &humans(T0, vec![track(7, person(1.5, 0.0))], Some(7)),
        Some(later),
    );
    assert!(b.scene(later).entity("partner").is_some());
}

#[test]
fn joint_states_move_the_capsules_by_forward_kinematics() {
    let mut b = SceneBuilder::new();
    let home = b.scene(T0);
    let raised = [
        ("arm_right_1_joint", 0.0),
        ("arm_right_2_joint", -1.0),
        ("arm_right_4_joint", 0.5),
        ("not_a_joint", 3.0),
    ];
    assert_eq!(
        b.on_message(&key("robot/state"), &joint_state(T0, &raised)),
        Some(Input::RobotState)
    );
    let moved = b.scene(T0);
    let model = RobotModel::tiago_dual();
    let grip = model
        .fk(b.joint_values(), "gripper_right_grasping_frame")
        .unwrap()
        .translation
        .vector;
    let right_gripper = |s: &echo_scene::Scene| match &s.entity("robot").unwrap().primitives[13] {
        Primitive::Capsule { b, .. } => *b,
        _ => panic!("capsule"),
    };
    assert!((Vector3::from(right_gripper(&moved)) - grip).norm() < 1e-12);
    assert_ne!(right_gripper(&home), right_gripper(&moved));
    // Joints not in the message keep their values (the left arm stays home).
    let i = model.joint_index("arm_left_2_joint").unwrap();
    assert_eq!(b.joint_values().0[i], echo_robot::HOME_ARM[1]);
}

#[test]
fn no_prefix_or_byte_flip_of_a_valid_message_panics() {
    let valid: Vec<(String, Vec<u8>)> = vec![
        (
            key("humans"),
            humans(T0, vec![track(7, person(1.5, 0.0))], Some(7)),
        ),
        (key("robot/state"), home_state(T0)),
        (key("forecast"), forecast(T0, 7, 1.5)),
        (
            key("safety/status"),
            safety(T0, SafetyState::Stopping, Some(0.3)),
        ),
    ];
    let mut b = SceneBuilder::new();
    let (mut refused, mut tried) = (0, 0);
    for (k, p) in &valid {
        // No strict prefix of a JSON object is one.
        for cut in (0..p.len()).step_by(7) {
            refused += u64::from(b.on_message(k, &p[..cut]).is_none());
            tried += 1;
        }
        for i in (0..p.len()).step_by(13) {
            let mut q = p.clone();
            q[i] = q[i].wrapping_add(1 + (i % 200) as u8);
            b.on_message(k, &q);
            let _ = b.scene(T0);
        }
        assert!(b.on_message(k, p).is_some());
    }
    assert_eq!(refused, tried);
    assert!(b.stats().rejected_total() >= refused);
    assert!(b.scene(T0).entity("partner").is_some());
}
