//! The service loop with scripted inputs and no network: robots whose frames arrive together
//! share a forward pass, a lone robot is not held back, and bad frames are counted.

use std::time::{Duration, Instant};

use echo_bus::{Received, Stats};
use echo_forecast::{ForecastServer, ServerConfig};
use echo_models::model::ForecasterConfig;
use echo_models::ZeroVelocityBackend;
use echo_msgs::{Forecast, Header, HumanSkeletons, HumanTrack};
use forecaster::{run, Input, Output};
use futures::StreamExt;

#[derive(Default)]
struct Collect(Vec<(String, Forecast)>);

impl Output for Collect {
    async fn forecast(&mut self, robot: &str, msg: Forecast) -> anyhow::Result<()> {
        self.0.push((robot.to_string(), msg));
        Ok(())
    }
}

fn frame(robot: &str, k: u64) -> Input {
    let joints: Vec<[f64; 3]> = (0..22)
        .map(|j| [1.5 + 0.01 * k as f64, 0.0, 0.05 * j as f64])
        .collect();
    let mut header = Header::new(robot, "test", "base_footprint");
    header.stamp_ns = 1_000_000_000 + k * 66_666_667;
    let msg = HumanSkeletons {
        header,
        rate_hz: 15.0,
        tracks: vec![HumanTrack::from_joints(1, joints)],
        partner_id: Some(1),
    };
    Input::Skeletons(
        robot.to_string(),
        Received {
            msg,
            at: Instant::now(),
        },
    )
}

fn server() -> ForecastServer {
    ForecastServer::new(
        ServerConfig::default(),
        Box::new(ZeroVelocityBackend::new(ForecasterConfig::default())),
        None,
        "zero-velocity",
        echo_robot::RobotModel::tiago_dual(),
    )
    .unwrap()
}

#[tokio::test]
async fn frames_of_three_robots_in_one_tick_share_a_batch() {
    let mut inputs = vec![];
    for k in 0..10 {
        for r in ["a", "b", "c"] {
            inputs.push(frame(r, k));
        }
    }
    // A reordered frame of robot b.
    inputs.push(frame("b", 3));
    let stats = Stats::new("forecaster");
    let mut out = Collect::default();
    let c = run(
        futures::stream::iter(inputs).boxed(),
        &mut out,
        server(),
        &stats,
        Duration::from_millis(50),
        3,
    )
    .await
    .unwrap();
    // 8 frames fill the history; frames 7, 8 and 9 each give one batch of three robots.
    assert_eq!(out.0.len(), 9);
    assert_eq!(c.batches, 3);
    assert_eq!(c.forecasts, 9);
    assert_eq!(stats.rejected_count("humans", "reordered"), 1);
    for r in ["a", "b", "c"] {
        assert_eq!(out.0.iter().filter(|(x, _)| x == r).count(), 3);
    }
}

#[tokio::test]
async fn a_lone_robot_is_forecast_at_once() {
    let inputs: Vec<Input> = (0..9).map(|k| frame("a", k)).collect();
    let stats = Stats::new("forecaster");
    let mut out = Collect::default();
    let c = run(
        futures::stream::iter(inputs).boxed(),
        &mut out,
        server(),
        &stats,
        Duration::from_secs(5),
        1,
    )
    .await
    .unwrap();
    assert_eq!(c.batches, 2);
    assert_eq!(out.0.len(), 2);
}
