//! Time to process one keypoint frame (lift, transform, track, filter, IK, output), with one
//! person and with a bystander, for both input formats.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use echo_perception::{BridgeConfig, PerceptionBridge};
use echo_robot::RobotModel;
use echo_sim::perception::{MockFormat, MockPerceptionConfig};
use echo_sim::scenario::bridge_inputs;

fn bench(c: &mut Criterion) {
    let model = RobotModel::tiago_dual();
    for (name, format, bystander) in [
        ("smpl24_1_person", MockFormat::Smpl24Points, false),
        ("smpl24_2_people", MockFormat::Smpl24Points, true),
        ("coco17_1_person", MockFormat::Coco17PixelsDepth, false),
    ] {
        let inputs = bridge_inputs(
            200,
            MockPerceptionConfig {
                format,
                bystander,
                ..Default::default()
            },
        );
        // A bridge warmed on 10 frames (tracks confirmed, filters running), then frame 11 timed.
        c.bench_function(&format!("bridge_frame/{name}"), |b| {
            b.iter_batched(
                || {
                    let mut br = PerceptionBridge::new(BridgeConfig::default(), model.clone());
                    for (js, f) in &inputs[..10] {
                        br.on_joint_state(js);
                        let _ = br.on_keypoints(f, f.header.stamp_ns + 30_000_000);
                    }
                    br
                },
                |mut br| {
                    let (js, f) = &inputs[10];
                    br.on_joint_state(js);
                    br.on_keypoints(f, f.header.stamp_ns + 30_000_000)
                        .map(|o| o.skeletons.len())
                },
                BatchSize::LargeInput,
            )
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
