//! The luma interpolation filter of block P frames (FORMAT.md section 3),
//! chosen per frame from how the two filters predicted the frames before
//! it, measured on their decided vectors (SATD of the luma prediction
//! against the source, both filters, a quarter of the macroblocks). Camera
//! noise and motion blur favour the smooth filter, clean synthetic detail
//! the sharp one; a scene keeps its kind from frame to frame, so the
//! frames before are a good guide at a small cost.
//!
//! The ratio of the two SATDs is small where the bits differ by a few per
//! cent (about 0.988 on cockatoo_720p, where smooth frames need 4 % fewer
//! bits), and near 1 it says little: on light_cif and cartoon_cif it
//! swings by 1 % from frame to frame either way while sharp frames need
//! 3-6 % fewer bits. So the ratio is averaged over frames and the smooth
//! filter taken only below [`SMOOTH_BELOW`], given up above
//! [`SHARP_ABOVE`] (between, the filter is kept).

use super::config::FilterChoice;
use crate::codec::consts::MB;
use crate::codec::interp::{predict_luma, LumaFilter};
use crate::codec::partition::MbVectors;
use crate::codec::Frame;
use crate::me::dsp::pixel;

/// One macroblock in this many is measured.
const SAMPLE: usize = 4;

/// The averaged smooth/sharp SATD ratio below which frames go smooth.
const SMOOTH_BELOW: f64 = 0.994;

/// The averaged ratio above which they go back to sharp.
const SHARP_ABOVE: f64 = 0.998;

/// The filter of the next block P frame.
#[derive(Debug, Clone, Copy)]
pub(super) struct FilterChooser {
    next: LumaFilter,
    /// The smooth/sharp SATD ratio, averaged with weight 1/2 on the
    /// latest frame.
    ratio: f64,
}

impl Default for FilterChooser {
    fn default() -> FilterChooser {
        FilterChooser {
            next: LumaFilter::Sharp,
            ratio: 1.0,
        }
    }
}

impl FilterChooser {
    /// The filter the next frame predicts with under `choice`.
    pub(super) fn next(&self, choice: FilterChoice) -> LumaFilter {
        match choice {
            FilterChoice::Auto => self.next,
            FilterChoice::Fixed(f) => f,
        }
    }

    /// Learns from a coded frame (`vectors` into `references`, the first
    /// as weighted for it) which filter predicts its source better; the
    /// `index`-th frame (it picks which macroblocks are measured).
    pub(super) fn learn(&mut self, src: &Frame, references: &[&Frame], vectors: &[MbVectors], index: usize) {
        let [sharp, smooth] = prediction_satd(src, references, vectors, index % SAMPLE);
        // Nothing at a fractional position says nothing.
        if sharp == 0 || smooth == sharp {
            return;
        }
        self.ratio = 0.5 * (self.ratio + smooth as f64 / sharp as f64);
        if self.ratio < SMOOTH_BELOW {
            self.next = LumaFilter::Smooth;
        } else if self.ratio > SHARP_ABOVE {
            self.next = LumaFilter::Sharp;
        }
    }
}

/// The luma prediction's SATD against `src` with each filter (in
/// [`LumaFilter::ALL`]'s order) over every `SAMPLE`-th inter macroblock
/// from `phase` on; blocks at whole-pel positions, the same with both,
/// are left out.
fn prediction_satd(src: &Frame, references: &[&Frame], vectors: &[MbVectors], phase: usize) -> [u64; 2] {
    let cols = src.width() / MB;
    let satd = pixel().satd;
    let source = src.y();
    let mut sums = [0u64; 2];
    let mut pred = [0u8; MB * MB];
    for (i, v) in vectors.iter().enumerate().skip(phase).step_by(SAMPLE) {
        let (x, y) = ((i % cols) * MB, (i / cols) * MB);
        let blocks: &[(usize, usize, usize)] = if v.iter().all(|b| *b == v[0]) {
            &[(0, 0, 16)]
        } else {
            &[(0, 0, 8), (8, 0, 8), (0, 8, 8), (8, 8, 8)]
        };
        for (k, &(bx, by, n)) in blocks.iter().enumerate() {
            let Some(m) = v[k] else {
                continue;
            };
            let Some(reference) = references.get(usize::from(m.ref_idx)) else {
                continue;
            };
            if m.mv.x & 3 == 0 && m.mv.y & 3 == 0 {
                continue;
            }
            let (px, py) = ((x + bx) as isize, (y + by) as isize);
            let at = source.index(px, py);
            for (sum, filter) in sums.iter_mut().zip(LumaFilter::ALL) {
                predict_luma(filter, reference.y(), px, py, m.mv.x, m.mv.y, n, n, &mut pred, n);
                *sum += u64::from(satd(&source.data()[at..], source.stride(), &pred, n, n, n));
            }
        }
    }
    sums
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::mv::Mv;
    use crate::codec::partition::RefMv;
    use crate::codec::picture::{PictureError, Plane};

    /// A 64x48 frame of luma `f` and grey chroma.
    fn luma_frame(f: impl FnMut(usize, usize) -> u8) -> Result<Frame, PictureError> {
        let grey = || Plane::filled(32, 24, 128);
        Frame::from_planes(Plane::from_fn(64, 48, f)?, grey()?, grey()?)
    }

    /// A noisy picture, and the same picture blurred and moved by half a
    /// pixel: what a smooth filter predicts better than a sharp one.
    fn blurred_shift() -> Result<(Frame, Frame), PictureError> {
        let noise = |x: usize, y: usize| -> f64 {
            let v = (x as u32).wrapping_mul(2_654_435_761) ^ (y as u32).wrapping_mul(40_503);
            f64::from(v.wrapping_mul(2_246_822_519) >> 24)
        };
        let reference = luma_frame(|x, y| noise(x, y) as u8)?;
        // Each source sample the mean of two horizontal neighbours: the
        // half-pel position of the linear interpolation, which the smooth
        // filter is nearer to than the sharp one.
        let src = luma_frame(|x, y| ((noise(x, y) + noise((x + 1).min(63), y)) / 2.0).round() as u8)?;
        Ok((src, reference))
    }

    #[test]
    fn a_blurred_half_pel_shift_picks_the_smooth_filter_and_whole_pels_keep_it() -> Result<(), PictureError> {
        let (src, reference) = blurred_shift()?;
        let cols = src.width() / MB;
        let n = cols * (src.height() / MB);
        let half = [Some(RefMv::previous(Mv::new(2, 0))); 4];
        let mut chooser = FilterChooser::default();
        assert_eq!(chooser.next(FilterChoice::Auto), LumaFilter::Sharp);
        chooser.learn(&src, &[&reference], &vec![half; n], 0);
        assert_eq!(chooser.next(FilterChoice::Auto), LumaFilter::Smooth);
        // A fixed choice overrides what was learnt.
        let sharp = FilterChoice::Fixed(LumaFilter::Sharp);
        assert_eq!(chooser.next(sharp), LumaFilter::Sharp);
        // Whole-pel vectors and intra macroblocks say nothing: kept.
        let whole = [Some(RefMv::previous(Mv::full_pel(1, 0))); 4];
        chooser.learn(&src, &[&reference], &vec![whole; n], 1);
        chooser.learn(&src, &[&reference], &vec![[None; 4]; n], 2);
        assert_eq!(chooser.next(FilterChoice::Auto), LumaFilter::Smooth);
        // The unblurred picture moved by a whole pixel, seen through a
        // vector a quarter-pel off it: the sharp filter keeps more of it.
        let moved = luma_frame(|x, y| reference.y().pixel_clamped(x as isize + 1, y as isize))?;
        let near = [Some(RefMv::previous(Mv::new(3, 0))); 4];
        chooser.learn(&moved, &[&reference], &vec![near; n], 0);
        assert_eq!(chooser.next(FilterChoice::Auto), LumaFilter::Sharp);
        Ok(())
    }
}
