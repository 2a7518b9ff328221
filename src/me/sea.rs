//! Successive elimination for exhaustive search (Li and Salari 1995; in
//! its multilevel form, as x264's `esa` prunes with sums of sub-blocks,
//! "ADS"): a position whose lower bound already exceeds the best cost
//! found cannot be the minimum and is not evaluated, so the search gives
//! exactly the vectors of evaluating every position.
//!
//! The bound of a block at a position is the sum over its four quadrants
//! of `|sum(current quadrant) - sum(reference quadrant)|` (each quadrant's
//! difference of sums is at most its SAD), turned into a bound on the
//! search's metric ([`bound_for`]), plus the position's rate term. The
//! reference's quadrant sums at every position are found once per
//! reference ([`QuadrantSums`]); the bounds of a row of positions are then a
//! few vector operations (the `ads` kernel of [`super::dsp`]). Positions
//! are evaluated best bound first, and the walk stops at the first bound
//! above the best cost.

use super::dsp::PixelDsp;
use super::Metric;
use crate::codec::Plane;

/// The sum of the `side x side` block at every position of a reference
/// plane's buffer (its border included), laid out as the plane is: what
/// the bounds of every block position are made of.
pub(crate) struct QuadrantSums {
    /// Side of the summed blocks: half the search's block.
    side: usize,
    stride: usize,
    sums: Vec<u16>,
}

impl QuadrantSums {
    /// The sums of `reference` for blocks of `block` (4 to 32) samples.
    pub fn new(reference: &Plane, block: usize, dsp: &PixelDsp) -> QuadrantSums {
        let side = block / 2;
        let (stride, rows) = (reference.stride(), reference.data().len() / reference.stride());
        let mut sums = vec![0u16; stride * rows];
        (dsp.box_sums)(reference.data(), stride, rows, side, &mut sums);
        QuadrantSums { side, stride, sums }
    }

    /// The quadrant sums' row through the buffer offset `at`.
    #[inline]
    fn row(&self, at: usize, len: usize) -> &[u16] {
        &self.sums[at..at + len]
    }
}

/// The scalar box sums: `out[p]` the sum of the `side x side` block whose
/// top-left sample is `data[p]`, wherever that block lies inside the
/// buffer of `rows` rows of `stride` (0 elsewhere).
#[inline(always)]
pub fn box_sums(data: &[u8], stride: usize, rows: usize, side: usize, out: &mut [u16]) {
    if side == 0 || rows < side || stride < side {
        return;
    }
    // Sums down each column of `side` rows, slid a row at a time; then
    // across `side` columns of them as `side` whole-row additions (a running
    // sum across would be one long dependency chain, these vectorise).
    let mut column = vec![0u16; stride];
    let mut across = (Vec::with_capacity(stride), Vec::with_capacity(stride));
    for r in 0..side {
        for (c, &v) in column.iter_mut().zip(&data[r * stride..(r + 1) * stride]) {
            *c += u16::from(v);
        }
    }
    let width = stride - side + 1;
    for top in 0..=rows - side {
        if top > 0 {
            let gone = &data[(top - 1) * stride..top * stride];
            let new = &data[(top + side - 1) * stride..(top + side) * stride];
            for ((c, &g), &n) in column.iter_mut().zip(gone).zip(new) {
                *c = *c - u16::from(g) + u16::from(n);
            }
        }
        let out_row = &mut out[top * stride..top * stride + width];
        if side.is_power_of_two() {
            sum_across_by_doubling(&column, side, [&mut across.0, &mut across.1], out_row);
            continue;
        }
        out_row.copy_from_slice(&column[..width]);
        for k in 1..side {
            for (o, &c) in out_row.iter_mut().zip(&column[k..k + width]) {
                *o += c;
            }
        }
    }
}

/// `out[c] = column[c] + ... + column[c + side - 1]` for a power-of-two
/// `side`, as sums of pairs, of pairs of pairs...: log2(side) whole-row
/// additions instead of side - 1 (3 instead of 7 for 16x16 blocks).
#[inline(always)]
fn sum_across_by_doubling(column: &[u16], side: usize, scratch: [&mut Vec<u16>; 2], out: &mut [u16]) {
    let [a, b] = scratch;
    a.clear();
    a.extend_from_slice(column);
    let mut span = 1;
    while span < side {
        let n = a.len() - span;
        b.clear();
        b.extend(a[..n].iter().zip(&a[span..]).map(|(&x, &y)| x + y));
        std::mem::swap(a, b);
        span *= 2;
    }
    out.copy_from_slice(&a[..out.len()]);
}

/// The scalar `ads`: for the `out.len()` positions along a row, `out[i] =
/// sum_q |rows[q][i] - current[q]|`, the quadrants' difference of sums, in
/// u16 lanes (twice as many to a vector as u32) with a saturating sum: up
/// to 16x16 blocks (8x8 quadrants, each sum at most 16320) the sum is
/// exact, beyond it a bound capped at `u16::MAX` is still a lower bound.
/// Returns the least of them (`u16::MAX` for none): a row whose least
/// bound is above the best cost holds no survivor, and the window's least
/// bound is the least of its rows'.
#[inline(always)]
pub fn ads(rows: [&[u16]; 4], current: [u16; 4], out: &mut [u16]) -> u16 {
    let n = out.len();
    let [a, b, c, d] = rows;
    let (a, b, c, d) = (&a[..n], &b[..n], &c[..n], &d[..n]);
    let mut least = u16::MAX;
    for i in 0..n {
        let bound = a[i]
            .abs_diff(current[0])
            .saturating_add(b[i].abs_diff(current[1]))
            .saturating_add(c[i].abs_diff(current[2]))
            .saturating_add(d[i].abs_diff(current[3]));
        out[i] = bound;
        least = least.min(bound);
    }
    least
}

/// Whether elimination saves time over a window of radius `r` in `metric`:
/// its sums and bounds cost about as much as a few evaluations per block,
/// and its bounds are tighter for SAD than for SATD and SSD. Measured on
/// `pan_cif` (`mocomp me --method esa --range R --qp 27 --threads 1`, with
/// and without `--no-elimination`): SAD gains from radius 4 (0.48 against
/// 0.52 ms a pass; 1.47 against 6.00 at 16), SATD only from 7 (1.95
/// against 2.10; 5.60 against 9.32 at 16) and loses at 3 and 4.
pub(crate) fn pays(metric: Metric, r: i32) -> bool {
    r >= if metric == Metric::Sad { 4 } else { 7 }
}

/// A lower bound of the block's distortion in `metric` from the sum over
/// its quadrants of the absolute differences of sums (`diff`), with
/// `samples` samples in each quadrant: SAD is at least it; SATD (halved
/// Hadamard, each 4x4 tile's DC coefficient its sum) at least half of it,
/// rounded up; SSD at least the sum of squares over samples per quadrant,
/// of which the square of the total over four quadrants is a lower bound
/// (by Cauchy-Schwarz: `sum d_q^2 >= (sum d_q)^2 / 4`).
#[inline]
pub(crate) fn bound_for(metric: Metric, diff: u32, samples: u32) -> u64 {
    match metric {
        Metric::Sad => u64::from(diff),
        Metric::Satd => u64::from(diff.div_ceil(2)),
        Metric::Ssd => {
            let d = u64::from(diff);
            (d * d) / (4 * u64::from(samples))
        }
    }
}

/// The largest quadrant difference `diff` whose [`bound_for`] does not
/// exceed `cost`: positions with a larger one cannot reach `cost`.
#[inline]
pub(crate) fn max_diff(metric: Metric, cost: u64, samples: u32) -> u64 {
    match metric {
        Metric::Sad => cost,
        Metric::Satd => cost.saturating_mul(2),
        Metric::Ssd => {
            // floor(d^2 / 4n) <= cost  <=>  d^2 < 4n (cost + 1).
            let limit = (4 * u128::from(samples)) * (u128::from(cost) + 1);
            let mut d = (limit as f64).sqrt() as u128;
            while d * d >= limit {
                d -= 1;
            }
            while (d + 1) * (d + 1) < limit {
                d += 1;
            }
            u64::try_from(d).unwrap_or(u64::MAX)
        }
    }
}

/// The current block's four quadrant sums (`cur` rows of `stride`, block
/// side `b`), in the order the bound reads the reference's: top-left,
/// top-right, bottom-left, bottom-right. 16x16 blocks go through the
/// `group_sums` kernel (sums of 8 columns down 8 rows, a vector
/// instruction a row): the scalar loop took 3.5-4.7 % of `mocomp me
/// --method esa` samples on webcam_cif (`perf`, two profiles).
pub(crate) fn current_sums(cur: &[u8], stride: usize, b: usize, dsp: &PixelDsp) -> [u16; 4] {
    let h = b / 2;
    if b == 16 && cur.len() >= 15 * stride + 16 {
        let (mut top, mut bottom) = ([0u32; 2], [0u32; 2]);
        (dsp.group_sums)(cur, stride, (16, 8), &mut top);
        (dsp.group_sums)(&cur[8 * stride..], stride, (16, 8), &mut bottom);
        // 64 samples of at most 255 a quadrant: within u16.
        return [top[0], top[1], bottom[0], bottom[1]].map(|v| v as u16);
    }
    let mut s = [0u16; 4];
    for (r, row) in cur.chunks(stride).take(b).enumerate() {
        let half = |part: &[u8]| part.iter().map(|&v| u16::from(v)).sum::<u16>();
        let q = usize::from(r >= h) * 2;
        s[q] += half(&row[..h]);
        s[q + 1] += half(&row[h..b]);
    }
    s
}

/// What a window's search needs to bound a row of positions.
pub(crate) struct RowBounds<'a> {
    pub sums: &'a QuadrantSums,
    pub current: [u16; 4],
    pub ads: super::dsp::AdsFn,
}

impl RowBounds<'_> {
    /// The quadrant bounds of `n` positions whose first block starts at
    /// buffer offset `at`, into `out`; returns the least of them.
    #[inline]
    pub fn row(&self, at: usize, n: usize, out: &mut [u16]) -> u16 {
        let (side, stride) = (self.sums.side, self.sums.stride);
        // Written out, not `map`ped: the map was a call of its own per row.
        let below = at + side * stride;
        let rows = [
            self.sums.row(at, n),
            self.sums.row(at + side, n),
            self.sums.row(below, n),
            self.sums.row(below + side, n),
        ];
        (self.ads)(rows, self.current, &mut out[..n])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_sums_are_the_blocks_sums() {
        let p = Plane::from_fn(23, 17, |x, y| ((x * 37 + y * 91) % 256) as u8).unwrap();
        let (stride, rows) = (p.stride(), p.data().len() / p.stride());
        for side in [2, 3, 4, 8, 16] {
            let mut out = vec![0u16; stride * rows];
            box_sums(p.data(), stride, rows, side, &mut out);
            for at in [0, 17, stride * 3 + 5, stride * (rows - side) + stride - side] {
                let want: u32 = (0..side)
                    .flat_map(|r| (0..side).map(move |c| (r, c)))
                    .map(|(r, c)| u32::from(p.data()[at + r * stride + c]))
                    .sum();
                assert_eq!(u32::from(out[at]), want, "side {side} at {at}");
            }
        }
    }

    #[test]
    fn current_sums_are_the_quadrants_sums() {
        let stride = 40;
        let data: Vec<u8> = (0..stride * 32).map(|i| ((i * 73 + i / 7) % 256) as u8).collect();
        for level in crate::codec::cpu::available() {
            let dsp = crate::me::dsp::PIXEL.at(level);
            for b in [4, 8, 16, 32] {
                let h = b / 2;
                let quadrant = |qy: usize, qx: usize| -> u32 {
                    (0..h)
                        .flat_map(|r| (0..h).map(move |c| (qy * h + r) * stride + qx * h + c))
                        .map(|i| u32::from(data[i + 3]))
                        .sum()
                };
                let want = [quadrant(0, 0), quadrant(0, 1), quadrant(1, 0), quadrant(1, 1)];
                let got = current_sums(&data[3..], stride, b, dsp).map(u32::from);
                assert_eq!(got, want, "{} {b}x{b}", level.name());
            }
        }
    }

    #[test]
    fn max_diff_is_the_inverse_of_the_bound() {
        for metric in Metric::ALL {
            for samples in [4, 16, 64, 256] {
                for cost in [0, 1, 2, 7, 100, 12345, 1 << 40] {
                    let d = max_diff(metric, cost, samples);
                    assert!(
                        bound_for(metric, d.min(u64::from(u32::MAX)) as u32, samples) <= cost
                            || d > u64::from(u32::MAX)
                    );
                    if d < u64::from(u32::MAX) {
                        assert!(
                            bound_for(metric, d as u32 + 1, samples) > cost,
                            "{metric:?} {samples} {cost}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn the_bounds_never_exceed_the_metric() {
        let mut s = 7u64;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s as u8
        };
        for b in [4, 8, 16, 32] {
            for _ in 0..200 {
                let a: Vec<u8> = (0..b * b).map(|_| next()).collect();
                let c: Vec<u8> = (0..b * b).map(|_| next() / 2 + 60).collect();
                let dsp = super::super::dsp::pixel();
                let (sa, sc) = (current_sums(&a, b, b, dsp), current_sums(&c, b, b, dsp));
                let diff: u32 = (0..4).map(|q| u32::from(sa[q].abs_diff(sc[q]))).sum();
                let samples = (b * b / 4) as u32;
                for metric in Metric::ALL {
                    let cost = u64::from(metric.cost(&a, b, &c, b, b, b));
                    assert!(bound_for(metric, diff, samples) <= cost, "{metric:?} {b}x{b}");
                }
            }
        }
    }
}
