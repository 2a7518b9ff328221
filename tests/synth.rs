//! The generator's ground truth against its own rendering: warping a frame
//! by the true flow reproduces its neighbour on valid pixels, to within
//! interpolation error; integer translations reproduce it exactly; occluded
//! pixels are marked; output is deterministic; the committed samples are
//! what the generator makes.

use mocomp::codec::Frame;
use mocomp::flow::{warp::warp_bilinear, Flow};
use mocomp::io::{flo, y4m::Y4mReader};
use mocomp::raster::plane_to_array;
use mocomp::synth::{forward_flow_name, standard_scenes, Motion, SceneSpec, Shape, Synth};
use ndarray::Array2;

/// Mean absolute difference of `a` and `b` over the valid pixels of `flow`.
fn valid_mad(a: &Array2<f32>, b: &Array2<f32>, flow: &Flow) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for ((idx, &x), &y) in a.indexed_iter().zip(b.iter()) {
        if flow.valid()[idx] {
            sum += (f64::from(x) - f64::from(y)).abs();
            n += 1;
        }
    }
    sum / n as f64
}

fn clean(spec: SceneSpec) -> SceneSpec {
    SceneSpec {
        noise_sigma: 0.0,
        brightness_step: 0.0,
        ..spec
    }
}

fn shifted(flow: &Flow, du: f32) -> Flow {
    let (u, v, valid) = flow.clone().into_parts();
    Flow::from_parts(u + du, v, valid)
}

#[test]
fn warping_by_the_true_flow_reproduces_the_neighbour_frame() {
    for spec in standard_scenes() {
        let synth = Synth::new(clean(spec.clone())).unwrap();
        let frames: Vec<Array2<f32>> = (0..spec.frames)
            .map(|t| plane_to_array(synth.frame(t).y()))
            .collect();
        for t in 0..spec.frames - 1 {
            let fwd = synth.forward_flow(t);
            let bwd = synth.backward_flow(t + 1);
            let err_fwd = valid_mad(&frames[t], &warp_bilinear(&frames[t + 1], &fwd), &fwd);
            let err_bwd = valid_mad(&frames[t + 1], &warp_bilinear(&frames[t], &bwd), &bwd);
            // A flow off by a quarter pixel must do clearly worse, or this test could not fail.
            let err_off = valid_mad(
                &frames[t],
                &warp_bilinear(&frames[t + 1], &shifted(&fwd, 0.25)),
                &fwd,
            );
            // Measured: 0.46-0.55 levels (8-bit rounding of both frames plus
            // bilinear interpolation), 0.83-0.89 with the quarter-pel error.
            assert!(
                err_fwd < 0.65 && err_bwd < 0.65,
                "{} {t}: {err_fwd} {err_bwd}",
                spec.name
            );
            assert!(
                err_off > 1.4 * err_fwd,
                "{} {t}: {err_off} vs {err_fwd}",
                spec.name
            );
            // Occlusions and exits exist in these scenes, but most pixels are valid.
            let share = fwd.valid_count() as f64 / (spec.width * spec.height) as f64;
            assert!(share > 0.9 && share < 1.0, "{share}");
        }
    }
}

#[test]
fn integer_translation_reproduces_pixels_exactly() {
    let (dx, dy) = (4i64, -2i64);
    let synth =
        Synth::new(SceneSpec::new("shift", 40, 32, 3).camera(Motion::translation(dx as f64, dy as f64)))
            .unwrap();
    for t in 0..2 {
        let (a, b) = (synth.frame(t), synth.frame(t + 1));
        let flow = synth.forward_flow(t);
        let mut compared = 0;
        for (p, s) in [(0usize, 1i64), (1, 2), (2, 2)] {
            let (pa, pb) = (a.plane(p), b.plane(p));
            for y in 0..pa.height() as i64 {
                for x in 0..pa.width() as i64 {
                    let (x2, y2) = (x + dx / s, y + dy / s);
                    if x2 >= 0 && y2 >= 0 && x2 < pa.width() as i64 && y2 < pa.height() as i64 {
                        assert_eq!(pa.get(x as usize, y as usize), pb.get(x2 as usize, y2 as usize));
                        compared += 1;
                    }
                }
            }
        }
        assert!(compared > 1000);
        for y in 0..32 {
            for x in 0..40 {
                let inside = x as i64 + dx <= 39 && y as i64 + dy >= 0;
                assert_eq!(flow.is_valid(x, y), inside, "({x}, {y})");
                if inside {
                    assert_eq!(flow.get(x, y), (dx as f32, dy as f32));
                }
            }
        }
    }
}

#[test]
fn occluded_and_uncovered_pixels_are_invalid() {
    // A still background; a 20x12 rectangle centred at (30, 24) moving right 3 px a frame.
    let spec = SceneSpec::new("occlusion", 64, 48, 2).object(
        Shape::Rect { hw: 10.0, hh: 6.0 },
        (30.0, 24.0),
        Motion::translation(3.0, 0.0),
    );
    let synth = Synth::new(spec).unwrap();
    let fwd = synth.forward_flow(0);
    let bwd = synth.backward_flow(1);
    // The object's interior moves with it.
    assert!(fwd.is_valid(30, 24) && fwd.get(30, 24) == (3.0, 0.0));
    assert!(bwd.is_valid(33, 24) && bwd.get(33, 24) == (-3.0, 0.0));
    // Background just right of the object (x 41..43) is covered in frame 1.
    for x in 41..=43 {
        assert!(
            !fwd.is_valid(x, 24),
            "covered background at x={x} should be invalid"
        );
    }
    // Background just left of the object in frame 1 (x 21..23) was hidden in frame 0.
    for x in 21..=23 {
        assert!(
            !bwd.is_valid(x, 24),
            "uncovered background at x={x} should be invalid"
        );
    }
    // Background far away is valid and still.
    assert!(fwd.is_valid(5, 5) && fwd.get(5, 5) == (0.0, 0.0));
    assert!(bwd.is_valid(60, 40) && bwd.get(60, 40) == (0.0, 0.0));
}

#[test]
fn noise_and_brightness_have_the_requested_size() {
    let base = SceneSpec::new("n", 96, 80, 3).camera(Motion::translation(1.0, 0.5));
    let clean = Synth::new(base.clone()).unwrap();
    let noisy = Synth::new(base.noise(2.0).brightness(1.5)).unwrap();
    let t = 2;
    let (a, b) = (clean.frame(t), noisy.frame(t));
    let d: Vec<f64> = a
        .y()
        .rows()
        .zip(b.y().rows())
        .flat_map(|(ra, rb)| {
            ra.iter()
                .zip(rb)
                .map(|(&x, &y)| y as f64 - x as f64)
                .collect::<Vec<_>>()
        })
        .collect();
    let mean = d.iter().sum::<f64>() / d.len() as f64;
    let sd = (d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / d.len() as f64).sqrt();
    assert!((mean - 1.5 * t as f64).abs() < 0.1, "brightness offset {mean}");
    // Rounding adds about 1/12 to the variance of the difference of two roundings.
    assert!((sd - (4.0f64 + 1.0 / 6.0).sqrt()).abs() < 0.1, "noise sd {sd}");
}

#[test]
fn rendering_is_deterministic_and_thread_independent() {
    let spec = standard_scenes().remove(0);
    let render = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let s = Synth::new(spec.clone()).unwrap();
            (s.frame(3), s.forward_flow(3), s.backward_flow(3))
        })
    };
    let one = render(1);
    assert_eq!(one, render(4));
    assert_eq!(one, render(1));
}

#[test]
fn committed_samples_are_what_the_generator_makes() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("samples");
    for spec in standard_scenes() {
        let synth = Synth::new(spec.clone()).unwrap();
        let reader = Y4mReader::open(&dir.join(format!("{}.y4m", spec.name))).unwrap();
        assert_eq!(reader.info(), &synth.y4m_info());
        let frames: Vec<Frame> = reader.read_all().unwrap();
        assert_eq!(frames.len(), spec.frames);
        for (t, f) in frames.iter().enumerate() {
            assert!(
                *f == synth.frame(t),
                "{} frame {t} differs from the generator",
                spec.name
            );
        }
        // Flows are committed for the QCIF sample (see samples/README.md).
        let flow_dir = dir.join(&spec.name);
        for t in 0..spec.frames - 1 {
            let path = flow_dir.join(forward_flow_name(t));
            if path.exists() {
                assert_eq!(
                    flo::read_flo(&path).unwrap(),
                    synth.forward_flow(t),
                    "{}",
                    path.display()
                );
            }
        }
    }
    assert!(dir.join("synth_qcif").join(forward_flow_name(8)).exists());
}
