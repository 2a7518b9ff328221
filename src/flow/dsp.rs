//! The flow kernels, one table per CPU level ([`crate::codec::dsp`]): the
//! DIS patch search over a pyramid level, its densification and the
//! variational refinement.
//! Their AVX2 builds are the scalar source compiled for AVX2, without FMA,
//! so that every sum rounds as in the scalar build: the same bits (held by
//! `tests/checkasm.rs` and the golden flows).

use ndarray::Array2;

use super::dis::densify::densify_body;
use super::dis::search::{search_level_body, LevelSearch, Padded, SparseFlow};
use super::refine::{RefineParams, Refiner};
use crate::codec::dsp::PerLevel;

/// The DIS search of one pyramid level: `(input, patch side)`.
pub(crate) type DisSearchFn = fn(&LevelSearch, usize) -> SparseFlow;

/// DIS densification of one level: `(i1, padded i2, patch vectors, u, v)`.
pub(crate) type DensifyFn = fn(&Array2<f32>, &Padded, &SparseFlow, &mut Array2<f32>, &mut Array2<f32>);

/// The variational refinement: `(refiner, i1, i2, u, v, params)`.
pub(crate) type RefineFn =
    fn(&mut Refiner, &Array2<f32>, &Array2<f32>, &mut Array2<f32>, &mut Array2<f32>, &RefineParams);

/// The flow kernels of one CPU level.
#[derive(Clone, Copy)]
pub(crate) struct FlowDsp {
    /// DIS patch search over a level.
    pub dis_search_level: DisSearchFn,
    /// DIS densification of a level.
    pub densify: DensifyFn,
    /// Variational refinement.
    pub refine: RefineFn,
}

const SCALAR: FlowDsp = FlowDsp {
    dis_search_level: |input, patch| search_level_body::<false>(input, patch),
    densify: densify_body,
    refine: Refiner::refine_body,
};

/// The tables, lowest level first.
pub(crate) static FLOW: PerLevel<FlowDsp> = PerLevel([
    SCALAR,
    SCALAR,
    #[cfg(target_arch = "x86_64")]
    FlowDsp {
        dis_search_level: avx2::dis_search_level,
        densify: avx2::densify,
        refine: avx2::refine,
    },
    #[cfg(not(target_arch = "x86_64"))]
    SCALAR,
]);

/// The kernels of the CPU level in force.
#[inline]
pub(crate) fn flow() -> &'static FlowDsp {
    FLOW.get()
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use ndarray::Array2;

    use super::{LevelSearch, Padded, RefineParams, Refiner, SparseFlow};
    crate::codec::compiled_for! { "avx2":
        fn dis_search_level(input: &LevelSearch, patch: usize) -> SparseFlow => super::search_level_body::<true>;
        fn densify(a1: &Array2<f32>, a2: &Padded, s: &SparseFlow, u: &mut Array2<f32>, v: &mut Array2<f32>)
            => super::densify_body;
        fn refine(r: &mut Refiner, i1: &Array2<f32>, i2: &Array2<f32>, u: &mut Array2<f32>, v: &mut Array2<f32>, p: &RefineParams)
            => Refiner::refine_body;
    }
}
