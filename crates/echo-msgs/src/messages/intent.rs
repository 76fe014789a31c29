//! Messages on the edge operator / dialogue → forecaster, safety.

use super::*;

/// Interaction types Echo knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Interaction {
    /// Shake hands.
    Handshake,
    /// Wave and wave back.
    Wave,
    /// High five.
    HighFive,
    /// Hand an object over.
    Handover,
    /// Hug.
    Hug,
    /// Bow and bow back.
    Bow,
    /// Point somewhere and look there.
    PointAndLook,
    /// Walk up and greet.
    ApproachGreet,
    /// Tap the other's shoulder.
    ShoulderTap,
    /// Mirror the other's arm motion.
    Imitation,
    /// Clap together.
    Clap,
    /// Walk past each other.
    WalkPast,
    /// No particular interaction.
    Idle,
}

impl Interaction {
    /// Interactions that bring the robot's hand into contact with the person.
    pub fn is_contact(self) -> bool {
        matches!(
            self,
            Interaction::Handshake
                | Interaction::HighFive
                | Interaction::Handover
                | Interaction::Hug
                | Interaction::ShoulderTap
        )
    }
}

/// Where the robot's motion comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ControlMode {
    /// Follow the forecaster's robot plan.
    Forecast,
    /// Mirror the partner through the retargeter.
    Imitation,
    /// Hold still.
    Hold,
}

/// The interaction the robot should take part in: text for the model, a typed intent for safety.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InteractionIntent {
    /// Header.
    pub header: Header,
    /// Natural-language description, e.g. "One person waves, and the other waves back."
    pub text: String,
    /// Typed interaction.
    pub interaction: Interaction,
    /// Control mode.
    pub mode: ControlMode,
}
message!(InteractionIntent, "interaction_intent");

/// Longest prompt accepted, in bytes.
pub const MAX_PROMPT_BYTES: usize = 1024;

impl Validate for InteractionIntent {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.text.len() > MAX_PROMPT_BYTES {
            return Err(ValidationError::OutOfRange {
                field: "text".into(),
                value: self.text.len() as f64,
                min: 0.0,
                max: MAX_PROMPT_BYTES as f64,
            });
        }
        Ok(())
    }
}
