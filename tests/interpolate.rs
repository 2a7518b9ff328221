//! Frame interpolation against middle frames known independently of the
//! interpolator: synthetic scenes rendered at times 0, 1 and 2 (a panning
//! camera, an object moving against it), rebuilding frame 1 from 0 and 2.

use mocomp::codec::Frame;
use mocomp::interpolate::{InterpolateParams, Interpolator};
use mocomp::metrics::{mse, psnr_from_mse};
use mocomp::synth::{Motion, SceneSpec, Shape, Synth};

fn scene(camera: (f64, f64), object: (f64, f64), seed: u64) -> Synth {
    Synth::new(
        SceneSpec::new("mid", 192, 144, 3)
            .seed(seed)
            .camera(Motion::translation(camera.0, camera.1))
            .object(
                Shape::Ellipse { rx: 24.0, ry: 18.0 },
                (80.0, 70.0),
                Motion::translation(object.0, object.1),
            ),
    )
    .unwrap()
}

fn psnr_y(a: &Frame, b: &Frame) -> f64 {
    psnr_from_mse(mse(a.y(), b.y()))
}

/// The plain average of two frames (what interpolation without motion gives).
fn average(a: &Frame, b: &Frame) -> Frame {
    let mean = |p: &mocomp::codec::Plane, q: &mocomp::codec::Plane| {
        mocomp::codec::Plane::from_fn(p.width(), p.height(), |x, y| {
            (u16::from(p.get(x, y)) + u16::from(q.get(x, y))).div_ceil(2) as u8
        })
        .unwrap()
    };
    Frame::from_planes(mean(a.y(), b.y()), mean(a.u(), b.u()), mean(a.v(), b.v())).unwrap()
}

#[test]
fn the_middle_frame_of_a_pan_with_a_moving_object_is_rebuilt() {
    for (camera, object, seed) in [
        ((3.0, 1.5), (-4.0, 2.0), 1),
        ((-5.0, 0.0), (3.0, -3.0), 2),
        ((2.0, -2.0), (0.0, 0.0), 3),
    ] {
        let s = scene(camera, object, seed);
        let (f0, f1, f2) = (s.frame(0), s.frame(1), s.frame(2));
        let mut interp = Interpolator::new(&InterpolateParams::default()).unwrap();
        let pair = interp.pair(&f0, &f2);
        assert!(!pair.cut, "{camera:?}: consistent {}", pair.consistent);
        let made = interp.at(&pair, &f0, &f2, 0.5);
        let (ours, plain) = (psnr_y(&f1, &made), psnr_y(&f1, &average(&f0, &f2)));
        eprintln!("{camera:?} {object:?}: {ours:.2} dB, average {plain:.2} dB");
        assert!(
            ours > 36.0 && ours > plain + 10.0,
            "{camera:?} {object:?}: {ours:.2} dB, average {plain:.2} dB"
        );
        // Chroma follows the same motion.
        let chroma = psnr_from_mse(mse(f1.u(), made.u()));
        assert!(chroma > 30.0, "chroma {chroma:.2} dB");
    }
}

#[test]
fn the_ends_are_the_frames_and_a_still_pair_stays_still() {
    let s = scene((3.0, 0.0), (0.0, 2.0), 4);
    let (f0, f2) = (s.frame(0), s.frame(2));
    let mut interp = Interpolator::new(&InterpolateParams::default()).unwrap();
    let pair = interp.pair(&f0, &f2);
    assert_eq!(interp.at(&pair, &f0, &f2, 0.0), f0);
    assert_eq!(interp.at(&pair, &f0, &f2, 1.0), f2);
    let still = interp.pair(&f0, &f0);
    assert!(psnr_y(&f0, &interp.at(&still, &f0, &f0, 0.3)) > 50.0);
}

#[test]
fn a_cut_repeats_the_earlier_frame() {
    let (a, b) = (
        scene((0.0, 0.0), (0.0, 0.0), 5).frame(0),
        scene((0.0, 0.0), (0.0, 0.0), 6).frame(0),
    );
    let mut interp = Interpolator::new(&InterpolateParams::default()).unwrap();
    let pair = interp.pair(&a, &b);
    assert!(pair.cut, "consistent {}", pair.consistent);
    assert_eq!(interp.at(&pair, &a, &b, 0.5), a);
    assert_eq!(interp.at(&pair, &a, &b, 0.75), b);
    assert!(Interpolator::new(&InterpolateParams {
        cut_below: 1.5,
        ..InterpolateParams::default()
    })
    .is_err());
}

/// A camera shaking along a sinusoid, frames 0 to 9; its speed changes
/// fastest at frame 6.
fn shaken(seed: u64) -> Synth {
    Synth::new(
        SceneSpec::new("shake", 192, 144, 10)
            .seed(seed)
            .camera(Motion::translation(1.0, 0.5).with_wobble((3.0, 2.0), 12.0)),
    )
    .unwrap()
}

/// PSNR-Y of frame `k` rebuilt from `k - 1` and `k + 1` along straight
/// paths, then along paths bent by the kept frames either side (`k - 3`,
/// `k + 3`), as interpolating every other frame does.
fn straight_and_curved(f: &[Frame], k: usize) -> (f64, f64) {
    let mut interp = Interpolator::new(&InterpolateParams::default()).unwrap();
    let (before, after) = (
        interp.pair(&f[k - 3], &f[k - 1]),
        interp.pair(&f[k + 1], &f[k + 3]),
    );
    let mut pair = interp.pair(&f[k - 1], &f[k + 1]);
    let straight = psnr_y(&f[k], &interp.at(&pair, &f[k - 1], &f[k + 1], 0.5));
    pair.accelerate(Some(&before), Some(&after));
    let curved = psnr_y(&f[k], &interp.at(&pair, &f[k - 1], &f[k + 1], 0.5));
    (straight, curved)
}

#[test]
fn a_shaking_camera_is_followed_along_a_curve_through_the_frames_either_side() {
    for seed in [7, 8] {
        let s = shaken(seed);
        let f: Vec<Frame> = (0..10).map(|t| s.frame(t)).collect();
        let (straight, curved) = straight_and_curved(&f, 6);
        eprintln!("seed {seed}: straight {straight:.2} dB, curved {curved:.2} dB");
        assert!(
            curved > 42.0 && curved > straight + 5.0,
            "straight {straight:.2} dB, curved {curved:.2} dB"
        );
    }
}

#[test]
fn a_steady_pan_with_sensor_noise_is_not_bent() {
    let s = scene((3.0, 1.5), (-4.0, 2.0), 9);
    let mut spec = s.spec().clone().noise(3.0);
    spec.frames = 7;
    let s = Synth::new(spec).unwrap();
    let f: Vec<Frame> = (0..7).map(|t| s.frame(t)).collect();
    let (straight, curved) = straight_and_curved(&f, 3);
    eprintln!("steady: straight {straight:.3} dB, curved {curved:.3} dB");
    assert!(
        curved > straight - 0.05,
        "straight {straight:.2} dB, curved {curved:.2} dB"
    );
}
