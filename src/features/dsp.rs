//! The feature matcher's kernel, one table per CPU level
//! ([`crate::codec::dsp`]): a descriptor's nearest and second-nearest
//! neighbours by Hamming distance. The AVX2 level's build is the scalar
//! source compiled with the `popcnt` instruction (the baseline counts bits
//! with a dozen instructions a word): the same result.

use super::describe::{hamming, Descriptor};
use crate::codec::dsp::PerLevel;

/// `(descriptor, others)`: the index of the nearest of `others`, its
/// distance and the second-nearest distance (`u32::MAX` where there is
/// none).
pub type NearestFn = fn(&Descriptor, &[Descriptor]) -> (usize, u32, u32);

/// The matcher's kernels of one CPU level.
#[derive(Debug, Clone, Copy)]
pub struct FeaturesDsp {
    /// Nearest neighbours by Hamming distance.
    pub nearest: NearestFn,
}

const SCALAR: FeaturesDsp = FeaturesDsp {
    nearest: nearest_body,
};

/// The tables, lowest level first.
pub static FEATURES: PerLevel<FeaturesDsp> = PerLevel([
    SCALAR,
    SCALAR,
    #[cfg(target_arch = "x86_64")]
    FeaturesDsp {
        nearest: popcnt::nearest,
    },
    #[cfg(not(target_arch = "x86_64"))]
    SCALAR,
]);

/// The kernels of the CPU level in force.
#[inline]
pub fn features() -> &'static FeaturesDsp {
    FEATURES.get()
}

#[cfg(target_arch = "x86_64")]
mod popcnt {
    use super::Descriptor;
    crate::codec::compiled_for! { "popcnt":
        fn nearest(da: &Descriptor, b: &[Descriptor]) -> (usize, u32, u32) => super::nearest_body;
    }
}

/// The scalar [`NearestFn`].
#[inline(always)]
pub fn nearest_body(da: &Descriptor, b: &[Descriptor]) -> (usize, u32, u32) {
    let (mut best, mut second, mut at) = (u32::MAX, u32::MAX, 0);
    for (j, db) in b.iter().enumerate() {
        let d = hamming(da, db);
        if d < best {
            (second, best, at) = (best, d, j);
        } else if d < second {
            second = d;
        }
    }
    (at, best, second)
}
