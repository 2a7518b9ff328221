//! The in-loop deblocking filter's kernel (normative: FORMAT.md section
//! 11, H.264 8.7.2): the thresholds of an edge and the filtering of a
//! piece of edge, line by line. The AVX2 build is the scalar source
//! compiled for AVX2 (integer arithmetic: the same samples).

use super::PerLevel;

/// A piece of edge filtered: `(data, (first, step, line_step), lines,
/// edge, luma)`, `lines` lines across the edge, the first with `q0` at
/// `data[first]` and `p0` at `data[first - step]`, each next line
/// `line_step` further on.
pub type FilterEdgeFn = fn(&mut [u8], (usize, usize, usize), usize, Edge, bool);

/// The deblocking kernels of one CPU level.
#[derive(Debug, Clone, Copy)]
pub struct LfDsp {
    /// One piece of edge (4 luma lines, 2 chroma).
    pub filter_edge: FilterEdgeFn,
}

const SCALAR: LfDsp = LfDsp { filter_edge };

/// The tables, lowest level first.
pub static LF: PerLevel<LfDsp> = PerLevel([
    SCALAR,
    SCALAR,
    #[cfg(target_arch = "x86_64")]
    LfDsp {
        filter_edge: avx2::filter_edge,
    },
    #[cfg(not(target_arch = "x86_64"))]
    SCALAR,
]);

/// The kernels of the CPU level in force.
#[inline]
pub fn lf() -> &'static LfDsp {
    LF.get()
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::Edge;
    crate::compiled_for! { "avx2":
        fn filter_edge(d: &mut [u8], at: (usize, usize, usize), lines: usize, e: Edge, luma: bool) => super::filter_edge;
    }
}

#[inline(always)]
fn filter_edge(
    d: &mut [u8],
    (first, step, line_step): (usize, usize, usize),
    lines: usize,
    e: Edge,
    luma: bool,
) {
    for k in 0..lines {
        filter_line(d, first + k * line_step, step, e, luma);
    }
}

/// alpha of an edge by QP (H.264 table 8-16, indexA): the largest step
/// across the edge that is still taken for a blocking artefact.
const ALPHA: [u8; 52] = [
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 4, 4, 5, 6, 7, 8, 9, 10, 12, 13, 15, 17, 20, 22, 25, 28,
    32, 36, 40, 45, 50, 56, 63, 71, 80, 90, 101, 113, 127, 144, 162, 182, 203, 226, 255, 255,
];

/// beta by QP (table 8-16, indexB): the largest step on either side of the
/// edge for it to count as flat there.
const BETA: [u8; 52] = [
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 2, 2, 2, 3, 3, 3, 3, 4, 4, 4, 6, 6, 7, 7, 8, 8, 9, 9, 10,
    10, 11, 11, 12, 12, 13, 13, 14, 14, 15, 15, 16, 16, 17, 17, 18, 18,
];

/// tc0 by boundary strength 1, 2, 3 (rows) and QP (table 8-17): how far
/// a sample may move.
const TC0: [[u8; 52]; 3] = [
    [
        0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 2,
        2, 2, 2, 3, 3, 3, 4, 4, 4, 5, 6, 6, 7, 8, 9, 10, 11, 13,
    ],
    [
        0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 2, 2, 2,
        2, 3, 3, 3, 4, 4, 5, 5, 6, 7, 8, 8, 10, 11, 12, 13, 15, 17,
    ],
    [
        0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3,
        4, 4, 4, 5, 6, 6, 7, 8, 9, 10, 11, 13, 14, 16, 18, 20, 23, 25,
    ],
];

/// The thresholds of one edge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Edge {
    bs: u8,
    alpha: i32,
    beta: i32,
    /// tc0 (bS 1 to 3).
    tc0: i32,
}

impl Edge {
    /// The thresholds of an edge of boundary strength `bs` (1..=4) at `qp`.
    pub fn new(bs: u8, qp: u8) -> Edge {
        let q = usize::from(qp);
        Edge {
            bs,
            alpha: i32::from(ALPHA[q]),
            beta: i32::from(BETA[q]),
            tc0: if (1..4).contains(&bs) {
                i32::from(TC0[usize::from(bs) - 1][q])
            } else {
                0
            },
        }
    }

    /// Whether any edge is filtered at `qp` (below QP 16 alpha is 0).
    pub fn filters_at(qp: u8) -> bool {
        ALPHA[usize::from(qp)] > 0
    }
}

/// Filters the line of samples across an edge: `q0` at `d[at]`, `q1` at
/// `d[at + step]`, `p0` at `d[at - step]`, and so on.
#[inline(always)]
fn filter_line(d: &mut [u8], at: usize, step: usize, e: Edge, luma: bool) {
    let s = |k: isize| (at as isize + k * step as isize) as usize;
    let v = |d: &[u8], k: isize| i32::from(d[s(k)]);
    let (p0, p1, q0, q1) = (v(d, -1), v(d, -2), v(d, 0), v(d, 1));
    if (p0 - q0).abs() >= e.alpha || (p1 - p0).abs() >= e.beta || (q1 - q0).abs() >= e.beta {
        return;
    }
    let clip = |x: i32| x.clamp(0, 255) as u8;
    if !luma {
        if e.bs == 4 {
            d[s(-1)] = ((2 * p1 + p0 + q1 + 2) >> 2) as u8;
            d[s(0)] = ((2 * q1 + q0 + p1 + 2) >> 2) as u8;
        } else {
            let tc = e.tc0 + 1;
            let delta = ((((q0 - p0) << 2) + (p1 - q1) + 4) >> 3).clamp(-tc, tc);
            d[s(-1)] = clip(p0 + delta);
            d[s(0)] = clip(q0 - delta);
        }
        return;
    }
    let (p2, q2) = (v(d, -3), v(d, 2));
    let (ap, aq) = ((p2 - p0).abs() < e.beta, (q2 - q0).abs() < e.beta);
    if e.bs == 4 {
        let strong = (p0 - q0).abs() < (e.alpha >> 2) + 2;
        let (p3, q3) = (v(d, -4), v(d, 3));
        if ap && strong {
            d[s(-1)] = ((p2 + 2 * p1 + 2 * p0 + 2 * q0 + q1 + 4) >> 3) as u8;
            d[s(-2)] = ((p2 + p1 + p0 + q0 + 2) >> 2) as u8;
            d[s(-3)] = ((2 * p3 + 3 * p2 + p1 + p0 + q0 + 4) >> 3) as u8;
        } else {
            d[s(-1)] = ((2 * p1 + p0 + q1 + 2) >> 2) as u8;
        }
        if aq && strong {
            d[s(0)] = ((p1 + 2 * p0 + 2 * q0 + 2 * q1 + q2 + 4) >> 3) as u8;
            d[s(1)] = ((p0 + q0 + q1 + q2 + 2) >> 2) as u8;
            d[s(2)] = ((2 * q3 + 3 * q2 + q1 + q0 + p0 + 4) >> 3) as u8;
        } else {
            d[s(0)] = ((2 * q1 + q0 + p1 + 2) >> 2) as u8;
        }
        return;
    }
    let tc = e.tc0 + i32::from(ap) + i32::from(aq);
    let delta = ((((q0 - p0) << 2) + (p1 - q1) + 4) >> 3).clamp(-tc, tc);
    d[s(-1)] = clip(p0 + delta);
    d[s(0)] = clip(q0 - delta);
    let mid = (p0 + q0 + 1) >> 1;
    if ap {
        d[s(-2)] = (p1 + ((p2 + mid - (p1 << 1)) >> 1).clamp(-e.tc0, e.tc0)) as u8;
    }
    if aq {
        d[s(1)] = (q1 + ((q2 + mid - (q1 << 1)) >> 1).clamp(-e.tc0, e.tc0)) as u8;
    }
}
