//! Coding of quantised transform coefficients (normative syntax).
//!
//! A macroblock's residual is 16 luma and 2 x 4 chroma 4x4 blocks of levels.
//! Which blocks carry anything is said in two steps:
//!
//! * `coded_block_pattern`, `ue(v)` in 0..=63: bit `q` (0..=3) is set when
//!   luma 8x8 quadrant `q` (raster order) has a non-zero level; bit 4 for
//!   Cb, bit 5 for Cr;
//! * for every 4x4 block of a flagged quadrant or chroma plane,
//!   `coded_block_flag`, `u(1)`.
//!
//! A coded 4x4 block is scanned in H.264's zig-zag order and written as
//! `ue(total - 1)` (1..=16 non-zero levels), then for each non-zero level in
//! scan order `ue(run)` (zeros skipped before it), `ue(|level| - 1)` and a
//! sign bit (1 = negative). Runs that would carry a level past position 15,
//! and levels above [`MAX_LEVEL`], are errors.

use crate::bits::{ue_len, BitError, BitReader, BitWriter};
use crate::transform::Block4;

/// H.264's 4x4 frame zig-zag scan: `ZIGZAG[k]` is the raster index
/// (`row * 4 + col`) of the k-th coefficient.
pub const ZIGZAG: [usize; 16] = [0, 1, 4, 8, 5, 2, 3, 6, 9, 12, 13, 10, 7, 11, 14, 15];

/// Largest level magnitude the syntax allows (far above what 8-bit
/// residuals quantise to at QP 0, about 1700).
pub const MAX_LEVEL: u32 = 1 << 15;

/// Why coefficient data is invalid.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ResidualError {
    /// The bits themselves.
    #[error(transparent)]
    Bits(#[from] BitError),
    /// A value outside its range.
    #[error("{what} is {value}, out of range, at bit {pos}")]
    Range {
        /// The syntax element.
        what: &'static str,
        /// Its value.
        value: u64,
        /// Bit position where it starts.
        pos: usize,
    },
}

/// The levels of one macroblock: 16 luma blocks in raster order of 4x4
/// blocks within the macroblock, then 4 Cb and 4 Cr blocks.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct MbResidual {
    /// Luma 4x4 blocks, index `by * 4 + bx`.
    pub luma: [Block4; 16],
    /// Chroma 4x4 blocks, `[plane][by * 2 + bx]`, plane 0 = Cb.
    pub chroma: [[Block4; 4]; 2],
}

fn is_zero(b: &Block4) -> bool {
    b.iter().all(|r| r.iter().all(|&v| v == 0))
}

/// Luma 4x4 block indices of 8x8 quadrant `q`.
fn quadrant_blocks(q: usize) -> [usize; 4] {
    let (qx, qy) = (q % 2, q / 2);
    let first = qy * 8 + qx * 2;
    [first, first + 1, first + 4, first + 5]
}

impl MbResidual {
    /// Whether every level is zero.
    pub fn is_empty(&self) -> bool {
        self.luma.iter().all(is_zero) && self.chroma.iter().flatten().all(is_zero)
    }

    /// The coded block pattern of these levels.
    pub fn cbp(&self) -> u32 {
        let mut cbp = 0;
        for q in 0..4 {
            if quadrant_blocks(q).iter().any(|&b| !is_zero(&self.luma[b])) {
                cbp |= 1 << q;
            }
        }
        for p in 0..2 {
            if self.chroma[p].iter().any(|b| !is_zero(b)) {
                cbp |= 1 << (4 + p);
            }
        }
        cbp
    }

    /// Writes the pattern and every coded block.
    pub fn write(&self, w: &mut BitWriter) {
        let cbp = self.cbp();
        w.put_ue(cbp);
        for q in 0..4 {
            if cbp & (1 << q) != 0 {
                for b in quadrant_blocks(q) {
                    write_block_with_flag(w, &self.luma[b]);
                }
            }
        }
        for p in 0..2 {
            if cbp & (1 << (4 + p)) != 0 {
                for b in &self.chroma[p] {
                    write_block_with_flag(w, b);
                }
            }
        }
    }

    /// The bits [`MbResidual::write`] writes, without writing them (the
    /// encoder's rate term).
    pub fn bit_len(&self) -> u32 {
        let cbp = self.cbp();
        let mut bits = ue_len(cbp);
        for q in 0..4 {
            if cbp & (1 << q) != 0 {
                bits += quadrant_blocks(q)
                    .iter()
                    .map(|&b| 1 + block_len(&self.luma[b]))
                    .sum::<u32>();
            }
        }
        for p in 0..2 {
            if cbp & (1 << (4 + p)) != 0 {
                bits += self.chroma[p].iter().map(|b| 1 + block_len(b)).sum::<u32>();
            }
        }
        bits
    }

    /// Reads what [`MbResidual::write`] writes.
    pub fn read(r: &mut BitReader<'_>) -> Result<MbResidual, ResidualError> {
        let pos = r.position();
        let cbp = r.get_ue()?;
        if cbp > 63 {
            return Err(ResidualError::Range {
                what: "coded_block_pattern",
                value: u64::from(cbp),
                pos,
            });
        }
        let mut out = MbResidual::default();
        for q in 0..4 {
            if cbp & (1 << q) != 0 {
                for b in quadrant_blocks(q) {
                    out.luma[b] = read_block_with_flag(r)?;
                }
            }
        }
        for p in 0..2 {
            if cbp & (1 << (4 + p)) != 0 {
                for b in &mut out.chroma[p] {
                    *b = read_block_with_flag(r)?;
                }
            }
        }
        Ok(out)
    }
}

fn write_block_with_flag(w: &mut BitWriter, b: &Block4) {
    let coded = !is_zero(b);
    w.put_bit(coded);
    if coded {
        write_block(w, b);
    }
}

fn read_block_with_flag(r: &mut BitReader<'_>) -> Result<Block4, ResidualError> {
    if r.get_bit()? {
        read_block(r)
    } else {
        Ok([[0; 4]; 4])
    }
}

/// Writes one 4x4 block with at least one non-zero level (run-level, see
/// the module documentation). Panics on an all-zero block or a level above
/// [`MAX_LEVEL`] (encoder bugs).
pub fn write_block(w: &mut BitWriter, b: &Block4) {
    let scan = ZIGZAG.map(|i| b[i / 4][i % 4]);
    let total = scan.iter().filter(|&&v| v != 0).count();
    assert!(total > 0, "write_block: all-zero block");
    w.put_ue(total as u32 - 1);
    let mut run = 0;
    for &v in &scan {
        if v == 0 {
            run += 1;
            continue;
        }
        assert!(v.unsigned_abs() <= MAX_LEVEL, "level {v} above {MAX_LEVEL}");
        w.put_ue(run);
        w.put_ue(v.unsigned_abs() - 1);
        w.put_bit(v < 0);
        run = 0;
    }
}

/// The bits [`write_block`] writes for `b` (0 for an all-zero block,
/// which it does not write), without its coded-block flag.
pub fn block_len(b: &Block4) -> u32 {
    let mut total = 0;
    let mut bits = 0;
    let mut run = 0;
    for &i in &ZIGZAG {
        let v = b[i / 4][i % 4];
        if v == 0 {
            run += 1;
            continue;
        }
        total += 1;
        bits += ue_len(run) + ue_len(v.unsigned_abs() - 1) + 1;
        run = 0;
    }
    if total == 0 {
        0
    } else {
        bits + ue_len(total - 1)
    }
}

/// Reads one 4x4 block written by [`write_block`].
pub fn read_block(r: &mut BitReader<'_>) -> Result<Block4, ResidualError> {
    let pos = r.position();
    let total = r.get_ue()? as u64 + 1;
    if total > 16 {
        return Err(ResidualError::Range {
            what: "total_coeff",
            value: total,
            pos,
        });
    }
    let mut b = [[0i32; 4]; 4];
    let mut next = 0u64; // first scan position the next level may take
    for i in 0..total {
        let pos = r.position();
        let run = u64::from(r.get_ue()?);
        let at = next + run;
        // Room must remain for the levels still to come.
        if at + (total - 1 - i) > 15 {
            return Err(ResidualError::Range {
                what: "run",
                value: run,
                pos,
            });
        }
        let pos = r.position();
        let magnitude = u64::from(r.get_ue()?) + 1;
        if magnitude > u64::from(MAX_LEVEL) {
            return Err(ResidualError::Range {
                what: "level",
                value: magnitude,
                pos,
            });
        }
        let negative = r.get_bit()?;
        let idx = ZIGZAG[at as usize];
        b[idx / 4][idx % 4] = if negative {
            -(magnitude as i32)
        } else {
            magnitude as i32
        };
        next = at + 1;
    }
    Ok(b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn zigzag_is_a_permutation_walking_the_diagonals() {
        let mut seen = [false; 16];
        for (k, &i) in ZIGZAG.iter().enumerate() {
            assert!(!seen[i]);
            seen[i] = true;
            if k > 0 {
                // Each step moves to a neighbouring cell (including diagonals).
                let (a, b) = (ZIGZAG[k - 1], i);
                assert!(
                    ((a / 4) as i32 - (b / 4) as i32).abs() <= 1
                        && ((a % 4) as i32 - (b % 4) as i32).abs() <= 1
                );
            }
        }
    }

    #[test]
    fn a_hand_coded_block() -> Result<(), ResidualError> {
        // Levels 3 at DC and -1 at scan position 2 (raster 4): total 2 ->
        // ue(1) = 010; run 0 -> 1, |3|-1 = 2 -> 011, sign 0; run 1 -> 010,
        // |-1|-1 = 0 -> 1, sign 1.
        let mut b = [[0; 4]; 4];
        b[0][0] = 3;
        b[1][0] = -1;
        let mut w = BitWriter::new();
        write_block(&mut w, &b);
        assert_eq!(w.len(), 3 + 1 + 3 + 1 + 3 + 1 + 1);
        let bytes = w.into_bytes();
        assert_eq!(bytes, [0b0101_0110, 0b0101_1000]);
        assert_eq!(read_block(&mut BitReader::new(&bytes))?, b);
        Ok(())
    }

    #[test]
    fn bad_runs_counts_and_levels_are_errors() {
        let encode = |f: &dyn Fn(&mut BitWriter)| {
            let mut w = BitWriter::new();
            f(&mut w);
            w.into_bytes()
        };
        // 17 levels.
        let b = encode(&|w| w.put_ue(16));
        assert!(matches!(
            read_block(&mut BitReader::new(&b)),
            Err(ResidualError::Range {
                what: "total_coeff",
                ..
            })
        ));
        // One level after a run of 16.
        let b = encode(&|w| {
            w.put_ue(0);
            w.put_ue(16);
            w.put_ue(0);
            w.put_bit(false);
        });
        assert!(matches!(
            read_block(&mut BitReader::new(&b)),
            Err(ResidualError::Range { what: "run", .. })
        ));
        // Two levels, the first at position 15: no room for the second.
        let b = encode(&|w| {
            w.put_ue(1);
            w.put_ue(15);
        });
        assert!(matches!(
            read_block(&mut BitReader::new(&b)),
            Err(ResidualError::Range { what: "run", .. })
        ));
        // A level of 2^15 + 1.
        let b = encode(&|w| {
            w.put_ue(0);
            w.put_ue(0);
            w.put_ue(MAX_LEVEL);
            w.put_bit(false);
        });
        assert!(matches!(
            read_block(&mut BitReader::new(&b)),
            Err(ResidualError::Range { what: "level", .. })
        ));
        // A pattern above 63.
        let b = encode(&|w| w.put_ue(64));
        assert!(matches!(
            MbResidual::read(&mut BitReader::new(&b)),
            Err(ResidualError::Range { .. })
        ));
    }

    fn block_strategy() -> impl Strategy<Value = Block4> {
        // Mostly zeros, as after quantisation.
        proptest::collection::vec(
            prop_oneof![6 => Just(0i32), 3 => -3i32..=3, 1 => -40_000i32..=40_000],
            16,
        )
        .prop_map(|v| {
            let mut b = [[0; 4]; 4];
            for (i, x) in v.into_iter().enumerate() {
                b[i / 4][i % 4] = x.clamp(-(MAX_LEVEL as i32), MAX_LEVEL as i32);
            }
            b
        })
    }

    proptest! {
        #[test]
        fn macroblock_residuals_round_trip(
            luma in proptest::collection::vec(block_strategy(), 16),
            chroma in proptest::collection::vec(block_strategy(), 8),
            empty_mask in any::<u32>()
        ) {
            let mut res = MbResidual::default();
            for (i, b) in luma.into_iter().enumerate() {
                if empty_mask & (1 << i) == 0 { res.luma[i] = b; }
            }
            for (i, b) in chroma.into_iter().enumerate() {
                if empty_mask & (1 << (16 + i)) == 0 { res.chroma[i / 4][i % 4] = b; }
            }
            let mut w = BitWriter::new();
            res.write(&mut w);
            let bits = w.len();
            prop_assert_eq!(res.bit_len() as usize, bits);
            let bytes = w.into_bytes();
            let mut r = BitReader::new(&bytes);
            prop_assert_eq!(MbResidual::read(&mut r), Ok(res));
            prop_assert_eq!(r.position(), bits);
        }

        #[test]
        fn arbitrary_bits_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..64)) {
            let _ = MbResidual::read(&mut BitReader::new(&bytes));
        }
    }
}
