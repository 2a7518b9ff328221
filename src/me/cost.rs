//! Block matching costs: SAD, SSD, SATD.
//!
//! Each kernel compares a `w x h` block of `a` (row stride `sa`) with one of
//! `b` (row stride `sb`). These are the scalar reference versions; the SIMD
//! kernels of [`super::dsp`] must return exactly the same values, and
//! [`Metric::cost`] goes through them.
//!
//! SATD is the sum of absolute values of the 4x4 Hadamard transform of the
//! difference, tile by tile, halved (as x264's `satd`) once for the whole
//! block and rounded up, so it is on the scale of SAD. Blocks for SATD have
//! sides that are multiples of 4.

use std::fmt;
use std::str::FromStr;

/// A block distortion measure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Metric {
    /// Sum of absolute differences.
    #[default]
    Sad,
    /// Sum of squared differences.
    Ssd,
    /// Sum of absolute 4x4 Hadamard-transformed differences, halved.
    Satd,
}

impl Metric {
    /// Every metric, in the order the CLI lists them.
    pub const ALL: [Metric; 3] = [Metric::Sad, Metric::Ssd, Metric::Satd];

    /// The name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Metric::Sad => "sad",
            Metric::Ssd => "ssd",
            Metric::Satd => "satd",
        }
    }

    /// The cost of block `a` against block `b`.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    pub fn cost(self, a: &[u8], sa: usize, b: &[u8], sb: usize, w: usize, h: usize) -> u32 {
        (self.kernel())(a, sa, b, sb, w, h)
    }

    /// The kernel [`Metric::cost`] calls, chosen once for loops that call it
    /// many times (a search's positions).
    pub fn kernel(self) -> super::dsp::CostFn {
        match self {
            Metric::Sad => super::dsp::pixel().sad,
            Metric::Ssd => ssd,
            Metric::Satd => super::dsp::pixel().satd,
        }
    }
}

impl fmt::Display for Metric {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Metric {
    type Err = String;
    fn from_str(s: &str) -> Result<Metric, String> {
        Metric::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| format!("unknown metric '{s}' (sad, ssd, satd)"))
    }
}

pub use super::dsp::{sad, satd};

/// Sum of squared differences (row by row with the metrics' kernel).
pub fn ssd(a: &[u8], sa: usize, b: &[u8], sb: usize, w: usize, h: usize) -> u32 {
    let rows = (0..h)
        .map(|r| crate::metrics::squared_difference_sum(&a[r * sa..r * sa + w], &b[r * sb..r * sb + w]));
    // A block of at most 64x64 samples: under 2^28.
    rows.sum::<u64>() as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_computed_costs() {
        let a = [10u8, 20, 30, 40, 50, 60, 70, 80];
        let b = [12u8, 18, 30, 45, 50, 61, 60, 80];
        // Differences -2, 2, 0, -5 / 0, -1, 10, 0.
        assert_eq!(sad(&a, 4, &b, 4, 4, 2), 20);
        assert_eq!(ssd(&a, 4, &b, 4, 4, 2), 4 + 4 + 25 + 1 + 100);
        // A stride wider than the block: only the first 2 columns.
        assert_eq!(sad(&a, 4, &b, 4, 2, 2), 2 + 2 + 1);
    }

    #[test]
    fn satd_of_a_constant_difference_is_its_dc() {
        // A constant difference d: only the DC coefficient, 16 d, halved: 8 d.
        let a = [100u8; 16];
        let b = [97u8; 16];
        assert_eq!(satd(&a, 4, &b, 4, 4, 4), 8 * 3);
        // One differing sample spreads over all 16 coefficients with |d|: 16 |d| / 2.
        let mut c = [100u8; 16];
        c[5] = 90;
        assert_eq!(satd(&a, 4, &c, 4, 4, 4), 8 * 10);
        assert_eq!(satd(&a, 4, &a, 4, 4, 4), 0);
    }

    #[test]
    fn names_parse() {
        for m in Metric::ALL {
            assert_eq!(m.name().parse::<Metric>(), Ok(m));
        }
        assert!("mse".parse::<Metric>().is_err());
    }
}
