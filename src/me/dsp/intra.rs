//! The intra searches' SATD kernels.
//!
//! [`QuadFn`]: four 4x4 predictions against one source block, two pairs
//! of tiles (as [`super::PairFn`]) in the two halves of a 256-bit vector
//! (`cargo bench --bench dsp -- satd_4x4_quad`: 8.2 ns in AVX2, 13.7 as
//! two SSE2 pairs). With it, and the mode prices found once a macroblock,
//! ultrafast's instructions x0.988 on the five encodes below.
//!
//! [`IntraSatdX3Fn`]: the SATD of the three 16x16 intra modes whose
//! prediction is constant down columns or along rows (vertical,
//! horizontal, DC) from one transform of the source, as x264's `intra_satd_x3_16x16`. The Hadamard
//! transform is linear, and in each 4x4 tile those predictions have only
//! a few nonzero coefficients (vertical: the first row, 4 H t; horizontal:
//! the first column, 4 H l; DC: the first, 16 dc): the source's
//! coefficients are found once, and per mode only those few are taken
//! off. `cargo bench --bench dsp -- intra_satd_x3`: 36 ns for the three
//! in AVX2, where one 16x16 SATD alone takes 25 ns; ultrafast's
//! instructions x0.986 on five 10-frame encodes (`benches/instructions.py`:
//! dog_1080p, cockatoo_720p, diver_vga, fish_1160, garden_720p).

/// Signature: `(source, top, left, dc)` gives the SATD (halved, rounded
/// up, as [`super::satd`]) of the 16x16 `source` (rows of 16) against the
/// vertical prediction from `top`, the horizontal one from `left` and the
/// flat `dc`, in that order. A mode whose edge the block lacks is the
/// caller's to leave out.
pub type IntraSatdX3Fn = fn(&[u8; 256], &[u8; 16], &[u8; 16], u8) -> [u32; 3];

/// Signature of the 4x4 SATD of four tiles: the source tile twice side
/// by side (8x4, rows of 8 bytes) against two such pairs of predictions;
/// each tile's SATD (halved, rounded up, as [`super::satd`] of that tile
/// alone).
pub type QuadFn = fn(&[u8; 32], &[[u8; 32]; 2]) -> [u32; 4];

/// The scalar [`QuadFn`]: two pairs.
pub fn satd_4x4_quad(a: &[u8; 32], b: &[[u8; 32]; 2]) -> [u32; 4] {
    let pair = |b: &[u8]| [0, 4].map(|o| super::satd(&a[o..], 8, &b[o..], 8, 4, 4));
    let ([p, q], [r, s]) = (pair(&b[0]), pair(&b[1]));
    [p, q, r, s]
}

/// The scalar [`IntraSatdX3Fn`]: each prediction made and measured, the
/// definition the other kernels must equal.
pub fn intra_satd_x3_16x16(src: &[u8; 256], top: &[u8; 16], left: &[u8; 16], dc: u8) -> [u32; 3] {
    let mut pred = [0u8; 256];
    let satd = |pred: &[u8; 256]| super::satd(src, 16, pred, 16, 16, 16);
    for row in pred.chunks_exact_mut(16) {
        row.copy_from_slice(top);
    }
    let vertical = satd(&pred);
    for (row, &l) in pred.chunks_exact_mut(16).zip(left) {
        row.fill(l);
    }
    let horizontal = satd(&pred);
    pred.fill(dc);
    [vertical, horizontal, satd(&pred)]
}

#[cfg(target_arch = "x86_64")]
pub(super) mod x86 {
    use std::arch::x86_64::*;

    /// The AVX2 [`super::IntraSatdX3Fn`]: a row of four tiles at a time,
    /// sixteen 16-bit lanes (every coefficient stays within +-8160).
    pub fn intra_satd_x3_16x16_avx2(src: &[u8; 256], top: &[u8; 16], left: &[u8; 16], dc: u8) -> [u32; 3] {
        // SAFETY: this kernel sits only in the AVX2 table, handed out only
        // where the CPU has AVX2; it reads the arrays alone.
        unsafe { satd_x3(src, top, left, dc) }
    }

    /// The AVX2 [`super::QuadFn`]: the paired tiles' butterflies of
    /// the SSE2 kernel, one pair in each 128-bit half.
    pub fn satd_4x4_quad_avx2(a: &[u8; 32], b: &[[u8; 32]; 2]) -> [u32; 4] {
        // SAFETY: this kernel sits only in the AVX2 table, handed out only
        // where the CPU has AVX2; it reads the arrays alone.
        let sums = unsafe { quad(a, b) };
        sums.map(|s| s.div_ceil(2))
    }

    #[target_feature(enable = "avx2")]
    unsafe fn quad(a: &[u8; 32], b: &[[u8; 32]; 2]) -> [u32; 4] {
        let row = |r: usize| {
            let x = _mm_loadl_epi64(a.as_ptr().add(8 * r).cast());
            let y0 = _mm_loadl_epi64(b[0].as_ptr().add(8 * r).cast());
            let y1 = _mm_loadl_epi64(b[1].as_ptr().add(8 * r).cast());
            let x = _mm256_cvtepu8_epi16(_mm_unpacklo_epi64(x, x));
            // Lanes 0-7 the first pair's row, 8-15 the second's.
            let y = _mm256_cvtepu8_epi16(_mm_unpacklo_epi64(y0, y1));
            _mm256_sub_epi16(x, y)
        };
        let (r0, r1, r2, r3) = (row(0), row(1), row(2), row(3));
        // Vertical butterflies (across rows), all four tiles at once.
        let (s01, d01) = (_mm256_add_epi16(r0, r1), _mm256_sub_epi16(r0, r1));
        let (s23, d23) = (_mm256_add_epi16(r2, r3), _mm256_sub_epi16(r2, r3));
        let v0 = _mm256_add_epi16(s01, s23);
        let v1 = _mm256_sub_epi16(s01, s23);
        let v2 = _mm256_sub_epi16(d01, d23);
        let v3 = _mm256_add_epi16(d01, d23);
        // Each half's two tiles transposed into vectors holding two
        // columns of four (unpacks stay within 128-bit halves).
        let (t0, t1) = (_mm256_unpacklo_epi16(v0, v1), _mm256_unpacklo_epi16(v2, v3));
        let (t2, t3) = (_mm256_unpackhi_epi16(v0, v1), _mm256_unpackhi_epi16(v2, v3));
        let mut sums = [0u32; 4];
        for (tile, (lo, hi)) in [(t0, t1), (t2, t3)].into_iter().enumerate() {
            let c01 = _mm256_unpacklo_epi32(lo, hi);
            let c23 = _mm256_unpackhi_epi32(lo, hi);
            // Horizontal butterflies (across columns).
            let x = _mm256_unpacklo_epi64(c01, c23);
            let y = _mm256_unpackhi_epi64(c01, c23);
            let (s, d) = (_mm256_add_epi16(x, y), _mm256_sub_epi16(x, y));
            let p = _mm256_unpacklo_epi64(s, d);
            let q = _mm256_unpackhi_epi64(s, d);
            let acc = _mm256_add_epi32(abs_sum(_mm256_add_epi16(p, q)), abs_sum(_mm256_sub_epi16(p, q)));
            // Each half's four 32-bit lanes summed: the tile of that pair.
            let s = _mm256_add_epi32(acc, _mm256_shuffle_epi32::<0b01_00_11_10>(acc));
            let s = _mm256_add_epi32(s, _mm256_shuffle_epi32::<0b10_11_00_01>(s));
            sums[tile] = _mm256_cvtsi256_si32(s) as u32;
            sums[tile + 2] = _mm256_extract_epi32::<4>(s) as u32;
        }
        sums
    }

    /// 16 samples widened to 16-bit lanes.
    #[target_feature(enable = "avx2")]
    unsafe fn widen(p: *const u8) -> __m256i {
        _mm256_cvtepu8_epi16(_mm_loadu_si128(p.cast()))
    }

    /// The 4-point Hadamard transform within each group of four 16-bit
    /// lanes, lane 0 of a group the sum of the four (partners one lane,
    /// then two lanes apart).
    #[target_feature(enable = "avx2")]
    fn across_fours(x: __m256i) -> __m256i {
        let swapped = _mm256_shufflehi_epi16::<0b10_11_00_01>(_mm256_shufflelo_epi16::<0b10_11_00_01>(x));
        let x = _mm256_add_epi16(
            swapped,
            _mm256_sign_epi16(x, _mm256_set1_epi32(0xffff_0001_u32 as i32)),
        );
        let swapped = _mm256_shufflehi_epi16::<0b01_00_11_10>(_mm256_shufflelo_epi16::<0b01_00_11_10>(x));
        _mm256_add_epi16(
            swapped,
            _mm256_sign_epi16(x, _mm256_set1_epi64x(0xffff_ffff_0001_0001_u64 as i64)),
        )
    }

    /// `sum |x|` of 16-bit lanes into 32-bit lanes.
    #[target_feature(enable = "avx2")]
    fn abs_sum(x: __m256i) -> __m256i {
        _mm256_madd_epi16(_mm256_abs_epi16(x), _mm256_set1_epi16(1))
    }

    /// `sum |x - y|` of 16-bit lanes into 32-bit lanes.
    #[target_feature(enable = "avx2")]
    fn abs_diff_sum(x: __m256i, y: __m256i) -> __m256i {
        abs_sum(_mm256_sub_epi16(x, y))
    }

    /// A value in lane 0 of every group of four 16-bit lanes, 0 elsewhere.
    #[target_feature(enable = "avx2")]
    fn first_of_fours(v: i32) -> __m256i {
        _mm256_set1_epi64x(i64::from(v as i16 as u16))
    }

    #[target_feature(enable = "avx2")]
    fn lanes_sum(x: __m256i) -> u32 {
        let s = _mm_add_epi32(_mm256_castsi256_si128(x), _mm256_extracti128_si256::<1>(x));
        let s = _mm_add_epi32(s, _mm_shuffle_epi32::<0b01_00_11_10>(s));
        let s = _mm_add_epi32(s, _mm_shuffle_epi32::<0b10_11_00_01>(s));
        _mm_cvtsi128_si32(s) as u32
    }

    #[target_feature(enable = "avx2")]
    unsafe fn satd_x3(src: &[u8; 256], top: &[u8; 16], left: &[u8; 16], dc: u8) -> [u32; 3] {
        // The vertical prediction's first coefficient row, the same in
        // every row of tiles; the DC prediction's one coefficient.
        let vertical = _mm256_slli_epi16::<2>(across_fours(widen(top.as_ptr())));
        let flat = first_of_fours(16 * i32::from(dc));
        let (mut rest, mut v, mut h, mut d) = (
            _mm256_setzero_si256(),
            _mm256_setzero_si256(),
            _mm256_setzero_si256(),
            _mm256_setzero_si256(),
        );
        for tiles in 0..4 {
            let at = |r: usize| src.as_ptr().add(16 * (4 * tiles + r));
            let (r0, r1, r2, r3) = (widen(at(0)), widen(at(1)), widen(at(2)), widen(at(3)));
            let (s01, d01) = (_mm256_add_epi16(r0, r1), _mm256_sub_epi16(r0, r1));
            let (s23, d23) = (_mm256_add_epi16(r2, r3), _mm256_sub_epi16(r2, r3));
            // Rows u of the tiles' coefficients (H S H^T), four tiles side
            // by side, in the order the left column is transformed below.
            let w = [
                _mm256_add_epi16(s01, s23),
                _mm256_add_epi16(d01, d23),
                _mm256_sub_epi16(s01, s23),
                _mm256_sub_epi16(d01, d23),
            ]
            .map(|x| across_fours(x));
            let l = &left[4 * tiles..4 * tiles + 4];
            let [l0, l1, l2, l3] = [0, 1, 2, 3].map(|k| i32::from(l[k]));
            let column = [
                l0 + l1 + l2 + l3,
                l0 - l1 + l2 - l3,
                l0 + l1 - l2 - l3,
                l0 - l1 - l2 + l3,
            ]
            .map(|c| first_of_fours(4 * c));
            // Rows 1-3 are the same in the vertical and DC predictions'
            // SATD: summed once (three magnitudes, at most 12240 a lane).
            let rows_1_to_3 = _mm256_add_epi16(_mm256_abs_epi16(w[1]), abs_add(w[2], w[3]));
            rest = _mm256_add_epi32(rest, _mm256_madd_epi16(rows_1_to_3, _mm256_set1_epi16(1)));
            v = _mm256_add_epi32(v, abs_diff_sum(w[0], vertical));
            d = _mm256_add_epi32(d, abs_diff_sum(w[0], flat));
            for u in 0..4 {
                h = _mm256_add_epi32(h, abs_diff_sum(w[u], column[u]));
            }
        }
        let rest = lanes_sum(rest);
        [
            (lanes_sum(v) + rest).div_ceil(2),
            lanes_sum(h).div_ceil(2),
            (lanes_sum(d) + rest).div_ceil(2),
        ]
    }

    /// `|a| + |b|` in 16-bit lanes (coefficients of at most 4080 each).
    #[target_feature(enable = "avx2")]
    fn abs_add(a: __m256i, b: __m256i) -> __m256i {
        _mm256_add_epi16(_mm256_abs_epi16(a), _mm256_abs_epi16(b))
    }
}
