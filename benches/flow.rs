//! Dense flow per method and preset on a CIF and a 720p pair (one thread),
//! the refinement, feature matching, and the sparse tracker.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use mocomp::features::{match_pictures, MatchParams};
use mocomp::flow::dis::{Dis, DisParams, DisPreset};
use mocomp::flow::hs::{horn_schunck, HsParams};
use mocomp::flow::lk::{dense_lk, LkParams};
use mocomp::flow::refine::{refine, RefineParams, Refiner};
use mocomp::flow::track::{good_features, track, TrackParams};
use mocomp::flow::tvl1::{tvl1, Tvl1Params};
use mocomp::raster::plane_to_array;
use mocomp::synth::{Motion, SceneSpec, Synth};
use ndarray::Array2;

fn pair(w: usize, h: usize) -> (Array2<f32>, Array2<f32>) {
    let motion = Motion::translation(1.8, -1.0).with_zoom(1.012).with_rotation(0.8);
    let s = Synth::new(SceneSpec::new("bench", w, h, 2).seed(5).camera(motion).noise(1.0)).unwrap();
    (plane_to_array(s.frame(0).y()), plane_to_array(s.frame(1).y()))
}

fn flow(c: &mut Criterion) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let lk = [
        (
            "lk_fast",
            LkParams {
                sigma: 2.5,
                finest: 2,
                ..LkParams::default()
            },
        ),
        ("lk_medium", LkParams::default()),
        (
            "lk_accurate",
            LkParams {
                sigma: 5.0,
                levels: 5,
                ..LkParams::default()
            },
        ),
    ];
    for (name, w, h) in [("cif", 352, 288), ("720p", 1280, 720)] {
        let (a, b) = pair(w, h);
        let mut g = c.benchmark_group(format!("flow_{name}"));
        g.sample_size(10);
        for (label, p) in lk {
            g.bench_function(BenchmarkId::new(label, name), |bench| {
                bench.iter(|| pool.install(|| dense_lk(&a, &b, &p)))
            });
        }
        for (label, preset) in [
            ("dis_ultrafast", DisPreset::Ultrafast),
            ("dis_fast", DisPreset::Fast),
            ("dis_medium", DisPreset::Medium),
            ("dis_accurate", DisPreset::Accurate),
        ] {
            let mut dis = Dis::new(DisParams::preset(preset));
            g.bench_function(BenchmarkId::new(label, name), |bench| {
                bench.iter(|| pool.install(|| dis.compute(&a, &b)))
            });
        }
        // One variational refinement (5 x 5 SOR) at half size, as DIS medium
        // runs it at its finest level.
        let (ha, hb) = (
            mocomp::flow::pyramid::downsample(&a),
            mocomp::flow::pyramid::downsample(&b),
        );
        g.bench_function(BenchmarkId::new("refine_half", name), |bench| {
            bench.iter(|| {
                let (mut u, mut v) = (Array2::zeros(ha.dim()), Array2::zeros(ha.dim()));
                pool.install(|| refine(&ha, &hb, &mut u, &mut v, &RefineParams::default()));
                u
            })
        });
        // The refinement with its buffers kept (as DIS runs it per level).
        let mut refiner = Refiner::default();
        g.bench_function(BenchmarkId::new("refine_half_kept", name), |bench| {
            bench.iter(|| {
                let (mut u, mut v) = (Array2::zeros(ha.dim()), Array2::zeros(ha.dim()));
                pool.install(|| refiner.refine(&ha, &hb, &mut u, &mut v, &RefineParams::default()));
                u
            })
        });
        g.bench_function(BenchmarkId::new("match", name), |bench| {
            bench.iter(|| pool.install(|| match_pictures(&a, &b, &MatchParams::default())))
        });
        g.bench_function(BenchmarkId::new("tvl1_medium", name), |bench| {
            bench.iter(|| pool.install(|| tvl1(&a, &b, &Tvl1Params::default())))
        });
        g.bench_function(BenchmarkId::new("hs_medium", name), |bench| {
            bench.iter(|| pool.install(|| horn_schunck(&a, &b, &HsParams::default())))
        });
        let points = good_features(&a, 300, 0.01, 8.0);
        g.bench_function(BenchmarkId::new("track_300", name), |bench| {
            bench.iter(|| pool.install(|| track(&a, &b, &points, &TrackParams::default())))
        });
        g.finish();
    }
}

criterion_group!(benches, flow);
criterion_main!(benches);
