//! Motion vectors, their prediction from neighbours, and their code length.
//!
//! A vector is in quarter-pel luma units (eighth-pel chroma). It is coded as
//! the difference from a predicted vector, range-coded by [`crate::modes`];
//! [`mvd_bits`], the Exp-Golomb length of that difference, is the rate
//! estimate a motion search weighs. The predictor follows H.264 8.4.1.3 for a single reference: with A the left,
//! B the upper and C the upper-right neighbour (the upper-left one, D, when
//! C is outside the picture or not yet decoded), a neighbour being
//! "unavailable" when outside the picture or intra-coded,
//!
//! 1. if B and C are unavailable and A is available, the predictor is A;
//! 2. otherwise, if exactly one of A, B, C is available, it is that one;
//! 3. otherwise it is the component-wise median of A, B, C, an unavailable
//!    one counting as zero.

use crate::bits::se_len;

pub use crate::consts::MV_LIMIT;

/// A motion vector in quarter-pel luma units: the block at `p` is predicted
/// from the reference at `p + (x, y) / 4`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Mv {
    /// Horizontal component, quarter-pel.
    pub x: i32,
    /// Vertical component, quarter-pel.
    pub y: i32,
}

impl Mv {
    /// The zero vector.
    pub const ZERO: Mv = Mv { x: 0, y: 0 };

    /// A vector from quarter-pel components.
    pub const fn new(x: i32, y: i32) -> Mv {
        Mv { x, y }
    }

    /// A vector of whole pixels.
    pub const fn full_pel(x: i32, y: i32) -> Mv {
        Mv { x: 4 * x, y: 4 * y }
    }

    /// Whether both components are within the coded range `[-MV_LIMIT, MV_LIMIT]`.
    pub fn in_range(self) -> bool {
        // A range test, not abs(): components come from the stream and may
        // be i32::MIN.
        let ok = |v: i32| (-MV_LIMIT..=MV_LIMIT).contains(&v);
        ok(self.x) && ok(self.y)
    }
}

impl std::ops::Sub for Mv {
    type Output = Mv;
    fn sub(self, o: Mv) -> Mv {
        Mv::new(self.x - o.x, self.y - o.y)
    }
}

impl Mv {
    /// Component-wise sum, `None` on overflow (a decoder's guard).
    pub fn checked_add(self, o: Mv) -> Option<Mv> {
        Some(Mv::new(self.x.checked_add(o.x)?, self.y.checked_add(o.y)?))
    }
}

impl std::ops::Add for Mv {
    type Output = Mv;
    fn add(self, o: Mv) -> Mv {
        Mv::new(self.x + o.x, self.y + o.y)
    }
}

/// The rate estimate of the vector `mv` predicted by `mvp`: `se(dx) +
/// se(dy)`, the Exp-Golomb length of the difference (the stream
/// range-codes it, [`crate::modes`]). This is the `R(mv - mvp)` of
/// rate-constrained motion search.
#[inline]
pub fn mvd_bits(mv: Mv, mvp: Mv) -> u32 {
    let d = mv - mvp;
    se_len(d.x) + se_len(d.y)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vector_difference_costs_se_bits() {
        assert_eq!(mvd_bits(Mv::new(5, -3), Mv::new(5, -3)), 2);
        // dx = 1 (3 bits), dy = -2 (5 bits).
        assert_eq!(mvd_bits(Mv::new(6, -5), Mv::new(5, -3)), 8);
        assert!(Mv::new(MV_LIMIT, -MV_LIMIT).in_range() && !Mv::new(MV_LIMIT + 1, 0).in_range());
        // Found by the decoder fuzzer: i32::MIN must not overflow.
        assert!(!Mv::new(i32::MIN, 0).in_range() && !Mv::new(0, i32::MIN).in_range());
        assert_eq!(Mv::full_pel(2, -3), Mv::new(8, -12));
    }
}
