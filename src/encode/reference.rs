//! A P frame's first reference brought in a band of macroblock rows at a
//! time, as a frame thread has it while the frame before finishes its rows
//! (x264's frame threads wait on the reference's rows the same way): the
//! rows copied, their borders extended, weighted, their half-pel planes
//! filled. Each step gives the whole frame's samples once every row is in
//! (`Plane::extend_border_rows`, `Weights::apply_rows`,
//! `HalfPel::fill_rows`), so a frame decided from it, each row once the
//! rows it reads are in, is the frame decided from the whole reference.
//! Where the frame before was finished when the frame started (one
//! thread), its reconstruction is the reference as it is: nothing copied.

use std::sync::Arc;

use crate::codec::consts::MB;
use crate::codec::weight::Weights;
use crate::codec::Frame;
use crate::me::halfpel::HalfPel;

/// How far below a sample the half-pel filter reads (`HalfPel::fill_rows`).
const FILTER_BELOW: usize = 4;

/// The previous reconstruction's samples: rows copied into a buffer as
/// they come, or the finished reconstruction itself.
enum Plain {
    Copied(Frame),
    Finished(Arc<Frame>),
}

/// The previous reconstruction as it arrives, weighted for the frame.
pub(super) struct GrowingReference {
    /// The rows as they came (borders extended).
    plain: Plain,
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
            plain: Plain::Copied(plain),
            weighted: None,
            weights: Weights::NONE,
            copied: 0,
            rows: 0,
            halfpel_rows: 0,
        }
    }

    /// A reference that is the finished reconstruction `frame` (borders
    /// extended), every row in.
    pub(super) fn finished(frame: Arc<Frame>) -> GrowingReference {
        let rows = frame.height() / MB;
        GrowingReference {
            plain: Plain::Finished(frame),
            weighted: None,
            weights: Weights::NONE,
            copied: rows,
            rows,
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
            weights.apply_rows(self.plain(), &mut weighted, 0..self.rows * MB);
        }
        self.weights = weights;
        self.weighted = Some(weighted);
    }

    /// [`GrowingReference::weigh`] after rows were settled unweighted
    /// (rows decided before the weights were measured): the half-pel
    /// planes to fill, the weighted luma's, are new ones, filled from the
    /// top.
    pub(super) fn reweigh(&mut self, weights: Weights, weighted: Frame) {
        self.halfpel_rows = 0;
        self.weigh(weights, weighted);
    }

    /// The rows as they came, unweighted: final to
    /// [`GrowingReference::frame`]'s rows.
    pub(super) fn plain(&self) -> &Frame {
        match &self.plain {
            Plain::Copied(f) => f,
            Plain::Finished(f) => f,
        }
    }

    /// What the frame predicts from: final to [`GrowingReference::rows`].
    pub(super) fn frame(&self) -> &Frame {
        self.weighted.as_ref().unwrap_or(self.plain())
    }

    /// The frame's buffers, to be used again (the rows' where they were
    /// copied).
    pub(super) fn into_frames(self) -> (Option<Frame>, Option<Frame>) {
        let plain = match self.plain {
            Plain::Copied(f) => Some(f),
            Plain::Finished(_) => None,
        };
        (plain, self.weighted)
    }

    /// Copies `from`'s macroblock rows to `upto` in (`from` is the
    /// reconstruction's published samples, coded size, final to there;
    /// its borders are not read; nothing to copy into a finished one): all that needs the frame before's published rows, so their
    /// lock is held no longer ([`GrowingReference::settle`] does the rest).
    pub(super) fn copy_in(&mut self, from: Option<&Frame>, upto: usize) {
        let Plain::Copied(plain) = &mut self.plain else {
            return;
        };
        // A frame that publishes no samples is finished before the frame
        // after it starts, which then has it whole (`finished`).
        debug_assert!(from.is_some(), "rows to copy from");
        let Some(from) = from else {
            return;
        };
        let upto = upto.min(plain.height() / MB);
        for p in 0..3 {
            let scale = if p == 0 { 1 } else { 2 };
            let (src, dst) = (from.plane(p), plain.plane_mut(p));
            for y in self.copied * MB / scale..upto.max(self.copied) * MB / scale {
                dst.row_mut(y).copy_from_slice(src.row(y));
            }
        }
        self.copied = self.copied.max(upto);
    }

    /// Makes the rows copied in usable: their borders extended, weighted,
    /// and `halfpel` (the weighted luma's planes) filled as far as the
    /// first `reach` macroblock rows need (a finished reference's too, a
    /// band at a time: filled whole before the first row, they held back
    /// the frame's first published rows, which the frame after it waits
    /// for).
    pub(super) fn settle(&mut self, halfpel: Option<&mut HalfPel>, reach: usize) {
        if let (Plain::Copied(plain), true) = (&mut self.plain, self.copied > self.rows) {
            let luma = self.rows * MB..self.copied * MB;
            for p in 0..3 {
                let rows = if p == 0 {
                    luma.clone()
                } else {
                    luma.start / 2..luma.end / 2
                };
                plain.plane_mut(p).extend_border_rows(rows);
            }
            if let Some(weighted) = &mut self.weighted {
                self.weights.apply_rows(plain, weighted, luma);
            }
            self.rows = self.copied;
        }
        let Some(halfpel) = halfpel else {
            return;
        };
        let all = self.plain().height() / MB;
        let margin = halfpel.margin();
        let usable = self.rows.min(reach);
        let luma_in = usable * MB;
        let end = if usable == all {
            self.plain().height() + 2 * margin
        } else {
            (luma_in + margin).saturating_sub(FILTER_BELOW + 1)
        };
        if end > self.halfpel_rows {
            halfpel.fill_rows(self.frame().y(), self.halfpel_rows..end);
            self.halfpel_rows = end;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::weight::PlaneWeight;

    /// A reconstruction with texture in every plane, borders extended.
    fn reconstruction(w: usize, h: usize) -> Frame {
        let mut f = Frame::new(w, h).unwrap();
        for p in 0..3 {
            let plane = f.plane_mut(p);
            for y in 0..plane.height() {
                for x in 0..plane.width() {
                    plane.set(x, y, ((x * 37 + y * 101 + p * 59) % 253) as u8);
                }
            }
        }
        f.extend_borders();
        f
    }

    /// Every sample of the frame's planes, borders included.
    fn samples(f: &Frame) -> Vec<Vec<u8>> {
        (0..3).map(|p| f.plane(p).data().to_vec()).collect()
    }

    #[test]
    fn a_finished_reference_is_the_one_brought_in_a_band_at_a_time() {
        let (w, h, margin) = (64, 48, 16);
        let recon = reconstruction(w, h);
        let weights = Weights([
            Some(PlaneWeight {
                scale: 80,
                offset: -7,
            }),
            None,
            Some(PlaneWeight {
                scale: 50,
                offset: 12,
            }),
        ]);
        // Brought in as a frame thread brings it: the top row, the weights,
        // then a row at a time with the half-pel planes behind.
        let mut banded = GrowingReference::new(Frame::new(w, h).unwrap());
        let mut banded_hp = HalfPel::unfilled(recon.y(), margin).unwrap();
        banded.copy_in(Some(&recon), 1);
        banded.settle(None, 1);
        banded.weigh(weights, Frame::new(w, h).unwrap());
        for upto in 2..=h / MB {
            banded.copy_in(Some(&recon), upto);
            banded.settle(Some(&mut banded_hp), upto);
        }
        // The finished reconstruction as it is, its half-pel planes filled
        // as the rows reach further.
        let mut whole = GrowingReference::finished(Arc::new(recon.clone()));
        let mut whole_hp = HalfPel::unfilled(recon.y(), margin).unwrap();
        whole.weigh(weights, Frame::new(w, h).unwrap());
        for reach in 1..=h / MB {
            whole.settle(Some(&mut whole_hp), reach);
        }
        assert_eq!(samples(whole.plain()), samples(&recon));
        assert_eq!(samples(banded.plain()), samples(&recon), "borders extended alike");
        assert_eq!(samples(whole.frame()), samples(banded.frame()), "weighted alike");
        assert_ne!(samples(whole.frame()), samples(&recon), "weights applied");
        let m = margin as isize;
        for phase in [(2, 0), (0, 2), (2, 2)] {
            for y in -m..h as isize + m {
                for x in -m..w as isize + m {
                    assert_eq!(
                        whole_hp.phase_at(whole.frame().y(), phase, x, y).0[0],
                        banded_hp.phase_at(banded.frame().y(), phase, x, y).0[0],
                        "phase {phase:?} at ({x}, {y})"
                    );
                }
            }
        }
        // Only the copied reference has a buffer to give back.
        assert!(whole.into_frames().0.is_none());
        assert!(banded.into_frames().0.is_some());
    }
}
