//! The 8x8 integer transform and its quantisation, after H.264's High
//! profile (8.5.13): an adaptive alternative to four 4x4 transforms for
//! the luma of a macroblock (FORMAT.md section 10.2). Smooth residuals
//! spend fewer levels in one 8x8 block than in four 4x4 ones.
//!
//! The forward transform `W = T X T^T` uses the integer matrix `T` whose
//! rows are H.264's basis scaled by 8 (`[8 ..]`, `[12 10 6 3 ..]`,
//! `[8 4 -4 -8 ..]`, `[10 -3 -12 -6 ..]`, ...): exact, with rows of squared
//! norms 512, 578 and 320 that the quantiser folds in. The inverse is
//! H.264's butterfly, whose halvings and quarterings make its basis `T / 8`.
//!
//! Normative: [`dequantize_8x8`] (`((level V) << (qp / 6)) + 2) >> 2`,
//! clamped to 16 bits; the step equals the 4x4 transform's at every QP) and
//! [`inverse_8x8`]. The forward transform and [`quantize_8x8`] are the
//! encoder's reference.
//!
//! ```
//! use mocomp_codec::transform8x8::{dequantize_8x8, forward_8x8, inverse_8x8, quantize_8x8};
//! let residual: [[i32; 8]; 8] = std::array::from_fn(|r| std::array::from_fn(|c| (r * 3 + c * 5) as i32 % 17 - 8));
//! let mut c = forward_8x8(&residual);
//! quantize_8x8(&mut c, 10, 0.5);
//! dequantize_8x8(&mut c, 10);
//! let back = inverse_8x8(&c);
//! for y in 0..8 {
//!     for x in 0..8 {
//!         assert!((back[y][x] - residual[y][x]).abs() <= 3);
//!     }
//! }
//! ```

use crate::transform::{quantize_levels, MAX_QP};

/// An 8x8 block of samples or coefficients, `[row][column]`.
pub type Block8 = [[i32; 8]; 8];

/// The zig-zag scan of an 8x8 block: `ZIGZAG8[k]` is the raster index
/// (`row * 8 + col`) of the k-th coefficient. Anti-diagonals in turn,
/// odd ones walked downward, even ones upward (the 4x4 scan's rule).
pub const ZIGZAG8: [usize; 64] = {
    let mut scan = [0usize; 64];
    let (mut k, mut d) = (0, 0usize);
    while d < 15 {
        // Rows lo..=hi lie on anti-diagonal d.
        let (lo, hi) = (d.saturating_sub(7), if d < 7 { d } else { 7 });
        let mut i = 0;
        while i <= hi - lo {
            let row = if d % 2 == 1 { lo + i } else { hi - i };
            scan[k] = row * 8 + (d - row);
            k += 1;
            i += 1;
        }
        d += 1;
    }
    scan
};

/// Dequantisation scale `V` for `qp % 6` (H.264 Table 8-15's
/// normAdjust8x8), by the six position classes of [`class8`].
const DEQUANT8: [[i32; 6]; 6] = [
    [20, 18, 32, 19, 25, 24],
    [22, 19, 35, 21, 28, 26],
    [26, 23, 42, 24, 33, 31],
    [28, 25, 45, 26, 35, 33],
    [32, 28, 51, 30, 40, 38],
    [36, 32, 58, 34, 46, 43],
];

/// Squared norms of the rows of `T`.
const ROW_NORM: [u64; 8] = [512, 578, 320, 578, 512, 578, 320, 578];

/// Which of the six scale classes position (row, col) falls in.
#[inline]
const fn class8(r: usize, c: usize) -> usize {
    match (r % 4, c % 4) {
        (0, 0) => 0,
        (2, 2) => 2,
        (0, 2) | (2, 0) => 4,
        _ if r % 2 == 1 && c % 2 == 1 => 1,
        (0, _) | (_, 0) => 3,
        _ => 5,
    }
}

/// Fraction bits of [`QUANT8`].
const QUANT_SHIFT: u32 = 22;

/// Quantisation multipliers by `qp % 6` and raster position: quantising
/// then dequantising returns the coefficient in the inverse's scale,
/// `W 4096 / (n_r n_c)`, which with `D = level V 2^(qp/6) / 4` gives
/// `MF = 2^22 16384 / (n_r n_c V)`.
const QUANT8: [[u64; 64]; 6] = {
    let mut t = [[0u64; 64]; 6];
    let mut m = 0;
    while m < 6 {
        let mut k = 0;
        while k < 64 {
            let (r, c) = (k / 8, k % 8);
            let den = ROW_NORM[r] * ROW_NORM[c] * DEQUANT8[m][class8(r, c)] as u64;
            t[m][k] = ((16384u64 << QUANT_SHIFT) + den / 2) / den;
            k += 1;
        }
        m += 1;
    }
    t
};

/// `T X`: the forward butterfly down every column at once (each step a
/// row-wide operation, which vectorises), by the even/odd halves.
#[inline(always)]
fn forward_columns(x: &Block8) -> Block8 {
    let mut out = [[0i32; 8]; 8];
    for c in 0..8 {
        let s: [i32; 4] = std::array::from_fn(|i| x[i][c] + x[7 - i][c]);
        let d: [i32; 4] = std::array::from_fn(|i| x[i][c] - x[7 - i][c]);
        out[0][c] = 8 * (s[0] + s[1] + s[2] + s[3]);
        out[1][c] = 12 * d[0] + 10 * d[1] + 6 * d[2] + 3 * d[3];
        out[2][c] = 8 * (s[0] - s[3]) + 4 * (s[1] - s[2]);
        out[3][c] = 10 * d[0] - 3 * d[1] - 12 * d[2] - 6 * d[3];
        out[4][c] = 8 * (s[0] - s[1] - s[2] + s[3]);
        out[5][c] = 6 * d[0] - 12 * d[1] + 3 * d[2] + 10 * d[3];
        out[6][c] = 4 * (s[0] - s[3]) - 8 * (s[1] - s[2]);
        out[7][c] = 3 * d[0] - 6 * d[1] + 10 * d[2] - 12 * d[3];
    }
    out
}

#[inline(always)]
fn transpose(x: &Block8) -> Block8 {
    std::array::from_fn(|r| std::array::from_fn(|c| x[c][r]))
}

/// Forward transform `T X T^T` (exact; 9-bit residuals give outputs within
/// 21 bits): `T X`, then `(T (T X)^T)^T`.
#[inline]
pub fn forward_8x8(x: &Block8) -> Block8 {
    transpose(&forward_columns(&transpose(&forward_columns(x))))
}

/// Quantises in place: `level = sign(w) ((|w| MF + f 2^s) >> s)` with
/// `s = 22 + qp / 6` and the rounding offset `f` in [0, 0.5].
#[inline]
pub fn quantize_8x8(coeffs: &mut Block8, qp: u8, rounding: f64) {
    assert!(qp <= MAX_QP, "qp {qp} above {MAX_QP}");
    let shift = QUANT_SHIFT + u32::from(qp / 6);
    let offset = (rounding.clamp(0.0, 0.5) * (1u64 << shift) as f64) as u64;
    // Magnitudes below 2^16 (most residuals') keep |w| MF + offset within
    // 32 bits (MF < 2^15, offset <= 2^29).
    let mf = &QUANT8_32[usize::from(qp % 6)];
    quantize_levels(coeffs.as_flattened_mut(), mf, (shift, offset), 1 << 16);
}

/// [`QUANT8`] in 32 bits (every entry is below 2^15).
const QUANT8_32: [[u32; 64]; 6] = {
    let mut t = [[0u32; 64]; 6];
    let mut m = 0;
    while m < 6 {
        let mut k = 0;
        while k < 64 {
            assert!(QUANT8[m][k] < 1 << 15);
            t[m][k] = QUANT8[m][k] as u32;
            k += 1;
        }
        m += 1;
    }
    t
};

/// [`dequantize_8x8`] of the one level at row `r`, column `c`.
#[inline]
pub fn dequantize_level_8x8(level: i32, qp: u8, r: usize, c: usize) -> i32 {
    debug_assert!(qp <= MAX_QP);
    let v = i64::from(DEQUANT8_BY_POSITION[usize::from(qp % 6)][r * 8 + c]);
    // i64: |level| <= 2^31, V < 2^6, qp / 6 <= 8: within 46 bits.
    let value = (((i64::from(level) * v) << (qp / 6)) + 2) >> 2;
    value.clamp(-32768, 32767) as i32
}

/// Normative dequantisation in place (`qp` at most [`MAX_QP`]).
#[inline]
pub fn dequantize_8x8(coeffs: &mut Block8, qp: u8) {
    debug_assert!(qp <= MAX_QP);
    let v = &DEQUANT8_BY_POSITION[usize::from(qp % 6)];
    let w = coeffs.as_flattened_mut();
    // Levels below 2^12 (all an encoder of 8-bit video makes) keep
    // `(l V) << (qp / 6)` within 32 bits: arithmetic that vectorises.
    if w.iter().all(|l| l.unsigned_abs() < 1 << 12) {
        for (l, &v) in w.iter_mut().zip(v) {
            *l = ((((*l * v) << (qp / 6)) + 2) >> 2).clamp(-32768, 32767);
        }
    } else {
        for (k, l) in w.iter_mut().enumerate() {
            *l = dequantize_level_8x8(*l, qp, k / 8, k % 8);
        }
    }
}

/// [`DEQUANT8`] spread over the 64 positions, row by row.
pub(crate) const DEQUANT8_BY_POSITION: [[i32; 64]; 6] = {
    let mut t = [[0i32; 64]; 6];
    let mut m = 0;
    while m < 6 {
        let mut k = 0;
        while k < 64 {
            t[m][k] = DEQUANT8[m][class8(k / 8, k % 8)];
            k += 1;
        }
        m += 1;
    }
    t
};

/// One pass of the inverse butterfly (H.264 8.5.13.2, equations 8-339 to
/// 8-362) down every column at once: inputs within 20 bits stay within 24.
#[inline(always)]
fn inverse_columns(d: &Block8) -> Block8 {
    let mut out = [[0i32; 8]; 8];
    for c in 0..8 {
        let e0 = d[0][c] + d[4][c];
        let e1 = -d[3][c] + d[5][c] - d[7][c] - (d[7][c] >> 1);
        let e2 = d[0][c] - d[4][c];
        let e3 = d[1][c] + d[7][c] - d[3][c] - (d[3][c] >> 1);
        let e4 = (d[2][c] >> 1) - d[6][c];
        let e5 = -d[1][c] + d[7][c] + d[5][c] + (d[5][c] >> 1);
        let e6 = d[2][c] + (d[6][c] >> 1);
        let e7 = d[3][c] + d[5][c] + d[1][c] + (d[1][c] >> 1);
        let f0 = e0 + e6;
        let f1 = e1 + (e7 >> 2);
        let f2 = e2 + e4;
        let f3 = e3 + (e5 >> 2);
        let f4 = e2 - e4;
        let f5 = (e3 >> 2) - e5;
        let f6 = e0 - e6;
        let f7 = e7 - (e1 >> 2);
        out[0][c] = f0 + f7;
        out[1][c] = f2 + f5;
        out[2][c] = f4 + f3;
        out[3][c] = f6 + f1;
        out[4][c] = f6 - f1;
        out[5][c] = f4 - f3;
        out[6][c] = f2 - f5;
        out[7][c] = f0 - f7;
    }
    out
}

/// Normative inverse transform: the butterfly on each row, then on each
/// column, then `(x + 32) >> 6`.
#[inline]
pub fn inverse_8x8(d: &Block8) -> Block8 {
    let rows = transpose(&inverse_columns(&transpose(d)));
    inverse_columns(&rows).map(|r| r.map(|v| (v + 32) >> 6))
}

/// `1 / sqrt(n)` of each row's squared norm `n` (512, 578, 320, ...).
const INVERSE_ROW_NORM: [f64; 8] = {
    const A: f64 = 0.044_194_173_824_159_216; // 1 / sqrt(512)
    const B: f64 = 0.041_594_516_540_385_42; // 1 / sqrt(578)
    const C: f64 = 0.055_901_699_437_494_74; // 1 / sqrt(320)
    [A, B, C, B, A, B, C, B]
};

/// The weight that turns a coefficient of [`forward_8x8`] at (r, c) into
/// the orthonormal transform's: `1 / sqrt(n_r n_c)`. Squared errors of
/// orthonormal coefficients are squared errors of samples, which is what
/// an encoder weighing single levels needs (not normative).
#[inline]
pub fn orthonormal_scale(r: usize, c: usize) -> f64 {
    ORTHONORMAL_SCALE8[r * 8 + c]
}

/// [`orthonormal_scale`] of every position, row by row (the same
/// products, taken once).
pub const ORTHONORMAL_SCALE8: [f64; 64] = {
    let mut t = [0.0; 64];
    let mut k = 0;
    while k < 64 {
        t[k] = INVERSE_ROW_NORM[k / 8] * INVERSE_ROW_NORM[k % 8];
        k += 1;
    }
    t
};

/// `4096` times [`ORTHONORMAL_SCALE8`]: what [`dequantized_orthonormal`]
/// divides by.
const DEQUANTIZED_DIVISOR8: [f64; 64] = {
    let mut t = [0.0; 64];
    let mut k = 0;
    while k < 64 {
        t[k] = 4096.0 * ORTHONORMAL_SCALE8[k];
        k += 1;
    }
    t
};

/// The orthonormal coefficient a dequantised value at (r, c) stands for:
/// `D sqrt(n_r n_c) / 4096` (not normative).
#[inline]
pub fn dequantized_orthonormal(d: i32, r: usize, c: usize) -> f64 {
    f64::from(d) / DEQUANTIZED_DIVISOR8[r * 8 + c]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transform::qstep;
    use proptest::prelude::*;

    /// The integer basis, written out.
    const T: [[i64; 8]; 8] = [
        [8, 8, 8, 8, 8, 8, 8, 8],
        [12, 10, 6, 3, -3, -6, -10, -12],
        [8, 4, -4, -8, -8, -4, 4, 8],
        [10, -3, -12, -6, 6, 12, 3, -10],
        [8, -8, -8, 8, 8, -8, -8, 8],
        [6, -12, 3, 10, -10, -3, 12, -6],
        [4, -8, 8, -4, -4, 8, -8, 4],
        [3, -6, 10, -12, 12, -10, 6, -3],
    ];

    fn block(values: &[i32]) -> Block8 {
        std::array::from_fn(|r| std::array::from_fn(|c| values[r * 8 + c]))
    }

    #[test]
    fn the_basis_is_orthogonal_with_the_folded_norms() {
        for (i, a) in T.iter().enumerate() {
            for (j, b) in T.iter().enumerate() {
                let dot: i64 = a.iter().zip(b).map(|(x, y)| x * y).sum();
                assert_eq!(dot, if i == j { ROW_NORM[i] as i64 } else { 0 }, "rows {i} {j}");
            }
        }
    }

    #[test]
    fn the_inverse_basis_is_t_over_8() {
        // A lone coefficient of 64 * 64 comes back as the outer product of
        // its basis rows, T_r^T T_c / 64, where the butterfly's shifts are
        // exact.
        for r in 0..8 {
            for c in 0..8 {
                let mut d = [[0; 8]; 8];
                d[r][c] = 64 * 64;
                let got = inverse_8x8(&d);
                for y in 0..8 {
                    for x in 0..8 {
                        assert_eq!(i64::from(got[y][x]), T[r][y] * T[c][x], "({r},{c}) at ({y},{x})");
                    }
                }
            }
        }
    }

    #[test]
    fn the_orthonormal_scales_are_the_row_norms() {
        for (r, &n) in ROW_NORM.iter().enumerate() {
            assert!((INVERSE_ROW_NORM[r] - 1.0 / (n as f64).sqrt()).abs() < 1e-15);
        }
    }

    #[test]
    fn the_scan_walks_every_position_along_the_diagonals() {
        let mut seen = [false; 64];
        for (k, &i) in ZIGZAG8.iter().enumerate() {
            assert!(!seen[i], "{i} twice");
            seen[i] = true;
            if k > 0 {
                let (a, b) = (ZIGZAG8[k - 1], i);
                let step = ((a / 8).abs_diff(b / 8), (a % 8).abs_diff(b % 8));
                assert!(step.0 <= 1 && step.1 <= 1, "step {a} -> {b}");
                assert!((a / 8 + a % 8) <= (b / 8 + b % 8));
            }
        }
        assert_eq!(&ZIGZAG8[..6], &[0, 1, 8, 16, 9, 2]);
        assert_eq!(ZIGZAG8[63], 63);
    }

    #[test]
    fn every_class_steps_as_the_4x4_quantiser() {
        // A level's value on the orthonormal basis is Qstep at every
        // position, within the table's 3 %.
        for qp in 0..=MAX_QP {
            for r in 0..8 {
                for c in 0..8 {
                    let a = dequantized_orthonormal(dequantize_level_8x8(4, qp, r, c), r, c) / 4.0;
                    assert!((a / qstep(qp) - 1.0).abs() < 0.03, "qp {qp} ({r},{c}): {a}");
                }
            }
        }
    }

    #[test]
    fn reconstruction_error_per_qp() {
        let mut seed = 0x9e37_79b9u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed % 511) as i32 - 255
        };
        let blocks: Vec<Block8> = (0..500)
            .map(|_| std::array::from_fn(|_| std::array::from_fn(|_| next())))
            .collect();
        for qp in 0..=MAX_QP {
            let (mut se, mut max, mut n) = (0f64, 0i32, 0f64);
            for x in &blocks {
                let mut c = forward_8x8(x);
                quantize_8x8(&mut c, qp, 0.5);
                dequantize_8x8(&mut c, qp);
                let y = inverse_8x8(&c);
                for (yr, xr) in y.iter().zip(x) {
                    for (a, b) in yr.iter().zip(xr) {
                        let e = a - b;
                        se += f64::from(e * e);
                        max = max.max(e.abs());
                        n += 1.0;
                    }
                }
            }
            // A uniform quantiser's RMS error is Qstep / sqrt(12), 0.289 Qstep;
            // the integer rounding adds about half a level at low QPs.
            let rms = (se / n).sqrt();
            assert!(rms <= 0.31 * qstep(qp) + 0.6, "qp {qp}: rms {rms}");
            assert!(f64::from(max) <= 1.6 * qstep(qp) + 2.0, "qp {qp}: max {max}");
        }
    }

    proptest! {
        #[test]
        fn butterflies_equal_the_matrix_product(values in proptest::collection::vec(-255i32..=255, 64)) {
            let x = block(&values);
            let got = forward_8x8(&x);
            for i in 0..8 {
                for j in 0..8 {
                    let want: i64 = (0..8)
                        .flat_map(|a| (0..8).map(move |b| (a, b)))
                        .map(|(a, b)| T[i][a] * i64::from(x[a][b]) * T[j][b])
                        .sum();
                    prop_assert_eq!(i64::from(got[i][j]), want);
                }
            }
        }

        #[test]
        fn both_dequantisers_agree(values in proptest::collection::vec(-4095i32..=4095, 64), qp in 0u8..=MAX_QP) {
            let mut fast = block(&values);
            dequantize_8x8(&mut fast, qp);
            for k in 0..64 {
                prop_assert_eq!(fast[k / 8][k % 8], dequantize_level_8x8(values[k], qp, k / 8, k % 8));
            }
        }

        #[test]
        fn dequantized_levels_never_overflow_the_inverse(values in proptest::collection::vec(any::<i32>(), 64), qp in 0u8..=MAX_QP) {
            let mut c = block(&values);
            dequantize_8x8(&mut c, qp);
            prop_assert!(c.as_flattened().iter().all(|w| (-32768..=32767).contains(w)));
            let _ = inverse_8x8(&c);
        }

        #[test]
        fn quantize_follows_its_formula(values in proptest::collection::vec(-(1i32 << 21)..(1 << 21), 64), small in any::<bool>(), qp in 0u8..=MAX_QP, rounding in 0.0f64..=0.5) {
            // Small blocks take the 32-bit path, the rest the 64-bit one.
            let x = block(&values).map(|r| r.map(|v| if small { v >> 6 } else { v }));
            let mut got = x;
            quantize_8x8(&mut got, qp, rounding);
            let shift = QUANT_SHIFT + u32::from(qp / 6);
            let offset = (rounding * (1u64 << shift) as f64) as u64;
            for k in 0..64 {
                let w = x[k / 8][k % 8];
                let level = ((u64::from(w.unsigned_abs()) * QUANT8[usize::from(qp % 6)][k] + offset) >> shift) as i32;
                prop_assert_eq!(got[k / 8][k % 8], level * w.signum());
            }
        }
    }
}
