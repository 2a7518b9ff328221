//! The coding tools added in stream version 3, on a CIF frame of the
//! synthetic sample: the deblocking filter (an intra frame: every edge
//! strength 3 or 4; an inter frame of coded blocks: strength 2 on their
//! edges) and the reference weighting of weighted prediction; and per
//! macroblock's luma, the 4x4 and 8x8 transforms (forward + quantise,
//! dequantise + inverse) and the nine 4x4 intra predictions of a block.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use mocomp::codec::deblock::{deblock_frame, MbEdgeInfo};
use mocomp::codec::intra4x4::{self, Edges, Intra4x4Mode};
use mocomp::codec::intra8x8;
use mocomp::codec::mv::Mv;
use mocomp::codec::partition::RefMv;
use mocomp::codec::transform::{dequantize, forward_4x4, inverse_4x4, quantize, Block4};
use mocomp::codec::transform8x8::{dequantize_8x8, forward_8x8, inverse_8x8, quantize_8x8, Block8};
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
    g.finish();
}

/// A macroblock's luma residual: a gradient with a ripple, in -60..60.
fn residual(x: usize, y: usize) -> i32 {
    ((x as i32 * 7 - y as i32 * 5) % 60) - 30 + ((x * y) % 7) as i32
}

fn kernels(c: &mut Criterion) {
    let mut g = c.benchmark_group("codec_kernels_per_mb");
    g.throughput(Throughput::Elements(256));
    let blocks4: Vec<Block4> = (0..16)
        .map(|k| std::array::from_fn(|r| std::array::from_fn(|c| residual((k % 4) * 4 + c, (k / 4) * 4 + r))))
        .collect();
    let blocks8: Vec<Block8> = (0..4)
        .map(|q| std::array::from_fn(|r| std::array::from_fn(|c| residual((q % 2) * 8 + c, (q / 2) * 8 + r))))
        .collect();
    g.bench_function("forward_quantize_4x4_qp28", |b| {
        b.iter(|| {
            blocks4
                .iter()
                .map(|x| {
                    let mut w = forward_4x4(black_box(x));
                    quantize(&mut w, 28, 1.0 / 6.0);
                    w
                })
                .collect::<Vec<_>>()
        })
    });
    g.bench_function("forward_quantize_8x8_qp28", |b| {
        b.iter(|| {
            blocks8
                .iter()
                .map(|x| {
                    let mut w = forward_8x8(black_box(x));
                    quantize_8x8(&mut w, 28, 1.0 / 6.0);
                    w
                })
                .collect::<Vec<_>>()
        })
    });
    let levels4: Vec<Block4> = blocks4.iter().map(|x| x.map(|r| r.map(|v| v / 8))).collect();
    let levels8: Vec<Block8> = blocks8.iter().map(|x| x.map(|r| r.map(|v| v / 8))).collect();
    g.bench_function("dequantize_inverse_4x4_qp28", |b| {
        b.iter(|| {
            levels4
                .iter()
                .map(|l| {
                    let mut d = *black_box(l);
                    dequantize(&mut d, 28);
                    inverse_4x4(&d)
                })
                .collect::<Vec<_>>()
        })
    });
    g.bench_function("dequantize_inverse_8x8_qp28", |b| {
        b.iter(|| {
            levels8
                .iter()
                .map(|l| {
                    let mut d = *black_box(l);
                    dequantize_8x8(&mut d, 28);
                    inverse_8x8(&d)
                })
                .collect::<Vec<_>>()
        })
    });
    g.finish();
    let edges = Edges {
        top: Some([90, 94, 99, 105, 110, 112, 113, 113]),
        left: Some([88, 86, 85, 85]),
        top_left: Some(89),
    };
    let modes: Vec<Intra4x4Mode> = (0..9).filter_map(Intra4x4Mode::from_code).collect();
    c.bench_function("intra4x4_nine_modes_one_block", |b| {
        b.iter(|| {
            let mut out = [0u8; 16];
            for &m in &modes {
                intra4x4::predict(m, black_box(&edges), &mut out);
            }
            out
        })
    });
    let edges8 = intra8x8::Edges8 {
        top: Some(std::array::from_fn(|x| 90 + (x * x / 4) as u8)),
        left: Some([88, 86, 85, 85, 84, 82, 81, 81]),
        top_left: Some(89),
    };
    c.bench_function("intra8x8_nine_modes_one_block", |b| {
        b.iter(|| {
            let mut out = [0u8; 64];
            for &m in &modes {
                intra8x8::predict(m, black_box(&edges8), &mut out);
            }
            out
        })
    });
    // As the encoder's search does it: the edges smoothed and the mode
    // table made once, then nine gathers.
    c.bench_function("intra8x8_nine_modes_one_source", |b| {
        b.iter(|| {
            let source = intra8x8::ModeSource::new(&intra8x8::filtered(black_box(&edges8)));
            let mut out = [0u8; 64];
            for &m in &modes {
                source.predict(m, &mut out);
            }
            out
        })
    });
}

criterion_group!(benches, tools, kernels);
criterion_main!(benches);
