//! The intra prediction kernels (normative: FORMAT.md section 9): the
//! 16x16 and chroma modes, the nine 4x4 modes and the nine 8x8 modes
//! (from edges already smoothed), with the mode and edge types they take.
//! The AVX2 builds are the scalar source compiled for AVX2 (integer
//! arithmetic: the same samples), but for the paired 4x4 gathers, which
//! are byte shuffles in intrinsics.

use super::PerLevel;

/// A 16x16 or chroma prediction: `(mode, neighbours, out, stride)`.
pub type PredBlockFn = fn(IntraMode, &Neighbours<'_>, &mut [u8], usize);

/// A 4x4 prediction: `(mode, edges, out)`, the mode's edges present.
pub type Pred4x4Fn = fn(Intra4x4Mode, &Edges, &mut [u8; 16]);

/// An 8x8 prediction from filtered edges: `(mode, edges, out)`.
pub type Pred8x8Fn = fn(Intra4x4Mode, &Edges8, &mut [u8; 64]);

/// Two 4x4 modes gathered from a block's [`ModeSource4`] side by side:
/// `(source, a, b, out)`, `out` in rows of eight samples, `a`'s four then
/// `b`'s (the layout of a paired 4x4 SATD).
pub type Pred4x4PairFn = fn(&ModeSource4, Intra4x4Mode, Intra4x4Mode, &mut [u8; 32]);

/// One 8x8 mode gathered from a block's [`ModeSource`]: `(source, mode,
/// out)`, `out` row-major (an encoder trying the nine modes builds the
/// source once).
pub type Pred8x8GatherFn = fn(&ModeSource, Intra4x4Mode, &mut [u8; 64]);

/// The intra prediction kernels of one CPU level.
#[derive(Debug, Clone, Copy)]
pub struct IpredDsp {
    /// 16x16 luma modes.
    pub pred_16x16: PredBlockFn,
    /// 8x8 chroma modes (the 16x16 modes' rules at size 8).
    pub pred_8x8_chroma: PredBlockFn,
    /// The nine 4x4 modes.
    pub pred_4x4: Pred4x4Fn,
    /// The nine 8x8 modes.
    pub pred_8x8: Pred8x8Fn,
    /// Two of a 4x4 block's modes at once, for an encoder trying them.
    pub pred_4x4_pair: Pred4x4PairFn,
    /// One of an 8x8 block's modes from its source.
    pub pred_8x8_gather: Pred8x8GatherFn,
}

const SCALAR: IpredDsp = IpredDsp {
    pred_16x16: predict_sized::<16>,
    pred_8x8_chroma: predict_sized::<8>,
    pred_4x4,
    pred_8x8,
    pred_4x4_pair,
    pred_8x8_gather,
};

/// The tables, lowest level first.
pub static IPRED: PerLevel<IpredDsp> = PerLevel([
    SCALAR,
    SCALAR,
    #[cfg(target_arch = "x86_64")]
    IpredDsp {
        // The AVX2 build of the 16x16 modes ran slower (plane: 51 against
        // 40 ns, `cargo bench --bench dsp -- dsp_ipred`): scalar.
        pred_16x16: predict_sized::<16>,
        pred_8x8_chroma: avx2::pred_8x8_chroma,
        // Its AVX2 build ran 25 % more instructions (the modes' per-sample
        // formulas do not vectorise): the scalar one at every level.
        pred_4x4,
        // The source built by the scalar source compiled for AVX2, each
        // mode a byte shuffle from it (the decoder's blocks too).
        pred_8x8: avx2::pred_8x8,
        // A byte shuffle a mode instead of sixteen indexed loads: with it
        // ultrafast ran 0.982x the instructions on dog_1080p over 10
        // frames (`benches/instructions.py`; the I frame's 4x4 search).
        pred_4x4_pair: avx2::pred_4x4_pair,
        // The same for 8x8 blocks: 64 indexed loads a mode were 1.8 % of
        // medium's instructions on diver_vga.
        pred_8x8_gather: avx2::pred_8x8_gather,
    },
    #[cfg(not(target_arch = "x86_64"))]
    SCALAR,
]);

/// The kernels of the CPU level in force.
#[inline]
pub fn ipred() -> &'static IpredDsp {
    IPRED.get()
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::{Edges8, Intra4x4Mode, IntraMode, ModeSource, ModeSource4, Neighbours};
    crate::compiled_for! { "avx2":
        fn pred_8x8_chroma(mode: IntraMode, n: &Neighbours<'_>, out: &mut [u8], stride: usize) => super::predict_sized::<8>;
        fn mode_source(e: &Edges8) -> ModeSource => ModeSource::new;
    }

    /// The AVX2 [`super::Pred8x8Fn`]: the block's source, then its mode's
    /// gather.
    pub(super) fn pred_8x8(mode: Intra4x4Mode, e: &Edges8, out: &mut [u8; 64]) {
        pred_8x8_gather(&mode_source(e), mode, out)
    }

    /// The AVX2 [`super::Pred8x8GatherFn`].
    pub(super) fn pred_8x8_gather(source: &ModeSource, mode: Intra4x4Mode, out: &mut [u8; 64]) {
        // SAFETY: this kernel sits only in the AVX2 table, handed out only
        // where the CPU has AVX2.
        unsafe { super::x86::pred_8x8_gather_avx2(&source.0, mode as usize, out) }
    }

    /// The AVX2 [`super::Pred4x4PairFn`].
    pub(super) fn pred_4x4_pair(source: &ModeSource4, a: Intra4x4Mode, b: Intra4x4Mode, out: &mut [u8; 32]) {
        // SAFETY: this kernel sits only in the AVX2 table, handed out only
        // where the CPU has AVX2 (and so SSSE3's byte shuffle).
        unsafe { super::x86::pred_4x4_pair_avx2(&source.0, a as usize, b as usize, out) }
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    use super::{MODE_SHUFFLE4, MODE_SHUFFLE8, SOURCE4_STORE, SOURCE_STORE};

    /// Mode `m` of an 8x8 block, row-major, from its source's five
    /// 16-byte chunks, each in both halves of a register: each half of
    /// the output shuffled from every chunk by the mode's masks (lanes
    /// taken from other chunks zeroed) and OR-ed.
    ///
    /// # Safety
    /// AVX2 is there; `m` is a mode's code (below 9).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn pred_8x8_gather_avx2(source: &[u8; SOURCE_STORE], m: usize, out: &mut [u8; 64]) {
        let p = source.as_ptr() as *const __m128i;
        let mut chunks = [_mm256_setzero_si256(); SOURCE_STORE / 16];
        for (k, chunk) in chunks.iter_mut().enumerate() {
            // SAFETY: the source holds five chunks of 16 bytes.
            *chunk = _mm256_broadcastsi128_si256(unsafe { _mm_loadu_si128(p.add(k)) });
        }
        let o = out.as_mut_ptr() as *mut __m256i;
        for (half, masks) in MODE_SHUFFLE8[m].iter().enumerate() {
            let mut v = _mm256_setzero_si256();
            for (chunk, mask) in chunks.iter().zip(masks) {
                // SAFETY: a mask is 32 bytes.
                let mask = unsafe { _mm256_loadu_si256(mask.as_ptr() as *const __m256i) };
                v = _mm256_or_si256(v, _mm256_shuffle_epi8(*chunk, mask));
            }
            // SAFETY: `out` holds two halves of 32 bytes.
            unsafe { _mm256_storeu_si256(o.add(half), v) };
        }
    }

    /// Mode `m` of a 4x4 block, row-major, from its source's three
    /// 16-byte `chunks`: each chunk shuffled by the mode's mask for it
    /// (lanes taken from other chunks zeroed) and the three OR-ed.
    ///
    /// # Safety
    /// AVX2 is there; `m` is a mode's code (below 9).
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn gather(chunks: &[__m128i; 3], m: usize) -> __m128i {
        let masks = &MODE_SHUFFLE4[m];
        let mut v = _mm_setzero_si128();
        for (chunk, mask) in chunks.iter().zip(masks) {
            // SAFETY: a mask is 16 bytes.
            let mask = unsafe { _mm_loadu_si128(mask.as_ptr() as *const __m128i) };
            v = _mm_or_si128(v, _mm_shuffle_epi8(*chunk, mask));
        }
        v
    }

    /// Modes `a` and `b` from `source` in rows of eight: the two
    /// row-major blocks interleaved a row (32 bits) at a time.
    ///
    /// # Safety
    /// AVX2 is there; `a` and `b` are modes' codes (below 9).
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn pred_4x4_pair_avx2(
        source: &[u8; SOURCE4_STORE],
        a: usize,
        b: usize,
        out: &mut [u8; 32],
    ) {
        let p = source.as_ptr() as *const __m128i;
        // SAFETY: the source holds three chunks of 16 bytes.
        let chunks = unsafe {
            [
                _mm_loadu_si128(p),
                _mm_loadu_si128(p.add(1)),
                _mm_loadu_si128(p.add(2)),
            ]
        };
        // SAFETY: the caller's contract.
        let (va, vb) = unsafe { (gather(&chunks, a), gather(&chunks, b)) };
        let o = out.as_mut_ptr() as *mut __m128i;
        // SAFETY: `out` holds two chunks of 16 bytes.
        unsafe {
            _mm_storeu_si128(o, _mm_unpacklo_epi32(va, vb));
            _mm_storeu_si128(o.add(1), _mm_unpackhi_epi32(va, vb));
        }
    }
}

/// An intra prediction mode; the value is its code in the bitstream.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum IntraMode {
    /// Copy the row above.
    Vertical = 0,
    /// Copy the column to the left.
    Horizontal = 1,
    /// Mean of the neighbours.
    Dc = 2,
    /// A plane fitted to the neighbours.
    Plane = 3,
}

impl IntraMode {
    /// All modes, in code order.
    pub const ALL: [IntraMode; 4] = [
        IntraMode::Vertical,
        IntraMode::Horizontal,
        IntraMode::Dc,
        IntraMode::Plane,
    ];

    /// The mode with this code, if any.
    pub fn from_code(code: u32) -> Option<IntraMode> {
        IntraMode::ALL.get(code as usize).copied()
    }

    /// Whether the neighbours this mode needs are available.
    pub fn is_available(self, n: &Neighbours<'_>) -> bool {
        match self {
            IntraMode::Vertical => n.top.is_some(),
            IntraMode::Horizontal => n.left.is_some(),
            IntraMode::Dc => true,
            IntraMode::Plane => n.top.is_some() && n.left.is_some() && n.top_left.is_some(),
        }
    }
}

/// The reconstructed samples around a block.
#[derive(Debug, Clone, Copy, Default)]
pub struct Neighbours<'a> {
    /// The row above, as wide as the block.
    pub top: Option<&'a [u8]>,
    /// The column to the left, as tall as the block.
    pub left: Option<&'a [u8]>,
    /// The sample above-left.
    pub top_left: Option<u8>,
}

/// A 4x4 intra prediction mode; the value is its code (H.264's numbering).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Intra4x4Mode {
    /// Copy the row above.
    Vertical = 0,
    /// Copy the column to the left.
    Horizontal = 1,
    /// Mean of the neighbours.
    Dc = 2,
    /// Along the 45-degree diagonal down and to the left (from above and above right).
    DiagonalDownLeft = 3,
    /// Along the diagonal down and to the right.
    DiagonalDownRight = 4,
    /// Steeply down and to the right.
    VerticalRight = 5,
    /// Shallowly down and to the right.
    HorizontalDown = 6,
    /// Steeply down and to the left.
    VerticalLeft = 7,
    /// Shallowly up and to the right (from the left column).
    HorizontalUp = 8,
}

impl Intra4x4Mode {
    /// All modes, in code order.
    pub const ALL: [Intra4x4Mode; 9] = [
        Intra4x4Mode::Vertical,
        Intra4x4Mode::Horizontal,
        Intra4x4Mode::Dc,
        Intra4x4Mode::DiagonalDownLeft,
        Intra4x4Mode::DiagonalDownRight,
        Intra4x4Mode::VerticalRight,
        Intra4x4Mode::HorizontalDown,
        Intra4x4Mode::VerticalLeft,
        Intra4x4Mode::HorizontalUp,
    ];

    /// The mode with this code, if any.
    pub fn from_code(code: u32) -> Option<Intra4x4Mode> {
        Intra4x4Mode::ALL.get(code as usize).copied()
    }

    /// Which edges the mode reads: (above, left); the corner is read by
    /// the modes needing both.
    pub fn needs(self) -> (bool, bool) {
        use Intra4x4Mode::*;
        match self {
            Vertical | DiagonalDownLeft | VerticalLeft => (true, false),
            Horizontal | HorizontalUp => (false, true),
            Dc => (false, false),
            DiagonalDownRight | VerticalRight | HorizontalDown => (true, true),
        }
    }

    /// Whether a block with these neighbours (above, left) can use it.
    pub fn is_available(self, above: bool, left: bool) -> bool {
        let (a, l) = self.needs();
        (above || !a) && (left || !l)
    }
}

/// The reconstructed samples around a 4x4 block.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Edges {
    /// The four samples above and the four above right (the last above
    /// repeated where those are not decoded yet).
    pub top: Option<[u8; 8]>,
    /// The four samples to the left, top to bottom.
    pub left: Option<[u8; 4]>,
    /// The sample above-left (present when both others are).
    pub top_left: Option<u8>,
}

/// The DC mode's value of a `size x size` block (16x16 luma or 8x8
/// chroma): the rounded mean of the neighbours there are, or 128.
pub fn dc_value(size: usize, n: &Neighbours<'_>) -> u8 {
    let sum = |s: &[u8]| s[..size].iter().map(|&v| u32::from(v)).sum::<u32>();
    let n_bits = size.trailing_zeros();
    (match (n.top, n.left) {
        (Some(t), Some(l)) => (sum(t) + sum(l) + size as u32) >> (n_bits + 1),
        (Some(t), None) => (sum(t) + size as u32 / 2) >> n_bits,
        (None, Some(l)) => (sum(l) + size as u32 / 2) >> n_bits,
        (None, None) => 128,
    }) as u8
}

/// An available 16x16 or chroma mode at size `N` (the intra module's
/// `predict` checks the mode and the neighbours).
#[inline(always)]
fn predict_sized<const N: usize>(mode: IntraMode, n: &Neighbours<'_>, out: &mut [u8], stride: usize) {
    let size = N;
    // Rows of a length the compiler knows: fills and copies become a few
    // moves instead of a library call a row.
    let rows = out.chunks_mut(stride).take(size).map(|r| &mut r[..N]);
    match mode {
        IntraMode::Vertical => {
            let top = &n.top.unwrap_or_default()[..N];
            rows.for_each(|r| r.copy_from_slice(top));
        }
        IntraMode::Horizontal => {
            let left = n.left.unwrap_or_default();
            rows.enumerate().for_each(|(y, r)| r.fill(left[y]));
        }
        IntraMode::Dc => {
            let dc = dc_value(size, n);
            rows.for_each(|r| r.fill(dc));
        }
        IntraMode::Plane => {
            let (top, left) = (n.top.unwrap_or_default(), n.left.unwrap_or_default());
            let corner = i32::from(n.top_left.unwrap_or_default());
            // p(k) along the top (k = -1 is the corner) and along the left.
            let t = |k: isize| if k < 0 { corner } else { i32::from(top[k as usize]) };
            let l = |k: isize| {
                if k < 0 {
                    corner
                } else {
                    i32::from(left[k as usize])
                }
            };
            let half = size as isize / 2;
            let (mut gh, mut gv) = (0i32, 0i32);
            for k in 0..half {
                gh += (k as i32 + 1) * (t(half + k) - t(half - 2 - k));
                gv += (k as i32 + 1) * (l(half + k) - l(half - 2 - k));
            }
            // 16x16: b = (5 H + 32) >> 6; 8x8: b = (34 H + 32) >> 6.
            let scale = if size == 16 { 5 } else { 34 };
            let (b, c) = ((scale * gh + 32) >> 6, (scale * gv + 32) >> 6);
            let a = 16 * (l(size as isize - 1) + t(size as isize - 1));
            let centre = half as i32 - 1;
            // a + b (x - centre) + c (y - centre) + 16, built from a row
            // start and b x by additions (the same values; no per-sample
            // multiply, so the loop vectorises).
            let mut bx = [0i32; N];
            for (x, v) in bx.iter_mut().enumerate() {
                *v = b * x as i32;
            }
            for (y, r) in rows.enumerate() {
                let start = a - b * centre + c * (y as i32 - centre) + 16;
                for (o, &step) in r.iter_mut().zip(&bx) {
                    *o = ((start + step) >> 5).clamp(0, 255) as u8;
                }
            }
        }
    }
}

/// The nine 4x4 modes (the mode's edges present; missing ones read as 0).
#[inline(always)]
fn pred_4x4(mode: Intra4x4Mode, e: &Edges, out: &mut [u8; 16]) {
    use Intra4x4Mode::*;
    // The edge as one line: left column bottom to top, the corner, then
    // the row above and above right. p(-1, y) = line[3 - y], p(x, -1) =
    // line[5 + x], the corner being both at index 4.
    let mut line = [0i32; 13];
    if let Some(l) = e.left {
        for y in 0..4 {
            line[3 - y] = i32::from(l[y]);
        }
    }
    line[4] = i32::from(e.top_left.unwrap_or(0));
    if let Some(t) = e.top {
        for x in 0..8 {
            line[5 + x] = i32::from(t[x]);
        }
    }
    let t = |x: i32| line[(5 + x) as usize];
    let l = |y: i32| line[(3 - y) as usize];
    // Three-tap and two-tap filters along the edge.
    let f3 = |a: i32, b: i32, c: i32| (a + 2 * b + c + 2) >> 2;
    let f2 = |a: i32, b: i32| (a + b + 1) >> 1;
    // One loop per mode (a mode chosen per sample cost 125 instructions a
    // block in the encoder's 4x4 search).
    #[inline(always)]
    fn fill(out: &mut [u8; 16], f: impl Fn(i32, i32) -> i32) {
        for y in 0..4i32 {
            for x in 0..4i32 {
                out[(y * 4 + x) as usize] = f(x, y) as u8;
            }
        }
    }
    match mode {
        Vertical => fill(out, |x, _| t(x)),
        Horizontal => fill(out, |_, y| l(y)),
        Dc => out.fill(dc(e) as u8),
        DiagonalDownLeft => fill(out, |x, y| {
            if x == 3 && y == 3 {
                (t(6) + 3 * t(7) + 2) >> 2
            } else {
                f3(t(x + y), t(x + y + 1), t(x + y + 2))
            }
        }),
        DiagonalDownRight => fill(out, |x, y| match x.cmp(&y) {
            std::cmp::Ordering::Greater => f3(t(x - y - 2), t(x - y - 1), t(x - y)),
            std::cmp::Ordering::Less => f3(l(y - x - 2), l(y - x - 1), l(y - x)),
            std::cmp::Ordering::Equal => f3(t(0), t(-1), l(0)),
        }),
        VerticalRight => fill(out, |x, y| match 2 * x - y {
            z @ 0..=6 if z % 2 == 0 => f2(t(x - (y >> 1) - 1), t(x - (y >> 1))),
            1 | 3 | 5 => f3(t(x - (y >> 1) - 2), t(x - (y >> 1) - 1), t(x - (y >> 1))),
            -1 => f3(l(0), l(-1), t(0)),
            _ => f3(l(y - 1), l(y - 2), l(y - 3)),
        }),
        HorizontalDown => fill(out, |x, y| match 2 * y - x {
            z @ 0..=6 if z % 2 == 0 => f2(l(y - (x >> 1) - 1), l(y - (x >> 1))),
            1 | 3 | 5 => f3(l(y - (x >> 1) - 2), l(y - (x >> 1) - 1), l(y - (x >> 1))),
            -1 => f3(l(0), l(-1), t(0)),
            _ => f3(t(x - 1), t(x - 2), t(x - 3)),
        }),
        VerticalLeft => fill(out, |x, y| {
            if y % 2 == 0 {
                f2(t(x + (y >> 1)), t(x + (y >> 1) + 1))
            } else {
                f3(t(x + (y >> 1)), t(x + (y >> 1) + 1), t(x + (y >> 1) + 2))
            }
        }),
        HorizontalUp => fill(out, |x, y| match x + 2 * y {
            0 | 2 | 4 => f2(l(y + (x >> 1)), l(y + (x >> 1) + 1)),
            1 | 3 => f3(l(y + (x >> 1)), l(y + (x >> 1) + 1), l(y + (x >> 1) + 2)),
            5 => (l(2) + 3 * l(3) + 2) >> 2,
            _ => l(3),
        }),
    }
}

/// What every 4x4 mode's samples are drawn from, as [`ModeSource`] for
/// 8x8 blocks: the edge as one line (`p(-1, y)` at `3 - y`, the corner at
/// 4, `p(x, -1)` at `5 + x`), its [1 2 1] and [1 1] averages, two values
/// of their own and the DC. An encoder trying the nine modes of a block
/// builds it once and gathers each mode from it; [`pred_4x4`] computes
/// one mode alone (the decoder's), and a test holds the two equal.
#[derive(Debug, Clone)]
pub struct ModeSource4([u8; SOURCE4_STORE]);

const LINE4: usize = 0; // 13 samples
const F3_4: usize = 13; // 13: (a + 2b + c + 2) >> 2 centred on line[i], i = 1..=11
const F2_4: usize = 26; // 12: (a + b + 1) >> 1 of line[i], line[i + 1]
const DDL_CORNER4: usize = 38; // diagonal down-left at (3, 3)
const HU_END4: usize = 39; // horizontal-up where x + 2y = 5
const DC_VALUE4: usize = 40;
const SOURCE4_LEN: usize = 41;
/// Its storage: three chunks of 16 bytes, for a byte shuffle's gathers.
const SOURCE4_STORE: usize = 48;

impl ModeSource4 {
    /// The source of a block whose edges are `e` (missing ones read as 0).
    pub fn new(e: &Edges) -> ModeSource4 {
        let line: [u16; 13] = edge_line(
            e.left.as_ref().map(|l| &l[..]),
            e.top_left,
            e.top.as_ref().map(|t| &t[..]),
        );
        let mut v = [0u8; SOURCE4_STORE];
        fill_source(&line, &LAYOUT4, &mut v[..SOURCE4_LEN]);
        v[DC_VALUE4] = dc(e) as u8;
        ModeSource4(v)
    }

    /// The prediction in `mode` into `out` (row-major).
    #[inline]
    pub fn predict(&self, mode: Intra4x4Mode, out: &mut [u8; 16]) {
        self.predict_strided(mode, out, 4);
    }

    /// The prediction in `mode` into the first four samples of four rows
    /// of `out`, `stride` apart (two modes side by side, say).
    #[inline]
    pub fn predict_strided(&self, mode: Intra4x4Mode, out: &mut [u8], stride: usize) {
        for (r, index) in MODE_INDEX4[mode as usize].chunks_exact(4).enumerate() {
            for (o, &i) in out[r * stride..r * stride + 4].iter_mut().zip(index) {
                *o = self.0[usize::from(i)];
            }
        }
    }
}

/// Where sample (x, y) of each 4x4 mode comes from in a [`ModeSource4`]:
/// [`pred_4x4`]'s formulas.
const MODE_INDEX4: [[u8; 16]; 9] = mode_table(4, &LAYOUT4);

/// [`MODE_INDEX4`] as byte-shuffle masks, one for each 16-byte chunk of
/// the source: a sample's index within the chunk it lies in, and 0x80
/// (the shuffle's zero) in the other chunks' masks.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
const MODE_SHUFFLE4: [[[u8; 16]; 3]; 9] = {
    let mut masks = [[[0x80u8; 16]; 3]; 9];
    let mut m = 0;
    while m < 9 {
        let mut i = 0;
        while i < 16 {
            let at = MODE_INDEX4[m][i] as usize;
            masks[m][at / 16][i] = (at % 16) as u8;
            i += 1;
        }
        m += 1;
    }
    masks
};

/// The scalar [`Pred4x4PairFn`]: the two gathers.
fn pred_4x4_pair(source: &ModeSource4, a: Intra4x4Mode, b: Intra4x4Mode, out: &mut [u8; 32]) {
    source.predict_strided(a, out, 8);
    source.predict_strided(b, &mut out[4..], 8);
}

/// Where a [`ModeSource4`]'s parts lie.
const LAYOUT4: SourceLayout = SourceLayout {
    line: LINE4,
    f3: F3_4,
    f2: F2_4,
    ddl_corner: DDL_CORNER4,
    hu_end: HU_END4,
    dc: DC_VALUE4,
};

/// DC of a 4x4 block: the rounded mean of the edges it has, 128 with none.
fn dc(e: &Edges) -> i32 {
    let top: i32 = e.top.map_or(0, |t| t[..4].iter().map(|&v| i32::from(v)).sum());
    let left: i32 = e.left.map_or(0, |l| l.iter().map(|&v| i32::from(v)).sum());
    match (e.top.is_some(), e.left.is_some()) {
        (true, true) => (top + left + 4) >> 3,
        (true, false) => (top + 2) >> 2,
        (false, true) => (left + 2) >> 2,
        (false, false) => 128,
    }
}

/// The reconstructed samples around an 8x8 block.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Edges8 {
    /// The eight samples above and the eight above right (the last above
    /// repeated where those are not decoded yet).
    pub top: Option<[u8; 16]>,
    /// The eight samples to the left, top to bottom.
    pub left: Option<[u8; 8]>,
    /// The sample above-left (present when both others are).
    pub top_left: Option<u8>,
}

/// What every mode's samples are drawn from, computed once per block from
/// its filtered edges: the edge as one line (left column bottom to top,
/// the corner, the row above and above right: `p(-1, y)` at `7 - y`,
/// `p(x, -1)` at `9 + x`), its [1 2 1] averages centred on each position,
/// its [1 1] averages of each position and the next, and three values of
/// their own. Each mode is then a fixed gather ([`MODE_INDEX`]), which is
/// how an encoder trying the nine modes shares the arithmetic.
#[derive(Debug, Clone)]
pub struct ModeSource([u8; SOURCE_STORE]);

const LINE: usize = 0; // 25 samples
const F3: usize = 25; // 25: (a + 2b + c + 2) >> 2 centred on line[i], i = 1..=23
const F2: usize = 50; // 24: (a + b + 1) >> 1 of line[i], line[i + 1]
const DDL_CORNER: usize = 74; // diagonal down-left at (7, 7)
const HU_END: usize = 75; // horizontal-up where x + 2y = 13
const DC_VALUE: usize = 76;
const SOURCE_LEN: usize = 77;
/// Its storage: five chunks of 16 bytes, for a byte shuffle's gathers.
const SOURCE_STORE: usize = 80;

impl ModeSource {
    /// The source of a block whose filtered edges are `e`.
    pub fn new(e: &Edges8) -> ModeSource {
        let line: [u16; 25] = edge_line(
            e.left.as_ref().map(|l| &l[..]),
            e.top_left,
            e.top.as_ref().map(|t| &t[..]),
        );
        let mut v = [0u8; SOURCE_STORE];
        fill_source(&line, &LAYOUT8, &mut v[..SOURCE_LEN]);
        v[DC_VALUE] = dc8(e);
        ModeSource(v)
    }

    /// The prediction in `mode` into `out` (row-major).
    #[inline]
    pub fn predict(&self, mode: Intra4x4Mode, out: &mut [u8; 64]) {
        for (o, &i) in out.iter_mut().zip(&MODE_INDEX[mode as usize]) {
            *o = self.0[usize::from(i)];
        }
    }
}

/// Where sample (x, y) of each mode comes from in a [`ModeSource`]
/// (FORMAT.md section 9.2's formulas).
const MODE_INDEX: [[u8; 64]; 9] = mode_table(8, &LAYOUT8);

/// [`MODE_INDEX`] as byte-shuffle masks: for each half of the block (32
/// samples) and each 16-byte chunk of the source, a sample's index within
/// the chunk it lies in, and 0x80 (the shuffle's zero) in the other
/// chunks' masks.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
const MODE_SHUFFLE8: [[[[u8; 32]; SOURCE_STORE / 16]; 2]; 9] = {
    let mut masks = [[[[0x80u8; 32]; SOURCE_STORE / 16]; 2]; 9];
    let mut m = 0;
    while m < 9 {
        let mut i = 0;
        while i < 64 {
            let at = MODE_INDEX[m][i] as usize;
            masks[m][i / 32][at / 16][i % 32] = (at % 16) as u8;
            i += 1;
        }
        m += 1;
    }
    masks
};

/// The scalar [`Pred8x8GatherFn`].
fn pred_8x8_gather(source: &ModeSource, mode: Intra4x4Mode, out: &mut [u8; 64]) {
    source.predict(mode, out)
}

/// Where a [`ModeSource`]'s parts lie.
const LAYOUT8: SourceLayout = SourceLayout {
    line: LINE,
    f3: F3,
    f2: F2,
    ddl_corner: DDL_CORNER,
    hu_end: HU_END,
    dc: DC_VALUE,
};

/// Where the parts of a mode source lie: the edge line, its [1 2 1] and
/// [1 1] averages, the two values of their own and the DC.
struct SourceLayout {
    line: usize,
    f3: usize,
    f2: usize,
    ddl_corner: usize,
    hu_end: usize,
    dc: usize,
}

/// An `n x n` block's edges as one line of `L = 3n + 1` samples: the left
/// column bottom to top, the corner, the row above and above right
/// (missing ones 0).
#[inline(always)]
fn edge_line<const L: usize>(left: Option<&[u8]>, top_left: Option<u8>, top: Option<&[u8]>) -> [u16; L] {
    let n = (L - 1) / 3;
    let mut line = [0u16; L];
    if let Some(l) = left {
        for (y, &v) in l.iter().enumerate() {
            line[n - 1 - y] = u16::from(v);
        }
    }
    line[n] = u16::from(top_left.unwrap_or(0));
    if let Some(t) = top {
        for (x, &v) in t.iter().enumerate() {
            line[n + 1 + x] = u16::from(v);
        }
    }
    line
}

/// A mode source's parts from its edge `line`, laid out as `at` says
/// (all but the DC, which is the caller's).
#[inline(always)]
fn fill_source<const L: usize>(line: &[u16; L], at: &SourceLayout, v: &mut [u8]) {
    let len = L;
    for (i, &x) in line.iter().enumerate() {
        v[at.line + i] = x as u8;
    }
    for i in 1..len - 1 {
        v[at.f3 + i] = ((line[i - 1] + 2 * line[i] + line[i + 1] + 2) >> 2) as u8;
    }
    for i in 0..len - 1 {
        v[at.f2 + i] = ((line[i] + line[i + 1] + 1) >> 1) as u8;
    }
    v[at.ddl_corner] = ((line[len - 2] + 3 * line[len - 1] + 2) >> 2) as u8;
    v[at.hu_end] = ((line[1] + 3 * line[0] + 2) >> 2) as u8;
}

/// The gather table of an `n x n` block's nine modes (`S = n * n`) from a
/// source laid out as `at` says.
const fn mode_table<const S: usize>(n: usize, at: &SourceLayout) -> [[u8; S]; 9] {
    let mut table = [[0u8; S]; 9];
    let mut m = 0;
    while m < 9 {
        let mut i = 0;
        while i < S {
            table[m][i] = mode_index(at, n as isize, m, (i % n) as isize, (i / n) as isize) as u8;
            i += 1;
        }
        m += 1;
    }
    table
}

/// Where sample (x, y) of mode `m` of an `n x n` block comes from: each
/// formula an average centred at (or starting from) one place of the
/// edge line, whose corner sits at `n` (`p(x, -1)` at `n + 1 + x`,
/// `p(-1, y)` at `n - 1 - y`).
const fn mode_index(at: &SourceLayout, n: isize, m: usize, x: isize, y: isize) -> isize {
    let (f3, f2, line) = (at.f3 as isize + n, at.f2 as isize + n, at.line as isize + n);
    match m {
        0 => line + 1 + x,
        1 => line - 1 - y,
        2 => at.dc as isize,
        3 if x == n - 1 && y == n - 1 => at.ddl_corner as isize,
        3 => f3 + 2 + x + y,
        4 => f3 + x - y,
        5 => match 2 * x - y {
            z if z >= 0 && z % 2 == 0 => f2 + x - (y >> 1),
            z if z > 0 => f3 + x - (y >> 1),
            -1 => f3,
            _ => f3 + 1 + 2 * x - y,
        },
        6 => match 2 * y - x {
            z if z >= 0 && z % 2 == 0 => f2 - 1 - y + (x >> 1),
            z if z > 0 => f3 - y + (x >> 1),
            -1 => f3,
            _ => f3 - 1 + x - 2 * y,
        },
        7 if y % 2 == 0 => f2 + 1 + x + (y >> 1),
        7 => f3 + 2 + x + (y >> 1),
        _ => match x + 2 * y {
            z if z < 2 * n - 3 && z % 2 == 0 => f2 - 2 - y - (x >> 1),
            z if z < 2 * n - 3 => f3 - 2 - y - (x >> 1),
            z if z == 2 * n - 3 => at.hu_end as isize,
            _ => at.line as isize,
        },
    }
}

/// An 8x8 block from its filtered edges: the mode's gather from the
/// block's [`ModeSource`].
#[inline(always)]
fn pred_8x8(mode: Intra4x4Mode, e: &Edges8, out: &mut [u8; 64]) {
    ModeSource::new(e).predict(mode, out);
}

/// DC of an 8x8 block: the rounded mean of the (filtered) edges it has,
/// 128 with none.
pub(crate) fn dc8(e: &Edges8) -> u8 {
    let sum = |v: &[u8]| v.iter().map(|&s| u32::from(s)).sum::<u32>();
    let top = e.top.map(|t| sum(&t[..8]));
    let left = e.left.map(|l| sum(&l));
    let v = match (top, left) {
        (Some(t), Some(l)) => (t + l + 8) >> 4,
        (Some(s), None) | (None, Some(s)) => (s + 4) >> 3,
        (None, None) => 128,
    };
    v as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_4x4_mode_source_predicts_as_each_mode_alone() {
        let mut seed = 7u32;
        let mut next = move || {
            seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
            (seed >> 16) as u8
        };
        for round in 0..400 {
            // Every pair of neighbours present or not; random, flat and
            // extreme samples.
            let (above, left) = (round % 2 == 0, round / 2 % 2 == 0);
            let mut sample = || match round % 5 {
                0 => 255,
                1 => 0,
                _ => next(),
            };
            let e = Edges {
                top: above.then(|| std::array::from_fn(|_| sample())),
                left: left.then(|| std::array::from_fn(|_| sample())),
                top_left: (above && left).then(&mut next),
            };
            let source = ModeSource4::new(&e);
            for mode in Intra4x4Mode::ALL {
                let (mut want, mut got) = ([0u8; 16], [0u8; 16]);
                pred_4x4(mode, &e, &mut want);
                source.predict(mode, &mut got);
                assert_eq!(got, want, "{mode:?} {e:?}");
            }
        }
    }
}
