//! Frame metrics on a CIF frame of the synthetic sample.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use mocomp::metrics::{frame_psnr, ssim, ssim_8x8};
use mocomp::synth::{standard_scenes, Synth};

fn metrics(c: &mut Criterion) {
    let spec = standard_scenes()
        .into_iter()
        .find(|s| s.name == "synth_cif")
        .unwrap();
    let synth = Synth::new(spec).unwrap();
    let (a, b) = (synth.frame(0), synth.frame(1));
    let mut g = c.benchmark_group("metrics_cif");
    g.throughput(Throughput::Elements((a.width() * a.height()) as u64));
    g.bench_function("psnr_yuv", |bench| bench.iter(|| frame_psnr(&a, &b)));
    g.bench_function("ssim_y", |bench| bench.iter(|| ssim(a.y(), b.y())));
    g.bench_function("ssim_8x8_y", |bench| bench.iter(|| ssim_8x8(a.y(), b.y())));
    g.finish();
    c.bench_function("synth_render_cif_frame", |bench| bench.iter(|| synth.frame(1)));
}

criterion_group!(benches, metrics);
criterion_main!(benches);
