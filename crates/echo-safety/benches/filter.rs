//! Time of one safety cycle for the 17 arm, torso and head joints: plan reference, separation
//! against a person (current + 8 forecast frames), self-collision, the filter step, and the
//! command rollout over the 0.2 s horizon plus the stop to rest.

use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use echo_safety::bench_support::moving_scene;

fn bench(c: &mut Criterion) {
    let (mut sup, mut feed) = moving_scene();
    let mut now = Instant::now();
    c.bench_function("safety_cycle/17_joints_person_in_view", |b| {
        b.iter(|| {
            now += Duration::from_millis(20);
            feed(&mut sup, now);
            sup.tick(now)
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
