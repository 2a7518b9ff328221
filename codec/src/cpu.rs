//! The one CPU level that chooses every SIMD kernel of the workspace (as
//! dav1d's and rav1e's CPU flags do): detected once, lowered by the
//! environment variable `MOCOMP_CPU` (`scalar`, `sse2`, `avx2`) or by
//! [`set_level`], never raised above what the CPU runs. Every kernel with
//! a SIMD build asks [`at_least`] and otherwise runs its scalar twin, and
//! the twins give the same results, so the level changes speed, never
//! output (the golden-stream test runs at every level).

use std::sync::atomic::{AtomicU8, Ordering};

/// Instruction-set levels, each including the ones below it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[repr(u8)]
pub enum CpuLevel {
    /// Portable Rust only.
    Scalar = 0,
    /// x86-64's baseline SIMD.
    Sse2 = 1,
    /// x86-64 with AVX2 (and POPCNT, which every AVX2 CPU has).
    Avx2 = 2,
}

impl CpuLevel {
    /// Every level, lowest first.
    pub const ALL: [CpuLevel; 3] = [CpuLevel::Scalar, CpuLevel::Sse2, CpuLevel::Avx2];

    /// The name `MOCOMP_CPU` takes.
    pub fn name(self) -> &'static str {
        match self {
            CpuLevel::Scalar => "scalar",
            CpuLevel::Sse2 => "sse2",
            CpuLevel::Avx2 => "avx2",
        }
    }

    /// The level of a name, if it is one.
    pub fn from_name(name: &str) -> Option<CpuLevel> {
        CpuLevel::ALL
            .into_iter()
            .find(|l| l.name().eq_ignore_ascii_case(name.trim()))
    }

    /// The highest level this CPU runs.
    pub fn detected() -> CpuLevel {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("popcnt") {
                return CpuLevel::Avx2;
            }
            CpuLevel::Sse2
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            CpuLevel::Scalar
        }
    }

    #[inline]
    fn from_u8(v: u8) -> CpuLevel {
        CpuLevel::ALL[usize::from(v).min(2)]
    }
}

/// No level chosen yet.
const UNSET: u8 = u8::MAX;

static LEVEL: AtomicU8 = AtomicU8::new(UNSET);

/// The level in force: the detected one, lowered by `MOCOMP_CPU` (an
/// unknown name there is ignored) or by [`set_level`].
#[inline]
pub fn level() -> CpuLevel {
    match LEVEL.load(Ordering::Relaxed) {
        UNSET => first_level(),
        v => CpuLevel::from_u8(v),
    }
}

/// The first call's work, apart so that [`level`] inlines into kernels'
/// dispatch (it is asked millions of times a sequence).
#[cold]
#[inline(never)]
fn first_level() -> CpuLevel {
    let from_env = std::env::var("MOCOMP_CPU")
        .ok()
        .and_then(|v| CpuLevel::from_name(&v));
    let level = from_env.map_or(CpuLevel::detected(), |l| l.min(CpuLevel::detected()));
    LEVEL.store(level as u8, Ordering::Relaxed);
    level
}

/// Whether kernels of `wanted` may run.
#[inline]
pub fn at_least(wanted: CpuLevel) -> bool {
    level() >= wanted
}

/// Sets the level for the whole process, at most the detected one;
/// returns the level now in force. Meant for tests and benchmarks: kernels
/// already running finish at the level they started with.
pub fn set_level(wanted: CpuLevel) -> CpuLevel {
    let level = wanted.min(CpuLevel::detected());
    LEVEL.store(level as u8, Ordering::Relaxed);
    level
}

/// The levels this CPU runs, lowest first.
pub fn available() -> Vec<CpuLevel> {
    CpuLevel::ALL
        .into_iter()
        .filter(|&l| l <= CpuLevel::detected())
        .collect()
}

/// Asks the processor to bring the cache lines of `value` (a sample, a
/// record) into cache ahead of its use: a hint that reads nothing and
/// cannot fault, for data whose next use a miss would stall on and which
/// the hardware prefetcher does not foresee (rows a stride apart, records
/// of a frame visited once).
#[inline]
pub fn prefetch<T>(value: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let start = std::ptr::from_ref(value).cast::<i8>();
        for offset in (0..std::mem::size_of::<T>().max(1)).step_by(64) {
            // SAFETY: a prefetch never faults and reads nothing
            // architecturally; the addresses are inside `value` anyway.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(start.add(offset)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = value;
}

/// [`prefetch`] of the line holding `data[first]` and of those holding
/// every `step`-th byte after it up to `data[last]` (rows of a picture a
/// stride apart): a few instructions a line, where a generic iterator
/// over the samples took several times as many.
#[inline]
pub fn prefetch_every(data: &[u8], first: usize, last: usize, step: usize) {
    assert!(
        first <= last && last < data.len() && step > 0,
        "lines inside the slice"
    );
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let base = data.as_ptr().cast::<i8>();
        let mut at = first;
        while at <= last {
            // SAFETY: `at <= last < data.len()`, so the address is inside
            // `data`; a prefetch never faults and reads nothing
            // architecturally.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(base.add(at)) };
            at += step;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_levels_are_ordered() {
        for l in CpuLevel::ALL {
            assert_eq!(CpuLevel::from_name(l.name()), Some(l));
        }
        assert_eq!(CpuLevel::from_name(" AVX2 "), Some(CpuLevel::Avx2));
        assert_eq!(CpuLevel::from_name("neon"), None);
        assert!(CpuLevel::Scalar < CpuLevel::Sse2 && CpuLevel::Sse2 < CpuLevel::Avx2);
        assert_eq!(available()[0], CpuLevel::Scalar);
        assert_eq!(available().last(), Some(&CpuLevel::detected()));
    }

    #[test]
    fn lines_are_prefetched_up_to_the_last_byte_and_no_further() {
        let data = [0u8; 100];
        prefetch_every(&data, 0, 99, 33);
        prefetch_every(&data, 99, 99, 1);
        let past = std::panic::catch_unwind(|| prefetch_every(&data, 0, 100, 10));
        assert!(past.is_err(), "a line past the slice is refused");
    }
}
