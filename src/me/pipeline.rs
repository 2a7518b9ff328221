//! Blocks whose search reads their neighbours' final vectors (the left,
//! top and top-right blocks: EPZS's candidates, the rate term's predicted
//! vector), searched row by row on several threads at once, each row
//! following the one above two blocks behind, as x264's threads follow
//! the row above. The vectors are those of searching in raster order on
//! one thread, for any number of threads.

use std::sync::atomic::{AtomicU32, AtomicU64, AtomicUsize, Ordering};

use super::Candidate;
use crate::codec::mv::Mv;
use crate::codec::mvpred::predict_in_grid;

/// The vectors found so far, readable while other rows are being written.
pub(crate) struct SharedGrid {
    cols: usize,
    /// A vector's x and y, as two u32 halves.
    cells: Vec<AtomicU64>,
}

impl SharedGrid {
    /// Zero vectors.
    pub fn new(cols: usize, rows: usize) -> SharedGrid {
        SharedGrid {
            cols,
            cells: (0..cols * rows).map(|_| AtomicU64::new(0)).collect(),
        }
    }

    /// Columns.
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// The vector of block (col, row): final where the pipeline let the
    /// reader see it, zero before.
    pub fn vector(&self, col: usize, row: usize) -> Mv {
        let v = self.cells[row * self.cols + col].load(Ordering::Relaxed);
        Mv::new(v as u32 as i32, (v >> 32) as u32 as i32)
    }

    /// The codec's predicted vector of block (col, row).
    pub fn predictor(&self, col: usize, row: usize) -> Mv {
        predict_in_grid(self.cols, col, row, |c, r| Some(self.vector(c, r)))
    }

    /// Publishes the vector of block (col, row).
    pub fn set(&self, col: usize, row: usize, mv: Mv) {
        let v = u64::from(mv.x as u32) | (u64::from(mv.y as u32) << 32);
        self.cells[row * self.cols + col].store(v, Ordering::Relaxed);
    }
}

/// A row's count of blocks done, on a cache line of its own (the row
/// below polls it while the row's worker writes it).
#[derive(Default)]
#[repr(align(64))]
struct Progress(AtomicUsize);

/// A row's progress once a block at or above it panicked.
const ABANDONED: usize = usize::MAX;

/// Marks a row abandoned if its block panics: the worker of the row below,
/// which waits for it, leaves its own row abandoned and stops instead of
/// waiting forever, and the scope passes the panic on.
struct RowLeftOnPanic<'a>(&'a Progress);

impl Drop for RowLeftOnPanic<'_> {
    fn drop(&mut self) {
        self.0 .0.store(ABANDONED, Ordering::Release);
    }
}

/// Runs `block(state, col, row)` for every block of a `cols x rows` grid
/// on the current rayon pool's threads, each row following the one above
/// two blocks behind (so that a block may read the results of its left,
/// top-left, top and top-right neighbours, and nothing else of the rows
/// being worked on); a row starts once the row above has done `start`
/// blocks (at least 2). Each worker makes its `state` once with `new_state`.
/// What a block computes must depend only on those neighbours (and on
/// what `block` publishes itself): then it is the same for any number of
/// threads. `block` must not wait on other rayon work (a worker spins
/// while the row above catches up). The states of the workers that took
/// rows are returned (one: it did every block).
pub(crate) fn wavefront<S: Send>(
    cols: usize,
    rows: usize,
    start: usize,
    new_state: &(dyn Fn() -> S + Sync),
    block: &(dyn Fn(&mut S, usize, usize) + Sync),
) -> Vec<S> {
    // Blocks done in each row; a row is claimed by one worker, in order.
    let done: Vec<Progress> = (0..rows).map(|_| Progress::default()).collect();
    let next_row = AtomicUsize::new(0);
    let states = std::sync::Mutex::new(Vec::new());
    let work = || {
        let mut state = None;
        loop {
            let r = next_row.fetch_add(1, Ordering::Relaxed);
            if r >= rows {
                break;
            }
            let state = state.get_or_insert_with(new_state);
            for c in 0..cols {
                if r > 0 {
                    // The row above must be past the top-right neighbour.
                    // The worker on it claimed it earlier and is running,
                    // so it gets there.
                    let need = if c == 0 { start.max(2) } else { c + 2 }.min(cols);
                    let mut spins = 0u32;
                    loop {
                        let above = done[r - 1].0.load(Ordering::Acquire);
                        if above == ABANDONED {
                            // A block above panicked: this row is left too.
                            done[r].0.store(ABANDONED, Ordering::Release);
                            return;
                        }
                        if above >= need {
                            break;
                        }
                        spins += 1;
                        if spins < 64 {
                            std::hint::spin_loop();
                        } else {
                            std::thread::yield_now();
                        }
                    }
                }
                let unwinding = RowLeftOnPanic(&done[r]);
                block(state, c, r);
                std::mem::forget(unwinding);
                done[r].0.store(c + 1, Ordering::Release);
            }
        }
        if let (Some(state), Ok(mut states)) = (state, states.lock()) {
            states.push(state);
        }
    };
    let workers = rayon::current_num_threads().min(rows).max(1);
    // Tasks of the current pool (not threads of their own: nested in a
    // parallel sweep they share its workers). Each claims rows until none
    // is left, so one task alone does them all.
    rayon::scope(|s| {
        for _ in 1..workers {
            s.spawn(|_| work());
        }
        work();
    });
    states.into_inner().unwrap_or_default()
}

/// Every block of a `cols x rows` grid searched by `search` (which may read
/// the grid's left, top and top-right neighbours of its block) on the
/// current rayon pool's threads: its vectors and costs in raster order.
pub(crate) fn search_rows(
    cols: usize,
    rows: usize,
    search: &(dyn Fn(&SharedGrid, usize, usize) -> Candidate + Sync),
) -> (Vec<Mv>, Vec<u32>) {
    let grid = SharedGrid::new(cols, rows);
    let costs: Vec<AtomicU32> = (0..cols * rows).map(|_| AtomicU32::new(0)).collect();
    wavefront(cols, rows, 2, &|| (), &|_, c, r| {
        let best = search(&grid, c, r);
        grid.set(c, r, best.mv);
        costs[r * cols + c].store(best.cost.min(u64::from(u32::MAX)) as u32, Ordering::Relaxed);
    });
    let vectors = (0..cols * rows)
        .map(|i| grid.vector(i % cols, i / cols))
        .collect();
    (vectors, costs.into_iter().map(AtomicU32::into_inner).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A block that panics ends the call with its panic on any number of
    /// threads, instead of leaving the rows below waiting for it.
    #[test]
    fn a_panicking_block_ends_the_rows_instead_of_hanging_them() {
        for threads in [1, 2, 3] {
            let (tx, rx) = std::sync::mpsc::channel();
            std::thread::spawn(move || {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(threads)
                    .build()
                    .unwrap();
                let outcome = pool.install(|| {
                    std::panic::catch_unwind(|| {
                        wavefront(6, 5, 2, &|| (), &|_, c, r| {
                            assert!((c, r) != (3, 1), "a block's bug");
                        })
                    })
                });
                let _ = tx.send(outcome.is_err());
            });
            let panicked = rx
                .recv_timeout(std::time::Duration::from_secs(20))
                .expect("the rows ended");
            assert!(panicked, "the block's panic passed on ({threads} threads)");
        }
    }
}
