//! Bit-level reading and writing: fixed-width fields, Exp-Golomb codes, byte
//! alignment.
//!
//! Bits are stored most significant first within each byte (the order of
//! H.264 and of every syntax table in `FORMAT.md`). Multi-bit fields go
//! through `bitvec`'s `BitField` (`store_be` / `load_be`), not bit by bit.
//!
//! Exp-Golomb codes are those of H.264 (9.1): `ue(v)` writes `v + 1` in
//! binary after as many zero bits as it has bits minus one; `se(v)` maps
//! `1, -1, 2, -2, ...` to `1, 2, 3, 4, ...` and writes that as `ue`.
//!
//! ```
//! use mocomp_codec::bits::{BitReader, BitWriter};
//! let mut w = BitWriter::new();
//! w.put(0b101, 3);
//! w.put_ue(4); // 00101
//! w.put_se(-2); // ue(4) again
//! let bytes = w.into_bytes();
//! assert_eq!(bytes, [0b1010_0101, 0b0010_1000]);
//! let mut r = BitReader::new(&bytes);
//! assert_eq!(r.get(3).unwrap(), 0b101);
//! assert_eq!(r.get_ue().unwrap(), 4);
//! assert_eq!(r.get_se().unwrap(), -2);
//! ```

use bitvec::field::BitField;
use bitvec::prelude::{BitSlice, BitVec, Msb0};

/// Longest run of leading zeros in an Exp-Golomb code this reader accepts:
/// enough for every `u32` value.
pub const MAX_EXP_GOLOMB_ZEROS: usize = 32;

/// What can go wrong reading bits. Positions are in bits from the start of
/// the buffer given to the reader.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum BitError {
    /// The data ends before the field does.
    #[error("unexpected end of data at bit {pos}: {needed} bits needed, {available} left")]
    EndOfData {
        /// Bit position of the field.
        pos: usize,
        /// Bits the field needs.
        needed: usize,
        /// Bits left.
        available: usize,
    },
    /// An Exp-Golomb code with too many leading zeros (or only zeros to the
    /// end of the data).
    #[error("malformed Exp-Golomb code at bit {pos}: more than {MAX_EXP_GOLOMB_ZEROS} leading zeros")]
    ExpGolombTooLong {
        /// Bit position of the code.
        pos: usize,
    },
    /// An Exp-Golomb code whose value does not fit the syntax element.
    #[error("Exp-Golomb value at bit {pos} is out of range")]
    ExpGolombRange {
        /// Bit position of the code.
        pos: usize,
    },
}

/// Bit length of `ue(v)`.
///
/// ```
/// use mocomp_codec::bits::ue_len;
/// assert_eq!([0, 1, 2, 3, 6, 7].map(ue_len), [1, 3, 3, 5, 5, 7]);
/// ```
#[inline]
pub fn ue_len(v: u32) -> u32 {
    let bits = 64 - (u64::from(v) + 1).leading_zeros();
    2 * bits - 1
}

/// The `ue` code number of a signed value: `0, 1, -1, 2, -2, ...` map to
/// `0, 1, 2, 3, 4, ...`.
#[inline]
pub fn se_to_ue(v: i32) -> u64 {
    if v > 0 {
        2 * v as u64 - 1
    } else {
        2 * u64::from(v.unsigned_abs())
    }
}

/// Bit length of `se(v)`.
#[inline]
pub fn se_len(v: i32) -> u32 {
    let bits = 64 - (se_to_ue(v) + 1).leading_zeros();
    2 * bits - 1
}

/// Appends bits to a growing buffer.
#[derive(Debug, Clone, Default)]
pub struct BitWriter {
    bits: BitVec<u8, Msb0>,
}

impl BitWriter {
    /// An empty writer.
    pub fn new() -> BitWriter {
        BitWriter::default()
    }

    /// Bits written so far.
    #[inline]
    pub fn len(&self) -> usize {
        self.bits.len()
    }

    /// Whether nothing was written.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.bits.is_empty()
    }

    /// Whether the next bit starts a byte.
    #[inline]
    pub fn is_aligned(&self) -> bool {
        self.bits.len() % 8 == 0
    }

    /// Writes the low `n` bits of `value`, most significant first
    /// (`n <= 64`; higher bits of `value` must be zero).
    #[inline]
    pub fn put(&mut self, value: u64, n: u32) {
        debug_assert!(
            n <= 64 && (n == 64 || value >> n == 0),
            "{value} does not fit {n} bits"
        );
        if n == 0 {
            return;
        }
        let start = self.bits.len();
        self.bits.resize(start + n as usize, false);
        self.bits[start..].store_be(value);
    }

    /// Writes one bit.
    #[inline]
    pub fn put_bit(&mut self, bit: bool) {
        self.bits.push(bit);
    }

    /// Writes `ue(v)` for a code number up to `2^32`.
    fn put_ue_u64(&mut self, v: u64) {
        let x = v + 1;
        let bits = 64 - x.leading_zeros();
        self.put(0, bits - 1);
        self.put(x, bits);
    }

    /// Writes `ue(v)`.
    #[inline]
    pub fn put_ue(&mut self, v: u32) {
        self.put_ue_u64(u64::from(v));
    }

    /// Writes `se(v)`.
    #[inline]
    pub fn put_se(&mut self, v: i32) {
        self.put_ue_u64(se_to_ue(v));
    }

    /// Writes zero bits up to the next byte boundary.
    pub fn align(&mut self) {
        let rem = self.bits.len() % 8;
        if rem != 0 {
            self.put(0, 8 - rem as u32);
        }
    }

    /// Writes whole bytes (at any bit position).
    pub fn put_bytes(&mut self, bytes: &[u8]) {
        if self.is_aligned() {
            self.bits.extend_from_raw_slice(bytes);
        } else {
            for &b in bytes {
                self.put(u64::from(b), 8);
            }
        }
    }

    /// The bytes written, the last one padded with zero bits.
    pub fn into_bytes(self) -> Vec<u8> {
        self.bits.into_vec()
    }
}

/// Reads bits from a byte slice. Every read is checked: running past the
/// end is an error, never a panic.
#[derive(Debug, Clone)]
pub struct BitReader<'a> {
    bits: &'a BitSlice<u8, Msb0>,
    pos: usize,
}

impl<'a> BitReader<'a> {
    /// A reader at the first bit of `bytes`.
    pub fn new(bytes: &'a [u8]) -> BitReader<'a> {
        BitReader {
            bits: BitSlice::from_slice(bytes),
            pos: 0,
        }
    }

    /// Position of the next bit.
    #[inline]
    pub fn position(&self) -> usize {
        self.pos
    }

    /// Bits left.
    #[inline]
    pub fn remaining(&self) -> usize {
        self.bits.len() - self.pos
    }

    /// Whether the next bit starts a byte.
    #[inline]
    pub fn is_aligned(&self) -> bool {
        self.pos % 8 == 0
    }

    #[inline]
    fn need(&self, n: usize) -> Result<(), BitError> {
        if n > self.remaining() {
            return Err(BitError::EndOfData {
                pos: self.pos,
                needed: n,
                available: self.remaining(),
            });
        }
        Ok(())
    }

    /// Reads an `n`-bit unsigned field, most significant bit first (`n <= 64`).
    #[inline]
    pub fn get(&mut self, n: u32) -> Result<u64, BitError> {
        debug_assert!(n <= 64);
        if n == 0 {
            return Ok(0);
        }
        self.need(n as usize)?;
        let v = self.bits[self.pos..self.pos + n as usize].load_be::<u64>();
        self.pos += n as usize;
        Ok(v)
    }

    /// Reads one bit.
    #[inline]
    pub fn get_bit(&mut self) -> Result<bool, BitError> {
        self.need(1)?;
        let b = self.bits[self.pos];
        self.pos += 1;
        Ok(b)
    }

    /// Reads an Exp-Golomb code number (up to `2^32`).
    fn get_ue_u64(&mut self) -> Result<u64, BitError> {
        let start = self.pos;
        let window = &self.bits[self.pos..(self.pos + MAX_EXP_GOLOMB_ZEROS + 1).min(self.bits.len())];
        let zeros = match window.first_one() {
            Some(z) => z,
            None if window.len() > MAX_EXP_GOLOMB_ZEROS => {
                return Err(BitError::ExpGolombTooLong { pos: start })
            }
            None => {
                return Err(BitError::EndOfData {
                    pos: start,
                    needed: window.len() + 1,
                    available: window.len(),
                })
            }
        };
        self.need(2 * zeros + 1).map_err(|_| BitError::EndOfData {
            pos: start,
            needed: 2 * zeros + 1,
            available: self.remaining(),
        })?;
        self.pos += zeros;
        let x = self.get(zeros as u32 + 1)?;
        Ok(x - 1)
    }

    /// Reads `ue(v)` into a `u32`.
    pub fn get_ue(&mut self) -> Result<u32, BitError> {
        let pos = self.pos;
        let v = self.get_ue_u64()?;
        u32::try_from(v).map_err(|_| BitError::ExpGolombRange { pos })
    }

    /// Reads `se(v)` into an `i32`.
    pub fn get_se(&mut self) -> Result<i32, BitError> {
        let pos = self.pos;
        let k = self.get_ue_u64()?;
        let magnitude = k.div_ceil(2);
        let v = if k % 2 == 1 {
            magnitude as i64
        } else {
            -(magnitude as i64)
        };
        i32::try_from(v).map_err(|_| BitError::ExpGolombRange { pos })
    }

    /// Skips to the next byte boundary.
    pub fn align(&mut self) {
        self.pos = self.pos.div_ceil(8) * 8;
        self.pos = self.pos.min(self.bits.len());
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn ue_codewords_match_h264_table() -> Result<(), BitError> {
        // H.264 Table 9-2: bit strings of code numbers 0..8.
        let table = [
            "1", "010", "011", "00100", "00101", "00110", "00111", "0001000", "0001001",
        ];
        for (v, code) in table.iter().enumerate() {
            let mut w = BitWriter::new();
            w.put_ue(v as u32);
            let bits: String = w.bits.iter().map(|b| if *b { '1' } else { '0' }).collect();
            assert_eq!(&bits, code, "ue({v})");
            assert_eq!(ue_len(v as u32) as usize, code.len());
        }
        // Table 9-3: se mapping.
        for (v, k) in [(0, 0), (1, 1), (-1, 2), (2, 3), (-2, 4), (3, 5)] {
            assert_eq!(se_to_ue(v), k);
        }
        Ok(())
    }

    #[test]
    fn extremes_round_trip() -> Result<(), BitError> {
        let mut w = BitWriter::new();
        w.put_ue(u32::MAX);
        w.put_se(i32::MIN);
        w.put_se(i32::MAX);
        w.put(u64::MAX, 64);
        let bytes = w.into_bytes();
        let mut r = BitReader::new(&bytes);
        assert_eq!(r.get_ue()?, u32::MAX);
        assert_eq!(r.get_se()?, i32::MIN);
        assert_eq!(r.get_se()?, i32::MAX);
        assert_eq!(r.get(64)?, u64::MAX);
        Ok(())
    }

    #[test]
    fn reading_past_the_end_is_an_error() {
        let mut r = BitReader::new(&[0xFF]);
        assert_eq!(r.get(5), Ok(31));
        assert_eq!(
            r.get(4),
            Err(BitError::EndOfData {
                pos: 5,
                needed: 4,
                available: 3
            })
        );
        // The failed read consumed nothing.
        assert_eq!(r.get(3), Ok(7));
        assert!(r.get_bit().is_err());
    }

    #[test]
    fn malformed_exp_golomb_codes_are_errors() -> Result<(), BitError> {
        // 40 zero bits: too many leading zeros.
        assert_eq!(
            BitReader::new(&[0; 5]).get_ue(),
            Err(BitError::ExpGolombTooLong { pos: 0 })
        );
        // Only zeros to the end, fewer than the limit.
        assert!(matches!(
            BitReader::new(&[0; 2]).get_ue(),
            Err(BitError::EndOfData { .. })
        ));
        // A prefix of 3 zeros and a 1, but the suffix is cut off.
        assert!(matches!(BitReader::new(&[0b0001_0000]).get_ue(), Ok(7)));
        let mut r = BitReader::new(&[0b1111_0001]);
        r.get(4)?;
        assert!(matches!(r.get_ue(), Err(BitError::EndOfData { pos: 4, .. })));
        // 32 zeros then a 1 and 32 ones: 2^33 - 2, beyond u32 and i32.
        let bytes = [0, 0, 0, 0, 0xFF, 0xFF, 0xFF, 0xFF, 0x80];
        assert_eq!(
            BitReader::new(&bytes).get_ue(),
            Err(BitError::ExpGolombRange { pos: 0 })
        );
        assert_eq!(
            BitReader::new(&bytes).get_se(),
            Err(BitError::ExpGolombRange { pos: 0 })
        );
        Ok(())
    }

    #[test]
    fn alignment_pads_with_zeros() -> Result<(), BitError> {
        let mut w = BitWriter::new();
        w.put_bit(true);
        w.align();
        assert!(w.is_aligned());
        w.put_bytes(&[0xAB, 0xCD]);
        w.put(1, 2);
        w.put_bytes(&[0xFF]);
        let bytes = w.into_bytes();
        assert_eq!(bytes, [0x80, 0xAB, 0xCD, 0b0111_1111, 0b1100_0000]);
        let mut r = BitReader::new(&bytes);
        r.get_bit()?;
        r.align();
        assert_eq!((r.position(), r.get(16)?), (8, 0xABCD));
        Ok(())
    }

    #[derive(Debug, Clone)]
    enum Element {
        Bits(u64, u32),
        Ue(u32),
        Se(i32),
        Align,
    }

    fn element() -> impl Strategy<Value = Element> {
        prop_oneof![
            (0u32..=64).prop_flat_map(|n| {
                let max = if n == 64 { u64::MAX } else { (1u64 << n) - 1 };
                (0..=max, Just(n)).prop_map(|(v, n)| Element::Bits(v, n))
            }),
            any::<u32>().prop_map(Element::Ue),
            (0u32..300).prop_map(Element::Ue),
            any::<i32>().prop_map(Element::Se),
            (-300i32..300).prop_map(Element::Se),
            Just(Element::Align),
        ]
    }

    proptest! {
        #[test]
        fn random_syntax_round_trips(elements in proptest::collection::vec(element(), 0..60)) {
            let mut w = BitWriter::new();
            let mut expected_len = 0usize;
            for e in &elements {
                match *e {
                    Element::Bits(v, n) => { w.put(v, n); expected_len += n as usize; }
                    Element::Ue(v) => { w.put_ue(v); expected_len += ue_len(v) as usize; }
                    Element::Se(v) => { w.put_se(v); expected_len += se_len(v) as usize; }
                    Element::Align => { w.align(); expected_len = expected_len.div_ceil(8) * 8; }
                }
                prop_assert_eq!(w.len(), expected_len);
            }
            let bytes = w.into_bytes();
            prop_assert_eq!(bytes.len(), expected_len.div_ceil(8));
            let mut r = BitReader::new(&bytes);
            for e in &elements {
                match *e {
                    Element::Bits(v, n) => prop_assert_eq!(r.get(n), Ok(v)),
                    Element::Ue(v) => prop_assert_eq!(r.get_ue(), Ok(v)),
                    Element::Se(v) => prop_assert_eq!(r.get_se(), Ok(v)),
                    Element::Align => r.align(),
                }
            }
            prop_assert_eq!(r.position(), expected_len);
        }

        #[test]
        fn any_bytes_read_without_panicking(bytes in proptest::collection::vec(any::<u8>(), 0..40), ops in proptest::collection::vec(0u8..5, 0..80)) {
            let mut r = BitReader::new(&bytes);
            for op in ops {
                let _ = match op {
                    0 => r.get_ue().map(u64::from),
                    1 => r.get_se().map(|v| v as u64),
                    2 => r.get(13),
                    3 => r.get_bit().map(u64::from),
                    _ => { r.align(); Ok(0) }
                };
                prop_assert!(r.position() <= bytes.len() * 8);
            }
        }
    }
}
