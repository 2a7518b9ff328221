//! The linear system of one fixed-point iteration, assembled row by row
//! straight into the sweeps' blocks: a row's data terms, smoothness
//! weights and fold are computed in a few rows of scratch and scattered to
//! the blocks at once. Made a term at a time, the system took seven
//! whole-grid arrays that were written, read back to be folded, and read
//! again to be gathered into the blocks, with the increment copied out of
//! the blocks before each iteration: about 200 bytes of memory traffic a
//! pixel, against the 80 that the assembly reads and writes (the nine
//! derivatives, the flow and increment, the seven coefficients).

use super::sweeps::{deinterleave, increment_row, Layout, COEFFICIENTS};
use super::system::{band_rows, data_row, fold_row, smoothness_row, FlowRows, Linearised, Padded};
use super::RefineParams;

/// What the assembly of every row reads.
#[derive(Clone, Copy)]
pub(crate) struct Terms<'a> {
    pub(super) lin: &'a Linearised,
    /// `[u, v]` on the padded grid.
    pub(super) flow: [&'a [f32]; 2],
    /// `[du, dv]` in the sweeps' blocks.
    pub(super) increment: [&'a [Vec<f32>; 4]; 2],
    pub(super) p: &'a RefineParams,
    pub(super) g: &'a Padded,
    pub(super) layout: Layout,
}

/// The rows in flight, `w` samples each (rows held by parity, `y % 2`).
#[derive(Default)]
struct Scratch {
    /// `[du, dv]` of a row and of the row below.
    increment: [[Vec<f32>; 2]; 2],
    /// The row's weights to the right, after a zero: the weight to the
    /// left of pixel `x` is sample `x`, to the right sample `x + 1`.
    right: Vec<f32>,
    /// The weights below of the row above and of the row.
    down: [Vec<f32>; 2],
    /// `[a11, a12, a22, b1, b2]` of the row.
    data: [Vec<f32>; 5],
}

/// Assembles the rows of a band into the blocks: `out` is the blocks'
/// coefficients (block `j`'s coefficient `i` at `7 j + i`, in the order of
/// [`super::sweeps::Sweeps::coefficients`]) cut to the band, which starts
/// at sample `base` of the blocks. The band's picture rows are those of
/// its block rows; each row's coefficients are computed alike whatever
/// the bands.
#[inline(always)]
pub(super) fn assemble_band(mut out: [&mut [f32]; 4 * COEFFICIENTS], base: usize, t: Terms<'_>) {
    let (w, h) = (t.g.w, t.g.h);
    let blocks = band_rows(base, out[0].len(), t.layout.stride, h.div_ceil(2));
    let rows = 2 * blocks.start..(2 * blocks.end).min(h);
    if rows.is_empty() {
        return;
    }
    // Taken out of the thread's slot and put back, so that the rows are
    // computed here, in the kernel's own build (a closure would be
    // compiled apart, without its CPU features).
    let mut s = SCRATCH.take();
    s.size(w);
    s.load_increment(t, rows.start);
    if rows.start > 0 {
        // The weights below of the row above: the fold's weights up.
        s.load_increment(t, rows.start - 1);
        s.smoothness(t, rows.start - 1);
    } else {
        // The first row has no edge above.
        s.down[1].fill(0.0);
    }
    for y in rows {
        if y + 1 < h {
            s.load_increment(t, y + 1);
        }
        s.smoothness(t, y);
        s.data(t, y);
        s.fold(t, y);
        s.scatter(&mut out, base, t, y);
    }
    SCRATCH.set(s);
}

thread_local! {
    /// Each thread's rows in flight, kept from band to band (the pipelined
    /// sweeps assemble a few rows at a time, hundreds of bands a level).
    static SCRATCH: std::cell::Cell<Scratch> = std::cell::Cell::new(Scratch::default());
}

impl Scratch {
    #[inline(always)]
    /// Rows of `w` samples (what they hold is written before it is read,
    /// but for the zero before the weights to the right).
    fn size(&mut self, w: usize) {
        let rows = self.increment.iter_mut().flatten();
        for row in rows.chain(&mut self.down).chain(&mut self.data) {
            row.resize(w, 0.0);
        }
        self.right.resize(w + 1, 0.0);
        self.right[0] = 0.0;
    }

    #[inline(always)]
    fn load_increment(&mut self, t: Terms<'_>, y: usize) {
        let [du, dv] = &mut self.increment[y % 2];
        increment_row([du, dv], t.layout, t.increment, y);
    }

    /// Row `y`'s weights to the right and below.
    #[inline(always)]
    fn smoothness(&mut self, t: Terms<'_>, y: usize) {
        let (w, below) = (t.g.w, y + 1 < t.g.h);
        let [u, v] = t.flow;
        let (r, next) = (t.g.at(0, y), t.g.at(0, if below { y + 1 } else { y }));
        let [du, dv] = &self.increment[y % 2];
        let [dub, dvb] = &self.increment[if below { (y + 1) % 2 } else { y % 2 }];
        let rows = FlowRows {
            flow: [
                [&u[r..r + w], &v[r..r + w]],
                [&u[next..next + w], &v[next..next + w]],
            ],
            increment: [[du, dv], [dub, dvb]],
            below,
        };
        smoothness_row([&mut self.right[1..], &mut self.down[y % 2]], rows, t.p);
    }

    #[inline(always)]
    fn data(&mut self, t: Terms<'_>, y: usize) {
        let [du, dv] = &self.increment[y % 2];
        let out = self.data.each_mut().map(|a| &mut a[..]);
        data_row(out, t.lin, t.g.at(0, y), [du, dv], t.p);
    }

    #[inline(always)]
    fn fold(&mut self, t: Terms<'_>, y: usize) {
        let [a11, _, a22, b1, b2] = &mut self.data;
        let (right, [down_a, down_b]) = (&self.right, &self.down);
        let (up, down) = if y % 2 == 0 {
            (down_b, down_a)
        } else {
            (down_a, down_b)
        };
        let weights = [&right[..], &right[1..], &up[..], &down[..]];
        fold_row([b1, b2, a11, a22], weights, t.flow, t.g.at(0, y), t.g.stride());
    }

    /// Row `y`'s coefficients into the two blocks that hold it.
    #[inline(always)]
    fn scatter(&self, out: &mut [&mut [f32]; 4 * COEFFICIENTS], base: usize, t: Terms<'_>, y: usize) {
        let [a11, a12, a22, b1, b2] = &self.data;
        let w = t.g.w;
        let down = &self.down[y % 2];
        let sources: [&[f32]; COEFFICIENTS] = [&self.right[1..], down, b1, b2, a11, a22, a12];
        // The row's even pixels go to the first block, its odd ones to the second.
        let [(even, start), (odd, _)] = t.layout.row_blocks(y);
        let (lo, hi) = out.split_at_mut(COEFFICIENTS * even.index.max(odd.index));
        let first = &mut lo[COEFFICIENTS * even.index.min(odd.index)..][..COEFFICIENTS];
        let (e, d) = if even.index < odd.index {
            (first, &mut hi[..COEFFICIENTS])
        } else {
            (&mut hi[..COEFFICIENTS], first)
        };
        let o = start - base;
        for ((src, e), d) in sources.iter().zip(e).zip(d) {
            deinterleave(&src[..w], &mut e[o..], &mut d[o..]);
        }
    }
}
