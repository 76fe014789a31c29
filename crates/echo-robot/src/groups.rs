//! Joint groups as the TIAGo++ controllers see them.

/// One controller's joints.
#[derive(Debug, Clone, PartialEq)]
pub struct JointGroup {
    /// Group name.
    pub name: &'static str,
    /// Controller that executes trajectories for it (ros2_control name).
    pub controller: &'static str,
    /// Joints, in the controller's order.
    pub joints: Vec<String>,
}

/// The TIAGo++ joint groups: arm_left (7), arm_right (7), torso (1), head (2), gripper_left (2),
/// gripper_right (2). The base is planar and commanded by twist, not listed here.
pub fn tiago_groups() -> Vec<JointGroup> {
    let arm = |side: &str| {
        (1..=7)
            .map(|i| format!("arm_{side}_{i}_joint"))
            .collect::<Vec<_>>()
    };
    let fingers = |side: &str| {
        vec![
            format!("gripper_{side}_left_finger_joint"),
            format!("gripper_{side}_right_finger_joint"),
        ]
    };
    vec![
        JointGroup {
            name: "arm_left",
            controller: "arm_left_controller",
            joints: arm("left"),
        },
        JointGroup {
            name: "arm_right",
            controller: "arm_right_controller",
            joints: arm("right"),
        },
        JointGroup {
            name: "torso",
            controller: "torso_controller",
            joints: vec!["torso_lift_joint".into()],
        },
        JointGroup {
            name: "head",
            controller: "head_controller",
            joints: vec!["head_1_joint".into(), "head_2_joint".into()],
        },
        JointGroup {
            name: "gripper_left",
            controller: "gripper_left_controller",
            joints: fingers("left"),
        },
        JointGroup {
            name: "gripper_right",
            controller: "gripper_right_controller",
            joints: fingers("right"),
        },
    ]
}

/// The groups the safety filter moves (arms, torso, head: 17 joints).
pub fn motion_groups() -> Vec<JointGroup> {
    tiago_groups()
        .into_iter()
        .filter(|g| !g.name.starts_with("gripper"))
        .collect()
}
