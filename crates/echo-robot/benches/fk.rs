//! Forward kinematics cost: one frame (the gripper, 12 joints deep), every link, and the capsule
//! model with its self-collision distance.

use criterion::{criterion_group, criterion_main, Criterion};
use echo_robot::collision::{min_self_distance, RobotBody};
use echo_robot::RobotModel;

fn bench(c: &mut Criterion) {
    let m = RobotModel::tiago_dual();
    let home = echo_robot::home_pose();
    let q = m
        .values_from(home.iter().map(|(n, v)| (n.as_str(), *v)))
        .unwrap();
    let body = RobotBody::tiago(&m).unwrap();
    c.bench_function("fk/gripper_right_grasping_frame", |b| {
        b.iter(|| m.fk(&q, "gripper_right_grasping_frame").unwrap())
    });
    c.bench_function("fk/all_links", |b| b.iter(|| m.fk_all(&q)));
    c.bench_function("fk/capsules_and_self_distance", |b| {
        b.iter(|| min_self_distance(&body.at(&m, &q)))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
