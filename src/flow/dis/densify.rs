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
use rayon::prelude::*;

use super::search::{Padded, SparseFlow};

/// Writes the dense flow of the level into `u`, `v`; `a2` is the second
/// picture padded as for the search. By the flow kernels of the CPU level
/// in force (the AVX2 build: this source compiled for AVX2, the same bits),
/// in bands of rows on every thread where the level is large enough: each
/// band visits the patches that cover it in the same order, so every
/// pixel's sums are the same whatever the bands.
pub(super) fn densify(
    a1: &Array2<f32>,
    a2: &Padded,
    s: &SparseFlow,
    u: &mut Array2<f32>,
    v: &mut Array2<f32>,
) {
    let kernel = crate::flow::dsp::flow().densify;
    let (h, w) = a1.dim();
    let (us, vs) = (
        u.as_slice_mut().expect("standard"),
        v.as_slice_mut().expect("standard"),
    );
    if crate::imgproc::pyramid::parallel_worth(w * h) {
        let band = h.div_ceil(4 * rayon::current_num_threads()) * w;
        us.par_chunks_mut(band)
            .zip(vs.par_chunks_mut(band))
            .enumerate()
            .for_each(|(k, (u, v))| kernel(a1, a2, s, k * band / w, u, v));
    } else {
        kernel(a1, a2, s, 0, us, vs)
    }
}

/// [`densify`] of the rows from `first` that the bands `u`, `v` hold, for
/// any instruction set.
#[inline(always)]
pub(crate) fn densify_body(
    a1: &Array2<f32>,
    a2: &Padded,
    s: &SparseFlow,
    first: usize,
    u: &mut [f32],
    v: &mut [f32],
) {
    match s.patch {
        16 => densify_sized::<16>(a1, a2, s, first, u, v),
        12 => densify_sized::<12>(a1, a2, s, first, u, v),
        8 => densify_sized::<8>(a1, a2, s, first, u, v),
        4 => densify_sized::<4>(a1, a2, s, first, u, v),
        2 => densify_sized::<2>(a1, a2, s, first, u, v),
        _ => densify_sized::<1>(a1, a2, s, first, u, v),
    }
}

#[inline(always)]
fn densify_sized<const P: usize>(
    a1: &Array2<f32>,
    a2: &Padded,
    s: &SparseFlow,
    first: usize,
    us: &mut [f32],
    vs: &mut [f32],
) {
    let w = a1.dim().1;
    let n = us.len().min(vs.len());
    let end = first + n / w.max(1);
    let i1 = a1.as_slice().expect("standard");
    let (mut su, mut sv, mut sw) = (vec![0f32; n], vec![0f32; n], vec![0f32; n]);
    let ws = s.xs.len();
    for (r, &y0) in s.ys.iter().enumerate() {
        // The patch's rows inside the band.
        let rows = first.max(y0)..end.min(y0 + P);
        if rows.is_empty() {
            continue;
        }
        for (c, &x0) in s.xs.iter().enumerate() {
            let (pu, pv) = (s.u[r * ws + c], s.v[r * ws + c]);
            let (base, [w00, w01, w10, w11]) = a2.patch_at::<P>(x0 as f32 + pu, y0 as f32 + pv);
            for y in rows.clone() {
                let (top, bot) = a2.rows::<P>(base, y - y0);
                let o = y * w + x0;
                let target = &i1[o..o + P];
                let b = o - first * w;
                let (ru, rv, rw) = (&mut su[b..b + P], &mut sv[b..b + P], &mut sw[b..b + P]);
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
    for i in 0..n {
        us[i] = su[i] / sw[i];
        vs[i] = sv[i] / sw[i];
    }
}
