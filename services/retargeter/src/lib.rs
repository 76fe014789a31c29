//! The retargeter service: wiring around [`echo_retarget::imitation::Imitator`] and
//! [`echo_retarget::Retargeter`].
//!
//! Inputs: `humans`, `robot/state`, `prompt` (imitation plans are published only while the
//! prompt's mode is `imitation`). Output: `retarget` (RobotPlan, mode imitation) → safety.
//! Queryable `retarget/batch`: `{"poses": [[[x, y, z] × 22], …]}` → `{"joint_names": […],
//! "poses": [[17 values] | null, …]}` (null where a pose cannot be retargeted), for building
//! datasets on a GPU box.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::{Context, Result};
use echo_bus::shutdown::Shutdown;
use echo_bus::{keys, topics, Bus, BusArgs, Received, Stats};
use echo_msgs::{ControlMode, HumanSkeletons, InteractionIntent, JointState, RobotPlan};
use echo_retarget::imitation::{ImitationConfig, Imitator};
use echo_retarget::Retargeter;
use echo_robot::RobotModel;
use futures::{Stream, StreamExt};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

/// Service name.
pub const SERVICE: &str = "retargeter";

/// Most poses one batch request may carry.
pub const MAX_BATCH: usize = 8192;

/// Command-line / environment configuration.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Network.
    #[command(flatten)]
    pub bus: BusArgs,
    /// Checkpoint stem.
    #[arg(
        long,
        env = "ECHO_RETARGETER_MODEL",
        default_value = "models/retargeter"
    )]
    pub model: PathBuf,
    /// Copy the partner side for side instead of mirroring.
    #[arg(long)]
    pub no_mirror: bool,
    /// Publish imitation plans whatever the prompt's mode (for testing without a prompt).
    #[arg(long)]
    pub always: bool,
    /// Robot description (URDF); the embedded TIAGo++ when absent.
    #[arg(long, env = "ECHO_URDF")]
    pub urdf: Option<PathBuf>,
}

/// One input event.
#[derive(Debug)]
pub enum Input {
    /// Partner skeletons.
    Skeletons(Received<HumanSkeletons>),
    /// Robot joint state.
    JointState(Received<JointState>),
    /// Prompt (mode).
    Prompt(Received<InteractionIntent>),
}

/// Where plans go.
pub trait Output {
    /// Publish one plan.
    fn plan(&mut self, plan: RobotPlan) -> impl std::future::Future<Output = Result<()>> + Send;
}

struct BusOutput(echo_bus::Publisher<RobotPlan>);

impl Output for BusOutput {
    async fn plan(&mut self, plan: RobotPlan) -> Result<()> {
        self.0.put(plan).await
    }
}

/// Batch request.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BatchRequest {
    /// Poses, 22 joints each.
    pub poses: Vec<Vec<[f64; 3]>>,
}

/// Batch reply.
#[derive(Debug, Serialize, Deserialize)]
pub struct BatchReply {
    /// Joint names of each result.
    pub joint_names: Vec<String>,
    /// One result per pose (null: not retargetable).
    pub poses: Vec<Option<Vec<f64>>>,
}

/// Answer a batch request (bytes in, JSON out); a clear error for anything malformed.
pub fn answer(r: &Retargeter, bytes: &[u8]) -> Result<BatchReply, String> {
    let req: BatchRequest =
        serde_json::from_slice(bytes).map_err(|e| format!("malformed request: {e}"))?;
    if req.poses.len() > MAX_BATCH {
        return Err(format!(
            "{} poses in one request (at most {MAX_BATCH})",
            req.poses.len()
        ));
    }
    let mut poses = Vec::with_capacity(req.poses.len());
    for (i, p) in req.poses.iter().enumerate() {
        if p.len() != 22 {
            return Err(format!("pose {i} has {} joints, expected 22", p.len()));
        }
        if p.iter().flatten().any(|v| !v.is_finite()) {
            return Err(format!("pose {i} has a non-finite coordinate"));
        }
        poses.push(std::array::from_fn(|k| {
            Vector3::new(p[k][0], p[k][1], p[k][2])
        }));
    }
    let out = r.retarget(&poses).map_err(|e| format!("retargeter: {e}"))?;
    Ok(BatchReply {
        joint_names: r.joint_names().to_vec(),
        poses: out.into_iter().map(|o| o.map(|p| p.positions)).collect(),
    })
}

/// Open the bus, wire inputs, outputs and the queryable; run until `stop`.
pub async fn serve(args: Args, stop: Shutdown) -> Result<()> {
    let model = match &args.urdf {
        Some(p) => {
            RobotModel::from_urdf_file(p).with_context(|| format!("loading {}", p.display()))?
        }
        None => RobotModel::tiago_dual(),
    };
    // One network serves both the imitation loop and the batch queryable.
    let batch_retargeter = std::sync::Arc::new(
        Retargeter::load(&args.model, model.clone())
            .with_context(|| format!("loading the retargeter {}", args.model.display()))?,
    );
    let imitator = Imitator::new(
        batch_retargeter.clone(),
        model.clone(),
        ImitationConfig {
            mirror: !args.no_mirror,
            ..Default::default()
        },
    );
    let bus = Bus::open(&args.bus, SERVICE).await?;
    let robot = bus.robot().clone();
    let sk = bus.subscribe(&topics::humans(&robot)).await?;
    let js = bus.subscribe(&topics::robot_state(&robot)).await?;
    let pr = bus.subscribe(&topics::prompt(&robot)).await?;
    let mut output = BusOutput(bus.publisher(&topics::retarget(&robot)).await?);
    let stats = bus.stats();
    let qkey = keys::retarget_batch(&robot);
    let qstats = stats.clone();
    let _queryable = bus
        .session()
        .declare_queryable(qkey.clone())
        .callback(move |query| {
            let bytes = query
                .payload()
                .map(|p| p.to_bytes().to_vec())
                .unwrap_or_default();
            let key = query.key_expr().clone();
            match answer(&batch_retargeter, &bytes) {
                Ok(reply) => {
                    qstats.received("retarget_batch");
                    let body = serde_json::to_vec(&reply).unwrap_or_default();
                    let _ = zenoh::Wait::wait(query.reply(key, body));
                }
                Err(e) => {
                    qstats.rejected("retarget_batch", "bad_request", &e);
                    let _ = zenoh::Wait::wait(query.reply_err(e.into_bytes()));
                }
            }
        })
        .await
        .map_err(|e| anyhow::anyhow!("declaring queryable {qkey}: {e}"))?;
    let alive = bus.declare_alive().await?;
    let reporter = bus.spawn_status_reporter(Duration::from_secs(1), stop.clone());
    let a = futures::stream::unfold(sk, |ib| async move {
        ib.recv().await.map(|m| (Input::Skeletons(m), ib))
    });
    let b = futures::stream::unfold(js, |ib| async move {
        ib.recv().await.map(|m| (Input::JointState(m), ib))
    });
    let c = futures::stream::unfold(pr, |ib| async move {
        ib.recv().await.map(|m| (Input::Prompt(m), ib))
    });
    let mut stop_inputs = stop.clone();
    let inputs = futures::stream::select(futures::stream::select(a, b), c)
        .take_until(Box::pin(async move { stop_inputs.wait().await }));
    stats.set_notes(vec![format!(
        "retargeter {} ({}); imitation plans {}",
        args.model.display(),
        if args.no_mirror { "copy" } else { "mirror" },
        if args.always {
            "always"
        } else {
            "in imitation mode"
        }
    )]);
    tracing::info!(robot = %robot, "retargeter running");
    run(Box::pin(inputs), &mut output, imitator, &stats, args.always).await?;
    let _ = tokio::time::timeout(Duration::from_secs(2), reporter).await;
    drop(alive);
    bus.close().await?;
    tracing::info!("retargeter stopped");
    Ok(())
}

/// Run over `inputs` until they end: every skeleton frame in imitation mode (or `always`)
/// becomes a plan; frames that cannot are counted by reason.
pub async fn run<S, O>(
    mut inputs: S,
    output: &mut O,
    mut imitator: Imitator,
    stats: &Stats,
    always: bool,
) -> Result<()>
where
    S: Stream<Item = Input> + Unpin,
    O: Output,
{
    let mut mode = ControlMode::Forecast;
    while let Some(input) = inputs.next().await {
        match input {
            Input::JointState(m) => imitator.on_joint_state(&m.msg),
            Input::Prompt(m) => mode = m.msg.mode,
            Input::Skeletons(m) => {
                if !(always || mode == ControlMode::Imitation) {
                    continue;
                }
                let started = std::time::Instant::now();
                match imitator.on_skeletons(&m.msg) {
                    Ok(plan) => {
                        stats.latency_ms(started.elapsed().as_secs_f64() * 1e3);
                        output.plan(plan).await?;
                    }
                    Err(e) => stats.rejected("humans", e.reason(), &e.to_string()),
                }
            }
        }
    }
    Ok(())
}
