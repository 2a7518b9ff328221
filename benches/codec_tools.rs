//! The coding tools added in stream version 3, on a CIF frame of the
//! synthetic sample: the deblocking filter (an intra frame: every edge
//! strength 3 or 4; an inter frame of coded blocks: strength 2 on their
//! edges) and the reference weighting of weighted prediction.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use mocomp::codec::deblock::{deblock_frame, MbEdgeInfo};
use mocomp::codec::mv::Mv;
use mocomp::codec::weight::{PlaneWeight, Weights};
use mocomp::synth::{standard_scenes, Synth};

fn tools(c: &mut Criterion) {
    let spec = standard_scenes()
        .into_iter()
        .find(|s| s.name == "synth_cif")
        .unwrap();
    let frame = Synth::new(spec).unwrap().frame(0);
    let mbs = (frame.width() / 16) * (frame.height() / 16);
    let intra = vec![
        MbEdgeInfo {
            intra: true,
            mvs: [None; 4],
            coded: 0,
            transform_8x8: false,
        };
        mbs
    ];
    // Every other 4x4 block coded, vectors alike.
    let inter = vec![
        MbEdgeInfo {
            intra: false,
            mvs: [Some(Mv::new(5, -3)); 4],
            coded: 0x5a5a,
            transform_8x8: false,
        };
        mbs
    ];
    let mut g = c.benchmark_group("codec_tools_cif");
    g.throughput(Throughput::Elements((frame.width() * frame.height()) as u64));
    for (name, info) in [("deblock_intra_qp32", &intra), ("deblock_inter_qp32", &inter)] {
        g.bench_function(name, |b| {
            b.iter_batched_ref(
                || frame.clone(),
                |f| deblock_frame(f, info, 32),
                BatchSize::LargeInput,
            )
        });
    }
    let weights = Weights([
        Some(PlaneWeight {
            scale: 72,
            offset: -6,
        }),
        None,
        None,
    ]);
    let mut out = frame.clone();
    g.bench_function("weigh_reference_luma", |b| {
        b.iter(|| weights.apply_into(&frame, &mut out))
    });
    g.finish();
}

criterion_group!(benches, tools);
criterion_main!(benches);
