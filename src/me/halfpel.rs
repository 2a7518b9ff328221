//! Half-pel planes of a reference, for sub-pel search (x264's approach).
//!
//! The three half-pel phases (horizontal, vertical, both) are computed once
//! per reference with the codec's own filter, so every half-pel candidate
//! costs a copy (or, where few blocks are searched, per searched block over
//! the patch its sub-pel steps read, [`with_patch`], the same samples); a
//! quarter-pel candidate is the rounded average of its two nearest full-
//! or half-pel samples, as H.264 interpolates. That average
//! only approximates the codec's 8-tap quarter-pel filter: the search uses
//! it to rank candidates, and what the encoder then predicts with is the
//! codec's exact interpolation.

use std::cell::RefCell;

use super::dsp::{
    average_rows, copy_rows, fill_halfpel, fill_halfpel_rows, pixel, HalfpelBand, PixelDsp, PATCH18_PHASE,
    PATCH18_ROWS, PATCH18_STRIDE,
};
use crate::codec::interp::{predict_luma, LumaFilter};
use crate::codec::mv::Mv;
use crate::codec::Plane;

/// How far beyond a sample the 8-tap filter reads (3 before, 4 after).
const FILTER_REACH: usize = 4;

/// The largest block a patch serves ([`with_patch`]): a macroblock (larger
/// blocks' searches keep whole planes).
pub(crate) const PATCH_BLOCK_MAX: usize = 16;

/// A patch's side for the largest block: the block and a sample each way.
const PATCH_SIDE_MAX: usize = PATCH_BLOCK_MAX + 2;

/// A patch's rows are filtered in multiples of this many samples.
const PATCH_ROW_STEP: usize = 32;

/// A patch's longest rows.
const PATCH_STRIDE_MAX: usize = PATCH_SIDE_MAX.next_multiple_of(PATCH_ROW_STEP);

/// The reference's half-pel phases over the picture and a margin around
/// it, or over one block's neighbourhood.
pub(crate) struct HalfPel {
    store: Store,
    /// How far outside the picture the phases are what the codec's filter
    /// gives (candidates beyond take the filter itself).
    margin: isize,
    /// The kernels that made the phases and average them.
    dsp: &'static PixelDsp,
}

/// Where a [`HalfPel`]'s samples are kept.
enum Store {
    /// Horizontal, vertical and diagonal half-pel planes: entry (x, y) is
    /// the sample at (x + 1/2, y), (x, y + 1/2), (x + 1/2, y + 1/2).
    /// (Only the picture and margin are written; nothing reads beyond.)
    Planes(Vec<Plane>),
    /// The same three phases over the `w x h` rectangle (`size`) from
    /// picture position `origin` only (each phase `h` rows of `w`, one
    /// after the other): all that one block's sub-pel steps read.
    Patch {
        samples: Box<[u8; 3 * PATCH_STRIDE_MAX * PATCH_SIDE_MAX]>,
        origin: (isize, isize),
        size: (usize, usize),
    },
}

impl HalfPel {
    /// The half-pel planes of `reference`, filled `margin` pixels beyond
    /// each edge; `margin + 4` must not exceed the reference's border.
    pub fn new(reference: &Plane, margin: usize) -> Option<HalfPel> {
        let (w, h, pad) = (reference.width(), reference.height(), reference.pad());
        if margin + FILTER_REACH > pad {
            return None;
        }
        let mut planes = Vec::with_capacity(3);
        for _ in 0..3 {
            planes.push(crate::spare_planes::take(w, h, pad)?);
        }
        let dsp = pixel();
        // A band per worker: the planes are most of what a frame's motion
        // analysis does on one thread before its rows start.
        let bands = rayon::current_num_threads();
        fill_halfpel(dsp.halfpel_planes, reference, margin, &mut planes, bands);
        Some(HalfPel {
            store: Store::Planes(planes),
            margin: margin as isize,
            dsp,
        })
    }

    /// Half-pel planes of `reference`'s size with none of their rows
    /// filled: [`HalfPel::fill_rows`] fills them as the reference's rows
    /// arrive (the reference of a frame thread, a band at a time).
    pub fn unfilled(reference: &Plane, margin: usize) -> Option<HalfPel> {
        let (w, h, pad) = (reference.width(), reference.height(), reference.pad());
        if margin + FILTER_REACH > pad {
            return None;
        }
        let planes = (0..3)
            .map(|_| crate::spare_planes::take(w, h, pad))
            .collect::<Option<Vec<_>>>()?;
        Some(HalfPel {
            store: Store::Planes(planes),
            margin: margin as isize,
            dsp: pixel(),
        })
    }

    /// Fills the planes' rows `rows` (counted from the margin's first:
    /// `0..height + 2 * margin`) as [`HalfPel::new`] fills them, from
    /// `reference`'s rows to `rows.end - margin + 4` (their borders
    /// extended): runs of rows from the top make the same planes.
    pub fn fill_rows(&mut self, reference: &Plane, rows: std::ops::Range<usize>) {
        if let Store::Planes(planes) = &mut self.store {
            fill_halfpel_rows(
                self.dsp.halfpel_planes,
                reference,
                self.margin as usize,
                planes,
                rows,
            );
        }
    }

    /// Fills this patch with the half-pel phases that the sub-pel steps
    /// of the `b x b` block at full-pel position (x, y) read (see
    /// [`with_patch`]).
    fn fill_patch(&mut self, reference: &Plane, (x, y): (isize, isize), b: usize) {
        let Store::Patch {
            samples,
            origin,
            size,
        } = &mut self.store
        else {
            return;
        };
        // The square from a sample before the block to one after it, cut
        // to where the reference's border holds the filter's taps (3
        // before, 4 after): no candidate that reaches into the margin
        // reads beyond that.
        let (pad, b) = (reference.pad() as isize, b as isize);
        let cut = |at: isize, len: usize| {
            let (first, end) = ((at - 1).max(3 - pad), (at + b + 1).min(len as isize + pad - 4));
            (first, (end - first).max(0) as usize)
        };
        let ((x0, w), (y0, h)) = (cut(x, reference.width()), cut(y, reference.height()));
        // Rows filtered 32 samples wide where the border holds them: the
        // kernels' vector width, where a few samples past it would go to
        // their scalar tails and cost more than the rest.
        let wide = w.next_multiple_of(PATCH_ROW_STEP);
        let w = if x0 + (wide + FILTER_REACH) as isize <= reference.width() as isize + pad {
            wide
        } else {
            w
        };
        if (w, h) == (PATCH18_STRIDE, PATCH18_ROWS) {
            // A macroblock's whole patch: the one-pass kernel.
            (self.dsp.halfpel_patch18)(reference, (x0, y0), &mut samples[..3 * PATCH18_PHASE]);
        } else if w > 0 && h > 0 {
            let area = w * h;
            let (hp, rest) = samples.split_at_mut(area);
            let (vp, rest) = rest.split_at_mut(area);
            let band = HalfpelBand {
                origin: (x0, y0),
                rows: h,
                span: w,
                out: [hp, vp, &mut rest[..area]],
                out_x: 0,
                stride: w,
            };
            (self.dsp.halfpel_planes)(reference, band);
        }
        (*origin, *size) = ((x0, y0), (w, h));
    }

    /// How far beyond the picture the phases are filled.
    pub fn margin(&self) -> usize {
        self.margin as usize
    }

    /// Whether the `b x b` block at (bx, by), and one sample around it,
    /// lies inside `reference`'s filled margin (for a patch, the same
    /// answer as for planes: only blocks the patch holds can lie inside).
    fn reaches(&self, reference: &Plane, bx: isize, by: isize, b: usize) -> bool {
        let (w, h) = (reference.width() as isize, reference.height() as isize);
        let b = b as isize;
        let inside =
            bx > -self.margin && by > -self.margin && bx + b < w + self.margin && by + b < h + self.margin;
        if let Store::Patch { origin, size, .. } = self.store {
            // The block and the sample after it (a quarter's average).
            let holds = |at: isize, o: isize, len: usize| at >= o && at + b < o + len as isize;
            let held = holds(bx, origin.0, size.0) && holds(by, origin.1, size.1);
            debug_assert!(!inside || held, "a sub-pel step beyond its patch");
            return inside && held;
        }
        inside
    }

    /// The samples of phase `(px, py)` (quarter-pels, each 0 or 2) from
    /// picture position (x, y) on, and their stride: the reference's own
    /// at (0, 0).
    pub(crate) fn phase_at<'a>(
        &'a self,
        reference: &'a Plane,
        (px, py): (i32, i32),
        x: isize,
        y: isize,
    ) -> (&'a [u8], usize) {
        let k = match (px, py) {
            (0, 0) => return (&reference.data()[reference.index(x, y)..], reference.stride()),
            (2, 0) => 0,
            (0, 2) => 1,
            _ => 2,
        };
        match &self.store {
            Store::Planes(planes) => {
                let p = &planes[k];
                (&p.data()[p.index(x, y)..], p.stride())
            }
            Store::Patch {
                samples,
                origin,
                size: (w, h),
            } => {
                let at = k * w * h + (y - origin.1) as usize * w + (x - origin.0) as usize;
                (&samples[at..], *w)
            }
        }
    }

    /// The `b x b` block at (x, y) displaced by the quarter-pel vector
    /// (mvx, mvy) where it lies on the half-pel grid (both components
    /// even): its samples where they are, in the reference or one of its
    /// planes, and their stride, with no copy (as x264's `get_ref`);
    /// `None` at a quarter-pel position or beyond the filled margin.
    pub fn block_in_place<'a>(
        &'a self,
        reference: &'a Plane,
        (x, y): (isize, isize),
        (mvx, mvy): (i32, i32),
        b: usize,
    ) -> Option<(&'a [u8], usize)> {
        let (bx, by) = (x + (mvx >> 2) as isize, y + (mvy >> 2) as isize);
        if (mvx | mvy) & 1 != 0 || !self.reaches(reference, bx, by, b) {
            return None;
        }
        Some(self.phase_at(reference, (mvx & 3, mvy & 3), bx, by))
    }

    /// The `b x b` block at (x, y) displaced by the quarter-pel vector
    /// (mvx, mvy), into `out`; `false` (nothing written) when it reaches
    /// beyond the filled margin.
    #[allow(clippy::too_many_arguments)]
    pub fn predict<'a>(
        &'a self,
        reference: &'a Plane,
        x: isize,
        y: isize,
        mvx: i32,
        mvy: i32,
        b: usize,
        out: &mut [u8],
    ) -> bool {
        let (bx, by) = (x + (mvx >> 2) as isize, y + (mvy >> 2) as isize);
        // Samples read: one beyond the block on each side at most.
        if !self.reaches(reference, bx, by, b) {
            return false;
        }
        let (fx, fy) = (mvx & 3, mvy & 3);
        // A point of the half-pel grid, in quarter-pels from (bx, by):
        // its plane and integer offset.
        let point = |px: i32, py: i32| ((px & 3, py & 3), bx + (px >> 2) as isize, by + (py >> 2) as isize);
        let rows = |(phase, px, py)| self.phase_at(reference, phase, px, py);
        // The macroblock and partition sizes through the table; 8 passed
        // as a constant, so that the rows have a length the compiler knows.
        let copy = |(a, sa): (&[u8], usize), out: &mut [u8]| match b {
            16 => (self.dsp.copy_16x16)(a, sa, out),
            8 => copy_rows(8, a, sa, out),
            _ => copy_rows(b, a, sa, out),
        };
        let average = |from, to, out: &mut [u8]| match b {
            16 => (self.dsp.average_16x16)(rows(from), rows(to), out),
            8 => (self.dsp.average_8x8)(rows(from), rows(to), out),
            _ => average_rows(b, rows(from), rows(to), out),
        };
        match (fx & 1, fy & 1) {
            (0, 0) => copy(rows(point(fx, fy)), out),
            (1, 0) => average(point(fx - 1, fy), point(fx + 1, fy), out),
            (0, 1) => average(point(fx, fy - 1), point(fx, fy + 1), out),
            _ => average(point(2, 4 * (fy / 2)), point(4 * (fx / 2), 2), out),
        }
        true
    }
}

/// The four phases of a [`HalfPel`] (whole pel, then the horizontal,
/// vertical and diagonal half-pel ones) as one `b x b` block's sub-pel
/// candidates read them: the phases and the range of full-pel
/// displacements within reach found once, so that each candidate costs an
/// offset, a bounds check and at most one average (the many candidates of
/// a block's sub-pel steps went through [`block_or_predicted`] each, and
/// finding the phase and its reach again took more instructions than the
/// 16x16 average: about 160 against 110 in birds_720p's profile).
/// It gives the samples [`block_or_predicted`] gives wherever it holds
/// the block ([`PhaseWindow::holds`]); elsewhere that takes the codec's
/// filter.
pub(crate) struct PhaseWindow<'a> {
    /// Each phase's samples from the block displaced by `lo` on, and
    /// their stride.
    phases: [(&'a [u8], usize); 4],
    /// The least and greatest full-pel displacements (dx, dy) within
    /// reach: the block and a sample after it inside what is filled.
    lo: (isize, isize),
    hi: (isize, isize),
    b: usize,
    dsp: &'static PixelDsp,
}

impl HalfPel {
    /// The window of the `b x b` block at (x, y); `None` where no
    /// displacement is within reach.
    pub(crate) fn window<'a>(
        &'a self,
        reference: &'a Plane,
        (x, y): (isize, isize),
        b: usize,
    ) -> Option<PhaseWindow<'a>> {
        let (w, h) = (reference.width() as isize, reference.height() as isize);
        let (b_i, m) = (b as isize, self.margin);
        // `reaches`: bx > -m and bx + b < w + m, by alike (bx = x + dx).
        let mut lo = (1 - m - x, 1 - m - y);
        let mut hi = (w + m - b_i - 1 - x, h + m - b_i - 1 - y);
        if let Store::Patch { origin, size, .. } = self.store {
            lo = (lo.0.max(origin.0 - x), lo.1.max(origin.1 - y));
            hi = (
                hi.0.min(origin.0 + size.0 as isize - b_i - 1 - x),
                hi.1.min(origin.1 + size.1 as isize - b_i - 1 - y),
            );
        }
        if lo.0 > hi.0 || lo.1 > hi.1 {
            return None;
        }
        let (x0, y0) = (x + lo.0, y + lo.1);
        let phases = [(0, 0), (2, 0), (0, 2), (2, 2)].map(|phase| self.phase_at(reference, phase, x0, y0));
        Some(PhaseWindow {
            phases,
            lo,
            hi,
            b,
            dsp: self.dsp,
        })
    }
}

impl<'a> PhaseWindow<'a> {
    /// Whether the phases hold the block displaced by quarter-pel `mv`.
    #[inline]
    pub(crate) fn holds(&self, mv: Mv) -> bool {
        let (dx, dy) = ((mv.x >> 2) as isize, (mv.y >> 2) as isize);
        (self.lo.0..=self.hi.0).contains(&dx) && (self.lo.1..=self.hi.1).contains(&dy)
    }

    /// The block displaced by quarter-pel `mv`, which the phases hold
    /// ([`PhaseWindow::holds`]), as [`block_or_predicted`] gives it: in
    /// place on the half-pel grid, else averaged into `scratch` (`b * b`
    /// samples).
    #[inline]
    pub(crate) fn block<'s>(&'s self, mv: Mv, scratch: &'s mut [u8]) -> (&'s [u8], usize) {
        debug_assert!(self.holds(mv));
        let (dx, dy) = ((mv.x >> 2) as isize, (mv.y >> 2) as isize);
        let (rx, ry) = ((dx - self.lo.0) as usize, (dy - self.lo.1) as usize);
        // A point of the half-pel grid in quarter pels (0, 2 or 4 each way)
        // from the displaced block: its phase's samples.
        let point = |px: i32, py: i32| {
            let (samples, stride) = self.phases[((px & 2) >> 1 | (py & 2)) as usize];
            let at = (ry + (py >> 2) as usize) * stride + rx + (px >> 2) as usize;
            (&samples[at..], stride)
        };
        let (fx, fy) = (mv.x & 3, mv.y & 3);
        let (from, to) = match (fx & 1, fy & 1) {
            (0, 0) => return point(fx, fy),
            (1, 0) => (point(fx - 1, fy), point(fx + 1, fy)),
            (0, 1) => (point(fx, fy - 1), point(fx, fy + 1)),
            _ => (point(2, 4 * (fy / 2)), point(4 * (fx / 2), 2)),
        };
        match self.b {
            16 => (self.dsp.average_16x16)(from, to, scratch),
            8 => (self.dsp.average_8x8)(from, to, scratch),
            b => average_rows(b, from, to, scratch),
        }
        (scratch, self.b)
    }
}

/// The `b x b` block of `reference` at (x, y) displaced by the
/// quarter-pel vector `mv`, and its stride: where it lies on the half-pel
/// grid, in place ([`HalfPel::block_in_place`]); else predicted into
/// `scratch` (`b * b` samples), on `halfpel`'s planes where they reach
/// ([`HalfPel::predict`]) or else by the codec's filter.
pub fn block_or_predicted<'a>(
    halfpel: Option<&'a HalfPel>,
    reference: &'a Plane,
    (x, y): (isize, isize),
    mv: Mv,
    b: usize,
    scratch: &'a mut [u8],
) -> (&'a [u8], usize) {
    if let Some(found) = halfpel.and_then(|h| h.block_in_place(reference, (x, y), (mv.x, mv.y), b)) {
        return found;
    }
    if !halfpel.is_some_and(|h| h.predict(reference, x, y, mv.x, mv.y, b, scratch)) {
        // The planes' filter: the search ranks with the sharp one whatever
        // the frame predicts with.
        predict_luma(LumaFilter::Sharp, reference, x, y, mv.x, mv.y, b, b, scratch, b);
    }
    (scratch, b)
}

thread_local! {
    /// Each thread's patch, filled again for every block it searches (a
    /// patch made per block was cleared first and copied out after).
    static PATCH: RefCell<Option<HalfPel>> = const { RefCell::new(None) };
}

/// Runs `f` with the half-pel phases that the sub-pel steps of the `b x b`
/// block at full-pel position `at` read, up to a pel from it each way (the
/// half- and quarter-pel steps' reach, three quarter-pels, and the quarter
/// average's further neighbour): the samples [`HalfPel::new`]'s planes
/// would hold there, for the same `margin`, for a search that visits too
/// few blocks for whole planes to pay. `f` gets `None` where planes would
/// be `None`, and for blocks larger than [`PATCH_BLOCK_MAX`]. `f` must
/// not call this function again (the patch is the thread's one).
pub(crate) fn with_patch<R>(
    reference: &Plane,
    margin: usize,
    at: (isize, isize),
    b: usize,
    f: impl FnOnce(Option<&HalfPel>) -> R,
) -> R {
    if margin + FILTER_REACH > reference.pad() || b > PATCH_BLOCK_MAX {
        return f(None);
    }
    PATCH.with(|cell| {
        let mut slot = cell.borrow_mut();
        let patch = slot.get_or_insert_with(|| HalfPel {
            store: Store::Patch {
                samples: Box::new([0; 3 * PATCH_STRIDE_MAX * PATCH_SIDE_MAX]),
                origin: (0, 0),
                size: (0, 0),
            },
            margin: 0,
            dsp: pixel(),
        });
        patch.margin = margin as isize;
        patch.fill_patch(reference, at, b);
        f(Some(patch))
    })
}

impl Drop for HalfPel {
    fn drop(&mut self) {
        if let Store::Planes(planes) = &mut self.store {
            crate::spare_planes::give_back(planes.drain(..));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn textured(w: usize, h: usize) -> Plane {
        Plane::from_fn(w, h, |x, y| {
            let (x, y) = (x as f64, y as f64);
            (128.0 + 60.0 * (x * 0.31).sin() * (y * 0.23).cos() + 30.0 * ((x + 2.0 * y) * 0.11).sin()) as u8
        })
        .unwrap()
    }

    #[test]
    fn planes_filled_a_band_at_a_time_are_the_whole_ones() {
        for (w, h, margin) in [(64, 48, 32), (37, 21, 16), (40, 24, 2)] {
            let r = textured(w, h);
            let whole = HalfPel::new(&r, margin).unwrap();
            let mut banded = HalfPel::unfilled(&r, margin).unwrap();
            let end = h + 2 * margin;
            for rows in [
                0..3,
                3..margin + 1,
                margin + 1..margin + 9,
                margin + 9..end - 2,
                end - 2..end,
            ] {
                banded.fill_rows(&r, rows);
            }
            for (mvx, mvy) in [(2, 0), (0, 2), (2, 2)] {
                let m = margin as isize;
                for y in -m..h as isize + m {
                    for x in -m..w as isize + m {
                        assert_eq!(
                            whole.phase_at(&r, (mvx, mvy), x, y).0[0],
                            banded.phase_at(&r, (mvx, mvy), x, y).0[0],
                            "{w}x{h} margin {margin}: phase ({mvx}, {mvy}) at ({x}, {y})"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn half_pel_phases_equal_the_codec_and_quarter_pel_is_close() {
        let r = textured(64, 48);
        let hp = HalfPel::new(&r, 32).unwrap();
        let (mut a, mut b) = ([0u8; 256], [0u8; 256]);
        for mvy in -9..=9 {
            for mvx in -9..=9 {
                for (x, y) in [(0, 0), (16, 16), (48, 32)] {
                    assert!(hp.predict(&r, x, y, mvx, mvy, 16, &mut a));
                    predict_luma(LumaFilter::Sharp, &r, x, y, mvx, mvy, 16, 16, &mut b, 16);
                    let in_place = hp.block_in_place(&r, (x, y), (mvx, mvy), 16);
                    if mvx % 2 == 0 && mvy % 2 == 0 {
                        assert_eq!(a, b, "half-pel ({mvx}, {mvy}) at ({x}, {y})");
                        // The same samples where they lie.
                        let (samples, stride) = in_place.expect("a half-pel block in place");
                        for row in 0..16 {
                            assert_eq!(samples[row * stride..][..16], a[row * 16..][..16]);
                        }
                    } else {
                        assert!(in_place.is_none());
                        // The average of neighbours against the 8-tap
                        // filter: close on a smooth texture.
                        let worst = a.iter().zip(&b).map(|(&u, &v)| u.abs_diff(v)).max().unwrap();
                        assert!(worst <= 3, "quarter-pel ({mvx}, {mvy}): {worst}");
                    }
                }
            }
        }
        // Every sample of the three planes, on a picture of odd size.
        let r = textured(37, 21);
        let hp = HalfPel::new(&r, 16).unwrap();
        let mut one = [0u8; 1];
        for (p, (mvx, mvy)) in [(2, 0), (0, 2), (2, 2)].into_iter().enumerate() {
            for y in -16..21 + 16 {
                for x in -16..37 + 16 {
                    predict_luma(LumaFilter::Sharp, &r, x, y, mvx, mvy, 1, 1, &mut one, 1);
                    assert_eq!(
                        hp.phase_at(&r, [(2, 0), (0, 2), (2, 2)][p], x, y).0[0],
                        one[0],
                        "phase {p} at ({x}, {y})"
                    );
                }
            }
        }
        let r = textured(64, 48);
        let hp = HalfPel::new(&r, 32).unwrap();
        // Beyond the margin: refused, so that the caller uses the codec.
        assert!(!hp.predict(&r, 0, 0, -4 * 40, 0, 16, &mut a));
        assert!(hp.block_in_place(&r, (0, 0), (-4 * 40, 0), 16).is_none());
    }

    /// Full-pel centres of patches for a block at (16, 16) of a 64x48
    /// picture with a margin of 24: inside, at the edges, out in the
    /// margin (where the patch is cut, or empty).
    const PATCH_CENTRES: [(isize, isize); 8] = [
        (16, 16),
        (0, 0),
        (48, 32),
        (-20, 5),
        (-28, -30),
        (60, 40),
        (70, 50),
        (45, -25),
    ];

    #[test]
    fn a_patch_gives_every_sub_pel_step_what_the_planes_give() {
        // Blocks inside, at the edges and out in the margin (where the
        // patch is cut, or empty), every step from a pel before the
        // full-pel centre to three quarter-pels after it, as the
        // refinement takes them (`search::PATCH_REACH`).
        let r = textured(64, 48);
        let margin = 24;
        let planes = HalfPel::new(&r, margin).unwrap();
        let (mut a, mut b) = ([0u8; 256], [0u8; 256]);
        // The block at (ox, oy), its full-pel best at (x, y).
        let (ox, oy) = (16isize, 16isize);
        for (x, y) in PATCH_CENTRES {
            with_patch(&r, margin, (x, y), 16, |patch| {
                let patch = patch.expect("a patch for a 16x16 block");
                for mvy in -4..=3 {
                    for mvx in -4..=3 {
                        let mv = (4 * (x - ox) as i32 + mvx, 4 * (y - oy) as i32 + mvy);
                        let from_planes = planes.predict(&r, ox, oy, mv.0, mv.1, 16, &mut a);
                        let from_patch = patch.predict(&r, ox, oy, mv.0, mv.1, 16, &mut b);
                        assert_eq!(from_planes, from_patch, "reach of ({mvx}, {mvy}) at ({x}, {y})");
                        if from_planes {
                            assert_eq!(a, b, "step ({mvx}, {mvy}) at ({x}, {y})");
                        }
                        let in_place = |h: &HalfPel| {
                            h.block_in_place(&r, (ox, oy), mv, 16).map(|(s, stride)| {
                                (0..16)
                                    .flat_map(|row| s[row * stride..][..16].to_vec())
                                    .collect::<Vec<_>>()
                            })
                        };
                        assert_eq!(
                            in_place(&planes),
                            in_place(patch),
                            "in place ({mvx}, {mvy}) at ({x}, {y})"
                        );
                    }
                }
            });
        }
        // Larger blocks keep whole planes.
        with_patch(&r, margin, (0, 0), 32, |patch| assert!(patch.is_none()));
    }

    /// The rows of a `b x b` block given as samples and stride.
    fn rows_of((samples, stride): (&[u8], usize), b: usize) -> Vec<u8> {
        (0..b)
            .flat_map(|row| samples[row * stride..][..b].to_vec())
            .collect()
    }

    /// Checks `h`'s window of the `b x b` block at `at` against
    /// [`block_or_predicted`] for every vector in `range` (quarter pels
    /// each way, every `step`th): held exactly where the phases reach
    /// (else the codec's filter is the answer), the same samples there.
    fn check_window(h: &HalfPel, r: &Plane, at: (isize, isize), b: usize, range: i32, step: usize) {
        let window = h.window(r, at, b);
        let (mut a, mut by_phases) = ([0u8; 256], [0u8; 256]);
        for mvy in (-range..=range).step_by(step) {
            for mvx in (-range..=range).step_by(step) {
                let mv = Mv::new(mvx, mvy);
                let reaches = h.block_in_place(r, at, (mvx, mvy), b).is_some()
                    || h.predict(r, at.0, at.1, mvx, mvy, b, &mut by_phases);
                let held = window.as_ref().is_some_and(|w| w.holds(mv));
                assert_eq!(held, reaches, "{b}x{b} at {at:?}, ({mvx}, {mvy})");
                if let Some(w) = window.as_ref().filter(|_| held) {
                    let mut scratch = [0u8; 256];
                    let expected = rows_of(block_or_predicted(Some(h), r, at, mv, b, &mut a), b);
                    assert_eq!(
                        rows_of(w.block(mv, &mut scratch), b),
                        expected,
                        "{b}x{b} at {at:?}, ({mvx}, {mvy})"
                    );
                }
            }
        }
    }

    #[test]
    fn a_window_gives_what_the_phases_give() {
        // Whole planes: blocks of each size inside, at the edges and in
        // the margin, vectors out past the margin each way.
        let r = textured(64, 48);
        let margin = 24;
        let planes = HalfPel::new(&r, margin).unwrap();
        for b in [16, 8, 4] {
            for at in [
                (16, 16),
                (0, 0),
                (48, 32),
                (60, 44),
                (-20, 5),
                (-24, -24),
                (70, 50),
            ] {
                check_window(&planes, &r, at, b, 4 * 36, 3);
            }
        }
        // Patches: the steps near their full-pel centre, as in
        // `a_patch_gives_every_sub_pel_step_what_the_planes_give`.
        let (ox, oy) = (16isize, 16isize);
        for (x, y) in PATCH_CENTRES {
            with_patch(&r, margin, (x, y), 16, |patch| {
                let patch = patch.expect("a patch for a 16x16 block");
                let window = patch.window(&r, (ox, oy), 16);
                // Rows are filtered 32 wide where the border holds them:
                // steps to 15 pels right of the centre may be held.
                for mvy in -8..=7 {
                    for mvx in -8..=4 * 16 {
                        let mv = Mv::new(4 * (x - ox) as i32 + mvx, 4 * (y - oy) as i32 + mvy);
                        let held = window.as_ref().is_some_and(|w| w.holds(mv));
                        // Within the patch's reach (a pel before its centre
                        // to three quarters after) held exactly where the
                        // planes reach; wherever held (rows are filtered
                        // wider than that), the planes' samples.
                        let near = (-4..=3).contains(&mvx) && (-4..=3).contains(&mvy);
                        let in_planes = planes.block_in_place(&r, (ox, oy), (mv.x, mv.y), 16).is_some()
                            || planes.predict(&r, ox, oy, mv.x, mv.y, 16, &mut [0u8; 256]);
                        assert!(!near || held == in_planes, "patch at ({x}, {y}), ({mvx}, {mvy})");
                        if let Some(w) = window.as_ref().filter(|_| held) {
                            let (mut a, mut scratch) = ([0u8; 256], [0u8; 256]);
                            let expected = rows_of(
                                block_or_predicted(Some(&planes), &r, (ox, oy), mv, 16, &mut a),
                                16,
                            );
                            assert_eq!(rows_of(w.block(mv, &mut scratch), 16), expected, "({mvx}, {mvy})");
                        }
                    }
                }
            });
        }
    }

    #[test]
    fn averages_round_half_up() {
        // The scalar rounding: (u + v + 1) >> 1, at every level's kernels.
        for level in crate::codec::cpu::available() {
            let dsp = super::super::dsp::PIXEL.at(level);
            let mut y = [0u8; 256];
            (dsp.average_16x16)((&[255u8; 256], 16), (&[0u8; 256], 16), &mut y);
            assert!(y.iter().all(|&v| v == 128), "{level:?}");
            (dsp.average_8x8)((&[3u8; 64], 8), (&[0u8; 64], 8), &mut y[..64]);
            assert!(y[..64].iter().all(|&v| v == 2), "{level:?}");
        }
    }
}
