//! A P frame's first reference brought in a band of macroblock rows at a
//! time, as a frame thread has it while the frame before finishes its rows
//! (x264's frame threads wait on the reference's rows the same way): the
//! rows copied, their borders extended, weighted, their half-pel planes
//! filled. Each step gives the whole frame's samples once every row is in
//! (`Plane::extend_border_rows`, `Weights::apply_rows`,
//! `HalfPel::fill_rows`), so a frame decided from it, each row once the
//! rows it reads are in, is the frame decided from the whole reference.

use crate::codec::consts::MB;
use crate::codec::weight::Weights;
use crate::codec::Frame;
use crate::me::halfpel::HalfPel;

/// How far below a sample the half-pel filter reads (`HalfPel::fill_rows`).
const FILTER_BELOW: usize = 4;

/// The previous reconstruction as it arrives, weighted for the frame.
pub(super) struct GrowingReference {
    /// The rows as they came (borders extended).
    plain: Frame,
    /// The rows weighted, where the frame weighs its reference.
    weighted: Option<Frame>,
    weights: Weights,
    /// Macroblock rows copied in, and of those the rows usable (borders
    /// extended, weighted).
    copied: usize,
    rows: usize,
    /// Rows of the half-pel planes filled (from the margin's first).
    halfpel_rows: usize,
}

impl GrowingReference {
    /// A reference of `plain`'s size (coded, its content any) with no row
    /// in yet, not weighted.
    pub(super) fn new(plain: Frame) -> GrowingReference {
        GrowingReference {
            plain,
            weighted: None,
            weights: Weights::NONE,
            copied: 0,
            rows: 0,
            halfpel_rows: 0,
        }
    }

    /// Weighs the reference by `weights` into `weighted` (the plain one's
    /// layout, its content any): the rows in now, and those brought in
    /// after. Before any half-pel row is filled (they are the weighted
    /// luma's).
    pub(super) fn weigh(&mut self, weights: Weights, mut weighted: Frame) {
        assert_eq!(self.halfpel_rows, 0, "weights after half-pel rows");
        if self.rows > 0 {
            weights.apply_rows(&self.plain, &mut weighted, 0..self.rows * MB);
        }
        self.weights = weights;
        self.weighted = Some(weighted);
    }

    /// The rows as they came, unweighted: final to
    /// [`GrowingReference::frame`]'s rows.
    pub(super) fn plain(&self) -> &Frame {
        &self.plain
    }

    /// What the frame predicts from: final to [`GrowingReference::rows`].
    pub(super) fn frame(&self) -> &Frame {
        self.weighted.as_ref().unwrap_or(&self.plain)
    }

    /// The frame's buffers, to be used again.
    pub(super) fn into_frames(self) -> (Frame, Option<Frame>) {
        (self.plain, self.weighted)
    }

    /// Copies `from`'s macroblock rows to `upto` in (`from` is the
    /// reconstruction, coded size, final to there; its borders are not
    /// read): all that needs the frame before's published rows, so their
    /// lock is held no longer ([`GrowingReference::settle`] does the rest).
    pub(super) fn copy_in(&mut self, from: &Frame, upto: usize) {
        let upto = upto.min(self.plain.height() / MB);
        for p in 0..3 {
            let scale = if p == 0 { 1 } else { 2 };
            let (src, dst) = (from.plane(p), self.plain.plane_mut(p));
            for y in self.copied * MB / scale..upto.max(self.copied) * MB / scale {
                dst.row_mut(y).copy_from_slice(src.row(y));
            }
        }
        self.copied = self.copied.max(upto);
    }

    /// Makes the rows copied in usable: their borders extended, weighted,
    /// and `halfpel` (the weighted luma's planes) filled as far as they
    /// reach.
    pub(super) fn settle(&mut self, halfpel: Option<&mut HalfPel>) {
        if self.copied > self.rows {
            let luma = self.rows * MB..self.copied * MB;
            for p in 0..3 {
                let rows = if p == 0 {
                    luma.clone()
                } else {
                    luma.start / 2..luma.end / 2
                };
                self.plain.plane_mut(p).extend_border_rows(rows);
            }
            if let Some(weighted) = &mut self.weighted {
                self.weights.apply_rows(&self.plain, weighted, luma);
            }
            self.rows = self.copied;
        }
        let Some(halfpel) = halfpel else {
            return;
        };
        let all = self.plain.height() / MB;
        let margin = halfpel.margin();
        let luma_in = self.rows * MB;
        let end = if self.rows == all {
            self.plain.height() + 2 * margin
        } else {
            (luma_in + margin).saturating_sub(FILTER_BELOW + 1)
        };
        if end > self.halfpel_rows {
            let reference = self.weighted.as_ref().unwrap_or(&self.plain);
            halfpel.fill_rows(reference.y(), self.halfpel_rows..end);
            self.halfpel_rows = end;
        }
    }
}
