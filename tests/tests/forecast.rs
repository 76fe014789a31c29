//! mock perception (a generated two-person interaction) → perception bridge → forecaster →
//! forecasts, as separate processes over Zenoh on loopback: the forecaster's predictions of the
//! partner beat holding the last observed pose (zero velocity) against the ground truth.

use std::collections::HashMap;
use std::time::Duration;

use echo_bus::topics;
use echo_motion::synth::{generate, Split};
use echo_msgs::now_ns;
use echo_sim::perception::{clip_actors, MockPerception, MockPerceptionConfig};
use echo_system_tests::Harness;
use nalgebra::Vector3;

/// Approach-and-greet from the test split (seeds never trained on).
const CLIP: &str = "test:7";
const SETTLE_S: f64 = 1.5;

/// A tracked person in one skeleton frame: track id and joints.
type Person = (u32, Vec<[f64; 3]>);

fn mean_error(a: &[[f64; 3]], b: &[Vector3<f64>; 22]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (Vector3::from(*p) - q).norm())
        .sum::<f64>()
        / 22.0
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn forecasts_beat_zero_velocity_on_a_scripted_interaction() -> anyhow::Result<()> {
    let model = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/forecaster");
    let mut h = Harness::new("sys-forecast", 4)?;
    let t0 = now_ns() + 3_000_000_000;
    h.spawn_services("single", &["mock-robot", "perception-bridge"])?;
    let vars = echo_system_tests::profile_vars()
        .set("forecaster_model", model.to_str().unwrap_or_default());
    h.spawn_service("demo", "forecaster", &vars, &[])?;
    h.spawn(
        "mock-perception",
        "echoctl",
        &[
            "mock-perception",
            "--clip",
            CLIP,
            "--t0-ns",
            &t0.to_string(),
        ],
    )?;
    let bus = h.bus("system-test").await?;
    let robot = bus.robot().clone();
    let humans = bus.subscribe(&topics::humans(&robot)).await?;
    let forecasts = bus.subscribe(&topics::forecast(&robot)).await?;
    h.wait_alive(
        &bus,
        &[
            "mock-robot",
            "perception-bridge",
            "forecaster",
            "mock-perception",
        ],
        Duration::from_secs(60),
    )
    .await?;

    // The same scene as the mock publisher.
    let clip = generate(&Split::parse("test").expect("split").clip(7));
    let truth =
        MockPerception::with_people(MockPerceptionConfig::default(), clip_actors(&clip, 2.8));
    let dur = clip.duration();
    // Observed people per stamp (for the zero-velocity forecast from the same input).
    let mut observed: HashMap<u64, Vec<Person>> = HashMap::new();
    let (mut model_err, mut zv_err, mut n_forecasts, mut latency) = (0.0, 0.0, 0usize, vec![]);
    // Forecasts not compared: [outside the scored part of the loop, no matching input frame].
    let mut skipped = [0usize; 2];
    let deadline = tokio::time::Instant::now() + Duration::from_secs(14);
    while tokio::time::Instant::now() < deadline {
        let Ok(Some(f)) = tokio::time::timeout(Duration::from_millis(200), forecasts.recv()).await
        else {
            continue;
        };
        // The input frame of this forecast arrived before it: take every frame received so far.
        for s in humans.drain() {
            let people = s.msg.tracks.iter();
            observed.insert(
                s.msg.header.stamp_ns,
                people
                    .map(|t| (t.track_id, t.pose.joints.clone()))
                    .collect(),
            );
        }
        let f = f.msg;
        assert_eq!(f.human.len(), 23, "1.53 s at 15 Hz");
        latency.push(f.inference_ms);
        let t = (f.header.stamp_ns as f64 - t0 as f64) / 1e9;
        let script_t = t.rem_euclid(dur);
        // Skip the start-up and forecasts whose horizon crosses the loop point of the script.
        if t < SETTLE_S || script_t + 1.6 > dur || script_t < SETTLE_S {
            skipped[0] += 1;
            continue;
        }
        let Some(last) = observed.get(&f.header.stamp_ns).and_then(|people| {
            people
                .iter()
                .find(|(id, _)| *id == f.partner_id)
                .map(|(_, j)| j.clone())
        }) else {
            skipped[1] += 1;
            continue;
        };
        // Which of the two actors is the partner: the one nearest the observed pelvis.
        let now = truth.truth(script_t);
        let who = (0..2)
            .min_by(|a, b| mean_error(&last, &now[*a]).total_cmp(&mean_error(&last, &now[*b])))
            .unwrap_or(0);
        for (k, future) in f.human.iter().enumerate().skip(7) {
            let gt = truth.truth(script_t + (k + 1) as f64 / f.rate_hz)[who];
            model_err += mean_error(future, &gt);
            zv_err += mean_error(&last, &gt);
        }
        n_forecasts += 1;
    }
    assert!(
        n_forecasts > 30,
        "only {n_forecasts} comparable forecasts of {} (clip {dur:.1} s, {} observed frames, skipped {skipped:?})",
        latency.len(),
        observed.len()
    );
    let steps = (n_forecasts * 16) as f64;
    let (m, z) = (model_err / steps * 1e3, zv_err / steps * 1e3);
    latency.sort_by(f64::total_cmp);
    eprintln!(
        "{n_forecasts} forecasts: mean joint error 0.53–1.53 s ahead {m:.1} mm (zero velocity {z:.1} mm); inference median {:.2} ms",
        latency[latency.len() / 2]
    );
    assert!(
        m < z,
        "forecaster {m:.1} mm must beat zero velocity {z:.1} mm"
    );
    assert!(h.is_running("forecaster"));
    assert!(
        h.stop("forecaster", Duration::from_secs(5)),
        "clean shutdown on SIGTERM"
    );
    Ok(())
}
