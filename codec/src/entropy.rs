//! Adaptive binary arithmetic coding (normative): the range coder that
//! carries everything after a frame's header (FORMAT.md section 3.4).
//!
//! A binary range coder in the manner of LZMA's: a 32-bit range, 15-bit
//! probabilities, byte-wise output with carry propagation. Each context is
//! a probability of a 0 bin and a count of the bins it has coded; it adapts
//! by an exponential decay whose rate slows as the count grows (fast
//! learning at first, then stable estimates, as AV1's symbol adaptation).
//! Bypass bins code equiprobable bits (signs, Exp-Golomb suffixes).
//!
//! The encoder's leading byte (always 0 in this construction) is not
//! written, and neither are trailing zero bytes: past the end the decoder
//! reads zeros. A decoder can therefore check that a partition was used to
//! its end ([`RangeDecoder::consumed_all`]).
//!
//! ```
//! use mocomp_codec::entropy::{Context, RangeDecoder, RangeEncoder};
//! let bits = [true, false, false, true, false, false, false];
//! let mut enc = RangeEncoder::new();
//! let mut ctx = Context::new();
//! for &b in &bits {
//!     enc.encode(&mut ctx, b);
//! }
//! enc.encode_bypass(true);
//! let bytes = enc.finish();
//! let mut dec = RangeDecoder::new(&bytes);
//! let mut ctx = Context::new();
//! for &b in &bits {
//!     assert_eq!(dec.decode(&mut ctx), b);
//! }
//! assert!(dec.decode_bypass());
//! assert!(dec.consumed_all());
//! ```

/// Probabilities are in units of 2^-15.
const PROB_BITS: u32 = 15;
const PROB_ONE: u32 = 1 << PROB_BITS;
/// The range is renormalised to stay at or above 2^24.
const TOP: u32 = 1 << 24;

/// One adaptive binary context: the probability that the next bin is 0.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Context {
    /// P(bin = 0) in units of 2^-15, kept within 1..2^15 - 1 by the update.
    p0: u16,
    /// Bins coded so far, saturating: chooses the adaptation rate.
    count: u8,
}

impl Default for Context {
    fn default() -> Context {
        Context::new()
    }
}

impl Context {
    /// A context with no knowledge: P(0) = 1/2.
    pub const fn new() -> Context {
        Context {
            p0: (PROB_ONE / 2) as u16,
            count: 0,
        }
    }

    /// P(bin = 0) in units of 2^-15.
    pub fn p0(&self) -> u32 {
        u32::from(self.p0)
    }

    /// Moves the probability toward the bin just coded. The rate is 1/16
    /// for the first 16 bins, 1/32 up to 48, then 1/64: with those
    /// shifts the probability stays strictly inside (0, 1).
    pub fn update(&mut self, bit: bool) {
        let shift = match self.count {
            0..=15 => 4,
            16..=47 => 5,
            _ => 6,
        };
        let p = u32::from(self.p0);
        let p = if bit {
            p - (p >> shift)
        } else {
            p + ((PROB_ONE - p) >> shift)
        };
        self.p0 = p as u16;
        self.count = self.count.saturating_add(1);
    }
}

/// Writes bins into bytes.
#[derive(Debug, Clone)]
pub struct RangeEncoder {
    low: u64,
    range: u32,
    /// The byte held back until it is known no carry can change it.
    cache: u8,
    /// How many bytes are held back: `cache` and then `pending - 1` 0xFF.
    pending: u64,
    /// Whether the construction's leading zero byte is still to be dropped.
    first: bool,
    out: Vec<u8>,
}

impl Default for RangeEncoder {
    fn default() -> RangeEncoder {
        RangeEncoder::new()
    }
}

impl RangeEncoder {
    /// An empty encoder.
    pub fn new() -> RangeEncoder {
        RangeEncoder {
            low: 0,
            range: u32::MAX,
            cache: 0,
            pending: 1,
            first: true,
            out: Vec::new(),
        }
    }

    fn shift_low(&mut self) {
        if self.low < 0xFF00_0000 || self.low >= 1 << 32 {
            let carry = (self.low >> 32) as u8;
            let mut byte = self.cache;
            while self.pending > 0 {
                if self.first {
                    self.first = false;
                } else {
                    self.out.push(byte.wrapping_add(carry));
                }
                byte = 0xFF;
                self.pending -= 1;
            }
            self.cache = (self.low >> 24) as u8;
        }
        self.pending += 1;
        self.low = (self.low & 0x00FF_FFFF) << 8;
    }

    fn normalise(&mut self) {
        while self.range < TOP {
            self.range <<= 8;
            self.shift_low();
        }
    }

    /// Codes `bit` with `ctx`'s probability, then adapts `ctx`.
    pub fn encode(&mut self, ctx: &mut Context, bit: bool) {
        let bound = (self.range >> PROB_BITS) * ctx.p0();
        if bit {
            self.low += u64::from(bound);
            self.range -= bound;
        } else {
            self.range = bound;
        }
        ctx.update(bit);
        self.normalise();
    }

    /// Codes an equiprobable bit.
    pub fn encode_bypass(&mut self, bit: bool) {
        self.range >>= 1;
        if bit {
            self.low += u64::from(self.range);
        }
        self.normalise();
    }

    /// Flushes the state and returns the bytes, without trailing zeros.
    pub fn finish(mut self) -> Vec<u8> {
        for _ in 0..5 {
            self.shift_low();
        }
        while self.out.last() == Some(&0) {
            self.out.pop();
        }
        self.out
    }
}

/// Reads the bins a [`RangeEncoder`] wrote. Past the end of its bytes it
/// reads zeros (those the encoder trimmed, and on a damaged stream any
/// number more: nothing panics); [`RangeDecoder::consumed_all`] says
/// whether the bytes were consistent with an encoder's.
#[derive(Debug, Clone)]
pub struct RangeDecoder<'a> {
    bytes: &'a [u8],
    pos: usize,
    code: u32,
    range: u32,
}

impl<'a> RangeDecoder<'a> {
    /// Starts decoding `bytes`.
    pub fn new(bytes: &'a [u8]) -> RangeDecoder<'a> {
        let mut d = RangeDecoder {
            bytes,
            pos: 0,
            code: 0,
            range: u32::MAX,
        };
        for _ in 0..4 {
            d.code = (d.code << 8) | u32::from(d.next_byte());
        }
        d
    }

    fn next_byte(&mut self) -> u8 {
        let b = self.bytes.get(self.pos).copied().unwrap_or(0);
        self.pos += 1;
        b
    }

    fn normalise(&mut self) {
        while self.range < TOP {
            self.range <<= 8;
            self.code = (self.code << 8) | u32::from(self.next_byte());
        }
    }

    /// Decodes a bin with `ctx`'s probability, then adapts `ctx`.
    pub fn decode(&mut self, ctx: &mut Context) -> bool {
        let bound = (self.range >> PROB_BITS) * ctx.p0();
        // A code at or above the range cannot come from an encoder; it
        // decodes as 1s, harmlessly, and the caller's checks reject it.
        let bit = self.code >= bound;
        if bit {
            self.code -= bound;
            self.range -= bound;
        } else {
            self.range = bound;
        }
        ctx.update(bit);
        self.normalise();
        bit
    }

    /// Decodes an equiprobable bit.
    pub fn decode_bypass(&mut self) -> bool {
        self.range >>= 1;
        let bit = self.code >= self.range;
        if bit {
            self.code -= self.range;
        }
        self.normalise();
        bit
    }

    /// Bytes consumed so far (may exceed the input's length on a damaged
    /// stream).
    pub fn position(&self) -> usize {
        self.pos
    }

    /// Whether the bins decoded so far account for every input byte, as
    /// when they are all an encoder wrote: every byte was read, and the
    /// last is not a zero (which the encoder would have trimmed).
    pub fn consumed_all(&self) -> bool {
        self.pos >= self.bytes.len() && self.bytes.last() != Some(&0)
    }
}

/// Cost in 1/256 bit of coding a bin whose probability is `p` (in units of
/// 2^-15): what the writer's bit statistics and an encoder's rate estimates
/// add up. Not normative (no decoded sample depends on it).
pub fn cost(p: u32) -> u32 {
    cost_table()[cost_index(p)]
}

/// The entry of [`cost_table`] for probability `p`.
#[inline]
fn cost_index(p: u32) -> usize {
    (p >> (PROB_BITS - COST_ENTRIES_LOG2)) as usize
}

/// [`cost`] tabulated, for pricers that look it up per bin.
pub fn cost_table() -> &'static [u32; COST_ENTRIES] {
    COST.get_or_init(|| {
        std::array::from_fn(|i| {
            let p = (i as f64 + 0.5) / COST_ENTRIES as f64;
            (-p.log2() * 256.0).round() as u32
        })
    })
}

const COST_ENTRIES_LOG2: u32 = 10;
/// Entries of [`cost_table`].
pub const COST_ENTRIES: usize = 1 << COST_ENTRIES_LOG2;
static COST: std::sync::OnceLock<[u32; COST_ENTRIES]> = std::sync::OnceLock::new();

impl Context {
    /// Cost in 1/256 bit of coding `bit` in this context's present state.
    pub fn cost(&self, bit: bool) -> u32 {
        self.cost_in(cost_table(), bit)
    }

    /// The costs of a 0 and of a 1 in this context's present state, for
    /// every context of a class at once (`table` from [`cost_table`]).
    #[inline]
    pub fn costs_in(&self, table: &[u32; COST_ENTRIES]) -> [u32; 2] {
        [self.cost_in(table, false), self.cost_in(table, true)]
    }

    /// [`Context::cost`] from the table, looked up once by the caller.
    #[inline]
    fn cost_in(&self, table: &[u32; COST_ENTRIES], bit: bool) -> u32 {
        let p = u32::from(self.p0);
        table[cost_index(if bit { PROB_ONE - p } else { p })]
    }
}

/// Cost in 1/256 bit of one bypass bin.
pub const BYPASS_COST: u32 = 256;

/// Where the syntax's bins go: written, only adapted, or only priced. The
/// binarisations in `residual.rs` and `modes.rs` are written once over
/// this (their `replay` methods run them into any sink), so an encoder's
/// rate estimates and the adaptation follow the writer exactly. `ctx`
/// indexes the coder's own context array (its `contexts()`).
pub trait Bins {
    /// A context-coded bin.
    fn bin(&mut self, ctx: usize, bit: bool);
    /// A bypass bin (probability one half).
    fn bypass(&mut self, bit: bool);
}

/// Writes bins, adapting the contexts, and adds up their cost (1/256 bit)
/// as it goes (for the per-category bit statistics).
pub(crate) struct Writer<'a> {
    enc: &'a mut RangeEncoder,
    contexts: &'a mut [Context],
    table: &'static [u32; COST_ENTRIES],
    pub cost: u32,
}

impl<'a> Writer<'a> {
    /// A writer into `enc` with `contexts`, its cost count at 0.
    pub fn new(enc: &'a mut RangeEncoder, contexts: &'a mut [Context]) -> Writer<'a> {
        Writer {
            enc,
            contexts,
            table: cost_table(),
            cost: 0,
        }
    }
}

impl Bins for Writer<'_> {
    #[inline]
    fn bin(&mut self, ctx: usize, bit: bool) {
        let c = &mut self.contexts[ctx];
        self.cost += c.cost_in(self.table, bit);
        self.enc.encode(c, bit);
    }
    fn bypass(&mut self, bit: bool) {
        self.cost += BYPASS_COST;
        self.enc.encode_bypass(bit);
    }
}

/// Adapts the contexts as writing would, writing nothing.
pub(crate) struct Adapter<'a>(pub &'a mut [Context]);

impl Bins for Adapter<'_> {
    fn bin(&mut self, ctx: usize, bit: bool) {
        self.0[ctx].update(bit);
    }
    fn bypass(&mut self, _: bool) {}
}

/// Prices bins in the contexts' present state (1/256 bit) without adapting
/// them: exact for a context's first bin, an estimate for the next ones.
/// Not normative: the sum a writer's bit statistics and an encoder's rate
/// estimates are made of.
pub struct Pricer<'a> {
    contexts: &'a [Context],
    table: &'static [u32; COST_ENTRIES],
    /// The bins' cost so far, 1/256 bit.
    pub cost: u32,
}

impl<'a> Pricer<'a> {
    /// A pricer over `contexts`, starting from `cost`.
    pub fn new(contexts: &'a [Context], cost: u32) -> Pricer<'a> {
        Pricer {
            contexts,
            table: cost_table(),
            cost,
        }
    }
}

impl Bins for Pricer<'_> {
    #[inline]
    fn bin(&mut self, ctx: usize, bit: bool) {
        self.cost += self.contexts[ctx].cost_in(self.table, bit);
    }
    fn bypass(&mut self, _: bool) {
        self.cost += BYPASS_COST;
    }
}

/// How many bypass bins [`put_exp_golomb`] writes for `v` of order `k`:
/// a one per doubling past `2^k`, the zero, and `k` plus that many
/// suffix bits.
pub fn exp_golomb_bins(v: u32, k: u32) -> u32 {
    // The ones: the largest `n` with `2^k (2^n - 1) <= v`.
    let n = (u64::from(v) / (1u64 << k) + 1).ilog2();
    2 * n + 1 + k
}

/// k-th order Exp-Golomb in bypass bins: ones while the value covers the
/// next `2^k` (k growing by one each time), a zero, then the remainder in
/// k bits, most significant first.
pub(crate) fn put_exp_golomb<B: Bins>(b: &mut B, mut v: u32, mut k: u32) {
    while v >= 1 << k {
        b.bypass(true);
        v -= 1 << k;
        k += 1;
    }
    b.bypass(false);
    while k > 0 {
        k -= 1;
        b.bypass((v >> k) & 1 != 0);
    }
}

/// Reads [`put_exp_golomb`]'s code; `None` when the ones run past
/// `max_ones` (or the value past `u32`).
pub(crate) fn get_exp_golomb(dec: &mut RangeDecoder<'_>, mut k: u32, max_ones: u32) -> Option<u32> {
    let mut v = 0u32;
    let mut ones = 0;
    while dec.decode_bypass() {
        v = v.checked_add(1u32.checked_shl(k)?)?;
        k += 1;
        ones += 1;
        if ones > max_ones || k > 31 {
            return None;
        }
    }
    let mut suffix = 0u32;
    for _ in 0..k {
        suffix = (suffix << 1) | u32::from(dec.decode_bypass());
    }
    v.checked_add(suffix)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Counts the bins it is given.
    struct Count(u32);
    impl Bins for Count {
        fn bin(&mut self, _: usize, _: bool) {
            self.0 += 1;
        }
        fn bypass(&mut self, _: bool) {
            self.0 += 1;
        }
    }

    #[test]
    fn exp_golomb_bins_counts_what_is_written() {
        let values = (0..300).chain([1 << 16, (1 << 20) - 1, u32::MAX >> 4]);
        for v in values {
            for k in 0..4 {
                let mut c = Count(0);
                put_exp_golomb(&mut c, v, k);
                assert_eq!(exp_golomb_bins(v, k), c.0, "v {v} k {k}");
            }
        }
    }
    use proptest::prelude::*;

    /// A deterministic stream of skewed bits from a small generator.
    fn skewed_bits(n: usize, one_in: u32, seed: u32) -> Vec<bool> {
        let mut s = seed | 1;
        (0..n)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 17;
                s ^= s << 5;
                s % one_in == 0
            })
            .collect()
    }

    #[test]
    fn skewed_bits_cost_near_their_entropy() {
        // P(1) = 1/10: entropy 0.469 bit per bin.
        let bits = skewed_bits(100_000, 10, 7);
        let mut enc = RangeEncoder::new();
        let mut ctx = Context::new();
        for &b in &bits {
            enc.encode(&mut ctx, b);
        }
        let bytes = enc.finish();
        let per_bin = bytes.len() as f64 * 8.0 / bits.len() as f64;
        assert!(per_bin > 0.46 && per_bin < 0.49, "{per_bin} bits per bin");
        let mut dec = RangeDecoder::new(&bytes);
        let mut ctx = Context::new();
        assert!(bits.iter().all(|&b| dec.decode(&mut ctx) == b));
        assert!(dec.consumed_all());
    }

    #[test]
    fn the_cost_table_matches_log2() {
        let c = Context::new();
        assert_eq!(c.cost(false), 256);
        assert_eq!(c.cost(true), 256);
        // P = 1/4: 2 bits.
        assert!((cost(PROB_ONE / 4) as i32 - 512).abs() <= 1);
    }

    #[test]
    fn probabilities_stay_inside_the_open_interval() {
        let mut c = Context::new();
        for _ in 0..10_000 {
            c.update(false);
        }
        assert!(c.p0() < PROB_ONE);
        for _ in 0..10_000 {
            c.update(true);
        }
        assert!(c.p0() > 0);
    }

    proptest! {
        #[test]
        fn any_bins_round_trip(
            bins in proptest::collection::vec((any::<bool>(), 0usize..4, any::<bool>()), 0..2000)
        ) {
            // (bit, context index, bypass?)
            let mut enc = RangeEncoder::new();
            let mut ctx = [Context::new(); 4];
            for &(b, i, bypass) in &bins {
                if bypass { enc.encode_bypass(b) } else { enc.encode(&mut ctx[i], b) }
            }
            let bytes = enc.finish();
            let mut dec = RangeDecoder::new(&bytes);
            let mut ctx = [Context::new(); 4];
            for &(b, i, bypass) in &bins {
                let got = if bypass { dec.decode_bypass() } else { dec.decode(&mut ctx[i]) };
                prop_assert_eq!(got, b);
            }
            prop_assert!(dec.consumed_all());
        }

        #[test]
        fn any_bytes_decode_without_panicking(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            let mut dec = RangeDecoder::new(&bytes);
            let mut ctx = Context::new();
            for i in 0..1000 {
                if i % 3 == 0 { dec.decode_bypass(); } else { dec.decode(&mut ctx); }
            }
        }
    }
}
