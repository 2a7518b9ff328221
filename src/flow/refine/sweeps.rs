//! The red-black SOR sweeps of the refinement over a split layout of the
//! pixels (see [`Sweeps`]), in runs that bands of threads can share.

/// A picture row's samples split into its even and its odd pixels:
/// `even[k] = row[2 k]`, `odd[k] = row[2 k + 1]` (`even` holds
/// `ceil(w / 2)` samples, `odd` `w / 2`).
#[inline(always)]
pub(super) fn deinterleave(row: &[f32], even: &mut [f32], odd: &mut [f32]) {
    let w = row.len();
    // Pairs zipped with both halves cut to length: a loop without bounds
    // checks that vectorises with shuffles (one sample at a time, a
    // strided loop, it took 4 % of the accurate preset's time).
    let (even, odd) = (&mut even[..w.div_ceil(2)], &mut odd[..w / 2]);
    for ((pair, e), o) in row.chunks_exact(2).zip(even.iter_mut()).zip(odd.iter_mut()) {
        (*e, *o) = (pair[0], pair[1]);
    }
    if w % 2 == 1 {
        even[w / 2] = row[w - 1];
    }
}

/// The inverse of [`deinterleave`].
#[inline(always)]
fn interleave(row: &mut [f32], even: &[f32], odd: &[f32]) {
    let w = row.len();
    let (even, odd) = (&even[..w.div_ceil(2)], &odd[..w / 2]);
    for ((pair, &e), &o) in row.chunks_exact_mut(2).zip(even).zip(odd) {
        (pair[0], pair[1]) = (e, o);
    }
    if w % 2 == 1 {
        row[w - 1] = even[w / 2];
    }
}

/// The SOR updates of a run of one colour's samples: each pixel's increment
/// `(du, dv)` from the weights to its four neighbours (left, right, up,
/// down), the neighbours' `du` and `dv`, `c_u`, `c_v`, the reciprocal
/// diagonals and the coupling `a12` (see [`super::system::fold_row`]). Every slice
/// cut to the run's length first, so that the loop runs without bounds
/// checks and vectorises.
#[inline(always)]
pub(super) fn sweep_run(
    omega: f32,
    du: &mut [f32],
    dv: &mut [f32],
    [el, er, eu, ed]: [&[f32]; 4],
    [ul, ur, uu, ud]: [&[f32]; 4],
    [vl, vr, vu, vd]: [&[f32]; 4],
    [cu, cv, iu, iv, a12]: [&[f32]; 5],
) {
    let n = du.len().min(dv.len());
    let (el, er, eu, ed) = (&el[..n], &er[..n], &eu[..n], &ed[..n]);
    let (ul, ur, uu, ud) = (&ul[..n], &ur[..n], &uu[..n], &ud[..n]);
    let (vl, vr, vu, vd) = (&vl[..n], &vr[..n], &vu[..n], &vd[..n]);
    let (cu, cv, iu, iv, a12) = (&cu[..n], &cv[..n], &iu[..n], &iv[..n], &a12[..n]);
    for k in 0..n {
        let nu = el[k] * ul[k] + er[k] * ur[k] + eu[k] * uu[k] + ed[k] * ud[k];
        let nv = el[k] * vl[k] + er[k] * vr[k] + eu[k] * vu[k] + ed[k] * vd[k];
        let new_u = (cu[k] + nu - a12[k] * dv[k]) * iu[k];
        du[k] += omega * (new_u - du[k]);
        let new_v = (cv[k] + nv - a12[k] * du[k]) * iv[k];
        dv[k] += omega * (new_v - dv[k]);
    }
}

/// The coefficients of a sweep and the increment, split into four blocks:
/// red and black pixels (`(x + y)` even and odd), each split again by the
/// parity of the first such pixel in its row (`first`, 0 or 1). Block
/// `(c, first)` holds the rows `y` of that parity (every other row), row
/// `r` holding pixels `x = first + 2 k` at samples `k`. Then every pixel
/// of a block finds its neighbours at the same offsets: left and right in
/// block `(1 - c, 1 - first)` at `k - 1 + first` and `k + first` of the
/// same row, up and down in block `(1 - c, first)` at sample `k` of rows
/// `r - 1 + q` and `r + q` (`q` the parity of the block's rows). So one
/// colour's update is two flat loops, one per block, over whole pictures
/// rather than rows, without per-row set-up or remainder (on CIF's
/// quarter-size level a colour's row is 44 samples: five vectors of eight
/// and four samples one by one; the flat loops took DIS fast on CIF to
/// 0.88x the time of the row loops). Every row has one sample of
/// padding on each side and a block one padding row above and below, all
/// zero, as are the weights towards them. A pixel's weights to its left
/// and upper neighbours are theirs to the right and below, read where
/// their increments are read: each weight is stored once.
pub(crate) struct Sweeps {
    /// Where each pixel's samples are.
    pub(super) layout: Layout,
    /// Per block (`2 c + first`): the weights to the right and to the
    /// lower neighbour; the folded right-hand sides; the reciprocal
    /// diagonals; the coupling (in that order: see
    /// [`super::assemble::assemble_band`]).
    pub(super) coefficients: [[Vec<f32>; COEFFICIENTS]; 4],
    /// Per block: the increment.
    pub(super) du: [Vec<f32>; 4],
    pub(super) dv: [Vec<f32>; 4],
}

/// A pixel's coefficients in [`Sweeps`].
pub(super) const COEFFICIENTS: usize = 7;

/// The geometry of the four blocks of [`Sweeps`] for a `w x h` picture.
#[derive(Clone, Copy)]
pub(crate) struct Layout {
    /// Samples per block row, padding included.
    pub(super) stride: usize,
    pub(super) w: usize,
    /// Picture rows.
    pub(super) h: usize,
}

/// A block of [`Sweeps`]: its index, the parity `q` of its rows, its row
/// count and the samples per row.
#[derive(Clone, Copy)]
pub(crate) struct Block {
    pub(super) index: usize,
    pub(super) first: usize,
    pub(super) q: usize,
    pub(super) rows: usize,
    pub(super) len: usize,
}

/// The four blocks in the order of the colours.
pub(super) const BLOCKS: [(usize, usize); 4] = [(0, 0), (0, 1), (1, 0), (1, 1)];

impl Sweeps {
    pub(super) fn new(w: usize, h: usize) -> Sweeps {
        let layout = Layout::of(w, h);
        let n = layout.len();
        let z = || std::array::from_fn(|_| vec![0f32; n]);
        Sweeps {
            layout,
            coefficients: std::array::from_fn(|_| std::array::from_fn(|_| vec![0f32; n])),
            du: z(),
            dv: z(),
        }
    }

    /// Every array.
    fn arrays(&mut self) -> impl Iterator<Item = &mut Vec<f32>> {
        let coefficients = self.coefficients.iter_mut().flatten();
        coefficients.chain(&mut self.du).chain(&mut self.dv)
    }

    /// Room for a `w x h` picture without a new allocation.
    pub(super) fn reserve(&mut self, w: usize, h: usize) {
        let n = Layout::of(w, h).len();
        for a in self.arrays() {
            a.reserve(n.saturating_sub(a.len()));
        }
    }

    /// Sized for a `w x h` picture, the increment zero, the coefficients'
    /// padding zero (the rest is written before the sweeps read it).
    pub(super) fn resize(&mut self, w: usize, h: usize) {
        self.layout = Layout::of(w, h);
        let n = self.layout.len();
        for a in self.arrays() {
            a.resize(n, 0.0);
        }
        let (layout, s) = (self.layout, self.layout.stride);
        for (c, first) in BLOCKS {
            let b = layout.block(c, first);
            for a in &mut self.coefficients[b.index] {
                // The rows above and below, and each row's sample before
                // and samples after its pixels.
                a[..s].fill(0.0);
                a[(b.rows + 1) * s..].fill(0.0);
                for r in 1..=b.rows {
                    a[r * s] = 0.0;
                    a[r * s + 1 + b.len..(r + 1) * s].fill(0.0);
                }
            }
        }
    }
}

impl Layout {
    pub(super) fn of(w: usize, h: usize) -> Layout {
        Layout {
            stride: w.div_ceil(2) + 2,
            w,
            h,
        }
    }

    /// Samples per block, padding included.
    pub(super) fn len(&self) -> usize {
        self.stride * (self.h.div_ceil(2) + 2)
    }

    pub(super) fn block(&self, c: usize, first: usize) -> Block {
        let q = (c + first) % 2;
        Block {
            index: 2 * c + first,
            first,
            q,
            rows: self.h.saturating_sub(q).div_ceil(2),
            len: self.w.saturating_sub(first).div_ceil(2),
        }
    }

    /// Where sample `k` of row `r` of a block is.
    pub(super) fn at(&self, r: usize, k: usize) -> usize {
        (r + 1) * self.stride + 1 + k
    }

    /// The samples a block's update runs over: from its first row's first
    /// sample to its last row's last (the padding between rows has zero
    /// coefficients and stays zero); empty for an empty block.
    pub(super) fn run(&self, b: Block) -> std::ops::Range<usize> {
        if b.rows == 0 || b.len == 0 {
            return 0..0;
        }
        self.at(0, 0)..self.at(b.rows - 1, b.len)
    }

    /// The blocks that hold picture row `y`, with where the row starts in
    /// them: its pixels `x = first + 2 k` are the samples `k` from there.
    pub(super) fn row_blocks(&self, y: usize) -> [(Block, usize); 2] {
        std::array::from_fn(|first| (self.block((y + first) % 2, first), self.at(y / 2, 0)))
    }
}

/// Picture row `y` of the increment out of the blocks into `[du, dv]`
/// (`w` samples each).
#[inline(always)]
pub(super) fn increment_row(out: [&mut [f32]; 2], layout: Layout, increment: [&[Vec<f32>; 4]; 2], y: usize) {
    // Row y's even pixels are in the first block, its odd ones in the second.
    let [(even, start), (odd, _)] = layout.row_blocks(y);
    for (row, blocks) in out.into_iter().zip(increment) {
        interleave(row, &blocks[even.index][start..], &blocks[odd.index][start..]);
    }
}

/// One band of a block's update: `[du, dv]` cut to the band, which starts
/// at sample `base` of the block; `coefficients` the block's arrays;
/// `lr` the increments `[du, dv]` and the weights to the right of the
/// block holding the left and right neighbours, `ud` the increments and
/// the weights below of the block holding those above and below.
#[inline(always)]
pub(super) fn sweep_band(
    [du, dv]: [&mut [f32]; 2],
    base: usize,
    omega: f32,
    coefficients: [&[f32]; COEFFICIENTS],
    [lr, ud]: [[&[f32]; 3]; 2],
    b: Block,
    stride: usize,
) {
    let (left, up, down) = (
        base + b.first - 1,
        base + b.q * stride - stride,
        base + b.q * stride,
    );
    let [er, ed, cu, cv, iu, iv, a12] = coefficients.map(|a| &a[base..]);
    // The left neighbour's weight to the right, the upper one's below.
    let (el, eu) = (&lr[2][left..], &ud[2][up..]);
    sweep_run(
        omega,
        du,
        dv,
        [el, er, eu, ed],
        [&lr[0][left..], &lr[0][left + 1..], &ud[0][up..], &ud[0][down..]],
        [&lr[1][left..], &lr[1][left + 1..], &ud[1][up..], &ud[1][down..]],
        [cu, cv, iu, iv, a12],
    );
}
