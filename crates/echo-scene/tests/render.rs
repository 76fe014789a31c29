//! The GIF of a small recording: it decodes, has the expected frames, and the person and the
//! robot are where the projection puts them.

mod common;

use common::*;
use echo_scene::render::{frame_count, Projector};
use echo_scene::{render_recording, RenderOptions};
use image::AnimationDecoder;

fn decode(path: &std::path::Path) -> Vec<image::RgbaImage> {
    let file = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    image::codecs::gif::GifDecoder::new(file)
        .unwrap()
        .into_frames()
        .collect_frames()
        .unwrap()
        .into_iter()
        .map(|f| f.into_buffer())
        .collect()
}

fn at(img: &image::RgbaImage, p: (f64, f64, f64)) -> [i32; 3] {
    let px = img.get_pixel(p.0 as u32, p.1 as u32).0;
    [px[0] as i32, px[1] as i32, px[2] as i32]
}

fn blue(c: [i32; 3]) -> bool {
    c[2] > c[0] + 60
}

#[test]
fn the_gif_shows_the_person_walking_up_and_the_robot() {
    let dir = tempfile::tempdir().unwrap();
    let (mcap, gif) = (dir.path().join("walk.mcap"), dir.path().join("walk.gif"));
    write_walk_recording(&mcap);
    let opts = RenderOptions {
        fps: 10.0,
        width: 320,
        ..RenderOptions::default()
    };
    let summary = render_recording(&mcap, &gif, &opts).unwrap();
    assert_eq!(summary.frames, 31);
    assert_eq!(frame_count(3_000_000_000, 10.0), 31);
    assert_eq!((summary.width, summary.height), (320, 240));
    assert!((summary.duration_s - 3.1).abs() < 1e-9);
    assert!((summary.recording_s - 3.0).abs() < 1e-9);
    assert_eq!(summary.rejected, 1, "the malformed message is counted");

    let frames = decode(&gif);
    assert_eq!(frames.len(), 31);
    assert!(frames.iter().all(|f| f.dimensions() == (320, 240)));

    let proj = Projector::new(&opts.camera, 320, 240);
    // The partner's torso (between spine1 and spine2) at the first and the last frame.
    let torso = |x: f64| {
        let j = person(x, 0.0);
        let mid = [
            (j[3][0] + j[6][0]) / 2.0,
            (j[3][1] + j[6][1]) / 2.0,
            (j[3][2] + j[6][2]) / 2.0,
        ];
        proj.project(mid).unwrap()
    };
    let (start, end) = (torso(walk_x(0.0)), torso(walk_x(3.0)));
    assert!(
        start.0 - end.0 > 20.0,
        "the walk spans pixels: {start:?} → {end:?}"
    );
    let (first, last) = (&frames[0], &frames[30]);
    assert!(
        blue(at(first, start)),
        "partner at the start: {:?}",
        at(first, start)
    );
    assert!(
        !blue(at(first, end)),
        "nobody there yet: {:?}",
        at(first, end)
    );
    assert!(
        blue(at(last, end)),
        "partner at the end: {:?}",
        at(last, end)
    );
    assert!(
        !blue(at(last, start)),
        "the partner left: {:?}",
        at(last, start)
    );
    // Halfway through, the partner is halfway.
    let mid = torso(walk_x(1.5));
    assert!(blue(at(&frames[15], mid)));

    // The robot's base (dark grey) at the origin, the same in every frame.
    let base = proj.project([0.0, 0.0, 0.2]).unwrap();
    for f in [first, last] {
        let c = at(f, base);
        assert!(c[0] < 140 && (c[0] - c[2]).abs() < 30, "base: {c:?}");
    }
    // Empty space above the partner's head is background.
    let sky = proj.project([walk_x(3.0), 0.0, 2.4]).unwrap();
    let c = at(last, sky);
    assert!(c.iter().all(|v| *v > 225), "background: {c:?}");
}

#[test]
fn bad_inputs_are_named_errors() {
    let dir = tempfile::tempdir().unwrap();
    let gif = dir.path().join("x.gif");
    let missing = dir.path().join("missing.mcap");
    let e = render_recording(&missing, &gif, &RenderOptions::default()).unwrap_err();
    assert!(e.to_string().contains("missing.mcap"), "{e}");
    let mcap = dir.path().join("walk.mcap");
    write_walk_recording(&mcap);
    for (opts, word) in [
        (
            RenderOptions {
                fps: 0.0,
                ..Default::default()
            },
            "fps",
        ),
        (
            RenderOptions {
                fps: 60.0,
                ..Default::default()
            },
            "fps",
        ),
        (
            RenderOptions {
                width: 5,
                ..Default::default()
            },
            "width",
        ),
        (
            RenderOptions {
                max_frames: 10,
                ..Default::default()
            },
            "limit",
        ),
    ] {
        let e = render_recording(&mcap, &gif, &opts)
            .unwrap_err()
            .to_string();
        assert!(e.contains(word), "{e}");
    }
}
