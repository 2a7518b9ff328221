//! Rate-distortion pricing of the mode decision (x264's `rdo.c` and the
//! lambda of `analyse.c`): the weight of a bit against squared error, the
//! J = SSD + lambda * bits of a coded candidate, the SATD + sqrt(lambda) *
//! bits estimate that ranks candidates before any is coded, and the rate
//! estimates of vectors and reference indices.

use crate::me::{lambda_for_qp, Metric};

/// How far above the best's SATD + rate estimate an alternative is still
/// coded and weighed by RD: sub-pel RD's steps and slower's splits (x264's
/// 5/4; the 16x16 candidates take `analyse::CANDIDATE_MARGIN`).
pub(super) const RD_MARGIN: f64 = 1.25;

/// The quantiser's rounding offset (a fraction of a step) of a residual
/// block: the H.264 reference encoder's dead zones (1/3 intra; 1/6 inter,
/// whose residuals are mostly noise) where the levels are kept as
/// rounded, and a rounding nearer the middle where RDOQ follows. RDOQ
/// only lowers levels, so from the dead zone's levels it never weighed
/// the level above them; x264's trellis starts from the nearest level.
/// Against the dead zones under RDOQ (medium, `benches/pair.py`, the 28
/// sequences and four kinds, 60 frames): 1/2 for both -0.98 % for 1.08x
/// the encoder's time (fish_1160 +5.2 %, cuts_cif +6.0 %: a flickering
/// light and cuts, coded inter), 1/2 intra and 1/4 inter -1.17 % for
/// 1.02x, 1/2 and 1/3 -1.77 % for 1.04x, 1/2 and 0.4 -1.43 % for 1.06x.
/// Without RDOQ the dead zone holds (fast, inter at 1/4: +0.43 %).
pub(super) const fn quant_rounding(intra: bool, rdoq: bool) -> f64 {
    match (intra, rdoq) {
        (true, false) => 1.0 / 3.0,
        (false, false) => 1.0 / 6.0,
        (true, true) => 0.5,
        (false, true) => 1.0 / 3.0,
    }
}

/// The mode decision's lambda at `qp`: the H.264 reference encoder's
/// `0.85 * 2^((qp - 12) / 3)` times `scale` (the configuration's
/// `lambda_scale`).
pub(super) fn lambda(qp: u8, scale: f64) -> f64 {
    scale * lambda_for_qp(Metric::Ssd, qp)
}

/// J = SSD + lambda * bits.
#[inline]
pub(super) fn cost(lambda: f64, ssd: u64, bits: f64) -> f64 {
    ssd as f64 + lambda * bits
}

/// A candidate's estimate before coding: SATD + sqrt(lambda) * bits.
#[inline]
pub(super) fn estimate(lambda: f64, satd: u32, bits: u32) -> f64 {
    f64::from(satd) + lambda.sqrt() * f64::from(bits)
}

/// Bits from the entropy coders' prices (1/256 bit units).
#[inline]
pub(super) fn bits(price: u32) -> f64 {
    f64::from(price) / 256.0
}

/// The length of reference index `ref_idx`'s truncated unary code among
/// `refs` references (the rate estimate of the motion search).
pub(super) fn reference_bits(ref_idx: u8, refs: u8) -> u32 {
    u32::from(if ref_idx + 1 < refs { ref_idx + 1 } else { ref_idx })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reference_indices_cost_their_truncated_unary_code() {
        // One reference: nothing coded. Three: 1, 2, 2 bits.
        assert_eq!(reference_bits(0, 1), 0);
        assert_eq!([0, 1, 2].map(|r| reference_bits(r, 3)), [1, 2, 2]);
    }

    #[test]
    fn the_lambda_doubles_every_three_qp_and_prices_bits_against_ssd() {
        let l = lambda(30, 1.0);
        assert!((lambda(33, 1.0) / l - 2.0).abs() < 1e-12);
        assert!((lambda(30, 1.4) / l - 1.4).abs() < 1e-12);
        assert_eq!(cost(10.0, 100, 3.0), 130.0);
        assert_eq!(estimate(16.0, 100, 3), 112.0);
        assert_eq!(bits(512), 2.0);
    }
}
