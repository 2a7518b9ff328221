//! Sub-pixel interpolation for motion compensation (normative).
//!
//! * Luma: quarter-pel, separable 8-tap filters, one of two that each P
//!   frame's header picks ([`LumaFilter`]): HEVC's (H.265 8.5.3.3.3.1) or
//!   H.264's 6-tap shape. A horizontal pass keeps full precision (gain
//!   64), a vertical pass divides by 64, and the result is rounded
//!   `(v + 32) >> 6` and clipped to 0..=255. Integer positions are plain
//!   copies.
//! * Chroma: bilinear at 1/8 pel (as H.264 8.4.2.2.2):
//!   `((8-fx)(8-fy) A + fx(8-fy) B + (8-fx)fy C + fx fy D + 32) >> 6`.
//!   A luma vector in quarter-pel units is the chroma vector in eighth-pel
//!   units (chroma has half the resolution).
//!
//! The reference picture extends without limit by repeating its edge
//! samples: any vector is valid. The plane's border holds that extension,
//! and a block displaced further out than the border is moved back inside
//! it, which reads the same samples as long as the border is at least the
//! block size plus 8 (checked).
//!
//! ```
//! use mocomp_codec::interp::{predict_luma, LumaFilter};
//! use mocomp_codec::picture::Plane;
//! let reference = Plane::from_fn(32, 32, |x, _| (x * 4) as u8).unwrap();
//! let mut out = [0u8; 16];
//! // Half a pixel to the right of (8, 8) on a ramp of slope 4: +2.
//! predict_luma(LumaFilter::Sharp, &reference, 8, 8, 2, 0, 4, 4, &mut out, 4);
//! assert_eq!(out[0], 34);
//! ```

use crate::dsp::mc::{mc, McDsp, TAPS_BEFORE};
pub use crate::dsp::mc::{LumaTaps, LUMA_TAPS, MAX_BLOCK, SMOOTH_LUMA_TAPS};
use crate::picture::Plane;

/// The luma interpolation filter of a P frame (its header's `luma_filter`
/// bit, FORMAT.md section 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum LumaFilter {
    /// HEVC's 8-tap filter ([`LUMA_TAPS`]): the sharper, for clean
    /// detailed pictures.
    #[default]
    Sharp,
    /// H.264's 6-tap shape ([`SMOOTH_LUMA_TAPS`]): the better prediction
    /// where the camera adds noise and blur.
    Smooth,
}

impl LumaFilter {
    /// Both, in the order of their header codes.
    pub const ALL: [LumaFilter; 2] = [LumaFilter::Sharp, LumaFilter::Smooth];

    /// Its taps.
    pub fn taps(self) -> &'static LumaTaps {
        match self {
            LumaFilter::Sharp => &LUMA_TAPS,
            LumaFilter::Smooth => &SMOOTH_LUMA_TAPS,
        }
    }

    /// Its header code.
    pub fn code(self) -> u64 {
        match self {
            LumaFilter::Sharp => 0,
            LumaFilter::Smooth => 1,
        }
    }

    /// The filter of a header code (one bit).
    pub fn from_code(code: u64) -> LumaFilter {
        if code == 0 {
            LumaFilter::Sharp
        } else {
            LumaFilter::Smooth
        }
    }
}

/// Samples the 8-tap filter reads before and after the block.
const BEFORE: isize = TAPS_BEFORE as isize;
const AFTER: isize = 4;

/// Moves a block's top-left coordinate (with `before` and `after` extra
/// samples read around a block of `size`) back into the plane's border
/// when it lies beyond it: the samples read are unchanged, since every
/// sample out there repeats the same edge sample.
#[inline]
fn clamp_into_border(
    pos: isize,
    size: usize,
    extent: usize,
    pad: usize,
    before: isize,
    after: isize,
) -> isize {
    let pad = pad as isize;
    let lo = -pad + before;
    let hi = extent as isize + pad - size as isize - after;
    pos.clamp(lo, hi.max(lo))
}

fn check_block(reference: &Plane, w: usize, h: usize, out: &[u8], out_stride: usize) {
    assert!(
        w <= MAX_BLOCK && h <= MAX_BLOCK && w > 0 && h > 0,
        "block {w}x{h}"
    );
    assert!(
        reference.pad() >= w.max(h) + 8,
        "plane border {} too small for {w}x{h} blocks",
        reference.pad()
    );
    assert!(
        out_stride >= w && out.len() >= (h - 1) * out_stride + w,
        "output too small"
    );
}

/// Luma prediction of the `w x h` block at (x, y) displaced by the
/// quarter-pel vector (mvx, mvy) through `filter`, into `out` (row stride
/// `out_stride`), by the motion compensation kernels of the CPU level in
/// force.
#[allow(clippy::too_many_arguments)]
pub fn predict_luma(
    filter: LumaFilter,
    reference: &Plane,
    x: isize,
    y: isize,
    mvx: i32,
    mvy: i32,
    w: usize,
    h: usize,
    out: &mut [u8],
    out_stride: usize,
) {
    predict_luma_with(
        (mc(), filter),
        reference,
        (x, y),
        (mvx, mvy),
        (w, h),
        out,
        out_stride,
    );
}

/// [`predict_luma`] with the kernels of `dsp`.
pub fn predict_luma_with(
    (dsp, filter): (&McDsp, LumaFilter),
    reference: &Plane,
    (x, y): (isize, isize),
    (mvx, mvy): (i32, i32),
    (w, h): (usize, usize),
    out: &mut [u8],
    out_stride: usize,
) {
    check_block(reference, w, h, out, out_stride);
    let (fx, fy) = ((mvx & 3) as usize, (mvy & 3) as usize);
    let (width, height, pad) = (reference.width(), reference.height(), reference.pad());
    let px = clamp_into_border(x + (mvx >> 2) as isize, w, width, pad, BEFORE, AFTER);
    let py = clamp_into_border(y + (mvy >> 2) as isize, h, height, pad, BEFORE, AFTER);
    let origin = reference.index(px - BEFORE, py - BEFORE);
    (dsp.luma)(
        filter.taps(),
        &reference.data()[origin..],
        reference.stride(),
        (fx, fy),
        (w, h),
        out,
        out_stride,
    );
}

/// Chroma prediction of the `w x h` block at chroma position (x, y)
/// displaced by the eighth-pel vector (mvx, mvy) (the luma quarter-pel
/// vector), into `out`.
#[allow(clippy::too_many_arguments)]
pub fn predict_chroma(
    reference: &Plane,
    x: isize,
    y: isize,
    mvx: i32,
    mvy: i32,
    w: usize,
    h: usize,
    out: &mut [u8],
    out_stride: usize,
) {
    predict_chroma_with(mc(), reference, (x, y), (mvx, mvy), (w, h), out, out_stride);
}

/// [`predict_chroma`] with the kernels of `dsp`.
pub fn predict_chroma_with(
    dsp: &McDsp,
    reference: &Plane,
    (x, y): (isize, isize),
    (mvx, mvy): (i32, i32),
    (w, h): (usize, usize),
    out: &mut [u8],
    out_stride: usize,
) {
    check_block(reference, w, h, out, out_stride);
    let (fx, fy) = ((mvx & 7) as usize, (mvy & 7) as usize);
    let (width, height, pad) = (reference.width(), reference.height(), reference.pad());
    let px = clamp_into_border(x + (mvx >> 3) as isize, w, width, pad, 0, 1);
    let py = clamp_into_border(y + (mvy >> 3) as isize, h, height, pad, 0, 1);
    let origin = reference.index(px, py);
    (dsp.chroma)(
        &reference.data()[origin..],
        reference.stride(),
        (fx, fy),
        (w, h),
        out,
        out_stride,
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::CpuLevel;
    use crate::dsp::mc::MC;
    use crate::picture::PictureError;
    use proptest::prelude::*;

    /// The luma equations written directly: every sample read through
    /// `pixel_clamped` (an infinitely extended picture), no border, no
    /// separable pass.
    fn reference_luma(
        filter: LumaFilter,
        p: &Plane,
        (x, y): (isize, isize),
        (mvx, mvy): (i32, i32),
        (w, h): (usize, usize),
    ) -> Vec<u8> {
        let taps = filter.taps();
        let (ix, iy) = (x + (mvx >> 2) as isize, y + (mvy >> 2) as isize);
        let (fx, fy) = ((mvx & 3) as usize, (mvy & 3) as usize);
        let mut out = Vec::with_capacity(w * h);
        for r in 0..h as isize {
            for c in 0..w as isize {
                let sample = |dx: isize, dy: isize| i64::from(p.pixel_clamped(ix + c + dx, iy + r + dy));
                let v = if fx == 0 && fy == 0 {
                    sample(0, 0)
                } else if fy == 0 {
                    ((0..8)
                        .map(|k| i64::from(taps[fx][k]) * sample(k as isize - 3, 0))
                        .sum::<i64>()
                        + 32)
                        >> 6
                } else if fx == 0 {
                    ((0..8)
                        .map(|k| i64::from(taps[fy][k]) * sample(0, k as isize - 3))
                        .sum::<i64>()
                        + 32)
                        >> 6
                } else {
                    let hpass = |dy: isize| {
                        (0..8)
                            .map(|k| i64::from(taps[fx][k]) * sample(k as isize - 3, dy))
                            .sum::<i64>()
                    };
                    let v = (0..8)
                        .map(|k| i64::from(taps[fy][k]) * hpass(k as isize - 3))
                        .sum::<i64>()
                        >> 6;
                    (v + 32) >> 6
                };
                out.push(v.clamp(0, 255) as u8);
            }
        }
        out
    }

    fn reference_chroma(p: &Plane, x: isize, y: isize, mvx: i32, mvy: i32, w: usize, h: usize) -> Vec<u8> {
        let (ix, iy) = (x + (mvx >> 3) as isize, y + (mvy >> 3) as isize);
        let (fx, fy) = (i64::from(mvx & 7), i64::from(mvy & 7));
        let mut out = Vec::with_capacity(w * h);
        for r in 0..h as isize {
            for c in 0..w as isize {
                let s = |dx, dy| i64::from(p.pixel_clamped(ix + c + dx, iy + r + dy));
                let v = (8 - fx) * (8 - fy) * s(0, 0)
                    + fx * (8 - fy) * s(1, 0)
                    + (8 - fx) * fy * s(0, 1)
                    + fx * fy * s(1, 1);
                out.push(((v + 32) >> 6) as u8);
            }
        }
        out
    }

    fn noise_plane(w: usize, h: usize, seed: u32) -> Result<Plane, PictureError> {
        Plane::from_fn(w, h, |x, y| {
            let v = (x as u32).wrapping_mul(2_654_435_761) ^ (y as u32).wrapping_mul(40_503) ^ seed;
            (v.wrapping_mul(2_246_822_519) >> 24) as u8
        })
    }

    #[test]
    fn taps_sum_to_64_and_half_pel_is_symmetric() {
        for filter in LumaFilter::ALL {
            let taps = filter.taps();
            for t in taps {
                assert_eq!(t.iter().sum::<i32>(), 64);
            }
            let half = taps[2];
            assert_eq!(
                half,
                [half[7], half[6], half[5], half[4], half[3], half[2], half[1], half[0]]
            );
            // The quarter and three-quarter filters mirror each other.
            let (q, tq) = (taps[1], taps[3]);
            for k in 0..8 {
                assert_eq!(q[k], tq[7 - k], "{filter:?}");
            }
            assert_eq!(LumaFilter::from_code(filter.code()), filter);
        }
        // H.264's quarter-pel sample: the mean of the whole sample and the
        // half-pel one, here without the rounding between.
        let (whole, half) = (SMOOTH_LUMA_TAPS[0], SMOOTH_LUMA_TAPS[2]);
        for k in 0..8 {
            assert_eq!(2 * SMOOTH_LUMA_TAPS[1][k], whole[k] + half[k]);
        }
    }

    #[test]
    fn every_level_predicts_what_the_scalar_kernels_predict() -> Result<(), PictureError> {
        let p = noise_plane(70, 50, 11)?;
        let (mut a, mut b) = (vec![0u8; 64 * 64], vec![0u8; 64 * 64]);
        for mvy in -9..=9 {
            for mvx in -9..=9 {
                for (x, y, w, h) in [(3, 5, 16, 16), (40, 20, 16, 16), (1, 2, 12, 3), (0, 0, 64, 40)] {
                    for level in crate::cpu::available() {
                        let (dsp, scalar) = (MC.at(level), MC.at(CpuLevel::Scalar));
                        let at = ((x, y), (mvx, mvy), (w, h));
                        for f in LumaFilter::ALL {
                            predict_luma_with((dsp, f), &p, at.0, at.1, at.2, &mut a, w);
                            predict_luma_with((scalar, f), &p, at.0, at.1, at.2, &mut b, w);
                            assert_eq!(a[..w * h], b[..w * h], "{level:?} {f:?} mv ({mvx},{mvy}) {w}x{h}");
                        }
                        predict_chroma_with(dsp, &p, at.0, at.1, at.2, &mut a, w);
                        predict_chroma_with(scalar, &p, at.0, at.1, at.2, &mut b, w);
                        assert_eq!(
                            a[..w * h],
                            b[..w * h],
                            "{level:?} chroma mv ({mvx},{mvy}) {w}x{h}"
                        );
                    }
                }
            }
        }
        Ok(())
    }

    #[test]
    fn every_phase_matches_the_direct_formula() -> Result<(), PictureError> {
        let p = noise_plane(37, 29, 7)?;
        let mut out = vec![0u8; 16 * 16];
        for mvy in -9..=9 {
            for mvx in -9..=9 {
                for (x, y, w, h) in [(0, 0, 16, 16), (21, 13, 16, 16), (5, 7, 4, 8), (33, 25, 8, 4)] {
                    for f in LumaFilter::ALL {
                        predict_luma(f, &p, x, y, mvx, mvy, w, h, &mut out, w);
                        assert_eq!(
                            out[..w * h],
                            reference_luma(f, &p, (x, y), (mvx, mvy), (w, h))[..],
                            "{f:?} luma mv ({mvx},{mvy}) at ({x},{y})"
                        );
                    }
                }
            }
        }
        let c = noise_plane(19, 15, 3)?;
        for mvy in -17..=17 {
            for mvx in -17..=17 {
                for (x, y, w, h) in [(0, 0, 8, 8), (11, 7, 8, 8), (16, 12, 4, 4)] {
                    predict_chroma(&c, x, y, mvx, mvy, w, h, &mut out, w);
                    assert_eq!(
                        out[..w * h],
                        reference_chroma(&c, x, y, mvx, mvy, w, h)[..],
                        "chroma mv ({mvx},{mvy})"
                    );
                }
            }
        }
        Ok(())
    }

    #[test]
    fn integer_vectors_copy_and_flat_pictures_stay_flat() -> Result<(), PictureError> {
        let p = noise_plane(40, 40, 1)?;
        let mut out = [0u8; 64];
        for f in LumaFilter::ALL {
            predict_luma(f, &p, 8, 8, 4 * 3, 4 * -2, 8, 8, &mut out, 8);
            for r in 0..8 {
                for c in 0..8 {
                    assert_eq!(out[r * 8 + c], p.get(11 + c, 6 + r));
                }
            }
        }
        let flat = Plane::filled(20, 20, 173)?;
        for phase in 0..16 {
            for f in LumaFilter::ALL {
                predict_luma(f, &flat, 2, 2, phase % 4 + 4, phase / 4 - 8, 8, 8, &mut out, 8);
                assert!(out.iter().all(|&v| v == 173));
            }
            predict_chroma(&flat, 2, 2, phase % 8, phase / 2 - 3, 8, 8, &mut out, 8);
            assert!(out.iter().all(|&v| v == 173));
        }
        Ok(())
    }

    proptest! {
        #[test]
        fn any_vector_reads_the_extended_picture(
            mvx in -40_000i32..40_000, mvy in -40_000i32..40_000,
            x in -20isize..60, y in -20isize..60, size in prop_oneof![Just(4usize), Just(8), Just(16), Just(32)]
        ) {
            let p = noise_plane(45, 38, 11)?;
            let mut out = vec![0u8; size * size];
            for f in LumaFilter::ALL {
                predict_luma(f, &p, x, y, mvx, mvy, size, size, &mut out, size);
                prop_assert_eq!(&out, &reference_luma(f, &p, (x, y), (mvx, mvy), (size, size)));
            }
            let c = noise_plane(23, 19, 5)?;
            let cs = (size / 2).max(2);
            let mut out = vec![0u8; cs * cs];
            predict_chroma(&c, x / 2, y / 2, mvx, mvy, cs, cs, &mut out, cs);
            prop_assert_eq!(&out, &reference_chroma(&c, x / 2, y / 2, mvx, mvy, cs, cs));
        }
    }
}
