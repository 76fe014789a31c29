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
struct Collect(Vec<(String, Forecast)>, Vec<Instant>);

impl Output for Collect {
    async fn forecast(&mut self, robot: &str, msg: Forecast) -> anyhow::Result<()> {
        self.0.push((robot.to_string(), msg));
        self.1.push(Instant::now());
        Ok(())
    }
}

fn frame(robot: &str, k: u64) -> Input {
    frame_from(robot, "test", k)
}

fn frame_from(robot: &str, source: &str, k: u64) -> Input {
    let joints: Vec<[f64; 3]> = (0..22)
        .map(|j| [1.5 + 0.01 * k as f64, 0.0, 0.05 * j as f64])
        .collect();
    let mut header = Header::new(robot, source, "base_footprint");
    header.stamp_ns = stamp(k);
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

fn stamp(k: u64) -> u64 {
    1_000_000_000 + k * 66_666_667
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
        echo_msgs::now_ns,
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
        echo_msgs::now_ns,
    )
    .await
    .unwrap();
    assert_eq!(c.batches, 2);
    assert_eq!(out.0.len(), 2);
}

/// Frames of robot "a" at 15 Hz in real time, with `forged` sent right after frame 9; returns
/// when the forged frame was handed over, the forecasts with their publish times, and the counters.
async fn paced_with_a_forged_frame(forged: Input, frames: u64) -> (Instant, Collect, Stats) {
    let mut inputs: Vec<Input> = (0..10).map(|k| frame("a", k)).collect();
    inputs.push(forged);
    inputs.extend((10..frames).map(|k| frame("a", k)));
    let sent = std::sync::Arc::new(std::sync::Mutex::new(None));
    let mark = sent.clone();
    let paced = futures::stream::iter(inputs).then(move |input| {
        let mark = mark.clone();
        async move {
            let mut input = input;
            let forged =
                matches!(&input, Input::Skeletons(_, m) if m.msg.header.source == "forger");
            if forged {
                *mark.lock().unwrap() = Some(Instant::now());
            } else {
                tokio::time::sleep(Duration::from_nanos(66_666_667)).await;
            }
            // Received now (the loop's monotonic clock is each input's receive instant).
            if let Input::Skeletons(_, m) = &mut input {
                m.at = Instant::now();
            }
            input
        }
    });
    let stats = Stats::new("forecaster");
    let mut out = Collect::default();
    run(
        paced.boxed(),
        &mut out,
        server(),
        &stats,
        Duration::from_millis(3),
        1,
        echo_msgs::now_ns,
    )
    .await
    .unwrap();
    let at = sent.lock().unwrap().expect("the forged frame was sent");
    (at, out, stats)
}

/// Seconds from `at` to the first forecast of a frame after frame 9.
fn resumed_after(at: Instant, out: &Collect) -> Option<f64> {
    out.0
        .iter()
        .zip(&out.1)
        .find(|((_, f), _)| f.header.stamp_ns > stamp(9))
        .map(|(_, t)| t.duration_since(at).as_secs_f64())
}

#[tokio::test]
async fn a_frame_stamped_at_the_end_of_time_does_not_stop_forecasts() {
    let mut forged = frame_from("a", "forger", 10);
    if let Input::Skeletons(_, m) = &mut forged {
        m.msg.header.stamp_ns = u64::MAX;
    }
    let (at, out, stats) = paced_with_a_forged_frame(forged, 20).await;
    let after = resumed_after(at, &out).expect("forecasts after the forged frame");
    assert!(
        after < 1.0,
        "first forecast {after:.3} s after the forged frame"
    );
    // Frames 7 … 19 are each forecast: none was lost to the forged one.
    assert_eq!(out.0.len(), 13);
    assert_eq!(stats.rejected_count("humans", "from_future"), 1);
    assert_eq!(stats.rejected_count("humans", "reordered"), 0);
}

#[tokio::test]
async fn a_frame_stamped_ahead_of_the_stream_pauses_forecasts_only_briefly() {
    // A minute ahead of the stream but not of this host's clock: it gets in, and the real frames
    // are refused as reordered until the history resyncs (500 ms), then refills (8 frames).
    let (at, out, stats) = paced_with_a_forged_frame(frame_from("a", "forger", 10 + 900), 36).await;
    let after = resumed_after(at, &out).expect("forecasts resume");
    assert!(
        after < 1.5,
        "first forecast {after:.3} s after the forged frame"
    );
    assert_eq!(stats.dropped_count("humans_resync"), 1);
    assert!(stats.rejected_count("humans", "reordered") >= 7);
}
