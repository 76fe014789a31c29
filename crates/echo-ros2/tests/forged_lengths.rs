//! A sample whose length fields lie is an error, and decoding it never allocates what the
//! lie claims: this test binary counts the largest single allocation.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use echo_ros2::*;

struct Largest;

static LARGEST: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Largest {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        LARGEST.fetch_max(l.size(), Ordering::Relaxed);
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        LARGEST.fetch_max(n, Ordering::Relaxed);
        unsafe { System.realloc(p, l, n) }
    }
}

#[global_allocator]
static A: Largest = Largest;

/// Set every 4-byte-aligned word of `bytes` (after the encapsulation header) to 0xffff_ffff in
/// turn and decode; the largest allocation made while doing so.
fn largest_allocation_decoding_forgeries<T: for<'de> serde::Deserialize<'de>>(
    bytes: &[u8],
) -> usize {
    LARGEST.store(0, Ordering::Relaxed);
    for at in (4..bytes.len().saturating_sub(3)).step_by(4) {
        let mut forged = bytes.to_vec();
        forged[at..at + 4].copy_from_slice(&u32::MAX.to_le_bytes());
        let _ = decode::<T>(&forged);
    }
    LARGEST.load(Ordering::Relaxed)
}

#[test]
fn forged_lengths_in_joint_states_images_and_camera_info_allocate_nothing_large() {
    let js = encode(&RosJointState {
        header: RosHeader {
            frame_id: "base_link".into(),
            ..Default::default()
        },
        name: vec!["arm_right_1_joint".into()],
        position: vec![1.0],
        ..Default::default()
    })
    .unwrap();
    let img = encode(&RosImage {
        encoding: "rgb8".into(),
        width: 2,
        height: 2,
        step: 6,
        data: vec![7; 12],
        ..Default::default()
    })
    .unwrap();
    let info = encode(&RosCameraInfo {
        distortion_model: "plumb_bob".into(),
        d: vec![0.0; 5],
        ..Default::default()
    })
    .unwrap();
    // The honest samples decode.
    assert!(decode::<RosJointState>(&js).is_ok());
    assert!(decode::<RosImage>(&img).is_ok());
    assert!(decode::<RosCameraInfo>(&info).is_ok());
    for (what, largest) in [
        (
            "joint state",
            largest_allocation_decoding_forgeries::<RosJointState>(&js),
        ),
        (
            "image",
            largest_allocation_decoding_forgeries::<RosImage>(&img),
        ),
        (
            "camera info",
            largest_allocation_decoding_forgeries::<RosCameraInfo>(&info),
        ),
    ] {
        assert!(
            largest <= 1 << 20,
            "{what}: a forged length allocated {largest} B"
        );
    }
}
