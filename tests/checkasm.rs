//! checkasm, as dav1d and x264 have it: every kernel family reached
//! through the CPU-level dispatch (`mocomp::codec::cpu`) gives, at every
//! level this machine runs, exactly what it gives at the scalar level, on
//! random inputs and worst cases (all 0, all 255, alternating extremes,
//! odd sizes and strides, blocks reaching past the picture's edges).
//! tests/kernels.rs holds the block-cost sets to their scalar twins
//! directly; tests/golden.rs holds whole encodings at every level.
//!
//! One test function: the level is a process-wide setting.

use mocomp::codec::cpu::{self, CpuLevel};
use mocomp::codec::interp::{predict_chroma, predict_luma};
use mocomp::codec::Plane;
use mocomp::flow::dis::{dis_flow, DisParams, DisPreset};
use mocomp::flow::refine::{refine, RefineParams};
use mocomp::metrics::{squared_difference_sum, ssim, ssim_8x8};
use ndarray::Array2;

/// Pictures of every kind the kernels must survive, `w x h`.
fn planes(w: usize, h: usize) -> Vec<Plane> {
    let mut s = 0x9e37_79b9_7f4a_7c15u64;
    let mut random = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        s as u8
    };
    vec![
        Plane::filled(w, h, 0).unwrap(),
        Plane::filled(w, h, 255).unwrap(),
        Plane::from_fn(w, h, |x, y| if (x + y) % 2 == 0 { 0 } else { 255 }).unwrap(),
        Plane::from_fn(w, h, |_, _| random()).unwrap(),
        Plane::from_fn(w, h, |x, y| ((x * 7 + y * 3) % 256) as u8).unwrap(),
    ]
}

/// Everything the dispatched kernels compute on these inputs, in one
/// value to compare between levels.
#[derive(Debug, PartialEq)]
struct Outputs {
    luma: Vec<u8>,
    chroma: Vec<u8>,
    sums: Vec<u64>,
    ssim: Vec<u64>,
    costs: Vec<u32>,
    flows: Vec<Vec<u32>>,
}

fn interpolation(pictures: &[Plane], out: &mut Outputs) {
    let mut block = vec![0u8; 16 * 16];
    for p in pictures {
        let (w, h) = (p.width() as isize, p.height() as isize);
        // Every phase, at the corners and past the edges into the border.
        for (x, y) in [(0, 0), (w - 16, h - 16), (-8, 3), (w - 5, -9), (5, 7)] {
            for (mvx, mvy) in [(0, 0), (1, 2), (3, 3), (-7, 5), (13, -30), (-250, 181)] {
                for (bw, bh) in [(16, 16), (8, 8), (4, 4), (16, 8), (3, 5)] {
                    predict_luma(p, x, y, mvx, mvy, bw, bh, &mut block, 16);
                    out.luma.extend_from_slice(&block[..16 * bh]);
                    predict_chroma(p, x / 2, y / 2, mvx, mvy, bw / 2 + 1, bh / 2 + 1, &mut block, 16);
                    out.chroma.extend_from_slice(&block[..16 * (bh / 2 + 1)]);
                }
            }
        }
    }
}

fn metrics(pictures: &[Plane], out: &mut Outputs) {
    for a in pictures {
        for b in pictures {
            for n in [0, 1, 15, 16, 17, 33, 64] {
                let n = n.min(a.width());
                out.sums
                    .push(squared_difference_sum(&a.row(0)[..n], &b.row(1)[..n]));
            }
            out.ssim.push(ssim_8x8(a, b).to_bits());
            out.ssim.push(ssim(a, b).to_bits());
        }
    }
}

fn block_costs(pictures: &[Plane], out: &mut Outputs) {
    let k = mocomp::me::dsp::pixel();
    for a in pictures {
        for b in pictures {
            for (w, h) in [(16, 16), (8, 8), (32, 32), (16, 4), (12, 8)] {
                let (da, db) = (&a.data()[a.index(1, 2)..], &b.data()[b.index(3, 0)..]);
                out.costs.push((k.sad)(da, a.stride(), db, b.stride(), w, h));
                out.costs.push((k.satd)(da, a.stride(), db, b.stride(), w, h));
            }
        }
    }
}

fn flows(out: &mut Outputs) {
    let f = |x: f32, y: f32| 128.0 + 60.0 * (x / 5.0).sin() * (y / 7.0).cos() + 20.0 * ((x + y) / 3.0).cos();
    let i1 = Array2::from_shape_fn((75, 101), |(y, x)| f(x as f32, y as f32));
    let i2 = Array2::from_shape_fn((75, 101), |(y, x)| f(x as f32 - 3.25, y as f32 + 1.5));
    let bits = |a: &Array2<f32>| a.iter().map(|v| v.to_bits()).collect::<Vec<u32>>();
    for preset in [DisPreset::Ultrafast, DisPreset::Medium, DisPreset::Accurate] {
        let flow = dis_flow(&i1, &i2, &DisParams::preset(preset));
        out.flows.push(bits(flow.u()));
        out.flows.push(bits(flow.v()));
    }
    let (mut u, mut v) = (Array2::from_elem(i1.dim(), 3.0f32), Array2::zeros(i1.dim()));
    refine(&i1, &i2, &mut u, &mut v, &RefineParams::default());
    out.flows.push(bits(&u));
    out.flows.push(bits(&v));
}

fn run_all() -> Outputs {
    let mut out = Outputs {
        luma: Vec::new(),
        chroma: Vec::new(),
        sums: Vec::new(),
        ssim: Vec::new(),
        costs: Vec::new(),
        flows: Vec::new(),
    };
    for (w, h) in [(37, 23), (64, 48), (17, 91)] {
        let pictures = planes(w, h);
        interpolation(&pictures, &mut out);
        metrics(&pictures, &mut out);
        block_costs(&pictures, &mut out);
    }
    flows(&mut out);
    out
}

#[test]
fn every_level_computes_what_the_scalar_level_computes() {
    assert_eq!(cpu::set_level(CpuLevel::Scalar), CpuLevel::Scalar);
    let reference = run_all();
    for level in cpu::available().into_iter().skip(1) {
        assert_eq!(cpu::set_level(level), level);
        let got = run_all();
        assert!(got.luma == reference.luma, "{}: luma interpolation", level.name());
        assert!(
            got.chroma == reference.chroma,
            "{}: chroma interpolation",
            level.name()
        );
        assert!(
            got.sums == reference.sums,
            "{}: squared differences",
            level.name()
        );
        assert!(got.ssim == reference.ssim, "{}: SSIM", level.name());
        assert!(got.costs == reference.costs, "{}: SAD / SATD", level.name());
        assert!(got.flows == reference.flows, "{}: flow kernels", level.name());
    }
}
