//! Motion compensation kernels (normative: FORMAT.md section 10): the
//! quarter-pel 8-tap luma filter and the eighth-pel bilinear chroma
//! filter over a block whose samples are all in the slice given (the
//! callers in [`crate::interp`] find them in the reference's border).

use super::PerLevel;

/// A luma filter's taps for phases 0, 1/4, 1/2, 3/4; each sums to 64.
/// Tap `k` applies to the sample at offset `k - 3`.
pub type LumaTaps = [[i32; 8]; 4];

/// The sharp luma filter: HEVC's 8-tap DCT-based interpolation.
pub const LUMA_TAPS: LumaTaps = [
    [0, 0, 0, 64, 0, 0, 0, 0],
    [-1, 4, -10, 58, 17, -5, 1, 0],
    [-1, 4, -11, 40, 40, -11, 4, -1],
    [0, 1, -5, 17, 58, -10, 4, -1],
];

/// The smooth luma filter: H.264's 6-tap half-pel filter (1, -5, 20, 20,
/// -5, 1) / 32, and its quarter-pel positions as the mean of the half-pel
/// and the nearest whole sample, here in one filter (no rounding between).
/// It passes less of the highest frequencies than [`LUMA_TAPS`]: the
/// better prediction of camera noise and motion blur.
pub const SMOOTH_LUMA_TAPS: LumaTaps = [
    [0, 0, 0, 64, 0, 0, 0, 0],
    [0, 1, -5, 52, 20, -5, 1, 0],
    [0, 2, -10, 40, 40, -10, 2, 0],
    [0, 1, -5, 20, 52, -5, 1, 0],
];

/// Largest block the kernels accept, per side.
pub const MAX_BLOCK: usize = 64;

/// Samples the 8-tap filter reads before the block (and 4 after).
pub const TAPS_BEFORE: usize = 3;

/// A luma prediction: `(taps, src, stride, (fx, fy), (w, h), out,
/// out_stride)`, the `w x h` block at quarter-pel phase (fx, fy) of the
/// filter `taps` (every product of a sample and a tap, and every partial
/// sum, fits 16 bits; [`LUMA_TAPS`] and [`SMOOTH_LUMA_TAPS`] do) whose samples start
/// [`TAPS_BEFORE`] rows above and columns left of `src[0]`'s block corner
/// (the slice holds the block and the filter's reach: h + 7 rows of w + 7).
pub type LumaFn = fn(&LumaTaps, &[u8], usize, (usize, usize), (usize, usize), &mut [u8], usize);

/// A chroma prediction: `(src, stride, (fx, fy), (w, h), out, out_stride)`,
/// the `w x h` block at eighth-pel phase (fx, fy) whose top-left integer
/// sample is `src[0]` (the slice holds h + 1 rows of w + 1).
pub type ChromaFn = fn(&[u8], usize, (usize, usize), (usize, usize), &mut [u8], usize);

/// The motion compensation kernels of one CPU level.
#[derive(Debug, Clone, Copy)]
pub struct McDsp {
    /// Luma quarter-pel prediction.
    pub luma: LumaFn,
    /// Chroma eighth-pel prediction.
    pub chroma: ChromaFn,
}

/// The scalar kernels.
const SCALAR: McDsp = McDsp {
    luma: luma_scalar,
    chroma: chroma_body,
};

/// The tables, lowest level first.
pub static MC: PerLevel<McDsp> = PerLevel([
    SCALAR,
    SCALAR,
    #[cfg(target_arch = "x86_64")]
    McDsp {
        luma: avx2::luma,
        chroma: avx2::chroma,
    },
    #[cfg(not(target_arch = "x86_64"))]
    SCALAR,
]);

/// The kernels of the CPU level in force.
#[inline]
pub fn mc() -> &'static McDsp {
    MC.get()
}

fn luma_scalar(
    taps: &LumaTaps,
    src: &[u8],
    stride: usize,
    phase: (usize, usize),
    size: (usize, usize),
    out: &mut [u8],
    os: usize,
) {
    // SAFETY: AVX2 off.
    unsafe { luma_body::<false>(taps, src, stride, phase, size, out, os) }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    crate::compiled_for! { "avx2":
        fn luma(taps: &super::LumaTaps, src: &[u8], stride: usize, phase: (usize, usize), size: (usize, usize), out: &mut [u8], os: usize)
            => super::luma_body::<true>;
        fn chroma_any(src: &[u8], stride: usize, phase: (usize, usize), size: (usize, usize), out: &mut [u8], os: usize)
            => super::chroma_body;
    }

    /// The AVX2 [`super::ChromaFn`]: blocks 8 wide (a macroblock's) in
    /// intrinsics, other widths as the scalar body compiled for AVX2.
    pub(super) fn chroma(
        src: &[u8],
        stride: usize,
        phase: (usize, usize),
        (w, h): (usize, usize),
        out: &mut [u8],
        os: usize,
    ) {
        if w != 8 || h == 0 {
            return chroma_any(src, stride, phase, (w, h), out, os);
        }
        assert!(
            src.len() >= h * stride + 9 && out.len() >= (h - 1) * os + 8,
            "an 8-wide chroma block past its slices"
        );
        // SAFETY: this kernel sits only in the AVX2 table, handed out only
        // where the CPU has AVX2; the rows it reads and writes were
        // checked above.
        unsafe { super::x86::chroma8_avx2(src, stride, phase, h, out, os) }
    }
}

/// The luma predictor, for any instruction set; `AVX2` takes the 16x16
/// vertical pass to AVX2 intrinsics.
///
/// # Safety
/// `AVX2` is true only where the CPU has AVX2.
#[inline(always)]
unsafe fn luma_body<const AVX2: bool>(
    taps: &LumaTaps,
    data: &[u8],
    stride: usize,
    (fx, fy): (usize, usize),
    (w, h): (usize, usize),
    out: &mut [u8],
    out_stride: usize,
) {
    const B: usize = TAPS_BEFORE;
    if w == 16 && h == 16 && (fx, fy) != (0, 0) {
        // The macroblock case, with sizes the compiler knows; written in
        // place where `out` is a macroblock's 16x16 block.
        if out_stride == 16 {
            if let Some(block) = out.first_chunk_mut::<256>() {
                // SAFETY: this function's contract passes on.
                luma_16x16::<AVX2>(taps, data, stride, fx, fy, block);
                return;
            }
        }
        let mut block = [0u8; 256];
        // SAFETY: this function's contract passes on.
        luma_16x16::<AVX2>(taps, data, stride, fx, fy, &mut block);
        for r in 0..16 {
            out[r * out_stride..][..16].copy_from_slice(&block[r * 16..][..16]);
        }
        return;
    }
    match (fx, fy) {
        (0, 0) => {
            // A whole-sample block is a copy: rows of the macroblock's or
            // a partition's width with a length the compiler knows (moves,
            // not a memcpy call a row).
            let row = |r: usize| (r + B) * stride + B;
            match w {
                16 => (0..h).for_each(|r| out[r * out_stride..][..16].copy_from_slice(&data[row(r)..][..16])),
                8 => (0..h).for_each(|r| out[r * out_stride..][..8].copy_from_slice(&data[row(r)..][..8])),
                _ => (0..h).for_each(|r| out[r * out_stride..][..w].copy_from_slice(&data[row(r)..][..w])),
            }
        }
        (_, 0) => {
            let taps = &taps[fx];
            let mut acc = [0i32; MAX_BLOCK];
            for r in 0..h {
                let src = (r + B) * stride;
                filter_row(taps, |k| &data[src + k..src + k + w], &mut acc[..w]);
                round_into(&acc[..w], 6, &mut out[r * out_stride..r * out_stride + w]);
            }
        }
        (0, _) => {
            let taps = &taps[fy];
            let mut acc = [0i32; MAX_BLOCK];
            for r in 0..h {
                let src = r * stride + B;
                filter_row(
                    taps,
                    |k| &data[src + k * stride..src + k * stride + w],
                    &mut acc[..w],
                );
                round_into(&acc[..w], 6, &mut out[r * out_stride..r * out_stride + w]);
            }
        }
        _ => luma_2d(taps, data, stride, (fx, fy), (w, h), out, out_stride),
    }
}

/// A two-dimensional luma phase of a `w x h` block whose taps start at
/// `data[0]`: a horizontal pass over h + 7 rows at full precision (it fits
/// 16 bits: -6120..=22440 with either filter), then vertical. Inlined into both of
/// [`luma_body`]'s instances.
#[inline(always)]
fn luma_2d(
    taps: &LumaTaps,
    data: &[u8],
    stride: usize,
    (fx, fy): (usize, usize),
    (w, h): (usize, usize),
    out: &mut [u8],
    out_stride: usize,
) {
    // Small blocks, the common case, use a small buffer, not cleared
    // first (a 736-byte memset a call): every sample is written below.
    let rows = h + 7;
    let mut small = [std::mem::MaybeUninit::<i16>::uninit(); 16 * 23];
    let mut large = Vec::new();
    let tmp = if w * rows <= small.len() {
        &mut small[..w * rows]
    } else {
        large.resize(w * rows, std::mem::MaybeUninit::new(0));
        &mut large[..]
    };
    let (th, tv) = (&taps[fx], &taps[fy]);
    let mut acc = [0i32; MAX_BLOCK];
    for r in 0..rows {
        let src = r * stride;
        filter_row(th, |k| &data[src + k..src + k + w], &mut acc[..w]);
        for (t, &a) in tmp[r * w..(r + 1) * w].iter_mut().zip(&acc[..w]) {
            t.write(a as i16);
        }
    }
    // SAFETY: rows 0..rows of w samples each, all of `tmp`, were written
    // above; `MaybeUninit<i16>` has `i16`'s layout.
    let tmp = unsafe { &*(tmp as *const [std::mem::MaybeUninit<i16>] as *const [i16]) };
    let mut acc = [0i32; MAX_BLOCK];
    for r in 0..h {
        let acc = &mut acc[..w];
        acc.fill(0);
        for (k, &t) in tv.iter().enumerate() {
            if t != 0 {
                for (a, &v) in acc.iter_mut().zip(&tmp[(r + k) * w..(r + k + 1) * w]) {
                    *a += t * i32::from(v);
                }
            }
        }
        for a in acc.iter_mut() {
            *a >>= 6;
        }
        round_into(acc, 6, &mut out[r * out_stride..r * out_stride + w]);
    }
}

const N16: usize = 16;

/// Row `r` of a 16x16 block's neighbourhood: 16 + 7 samples.
#[inline(always)]
fn row23(data: &[u8], stride: usize, r: usize) -> &[u8; N16 + 7] {
    let s = &data[r * stride..r * stride + N16 + 7];
    s.try_into().unwrap_or(&[0; N16 + 7])
}

/// The horizontal 8-tap filter of 16 samples, full precision, in 16-bit
/// lanes (twice as many a vector as 32-bit ones): every product and
/// partial sum of 8-bit samples with either filter's taps lies within
/// -6120..=22440.
#[inline(always)]
fn hpass16(r: &[u8; N16 + 7], taps: &[i32; 8]) -> [i16; N16] {
    let mut acc = [0i16; N16];
    for (k, &t) in taps.iter().enumerate() {
        let s = &r[k..k + N16];
        let t = t as i16;
        for (a, &v) in acc.iter_mut().zip(s) {
            *a += t * i16::from(v);
        }
    }
    acc
}

/// `clip((acc + 32) >> 6)` of 16 values.
#[inline(always)]
fn round16<T: Copy + Into<i32>>(acc: &[T; N16], o: &mut [u8]) {
    for (o, &a) in o.iter_mut().zip(acc) {
        *o = ((a.into() + 32) >> 6).clamp(0, 255) as u8;
    }
}

/// A 16x16 luma prediction at phase (fx, fy), not both 0, from `data`
/// starting 3 rows above and 3 columns left of the block. (Functions, not
/// closures: closures do not inherit the caller's target features.)
#[inline(always)]
unsafe fn luma_16x16<const AVX2: bool>(
    taps: &LumaTaps,
    data: &[u8],
    stride: usize,
    fx: usize,
    fy: usize,
    out: &mut [u8; 256],
) {
    const N: usize = N16;
    const B: usize = TAPS_BEFORE;
    #[cfg(target_arch = "x86_64")]
    if AVX2 && fx != 0 {
        let rows = if fy == 0 { N } else { N + 7 };
        let first = if fy == 0 { B } else { 0 };
        // Not cleared first (a 736-byte memset a call): the pass writes
        // every row it returns.
        let mut tmp = [std::mem::MaybeUninit::<[i16; N]>::uninit(); N + 7];
        // SAFETY: the caller's contract: AVX2 only where the CPU has it.
        let tmp = unsafe { x86::hpass16_rows(data, stride, first, &taps[fx], &mut tmp[..rows]) };
        if let Ok(all) = <&[[i16; N]; N + 7]>::try_from(&*tmp) {
            // SAFETY: the caller's contract: AVX2 only where the CPU has it.
            unsafe { x86::vpass16_avx2(all, &taps[fy], out) };
        } else {
            for (r, acc) in tmp.iter().enumerate() {
                round16(acc, &mut out[r * N..(r + 1) * N]);
            }
        }
        return;
    }
    if fy == 0 {
        for r in 0..N {
            let acc = hpass16(row23(data, stride, r + B), &taps[fx]);
            round16(&acc, &mut out[r * N..(r + 1) * N]);
        }
        return;
    }
    // Not cleared first (a 736-byte memset a call): each row is written.
    let mut rows = [std::mem::MaybeUninit::<[i16; N]>::uninit(); N + 7];
    for (r, t) in rows.iter_mut().enumerate() {
        let src = row23(data, stride, r);
        if fx == 0 {
            // Scaled by 64 (at most 16320: still 16 bits) so that one
            // vertical pass serves both cases; its >> 6 below is then
            // exact, as the direct vertical filter's single rounding needs.
            t.write(std::array::from_fn(|c| i16::from(src[B + c]) << 6));
        } else {
            t.write(hpass16(src, &taps[fx]));
        }
    }
    // SAFETY: every row was written above; `MaybeUninit<T>` has `T`'s
    // layout.
    let tmp =
        unsafe { &*(&rows as *const [std::mem::MaybeUninit<[i16; N]>; N + 7] as *const [[i16; N]; N + 7]) };
    let tv = &taps[fy];
    #[cfg(target_arch = "x86_64")]
    if AVX2 {
        // SAFETY: the caller's contract: AVX2 only where the CPU has it.
        unsafe { x86::vpass16_avx2(tmp, tv, out) };
        return;
    }
    for (r, window) in tmp.windows(8).enumerate() {
        let mut acc = [0i32; N];
        for (&t, row) in tv.iter().zip(window) {
            for (a, &v) in acc.iter_mut().zip(row) {
                *a += t * i32::from(v);
            }
        }
        for a in acc.iter_mut() {
            *a >>= 6;
        }
        round16(&acc, &mut out[r * N..(r + 1) * N]);
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;
    use std::mem::MaybeUninit;

    use super::N16;

    /// An 8-wide bilinear chroma block, a row at a time: each source row's
    /// samples paired with their right neighbours (two 8-byte loads,
    /// interleaved) and weighed by one `pmaddubsw` for the row below it
    /// and one for the row above (weights at most 64, sums at most
    /// 64 * 255: exact in 16 bits, as the scalar body).
    ///
    /// # Safety
    /// AVX2 is there; `src` holds `h + 1` rows of 9 samples `stride`
    /// apart and `out` `h` rows of 8, `os` apart.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn chroma8_avx2(
        src: &[u8],
        stride: usize,
        (fx, fy): (usize, usize),
        h: usize,
        out: &mut [u8],
        os: usize,
    ) {
        let weights = |left: usize, right: usize| _mm_set1_epi16(((right << 8) | left) as i16);
        let top = weights((8 - fx) * (8 - fy), fx * (8 - fy));
        let below = weights((8 - fx) * fy, fx * fy);
        let round = _mm_set1_epi16(32);
        // SAFETY (the loads and stores): the caller's contract.
        let pairs = |r: usize| unsafe {
            let p = src.as_ptr().add(r * stride);
            _mm_unpacklo_epi8(
                _mm_loadl_epi64(p as *const __m128i),
                _mm_loadl_epi64(p.add(1) as *const __m128i),
            )
        };
        let mut upper = pairs(0);
        for r in 0..h {
            let lower = pairs(r + 1);
            let sum = _mm_add_epi16(_mm_maddubs_epi16(upper, top), _mm_maddubs_epi16(lower, below));
            let v = _mm_srli_epi16::<6>(_mm_add_epi16(sum, round));
            // SAFETY: the caller's contract.
            unsafe {
                _mm_storel_epi64(
                    out.as_mut_ptr().add(r * os) as *mut __m128i,
                    _mm_packus_epi16(v, v),
                )
            };
            upper = lower;
        }
    }

    /// The `pshufb` masks of [`hpass16_rows`], for the pairs of taps 0-1,
    /// 2-3, 4-5 and 6-7: output i (of 8 a 128-bit lane) needs samples
    /// i + k and i + k + 1 for the pair of taps k, k + 1. The upper lane
    /// holds the row from sample 7 on (its outputs 8-15: offsets one
    /// further), so that no load reads past the row's 23 samples.
    const HPASS_SHUFFLES: [[u8; 32]; 4] = {
        let mut masks = [[0u8; 32]; 4];
        let mut p = 0;
        while p < 4 {
            let mut j = 0;
            while j < 32 {
                let lane_base = if j < 16 { 0 } else { 1 };
                let jj = j % 16;
                masks[p][j] = (lane_base + 2 * p + jj / 2 + jj % 2) as u8;
                j += 1;
            }
            p += 1;
        }
        masks
    };

    /// The horizontal 8-tap pass of `out.len()` rows of a 16x16
    /// prediction, from row `first` of `data` on (each row 16 + 7
    /// samples), at full precision as the scalar [`super::hpass16`]:
    /// `out`, every row written.
    ///
    /// # Safety
    /// AVX2 is there.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn hpass16_rows<'o>(
        data: &[u8],
        stride: usize,
        first: usize,
        taps: &[i32; 8],
        out: &'o mut [MaybeUninit<[i16; N16]>],
    ) -> &'o mut [[i16; N16]] {
        let Some(last) = (first + out.len()).checked_sub(1) else {
            return &mut [];
        };
        assert!(
            data.len() >= last * stride + N16 + 7,
            "rows {first}..={last} of 23 samples past the slice"
        );
        // The taps in pairs, one signed byte each (each fits: -11..=58),
        // for `pmaddubsw` against pairs of neighbouring samples.
        let pair = |k: usize| _mm256_set1_epi16(((taps[k + 1] << 8) | (taps[k] & 0xff)) as i16);
        let coef = [pair(0), pair(2), pair(4), pair(6)];
        // SAFETY: each mask is 32 bytes; unaligned loads.
        let masks = HPASS_SHUFFLES.map(|m| unsafe { _mm256_loadu_si256(m.as_ptr() as *const __m256i) });
        for (r, o) in out.iter_mut().enumerate() {
            let at = (first + r) * stride;
            // SAFETY: bytes at..at + 16 and at + 7..at + 23 lie in `data`
            // (asserted above); unaligned loads.
            let row = unsafe {
                let p = data.as_ptr().add(at);
                _mm256_loadu2_m128i(p.add(7) as *const __m128i, p as *const __m128i)
            };
            let mut acc = _mm256_setzero_si256();
            for (m, c) in masks.iter().zip(&coef) {
                // Each pair's sum lies within -2805..=14790 (no
                // saturation), every partial total within 255 times the
                // negative and the positive taps' sums, -6120..=22440.
                acc = _mm256_add_epi16(acc, _mm256_maddubs_epi16(_mm256_shuffle_epi8(row, *m), *c));
            }
            // SAFETY: `o` is 16 i16 = 32 bytes; unaligned store.
            unsafe { _mm256_storeu_si256(o.as_mut_ptr() as *mut __m256i, acc) };
        }
        // SAFETY: every row was written above; `MaybeUninit<T>` has `T`'s
        // layout.
        unsafe { std::slice::from_raw_parts_mut(out.as_mut_ptr() as *mut [i16; N16], out.len()) }
    }

    /// The vertical 8-tap pass of a 16x16 prediction from its 23 rows of
    /// 16-bit first-pass values: taps in pairs, each pair one `pmaddwd` of
    /// two interleaved rows (exact 32-bit sums, as the scalar pass), then
    /// `>> 6`, `(v + 32) >> 6` and saturation to 8 bits.
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn vpass16_avx2(tmp: &[[i16; N16]; N16 + 7], taps: &[i32; 8], out: &mut [u8; 256]) {
        let pair = |k: usize| _mm256_set1_epi32((taps[k + 1] << 16) | (taps[k] & 0xffff));
        let coef = [pair(0), pair(2), pair(4), pair(6)];
        let round = _mm256_set1_epi32(32);
        // Rows loaded where used (from L1), not gathered into an array of
        // 23 vectors first: more than the registers hold, that array was a
        // 736-byte copy of `tmp` on the stack every call.
        let rows = tmp.as_ptr() as *const __m256i;
        for (r, o) in out.chunks_exact_mut(N16).enumerate() {
            let (mut lo, mut hi) = (_mm256_setzero_si256(), _mm256_setzero_si256());
            for (p, c) in coef.iter().enumerate() {
                // SAFETY: rows r + 2p and r + 2p + 1 are at most row 22 of
                // tmp's 23 rows of 16 i16 (32 bytes each); unaligned loads.
                let (a, b) = unsafe {
                    (
                        _mm256_loadu_si256(rows.add(r + 2 * p)),
                        _mm256_loadu_si256(rows.add(r + 2 * p + 1)),
                    )
                };
                lo = _mm256_add_epi32(lo, _mm256_madd_epi16(_mm256_unpacklo_epi16(a, b), *c));
                hi = _mm256_add_epi32(hi, _mm256_madd_epi16(_mm256_unpackhi_epi16(a, b), *c));
            }
            let finish =
                |v: __m256i| _mm256_srai_epi32::<6>(_mm256_add_epi32(_mm256_srai_epi32::<6>(v), round));
            // Within each 128-bit lane: lo holds columns 0-3 (8-11), hi 4-7
            // (12-15), so the packs restore column order per lane.
            let words = _mm256_packs_epi32(finish(lo), finish(hi));
            let bytes = _mm256_packus_epi16(words, words);
            let row = _mm256_permute4x64_epi64::<0b00_00_10_00>(bytes);
            // SAFETY: `o` is 16 bytes.
            unsafe { _mm_storeu_si128(o.as_mut_ptr() as *mut __m128i, _mm256_castsi256_si128(row)) };
        }
    }
}

/// `acc[c] = sum_k taps[k] * row(k)[c]` over the 8 taps (zero taps
/// skipped); written tap-outer so that the compiler vectorises it.
#[inline(always)]
fn filter_row<'a>(taps: &[i32; 8], row: impl Fn(usize) -> &'a [u8], acc: &mut [i32]) {
    acc.fill(0);
    for (k, &t) in taps.iter().enumerate() {
        if t != 0 {
            for (a, &v) in acc.iter_mut().zip(row(k)) {
                *a += t * i32::from(v);
            }
        }
    }
}

/// `out = clip((acc + 2^(shift-1)) >> shift)`.
#[inline(always)]
fn round_into(acc: &[i32], shift: u32, out: &mut [u8]) {
    let half = 1 << (shift - 1);
    for (o, &a) in out.iter_mut().zip(acc) {
        *o = ((a + half) >> shift).clamp(0, 255) as u8;
    }
}

/// The chroma predictor, for any instruction set.
#[inline(always)]
fn chroma_body(
    data: &[u8],
    stride: usize,
    (fx, fy): (usize, usize),
    (w, h): (usize, usize),
    out: &mut [u8],
    out_stride: usize,
) {
    // Weights at most 64 and a sum at most 64 * 255: 16 bits suffice.
    let (wa, wb, wc, wd) = (
        ((8 - fx) * (8 - fy)) as u16,
        (fx * (8 - fy)) as u16,
        ((8 - fx) * fy) as u16,
        (fx * fy) as u16,
    );
    if w == 8 {
        // The macroblock case, with a width the compiler knows: one vector
        // of eight 16-bit lanes a row.
        for r in 0..h {
            let src = r * stride;
            let row = |at: usize| -> [u16; 9] {
                let s = &data[at..at + 9];
                std::array::from_fn(|i| u16::from(s[i]))
            };
            let (top, below) = (row(src), row(src + stride));
            let o = &mut out[r * out_stride..r * out_stride + 8];
            for c in 0..8 {
                let s = wa * top[c] + wb * top[c + 1] + wc * below[c] + wd * below[c + 1];
                o[c] = ((s + 32) >> 6) as u8;
            }
        }
        return;
    }
    for r in 0..h {
        let src = r * stride;
        let (top, below) = (&data[src..src + w + 1], &data[src + stride..src + stride + w + 1]);
        let o = &mut out[r * out_stride..r * out_stride + w];
        for (c, o) in o.iter_mut().enumerate() {
            let s = wa * u16::from(top[c])
                + wb * u16::from(top[c + 1])
                + wc * u16::from(below[c])
                + wd * u16::from(below[c + 1]);
            *o = ((s + 32) >> 6) as u8;
        }
    }
}
