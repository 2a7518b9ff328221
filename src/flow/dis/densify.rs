//! From the patch grid's vectors to a dense field: each pixel takes the
//! average of the vectors of the patches that cover it, each weighted by
//! `1 / max(1, |I2(p + w) - I1(p)|)`, so a patch whose vector does not fit
//! the pixel (it straddles a motion boundary) counts little there.
//!
//! The sums are gathered patch by patch: a patch's vector is one
//! displacement, so its bilinear weights are the same for all its pixels
//! and each of its rows is one straight loop. Patches are visited in a
//! fixed order, so the sums do not depend on the number of threads.

use ndarray::Array2;

use super::search::{Padded, SparseFlow};

/// Writes the dense flow of the level into `u`, `v`; `a2` is the second
/// picture padded as for the search. By the flow kernels of the CPU level
/// in force (the AVX2 build: this source compiled for AVX2, the same bits).
pub(super) fn densify(
    a1: &Array2<f32>,
    a2: &Padded,
    s: &SparseFlow,
    u: &mut Array2<f32>,
    v: &mut Array2<f32>,
) {
    (crate::flow::dsp::flow().densify)(a1, a2, s, u, v)
}

/// [`densify`] for any instruction set.
#[inline(always)]
pub(crate) fn densify_body(
    a1: &Array2<f32>,
    a2: &Padded,
    s: &SparseFlow,
    u: &mut Array2<f32>,
    v: &mut Array2<f32>,
) {
    match s.patch {
        16 => densify_sized::<16>(a1, a2, s, u, v),
        12 => densify_sized::<12>(a1, a2, s, u, v),
        8 => densify_sized::<8>(a1, a2, s, u, v),
        4 => densify_sized::<4>(a1, a2, s, u, v),
        2 => densify_sized::<2>(a1, a2, s, u, v),
        _ => densify_sized::<1>(a1, a2, s, u, v),
    }
}

#[inline(always)]
fn densify_sized<const P: usize>(
    a1: &Array2<f32>,
    a2: &Padded,
    s: &SparseFlow,
    u: &mut Array2<f32>,
    v: &mut Array2<f32>,
) {
    let (h, w) = a1.dim();
    let i1 = a1.as_slice().expect("standard");
    let (mut su, mut sv, mut sw) = (vec![0f32; w * h], vec![0f32; w * h], vec![0f32; w * h]);
    let ws = s.xs.len();
    for (r, &y0) in s.ys.iter().enumerate() {
        for (c, &x0) in s.xs.iter().enumerate() {
            let (pu, pv) = (s.u[r * ws + c], s.v[r * ws + c]);
            let (base, [w00, w01, w10, w11]) = a2.patch_at::<P>(x0 as f32 + pu, y0 as f32 + pv);
            for row in 0..P {
                let (top, bot) = a2.rows::<P>(base, row);
                let o = (y0 + row) * w + x0;
                let target = &i1[o..o + P];
                let (ru, rv, rw) = (&mut su[o..o + P], &mut sv[o..o + P], &mut sw[o..o + P]);
                for k in 0..P {
                    let d = w00 * top[k] + w01 * top[k + 1] + w10 * bot[k] + w11 * bot[k + 1] - target[k];
                    let weight = 1.0 / d.abs().max(1.0);
                    ru[k] += weight * pu;
                    rv[k] += weight * pv;
                    rw[k] += weight;
                }
            }
        }
    }
    let (us, vs) = (
        u.as_slice_mut().expect("standard"),
        v.as_slice_mut().expect("standard"),
    );
    for i in 0..w * h {
        us[i] = su[i] / sw[i];
        vs[i] = sv[i] / sw[i];
    }
}
