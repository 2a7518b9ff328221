//! A frame's reconstruction published a band of macroblock rows at a time
//! as the rows become final, for the frame after it (x264's frame threads
//! broadcast a frame's finished rows the same way): the rows are copied
//! out, so that no frame is written by one thread while another reads it.
//! The rows' decided vectors go with them: the next frame's co-located
//! search candidates. A frame finished before the frame after it starts
//! (one thread, or a frame coded whole) publishes its vectors alone: the
//! frame after reads its finished reconstruction, and nothing is copied.

use std::sync::{Condvar, Mutex, MutexGuard, PoisonError};

use crate::codec::consts::MB;
use crate::codec::mv::Mv;
use crate::codec::partition::MbVectors;
use crate::codec::Frame;

/// The final rows of a frame being coded.
pub(super) struct FrameProgress {
    published: Mutex<Published>,
    more: Condvar,
    /// The frame's macroblock rows.
    mb_rows: usize,
}

struct Published {
    /// The reconstruction's final rows (coded size; the rest unspecified,
    /// borders not extended), where the frame publishes its samples.
    samples: Option<Frame>,
    /// Macroblock rows final.
    rows: usize,
    /// The co-located candidates of the frame after, a vector per
    /// macroblock (raster order), final to `rows`: a P frame's decided
    /// vectors into its first reference (zero where none), an I frame's
    /// those it was given; none before the first P frame.
    prior: Option<Vec<Mv>>,
    /// Readers waiting for rows: the condition is signalled only where
    /// one is (a signal is a system call whether anyone waits or not, and
    /// rows are published a macroblock row at a time).
    waiting: usize,
}

impl FrameProgress {
    /// Progress of a frame of `(width, height)` (coded size), its rows
    /// copied into `samples` (that size, its content any) where the frame
    /// after may start before it is finished: no row final yet; with
    /// co-located candidates where `prior`.
    pub(super) fn new((width, height): (usize, usize), samples: Option<Frame>, prior: bool) -> FrameProgress {
        let mbs = (width / MB) * (height / MB);
        let prior = prior.then(|| vec![Mv::ZERO; mbs]);
        FrameProgress {
            published: Mutex::new(Published {
                samples,
                rows: 0,
                prior,
                waiting: 0,
            }),
            more: Condvar::new(),
            mb_rows: height / MB,
        }
    }

    /// Whether the frame publishes co-located candidates.
    pub(super) fn has_prior(&self) -> bool {
        self.lock().prior.is_some()
    }

    /// The buffer the samples were published into, to be used again.
    pub(super) fn into_samples(self) -> Option<Frame> {
        self.published
            .into_inner()
            .unwrap_or_else(PoisonError::into_inner)
            .samples
    }

    fn lock(&self) -> MutexGuard<'_, Published> {
        // A panic while copying leaves rows no one reads as final.
        self.published.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Publishes `from`'s macroblock rows to `upto` (final there; the
    /// frame's size) with their `vectors` (raster order, at least to
    /// `upto`), and wakes whoever waits for them.
    pub(super) fn publish(&self, from: &Frame, vectors: &[MbVectors], upto: usize) {
        let mut published = self.lock();
        let rows = published.rows..upto.min(self.mb_rows);
        if rows.is_empty() {
            return;
        }
        let cols = from.width() / MB;
        if let Some(prior) = &mut published.prior {
            let mbs = rows.start * cols..rows.end * cols;
            for (p, v) in prior[mbs.clone()].iter_mut().zip(&vectors[mbs]) {
                *p = super::motion::colocated(v);
            }
        }
        Self::copy_rows(&mut published, from, rows);
        self.wake(published);
    }

    /// Publishes the whole of `from` (final) with the co-located
    /// candidates `prior` (one per macroblock, where the frame has them).
    pub(super) fn publish_whole(&self, from: &Frame, prior: Option<&[Mv]>) {
        let mut published = self.lock();
        if let (Some(to), Some(from)) = (&mut published.prior, prior) {
            to.copy_from_slice(from);
        }
        let rows = published.rows..self.mb_rows;
        Self::copy_rows(&mut published, from, rows);
        self.wake(published);
    }

    /// Gives up: every row counts as published, whatever it holds, so that
    /// no one waits for a frame that failed (its error is reported in its
    /// place).
    pub(super) fn abandon(&self) {
        let mut published = self.lock();
        published.rows = self.mb_rows;
        self.wake(published);
    }

    /// Releases the lock and wakes the readers waiting, if any.
    fn wake(&self, published: MutexGuard<'_, Published>) {
        let waiting = published.waiting > 0;
        drop(published);
        if waiting {
            self.more.notify_all();
        }
    }

    fn copy_rows(published: &mut Published, from: &Frame, rows: std::ops::Range<usize>) {
        if rows.is_empty() {
            return;
        }
        if let Some(samples) = &mut published.samples {
            for p in 0..3 {
                let scale = if p == 0 { 1 } else { 2 };
                let (src, dst) = (from.plane(p), samples.plane_mut(p));
                for y in rows.start * MB / scale..rows.end * MB / scale {
                    dst.row_mut(y).copy_from_slice(src.row(y));
                }
            }
        }
        published.rows = rows.end;
    }

    /// How many macroblock rows are published now.
    pub(super) fn rows(&self) -> usize {
        self.lock().rows
    }

    /// `f` of the published samples (where the frame publishes them) and
    /// co-located candidates once `rows` macroblock rows of them are final
    /// (all it has, if fewer), waiting until they are.
    pub(super) fn with_rows<R>(&self, rows: usize, f: impl FnOnce(Option<&Frame>, Option<&[Mv]>) -> R) -> R {
        let mut published = self.lock();
        let rows = rows.min(self.mb_rows);
        while published.rows < rows {
            published.waiting += 1;
            published = self.more.wait(published).unwrap_or_else(PoisonError::into_inner);
            published.waiting -= 1;
        }
        f(published.samples.as_ref(), published.prior.as_deref())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_reader_waits_for_the_rows_it_asks_and_sees_them_as_published() {
        let (w, h) = (32, 48);
        let mut recon = Frame::new(w, h).unwrap();
        for p in 0..3 {
            let plane = recon.plane_mut(p);
            for y in 0..plane.height() {
                for x in 0..plane.width() {
                    plane.set(x, y, (x + 3 * y + 50 * p) as u8);
                }
            }
        }
        let cols = w / MB;
        // Macroblock i's vector (i, -i) into reference 0, but the 5th's
        // into reference 1 and the 6th intra: zero candidates.
        let vectors: Vec<MbVectors> = (0..cols * h / MB)
            .map(|i| match i {
                5 => {
                    [Some(crate::codec::partition::RefMv {
                        mv: Mv::new(9, 9),
                        ref_idx: 1,
                    }); 4]
                }
                6 => [None; 4],
                _ => {
                    [Some(crate::codec::partition::RefMv::previous(Mv::new(
                        i as i32,
                        -(i as i32),
                    ))); 4]
                }
            })
            .collect();
        let progress = FrameProgress::new((w, h), Some(Frame::new(w, h).unwrap()), true);
        std::thread::scope(|s| {
            let reader = s.spawn(|| {
                progress.with_rows(2, |f, prior| {
                    let f = f.expect("samples published");
                    // The two rows asked for are in, all three planes, and
                    // their vectors.
                    let prior = prior.expect("a P frame's candidates");
                    let samples = (0..3).all(|p| {
                        let rows = if p == 0 { 2 * MB } else { MB };
                        (0..rows).all(|y| f.plane(p).row(y) == recon.plane(p).row(y))
                    });
                    let candidates = (0..2 * cols).all(|i| {
                        let want = if i == 5 || i == 6 { 0 } else { i as i32 };
                        prior[i] == Mv::new(want, -want)
                    });
                    samples && candidates
                })
            });
            for upto in 1..=3 {
                progress.publish(&recon, &vectors, upto);
                std::thread::yield_now();
            }
            assert!(reader.join().unwrap(), "rows seen before they were published");
        });
        // More rows than the frame has: all of them, no wait.
        assert!(progress.with_rows(10, |f, _| f == Some(&recon)));
    }

    #[test]
    fn a_reader_already_waiting_is_woken_by_the_rows_and_by_an_abandon() {
        // The rows published only once the reader waits: the signal sent
        // where one waits must reach it (a lost one leaves it waiting).
        let (w, h) = (32, 48);
        let recon = Frame::new(w, h).unwrap();
        let progress = FrameProgress::new((w, h), Some(Frame::new(w, h).unwrap()), false);
        let wait_for_reader = || {
            while progress.lock().waiting == 0 {
                std::thread::yield_now();
            }
        };
        std::thread::scope(|s| {
            let reader = s.spawn(|| progress.with_rows(2, |f, _| f.is_some()));
            wait_for_reader();
            progress.publish(&recon, &[], 2);
            assert!(reader.join().unwrap());
            assert_eq!(progress.rows(), 2);
            let reader = s.spawn(|| progress.with_rows(3, |_, _| ()));
            wait_for_reader();
            progress.abandon();
            reader.join().unwrap();
        });
        assert_eq!(progress.lock().waiting, 0, "no reader left counted");
    }

    #[test]
    fn an_abandoned_frame_keeps_no_one_waiting() {
        let progress = FrameProgress::new((32, 48), Some(Frame::new(32, 48).unwrap()), false);
        std::thread::scope(|s| {
            let reader = s.spawn(|| progress.with_rows(3, |_, prior| prior.is_none()));
            progress.abandon();
            assert!(reader.join().unwrap());
        });
    }

    #[test]
    fn a_frame_without_samples_publishes_its_rows_and_vectors() {
        let (w, h) = (32, 48);
        let recon = Frame::new(w, h).unwrap();
        let vectors =
            vec![[Some(crate::codec::partition::RefMv::previous(Mv::new(3, -1))); 4]; (w / MB) * (h / MB)];
        let progress = FrameProgress::new((w, h), None, true);
        std::thread::scope(|s| {
            let reader = s.spawn(|| {
                progress.with_rows(3, |f, prior| {
                    f.is_none() && prior.is_some_and(|p| p.iter().all(|&v| v == Mv::new(3, -1)))
                })
            });
            progress.publish(&recon, &vectors, 3);
            assert!(reader.join().unwrap(), "vectors of every row, no samples");
        });
        assert!(progress.into_samples().is_none());
    }
}
