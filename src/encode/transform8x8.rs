//! Luma in the 8x8 transform (FORMAT.md section 10.2): the levels of an
//! inter macroblock, with the small-level zeroing and rate-distortion
//! optimised quantisation, for the macroblock coder to weigh against four
//! 4x4 transforms per quadrant; and those of one block of an 8x8 intra
//! macroblock, for its search.

use super::rate::{few_levels, Block8Pricer, ScanLevels, TrialPrices, WholeTrials};
use super::rdo::quant_rounding;
use crate::codec::syntax::MB;
use crate::codec::transform8x8::{
    dequantize_level_8x8, dequantized_orthonormal, forward_8x8, quantize_8x8, Block8, ORTHONORMAL_SCALE8,
    ZIGZAG8,
};

/// Zeroing cost of a lone ±1 after a run of `r` zeros in scan order: the
/// 4x4 rule's (3 right after another level, nothing after 6 zeros) with
/// runs four times as long, as 64 positions hold four blocks' worth.
fn lone_level_cost(run: usize) -> u32 {
    match run {
        0..=3 => 3,
        4..=11 => 2,
        12..=23 => 1,
        _ => 0,
    }
}

/// The reference encoder's measure of whether a block's levels are worth
/// their bits: large for any level above 1, else the lone levels' costs.
#[inline(always)]
fn coefficient_cost8(b: &Block8) -> u32 {
    let flat = b.as_flattened();
    // (Branch-free passes the compiler vectorises: most blocks are empty.)
    let (mut any, mut big) = (false, false);
    for &v in flat {
        any |= v != 0;
        big |= v.unsigned_abs() > 1;
    }
    if big {
        return 999;
    }
    if !any {
        return 0;
    }
    let (mut cost, mut run) = (0, 0);
    for &k in &ZIGZAG8 {
        if flat[k] != 0 {
            cost += lone_level_cost(run);
            run = 0;
        } else {
            run += 1;
        }
    }
    cost
}

/// Drops the 8x8 blocks whose levels cost < 4, and all of them when what
/// is left costs < 6 (the thresholds of the 4x4 quadrants).
#[inline(always)]
fn drop_costly_small(blocks: &mut [Block8; 4]) {
    let mut total = 0;
    for b in blocks.iter_mut() {
        let cost = coefficient_cost8(b);
        if cost < 4 {
            *b = [[0; 8]; 8];
        } else {
            total += cost;
        }
    }
    if total < 6 {
        *blocks = [[[0; 8]; 8]; 4];
    }
}

/// The residual of quadrant `q` of `src - pred` (16x16 luma).
#[inline(always)]
fn quadrant_residual(src: &[u8; 256], pred: &[u8; 256], q: usize) -> Block8 {
    let (x0, y0) = ((q % 2) * 8, (q / 2) * 8);
    std::array::from_fn(|r| {
        std::array::from_fn(|c| {
            let i = (y0 + r) * MB + x0 + c;
            i32::from(src[i]) - i32::from(pred[i])
        })
    })
}

/// The 8x8 transform of quadrant `q` of `src - pred` (16x16 luma): the
/// scalar kernel ([`super::dsp::Forward8Fn`]).
#[inline(always)]
pub(crate) fn quadrant_forward8(src: &[u8; 256], pred: &[u8; 256], q: usize) -> Block8 {
    forward_8x8(&quadrant_residual(src, pred, q))
}

/// The coefficients of [`forward_8x8`] on the orthonormal basis (what
/// RDOQ measures its error on).
#[inline(always)]
fn orthonormal(w: &Block8) -> [f64; 64] {
    let w = w.as_flattened();
    std::array::from_fn(|k| f64::from(w[k]) * ORTHONORMAL_SCALE8[k])
}

/// Rate-distortion optimised quantisation of one block, greedy from the
/// last level to the first: a level steps toward zero where that lowers
/// squared error + lambda * bits. The error is measured on the orthonormal
/// coefficients (`source`, which the transform keeps to within its
/// rounding), so a trial costs no inverse transform.
#[inline(always)]
fn lower_levels8(source: &[f64; 64], levels: &mut Block8, qp: u8, lambda: f64, rate: &Block8Pricer) {
    let scan = ScanLevels::gather(levels.as_flattened(), &ZIGZAG8);
    let bits = f64::from(rate.scan_cost(&scan)) / 256.0;
    if bits == 0.0 {
        return;
    }
    if few_levels(scan.mask) {
        descend8(
            source,
            levels,
            (qp, lambda),
            (&scan, bits),
            WholeTrials::new(rate, scan),
        );
    } else {
        descend8(source, levels, (qp, lambda), (&scan, bits), rate.trials(&scan));
    }
}

/// [`lower_levels8`]'s descent over the levels of `scan`, priced by
/// `trials`.
#[inline(always)]
fn descend8(
    source: &[f64; 64],
    levels: &mut Block8,
    (qp, lambda): (u8, f64),
    (scan, mut bits): (&ScanLevels<64>, f64),
    mut trials: impl TrialPrices,
) {
    let recon =
        |v: i32, k: usize| dequantized_orthonormal(dequantize_level_8x8(v, qp, k / 8, k % 8), k / 8, k % 8);
    let sq = |x: f64| x * x;
    // Each position's squared error, summed in raster order. A level of 0
    // stands for 0, so its term is the source's own square: only the
    // non-zero levels are dequantised.
    let mut terms: [f64; 64] = std::array::from_fn(|k| sq(source[k]));
    let zero_error: f64 = terms.iter().sum();
    let mut nonzero = scan.mask;
    while nonzero != 0 {
        let k = ZIGZAG8[nonzero.trailing_zeros() as usize];
        nonzero &= nonzero - 1;
        terms[k] = sq(source[k] - recon(levels[k / 8][k % 8], k));
    }
    let mut error: f64 = terms.iter().sum();
    // The non-zero levels from the last: a trial changes only its own.
    let mut untried = scan.mask;
    while untried != 0 {
        let i = 63 - untried.leading_zeros() as usize;
        untried &= !(1 << i);
        let k = ZIGZAG8[i];
        let (r, c) = (k / 8, k % 8);
        let v = levels[r][c];
        let lowered = v - v.signum();
        let delta = sq(source[k] - recon(lowered, k)) - sq(source[k] - recon(v, k));
        // Fewer bits than none cannot pay for more error than this.
        if delta >= lambda * bits {
            trials.keep(i, v);
            continue;
        }
        let b = f64::from(trials.cost_with(i, lowered)) / 256.0;
        if delta + lambda * (b - bits) >= 0.0 {
            trials.keep(i, v);
        } else {
            trials.keep(i, lowered);
            levels[r][c] = lowered;
            error += delta;
            bits = b;
        }
    }
    // Last, the whole block against none of it.
    if bits > 0.0 && zero_error - error <= lambda * bits {
        *levels = [[0; 8]; 8];
    }
}

/// The luma levels of an inter macroblock in the 8x8 transform (RDOQ
/// priced by `rate` when given), or `None` when none is left.
#[inline(always)]
pub(crate) fn inter_luma8(
    src: &[u8; 256],
    pred: &[u8; 256],
    qp: u8,
    lambda: f64,
    rate: Option<&Block8Pricer>,
) -> Option<Box<[Block8; 4]>> {
    inter_luma8_with(quadrant_forward8, src, pred, (qp, lambda), rate)
}

/// [`inter_luma8`] with the quadrants transformed by `forward` (a
/// [`super::dsp::Forward8Fn`] of the CPU level it is compiled for).
#[inline(always)]
pub(crate) fn inter_luma8_with(
    forward: impl Fn(&[u8; 256], &[u8; 256], usize) -> Block8,
    src: &[u8; 256],
    pred: &[u8; 256],
    (qp, lambda): (u8, f64),
    rate: Option<&Block8Pricer>,
) -> Option<Box<[Block8; 4]>> {
    let mut blocks = Box::new([[[0; 8]; 8]; 4]);
    // The orthonormal coefficients only where RDOQ weighs them.
    let mut sources = [[0.0; 64]; 4];
    for (q, (levels, source)) in blocks.iter_mut().zip(&mut sources).enumerate() {
        *levels = forward(src, pred, q);
        if rate.is_some() {
            *source = orthonormal(levels);
        }
        quantize_8x8(levels, qp, quant_rounding(false, rate.is_some()));
    }
    drop_costly_small(&mut blocks);
    if let Some(rate) = rate {
        for (levels, source) in blocks.iter_mut().zip(&sources) {
            lower_levels8(source, levels, qp, lambda, rate);
        }
        drop_costly_small(&mut blocks);
    }
    let any = blocks.as_flattened().as_flattened().iter().any(|&v| v != 0);
    any.then_some(blocks)
}

/// The levels of 8x8 block `q` of an intra macroblock's `src - pred`
/// (16x16 luma, block `q` of `pred` predicted), RDOQ priced by `rate` when
/// given. Intra levels are not zeroed for their cost, as 4x4 ones are not:
/// their errors would carry into the blocks predicted from them.
#[inline(always)]
pub(crate) fn intra_block8(
    src: &[u8; 256],
    pred: &[u8; 256],
    q: usize,
    qp_lambda: (u8, f64),
    rate: Option<&Block8Pricer>,
) -> Block8 {
    intra_block8_with(quadrant_forward8, src, pred, q, qp_lambda, rate)
}

/// [`intra_block8`] with the block transformed by `forward`, as
/// [`inter_luma8_with`].
#[inline(always)]
pub(crate) fn intra_block8_with(
    forward: impl Fn(&[u8; 256], &[u8; 256], usize) -> Block8,
    src: &[u8; 256],
    pred: &[u8; 256],
    q: usize,
    (qp, lambda): (u8, f64),
    rate: Option<&Block8Pricer>,
) -> Block8 {
    let w = forward(src, pred, q);
    let mut levels = w;
    quantize_8x8(&mut levels, qp, quant_rounding(true, rate.is_some()));
    if let Some(rate) = rate {
        lower_levels8(&orthonormal(&w), &mut levels, qp, lambda, rate);
    }
    levels
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::recon::add_luma8;
    use crate::codec::residual::ResidualCoder;

    /// A smooth ramp residual over a flat prediction.
    fn ramp() -> ([u8; 256], [u8; 256]) {
        let src = std::array::from_fn(|i| (60 + (i % 16) * 3 + (i / 16) * 2) as u8);
        (src, [80; 256])
    }

    fn reconstruct(pred: &[u8; 256], blocks: &[Block8; 4], qp: u8) -> [u8; 256] {
        let mut out = *pred;
        add_luma8(blocks, qp, &mut out);
        out
    }

    fn sse(a: &[u8; 256], b: &[u8; 256]) -> u64 {
        a.iter()
            .zip(b)
            .map(|(&x, &y)| u64::from(x.abs_diff(y)).pow(2))
            .sum()
    }

    #[test]
    fn a_smooth_residual_comes_back_within_the_step() {
        let (src, pred) = ramp();
        for qp in [12u8, 22, 32] {
            let blocks = inter_luma8(&src, &pred, qp, 0.0, None).expect("levels");
            let rec = reconstruct(&pred, &blocks, qp);
            let rms = (sse(&src, &rec) as f64 / 256.0).sqrt();
            assert!(
                rms < 0.5 * crate::codec::transform::qstep(qp) + 0.5,
                "qp {qp}: rms {rms}"
            );
        }
    }

    #[test]
    fn rdoq_lowers_levels_and_keeps_the_cost_within_the_transforms_rounding() {
        let coder = ResidualCoder::new(1, 1);
        let rate = crate::encode::rate::block8_pricer(&coder, false);
        let mut seed = 3u32;
        let mut noise = || {
            seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
            (seed >> 16) % 23
        };
        let src: [u8; 256] = std::array::from_fn(|i| (70 + (i % 16) * 4) as u8 + noise() as u8);
        let pred = [90; 256];
        for qp in [18u8, 26, 34] {
            let lambda = crate::me::lambda_for_qp(crate::me::Metric::Ssd, qp);
            let plain = inter_luma8(&src, &pred, qp, lambda, None).expect("levels");
            let cost = |b: &Option<Box<[Block8; 4]>>| {
                let zero = Box::new([[[0; 8]; 8]; 4]);
                let b = b.as_ref().unwrap_or(&zero);
                let bits: u32 = b.iter().map(|x| rate.block_cost(x)).sum();
                sse(&src, &reconstruct(&pred, b, qp)) as f64 + lambda * f64::from(bits) / 256.0
            };
            // RDOQ's levels start from a rounding nearer the middle.
            let mut start = Box::new([[[0; 8]; 8]; 4]);
            for (q, levels) in start.iter_mut().enumerate() {
                *levels = forward_8x8(&quadrant_residual(&src, &pred, q));
                quantize_8x8(levels, qp, quant_rounding(false, true));
            }
            drop_costly_small(&mut start);
            let lowered = inter_luma8(&src, &pred, qp, lambda, Some(&rate));
            if let Some(l) = &lowered {
                for (a, b) in l
                    .as_flattened()
                    .as_flattened()
                    .iter()
                    .zip(start.as_flattened().as_flattened())
                {
                    assert!(a.abs() <= b.abs() && (a.signum() == b.signum() || *a == 0));
                }
            }
            // The decisions use the transform domain's error: the true
            // cost may differ by the integer transform's rounding.
            assert!(cost(&lowered) <= cost(&Some(start)) * 1.02, "qp {qp}");
            assert!(cost(&lowered) <= cost(&Some(plain.clone())) * 1.02, "qp {qp}");
        }
    }

    #[test]
    fn lone_small_levels_are_dropped() {
        let mut b = [[[0; 8]; 8]; 4];
        // A lone ±1 late in the scan costs nothing to drop; two ±1 at the
        // scan's start cost 3 + 3 and stay; a level above 1 always stays.
        b[0][7][7] = 1;
        b[1][0][0] = 5;
        b[2][0][1] = -1;
        b[2][1][0] = 1;
        drop_costly_small(&mut b);
        assert_eq!(b[0], [[0; 8]; 8]);
        assert_eq!((b[1][0][0], b[2][0][1], b[2][1][0]), (5, -1, 1));
        // One ±1 near the start costs 3, under 4: dropped like the late one.
        let mut pair = [[[0; 8]; 8]; 4];
        pair[2][0][1] = -1;
        pair[3][4][4] = 1;
        drop_costly_small(&mut pair);
        assert_eq!(pair, [[[0; 8]; 8]; 4]);
    }
}
