//! A frame's reconstruction published a band of macroblock rows at a time
//! as the rows become final, for the frame after it (x264's frame threads
//! broadcast a frame's finished rows the same way): the rows are copied
//! out, so that no frame is written by one thread while another reads it.

use std::sync::{Condvar, Mutex, MutexGuard, PoisonError};

use crate::codec::consts::MB;
use crate::codec::Frame;

/// The final rows of a frame being coded.
pub(super) struct FrameProgress {
    published: Mutex<Published>,
    more: Condvar,
}

struct Published {
    /// The reconstruction's final rows (coded size; the rest unspecified,
    /// borders not extended).
    frame: Frame,
    /// Macroblock rows final.
    rows: usize,
}

impl FrameProgress {
    /// Progress into `frame` (the coded size, its content any): no row
    /// final yet.
    pub(super) fn new(frame: Frame) -> FrameProgress {
        FrameProgress {
            published: Mutex::new(Published { frame, rows: 0 }),
            more: Condvar::new(),
        }
    }

    /// The published frame's buffer, to be used again.
    pub(super) fn into_frame(self) -> Frame {
        self.published
            .into_inner()
            .unwrap_or_else(PoisonError::into_inner)
            .frame
    }

    fn lock(&self) -> MutexGuard<'_, Published> {
        // A panic while copying leaves rows no one reads as final.
        self.published.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Publishes `from`'s macroblock rows to `upto` (final there; the
    /// frame's size), and wakes whoever waits for them.
    pub(super) fn publish(&self, from: &Frame, upto: usize) {
        let mut published = self.lock();
        let rows = published.rows..upto.min(from.height() / MB);
        if rows.is_empty() {
            return;
        }
        for p in 0..3 {
            let scale = if p == 0 { 1 } else { 2 };
            let (src, dst) = (from.plane(p), published.frame.plane_mut(p));
            for y in rows.start * MB / scale..rows.end * MB / scale {
                dst.row_mut(y).copy_from_slice(src.row(y));
            }
        }
        published.rows = rows.end;
        drop(published);
        self.more.notify_all();
    }

    /// `f` of the published frame once `rows` macroblock rows of it are
    /// final (all it has, if fewer), waiting until they are.
    pub(super) fn with_rows<R>(&self, rows: usize, f: impl FnOnce(&Frame) -> R) -> R {
        let mut published = self.lock();
        let rows = rows.min(published.frame.height() / MB);
        while published.rows < rows {
            published = self.more.wait(published).unwrap_or_else(PoisonError::into_inner);
        }
        f(&published.frame)
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
        let progress = FrameProgress::new(Frame::new(w, h).unwrap());
        std::thread::scope(|s| {
            let reader = s.spawn(|| {
                progress.with_rows(2, |f| {
                    // The two rows asked for are in, all three planes.
                    (0..3).all(|p| {
                        let rows = if p == 0 { 2 * MB } else { MB };
                        (0..rows).all(|y| f.plane(p).row(y) == recon.plane(p).row(y))
                    })
                })
            });
            for upto in 1..=3 {
                progress.publish(&recon, upto);
                std::thread::yield_now();
            }
            assert!(reader.join().unwrap(), "rows seen before they were published");
        });
        // More rows than the frame has: all of them, no wait.
        assert!(progress.with_rows(10, |f| *f == recon));
    }
}
