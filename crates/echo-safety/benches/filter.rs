//! Time of one safety cycle for the 17 arm, torso and head joints: plan reference, separation
//! against a person (current + 8 forecast frames; at 1.5 m, or a handshake partner at 0.7 m in
//! contact mode), self-collision, the filter step, and the command rollout over the 0.2 s horizon
//! plus the stop to rest.

use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use echo_safety::bench_support::{moving_scene, Scene};

fn bench(c: &mut Criterion) {
    for (scene, name) in [
        (Scene::PersonInView, "safety_cycle/17_joints_person_in_view"),
        (
            Scene::HandshakePartner,
            "safety_cycle/17_joints_handshake_partner",
        ),
    ] {
        let (mut sup, mut feed) = moving_scene(scene);
        let mut now = Instant::now();
        c.bench_function(name, |b| {
            b.iter(|| {
                now += Duration::from_millis(20);
                feed(&mut sup, now);
                sup.tick(now)
            })
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
