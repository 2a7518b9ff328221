//! Moving-object segmentation against masks known independently of the
//! segmenter: synthetic scenes whose camera pans (and zooms) while an
//! object moves against it; the truth is where the scene's exact flow
//! departs from the camera's.

use mocomp::codec::{Frame, Plane};
use mocomp::segment::{iou, neighbours, SegmentParams, Segmenter};
use mocomp::synth::{Motion, SceneSpec, Shape, Synth};

/// Frames and true masks of a scene with `camera` and one object.
fn scene(camera: Motion, object: Motion, shape: Shape, seed: u64) -> (Vec<Frame>, Vec<Plane>) {
    let (w, h, n) = (192, 144, 6);
    let s = Synth::new(SceneSpec::new("seg", w, h, n).seed(seed).camera(camera).object(
        shape,
        (90.0, 70.0),
        object,
    ))
    .unwrap();
    let frames: Vec<Frame> = (0..n).map(|t| s.frame(t)).collect();
    let still = Synth::new(SceneSpec::new("cam", w, h, n).seed(seed).camera(camera)).unwrap();
    let masks = (0..n)
        .map(|t| {
            let (a, b) = if t + 1 < n {
                (s.forward_flow(t), still.forward_flow(t))
            } else {
                (s.backward_flow(t), still.backward_flow(t))
            };
            Plane::from_fn(w, h, |x, y| {
                let ((u, v), (cu, cv)) = (a.get(x, y), b.get(x, y));
                if (u - cu).hypot(v - cv) > 0.5 {
                    255
                } else {
                    0
                }
            })
            .unwrap()
        })
        .collect();
    (frames, masks)
}

fn mean_iou(frames: &[Frame], masks: &[Plane]) -> f64 {
    mean_iou_with(frames, masks, &SegmentParams::default())
}

fn mean_iou_with(frames: &[Frame], masks: &[Plane], params: &SegmentParams) -> f64 {
    let mut seg = Segmenter::new(params).unwrap();
    let scores: Vec<f64> = (0..frames.len())
        .map(|t| iou(&seg.mask(&frames[t], &neighbours(frames, t)), &masks[t]))
        .collect();
    eprintln!("{scores:?}");
    scores.iter().sum::<f64>() / scores.len() as f64
}

#[test]
fn an_object_moving_against_a_panning_camera_is_found() {
    let cases = [
        (
            Motion::translation(3.0, 1.0),
            Motion::translation(-3.0, 2.0),
            Shape::Ellipse { rx: 26.0, ry: 20.0 },
            1,
        ),
        (
            Motion::translation(-2.0, 0.0).with_zoom(1.01),
            Motion::translation(4.0, -1.0),
            Shape::Ellipse { rx: 30.0, ry: 16.0 },
            2,
        ),
        (
            Motion::translation(0.0, 2.5),
            Motion::translation(2.0, -2.0),
            Shape::Ellipse { rx: 20.0, ry: 20.0 },
            3,
        ),
    ];
    for (camera, object, shape, seed) in cases {
        let (frames, masks) = scene(camera, object, shape, seed);
        let covered: usize = masks[2]
            .rows()
            .map(|r| r.iter().filter(|&&v| v > 0).count())
            .sum();
        assert!(covered > 600, "the object covers {covered} pixels");
        let m = mean_iou(&frames, &masks);
        assert!(m >= 0.85, "seed {seed}: mean IoU {m:.3}");
    }
}

#[test]
fn a_scene_moving_only_with_the_camera_has_empty_masks() {
    // The object moves exactly as the camera pans: nothing moves against it.
    let (frames, _) = scene(
        Motion::translation(3.0, -2.0),
        Motion::translation(3.0, -2.0),
        Shape::Ellipse { rx: 24.0, ry: 18.0 },
        4,
    );
    let mut seg = Segmenter::new(&SegmentParams::default()).unwrap();
    for t in 0..frames.len() - 1 {
        let mask = seg.mask(&frames[t], &[&frames[t + 1]]);
        let set: usize = mask.rows().map(|r| r.iter().filter(|&&v| v > 0).count()).sum();
        assert!(set < 192 * 144 / 100, "frame {t}: {set} pixels marked");
    }
}

#[test]
fn flows_kept_from_the_frame_before_give_the_masks_of_fresh_ones() {
    // Frame t's flows with t + 1 are frame t + 1's with t, kept from one
    // call to the next: the masks must be those of a segmenter that
    // computes every flow.
    let (frames, _) = scene(
        Motion::translation(1.5, -0.75),
        Motion::translation(-2.0, 1.0),
        Shape::Ellipse { rx: 22.0, ry: 16.0 },
        3,
    );
    let near = |t: usize| neighbours(&frames, t);
    let mut kept = Segmenter::new(&SegmentParams::default()).unwrap();
    for (t, frame) in frames.iter().enumerate() {
        let mut fresh = Segmenter::new(&SegmentParams::default()).unwrap();
        assert!(
            kept.mask(frame, &near(t)) == fresh.mask(frame, &near(t)),
            "frame {t}"
        );
    }
}

/// A textured disc moving over a flat wall that fills the middle of a
/// textured, panning scene (a person before a white door): the flow
/// spreads the disc's motion over the flat wall around it, and the rest
/// of the wall must outvote it.
fn disc_before_a_flat_wall() -> (Vec<Frame>, Vec<Plane>) {
    let (w, h, n) = (192usize, 144usize, 6usize);
    let hash = |x: i64, y: i64| {
        let v = (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663)) as u64;
        (v.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 58) as i64
    };
    // Texture: 8x8 cells of random grey (64 levels), in scene coordinates.
    let texture = |x: i64, y: i64| 60 + 2 * hash(x.div_euclid(8), y.div_euclid(8));
    let (r, mut frames, mut masks) = (18i64, Vec::new(), Vec::new());
    for t in 0..n as i64 {
        let (cx, cy) = (70 + 3 * t, 72 - t);
        let luma = Plane::from_fn(w, h, |x, y| {
            let (x, y) = (x as i64, y as i64);
            let (dx, dy) = (x - cx, y - cy);
            let v = if dx * dx + dy * dy <= r * r {
                // The disc's own texture moves with it.
                150 + texture(dx + 40, dy + 40) / 2
            } else if (36..156).contains(&(x + t)) && (24..120).contains(&(y + t)) {
                // The wall pans with the rest of the scene.
                200
            } else {
                // The camera pans 1 px right and 1 px down a frame.
                texture(x + t, y + t)
            };
            v as u8
        })
        .unwrap();
        let (cw, ch) = Frame::chroma_size(w, h);
        let grey = || Plane::from_fn(cw, ch, |_, _| 128).unwrap();
        frames.push(Frame::from_planes(luma, grey(), grey()).unwrap());
        masks.push(
            Plane::from_fn(w, h, |x, y| {
                let (dx, dy) = (x as i64 - cx, y as i64 - cy);
                if dx * dx + dy * dy <= r * r {
                    255
                } else {
                    0
                }
            })
            .unwrap(),
        );
    }
    (frames, masks)
}

#[test]
fn a_flat_wall_beside_a_moving_object_is_not_marked() {
    let (frames, masks) = disc_before_a_flat_wall();
    let regions = mean_iou(&frames, &masks);
    let plain = mean_iou_with(
        &frames,
        &masks,
        &SegmentParams {
            region_reach: 0.0,
            ..SegmentParams::default()
        },
    );
    eprintln!("flat wall: mean IoU {regions:.3}, without the regions' vote {plain:.3}");
    assert!(regions >= 0.78, "mean IoU {regions:.3}");
    assert!(
        regions > plain + 0.3,
        "{regions:.3} against {plain:.3} without the vote"
    );
}

/// Every frame's mask from [`Segmenter::masks`] (consistent in time).
fn masks_in_time(frames: &[Frame]) -> Vec<Plane> {
    let mut seg = Segmenter::new(&SegmentParams::default()).unwrap();
    let mut out = Vec::new();
    seg.masks(frames, |t, m| -> Result<(), ()> {
        assert_eq!(t, out.len(), "masks come in order");
        out.push(m);
        Ok(())
    })
    .unwrap();
    out
}

#[test]
fn masks_in_time_find_the_object_as_frame_by_frame_masks_do() {
    // On clean scenes the temporal median changes little: the same bar as
    // the frame-by-frame masks, every frame given once, in order.
    let (frames, masks) = scene(
        Motion::translation(3.0, 1.0),
        Motion::translation(-3.0, 2.0),
        Shape::Ellipse { rx: 26.0, ry: 20.0 },
        1,
    );
    let timed = masks_in_time(&frames);
    assert_eq!(timed.len(), frames.len());
    let scores: Vec<f64> = timed.iter().zip(&masks).map(|(a, b)| iou(a, b)).collect();
    let m = scores.iter().sum::<f64>() / scores.len() as f64;
    assert!(m >= 0.85, "mean IoU {m:.3} ({scores:?})");
}
