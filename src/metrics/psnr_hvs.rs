//! PSNR-HVS-M (Ponomarenko et al. 2007) as Daala's `dump_psnrhvs` and
//! libvmaf's `psnr_hvs` compute it, which AWCY reports as "PSNR-HVS".
//!
//! The picture is cut into 8x8 blocks at a step of 7 samples. In each
//! block the error of every DCT coefficient is weighted by a contrast
//! sensitivity table, after the part that the block's own texture masks is
//! taken away (masking from the larger of the source's and the test's AC
//! energy, scaled by how uneven the block's four quarters are). The DC
//! coefficient is weighted but never masked. The mean weighted squared
//! error over all coefficients is turned into dB like an MSE.
//!
//! The transform is Daala's integer 8-point DCT (a lifting factorisation
//! of the orthonormal DCT-II whose rounding the figures depend on: on
//! `samples/tree_qcif*.y4m` the orthonormal DCT in floating point gave
//! 36.40 dB for frame 0's luma where libvmaf gives 36.20).

use super::PSNR_CAP_DB;
use crate::codec::{Frame, Plane};

/// Contrast sensitivity per coefficient (row = vertical frequency), for
/// luma. Tables as Daala gives them: tuned for MOS agreement, not the
/// paper's JPEG-based ones.
#[rustfmt::skip]
const CSF_Y: [[f64; 8]; 8] = [
    [1.6193873005, 2.2901594831, 2.08509755623, 1.48366094411, 1.00227514334, 0.678296995242, 0.466224900598, 0.3265091542],
    [2.2901594831, 1.94321815382, 2.04793073064, 1.68731108984, 1.2305666963, 0.868920337363, 0.61280991668, 0.436405793551],
    [2.08509755623, 2.04793073064, 1.34329019223, 1.09205635862, 0.875748795257, 0.670882927016, 0.501731932449, 0.372504254596],
    [1.48366094411, 1.68731108984, 1.09205635862, 0.772819797575, 0.605636379554, 0.48309405692, 0.380429446972, 0.295774038565],
    [1.00227514334, 1.2305666963, 0.875748795257, 0.605636379554, 0.448996256676, 0.352889268808, 0.283006984131, 0.226951348204],
    [0.678296995242, 0.868920337363, 0.670882927016, 0.48309405692, 0.352889268808, 0.27032073436, 0.215017739696, 0.17408067321],
    [0.466224900598, 0.61280991668, 0.501731932449, 0.380429446972, 0.283006984131, 0.215017739696, 0.168869545842, 0.136153931001],
    [0.3265091542, 0.436405793551, 0.372504254596, 0.295774038565, 0.226951348204, 0.17408067321, 0.136153931001, 0.109083846276],
];

/// The same for 4:2:0 Cb.
#[rustfmt::skip]
const CSF_CB420: [[f64; 8]; 8] = [
    [1.91113096927, 2.46074210438, 1.18284184739, 1.14982565193, 1.05017074788, 0.898018824055, 0.74725392039, 0.615105596242],
    [2.46074210438, 1.58529308355, 1.21363250036, 1.38190029285, 1.33100189972, 1.17428548929, 0.996404342439, 0.830890433625],
    [1.18284184739, 1.21363250036, 0.978712413627, 1.02624506078, 1.03145147362, 0.960060382087, 0.849823426169, 0.731221236837],
    [1.14982565193, 1.38190029285, 1.02624506078, 0.861317501629, 0.801821139099, 0.751437590932, 0.685398513368, 0.608694761374],
    [1.05017074788, 1.33100189972, 1.03145147362, 0.801821139099, 0.676555426187, 0.605503172737, 0.55002013668, 0.495804539034],
    [0.898018824055, 1.17428548929, 0.960060382087, 0.751437590932, 0.605503172737, 0.514674450957, 0.454353482512, 0.407050308965],
    [0.74725392039, 0.996404342439, 0.849823426169, 0.685398513368, 0.55002013668, 0.454353482512, 0.389234902883, 0.342353999733],
    [0.615105596242, 0.830890433625, 0.731221236837, 0.608694761374, 0.495804539034, 0.407050308965, 0.342353999733, 0.295530605237],
];

/// The same for 4:2:0 Cr.
#[rustfmt::skip]
const CSF_CR420: [[f64; 8]; 8] = [
    [2.03871978502, 2.62502345193, 1.26180942886, 1.11019789803, 1.01397751469, 0.867069376285, 0.721500455585, 0.593906509971],
    [2.62502345193, 1.69112867013, 1.17180569821, 1.3342742857, 1.28513006198, 1.13381474809, 0.962064122248, 0.802254508198],
    [1.26180942886, 1.17180569821, 0.944981930573, 0.990876405848, 0.995903384143, 0.926972725286, 0.820534991409, 0.706020324706],
    [1.11019789803, 1.3342742857, 0.990876405848, 0.831632933426, 0.77418706195, 0.725539939514, 0.661776842059, 0.587716619023],
    [1.01397751469, 1.28513006198, 0.995903384143, 0.77418706195, 0.653238524286, 0.584635025748, 0.531064164893, 0.478717061273],
    [0.867069376285, 1.13381474809, 0.926972725286, 0.725539939514, 0.584635025748, 0.496936637883, 0.438694579826, 0.393021669543],
    [0.721500455585, 0.962064122248, 0.820534991409, 0.661776842059, 0.531064164893, 0.438694579826, 0.375820256136, 0.330555063063],
    [0.593906509971, 0.802254508198, 0.706020324706, 0.587716619023, 0.478717061273, 0.393021669543, 0.330555063063, 0.285345396658],
];

/// Daala's factor from the CSF to the masking weights (its square): the
/// paper's masking table is the JPEG-derived CSF scaled by this.
const MASK_SCALE: f64 = 0.3885746225901003;

/// Block step: blocks overlap by one sample.
const STEP: usize = 7;

/// PSNR-HVS of each plane and their combination, dB.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PsnrHvs {
    /// Luma.
    pub y: f64,
    /// Cb.
    pub cb: f64,
    /// Cr.
    pub cr: f64,
    /// The planes' weighted errors combined 0.8 : 0.1 : 0.1 before the dB
    /// (libvmaf's `psnr_hvs`, AWCY's "PSNR-HVS").
    pub total: f64,
}

/// PSNR-HVS of `test` against `reference` (4:2:0 frames of one size).
/// Panics if the sizes differ.
///
/// ```
/// use mocomp::codec::Frame;
/// let a = Frame::filled(32, 32, 100, 128, 128).unwrap();
/// let mut b = a.clone();
/// b.plane_mut(0).set(9, 9, 140);
/// let hvs = mocomp::metrics::psnr_hvs(&a, &b);
/// assert!(hvs.y > 30.0 && hvs.y < 100.0 && hvs.cb == 100.0);
/// ```
pub fn psnr_hvs(reference: &Frame, test: &Frame) -> PsnrHvs {
    assert!(
        reference.width() == test.width() && reference.height() == test.height(),
        "psnr_hvs: frames of different sizes"
    );
    let e = [
        plane_error(reference.y(), test.y(), &CSF_Y),
        plane_error(reference.u(), test.u(), &CSF_CB420),
        plane_error(reference.v(), test.v(), &CSF_CR420),
    ];
    PsnrHvs {
        y: error_db(e[0]),
        cb: error_db(e[1]),
        cr: error_db(e[2]),
        total: error_db(0.8 * e[0] + 0.1 * (e[1] + e[2])),
    }
}

/// A weighted squared error per coefficient, relative to 255^2, in dB;
/// capped as PSNR is.
fn error_db(e: f64) -> f64 {
    if e <= 0.0 {
        PSNR_CAP_DB
    } else {
        (-10.0 * e.log10()).min(PSNR_CAP_DB)
    }
}

/// The mean weighted squared coefficient error of a plane, over 255^2 (0
/// for planes too small to hold a block).
fn plane_error(a: &Plane, b: &Plane, csf: &[[f64; 8]; 8]) -> f64 {
    let mask = csf.map(|row| row.map(|c| (c * MASK_SCALE) * (c * MASK_SCALE)));
    let (w, h) = (a.width(), a.height());
    let (mut sum, mut coefficients) = (0.0, 0usize);
    for y in (0..h.saturating_sub(7)).step_by(STEP) {
        for x in (0..w.saturating_sub(7)).step_by(STEP) {
            let (sa, sb) = (block(a, x, y), block(b, x, y));
            sum += block_error(&sa, &sb, csf, &mask);
            coefficients += 64;
        }
    }
    if coefficients == 0 {
        return 0.0;
    }
    sum / coefficients as f64 / (255.0 * 255.0)
}

fn block(p: &Plane, x: usize, y: usize) -> [[i32; 8]; 8] {
    std::array::from_fn(|i| std::array::from_fn(|j| i32::from(p.row(y + i)[x + j])))
}

/// Sum over the block's coefficients of (masked error * csf)^2.
fn block_error(a: &[[i32; 8]; 8], b: &[[i32; 8]; 8], csf: &[[f64; 8]; 8], mask: &[[f64; 8]; 8]) -> f64 {
    let (da, db) = (dct8x8(a), dct8x8(b));
    let masking = masking_energy(a, &da, mask).max(masking_energy(b, &db, mask));
    let mut sum = 0.0;
    for i in 0..8 {
        for j in 0..8 {
            let mut err = f64::from((da[i][j] - db[i][j]).abs());
            if i != 0 || j != 0 {
                err = (err - masking / mask[i][j]).max(0.0);
            }
            sum += (err * csf[i][j]) * (err * csf[i][j]);
        }
    }
    sum
}

/// The block's masking threshold: its AC energy under the masking weights,
/// scaled by the ratio of the quarters' variance to the whole block's
/// (textured blocks mask more than one edge does).
fn masking_energy(samples: &[[i32; 8]; 8], coeffs: &[[i32; 8]; 8], mask: &[[f64; 8]; 8]) -> f64 {
    let mut ac = 0.0;
    for i in 0..8 {
        for j in 0..8 {
            if i != 0 || j != 0 {
                ac += f64::from(coeffs[i][j] * coeffs[i][j]) * mask[i][j];
            }
        }
    }
    (ac * quarter_variance_ratio(samples)).sqrt() / 32.0
}

/// Sum of the four 4x4 quarters' variances over the block's variance
/// (sample variances, n - 1), or 0 for a flat block.
fn quarter_variance_ratio(s: &[[i32; 8]; 8]) -> f64 {
    let quarter = |i: usize, j: usize| (i / 4) * 2 + j / 4;
    let mut mean = 0.0;
    let mut means = [0.0; 4];
    for (i, row) in s.iter().enumerate() {
        for (j, &v) in row.iter().enumerate() {
            mean += f64::from(v);
            means[quarter(i, j)] += f64::from(v);
        }
    }
    mean /= 64.0;
    let means = means.map(|m| m / 16.0);
    let (mut var, mut vars) = (0.0, [0.0; 4]);
    for (i, row) in s.iter().enumerate() {
        for (j, &v) in row.iter().enumerate() {
            let (q, v) = (quarter(i, j), f64::from(v));
            var += (v - mean) * (v - mean);
            vars[q] += (v - means[q]) * (v - means[q]);
        }
    }
    let var = var * 64.0 / 63.0;
    let quarters: f64 = vars.iter().map(|v| v * 16.0 / 15.0).sum();
    if var > 0.0 {
        quarters / var
    } else {
        0.0
    }
}

/// Daala's integer 8-point DCT-II: butterflies, then the embedded 4- and
/// 2-point DCTs and DSTs as lifting steps with 14- and 15-bit multipliers,
/// outputs in frequency order with the orthonormal DCT's gain.
fn fdct8(x: [i32; 8]) -> [i32; 8] {
    // Round(v * num / 2^shift), the shift arithmetic (floor).
    let mul = |v: i32, num: i32, shift: u32| (v * num + (1 << (shift - 1))) >> shift;
    // Halving that truncates toward zero, as Daala's unbiased shift does.
    let half = |v: i32| v / 2;
    let [mut t0, mut t4, mut t2, mut t6, mut t7, mut t3, mut t5, mut t1] = x;
    t1 = t0 - t1;
    let t1h = half(t1);
    t0 -= t1h;
    t4 += t5;
    let t4h = half(t4);
    t5 -= t4h;
    t3 = t2 - t3;
    t2 -= half(t3);
    t6 += t7;
    let t6h = half(t6);
    t7 = t6h - t7;
    // The even half: a 4-point DCT (a 2-point DCT and a 2-point DST).
    t0 += t6h;
    t6 = t0 - t6;
    t2 = t4h - t2;
    t4 = t2 - t4;
    t0 -= mul(t4, 13573, 15);
    t4 += mul(t0, 11585, 14);
    t0 -= mul(t4, 13573, 15);
    t6 -= mul(t2, 21895, 15);
    t2 += mul(t6, 15137, 14);
    t6 -= mul(t2, 21895, 15);
    // The odd half: a 4-point DST.
    t3 += mul(t5, 19195, 15);
    t5 += mul(t3, 11585, 14);
    t3 -= mul(t5, 7489, 13);
    t7 = half(t5) - t7;
    t5 -= t7;
    t3 = t1h - t3;
    t1 -= t3;
    t7 += mul(t1, 3227, 15);
    t1 -= mul(t7, 6393, 15);
    t7 += mul(t1, 3227, 15);
    t5 += mul(t3, 2485, 13);
    t3 -= mul(t5, 18205, 15);
    t5 += mul(t3, 2485, 13);
    [t0, t1, t2, t3, t4, t5, t6, t7]
}

/// The 2-D transform: columns first, then rows, as Daala orders it (the
/// rounding makes the order matter). `out[i][j]`: vertical frequency i,
/// horizontal j.
fn dct8x8(s: &[[i32; 8]; 8]) -> [[i32; 8]; 8] {
    let columns: [[i32; 8]; 8] = std::array::from_fn(|j| fdct8(std::array::from_fn(|i| s[i][j])));
    std::array::from_fn(|i| fdct8(std::array::from_fn(|j| columns[j][i])))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_integer_dct_approximates_the_orthonormal_one() {
        let x = [12, 200, 37, 90, 255, 0, 128, 64];
        let got = fdct8(x);
        for (k, &g) in got.iter().enumerate() {
            let scale = if k == 0 { (1.0f64 / 8.0).sqrt() } else { 0.5 };
            let want: f64 = (0..8)
                .map(|n| {
                    scale
                        * f64::from(x[n])
                        * (std::f64::consts::PI * (2 * n + 1) as f64 * k as f64 / 16.0).cos()
                })
                .sum();
            assert!((f64::from(g) - want).abs() <= 3.0, "{k}: {g} {want}");
        }
        // A flat block has only DC, 8 times the sample value (to rounding).
        let d = dct8x8(&[[10; 8]; 8]);
        assert!((d[0][0] - 80).abs() <= 1, "{}", d[0][0]);
        assert!(d.iter().flatten().skip(1).all(|&c| c == 0));
    }

    #[test]
    fn tables_are_symmetric() {
        for t in [&CSF_Y, &CSF_CB420, &CSF_CR420] {
            let transposed: [[f64; 8]; 8] = std::array::from_fn(|i| std::array::from_fn(|j| t[j][i]));
            assert_eq!(*t, transposed);
        }
    }

    #[test]
    fn a_dc_error_is_weighted_by_the_dc_sensitivity_alone() {
        // A flat offset of 2 in flat blocks: no AC, no masking, DC error
        // about 16 (8 times 2, to the integer transform's rounding).
        let a = Plane::filled(15, 8, 100).unwrap();
        let b = Plane::filled(15, 8, 102).unwrap();
        let dc = f64::from(dct8x8(&[[102; 8]; 8])[0][0] - dct8x8(&[[100; 8]; 8])[0][0]);
        assert!((dc - 16.0).abs() <= 1.0);
        // Two blocks (x = 0 and 7), the same error in each.
        let want = (dc * CSF_Y[0][0]).powi(2) / 64.0 / (255.0 * 255.0);
        assert!((plane_error(&a, &b, &CSF_Y) - want).abs() < 1e-15);
    }

    #[test]
    fn texture_masks_an_error_that_a_flat_block_shows() {
        let noise = |x: usize, y: usize| ((x * 7919 + y * 104_729) % 61) as u8;
        // A zero-mean error of middle frequencies (period 4 both ways).
        let err = |x: usize, y: usize| if (x / 2 + y / 2) % 2 == 0 { 3 } else { -3 };
        let flat = Plane::filled(64, 64, 120).unwrap();
        let textured = Plane::from_fn(64, 64, |x, y| 90 + noise(x, y)).unwrap();
        let flat_err = Plane::from_fn(64, 64, |x, y| (120 + err(x, y)) as u8).unwrap();
        let textured_err =
            Plane::from_fn(64, 64, |x, y| (90 + i32::from(noise(x, y)) + err(x, y)) as u8).unwrap();
        let (ef, et) = (
            plane_error(&flat, &flat_err, &CSF_Y),
            plane_error(&textured, &textured_err, &CSF_Y),
        );
        assert!(et < 0.5 * ef, "{et} {ef}");
    }
}
