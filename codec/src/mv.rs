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
use crate::partition::{predict_with_references, RefMv};

/// Largest coded vector component magnitude, quarter-pel: 4096 pixels.
pub const MV_LIMIT: i32 = 1 << 14;

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

/// The median of three values.
#[inline]
pub(crate) fn median3(a: i32, b: i32, c: i32) -> i32 {
    a.max(b).min(a.min(b).max(c))
}

/// The predicted vector of a block from its neighbours' vectors (`None`
/// where unavailable); see the module documentation.
///
/// ```
/// use mocomp_codec::mv::{predict_mv, Mv};
/// let (a, b, c) = (Mv::new(4, -8), Mv::new(12, 0), Mv::new(-4, 2));
/// assert_eq!(predict_mv(Some(a), Some(b), Some(c), None), Mv::new(4, 0));
/// assert_eq!(predict_mv(Some(a), None, None, None), a);
/// ```
pub fn predict_mv(left: Option<Mv>, top: Option<Mv>, top_right: Option<Mv>, top_left: Option<Mv>) -> Mv {
    // One reference: the rule of several with every neighbour on it.
    let c = top_right.or(top_left);
    predict_with_references([left, top, c].map(|m| m.map(RefMv::previous)), 0)
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
    fn median_of_three() {
        for (a, b, c, m) in [
            (1, 2, 3, 2),
            (3, 1, 2, 2),
            (2, 3, 1, 2),
            (5, 5, 1, 5),
            (-4, 7, 0, 0),
        ] {
            assert_eq!(median3(a, b, c), m);
        }
    }

    #[test]
    fn prediction_rules() {
        let (a, b, c, d) = (Mv::new(4, 4), Mv::new(8, -4), Mv::new(-12, 0), Mv::new(100, 100));
        // All available: component-wise median.
        assert_eq!(predict_mv(Some(a), Some(b), Some(c), Some(d)), Mv::new(4, 0));
        // C unavailable: D takes its place.
        assert_eq!(predict_mv(Some(a), Some(b), None, Some(d)), Mv::new(8, 4));
        // Top row of the picture: only A.
        assert_eq!(predict_mv(Some(a), None, None, None), a);
        // Exactly one available: that one.
        assert_eq!(predict_mv(None, Some(b), None, None), b);
        assert_eq!(predict_mv(None, None, Some(c), None), c);
        // Two available: median with a zero.
        assert_eq!(predict_mv(None, Some(b), Some(c), None), Mv::new(0, 0));
        // None available: zero.
        assert_eq!(predict_mv(None, None, None, None), Mv::ZERO);
    }

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
