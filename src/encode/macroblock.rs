//! One macroblock: its residual (transform, quantisation, the small-block
//! zeroing H.264's reference encoder does), its rate as the frame's
//! residual coder prices it in its present state, and the rate-distortion
//! cost J = SSD + lambda * bits of each way to code it.

use super::transform8x8::inter_luma8;
use crate::codec::bits::ue_len;
use crate::codec::intra::IntraMode;
use crate::codec::recon::{add_luma8, chroma_qp, reconstruct_samples, IntraEdges, MbSamples};
use crate::codec::residual::{BlockClass, BlockPricer, MbResidual, ResidualCoder, ResidualSyntax, ZIGZAG};
use crate::codec::syntax::{intra_mode_allowed, MB};
use crate::codec::transform::{
    dequantize, dequantize_level, forward_4x4, inverse_4x4, inverse_4x4_unrounded, quantize, Block4,
};
use crate::codec::transform8x8::Block8;
use crate::codec::Frame;
use crate::me::Metric;
use crate::metrics::squared_difference_sum;

/// Quantiser rounding offsets (fractions of a step), as in the H.264
/// reference encoder: a wider dead zone for inter residuals, which are
/// mostly noise.
const ROUND_INTRA: f64 = 1.0 / 3.0;
const ROUND_INTER: f64 = 1.0 / 6.0;

/// The source samples of one macroblock.
#[derive(Debug, Clone)]
pub(crate) struct MbSource {
    pub luma: [u8; 256],
    pub chroma: [[u8; 64]; 2],
}

impl MbSource {
    /// Macroblock (mb_x, mb_y) of a coded-size frame.
    pub fn load(frame: &Frame, mb_x: usize, mb_y: usize) -> MbSource {
        let mut s = MbSource {
            luma: [0; 256],
            chroma: [[0; 64]; 2],
        };
        let (x0, y0) = (mb_x * MB, mb_y * MB);
        for r in 0..MB {
            s.luma[r * MB..(r + 1) * MB].copy_from_slice(&frame.y().row(y0 + r)[x0..x0 + MB]);
        }
        for p in 0..2 {
            for r in 0..8 {
                s.chroma[p][r * 8..(r + 1) * 8]
                    .copy_from_slice(&frame.plane(p + 1).row(y0 / 2 + r)[x0 / 2..x0 / 2 + 8]);
            }
        }
        s
    }

    /// Squared error of a prediction (or reconstruction), luma and chroma.
    pub fn ssd(&self, p: &MbSamples) -> u64 {
        let d = squared_difference_sum;
        d(&self.luma, &p.luma) + d(&self.chroma[0], &p.chroma[0]) + d(&self.chroma[1], &p.chroma[1])
    }
}

/// A residual with its rate and the reconstruction it gives.
#[derive(Debug, Clone)]
pub(crate) struct Coded {
    /// On the heap: candidates move it around until one is written.
    pub residual: Box<MbResidual>,
    /// Bits of the coded block pattern, flags and levels (the residual
    /// coder's estimate).
    pub bits: f64,
    /// Squared error of the reconstruction.
    pub ssd: u64,
    /// The reconstructed macroblock.
    pub samples: MbSamples,
}

impl Coded {
    /// `residual` reconstructed as `samples`, measured against `src` and
    /// priced by the frame's `residual_coder` for macroblock `at`.
    fn priced(
        src: &MbSource,
        residual: Box<MbResidual>,
        samples: MbSamples,
        (residual_coder, syntax): (&ResidualCoder, ResidualSyntax),
        (mb_x, mb_y): (usize, usize),
    ) -> Coded {
        Coded {
            bits: f64::from(residual_coder.cost(mb_x, mb_y, syntax, &residual)) / 256.0,
            ssd: src.ssd(&samples),
            residual,
            samples,
        }
    }
}

/// The per-frame constants of macroblock coding.
#[derive(Debug, Clone, Copy)]
pub(crate) struct MbCoder {
    pub qp: u8,
    /// Weight of one bit against squared error.
    pub lambda: f64,
    /// Rate-distortion optimised quantisation (see [`lower_levels`]).
    pub rdoq: bool,
    /// Intra luma may be coded in 4x4 blocks.
    pub intra4x4: bool,
    /// Intra luma may be coded in 8x8 blocks.
    pub intra8x8: bool,
    /// Inter luma may be coded in the 8x8 transform.
    pub transform_8x8: bool,
}

/// H.264 reference-encoder cost of a 4x4 block's levels for the zeroing
/// decision: a level above 1 makes it worth keeping; a lone ±1 costs by
/// how few zeros precede it.
#[inline(always)]
fn coefficient_cost(b: &Block4) -> u32 {
    const COST: [u32; 16] = [3, 2, 2, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
    let flat = b.as_flattened();
    // Which raster positions hold a level (a compare and a bit gather the
    // compiler vectorises), and whether any exceeds 1.
    let (mut raster, mut big) = (0usize, false);
    for (k, &v) in flat.iter().enumerate() {
        raster |= usize::from(v != 0) << k;
        big |= v.unsigned_abs() > 1;
    }
    if big {
        return 999;
    }
    // The same bits in scan order.
    let mut mask = u32::from(TO_SCAN[0][raster & 0xff] | TO_SCAN[1][raster >> 8]);
    // Each level costs by the run of zeros since the previous one.
    let (mut cost, mut next) = (0, 0);
    while mask != 0 {
        let k = mask.trailing_zeros();
        cost += COST[(k - next) as usize];
        next = k + 1;
        mask &= mask - 1;
    }
    cost
}

/// `TO_SCAN[h][m]`: the zig-zag-order bit mask of the raster bits `m` of
/// the block's first (`h` 0) or second (`h` 1) eight positions.
const TO_SCAN: [[u16; 256]; 2] = {
    let mut t = [[0u16; 256]; 2];
    let mut h = 0;
    while h < 2 {
        let mut m = 0;
        while m < 256 {
            let mut k = 0;
            while k < 16 {
                let raster = ZIGZAG[k];
                if raster / 8 == h && (m >> (raster % 8)) & 1 == 1 {
                    t[h][m] |= 1 << k;
                }
                k += 1;
            }
            m += 1;
        }
        h += 1;
    }
    t
};

/// [`coefficient_cost`] summed over blocks.
#[inline(always)]
fn blocks_cost<'a>(blocks: impl IntoIterator<Item = &'a Block4>) -> u32 {
    let mut total = 0;
    for b in blocks {
        total += coefficient_cost(b);
    }
    total
}

/// Lone small levels cost more bits than they save distortion: drops an
/// 8x8 quadrant of inter luma whose levels cost < 4, and all of it when
/// the macroblock's total is < 6 (JM's thresholds).
#[inline(always)]
fn drop_costly_small_luma(luma: &mut [Block4; 16]) {
    let mut total = 0;
    for q in 0..4 {
        let blocks = [0, 1, 4, 5].map(|o| (q % 2) * 2 + (q / 2) * 8 + o);
        let cost = blocks_cost(blocks.iter().map(|&k| &luma[k]));
        if cost < 4 {
            for k in blocks {
                luma[k] = [[0; 4]; 4];
            }
        } else {
            total += cost;
        }
    }
    if total < 6 {
        *luma = [[[0; 4]; 4]; 16];
    }
}

/// Squared error between a residual and what `levels` reconstruct to.
#[inline(always)]
fn block_error(residual: &Block4, levels: &Block4, qp: u8) -> i64 {
    let mut d = *levels;
    dequantize(&mut d, qp);
    let r = inverse_4x4(&d);
    let mut e = 0i64;
    for (a, b) in residual.as_flattened().iter().zip(r.as_flattened()) {
        let x = i64::from(a - b);
        e += x * x;
    }
    e
}

/// Bits `levels` add over an empty block, priced for its class (chroma or
/// luma, intra or inter) in the frame's residual coder as it stands.
#[inline(always)]
fn block_bits(rate: &BlockPricer, levels: &Block4) -> f64 {
    f64::from(rate.block_cost(levels)) / 256.0
}

/// The inverse transform's basis doubled: row `k` is twice the weight of
/// coefficient `k` on each of the four samples in one butterfly pass.
const INVERSE_BASIS_X2: [[i32; 4]; 4] = [[2, 2, 2, 2], [2, 1, -1, -2], [2, -2, -2, 2], [1, -2, 2, -1]];

/// Squared error between a residual and the reconstruction whose inverse
/// transform before the final rounding is `unrounded`.
#[inline(always)]
fn rounded_error(residual: &Block4, unrounded: &Block4) -> i64 {
    let mut e = 0i64;
    for (a, u) in residual.as_flattened().iter().zip(unrounded.as_flattened()) {
        let x = i64::from(a - ((u + 32) >> 6));
        e += x * x;
    }
    e
}

/// Rate-distortion optimised quantisation, greedy: from the last level in
/// scan order to the first, each level moves one step toward zero when
/// that lowers squared error + lambda * bits (the residual coder's price
/// of the block; the error measured after the inverse transform, so the
/// transform's unequal gains are accounted for).
///
/// The error of a step is exact and cheap: when the dequantised
/// coefficient changes by a multiple of 4 (every step from QP 12 up), the
/// butterflies' halvings stay exact, so the inverse transform before its
/// final rounding moves by `d/4` times the coefficient's (doubled) basis
/// block. Other steps go through the whole inverse transform.
#[inline(always)]
fn lower_levels(residual: &Block4, levels: &mut Block4, qp: u8, lambda: f64, rate: &BlockPricer) {
    if levels.as_flattened().iter().all(|&v| v == 0) {
        return;
    }
    let mut coeffs = *levels;
    dequantize(&mut coeffs, qp);
    let mut unrounded = inverse_4x4_unrounded(&coeffs);
    let mut error = rounded_error(residual, &unrounded);
    let mut bits = block_bits(rate, levels);
    for &k in ZIGZAG.iter().rev() {
        let (r, c) = (k / 4, k % 4);
        let v = levels[r][c];
        if v == 0 {
            continue;
        }
        let mut trial = *levels;
        trial[r][c] = v - v.signum();
        let coeff = dequantize_level(trial[r][c], qp, r, c);
        let delta = coeff - coeffs[r][c];
        let moved = if delta % 4 == 0 {
            let mut u = unrounded;
            for (rr, row) in u.iter_mut().enumerate() {
                for (cc, x) in row.iter_mut().enumerate() {
                    *x += delta / 4 * INVERSE_BASIS_X2[r][rr] * INVERSE_BASIS_X2[c][cc];
                }
            }
            u
        } else {
            let mut d = coeffs;
            d[r][c] = coeff;
            inverse_4x4_unrounded(&d)
        };
        let e = rounded_error(residual, &moved);
        // Fewer bits than none cannot pay for more error than this.
        if (e - error) as f64 >= lambda * bits {
            continue;
        }
        let b = block_bits(rate, &trial);
        if (e - error) as f64 + lambda * (b - bits) < 0.0 {
            *levels = trial;
            coeffs[r][c] = coeff;
            unrounded = moved;
            error = e;
            bits = b;
        }
    }
    // Last, the whole block against none of it.
    if bits > 0.0 {
        let zero = [[0; 4]; 4];
        if (block_error(residual, &zero, qp) - error) as f64 <= lambda * bits {
            *levels = zero;
        }
    }
}

impl MbCoder {
    pub fn new(qp: u8, lambda_scale: f64, rdoq: bool) -> MbCoder {
        MbCoder {
            qp,
            lambda: lambda_scale * crate::me::lambda_for_qp(Metric::Ssd, qp),
            rdoq,
            intra4x4: true,
            intra8x8: true,
            transform_8x8: true,
        }
    }

    /// This coder with 4x4 intra on or off.
    pub fn intra4x4(self, on: bool) -> MbCoder {
        MbCoder { intra4x4: on, ..self }
    }

    /// This coder with 8x8 intra on or off.
    pub fn intra8x8(self, on: bool) -> MbCoder {
        MbCoder { intra8x8: on, ..self }
    }

    /// This coder with the inter 8x8 transform on or off.
    pub fn transform_8x8(self, on: bool) -> MbCoder {
        MbCoder {
            transform_8x8: on,
            ..self
        }
    }

    /// Transforms and quantises `src - pred`, reconstructs the macroblock
    /// (through the codec, as the decoder will) and measures it, the rate
    /// priced by `residual_coder` (the frame's, as it stands before
    /// macroblock (mb_x, mb_y)).
    pub fn code(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        intra: bool,
        residual_coder: &ResidualCoder,
        mb_x: usize,
        mb_y: usize,
    ) -> Coded {
        #[cfg(target_arch = "x86_64")]
        {
            // std caches the answer after the first call.
            if crate::codec::cpu::at_least(crate::codec::cpu::CpuLevel::Avx2) {
                // SAFETY: the CPU has AVX2; the function is the safe code
                // below compiled with AVX2 (integer arithmetic and the same
                // floating-point operations: the same result).
                return unsafe { self.code_avx2(src, pred, intra, residual_coder, mb_x, mb_y) };
            }
        }
        self.code_body(src, pred, intra, residual_coder, mb_x, mb_y)
    }

    /// [`MbCoder::code`] compiled for AVX2: the baseline x86-64 build has
    /// no 32-bit vector multiply, so the quantiser and RDOQ's error updates
    /// would run a coefficient at a time.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn code_avx2(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        intra: bool,
        residual_coder: &ResidualCoder,
        mb_x: usize,
        mb_y: usize,
    ) -> Coded {
        self.code_body(src, pred, intra, residual_coder, mb_x, mb_y)
    }

    /// One 4x4 block of `s - p` (`size` samples a row, block column `bx`,
    /// row `by`) and its levels, quantised without RDOQ.
    #[inline(always)]
    fn block_levels(
        s: &[u8],
        p: &[u8],
        size: usize,
        (bx, by): (usize, usize),
        qp: u8,
        intra: bool,
    ) -> (Block4, Block4) {
        let mut b = [[0i32; 4]; 4];
        for (r, row) in b.iter_mut().enumerate() {
            let i = (by * 4 + r) * size + bx * 4;
            for (c, v) in row.iter_mut().enumerate() {
                *v = i32::from(s[i + c]) - i32::from(p[i + c]);
            }
        }
        let mut c = forward_4x4(&b);
        quantize(&mut c, qp, if intra { ROUND_INTRA } else { ROUND_INTER });
        (b, c)
    }

    /// The levels of intra luma block (bx, by) (in blocks) of `src -
    /// pred`, as [`MbCoder::code`] quantises them (RDOQ priced by `rate`
    /// when given): what a 4x4 intra search reconstructs each block from.
    pub fn intra_luma_levels(
        &self,
        src: &MbSource,
        pred: &[u8; 256],
        at: (usize, usize),
        rate: Option<&BlockPricer>,
    ) -> Block4 {
        let (diff, mut levels) = Self::block_levels(&src.luma, pred, MB, at, self.qp, true);
        if let Some(rate) = rate {
            lower_levels(&diff, &mut levels, self.qp, self.lambda, rate);
        }
        levels
    }

    #[inline(always)]
    fn code_body(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        intra: bool,
        residual_coder: &ResidualCoder,
        mb_x: usize,
        mb_y: usize,
    ) -> Coded {
        let mut residual = Box::<MbResidual>::default();
        let mut luma_residual = [[[0i32; 4]; 4]; 16];
        for (k, (block, diff)) in residual.luma.iter_mut().zip(&mut luma_residual).enumerate() {
            (*diff, *block) = Self::block_levels(&src.luma, &pred.luma, MB, (k % 4, k / 4), self.qp, intra);
        }
        // Inter blocks are zeroed below where their levels cost little.
        // RDOQ only lowers levels, and lowering never raises that cost, so
        // what the rule zeroes before RDOQ it zeroes after it too: it is
        // applied first, and RDOQ spends no work on those blocks.
        if !intra {
            drop_costly_small_luma(&mut residual.luma);
        }
        // (Pricers are made only for levels left to lower.)
        let coded = |blocks: &[Block4]| blocks.iter().any(|b| b.as_flattened().iter().any(|&v| v != 0));
        if self.rdoq && coded(&residual.luma) {
            let rate = residual_coder.block_pricer(BlockClass::luma(intra));
            for (block, diff) in residual.luma.iter_mut().zip(&luma_residual) {
                lower_levels(diff, block, self.qp, self.lambda, &rate);
            }
            if !intra {
                drop_costly_small_luma(&mut residual.luma);
            }
        }
        self.code_chroma(src, pred, intra, residual_coder, &mut residual);
        let samples = reconstruct_samples(pred, &residual, self.qp);
        Coded::priced(
            src,
            residual,
            samples,
            (residual_coder, ResidualSyntax::of_4x4(intra)),
            (mb_x, mb_y),
        )
    }

    /// The chroma levels of `src - pred` into `residual`, as
    /// [`MbCoder::code`] quantises them.
    #[inline(always)]
    fn code_chroma(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        intra: bool,
        residual_coder: &ResidualCoder,
        residual: &mut MbResidual,
    ) {
        let coded = |blocks: &[Block4]| blocks.iter().any(|b| b.as_flattened().iter().any(|&v| v != 0));
        let cqp = chroma_qp(self.qp);
        let mut chroma_rate = None;
        for p in 0..2 {
            let mut diffs = [[[0i32; 4]; 4]; 4];
            for (k, (block, diff)) in residual.chroma[p].iter_mut().zip(&mut diffs).enumerate() {
                (*diff, *block) =
                    Self::block_levels(&src.chroma[p], &pred.chroma[p], 8, (k % 2, k / 2), cqp, intra);
            }
            let cheap = |blocks: &[Block4; 4]| blocks_cost(blocks) < 4;
            if !intra && cheap(&residual.chroma[p]) {
                residual.chroma[p] = [[[0; 4]; 4]; 4];
                continue;
            }
            if self.rdoq && coded(&residual.chroma[p]) {
                let rate =
                    chroma_rate.get_or_insert_with(|| residual_coder.block_pricer(BlockClass::chroma(intra)));
                for (block, diff) in residual.chroma[p].iter_mut().zip(&diffs) {
                    lower_levels(diff, block, cqp, self.lambda, rate);
                }
                if !intra && cheap(&residual.chroma[p]) {
                    residual.chroma[p] = [[[0; 4]; 4]; 4];
                }
            }
        }
    }

    /// An intra macroblock coded in 8x8 blocks: `pred` (each luma block
    /// predicted from the reconstruction of those before it with `luma8`,
    /// the levels the search chose), the chroma coded as [`MbCoder::code`]
    /// codes it.
    pub fn code_intra8x8(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        luma8: Option<Box<[Block8; 4]>>,
        residual_coder: &ResidualCoder,
        at: (usize, usize),
    ) -> Coded {
        let mut residual = Box::new(MbResidual {
            luma8,
            ..MbResidual::default()
        });
        self.code_chroma(src, pred, true, residual_coder, &mut residual);
        let samples = reconstruct_samples(pred, &residual, self.qp);
        Coded::priced(
            src,
            residual,
            samples,
            (residual_coder, ResidualSyntax::Intra8x8),
            at,
        )
    }

    /// An inter macroblock's `residual` and reconstructed `samples` (as
    /// [`MbCoder::code`] codes them, in 4x4 transforms) with its luma in
    /// the 8x8 transform instead, when this coder allows it, the 4x4
    /// transforms left luma levels and the 8x8 one leaves some: the chroma
    /// kept, the rate priced as [`MbCoder::code`] prices it. Whichever
    /// costs less is the caller's to keep (x264 decides the transform size
    /// once the mode is decided).
    ///
    /// Trying it where the 4x4 transforms left no luma levels too gained
    /// 0.2 % more on the development set's mean (-0.8 % against -0.6 %,
    /// BD-rate against no 8x8 transform) for twice the time (+11 % against
    /// +6 % of the medium preset's on pan_cif).
    pub fn luma8_alternative(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        (residual, samples): (&MbResidual, &MbSamples),
        residual_coder: &ResidualCoder,
        at: (usize, usize),
    ) -> Option<Coded> {
        if !self.transform_8x8 || residual.cbp() & 15 == 0 {
            return None;
        }
        #[cfg(target_arch = "x86_64")]
        {
            if crate::codec::cpu::at_least(crate::codec::cpu::CpuLevel::Avx2) {
                // SAFETY: the CPU has AVX2; the same safe code compiled
                // with it (integer arithmetic and the same floating-point
                // operations: the same result).
                return unsafe { self.luma8_avx2(src, pred, (residual, samples), residual_coder, at) };
            }
        }
        self.luma8_body(src, pred, (residual, samples), residual_coder, at)
    }

    /// [`MbCoder::luma8_alternative`] compiled for AVX2 (the transforms'
    /// and quantiser's 32-bit multiplies eight at a time).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn luma8_avx2(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        (residual, samples): (&MbResidual, &MbSamples),
        residual_coder: &ResidualCoder,
        at: (usize, usize),
    ) -> Option<Coded> {
        self.luma8_body(src, pred, (residual, samples), residual_coder, at)
    }

    #[inline(always)]
    fn luma8_body(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        (residual, samples): (&MbResidual, &MbSamples),
        residual_coder: &ResidualCoder,
        at: (usize, usize),
    ) -> Option<Coded> {
        let rate = self.rdoq.then(|| residual_coder.block8_pricer(false));
        let luma8 = inter_luma8(&src.luma, &pred.luma, self.qp, self.lambda, rate.as_ref())?;
        // The chroma as coded already: only the luma is reconstructed.
        let mut samples = samples.clone();
        samples.luma = pred.luma;
        add_luma8(&luma8, self.qp, &mut samples.luma);
        let mut residual = Box::new(residual.clone());
        residual.luma = Default::default();
        residual.luma8 = Some(luma8);
        Some(Coded::priced(
            src,
            residual,
            samples,
            (residual_coder, ResidualSyntax::Inter),
            at,
        ))
    }

    /// [`MbCoder::code`] of an inter macroblock, then the cheaper of it and
    /// its [`MbCoder::luma8_alternative`].
    pub fn code_inter(
        &self,
        src: &MbSource,
        pred: &MbSamples,
        residual_coder: &ResidualCoder,
        mb_x: usize,
        mb_y: usize,
    ) -> Coded {
        let coded = self.code(src, pred, false, residual_coder, mb_x, mb_y);
        let coded4 = (&*coded.residual, &coded.samples);
        match self.luma8_alternative(src, pred, coded4, residual_coder, (mb_x, mb_y)) {
            Some(c8) if self.cost(c8.ssd, c8.bits) < self.cost(coded.ssd, coded.bits) => c8,
            _ => coded,
        }
    }

    /// J = SSD + lambda * bits.
    pub fn cost(&self, ssd: u64, bits: f64) -> f64 {
        ssd as f64 + self.lambda * bits
    }

    /// The luma intra mode allowed at (mb_x, mb_y) with the smallest SATD
    /// plus the mode's bits, its prediction (into `pred.luma`) and SATD.
    /// (Luma and chroma modes are independent: each plane's is chosen on
    /// its own.)
    pub fn best_intra_luma(
        &self,
        src: &MbSource,
        recon: &Frame,
        (mb_x, mb_y): (usize, usize),
        pred: &mut MbSamples,
    ) -> (IntraMode, u32) {
        let sad_lambda = self.lambda.sqrt();
        let mut trial = [0u8; 256];
        let (mut luma, mut best_cost, mut satd) = (IntraMode::Dc, f64::INFINITY, 0);
        let edges = IntraEdges::of(recon, 0, mb_x, mb_y);
        for m in allowed_intra_modes(mb_x, mb_y) {
            edges.predict(m, &mut trial);
            let d = Metric::Satd.cost(&src.luma, MB, &trial, MB, MB, MB);
            let c = f64::from(d) + sad_lambda * f64::from(ue_len(m as u32));
            if c < best_cost {
                (luma, best_cost, satd) = (m, c, d);
                pred.luma = trial;
            }
        }
        (luma, satd)
    }

    /// The chroma intra mode allowed at (mb_x, mb_y) with the smallest SAD
    /// (both planes) plus the mode's bits, and its prediction (into
    /// `pred.chroma`).
    pub fn best_intra_chroma(
        &self,
        src: &MbSource,
        recon: &Frame,
        (mb_x, mb_y): (usize, usize),
        pred: &mut MbSamples,
    ) -> IntraMode {
        let sad_lambda = self.lambda.sqrt();
        let mut chroma = IntraMode::Dc;
        let mut best_c = f64::INFINITY;
        let mut trial = [[0u8; 64]; 2];
        let edges = [1, 2].map(|p| IntraEdges::of(recon, p, mb_x, mb_y));
        for m in allowed_intra_modes(mb_x, mb_y) {
            let mut c = sad_lambda * f64::from(ue_len(m as u32));
            for (k, t) in trial.iter_mut().enumerate() {
                edges[k].predict(m, t);
                c += f64::from(Metric::Sad.cost(&src.chroma[k], 8, t, 8, 8, 8));
            }
            if c < best_c {
                (chroma, best_c) = (m, c);
                pred.chroma = trial;
            }
        }
        chroma
    }
}

/// The intra modes macroblock (mb_x, mb_y) has the neighbours for.
fn allowed_intra_modes(mb_x: usize, mb_y: usize) -> impl Iterator<Item = IntraMode> {
    IntraMode::ALL
        .into_iter()
        .filter(move |&m| intra_mode_allowed(m, mb_x, mb_y))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coefficient_cost_equals_the_scan_walk() {
        // The reference encoder's definition, walked in scan order.
        fn walk(b: &Block4) -> u32 {
            const COST: [u32; 16] = [3, 2, 2, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0];
            let (mut cost, mut run) = (0, 0);
            for &k in &ZIGZAG {
                let v = b[k / 4][k % 4];
                if v == 0 {
                    run += 1;
                } else if v.abs() > 1 {
                    return 999;
                } else {
                    cost += COST[run];
                    run = 0;
                }
            }
            cost
        }
        let mut seed = 3u32;
        for _ in 0..20_000 {
            let mut b = [[0i32; 4]; 4];
            for v in b.as_flattened_mut() {
                seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
                *v = match (seed >> 16) % 12 {
                    0 => 1,
                    1 => -1,
                    2 if seed % 7 == 0 => 2,
                    _ => 0,
                };
            }
            assert_eq!(coefficient_cost(&b), walk(&b), "{b:?}");
        }
    }

    #[test]
    fn coefficient_cost_keeps_large_levels_and_prices_lone_ones() {
        let mut b = [[0; 4]; 4];
        assert_eq!(coefficient_cost(&b), 0);
        b[0][0] = 1; // first in scan order, no zeros before it
        assert_eq!(coefficient_cost(&b), 3);
        b[3][3] = -1; // last, after 14 zeros
        assert_eq!(coefficient_cost(&b), 3);
        b[1][1] = 2;
        assert_eq!(coefficient_cost(&b), 999);
    }

    #[test]
    fn the_dispatched_coding_equals_its_baseline_twin() {
        let mut seed = 99u32;
        let mut next = |spread: u32| {
            seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
            ((seed >> 16) % spread) as u8
        };
        let mut residual_coder = ResidualCoder::new(2, 2);
        for case in 0..60 {
            let (qp, intra) = ([4, 18, 28, 40, 51][case % 5], case % 2 == 0);
            let coder = MbCoder::new(qp, 1.0, case % 3 != 0);
            let mut src = MbSource {
                luma: [0; 256],
                chroma: [[0; 64]; 2],
            };
            let mut pred = MbSamples::default();
            // Residuals from small noise to full-range differences.
            let spread = [4, 32, 256][case % 3];
            for (s, p) in src.luma.iter_mut().zip(pred.luma.iter_mut()) {
                (*s, *p) = (next(256), next(spread));
            }
            for (s, p) in src
                .chroma
                .iter_mut()
                .flatten()
                .zip(pred.chroma.iter_mut().flatten())
            {
                (*s, *p) = (next(256), next(spread));
            }
            let a = coder.code(&src, &pred, intra, &residual_coder, case % 2, 1);
            let b = coder.code_body(&src, &pred, intra, &residual_coder, case % 2, 1);
            assert_eq!(a.residual, b.residual, "case {case}");
            assert_eq!((a.bits, a.ssd), (b.bits, b.ssd), "case {case}");
            assert_eq!(a.samples, b.samples, "case {case}");
            // Later cases price with adapted contexts.
            residual_coder.commit(case % 2, 0, ResidualSyntax::of_4x4(intra), &a.residual);
        }
    }

    #[test]
    fn rdoq_only_moves_levels_toward_zero_and_never_raises_the_cost() {
        let qp = 28;
        let lambda = MbCoder::new(qp, 1.4, true).lambda;
        let mut seed = 12345u32;
        for _ in 0..500 {
            let mut residual = [[0i32; 4]; 4];
            for v in residual.iter_mut().flatten() {
                seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
                *v = ((seed >> 16) % 61) as i32 - 30;
            }
            let mut levels = forward_4x4(&residual);
            quantize(&mut levels, qp, ROUND_INTER);
            let before = levels;
            let rate = ResidualCoder::new(1, 1).block_pricer(BlockClass::luma(false));
            lower_levels(&residual, &mut levels, qp, lambda, &rate);
            let cost = |l: &Block4| block_error(&residual, l, qp) as f64 + lambda * block_bits(&rate, l);
            assert!(cost(&levels) <= cost(&before) + 1e-9);
            for (a, b) in levels.iter().flatten().zip(before.iter().flatten()) {
                assert!(a.abs() <= b.abs() && a * b >= 0, "{a} from {b}");
            }
        }
    }
}
