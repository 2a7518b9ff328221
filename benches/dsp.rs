//! Every entry of every DSP table at every CPU level this machine runs,
//! one criterion benchmark each (`dsp_<table>/<entry>/<level>`), on
//! cache-resident inputs of the size the encoder calls it with: what a
//! SIMD twin buys is read here, entry by entry (`cargo bench --bench dsp
//! -- dsp_pixel`), before it is measured on whole encodes.

use std::hint::black_box;

use criterion::{criterion_group, criterion_main, BenchmarkGroup, BenchmarkId, Criterion};
use mocomp::codec::cpu;
use mocomp::codec::dsp::ipred::{
    Edges, Edges8, Intra4x4Mode, IntraMode, ModeSource, ModeSource4, Neighbours, IPRED,
};
use mocomp::codec::dsp::itx::ITX;
use mocomp::codec::dsp::lf::{LfLevel, LF};
use mocomp::codec::dsp::mc::{LUMA_TAPS, MC};
use mocomp::codec::dsp::PerLevel;
use mocomp::codec::residual::{BlockClass, MbResidual, ResidualCoder};
use mocomp::codec::Plane;
use mocomp::encode::dsp::CODER;
use mocomp::features::dsp::FEATURES;
use mocomp::imgproc::dsp::IMGPROC;
use mocomp::me::dsp::{fill_halfpel, PATCH18_PHASE, PIXEL};
use mocomp::metrics::dsp::{BandScratch, ColumnSums, METRICS, WIN};

type Group<'a> = BenchmarkGroup<'a, criterion::measurement::WallTime>;

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

/// `run(group, table, level name)` for every level of `tables`.
fn levels<T>(
    c: &mut Criterion,
    name: &str,
    tables: &'static PerLevel<T>,
    mut run: impl FnMut(&mut Group, &T, &str),
) {
    let mut g = c.benchmark_group(format!("dsp_{name}"));
    for level in cpu::available() {
        run(&mut g, tables.at(level), level.name());
    }
    g.finish();
}

fn bench<O>(g: &mut Group, entry: &str, level: &str, mut f: impl FnMut() -> O) {
    g.bench_function(BenchmarkId::new(entry, level), |b| b.iter(|| black_box(f())));
}

fn codec_tables(c: &mut Criterion) {
    let src = noise(80 * 80, 1);
    let mut out = vec![0u8; 64 * 64];
    levels(c, "mc", &MC, |g, t, l| {
        bench(g, "luma_16x16_hv", l, || {
            (t.luma)(&LUMA_TAPS, black_box(&src), 80, (1, 3), (16, 16), &mut out, 16)
        });
        bench(g, "luma_8x8_h", l, || {
            (t.luma)(&LUMA_TAPS, black_box(&src), 80, (2, 0), (8, 8), &mut out, 8)
        });
        bench(g, "chroma_8x8", l, || {
            (t.chroma)(black_box(&src), 80, (3, 5), (8, 8), &mut out, 8)
        });
    });
    let levels4 = [[3, -2, 1, 0], [1, 0, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 0]];
    let levels8: [[i32; 8]; 8] = std::array::from_fn(|r| std::array::from_fn(|c| (r as i32 - c as i32) / 3));
    let mut mb = [128u8; 256];
    levels(c, "itx", &ITX, |g, t, l| {
        bench(g, "add_4x4", l, || {
            (t.add_4x4)(black_box(&levels4), 28, &mut mb, 16, (4, 4))
        });
        bench(g, "add_8x8", l, || {
            (t.add_8x8)(black_box(&levels8), 28, &mut mb, (8, 8))
        });
        bench(g, "add_4x4_dc", l, || {
            (t.add_4x4_dc)(black_box(&levels4), 1200, 28, &mut mb, 16, (4, 4))
        });
    });
    let edge = noise(32, 2);
    let n = Neighbours {
        top: Some(&edge[..16]),
        left: Some(&edge[16..]),
        top_left: Some(edge[3]),
    };
    let e4 = Edges {
        top: Some(edge[..8].try_into().unwrap()),
        left: Some(edge[8..12].try_into().unwrap()),
        top_left: Some(edge[12]),
    };
    let e8 = Edges8 {
        top: Some(edge[..16].try_into().unwrap()),
        left: Some(edge[16..24].try_into().unwrap()),
        top_left: Some(edge[24]),
    };
    levels(c, "ipred", &IPRED, |g, t, l| {
        bench(g, "pred_16x16_plane", l, || {
            (t.pred_16x16)(IntraMode::Plane, black_box(&n), &mut out, 16)
        });
        bench(g, "pred_8x8_chroma_dc", l, || {
            (t.pred_8x8_chroma)(IntraMode::Dc, black_box(&n), &mut out, 8)
        });
        let (mut o4, mut o8) = ([0u8; 16], [0u8; 64]);
        bench(g, "pred_4x4_nine_modes", l, || {
            Intra4x4Mode::ALL.map(|m| (t.pred_4x4)(m, black_box(&e4), &mut o4))
        });
        bench(g, "pred_8x8_nine_modes", l, || {
            Intra4x4Mode::ALL.map(|m| (t.pred_8x8)(m, black_box(&e8), &mut o8))
        });
        let (source, mut o32) = (ModeSource4::new(&e4), [0u8; 32]);
        bench(g, "pred_4x4_pair_nine_modes", l, || {
            Intra4x4Mode::ALL.map(|m| (t.pred_4x4_pair)(black_box(&source), m, Intra4x4Mode::Dc, &mut o32))
        });
        let source8 = ModeSource::new(&e8);
        bench(g, "pred_8x8_gather_nine_modes", l, || {
            Intra4x4Mode::ALL.map(|m| (t.pred_8x8_gather)(black_box(&source8), m, &mut o8))
        });
    });
    // Near-flat with a step across the edges: most lines are filtered.
    let mut plane: Vec<u8> = noise(24 * 24, 3)
        .iter()
        .enumerate()
        .map(|(i, v)| 100 + v % 4 + if (i % 24 >= 8) ^ (i / 24 >= 8) { 6 } else { 0 })
        .collect();
    levels(c, "lf", &LF, |g, t, l| {
        bench(g, "filter_mb_edge_luma_vertical_bs2", l, || {
            (t.filter_mb_edge)(black_box(&mut plane), (8, 1, 24), [2; 4], LfLevel::at(32), true)
        });
        bench(g, "filter_mb_edge_luma_horizontal_bs4", l, || {
            (t.filter_mb_edge)(
                black_box(&mut plane),
                (8 * 24, 24, 1),
                [4; 4],
                LfLevel::at(32),
                true,
            )
        });
        bench(g, "filter_mb_edge_chroma_vertical_bs1", l, || {
            (t.filter_mb_edge)(black_box(&mut plane), (8, 1, 24), [1; 4], LfLevel::at(32), false)
        });
    });
}

fn pixel_table(c: &mut Criterion) {
    let (a, b) = (noise(64 * 64, 4), noise(64 * 64, 5));
    let reference = Plane::from_fn(352, 288, |x, y| ((x * 7) ^ (y * 13)) as u8).unwrap();
    let mut planes: Vec<Plane> = (0..3).map(|_| Plane::new(352, 288).unwrap()).collect();
    let pair: [u8; 32] = a[..32].try_into().unwrap();
    let mut out = [0u8; 256];
    let mut sums = vec![0u16; reference.data().len()];
    let mut bounds = [0u16; 33];
    levels(c, "pixel", &PIXEL, |g, t, l| {
        for size in [8, 16, 32] {
            bench(g, &format!("sad_{size}x{size}"), l, || {
                (t.sad)(black_box(&a[1..]), 64, &b[3..], 64, size, size)
            });
            bench(g, &format!("satd_{size}x{size}"), l, || {
                (t.satd)(black_box(&a[1..]), 64, &b[3..], 64, size, size)
            });
        }
        let mut row = [0u32; 16];
        bench(g, "sad_16x16_row_of_16", l, || {
            (t.sad_16x16_row)(black_box(&a[1..]), 64, &b[3..], 64, &mut row)
        });
        bench(g, "satd_4x4_pair", l, || {
            (t.satd_4x4_pair)(black_box(&pair), &pair)
        });
        let pairs = [pair, b[..32].try_into().unwrap()];
        bench(g, "satd_4x4_quad", l, || {
            (t.satd_4x4_quad)(black_box(&pair), &pairs)
        });
        let mb: [u8; 256] = a[..256].try_into().unwrap();
        let (top, left): ([u8; 16], [u8; 16]) = (b[..16].try_into().unwrap(), b[64..80].try_into().unwrap());
        bench(g, "intra_satd_x3_16x16", l, || {
            (t.intra_satd_x3_16x16)(black_box(&mb), &top, &left, 128)
        });
        bench(g, "satd_16x16_capped", l, || {
            (t.satd_16x16_capped)(black_box(&a), 64, &b, 64, 500)
        });
        bench(g, "halfpel_planes_cif", l, || {
            fill_halfpel(t.halfpel_planes, black_box(&reference), 32, &mut planes, 1)
        });
        // One macroblock's patch (a CIF frame's planes are 396 of them).
        let mut patch = [0u8; 3 * PATCH18_PHASE];
        bench(g, "halfpel_patch18", l, || {
            (t.halfpel_patch18)(black_box(&reference), (159, 95), &mut patch)
        });
        let (stride, rows) = (reference.stride(), reference.data().len() / reference.stride());
        let mut groups = vec![0u32; 44];
        bench(g, "abs_count_cif", l, || {
            (t.abs_count)(black_box(reference.data()), stride, (352, 288), 117)
        });
        bench(g, "group_sums_cif_band", l, || {
            (t.group_sums)(black_box(reference.data()), stride, (352, 8), &mut groups)
        });
        bench(g, "box_sums_cif_8", l, || {
            (t.box_sums)(black_box(reference.data()), stride, rows, 8, &mut sums)
        });
        let quadrants = [
            &sums[..],
            &sums[8..],
            &sums[8 * stride..],
            &sums[8 * stride + 8..],
        ];
        bench(g, "ads_33", l, || {
            (t.ads)(black_box(quadrants), [1000, 2000, 3000, 4000], &mut bounds)
        });
        bench(g, "copy_16x16", l, || (t.copy_16x16)(black_box(&a), 64, &mut out));
        bench(g, "average_16x16", l, || {
            (t.average_16x16)((black_box(&a), 64), (&b, 64), &mut out)
        });
        bench(g, "average_8x8", l, || {
            (t.average_8x8)((black_box(&a), 64), (&b, 64), &mut out[..64])
        });
    });
}

fn analysis_tables(c: &mut Criterion) {
    let (a, b) = (noise(352 * 288, 6), noise(352 * 288, 7));
    let (pa, pb) = (
        Plane::from_fn(352, 288, |x, y| a[y * 352 + x]).unwrap(),
        Plane::from_fn(352, 288, |x, y| b[y * 352 + x] / 2 + a[y * 352 + x] / 2).unwrap(),
    );
    let g11 = [0.05, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, 0.05];
    let (mut scratch, mut cols, mut sums) =
        (BandScratch::default(), ColumnSums::default(), vec![[0u32; 4]; 88]);
    levels(c, "metrics", &METRICS, |g, t, l| {
        bench(g, "ssd_cif_row", l, || (t.ssd)(black_box(&a[..352]), &b[..352]));
        bench(g, "ssim_band_32_rows", l, || {
            (t.ssim_band)(&mut scratch, &pa, &pb, &g11, 0, 32, 352 - WIN + 1)
        });
        bench(g, "ssim_8x8_row_sums", l, || {
            (t.ssim_8x8_row_sums)(&pa, &pb, 8, &mut cols, &mut sums)
        });
    });
    let src: Vec<f32> = a.iter().map(|&v| f32::from(v)).collect();
    let mut dst = vec![0f32; 352 * 32];
    let kernel = [0.0625f32, 0.25, 0.375, 0.25, 0.0625];
    let picture = ndarray::Array2::from_shape_vec((288, 352), src.clone()).unwrap();
    let (mut half, mut scratch) = (ndarray::Array2::zeros((144, 176)), Vec::new());
    let bytes = ndarray::Array2::from_shape_vec((288, 352), a[..288 * 352].to_vec()).unwrap();
    let quarter = ndarray::Array2::from_shape_fn((72, 88), |(y, x)| (x as f32 - y as f32) * 0.25);
    let mut pairs = vec![0f32; 2 * 288 * 352];
    let mut upsampled = vec![0f32; 288 * 352];
    levels(c, "imgproc", &IMGPROC, |g, t, l| {
        bench(g, "filter_rows_32_rows", l, || {
            (t.filter_rows)(black_box(&src[..352 * 32]), 352, &kernel, &mut dst)
        });
        bench(g, "filter_cols_32_rows", l, || {
            (t.filter_cols)(black_box(&src), 288, 352, 64, &kernel, &mut dst)
        });
        bench(g, "downsample_binomial_cif", l, || {
            (t.downsample_binomial)(black_box(picture.view()), &mut scratch, &mut half)
        });
        bench(g, "downsample_binomial_u8_cif", l, || {
            (t.downsample_binomial_u8)(black_box(bytes.view()), &mut scratch, &mut half)
        });
        bench(g, "upsample_1_level_to_cif", l, || {
            (t.upsample_levels)(black_box(&half), (288, 352), 1, 2.0, &mut upsampled)
        });
        bench(g, "upsample_pair_2_levels_to_cif", l, || {
            (t.upsample_levels_pair)(black_box(&quarter), &quarter, (288, 352), 2, 4.0, 0, &mut pairs)
        });
    });
    let words: Vec<[u64; 4]> = a
        .chunks_exact(32)
        .take(500)
        .map(|c| std::array::from_fn(|k| u64::from_le_bytes(c[8 * k..8 * k + 8].try_into().unwrap())))
        .collect();
    levels(c, "features", &FEATURES, |g, t, l| {
        bench(g, "nearest_of_500", l, || {
            (t.nearest)(black_box(&words[7]), &words)
        });
    });
}

fn coder_table(c: &mut Criterion) {
    let (src, pred) = (
        noise(256, 8),
        noise(256, 9).iter().map(|&v| v / 4 + 96).collect::<Vec<u8>>(),
    );
    let (src, pred): ([u8; 256], [u8; 256]) = (src.try_into().unwrap(), pred.try_into().unwrap());
    let coder = ResidualCoder::new(1, 1);
    let (rate4, rate8) = (
        mocomp::encode::rate::block_pricer(&coder, BlockClass::luma(false)),
        mocomp::encode::rate::block8_pricer(&coder, false),
    );
    let lambda = 0.85 * 2f64.powf(16.0 / 3.0);
    let (mut residuals, mut blocks) = ([[[0i32; 4]; 4]; 16], [[[0i32; 4]; 4]; 16]);
    levels(c, "coder", &CODER, |g, t, l| {
        bench(g, "quantize_4x4", l, || {
            (t.quantize_4x4)(black_box(&src), &pred, 16, (1, 2), 28, 1.0 / 6.0)
        });
        bench(g, "quantize_blocks_16x16", l, || {
            (t.quantize_blocks)(
                black_box(&src),
                &pred,
                16,
                28,
                1.0 / 6.0,
                &mut residuals,
                &mut blocks,
            )
        });
        bench(g, "quadrant_levels", l, || {
            (t.quadrant_levels)(black_box(&src), &pred, 3, 28, 1.0 / 6.0)
        });
        let (residual, levels) = (residuals[5], blocks[5]);
        bench(g, "rdoq_4x4", l, || {
            let mut x = levels;
            (t.rdoq_4x4)(black_box(&residual), &mut x, 28, lambda, &rate4);
            x
        });
        bench(g, "decimate_luma", l, || {
            let mut x = blocks;
            (t.decimate_luma)(black_box(&mut x));
            x
        });
        bench(g, "decimate_score_4", l, || {
            (t.decimate_score)(black_box(&blocks[..4]))
        });
        let coded = MbResidual {
            luma: blocks,
            chroma: [blocks[..4].try_into().unwrap(), blocks[4..8].try_into().unwrap()],
            ..MbResidual::default()
        };
        bench(g, "residual_estimate", l, || {
            (t.residual_estimate)(black_box(&coded))
        });
        bench(g, "forward_8x8", l, || (t.forward_8x8)(black_box(&src), &pred, 2));
        bench(g, "inter_luma8_plain", l, || {
            (t.inter_luma8)(black_box(&src), &pred, 28, lambda, None)
        });
        bench(g, "inter_luma8_rdoq", l, || {
            (t.inter_luma8)(black_box(&src), &pred, 28, lambda, Some(&rate8))
        });
        bench(g, "intra_block8_rdoq", l, || {
            (t.intra_block8)(black_box(&src), &pred, 1, (28, lambda), Some(&rate8))
        });
    });
}

/// The flow table's entries take the DIS search's own types: benched
/// through their callers, the level set for the process (DIS medium's
/// patch search over a CIF pair, one variational refinement).
fn flow_table(c: &mut Criterion) {
    use mocomp::flow::dis::{Dis, DisParams, DisPreset};
    use mocomp::flow::refine::{refine, RefineParams};
    use ndarray::Array2;
    let f = |x: f32, y: f32| 128.0 + 60.0 * (x / 5.0).sin() * (y / 7.0).cos() + 20.0 * ((x + y) / 3.0).cos();
    let a = Array2::from_shape_fn((288, 352), |(y, x)| f(x as f32, y as f32));
    let b = Array2::from_shape_fn((288, 352), |(y, x)| f(x as f32 - 3.25, y as f32 + 1.5));
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let mut g = c.benchmark_group("dsp_flow");
    g.sample_size(10);
    for level in cpu::available() {
        let mut dis = Dis::new(DisParams::preset(DisPreset::Medium));
        g.bench_function(BenchmarkId::new("dis_medium_cif", level.name()), |bench| {
            cpu::set_level(level);
            bench.iter(|| pool.install(|| dis.compute(&a, &b)))
        });
        g.bench_function(BenchmarkId::new("refine_cif", level.name()), |bench| {
            cpu::set_level(level);
            bench.iter(|| {
                let (mut u, mut v) = (Array2::from_elem(a.dim(), 3.0f32), Array2::zeros(a.dim()));
                pool.install(|| refine(&a, &b, &mut u, &mut v, &RefineParams::default()));
                (u, v)
            })
        });
    }
    cpu::set_level(cpu::CpuLevel::detected());
    g.finish();
}

criterion_group!(
    benches,
    codec_tables,
    pixel_table,
    analysis_tables,
    coder_table,
    flow_table
);
criterion_main!(benches);
