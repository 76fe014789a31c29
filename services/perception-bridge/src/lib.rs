//! The perception-bridge service: wiring and lifecycle around [`echo_perception::PerceptionBridge`].
//!
//! Inputs: `perception/raw` (KeypointFrame), `robot/state` (JointState).
//! Output: `humans` (HumanSkeletons) at the model rate; `status/perception-bridge`.

use std::time::Instant;

use anyhow::Result;
use echo_bus::{Received, Stats};
use echo_msgs::{HumanSkeletons, JointState, KeypointFrame};
use echo_perception::PerceptionBridge;
use futures::{Stream, StreamExt};

/// Service name (liveliness token, status key, logs).
pub const SERVICE: &str = "perception-bridge";

/// Edge name of the keypoint input in counters.
pub const INPUT_EDGE: &str = "perception_raw";

/// One input event.
#[derive(Debug)]
pub enum Input {
    /// A keypoint frame from the pose estimator.
    Keypoints(Received<KeypointFrame>),
    /// A robot joint state.
    JointState(Received<JointState>),
}

/// Where the service's output goes.
pub trait Output {
    /// Publish one skeletons message.
    fn skeletons(
        &mut self,
        msg: HumanSkeletons,
    ) -> impl std::future::Future<Output = Result<()>> + Send;
}

/// Run the bridge over `inputs` until they end. `wall_now_ns` reads the receiver's wall clock
/// (compared with capture stamps for staleness). Rejections are counted in `stats` and logged.
pub async fn run<S, O>(
    mut inputs: S,
    output: &mut O,
    mut bridge: PerceptionBridge,
    stats: &Stats,
    wall_now_ns: impl Fn() -> u64,
) -> Result<()>
where
    S: Stream<Item = Input> + Unpin,
    O: Output,
{
    while let Some(input) = inputs.next().await {
        match input {
            Input::JointState(js) => bridge.on_joint_state(&js.msg),
            Input::Keypoints(frame) => {
                let started = Instant::now();
                match bridge.on_keypoints(&frame.msg, wall_now_ns()) {
                    Ok(out) => {
                        for e in &out.rejected_people {
                            stats.rejected(INPUT_EDGE, e.reason(), &e.to_string());
                        }
                        for s in out.skeletons {
                            output.skeletons(s).await?;
                        }
                        stats.latency_ms(started.elapsed().as_secs_f64() * 1e3);
                    }
                    Err(e) => stats.rejected(INPUT_EDGE, e.reason(), &e.to_string()),
                }
            }
        }
    }
    Ok(())
}
