//! From the patch grid's vectors to a dense field: each pixel takes the
//! average of the vectors of the patches that cover it, each weighted by
//! `1 / max(1, |I2(p + w) - I1(p)|)`, so a patch whose vector does not fit
//! the pixel (it straddles a motion boundary) counts little there.

use ndarray::Array2;
use rayon::prelude::*;

use super::search::SparseFlow;
use crate::flow::pyramid::{parallel_worth, rows_per_task};
use crate::flow::warp::bilinear_clamped;

/// For each position along a side of `n` pixels, the range of patches
/// (by index into `origins`) that cover it.
fn covering(origins: &[usize], patch: usize, n: usize) -> Vec<(usize, usize)> {
    let (mut lo, mut hi) = (0, 0);
    (0..n)
        .map(|x| {
            while hi < origins.len() && origins[hi] <= x {
                hi += 1;
            }
            while lo < hi && origins[lo] + patch <= x {
                lo += 1;
            }
            (lo, hi)
        })
        .collect()
}

/// Writes the dense flow of the level into `u`, `v`.
pub(super) fn densify(
    a1: &Array2<f32>,
    a2: &Array2<f32>,
    s: &SparseFlow,
    u: &mut Array2<f32>,
    v: &mut Array2<f32>,
) {
    let (h, w) = a1.dim();
    let (i1, i2) = (a1.as_slice().expect("standard"), a2.as_slice().expect("standard"));
    let (cols, rows) = (covering(&s.xs, s.patch, w), covering(&s.ys, s.patch, h));
    let ws = s.xs.len();
    let row = |y: usize, ru: &mut [f32], rv: &mut [f32]| {
        let (r0, r1) = rows[y];
        for x in 0..w {
            let (c0, c1) = cols[x];
            let target = i1[y * w + x];
            let (mut su, mut sv, mut sw) = (0f32, 0f32, 0f32);
            for r in r0..r1 {
                for k in r * ws + c0..r * ws + c1 {
                    let (pu, pv) = (s.u[k], s.v[k]);
                    let diff = bilinear_clamped(i2, w, h, x as f32 + pu, y as f32 + pv) - target;
                    let weight = 1.0 / diff.abs().max(1.0);
                    su += weight * pu;
                    sv += weight * pv;
                    sw += weight;
                }
            }
            ru[x] = su / sw;
            rv[x] = sv / sw;
        }
    };
    let (us, vs) = (
        u.as_slice_mut().expect("standard"),
        v.as_slice_mut().expect("standard"),
    );
    if parallel_worth(w * h) {
        let band = rows_per_task(w);
        us.par_chunks_mut(band * w)
            .zip(vs.par_chunks_mut(band * w))
            .enumerate()
            .for_each(|(t, (bu, bv))| {
                for (k, (ru, rv)) in bu.chunks_mut(w).zip(bv.chunks_mut(w)).enumerate() {
                    row(t * band + k, ru, rv);
                }
            });
    } else {
        for (y, (ru, rv)) in us.chunks_mut(w).zip(vs.chunks_mut(w)).enumerate() {
            row(y, ru, rv);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_pixel_is_covered_by_the_patches_over_it() {
        let origins = [0, 4, 8, 12, 13];
        let c = covering(&origins, 8, 21);
        assert_eq!(c[0], (0, 1));
        assert_eq!(c[5], (0, 2));
        assert_eq!(c[12], (2, 4));
        assert_eq!(c[20], (4, 5));
        for (x, &(lo, hi)) in c.iter().enumerate() {
            assert!(lo < hi);
            for &o in &origins[lo..hi] {
                assert!(o <= x && x < o + 8);
            }
        }
    }
}
