//! Motion put to work, per stage (one thread): the bicubic warp of a VGA
//! frame, the stabiliser's path planning (Gaussian and L1) over 90 frames,
//! interpolating a CIF frame (flows, then the splat and blend alone), and
//! a CIF segmentation mask.

use criterion::{criterion_group, criterion_main, Criterion};
use mocomp::global::Transform;
use mocomp::imgproc::warp::{warp_frame, Border};
use mocomp::interpolate::{InterpolateParams, Interpolator};
use mocomp::segment::{SegmentParams, Segmenter};
use mocomp::stabilize::shake::{offsets, ShakeParams};
use mocomp::stabilize::{plan, Smoothing, StabilizeParams};
use mocomp::synth::{Motion, SceneSpec, Shape, Synth};

fn scene(w: usize, h: usize, frames: usize) -> Synth {
    Synth::new(
        SceneSpec::new("apps", w, h, frames)
            .seed(9)
            .camera(Motion::translation(2.5, -1.0))
            .object(
                Shape::Ellipse { rx: 30.0, ry: 22.0 },
                (120.0, 90.0),
                Motion::translation(-3.0, 2.0),
            ),
    )
    .unwrap()
}

fn apps(c: &mut Criterion) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let vga = scene(640, 480, 1).frame(0);
    let (s, co) = (0.02f64.sin(), 0.02f64.cos());
    let turn = [co, -s, 6.0, s, co, -4.0, 0.0, 0.0, 1.0];
    c.bench_function("apps/warp_vga_bicubic", |b| {
        b.iter(|| pool.install(|| warp_frame(&vga, 640, 480, &turn, Border::Replicate)))
    });
    // A shaky still camera: the motions between the shake's offsets.
    let poses = offsets(90, &ShakeParams::default());
    let motions: Vec<Option<Transform>> = (1..90)
        .map(|t| {
            Some(
                poses[t - 1]
                    .transform()
                    .inverse()
                    .unwrap()
                    .then_after(&poses[t].transform()),
            )
        })
        .collect();
    for (name, smoothing) in [("gaussian", Smoothing::Gaussian(10)), ("l1", Smoothing::L1)] {
        let params = StabilizeParams {
            smoothing,
            ..StabilizeParams::default()
        };
        c.bench_function(&format!("apps/stabilize_plan_90_{name}"), |b| {
            b.iter(|| plan(&motions, 640, 480, &params).unwrap())
        });
    }
    let cif = scene(352, 288, 3);
    let (f0, f2) = (cif.frame(0), cif.frame(2));
    let mut interp = Interpolator::new(&InterpolateParams::default()).unwrap();
    c.bench_function("apps/interpolate_cif_flows", |b| {
        b.iter(|| pool.install(|| interp.pair(&f0, &f2)))
    });
    let pair = interp.pair(&f0, &f2);
    c.bench_function("apps/interpolate_cif_blend", |b| {
        b.iter(|| pool.install(|| interp.at(&pair, &f0, &f2, 0.5)))
    });
    let mut seg = Segmenter::new(&SegmentParams::default()).unwrap();
    let f1 = cif.frame(1);
    c.bench_function("apps/segment_cif_mask", |b| {
        b.iter(|| pool.install(|| seg.mask(&f1, &[&f0, &f2])))
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = apps
}
criterion_main!(benches);
