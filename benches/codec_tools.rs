//! The coding tools added in stream version 3, on a CIF frame of the
//! synthetic sample: the deblocking filter (an intra frame: every edge
//! strength 3 or 4; an inter frame of coded blocks: strength 2 on their
//! edges) and the reference weighting of weighted prediction (and the
//! encoder's guess of the weights); and the
//! nine 8x8 intra modes as the encoder's search makes them. The kernels
//! under them, one by one at every CPU level, are in `benches/dsp.rs`.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use mocomp::codec::deblock::{deblock_frame, MbEdgeInfo};
use mocomp::codec::intra4x4::Intra4x4Mode;
use mocomp::codec::intra8x8;
use mocomp::codec::mv::Mv;
use mocomp::codec::partition::RefMv;
use mocomp::codec::weight::{PlaneWeight, Weights};
use mocomp::synth::{standard_scenes, Synth};
use std::hint::black_box;

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
            mvs: [Some(RefMv::previous(Mv::new(5, -3))); 4],
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
    // The encoder's guess of the weights (every plane's statistics of the
    // source and of the reference), here of a frame from a darker copy.
    g.bench_function("estimate_weights", |b| {
        b.iter(|| mocomp::encode::estimate_weights(black_box(&frame), black_box(&out), usize::MAX))
    });
    g.finish();
}

/// The nine 8x8 intra modes as the encoder's search makes them: the edges
/// smoothed and the mode table made once, then nine gathers (the table's
/// `pred_8x8` entry, which makes the table per call, is in `benches/dsp.rs`).
fn intra8x8_search(c: &mut Criterion) {
    let edges8 = intra8x8::Edges8 {
        top: Some(std::array::from_fn(|x| 90 + (x * x / 4) as u8)),
        left: Some([88, 86, 85, 85, 84, 82, 81, 81]),
        top_left: Some(89),
    };
    c.bench_function("intra8x8_nine_modes_one_source", |b| {
        b.iter(|| {
            let source = intra8x8::ModeSource::new(&intra8x8::filtered(black_box(&edges8)));
            let mut out = [0u8; 64];
            for m in Intra4x4Mode::ALL {
                source.predict(m, &mut out);
            }
            out
        })
    });
}

criterion_group!(benches, tools, intra8x8_search);
criterion_main!(benches);
