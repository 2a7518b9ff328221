//! The in-loop deblocking filter's kernel (normative: FORMAT.md section
//! 11, H.264 8.7.2): the thresholds of an edge and the filtering of a
//! macroblock's length of edge, line by line in the scalar build, its
//! sixteen lines at once in the AVX2 one (integer arithmetic: the same
//! samples, held equal by `tests/checkasm.rs`).

use super::PerLevel;

/// One macroblock's length of an edge: `(data, (first, step, line_step),
/// strengths, level, luma)`, 16 luma lines (8 chroma) across the edge in
/// four pieces of 4 lines (2 chroma), piece `k` filtered with boundary
/// strength `strengths[k]` (0: left as it is) at `level`. The first line has
/// `q0` at `data[first]` and `p0` at `data[first - step]`, each next line
/// lies `line_step` further on. Every line reads 4 samples on each side.
pub type FilterMbEdgeFn = fn(&mut [u8], (usize, usize, usize), [u8; 4], LfLevel, bool);

/// The same chroma edge of both chroma planes (laid out alike): `(u, v,
/// (first, step, line_step), strengths, level)`, [`FilterMbEdgeFn`] on
/// each (`luma` false).
pub type FilterChromaEdgeFn = fn(&mut [u8], &mut [u8], (usize, usize, usize), [u8; 4], LfLevel);

/// The deblocking kernels of one CPU level.
#[derive(Debug, Clone, Copy)]
pub struct LfDsp {
    /// One macroblock's length of an edge.
    pub filter_mb_edge: FilterMbEdgeFn,
    /// One macroblock's length of a chroma edge, in both chroma planes.
    pub filter_chroma_edge: FilterChromaEdgeFn,
}

const SCALAR: LfDsp = LfDsp {
    filter_mb_edge,
    filter_chroma_edge,
};

/// The tables, lowest level first.
pub static LF: PerLevel<LfDsp> = PerLevel([
    SCALAR,
    SCALAR,
    #[cfg(target_arch = "x86_64")]
    LfDsp {
        filter_mb_edge: x86::filter_mb_edge_avx2,
        filter_chroma_edge: x86::filter_chroma_edge_avx2,
    },
    #[cfg(not(target_arch = "x86_64"))]
    SCALAR,
]);

/// The kernels of the CPU level in force.
#[inline]
pub fn lf() -> &'static LfDsp {
    LF.get()
}

/// Lines of a macroblock's length of edge, and of each of its four pieces.
fn mb_edge_lines(luma: bool) -> (usize, usize) {
    if luma {
        (16, 4)
    } else {
        (8, 2)
    }
}

/// [`FilterMbEdgeFn`], line by line.
pub fn filter_mb_edge(
    d: &mut [u8],
    (first, step, line_step): (usize, usize, usize),
    strengths: [u8; 4],
    level: LfLevel,
    luma: bool,
) {
    let (_, piece) = mb_edge_lines(luma);
    for (k, &bs) in strengths.iter().enumerate() {
        if bs == 0 {
            continue;
        }
        let e = Edge::new(bs, level);
        for line in k * piece..(k + 1) * piece {
            filter_line(d, first + line * line_step, step, e, luma);
        }
    }
}

/// [`FilterChromaEdgeFn`], a plane at a time.
pub fn filter_chroma_edge(
    u: &mut [u8],
    v: &mut [u8],
    at: (usize, usize, usize),
    strengths: [u8; 4],
    level: LfLevel,
) {
    filter_mb_edge(u, at, strengths, level, false);
    filter_mb_edge(v, at, strengths, level, false);
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    //! The edge filter on sixteen lines at once, as x264's `deblock_v_luma`
    //! and `deblock_h_luma`: each of eight vectors holds one distance from
    //! the edge (p3 ... q3) of every line, in 16-bit lanes; a vertical
    //! edge's lines are transposed into that form and back.

    use std::arch::x86_64::*;

    use super::{filter_chroma_edge, filter_mb_edge, mb_edge_lines, Edge, LfLevel, ALPHA, BETA, TC0};

    /// [`super::FilterMbEdgeFn`] with AVX2 (the scalar twin where the
    /// edge is neither along rows nor along columns, or reaches past the
    /// slice).
    pub(super) fn filter_mb_edge_avx2(
        d: &mut [u8],
        (first, step, line_step): (usize, usize, usize),
        strengths: [u8; 4],
        level: LfLevel,
        luma: bool,
    ) {
        if strengths == [0; 4] || !Edge::filters_at(level) {
            return;
        }
        let (lines, _) = mb_edge_lines(luma);
        let vertical = step == 1 && first >= 4 && first + (lines - 1) * line_step + 4 <= d.len();
        let horizontal = line_step == 1 && first >= 4 * step && first + 3 * step + lines <= d.len();
        if !vertical && !horizontal {
            return filter_mb_edge(d, (first, step, line_step), strengths, level, luma);
        }
        let p = d.as_mut_ptr();
        // SAFETY (every call): AVX2 is in force (this kernel sits only in
        // the AVX2 table, which is handed out only where the CPU has it),
        // and every sample read or written lies in the ranges checked just
        // above. Luma and chroma are kernels of their own (the lines and
        // filters known when compiled).
        unsafe {
            match (vertical, luma) {
                (true, true) => across_columns::<true>(p.add(first - 4), line_step, strengths, level),
                (true, false) => across_columns::<false>(p.add(first - 4), line_step, strengths, level),
                (false, true) => across_rows::<true>(p.add(first - 4 * step), step, strengths, level),
                (false, false) => across_rows::<false>(p.add(first - 4 * step), step, strengths, level),
            }
        }
    }

    /// [`super::FilterChromaEdgeFn`] with AVX2: both planes' eight lines in
    /// the sixteen lanes (Cb's in the low eight, Cr's in the high), one
    /// pass of the kernel for the two (the scalar twin where the edge is
    /// neither along rows nor along columns, or reaches past a slice).
    pub(super) fn filter_chroma_edge_avx2(
        u: &mut [u8],
        v: &mut [u8],
        (first, step, line_step): (usize, usize, usize),
        strengths: [u8; 4],
        level: LfLevel,
    ) {
        if strengths == [0; 4] || !Edge::filters_at(level) {
            return;
        }
        let len = u.len().min(v.len());
        let vertical = step == 1 && first >= 4 && first + 7 * line_step + 4 <= len;
        let horizontal = line_step == 1 && first >= 4 * step && first + 3 * step + 8 <= len;
        let (pu, pv) = (u.as_mut_ptr(), v.as_mut_ptr());
        // SAFETY (both calls): AVX2 is in force (this kernel sits only in
        // the AVX2 table), and every sample read or written lies in the
        // ranges checked just above, in both planes.
        if vertical {
            unsafe {
                across_columns_pair(
                    (pu.add(first - 4), pv.add(first - 4)),
                    line_step,
                    strengths,
                    level,
                )
            };
        } else if horizontal {
            let back = first - 4 * step;
            unsafe { across_rows_pair((pu.add(back), pv.add(back)), step, strengths, level) };
        } else {
            filter_chroma_edge(u, v, (first, step, line_step), strengths, level);
        }
    }

    /// A horizontal chroma edge of both planes: each of the rows p3 ... q3
    /// (from `base`, `stride` apart) holds Cb's eight columns, then Cr's.
    #[target_feature(enable = "avx2")]
    unsafe fn across_rows_pair(
        (u, v): (*mut u8, *mut u8),
        stride: usize,
        strengths: [u8; 4],
        level: LfLevel,
    ) {
        let lanes = &Lanes::chroma_pair(strengths, level);
        let mut x = [_mm256_setzero_si256(); 8];
        for (r, x) in x.iter_mut().enumerate() {
            let (a, b) = (
                u.add(r * stride) as *const __m128i,
                v.add(r * stride) as *const __m128i,
            );
            *x = _mm256_cvtepu8_epi16(_mm_unpacklo_epi64(_mm_loadl_epi64(a), _mm_loadl_epi64(b)));
        }
        filter::<false>(&mut x, lanes);
        // Only p0 and q0 change.
        for (r, &row) in x.iter().enumerate().take(5).skip(3) {
            let both = narrow(row);
            _mm_storel_epi64(u.add(r * stride) as *mut __m128i, both);
            _mm_storel_epi64(v.add(r * stride) as *mut __m128i, _mm_unpackhi_epi64(both, both));
        }
    }

    /// A vertical chroma edge of both planes: Cb's eight lines (from `u`,
    /// `stride` apart, each p3 ... q3) as the first eight of sixteen, Cr's
    /// as the last.
    #[target_feature(enable = "avx2")]
    unsafe fn across_columns_pair(
        (u, v): (*mut u8, *mut u8),
        stride: usize,
        strengths: [u8; 4],
        level: LfLevel,
    ) {
        let lanes = &Lanes::chroma_pair(strengths, level);
        let line = |k: usize| {
            if k < 8 {
                u.add(k * stride)
            } else {
                v.add((k - 8) * stride)
            }
        };
        let mut rows = [_mm_setzero_si128(); 16];
        for (k, r) in rows.iter_mut().enumerate() {
            *r = _mm_loadl_epi64(line(k) as *const __m128i);
        }
        let columns = transpose_16x8(&rows);
        let mut x = [_mm256_setzero_si256(); 8];
        for (x, c) in x.iter_mut().zip(columns) {
            *x = _mm256_cvtepu8_epi16(c);
        }
        filter::<false>(&mut x, lanes);
        let mut columns = [_mm_setzero_si128(); 8];
        for (c, x) in columns.iter_mut().zip(x) {
            *c = narrow(x);
        }
        for (k, r) in transpose_8x16(&columns).iter().enumerate() {
            _mm_storel_epi64(line(k) as *mut __m128i, *r);
        }
    }

    /// Each lane's thresholds: alpha (0 in a lane not filtered), beta,
    /// tc0, and whether its strength is 4; and whether any lane has a
    /// strength of 1-3 (`normal`) or of 4 (`any_strong`), so that the
    /// kernel computes only the filters some lane takes (an inter edge
    /// has no strength 4, an intra macroblock's edge only 4).
    struct Lanes {
        alpha: __m256i,
        beta: __m256i,
        tc0: __m256i,
        strong: __m256i,
        normal: bool,
        any_strong: bool,
    }

    impl Lanes {
        /// Chroma's thresholds in both 128-bit halves: the same edge of
        /// the two chroma planes.
        #[target_feature(enable = "avx2")]
        fn chroma_pair(strengths: [u8; 4], level: LfLevel) -> Lanes {
            let one = Lanes::new(strengths, level, false);
            let both = |x: __m256i| _mm256_broadcastsi128_si256(_mm256_castsi256_si128(x));
            Lanes {
                alpha: both(one.alpha),
                tc0: both(one.tc0),
                strong: both(one.strong),
                ..one
            }
        }

        /// Each lane's strength looked up in byte tables indexed by
        /// strength (a shuffle), four lanes a piece for luma, two for
        /// chroma (its upper eight lanes 0).
        #[target_feature(enable = "avx2")]
        fn new(strengths: [u8; 4], level: LfLevel, luma: bool) -> Lanes {
            let (a, b) = (usize::from(level.a), usize::from(level.b));
            let spread = if luma {
                _mm_setr_epi8(0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3)
            } else {
                _mm_setr_epi8(0, 0, 1, 1, 2, 2, 3, 3, -1, -1, -1, -1, -1, -1, -1, -1)
            };
            let bs = _mm_shuffle_epi8(_mm_cvtsi32_si128(i32::from_le_bytes(strengths)), spread);
            // By strength 0 ... 4 (bytes 5-15 unused: strengths are <= 4).
            let (alpha, tc) = (ALPHA[a] as i8, |s: usize| TC0[s][a] as i8);
            let alpha_by = _mm_setr_epi8(0, alpha, alpha, alpha, alpha, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0);
            let tc0_by = _mm_setr_epi8(0, tc(0), tc(1), tc(2), 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0);
            Lanes {
                alpha: _mm256_cvtepu8_epi16(_mm_shuffle_epi8(alpha_by, bs)),
                beta: _mm256_set1_epi16(i16::from(BETA[b])),
                tc0: _mm256_cvtepu8_epi16(_mm_shuffle_epi8(tc0_by, bs)),
                strong: _mm256_cvtepi8_epi16(_mm_cmpeq_epi8(bs, _mm_set1_epi8(4))),
                normal: strengths.iter().any(|s| (1..4).contains(s)),
                any_strong: strengths.contains(&4),
            }
        }
    }

    /// A horizontal edge: lines run down the columns, the eight rows
    /// p3 ... q3 from `base` on, `stride` apart.
    #[target_feature(enable = "avx2")]
    unsafe fn across_rows<const LUMA: bool>(
        base: *mut u8,
        stride: usize,
        strengths: [u8; 4],
        level: LfLevel,
    ) {
        let mut v = [_mm256_setzero_si256(); 8];
        for (r, x) in v.iter_mut().enumerate() {
            let at = base.add(r * stride) as *const __m128i;
            *x = _mm256_cvtepu8_epi16(if LUMA {
                _mm_loadu_si128(at)
            } else {
                _mm_loadl_epi64(at)
            });
        }
        filter::<LUMA>(&mut v, &Lanes::new(strengths, level, LUMA));
        let changed = if LUMA { 1..7 } else { 3..5 };
        for r in changed {
            let at = base.add(r * stride) as *mut __m128i;
            if LUMA {
                _mm_storeu_si128(at, narrow(v[r]));
            } else {
                _mm_storel_epi64(at, narrow(v[r]));
            }
        }
    }

    /// A vertical edge: lines run along the rows, each line's eight samples
    /// p3 ... q3 from `base` on, the lines `stride` apart.
    #[target_feature(enable = "avx2")]
    unsafe fn across_columns<const LUMA: bool>(
        base: *mut u8,
        stride: usize,
        strengths: [u8; 4],
        level: LfLevel,
    ) {
        let (lines, _) = mb_edge_lines(LUMA);
        let mut rows = [_mm_setzero_si128(); 16];
        for (k, r) in rows.iter_mut().enumerate().take(lines) {
            *r = _mm_loadl_epi64(base.add(k * stride) as *const __m128i);
        }
        let columns = transpose_16x8(&rows);
        let mut v = [_mm256_setzero_si256(); 8];
        for (x, c) in v.iter_mut().zip(columns) {
            *x = _mm256_cvtepu8_epi16(c);
        }
        filter::<LUMA>(&mut v, &Lanes::new(strengths, level, LUMA));
        let mut columns = [_mm_setzero_si128(); 8];
        for (c, x) in columns.iter_mut().zip(v) {
            *c = narrow(x);
        }
        let rows = transpose_8x16(&columns);
        for (k, r) in rows.iter().enumerate().take(lines) {
            _mm_storel_epi64(base.add(k * stride) as *mut __m128i, *r);
        }
    }

    /// Sixteen 16-bit lanes saturated to bytes.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn narrow(v: __m256i) -> __m128i {
        _mm_packus_epi16(_mm256_castsi256_si128(v), _mm256_extracti128_si256::<1>(v))
    }

    /// Sixteen rows of 8 bytes (each in the low half of its vector) as
    /// eight columns of 16.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn transpose_16x8(r: &[__m128i; 16]) -> [__m128i; 8] {
        let mut a = [_mm_setzero_si128(); 8];
        for (i, x) in a.iter_mut().enumerate() {
            *x = _mm_unpacklo_epi8(r[2 * i], r[2 * i + 1]);
        }
        // Columns 0-3 (lo) and 4-7 (hi) of rows 4j ... 4j + 3.
        let (mut lo, mut hi) = ([_mm_setzero_si128(); 4], [_mm_setzero_si128(); 4]);
        for j in 0..4 {
            lo[j] = _mm_unpacklo_epi16(a[2 * j], a[2 * j + 1]);
            hi[j] = _mm_unpackhi_epi16(a[2 * j], a[2 * j + 1]);
        }
        let mut columns = [_mm_setzero_si128(); 8];
        for (half, quads) in [lo, hi].iter().enumerate() {
            // Column pairs of rows 0-7 (top) and of rows 8-15 (bottom).
            let top = [
                _mm_unpacklo_epi32(quads[0], quads[1]),
                _mm_unpackhi_epi32(quads[0], quads[1]),
            ];
            let bottom = [
                _mm_unpacklo_epi32(quads[2], quads[3]),
                _mm_unpackhi_epi32(quads[2], quads[3]),
            ];
            for p in 0..2 {
                let c = half * 4 + p * 2;
                columns[c] = _mm_unpacklo_epi64(top[p], bottom[p]);
                columns[c + 1] = _mm_unpackhi_epi64(top[p], bottom[p]);
            }
        }
        columns
    }

    /// Eight columns of 16 bytes as sixteen rows of 8 (each in the low
    /// half of its vector): [`transpose_16x8`] undone.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn transpose_8x16(c: &[__m128i; 8]) -> [__m128i; 16] {
        // Column pairs (2i, 2i + 1) of rows 0-7 (lo) and of rows 8-15 (hi).
        let (mut lo, mut hi) = ([_mm_setzero_si128(); 4], [_mm_setzero_si128(); 4]);
        for i in 0..4 {
            lo[i] = _mm_unpacklo_epi8(c[2 * i], c[2 * i + 1]);
            hi[i] = _mm_unpackhi_epi8(c[2 * i], c[2 * i + 1]);
        }
        let mut rows = [_mm_setzero_si128(); 16];
        for (half, x) in [lo, hi].iter().enumerate() {
            // Columns 0-3 and 4-7 of rows 0-3 and of rows 4-7.
            let c03 = [_mm_unpacklo_epi16(x[0], x[1]), _mm_unpackhi_epi16(x[0], x[1])];
            let c47 = [_mm_unpacklo_epi16(x[2], x[3]), _mm_unpackhi_epi16(x[2], x[3])];
            for q in 0..2 {
                let both = [
                    _mm_unpacklo_epi32(c03[q], c47[q]),
                    _mm_unpackhi_epi32(c03[q], c47[q]),
                ];
                for (k, v) in both.into_iter().enumerate() {
                    let r = half * 8 + q * 4 + k * 2;
                    rows[r] = v;
                    rows[r + 1] = _mm_unpackhi_epi64(v, v);
                }
            }
        }
        rows
    }

    // Lane-wise helpers (functions rather than closures, so that they are
    // compiled for AVX2 and inlined).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn add(a: __m256i, b: __m256i) -> __m256i {
        _mm256_add_epi16(a, b)
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    fn sub(a: __m256i, b: __m256i) -> __m256i {
        _mm256_sub_epi16(a, b)
    }

    /// |a - b|.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn dist(a: __m256i, b: __m256i) -> __m256i {
        _mm256_abs_epi16(_mm256_sub_epi16(a, b))
    }

    /// a < b, as a mask.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn below(a: __m256i, b: __m256i) -> __m256i {
        _mm256_cmpgt_epi16(b, a)
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    fn and(a: __m256i, b: __m256i) -> __m256i {
        _mm256_and_si256(a, b)
    }

    /// `yes` where `mask` is set, `no` elsewhere.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn pick(mask: __m256i, no: __m256i, yes: __m256i) -> __m256i {
        _mm256_blendv_epi8(no, yes, mask)
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    fn k(c: i16) -> __m256i {
        _mm256_set1_epi16(c)
    }

    /// x within +-limit.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn within(x: __m256i, limit: __m256i) -> __m256i {
        _mm256_max_epi16(sub(k(0), limit), _mm256_min_epi16(x, limit))
    }

    /// The sum of `terms` shifted right by `shift`.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn sum_shr<const SHIFT: i32>(terms: &[__m256i]) -> __m256i {
        let mut acc = k(0);
        for &t in terms {
            acc = add(acc, t);
        }
        _mm256_srai_epi16::<SHIFT>(acc)
    }

    /// (2 x1 + x0 + y1 + 2) >> 2: p0 (q0) of strength 4 without the
    /// strong filter, and of chroma.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn soft(x1: __m256i, x0: __m256i, y1: __m256i) -> __m256i {
        sum_shr::<2>(&[x1, x1, x0, y1, k(2)])
    }

    /// The change of p0 (and minus that of q0) at strengths 1-3, within
    /// +-tc.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn delta(p1: __m256i, p0: __m256i, q0: __m256i, q1: __m256i, tc: __m256i) -> __m256i {
        let d = add(_mm256_slli_epi16::<2>(sub(q0, p0)), add(sub(p1, q1), k(4)));
        within(_mm256_srai_epi16::<3>(d), tc)
    }

    /// [`super::filter_line`] on every lane of `v` (p3 ... q3).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn filter<const LUMA: bool>(v: &mut [__m256i; 8], l: &Lanes) {
        let [_, p2, p1, p0, q0, q1, q2, _] = *v;
        let filtered = and(
            below(dist(p0, q0), l.alpha),
            and(below(dist(p1, p0), l.beta), below(dist(q1, q0), l.beta)),
        );
        // Each changed sample by the strength's filter: the lanes of
        // strength 4 take `strong`'s, the others `normal`'s.
        let choose = |normal: __m256i, strong: __m256i| match (l.normal, l.any_strong) {
            (true, true) => pick(l.strong, normal, strong),
            (false, true) => strong,
            _ => normal,
        };
        if !LUMA {
            let dl = if l.normal {
                delta(p1, p0, q0, q1, add(l.tc0, k(1)))
            } else {
                k(0)
            };
            let (sp, sq) = if l.any_strong {
                (soft(p1, p0, q1), soft(q1, q0, p1))
            } else {
                (p0, q0)
            };
            v[3] = pick(filtered, p0, choose(add(p0, dl), sp));
            v[4] = pick(filtered, q0, choose(sub(q0, dl), sq));
            return;
        }
        let (ap, aq) = (below(dist(p2, p0), l.beta), below(dist(q2, q0), l.beta));
        let normal = if l.normal {
            normal_luma([p2, p1, p0, q0, q1, q2], (ap, aq), l.tc0)
        } else {
            [p2, p1, p0, q0, q1, q2]
        };
        let strong = if l.any_strong {
            strong_luma(v, (ap, aq), l.alpha)
        } else {
            normal
        };
        for i in 0..6 {
            v[i + 1] = pick(filtered, v[i + 1], choose(normal[i], strong[i]));
        }
    }

    /// p2 ... q2 of luma lanes at strengths 1-3 (`ap` and `aq` -1 where
    /// the side is flat).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn normal_luma(
        [p2, p1, p0, q0, q1, q2]: [__m256i; 6],
        (ap, aq): (__m256i, __m256i),
        tc0: __m256i,
    ) -> [__m256i; 6] {
        let dl = delta(p1, p0, q0, q1, sub(sub(tc0, ap), aq));
        let mid = _mm256_srai_epi16::<1>(add(add(p0, q0), k(1)));
        let p1n = add(
            p1,
            within(_mm256_srai_epi16::<1>(sub(add(p2, mid), add(p1, p1))), tc0),
        );
        let q1n = add(
            q1,
            within(_mm256_srai_epi16::<1>(sub(add(q2, mid), add(q1, q1))), tc0),
        );
        [
            p2,
            pick(ap, p1, p1n),
            add(p0, dl),
            sub(q0, dl),
            pick(aq, q1, q1n),
            q2,
        ]
    }

    /// p2 ... q2 of luma lanes at strength 4.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn strong_luma(v: &[__m256i; 8], (ap, aq): (__m256i, __m256i), alpha: __m256i) -> [__m256i; 6] {
        let [p3, p2, p1, p0, q0, q1, q2, q3] = *v;
        let steep = below(dist(p0, q0), add(_mm256_srai_epi16::<2>(alpha), k(2)));
        let (sp, sq) = (and(ap, steep), and(aq, steep));
        [
            pick(sp, p2, sum_shr::<3>(&[p3, p3, p2, p2, p2, p1, p0, q0, k(4)])),
            pick(sp, p1, sum_shr::<2>(&[p2, p1, p0, q0, k(2)])),
            pick(
                sp,
                soft(p1, p0, q1),
                sum_shr::<3>(&[p2, p1, p1, p0, p0, q0, q0, q1, k(4)]),
            ),
            pick(
                sq,
                soft(q1, q0, p1),
                sum_shr::<3>(&[p1, p0, p0, q0, q0, q1, q1, q2, k(4)]),
            ),
            pick(sq, q1, sum_shr::<2>(&[p0, q0, q1, q2, k(2)])),
            pick(sq, q2, sum_shr::<3>(&[q3, q3, q2, q2, q2, q1, q0, p0, k(4)])),
        ]
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
    /// The thresholds of an edge of boundary strength `bs` (1..=4) at
    /// `level`.
    pub fn new(bs: u8, level: LfLevel) -> Edge {
        let (a, b) = (usize::from(level.a), usize::from(level.b));
        Edge {
            bs,
            alpha: i32::from(ALPHA[a]),
            beta: i32::from(BETA[b]),
            tc0: if (1..4).contains(&bs) {
                i32::from(TC0[usize::from(bs) - 1][a])
            } else {
                0
            },
        }
    }

    /// Whether any edge is filtered at `level` (below index 16 alpha and
    /// beta are 0).
    pub fn filters_at(level: LfLevel) -> bool {
        ALPHA[usize::from(level.a)] > 0 && BETA[usize::from(level.b)] > 0
    }
}

/// The indices of an edge's thresholds (H.264 8.7.2.2): `a` of alpha and
/// tc0 (indexA), `b` of beta (indexB), each the QP plus the frame
/// header's offset, within 0..=51.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LfLevel {
    /// indexA: alpha's and tc0's.
    pub a: u8,
    /// indexB: beta's.
    pub b: u8,
}

impl LfLevel {
    /// The level at `qp` with offsets `(alpha, beta)` added.
    pub fn new(qp: u8, (alpha, beta): (i8, i8)) -> LfLevel {
        let index = |offset: i8| (i32::from(qp) + i32::from(offset)).clamp(0, 51) as u8;
        LfLevel {
            a: index(alpha),
            b: index(beta),
        }
    }

    /// The level at `qp`, no offsets.
    pub fn at(qp: u8) -> LfLevel {
        LfLevel::new(qp, (0, 0))
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
