//! Block matching: the cost kernels per block size and kernel set, and each
//! method on a CIF and a 720p frame at range 7 and 16 (one thread), and
//! esa without successive elimination.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use mocomp::codec::cpu;
use mocomp::codec::Plane;
use mocomp::me::cost::ssd;
use mocomp::me::dsp::PIXEL;
use mocomp::me::{estimate, MeConfig, Method};
use mocomp::synth::{Motion, SceneSpec, Synth};

fn noise(n: usize, seed: u64) -> Vec<u8> {
    let mut s = seed | 1;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s as u8
        })
        .collect()
}

fn kernels(c: &mut Criterion) {
    // Cache-resident: two 64-stride buffers of 64 rows, 8 KiB in all.
    let (a, b) = (noise(64 * 64, 1), noise(64 * 64, 2));
    for size in [4usize, 8, 16, 32] {
        let mut g = c.benchmark_group(format!("cost_{size}x{size}"));
        g.throughput(Throughput::Elements((size * size) as u64));
        for level in cpu::available() {
            let k = PIXEL.at(level);
            for (name, kernel) in [("sad", k.sad), ("satd", k.satd)] {
                g.bench_function(BenchmarkId::new(name, level.name()), |bench| {
                    bench.iter(|| {
                        kernel(
                            std::hint::black_box(&a[1..]),
                            64,
                            std::hint::black_box(&b[3..]),
                            64,
                            size,
                            size,
                        )
                    })
                });
            }
        }
        g.bench_function("ssd/scalar", |bench| {
            bench.iter(|| ssd(std::hint::black_box(&a), 64, &b, 64, size, size))
        });
        g.finish();
    }
}

fn frames(w: usize, h: usize) -> (Plane, Plane) {
    let s = Synth::new(
        SceneSpec::new("bench", w, h, 2)
            .seed(3)
            .camera(Motion::translation(2.5, -1.25).with_zoom(1.01))
            .noise(1.0),
    )
    .unwrap();
    (s.frame(1).y().clone(), s.frame(0).y().clone())
}

fn methods(c: &mut Criterion) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    for (name, w, h) in [("cif", 352, 288), ("720p", 1280, 720)] {
        let (cur, reference) = frames(w, h);
        let mut g = c.benchmark_group(format!("me_{name}"));
        g.sample_size(10);
        for method in Method::ALL {
            for range in [7, 16] {
                let cfg = MeConfig::new(method, 16, range);
                g.bench_function(BenchmarkId::new(method.name(), range), |bench| {
                    bench.iter(|| pool.install(|| estimate(&cur, &reference, &cfg).unwrap()))
                });
            }
        }
        // What successive elimination saves: esa evaluating every position.
        for range in [7, 16] {
            let cfg = MeConfig {
                successive_elimination: false,
                ..MeConfig::new(Method::Esa, 16, range)
            };
            g.bench_function(BenchmarkId::new("esa_every_position", range), |bench| {
                bench.iter(|| pool.install(|| estimate(&cur, &reference, &cfg).unwrap()))
            });
        }
        g.finish();
    }
}

criterion_group!(benches, kernels, methods);
criterion_main!(benches);
