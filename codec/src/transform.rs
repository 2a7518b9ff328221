//! The 4x4 integer transform and its quantisation, after H.264 (8.5.12).
//!
//! The forward core transform `W = Cf X Cf^T` with
//! `Cf = [[1,1,1,1],[2,1,-1,-2],[1,-1,-1,1],[1,-2,2,-1]]` is exact integer
//! arithmetic; its non-unit norms are folded into the quantiser (`MF`) and
//! the normative dequantiser (`V`). The quantiser step doubles every 6 QP:
//! `Qstep(qp) = Qstep(qp % 6) * 2^(qp / 6)`, from 0.625 at QP 0 to 224 at
//! QP 51.
//!
//! Normative (the decoder does exactly this): [`dequantize`], which clamps
//! every dequantised coefficient to the 16-bit range so that no bitstream can
//! overflow the inverse, and [`inverse_4x4`]. The forward transform and
//! [`quantize`] are the reference the encoder uses; their rounding is an
//! encoder choice.
//!
//! ```
//! use mocomp_codec::transform::{dequantize, forward_4x4, inverse_4x4, quantize};
//! let residual = [[5, 11, 8, 10], [9, 8, 4, 12], [1, 10, 11, 4], [19, 6, 15, 7]];
//! let qp = 10;
//! let mut c = forward_4x4(&residual);
//! quantize(&mut c, qp, 1.0 / 3.0);
//! dequantize(&mut c, qp);
//! let back = inverse_4x4(&c);
//! for y in 0..4 {
//!     for x in 0..4 {
//!         assert!((back[y][x] - residual[y][x]).abs() <= 3);
//!     }
//! }
//! ```

pub use crate::consts::MAX_QP;

/// Chroma QP from luma QP (H.264 Table 8-15).
pub fn chroma_qp(qp: u8) -> u8 {
    const ABOVE_29: [u8; 22] = [
        29, 30, 31, 32, 32, 33, 34, 34, 35, 35, 36, 36, 37, 37, 37, 38, 38, 38, 39, 39, 39, 39,
    ];
    if qp < 30 {
        qp
    } else {
        ABOVE_29[usize::from(qp.min(51)) - 30]
    }
}

/// A 4x4 block of samples or coefficients, `[row][column]`.
pub type Block4 = [[i32; 4]; 4];

/// Dequantisation scale `V` for `qp % 6` (H.264 Table 8-13's `v`): columns
/// are positions with both indices even, both odd, and the rest.
const DEQUANT: [[i32; 3]; 6] = [
    [10, 16, 13],
    [11, 18, 14],
    [13, 20, 16],
    [14, 23, 18],
    [16, 25, 20],
    [18, 29, 23],
];

/// Quantisation multipliers `MF` for `qp % 6`, same columns; `MF * V` is
/// close to `2^15 * 16 / norm^2`, so quantise + dequantise + inverse is the
/// identity up to rounding.
const QUANT: [[i32; 3]; 6] = [
    [13107, 5243, 8066],
    [11916, 4660, 7490],
    [10082, 4194, 6554],
    [9362, 3647, 5825],
    [8192, 3355, 5243],
    [7282, 2893, 4559],
];

/// Which of the three scale classes position (row, col) falls in.
#[inline]
const fn class(row: usize, col: usize) -> usize {
    match (row % 2, col % 2) {
        (0, 0) => 0,
        (1, 1) => 1,
        _ => 2,
    }
}

/// The quantiser step at `qp` (informative: the codec uses the integer
/// tables, this is for rate-distortion and documentation).
pub fn qstep(qp: u8) -> f64 {
    const BASE: [f64; 6] = [0.625, 0.6875, 0.8125, 0.875, 1.0, 1.125];
    BASE[(qp % 6) as usize] * f64::from(1u32 << (qp / 6))
}

/// Forward core transform `Cf X Cf^T` (exact; inputs up to 16 bits give
/// outputs within 22 bits).
#[inline]
pub fn forward_4x4(x: &Block4) -> Block4 {
    let mut tmp = [[0i32; 4]; 4];
    for (i, row) in x.iter().enumerate() {
        let (s03, d03) = (row[0] + row[3], row[0] - row[3]);
        let (s12, d12) = (row[1] + row[2], row[1] - row[2]);
        tmp[i] = [s03 + s12, 2 * d03 + d12, s03 - s12, d03 - 2 * d12];
    }
    let mut out = [[0i32; 4]; 4];
    for j in 0..4 {
        let (s03, d03) = (tmp[0][j] + tmp[3][j], tmp[0][j] - tmp[3][j]);
        let (s12, d12) = (tmp[1][j] + tmp[2][j], tmp[1][j] - tmp[2][j]);
        out[0][j] = s03 + s12;
        out[1][j] = 2 * d03 + d12;
        out[2][j] = s03 - s12;
        out[3][j] = d03 - 2 * d12;
    }
    out
}

/// Quantises transform coefficients in place:
/// `level = sign(w) * ((|w| * MF + f * 2^(15 + qp/6)) >> (15 + qp/6))`, with
/// the rounding offset `f` in [0, 0.5] (H.264's reference encoder uses 1/3
/// for intra and 1/6 for inter blocks).
#[inline(always)]
pub fn quantize(coeffs: &mut Block4, qp: u8, rounding: f64) {
    let q = Quantizer4x4::new(qp, rounding);
    // Magnitudes below 2^17 (every 8-bit residual's) keep |w| * MF +
    // offset within 32 bits (MF < 2^14, offset <= 2^22).
    quantize_levels(
        coeffs.as_flattened_mut(),
        q.multipliers,
        (q.shift, q.offset),
        1 << 17,
    );
}

/// What [`quantize`] computes a 4x4 block's levels with, for kernels that
/// quantise several blocks at once.
#[derive(Debug, Clone, Copy)]
pub struct Quantizer4x4 {
    /// MF of each position, row by row.
    pub multipliers: &'static [u32; 16],
    /// `15 + qp / 6`.
    pub shift: u32,
    /// The rounding offset `f * 2^shift` (below `2^shift / 2 + 1`).
    pub offset: u64,
}

impl Quantizer4x4 {
    /// The quantiser of `qp` with rounding offset `rounding` (clamped to
    /// [0, 0.5]); panics above [`MAX_QP`].
    #[inline(always)]
    pub fn new(qp: u8, rounding: f64) -> Quantizer4x4 {
        assert!(qp <= MAX_QP, "qp {qp} above {MAX_QP}");
        let shift = 15 + u32::from(qp / 6);
        Quantizer4x4 {
            multipliers: &QUANT_BY_POSITION[(qp % 6) as usize],
            shift,
            offset: (rounding.clamp(0.0, 0.5) * f64::from(1u32 << shift)) as u64,
        }
    }
}

/// `w = sign(w) ((|w| mf + offset) >> shift)` over coefficients and their
/// multipliers; in 32-bit arithmetic, which vectorises, when every
/// magnitude is below `small` (the caller's bound for that to be exact).
#[inline(always)]
pub(crate) fn quantize_levels(w: &mut [i32], mf: &[u32], (shift, offset): (u32, u64), small: u32) {
    if w.iter().all(|v| v.unsigned_abs() < small) {
        let offset = offset as u32;
        for (w, &m) in w.iter_mut().zip(mf) {
            let level = ((w.unsigned_abs() * m + offset) >> shift) as i32;
            *w = if *w < 0 { -level } else { level };
        }
    } else {
        for (w, &m) in w.iter_mut().zip(mf) {
            let level = ((u64::from(w.unsigned_abs()) * u64::from(m) + offset) >> shift) as i32;
            *w = if *w < 0 { -level } else { level };
        }
    }
}

/// The 2x2 Hadamard transform of a chroma plane's four values, in block
/// order (`k = 2 row + column`): `H c H` with `H = [[1, 1], [1, -1]]`. It
/// is its own inverse up to a factor of 4.
#[inline]
pub fn hadamard_2x2(c: [i32; 4]) -> [i32; 4] {
    let (s01, d01) = (c[0] + c[1], c[0] - c[1]);
    let (s23, d23) = (c[2] + c[3], c[2] - c[3]);
    [s01 + s23, d01 + d23, s01 - s23, d01 - d23]
}

/// A chroma plane's DC levels (H.264 8.5.11, the encoder's side): the 2x2
/// Hadamard transform of its four blocks' DC coefficients (`dc`, block
/// order, as [`forward_4x4`] gives them), quantised with the DC position's
/// multiplier one bit further down, `rounding` as [`quantize`]'s.
pub fn quantize_chroma_dc(dc: [i32; 4], qp: u8, rounding: f64) -> [i32; 4] {
    let q = Quantizer4x4::new(qp, rounding);
    let (mf, shift) = (u64::from(q.multipliers[0]), q.shift + 1);
    let offset = 2 * q.offset;
    // No transformed value exceeds the sum of magnitudes: most planes
    // quantise to nothing.
    let bound: u64 = dc.iter().map(|v| u64::from(v.unsigned_abs())).sum();
    if (bound * mf + offset) >> shift == 0 {
        return [0; 4];
    }
    hadamard_2x2(dc).map(|f| quantize_dc(i64::from(f), mf as i64, (offset as i64, shift)))
}

/// `sign(f) ((|f| mf + offset) >> shift)`: one value of a DC transform
/// quantised.
#[inline]
fn quantize_dc(f: i64, mf: i64, (offset, shift): (i64, u32)) -> i32 {
    let level = ((f.abs() * mf + offset) >> shift) as i32;
    if f < 0 {
        -level
    } else {
        level
    }
}

/// Normative: one value `c` of a DC transform of levels scaled as the DC
/// position is at `qp`, divided by `2^down` (rounding half up) and clamped
/// to the 16-bit range as [`dequantize`] clamps. `c` is a sum of at most
/// sixteen levels of at most 2^15 (the reader's bound): no overflow.
#[inline]
fn dequantize_dc(c: i64, qp: u8, down: u32) -> i32 {
    debug_assert!(qp <= MAX_QP);
    let v = i64::from(DEQUANT[(qp % 6) as usize][0]);
    ((((c * v) << (qp / 6)) + (1 << (down - 1))) >> down).clamp(-32768, 32767) as i32
}

/// Normative: the DC coefficients of a chroma plane's four blocks from its
/// DC levels (`levels`, block order; FORMAT.md section 10.1): the 2x2
/// Hadamard transform of the levels, each scaled as the DC position is at
/// `qp` and halved (rounding half up), clamped to the 16-bit range as
/// [`dequantize`] clamps. The first level alone, `2 l`, gives every block
/// the DC coefficient that a block's own DC level `l` dequantises to.
pub fn dequantize_chroma_dc(levels: [i32; 4], qp: u8) -> [i32; 4] {
    let l = levels.map(i64::from);
    let (s01, d01) = (l[0] + l[1], l[0] - l[1]);
    let (s23, d23) = (l[2] + l[3], l[2] - l[3]);
    [s01 + s23, d01 + d23, s01 - s23, d01 - d23].map(|c| dequantize_dc(c, qp, 1))
}

/// The 4x4 Hadamard transform of a macroblock's sixteen values in raster
/// order of its 4x4 blocks (`k = 4 row + column`): `H c H` with `H` the
/// 4x4 matrix of rows `[1, 1, 1, 1]`, `[1, 1, -1, -1]`, `[1, -1, -1, 1]`,
/// `[1, -1, 1, -1]` (H.264 8.5.10). It is its own inverse up to a factor
/// of 16.
#[inline]
pub fn hadamard_4x4(c: [i64; 16]) -> [i64; 16] {
    let mut tmp = [0i64; 16];
    for r in 0..4 {
        let row = &c[4 * r..4 * r + 4];
        let (s01, d01) = (row[0] + row[1], row[0] - row[1]);
        let (s23, d23) = (row[2] + row[3], row[2] - row[3]);
        tmp[4 * r..4 * r + 4].copy_from_slice(&[s01 + s23, s01 - s23, d01 - d23, d01 + d23]);
    }
    let mut out = [0i64; 16];
    for col in 0..4 {
        let at = |r: usize| tmp[4 * r + col];
        let (s01, d01) = (at(0) + at(1), at(0) - at(1));
        let (s23, d23) = (at(2) + at(3), at(2) - at(3));
        for (r, v) in [s01 + s23, s01 - s23, d01 - d23, d01 + d23]
            .into_iter()
            .enumerate()
        {
            out[4 * r + col] = v;
        }
    }
    out
}

/// An intra 16x16 macroblock's luma DC levels (H.264 8.5.10, the encoder's
/// side): the 4x4 Hadamard transform of its sixteen blocks' DC
/// coefficients (`dc`, raster order of the blocks, as [`forward_4x4`]
/// gives them), quantised with the DC position's multiplier two bits
/// further down, `rounding` as [`quantize`]'s.
pub fn quantize_luma_dc(dc: [i32; 16], qp: u8, rounding: f64) -> [i32; 16] {
    let q = Quantizer4x4::new(qp, rounding);
    let (mf, shift) = (q.multipliers[0] as i64, q.shift + 2);
    let offset = 4 * q.offset as i64;
    hadamard_4x4(dc.map(i64::from)).map(|f| quantize_dc(f, mf, (offset, shift)))
}

/// Normative: the DC coefficients of an intra 16x16 macroblock's sixteen
/// luma blocks from its luma DC levels (`levels`, raster order of the
/// blocks; FORMAT.md section 10.1): the 4x4 Hadamard transform of the
/// levels, each scaled as the DC position is at `qp` and divided by 4
/// (rounding half up), clamped to the 16-bit range as [`dequantize`]
/// clamps. The first level alone, `4 l`, gives every block the DC
/// coefficient that a block's own DC level `l` dequantises to.
pub fn dequantize_luma_dc(levels: [i32; 16], qp: u8) -> [i32; 16] {
    hadamard_4x4(levels.map(i64::from)).map(|c| dequantize_dc(c, qp, 2))
}

/// [`QUANT`] spread over the 16 positions of a block, row by row.
const QUANT_BY_POSITION: [[u32; 16]; 6] = {
    let mut t = [[0u32; 16]; 6];
    let mut q = 0;
    while q < 6 {
        let mut k = 0;
        while k < 16 {
            t[q][k] = QUANT[q][class(k / 4, k % 4)] as u32;
            k += 1;
        }
        q += 1;
    }
    t
};

/// Normative dequantisation in place: `w = level * V << (qp / 6)`, each
/// result clamped to -32768..=32767. `qp` must be at most [`MAX_QP`]
/// (the bitstream reader checks it).
#[inline]
pub fn dequantize(coeffs: &mut Block4, qp: u8) {
    for (r, row) in coeffs.iter_mut().enumerate() {
        for (c, w) in row.iter_mut().enumerate() {
            *w = dequantize_level(*w, qp, r, c);
        }
    }
}

/// [`DEQUANT`] spread over the 16 positions of a block, row by row, for
/// kernels that dequantise a block at once ([`dequantize_level`] is the
/// definition).
pub const DEQUANT_BY_POSITION: [[i32; 16]; 6] = {
    let mut t = [[0i32; 16]; 6];
    let mut q = 0;
    while q < 6 {
        let mut k = 0;
        while k < 16 {
            t[q][k] = DEQUANT[q][class(k / 4, k % 4)];
            k += 1;
        }
        q += 1;
    }
    t
};

/// [`dequantize`] of the one level at row `r`, column `c`: what an encoder
/// trying single levels needs.
#[inline]
pub fn dequantize_level(level: i32, qp: u8, r: usize, c: usize) -> i32 {
    debug_assert!(qp <= MAX_QP);
    let v = DEQUANT[(qp % 6) as usize][class(r, c)];
    // i64: a level is at most 2^31 in magnitude, so this cannot overflow.
    let value = (i64::from(level) * i64::from(v)) << (qp / 6);
    value.clamp(-32768, 32767) as i32
}

/// Normative inverse transform (H.264 8.5.12.2), with the final rounding
/// `(x + 32) >> 6`. Inputs within 16 bits keep every intermediate within
/// 20 bits.
#[inline]
pub fn inverse_4x4(d: &Block4) -> Block4 {
    let mut out = inverse_4x4_unrounded(d);
    for v in out.as_flattened_mut() {
        *v = (*v + 32) >> 6;
    }
    out
}

/// [`inverse_4x4`] before its final rounding: what an encoder weighing
/// changes of single coefficients can update in place.
#[inline]
pub fn inverse_4x4_unrounded(d: &Block4) -> Block4 {
    let mut tmp = [[0i32; 4]; 4];
    for (i, row) in d.iter().enumerate() {
        let (e, f) = (row[0] + row[2], row[0] - row[2]);
        let (g, h) = ((row[1] >> 1) - row[3], row[1] + (row[3] >> 1));
        tmp[i] = [e + h, f + g, f - g, e - h];
    }
    let mut out = [[0i32; 4]; 4];
    for j in 0..4 {
        let (e, f) = (tmp[0][j] + tmp[2][j], tmp[0][j] - tmp[2][j]);
        let (g, h) = ((tmp[1][j] >> 1) - tmp[3][j], tmp[1][j] + (tmp[3][j] >> 1));
        out[0][j] = e + h;
        out[1][j] = f + g;
        out[2][j] = f - g;
        out[3][j] = e - h;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The textbook matrix product, to check the butterflies against.
    fn matmul(a: &[[i64; 4]; 4], b: &[[i64; 4]; 4]) -> [[i64; 4]; 4] {
        let mut out = [[0i64; 4]; 4];
        for i in 0..4 {
            for j in 0..4 {
                out[i][j] = (0..4).map(|k| a[i][k] * b[k][j]).sum();
            }
        }
        out
    }

    fn transpose(a: &[[i64; 4]; 4]) -> [[i64; 4]; 4] {
        let mut t = [[0i64; 4]; 4];
        for i in 0..4 {
            for j in 0..4 {
                t[i][j] = a[j][i];
            }
        }
        t
    }

    const CF: [[i64; 4]; 4] = [[1, 1, 1, 1], [2, 1, -1, -2], [1, -1, -1, 1], [1, -2, 2, -1]];

    fn block(values: &[i32]) -> Block4 {
        let mut b = [[0; 4]; 4];
        for (i, v) in values.iter().enumerate() {
            b[i / 4][i % 4] = *v;
        }
        b
    }

    #[test]
    fn step_doubles_every_six_and_tables_agree() {
        for qp in 0..=MAX_QP - 6 {
            assert_eq!(qstep(qp + 6), 2.0 * qstep(qp));
        }
        assert_eq!((qstep(0), qstep(4), qstep(51)), (0.625, 1.0, 224.0));
        // MF = PF / Qstep * 2^15 and V = Qstep * PFi * 64, so MF * V =
        // PF * PFi * 2^21 whatever the QP: 1/16, 1/25 and 1/20 of 2^21 for
        // the three position classes. The integer tables hold this within 0.05 %.
        let want = [2f64.powi(21) / 16.0, 2f64.powi(21) / 25.0, 2f64.powi(21) / 20.0];
        for m in 0..6 {
            for c in 0..3 {
                let product = f64::from(QUANT[m][c] * DEQUANT[m][c]);
                assert!(
                    (product / want[c] - 1.0).abs() < 5e-4,
                    "qp%6 {m} class {c}: {product}"
                );
            }
        }
    }

    #[test]
    fn reconstruction_error_per_qp() {
        // Deterministic pseudo-random residual blocks in -255..=255.
        let mut seed = 0x1234_5678u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed % 511) as i32 - 255
        };
        let blocks: Vec<Block4> = (0..2000)
            .map(|_| [[0; 4]; 4].map(|r: [i32; 4]| r.map(|_| next())))
            .collect();
        for qp in 0..=MAX_QP {
            let (mut se, mut max, mut n) = (0f64, 0i32, 0f64);
            for x in &blocks {
                let mut c = forward_4x4(x);
                quantize(&mut c, qp, 0.5);
                dequantize(&mut c, qp);
                let y = inverse_4x4(&c);
                for i in 0..4 {
                    for j in 0..4 {
                        let e = y[i][j] - x[i][j];
                        se += f64::from(e * e);
                        max = max.max(e.abs());
                        n += 1.0;
                    }
                }
            }
            // A uniform quantiser's error has an RMS of Qstep / sqrt(12) = 0.289
            // Qstep; measured 0.11 (QP 0) to 0.293 (QP 51) Qstep, max 1 level at
            // QP 0 (the H.264 design is not lossless there) and at most
            // 1.31 Qstep elsewhere.
            let rms = (se / n).sqrt();
            assert!(rms <= 0.31 * qstep(qp) + 0.05, "qp {qp}: rms {rms}");
            assert!(f64::from(max) <= 1.4 * qstep(qp) + 1.0, "qp {qp}: max {max}");
            if qp == 0 {
                assert!(max <= 1 && rms < 0.1, "qp 0: max {max} rms {rms}");
            }
        }
    }

    proptest! {
        #[test]
        fn butterflies_equal_the_matrix_products(values in proptest::collection::vec(-255i32..=255, 16)) {
            let x = block(&values);
            let xi = x.map(|r| r.map(i64::from));
            let want = matmul(&matmul(&CF, &xi), &transpose(&CF));
            prop_assert_eq!(forward_4x4(&x).map(|r| r.map(i64::from)), want);
        }

        #[test]
        fn quantize_follows_its_formula_at_any_magnitude(
            values in proptest::collection::vec(-(1i32 << 22)..(1 << 22), 16),
            small in any::<bool>(),
            qp in 0u8..=MAX_QP,
            rounding in 0.0f64..=0.5,
        ) {
            // Small blocks take the 32-bit path, the rest the 64-bit one.
            let x = block(&values).map(|r| r.map(|v| if small { v >> 6 } else { v }));
            let mut got = x;
            quantize(&mut got, qp, rounding);
            let shift = 15 + u32::from(qp / 6);
            let offset = (rounding * f64::from(1u32 << shift)) as i64;
            for r in 0..4 {
                for c in 0..4 {
                    let mf = i64::from(QUANT[usize::from(qp % 6)][class(r, c)]);
                    let level = ((i64::from(x[r][c]).abs() * mf + offset) >> shift) as i32;
                    prop_assert_eq!(got[r][c], level * x[r][c].signum());
                }
            }
        }

        #[test]
        fn dequantized_levels_never_overflow_the_inverse(values in proptest::collection::vec(any::<i32>(), 16), qp in 0u8..=MAX_QP) {
            let mut c = block(&values);
            dequantize(&mut c, qp);
            for row in &c {
                for &w in row {
                    prop_assert!((-32768..=32767).contains(&w));
                }
            }
            let _ = inverse_4x4(&c);
        }
    }

    #[test]
    fn a_lone_first_chroma_dc_level_is_every_blocks_dc() {
        for qp in 0..=MAX_QP {
            for l in [-300, -7, -1, 1, 2, 5, 1000] {
                let want = dequantize_level(l, qp, 0, 0);
                assert_eq!(
                    dequantize_chroma_dc([2 * l, 0, 0, 0], qp),
                    [want; 4],
                    "qp {qp} level {l}"
                );
            }
        }
    }

    #[test]
    fn chroma_dc_levels_rebuild_the_blocks_means() {
        // Four blocks of constant residuals: the DC path alone rebuilds
        // each within half a quantiser step (plus the inverse's rounding).
        let planes = [[3, 3, 3, 3], [-20, 14, 0, 7], [100, -100, 55, -1], [1, 0, 0, 0]];
        for qp in [0u8, 12, 22, 28, 34, 40, 51] {
            let cqp = chroma_qp(qp);
            for means in planes {
                let dc = means.map(|m| forward_4x4(&[[m; 4]; 4])[0][0]);
                let levels = quantize_chroma_dc(dc, cqp, 0.5);
                let coeffs = dequantize_chroma_dc(levels, cqp);
                for k in 0..4 {
                    let mut d = [[0; 4]; 4];
                    d[0][0] = coeffs[k];
                    let back = inverse_4x4(&d);
                    let bound = qstep(cqp) / 2.0 + 1.0;
                    for v in back.as_flattened() {
                        assert!(
                            f64::from((v - means[k]).abs()) <= bound,
                            "qp {cqp} means {means:?} block {k}: {v} for {}",
                            means[k]
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn a_lone_first_luma_dc_level_is_every_blocks_dc() {
        for qp in 0..=MAX_QP {
            for l in [-300, -7, -1, 1, 2, 5, 1000] {
                let want = dequantize_level(l, qp, 0, 0);
                let mut levels = [0; 16];
                levels[0] = 4 * l;
                assert_eq!(dequantize_luma_dc(levels, qp), [want; 16], "qp {qp} level {l}");
            }
        }
    }

    #[test]
    fn luma_dc_levels_rebuild_the_blocks_means() {
        // Sixteen blocks of constant residuals: the DC path alone rebuilds
        // each block's mean. Each level's rounding (half a level) reaches a
        // block through the inverse Hadamard at a quarter of a quantiser
        // step, so no block is off by more than sixteen of them (2 steps,
        // plus the inverse's rounding), and on average by far less.
        let mut seed = 7u32;
        let mut next = |n: i32| {
            seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
            (seed >> 8) as i32 % n
        };
        for qp in [0u8, 12, 22, 28, 34, 40, 51] {
            let (mut squared, mut count) = (0.0, 0.0);
            for round in 0..40 {
                let means: [i32; 16] = std::array::from_fn(|k| match round {
                    0 => 3,
                    1 => k as i32 * 9 - 70,
                    _ => next(241) - 120,
                });
                let dc = means.map(|m| forward_4x4(&[[m; 4]; 4])[0][0]);
                let coeffs = dequantize_luma_dc(quantize_luma_dc(dc, qp, 0.5), qp);
                for k in 0..16 {
                    let mut d = [[0; 4]; 4];
                    d[0][0] = coeffs[k];
                    let v = inverse_4x4(&d)[0][0];
                    let err = f64::from(v - means[k]);
                    assert!(
                        err.abs() <= 2.0 * qstep(qp) + 1.0,
                        "qp {qp} round {round} block {k}: {v} for {}",
                        means[k]
                    );
                    squared += err * err;
                    count += 1.0;
                }
            }
            let rms = (squared / count).sqrt();
            assert!(rms <= 0.5 * qstep(qp) + 1.0, "qp {qp}: rms error {rms}");
        }
    }

    #[test]
    fn the_4x4_hadamard_is_its_own_inverse_up_to_sixteen() {
        let c: [i64; 16] = std::array::from_fn(|k| (k as i64 * 37 % 23) - 11);
        assert_eq!(hadamard_4x4(hadamard_4x4(c)), c.map(|v| 16 * v));
    }

    #[test]
    fn the_2x2_hadamard_is_its_own_inverse_up_to_four() {
        let c = [5, -3, 11, 0];
        assert_eq!(hadamard_2x2(hadamard_2x2(c)), c.map(|v| 4 * v));
    }
}
