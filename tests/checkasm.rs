//! checkasm, as dav1d and x264 have it: every entry of every DSP table
//! (`mocomp::codec::dsp` and the `dsp` modules of `mocomp`), at every CPU
//! level this machine runs, gives exactly what the scalar table's entry
//! gives, on random inputs and worst cases (all 0, all 255, alternating
//! extremes, odd sizes and strides, blocks reaching the slice's end).
//!
//! Each test destructures its table with every field named, so that an
//! entry added to a table does not compile here until it is checked.
//! tests/golden.rs and tests/golden_motion.rs hold whole encodings, flows
//! and metrics at every level.

use mocomp::codec::cpu::{self, CpuLevel};
use mocomp::codec::dsp::ipred::{
    Edges, Edges8, Intra4x4Mode, IntraMode, IpredDsp, ModeSource, ModeSource4, Neighbours, IPRED,
};
use mocomp::codec::dsp::itx::{ItxDsp, ITX};
use mocomp::codec::dsp::lf::{LfDsp, LfLevel, LF};
use mocomp::codec::dsp::mc::{McDsp, LUMA_TAPS, MC, SMOOTH_LUMA_TAPS};
use mocomp::codec::dsp::PerLevel;
use mocomp::codec::residual::{BlockClass, MbResidual, ResidualCoder};
use mocomp::codec::Plane;
use mocomp::encode::dsp::{CoderDsp, CODER};
use mocomp::features::dsp::{FeaturesDsp, FEATURES};
use mocomp::flow::dis::{dis_flow, DisParams, DisPreset};
use mocomp::flow::refine::{refine, RefineParams};
use mocomp::imgproc::dsp::{ImgprocDsp, IMGPROC};
use mocomp::me::dsp::{fill_halfpel, PixelDsp, PATCH18_PHASE, PIXEL};
use mocomp::metrics::dsp::{BandScratch, ColumnSums, MetricsDsp, METRICS, WIN};
use ndarray::Array2;

/// xorshift bytes.
struct Random(u64);

impl Random {
    fn byte(&mut self) -> u8 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0 as u8
    }
    fn bytes(&mut self, n: usize) -> Vec<u8> {
        (0..n).map(|_| self.byte()).collect()
    }
    fn below(&mut self, n: u32) -> u32 {
        ((u32::from(self.byte()) << 8) | u32::from(self.byte())) % n.max(1)
    }
}

/// Buffers of `n` samples of every kind the kernels must survive.
fn sample_sets(n: usize, seed: u64) -> Vec<Vec<u8>> {
    let mut r = Random(seed | 1);
    vec![
        vec![0; n],
        vec![255; n],
        (0..n).map(|i| if i % 2 == 0 { 0 } else { 255 }).collect(),
        r.bytes(n),
        (0..n).map(|i| ((i * 7 + i / 13 * 3) % 256) as u8).collect(),
    ]
}

/// Pictures of every kind, `w x h`.
fn planes(w: usize, h: usize) -> Vec<Plane> {
    sample_sets(w * h, 0x9e37_79b9)
        .into_iter()
        .map(|s| Plane::from_fn(w, h, |x, y| s[y * w + x]).unwrap())
        .collect()
}

/// Every level above scalar, with its table and the scalar one.
fn each_level<T>(tables: &'static PerLevel<T>, mut check: impl FnMut(&str, &T, &T)) {
    let scalar = tables.at(CpuLevel::Scalar);
    for level in cpu::available().into_iter().skip(1) {
        check(level.name(), tables.at(level), scalar);
    }
}

#[test]
fn motion_compensation() {
    each_level(&MC, |isa, t, s| {
        let McDsp { luma, chroma } = *t;
        for data in sample_sets(80 * 80, 1) {
            for (fx, fy) in (0..4).flat_map(|x| (0..4).map(move |y| (x, y))) {
                for (w, h) in [(16, 16), (8, 8), (4, 4), (16, 8), (3, 5), (64, 64)] {
                    for taps in [&LUMA_TAPS, &SMOOTH_LUMA_TAPS] {
                        let (mut a, mut b) = (vec![0u8; 64 * 64], vec![0u8; 64 * 64]);
                        luma(taps, &data[1..], 80, (fx, fy), (w, h), &mut a, 64);
                        (s.luma)(taps, &data[1..], 80, (fx, fy), (w, h), &mut b, 64);
                        assert_eq!(a, b, "{isa} luma {w}x{h} phase ({fx}, {fy}) {taps:?}");
                    }
                }
            }
            for (fx, fy) in (0..8).flat_map(|x| (0..8).map(move |y| (x, y))) {
                for (w, h) in [(8, 8), (4, 4), (2, 2), (5, 3), (32, 32)] {
                    let (mut a, mut b) = (vec![0u8; 32 * 32], vec![0u8; 32 * 32]);
                    chroma(&data[3..], 80, (fx, fy), (w, h), &mut a, 32);
                    (s.chroma)(&data[3..], 80, (fx, fy), (w, h), &mut b, 32);
                    assert_eq!(a, b, "{isa} chroma {w}x{h} phase ({fx}, {fy})");
                }
                // 8 wide with the slices no longer than the contract's
                // (h + 1 rows of 9 samples; h rows of 8 out).
                for h in [1, 4, 8] {
                    let src = &data[5..5 + h * 80 + 9];
                    let (mut a, mut b) = (vec![0u8; (h - 1) * 8 + 8], vec![0u8; (h - 1) * 8 + 8]);
                    chroma(src, 80, (fx, fy), (8, h), &mut a, 8);
                    (s.chroma)(src, 80, (fx, fy), (8, h), &mut b, 8);
                    assert_eq!(a, b, "{isa} chroma 8x{h} in tight slices, phase ({fx}, {fy})");
                }
            }
        }
    });
}

/// Levels of every kind: zero, small, large, extreme.
fn level_blocks<const N: usize>(seed: u64) -> Vec<[[i32; N]; N]> {
    let mut r = Random(seed | 1);
    let mut out = vec![[[0; N]; N], [[1; N]; N], [[-2048; N]; N], [[2047; N]; N]];
    for spread in [3, 40, 600] {
        for _ in 0..20 {
            out.push(std::array::from_fn(|_| {
                std::array::from_fn(|_| r.below(2 * spread + 1) as i32 - spread as i32)
            }));
        }
    }
    out
}

#[test]
fn inverse_transforms() {
    each_level(&ITX, |isa, t, s| {
        let ItxDsp {
            add_4x4,
            add_8x8,
            add_4x4_dc,
        } = *t;
        for pred in sample_sets(256, 2) {
            for qp in [0, 12, 27, 51] {
                // Past 16 bits too: dequantisation clamps them.
                let extreme = [
                    [[i32::MAX, i32::MIN, 40_000, -40_000]; 4],
                    [[70_000, 0, 0, -1]; 4],
                ];
                for levels in level_blocks::<4>(qp as u64).into_iter().chain(extreme) {
                    let (mut a, mut b) = (pred.clone(), pred.clone());
                    add_4x4(&levels, qp, &mut a, 16, (4, 8));
                    (s.add_4x4)(&levels, qp, &mut b, 16, (4, 8));
                    assert_eq!(a, b, "{isa} 4x4 at QP {qp}");
                    // Dequantised DC coefficients across their 16-bit
                    // range (the levels' position 0 ignored).
                    for dc in [0, 1, -1, 97, -4000, 32767, -32768] {
                        let (mut a, mut b) = (pred.clone(), pred.clone());
                        add_4x4_dc(&levels, dc, qp, &mut a, 16, (4, 8));
                        (s.add_4x4_dc)(&levels, dc, qp, &mut b, 16, (4, 8));
                        assert_eq!(a, b, "{isa} 4x4 with DC {dc} at QP {qp}");
                    }
                }
                // Past 12 bits (the scalar build's 64-bit path) and 16.
                let extreme8 = [
                    [[i32::MAX, i32::MIN, 40_000, -40_000, 5_000, -5_000, 70_000, 1]; 8],
                    [[4_096, 0, 0, -4_097, 0, 0, 0, 0]; 8],
                ];
                for levels in level_blocks::<8>(qp as u64 + 9).into_iter().chain(extreme8) {
                    for at in [(0, 0), (8, 0), (0, 8), (8, 8)] {
                        let mut a: [u8; 256] = pred.clone().try_into().unwrap();
                        let mut b = a;
                        add_8x8(&levels, qp, &mut a, at);
                        (s.add_8x8)(&levels, qp, &mut b, at);
                        assert_eq!(a, b, "{isa} 8x8 at {at:?}, QP {qp}");
                    }
                }
            }
        }
    });
}

#[test]
fn intra_prediction() {
    each_level(&IPRED, |isa, t, s| {
        let IpredDsp {
            pred_16x16,
            pred_8x8_chroma,
            pred_4x4,
            pred_8x8,
            pred_4x4_pair,
            pred_8x8_gather,
        } = *t;
        for edge in sample_sets(32, 3) {
            for (top, left) in [(true, true), (true, false), (false, true), (false, false)] {
                let n = Neighbours {
                    top: top.then_some(&edge[..16]),
                    left: left.then_some(&edge[16..]),
                    top_left: (top && left).then_some(edge[7]),
                };
                for mode in IntraMode::ALL.into_iter().filter(|m| m.is_available(&n)) {
                    let (mut a, mut b) = ([0u8; 256], [0u8; 256]);
                    pred_16x16(mode, &n, &mut a, 16);
                    (s.pred_16x16)(mode, &n, &mut b, 16);
                    assert_eq!(a, b, "{isa} 16x16 {mode:?}");
                    pred_8x8_chroma(mode, &n, &mut a, 8);
                    (s.pred_8x8_chroma)(mode, &n, &mut b, 8);
                    assert_eq!(a, b, "{isa} chroma {mode:?}");
                }
                let e4 = Edges {
                    top: top.then(|| edge[..8].try_into().unwrap()),
                    left: left.then(|| edge[8..12].try_into().unwrap()),
                    top_left: (top && left).then_some(edge[12]),
                };
                let e8 = Edges8 {
                    top: top.then(|| edge[..16].try_into().unwrap()),
                    left: left.then(|| edge[16..24].try_into().unwrap()),
                    top_left: (top && left).then_some(edge[24]),
                };
                for mode in Intra4x4Mode::ALL
                    .into_iter()
                    .filter(|m| m.is_available(top, left))
                {
                    let (mut a, mut b) = ([0u8; 16], [0u8; 16]);
                    pred_4x4(mode, &e4, &mut a);
                    (s.pred_4x4)(mode, &e4, &mut b);
                    assert_eq!(a, b, "{isa} 4x4 {mode:?}");
                    let (mut a, mut b) = ([0u8; 64], [0u8; 64]);
                    pred_8x8(mode, &e8, &mut a);
                    (s.pred_8x8)(mode, &e8, &mut b);
                    assert_eq!(a, b, "{isa} 8x8 {mode:?}");
                }
                // Every pair of modes, the unavailable ones too (a gather
                // is defined for any).
                let source = ModeSource4::new(&e4);
                for a_mode in Intra4x4Mode::ALL {
                    for b_mode in Intra4x4Mode::ALL {
                        let (mut a, mut b) = ([0u8; 32], [0u8; 32]);
                        pred_4x4_pair(&source, a_mode, b_mode, &mut a);
                        (s.pred_4x4_pair)(&source, a_mode, b_mode, &mut b);
                        assert_eq!(a, b, "{isa} 4x4 pair {a_mode:?} {b_mode:?}");
                    }
                }
                let source = ModeSource::new(&e8);
                for mode in Intra4x4Mode::ALL {
                    let (mut a, mut b) = ([0u8; 64], [0u8; 64]);
                    pred_8x8_gather(&source, mode, &mut a);
                    (s.pred_8x8_gather)(&source, mode, &mut b);
                    assert_eq!(a, b, "{isa} 8x8 gather {mode:?}");
                }
            }
        }
    });
}

#[test]
fn deblocking() {
    each_level(&LF, |isa, t, s| {
        let LfDsp {
            filter_mb_edge,
            filter_chroma_edge,
        } = *t;
        let mut r = Random(0x5eed_deb1);
        // 24x24 pictures of every kind, and near-flat ones with a step at
        // the edge (where most lines pass the filter's thresholds).
        let mut pictures = sample_sets(24 * 24, 4);
        for _ in 0..60 {
            let (base, noise, step) = (
                r.below(256) as i32,
                1 + r.below(9) as i32,
                r.below(40) as i32 - 20,
            );
            pictures.push(
                (0..24 * 24)
                    .map(|i| {
                        let far = (i % 24 >= 12) ^ (i / 24 >= 12);
                        (base + r.below(noise as u32) as i32 + if far { step } else { 0 }).clamp(0, 255) as u8
                    })
                    .collect(),
            );
        }
        let (mut trials, mut changed) = (0, 0);
        for (n, data) in pictures.iter().enumerate() {
            for qp in [15, 16, 22, 30, 37, 45, 51, 16 + r.below(36) as u8] {
                // indexA and indexB apart (the header's offsets), as
                // often as not.
                let mut offset = || r.below(25) as i8 - 12;
                let level = LfLevel::new(qp, (offset(), offset()));
                // Mixed strengths, and (a third each) one strength on all
                // four pieces or only 1-3 (the kernels compute only the
                // filters some piece takes: an intra edge's 4s alone, an
                // inter edge's 0-2).
                let strengths = match r.below(3) {
                    0 => [0, 1, 2, 3].map(|_| r.below(5) as u8),
                    1 => [1 + r.below(4) as u8; 4],
                    _ => [0, 1, 2, 3].map(|_| r.below(4) as u8),
                };
                // Both chroma planes at once (the second plane another
                // picture), against the scalar kernel on each.
                let other = &pictures[(n + 7) % pictures.len()];
                let chroma_edges = [(12, 1, 24, 16 + 7 * 24), (12 * 24 + 4, 24, 1, 15 * 24 + 4 + 8)];
                for (first, step, line_step, end) in chroma_edges {
                    let (mut u, mut v) = (data.clone(), other.clone());
                    let (mut su, mut sv) = (data.clone(), other.clone());
                    filter_chroma_edge(
                        &mut u[..end],
                        &mut v[..end],
                        (first, step, line_step),
                        strengths,
                        level,
                    );
                    (s.filter_mb_edge)(&mut su[..end], (first, step, line_step), strengths, level, false);
                    (s.filter_mb_edge)(&mut sv[..end], (first, step, line_step), strengths, level, false);
                    assert!(
                        u == su && v == sv,
                        "{isa} chroma pair {n} bS {strengths:?} {level:?} step {step}"
                    );
                }
                for luma in [true, false] {
                    // A vertical edge at x = 12, a horizontal one at y =
                    // 12 (the slice ending at the last sample read).
                    let lines = if luma { 16 } else { 8 };
                    let edges = [
                        (12, 1, 24, 16 + (lines - 1) * 24),
                        (12 * 24 + 4, 24, 1, 15 * 24 + 4 + lines),
                    ];
                    for (first, step, line_step, end) in edges {
                        let (mut a, mut b) = (data.clone(), data.clone());
                        filter_mb_edge(&mut a[..end], (first, step, line_step), strengths, level, luma);
                        (s.filter_mb_edge)(&mut b[..end], (first, step, line_step), strengths, level, luma);
                        assert_eq!(
                            a, b,
                            "{isa} picture {n} bS {strengths:?} {level:?} luma {luma} step {step}"
                        );
                        trials += 1;
                        changed += usize::from(a != *data);
                    }
                }
            }
        }
        // The near-flat pictures are mostly filtered: the kernels were
        // compared on samples they move.
        assert!(changed * 2 > trials, "{changed} of {trials} filtered");
    });
}

#[test]
fn pixel_kernels() {
    each_level(&PIXEL, |isa, t, s| {
        let PixelDsp {
            sad,
            satd,
            satd_4x4_pair,
            satd_4x4_quad,
            intra_satd_x3_16x16,
            satd_16x16_capped,
            halfpel_planes,
            halfpel_patch18,
            copy_16x16,
            average_16x16,
            average_8x8,
            box_sums,
            ads,
            group_sums,
            abs_count,
            sad_16x16_row,
        } = *t;
        let sets = sample_sets(100 * 70, 5);
        for a in &sets {
            for b in &sets {
                for (w, h) in [
                    (16, 16),
                    (8, 8),
                    (8, 16),
                    (8, 4),
                    (32, 32),
                    (16, 4),
                    (12, 8),
                    (4, 4),
                    (64, 64),
                    (3, 7),
                ] {
                    let (da, db) = (&a[101..], &b[7..]);
                    assert_eq!(
                        sad(da, 100, db, 100, w, h),
                        (s.sad)(da, 100, db, 100, w, h),
                        "{isa} sad {w}x{h}"
                    );
                    if w % 4 == 0 && h % 4 == 0 {
                        assert_eq!(
                            satd(da, 100, db, 100, w, h),
                            (s.satd)(da, 100, db, 100, w, h),
                            "{isa} satd {w}x{h}"
                        );
                    }
                }
                // 16 positions along a row, each against the plain SAD,
                // the reference ending exactly where the kernel may read.
                let n = b.len() - 15 * 100 - 32;
                for (da, db) in [(&a[101..], &b[7..]), (&a[..], &b[n..])] {
                    let (mut x, mut y) = ([0u32; 16], [0u32; 16]);
                    let least_x = sad_16x16_row(da, 100, db, 100, &mut x);
                    let least_y = (s.sad_16x16_row)(da, 100, db, 100, &mut y);
                    let each: [u32; 16] = std::array::from_fn(|k| sad(da, 100, &db[k..], 100, 16, 16));
                    assert_eq!((x, y), (each, each), "{isa} 16x16 SADs along a row");
                    let least = each.iter().min().copied();
                    assert_eq!(
                        (Some(least_x), Some(least_y)),
                        (least, least),
                        "{isa} their least"
                    );
                }
                // A block ending exactly at its slice's end.
                let n = a.len() - 15 * 100 - 16;
                assert_eq!(
                    sad(&a[n..], 100, &b[n..], 100, 16, 16),
                    (s.sad)(&a[n..], 100, &b[n..], 100, 16, 16)
                );
                let (pa, pb): ([u8; 32], [u8; 32]) =
                    (a[..32].try_into().unwrap(), b[40..72].try_into().unwrap());
                assert_eq!(
                    satd_4x4_pair(&pa, &pb),
                    (s.satd_4x4_pair)(&pa, &pb),
                    "{isa} paired satd"
                );
                let quad: [[u8; 32]; 2] = [b[200..232].try_into().unwrap(), b[500..532].try_into().unwrap()];
                assert_eq!(
                    satd_4x4_quad(&pa, &quad),
                    (s.satd_4x4_quad)(&pa, &quad),
                    "{isa} four 4x4 SATDs"
                );
                let block = |d: &[u8], at: usize| -> [u8; 16] { d[at..at + 16].try_into().unwrap() };
                let src: [u8; 256] = a[300..556].try_into().unwrap();
                let (top, left) = (block(b, 11), block(b, 900));
                for dc in [0, b[5], 255] {
                    assert_eq!(
                        intra_satd_x3_16x16(&src, &top, &left, dc),
                        (s.intra_satd_x3_16x16)(&src, &top, &left, dc),
                        "{isa} 16x16 intra SATD x3, dc {dc}"
                    );
                }
                let full = (s.satd)(a, 100, b, 100, 16, 16);
                for cap in [0, full / 3, full, u32::MAX] {
                    assert_eq!(
                        satd_16x16_capped(a, 100, b, 100, cap),
                        (s.satd_16x16_capped)(a, 100, b, 100, cap),
                        "{isa} capped satd at {cap}"
                    );
                }
                let (mut x, mut y) = ([0u8; 256], [0u8; 256]);
                copy_16x16(&a[3..], 100, &mut x);
                (s.copy_16x16)(&a[3..], 100, &mut y);
                assert_eq!(x, y, "{isa} copy");
                average_16x16((&a[5..], 100), (b, 99), &mut x);
                (s.average_16x16)((&a[5..], 100), (b, 99), &mut y);
                assert_eq!(x, y, "{isa} average 16x16");
                average_8x8((&a[7..], 100), (&b[2..], 33), &mut x[..64]);
                (s.average_8x8)((&a[7..], 100), (&b[2..], 33), &mut y[..64]);
                assert_eq!(x, y, "{isa} average 8x8");
            }
        }
        // The coefficients' extremes: a white source against black edges
        // and the reverse (every difference +-255), and a checkerboard.
        let checker: [u8; 256] = std::array::from_fn(|i| if (i + i / 16) % 2 == 0 { 255 } else { 0 });
        for (src, edge) in [([255u8; 256], 0u8), ([0; 256], 255), (checker, 0), (checker, 255)] {
            let edges = [edge; 16];
            for dc in [0, 255] {
                assert_eq!(
                    intra_satd_x3_16x16(&src, &edges, &edges, dc),
                    (s.intra_satd_x3_16x16)(&src, &edges, &edges, dc),
                    "{isa} 16x16 intra SATD x3 at the extremes"
                );
            }
        }
        // Box sums of every side successive elimination uses, on buffers
        // narrower and wider than a vector, white and saturated (the u16
        // sums' largest values).
        for (stride, rows) in [(7, 5), (37, 21), (100, 70), (64, 40)] {
            for data in [sets[3][..stride * rows].to_vec(), vec![255u8; stride * rows]] {
                for side in [2, 4, 8, 16] {
                    let (mut x, mut y) = (vec![0u16; stride * rows], vec![0u16; stride * rows]);
                    box_sums(&data, stride, rows, side, &mut x);
                    (s.box_sums)(&data, stride, rows, side, &mut y);
                    assert_eq!(x, y, "{isa} box sums {stride}x{rows} side {side}");
                }
            }
        }
        // Distances from levels at both ends and between, over rows of
        // widths with and without a remainder past the 16-column steps.
        for (stride, width) in [(7usize, 7usize), (40, 37), (100, 96), (100, 100), (64, 16)] {
            for data in [sets[3][..stride * 9].to_vec(), vec![255u8; stride * 9]] {
                for rows in [0, 1, 5, 9] {
                    for c in [0u8, 1, 97, 128, 254, 255] {
                        let got = (s.abs_count)(&data, stride, (width, rows), c);
                        assert_eq!(
                            abs_count(&data, stride, (width, rows), c),
                            got,
                            "{isa} distances {width} of {stride}, {rows} rows, level {c}"
                        );
                        let samples = (0..rows).flat_map(|r| data[r * stride..r * stride + width].iter());
                        let want = samples.fold((0u64, 0u64), |(t, n), &v| {
                            (t + u64::from(v.abs_diff(c)), n + u64::from(v <= c))
                        });
                        assert_eq!(got, want, "{isa} distances against the samples");
                    }
                }
            }
        }
        // Group sums over bands of 0 to 8 rows, widths with and without a
        // remainder past the 16-column steps and a last group of fewer
        // than 8 columns, white and saturated.
        for (stride, width) in [(7usize, 7usize), (40, 37), (100, 96), (100, 100), (64, 16)] {
            for data in [sets[3][..stride * 8].to_vec(), vec![255u8; stride * 8]] {
                for rows in 0..=8 {
                    let groups = width.div_ceil(8);
                    let (mut x, mut y) = (vec![7u32; groups], vec![9u32; groups]);
                    group_sums(&data, stride, (width, rows), &mut x);
                    (s.group_sums)(&data, stride, (width, rows), &mut y);
                    assert_eq!(x, y, "{isa} group sums {width} of {stride}, {rows} rows");
                    // Against the samples themselves.
                    let want = |g: usize| -> u32 {
                        (0..rows)
                            .flat_map(|r| (8 * g..(8 * g + 8).min(width)).map(move |c| (r, c)))
                            .map(|(r, c)| u32::from(data[r * stride + c]))
                            .sum()
                    };
                    assert!(
                        (0..groups).all(|g| y[g] == want(g)),
                        "{isa} group sums {width}, {rows} rows"
                    );
                }
            }
        }
        let sums: Vec<u16> = sets[3].iter().map(|&v| u16::from(v) * 200).collect();
        for n in [0, 1, 15, 16, 17, 33, 129] {
            let rows = [&sums[..], &sums[3..], &sums[170..], &sums[1001..]];
            for current in [[0, 0, 0, 0], [65535, 1, 30000, 40000], [12345, 54321, 0, 255]] {
                let (mut x, mut y) = (vec![0u16; n], vec![0u16; n]);
                let least_x = ads(rows, current, &mut x);
                let least_y = (s.ads)(rows, current, &mut y);
                assert_eq!(x, y, "{isa} ads of {n}");
                assert_eq!(least_x, least_y, "{isa} ads' least of {n}");
                assert_eq!(
                    least_y,
                    y.iter().copied().min().unwrap_or(u16::MAX),
                    "{isa} least of {n}"
                );
                // The exact sum, capped where it passes u16's range.
                let exact =
                    |i: usize| -> u32 { (0..4).map(|q| u32::from(rows[q][i].abs_diff(current[q]))).sum() };
                assert!(
                    (0..n).all(|i| u32::from(y[i]) == exact(i).min(u32::from(u16::MAX))),
                    "{isa} ads of {n} against the exact sums"
                );
            }
        }
        // Widths with and without a remainder past the 16-column steps.
        for (w, h, margin) in [(37, 21, 16), (64, 16, 32), (5, 9, 0)] {
            for r in planes(w, h) {
                let fresh = || (0..3).map(|_| Plane::new(w, h).unwrap()).collect::<Vec<_>>();
                // One band against several: bands only split the rows.
                for bands in [1, 3, 64] {
                    let (mut a, mut b) = (fresh(), fresh());
                    fill_halfpel(halfpel_planes, &r, margin, &mut a, bands);
                    fill_halfpel(s.halfpel_planes, &r, margin, &mut b, 1);
                    for (p, q) in a.iter().zip(&b) {
                        assert!(
                            p.data() == q.data(),
                            "{isa} half-pel planes {w}x{h} margin {margin}, {bands} bands"
                        );
                    }
                }
            }
        }
        // A macroblock's patch wherever the border holds its taps: inside,
        // and at the border's four limits.
        for r in planes(48, 40) {
            let pad = r.pad() as isize;
            let (last_x, last_y) = (48 + pad - 36, 40 + pad - 22);
            for (x, y) in [
                (13, 7),
                (0, 0),
                (3 - pad, 3 - pad),
                (last_x, last_y),
                (3 - pad, last_y),
                (last_x, -5),
            ] {
                let (mut a, mut b) = ([0u8; 3 * PATCH18_PHASE], [0u8; 3 * PATCH18_PHASE]);
                halfpel_patch18(&r, (x, y), &mut a);
                (s.halfpel_patch18)(&r, (x, y), &mut b);
                assert!(a == b, "{isa} half-pel patch at ({x}, {y})");
            }
        }
    });
}

#[test]
fn metrics_kernels() {
    each_level(&METRICS, |isa, t, s| {
        let MetricsDsp {
            ssd,
            ssim_band,
            ssim_8x8_row_sums,
        } = *t;
        // Lengths around the 16- and 32-sample steps and past one 4096
        // block.
        for len in [
            0, 1, 15, 16, 17, 31, 32, 33, 47, 64, 100, 4095, 4096, 4097, 10_000,
        ] {
            for a in sample_sets(len, 6) {
                for b in sample_sets(len, 7) {
                    assert_eq!(ssd(&a, &b), (s.ssd)(&a, &b), "{isa} ssd of {len}");
                }
            }
        }
        for (w, h) in [(70, 40), (68, 12), (17, 23)] {
            for a in planes(w, h) {
                for b in planes(w, h).into_iter().rev() {
                    if w >= WIN && h >= WIN {
                        let g = [0.05, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.05];
                        let (ow, rows) = (w - WIN + 1, h - WIN + 1);
                        let got = ssim_band(&mut BandScratch::default(), &a, &b, &g, 0, rows, ow);
                        let want = (s.ssim_band)(&mut BandScratch::default(), &a, &b, &g, 0, rows, ow);
                        assert_eq!(got.to_bits(), want.to_bits(), "{isa} ssim band {w}x{h}");
                    }
                    let (mut c1, mut c2) = (ColumnSums::default(), ColumnSums::default());
                    let (mut o1, mut o2) = (vec![[0u32; 4]; w / 4], vec![[0u32; 4]; w / 4]);
                    for y0 in (0..h - 3).step_by(4) {
                        ssim_8x8_row_sums(&a, &b, y0, &mut c1, &mut o1);
                        (s.ssim_8x8_row_sums)(&a, &b, y0, &mut c2, &mut o2);
                        assert_eq!(o1, o2, "{isa} ssim 8x8 sums {w}x{h} from row {y0}");
                    }
                }
            }
        }
    });
}

#[test]
fn image_filters() {
    each_level(&IMGPROC, |isa, t, s| {
        let ImgprocDsp {
            filter_rows,
            filter_cols,
            downsample_binomial,
            downsample_binomial_u8,
            upsample_levels,
            upsample_levels_pair,
        } = *t;
        let mut r = Random(8);
        for (w, h) in [(101, 75), (16, 3), (5, 40)] {
            let src: Vec<f32> = (0..w * h).map(|_| f32::from(r.byte()) * 0.73 - 40.0).collect();
            for kernel in [vec![0.25f32, 0.5, 0.25], vec![0.1, 0.2, 0.4, 0.2, 0.1], vec![1.0]] {
                let (mut a, mut b) = (vec![0f32; w * h], vec![0f32; w * h]);
                filter_rows(&src, w, &kernel, &mut a);
                (s.filter_rows)(&src, w, &kernel, &mut b);
                assert!(
                    a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
                    "{isa} rows {w}x{h}"
                );
                let rows = h.min(7);
                let (mut a, mut b) = (vec![0f32; w * rows], vec![0f32; w * rows]);
                filter_cols(&src, h, w, h - rows, &kernel, &mut a);
                (s.filter_cols)(&src, h, w, h - rows, &kernel, &mut b);
                assert!(
                    a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
                    "{isa} cols {w}x{h}"
                );
            }
        }
        let same =
            |a: &Array2<f32>, b: &Array2<f32>| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
        for (w, h) in [(101, 75), (16, 3), (5, 40), (1, 1), (290, 235)] {
            let src = Array2::from_shape_fn((h, w), |_| f32::from(r.byte()) * 0.61 - 20.0);
            let (mut a, mut b) = (
                Array2::zeros((h.div_ceil(2), w.div_ceil(2))),
                Array2::zeros((h.div_ceil(2), w.div_ceil(2))),
            );
            downsample_binomial(src.view(), &mut Vec::new(), &mut a);
            (s.downsample_binomial)(src.view(), &mut Vec::new(), &mut b);
            assert!(same(&a, &b), "{isa} binomial halving {w}x{h}");
            let bytes = Array2::from_shape_fn((h, w), |_| r.byte());
            downsample_binomial_u8(bytes.view(), &mut Vec::new(), &mut a);
            (s.downsample_binomial_u8)(bytes.view(), &mut Vec::new(), &mut b);
            assert!(same(&a, &b), "{isa} binomial halving of bytes {w}x{h}");
            let other = src.mapv(|x| 0.5 - x);
            for levels in 0..4 {
                let (uh, uw) = (h << levels, (w << levels).saturating_sub(levels));
                // Written over old values: every sample is the kernel's.
                let (mut a, mut b) = (vec![7f32; uh * uw], vec![-3f32; uh * uw]);
                upsample_levels(&src, (uh, uw), levels, 1.5, &mut a);
                (s.upsample_levels)(&src, (uh, uw), levels, 1.5, &mut b);
                assert!(
                    a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
                    "{isa} upsample {w}x{h} by {levels} levels"
                );
                // From a middle row to the end, as a worker's half does.
                let y0 = uh / 3;
                let (mut a, mut b) = (vec![0f32; 2 * (uh - y0) * uw], vec![1f32; 2 * (uh - y0) * uw]);
                upsample_levels_pair(&src, &other, (uh, uw), levels, 1.5, y0, &mut a);
                (s.upsample_levels_pair)(&src, &other, (uh, uw), levels, 1.5, y0, &mut b);
                assert!(
                    a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()),
                    "{isa} upsample pair {w}x{h} by {levels} levels"
                );
            }
        }
    });
}

#[test]
fn feature_matching() {
    each_level(&FEATURES, |isa, t, s| {
        let FeaturesDsp { nearest } = *t;
        let mut r = Random(9);
        let mut word = || (0..8).fold(0u64, |w, _| w << 8 | u64::from(r.byte()));
        let others: Vec<[u64; 4]> = (0..300).map(|_| [word(), word(), word(), word()]).collect();
        for d in others.iter().take(40).chain(&[[0; 4], [u64::MAX; 4]]) {
            assert_eq!(nearest(d, &others), (s.nearest)(d, &others), "{isa} nearest");
        }
        assert_eq!(
            nearest(&[0; 4], &[]),
            (s.nearest)(&[0; 4], &[]),
            "{isa} no candidates"
        );
    });
}

#[test]
fn macroblock_coder() {
    let coder = ResidualCoder::new(2, 2);
    each_level(&CODER, |isa, t, s| {
        let CoderDsp {
            quantize_4x4,
            quantize_blocks,
            quadrant_levels,
            rdoq_4x4,
            decimate_luma,
            decimate_score,
            residual_estimate,
            inter_luma8,
            intra_block8,
            forward_8x8,
        } = *t;
        let sources = sample_sets(256, 10);
        for src in &sources {
            for pred in sample_sets(256, 11) {
                for qp in [0, 12, 26, 40, 51] {
                    for rounding in [1.0 / 3.0, 1.0 / 6.0] {
                        // Blocks inside and at the end of the samples.
                        for (size, at) in [(16, (1, 2)), (16, (3, 3)), (8, (0, 0)), (8, (1, 1))] {
                            let n = size * size;
                            assert_eq!(
                                quantize_4x4(&src[..n], &pred[..n], size, at, qp, rounding),
                                (s.quantize_4x4)(&src[..n], &pred[..n], size, at, qp, rounding),
                                "{isa} quantise block {at:?} of {size}x{size}"
                            );
                        }
                        for size in [16, 8] {
                            let n = (size / 4) * (size / 4);
                            let mut got = (vec![[[0; 4]; 4]; n], vec![[[0; 4]; 4]; n]);
                            let mut want = got.clone();
                            quantize_blocks(src, &pred, size, qp, rounding, &mut got.0, &mut got.1);
                            (s.quantize_blocks)(src, &pred, size, qp, rounding, &mut want.0, &mut want.1);
                            assert_eq!(got, want, "{isa} quantise {size}x{size} at QP {qp}");
                        }
                    }
                    let (src, pred): (&[u8; 256], [u8; 256]) =
                        (src[..].try_into().unwrap(), pred.clone().try_into().unwrap());
                    for q in 0..4 {
                        assert_eq!(
                            forward_8x8(src, &pred, q),
                            (s.forward_8x8)(src, &pred, q),
                            "{isa} 8x8 transform of quadrant {q}"
                        );
                        for rounding in [1.0 / 3.0, 1.0 / 6.0] {
                            assert_eq!(
                                quadrant_levels(src, &pred, q, qp, rounding),
                                (s.quadrant_levels)(src, &pred, q, qp, rounding),
                                "{isa} quadrant {q} at QP {qp}"
                            );
                            let (bx, by) = ((q % 2) * 2, (q / 2) * 2);
                            let one_by_one: [[[i32; 4]; 4]; 4] = std::array::from_fn(|k| {
                                quantize_4x4(src, &pred, 16, (bx + k % 2, by + k / 2), qp, rounding).1
                            });
                            assert_eq!(
                                quadrant_levels(src, &pred, q, qp, rounding),
                                one_by_one,
                                "quadrant {q}'s blocks in raster order"
                            );
                        }
                    }
                    let lambda = 0.85 * 2f64.powf((f64::from(qp) - 12.0) / 3.0);
                    for intra in [true, false] {
                        let rate = mocomp::encode::rate::block8_pricer(&coder, intra);
                        for rate in [None, Some(&rate)] {
                            if !intra {
                                assert_eq!(
                                    inter_luma8(src, &pred, qp, lambda, rate),
                                    (s.inter_luma8)(src, &pred, qp, lambda, rate),
                                    "{isa} inter luma 8x8"
                                );
                            }
                            for q in 0..4 {
                                assert_eq!(
                                    intra_block8(src, &pred, q, (qp, lambda), rate),
                                    (s.intra_block8)(src, &pred, q, (qp, lambda), rate),
                                    "{isa} intra 8x8 block {q}"
                                );
                            }
                        }
                    }
                }
            }
        }
        for (k, residual) in level_blocks::<4>(12).into_iter().enumerate() {
            for qp in [12, 28, 40] {
                let lambda = 0.85 * 2f64.powf((f64::from(qp) - 12.0) / 3.0);
                let levels = level_blocks::<4>(13 + k as u64)[k % 10].map(|r| r.map(|v| v / 8));
                for class in [
                    BlockClass::luma(true),
                    BlockClass::luma(false),
                    BlockClass::chroma(false),
                ] {
                    let rate = mocomp::encode::rate::block_pricer(&coder, class);
                    let (mut a, mut b) = (levels, levels);
                    rdoq_4x4(&residual, &mut a, qp, lambda, &rate);
                    (s.rdoq_4x4)(&residual, &mut b, qp, lambda, &rate);
                    assert_eq!(a, b, "{isa} RDOQ");
                }
            }
        }
        let small: Vec<[[i32; 4]; 4]> = level_blocks::<4>(14)
            .iter()
            .map(|b| b.map(|r| r.map(|v| v % 3)))
            .collect();
        for blocks in small.chunks_exact(16) {
            let mut a: [[[i32; 4]; 4]; 16] = blocks.try_into().unwrap();
            let mut b = a;
            decimate_luma(&mut a);
            (s.decimate_luma)(&mut b);
            assert_eq!(a, b, "{isa} zeroing");
            assert_eq!(
                decimate_score(blocks),
                (s.decimate_score)(blocks),
                "{isa} zeroing score"
            );
        }
        // Macroblocks of every kind of level, with and without the 8x8
        // transform's blocks and intra 16x16's DC levels.
        let blocks = level_blocks::<4>(15);
        let blocks8 = level_blocks::<8>(16);
        for (k, luma) in blocks.chunks_exact(16).enumerate() {
            let mut res = MbResidual {
                luma: luma.try_into().unwrap(),
                ..MbResidual::default()
            };
            res.chroma[k % 2] = blocks[k..k + 4].try_into().unwrap();
            res.luma_dc = blocks[(k + 7) % blocks.len()].as_flattened().try_into().unwrap();
            for luma8 in [None, Some(blocks8[k % blocks8.len()..][..4].try_into().unwrap())] {
                res.luma8 = luma8.map(Box::new);
                assert_eq!(
                    residual_estimate(&res),
                    (s.residual_estimate)(&res),
                    "{isa} residual estimate"
                );
            }
        }
    });
}

/// The flow kernels' table is the crate's own (its entries take the DIS
/// search's internal types): checked through the functions that call it,
/// the level set for the whole process (this file's only test to do so).
#[test]
fn flow_kernels_through_their_callers() {
    let f = |x: f32, y: f32| 128.0 + 60.0 * (x / 5.0).sin() * (y / 7.0).cos() + 20.0 * ((x + y) / 3.0).cos();
    let i1 = Array2::from_shape_fn((75, 101), |(y, x)| f(x as f32, y as f32));
    let i2 = Array2::from_shape_fn((75, 101), |(y, x)| f(x as f32 - 3.25, y as f32 + 1.5));
    let bits = |a: &Array2<f32>| a.iter().map(|v| v.to_bits()).collect::<Vec<u32>>();
    let run = || {
        let mut out = Vec::new();
        for preset in [DisPreset::Ultrafast, DisPreset::Medium, DisPreset::Accurate] {
            let flow = dis_flow(&i1, &i2, &DisParams::preset(preset));
            out.push(bits(flow.u()));
            out.push(bits(flow.v()));
        }
        let (mut u, mut v) = (Array2::from_elem(i1.dim(), 3.0f32), Array2::zeros(i1.dim()));
        refine(&i1, &i2, &mut u, &mut v, &RefineParams::default());
        out.push(bits(&u));
        out.push(bits(&v));
        out
    };
    assert_eq!(cpu::set_level(CpuLevel::Scalar), CpuLevel::Scalar);
    let reference = run();
    for level in cpu::available().into_iter().skip(1) {
        assert_eq!(cpu::set_level(level), level);
        assert!(run() == reference, "{}: flow kernels", level.name());
    }
}
