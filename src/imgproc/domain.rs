//! Edge-aware smoothing by the domain transform's recursive filter
//! (Gastal and Oliveira, "Domain Transform for Edge-Aware Image and Video
//! Processing", 2011): a value spreads along rows and columns as far as
//! `sigma_s` over flat parts of the guide, and a brightness step of
//! `sigma_r` grey levels stretches the distance across it by `sigma_s`, so
//! that regions of like brightness are smoothed as wholes, whatever their
//! size, and little crosses their edges. Linear in the pixels, whatever
//! `sigma_s`.

use ndarray::{Array2, Axis};

/// `input` smoothed within the regions of `guide` (same size): spatial
/// reach `sigma_s` pixels, range `sigma_r` grey levels, in `iterations`
/// rounds of a horizontal and a vertical pass (3 in the paper). Panics
/// unless `guide` and `input` are of one size.
pub fn domain_transform(
    guide: &Array2<f32>,
    input: &Array2<f32>,
    sigma_s: f32,
    sigma_r: f32,
    iterations: u32,
) -> Array2<f32> {
    assert_eq!(guide.dim(), input.dim(), "guide and input of one size");
    let stretch = sigma_s / sigma_r;
    // The brightness step from each pixel's neighbour before it.
    let steps = |axis: Axis| {
        let mut d = Array2::<f32>::zeros(guide.dim());
        for (mut dl, gl) in d.lanes_mut(axis).into_iter().zip(guide.lanes(axis)) {
            for i in 1..gl.len() {
                dl[i] = (gl[i] - gl[i - 1]).abs();
            }
        }
        d
    };
    let (dx, dy) = (steps(Axis(1)), steps(Axis(0)));
    let mut out = input.clone();
    let n = iterations.max(1) as i32;
    for i in 0..n {
        // The paper's sigmas per round: their squares sum to sigma_s^2.
        let sigma = sigma_s * 3f32.sqrt() * 2f32.powi(n - 1 - i) / (4f32.powi(n) - 1.0).sqrt();
        let feedback = Feedback::new((-(2f32.sqrt()) / sigma).exp(), stretch);
        horizontal_pass(&mut out, &dx, &feedback);
        vertical_pass(&mut out, &dy, &feedback);
    }
    out
}

/// A round's feedback `a` to the power of the transformed distance
/// `1 + stretch * step`: from a table for the whole steps of 8-bit
/// pictures (a power per pixel was most of the filter's time).
struct Feedback {
    a: f32,
    stretch: f32,
    whole: [f32; 256],
}

impl Feedback {
    fn new(a: f32, stretch: f32) -> Feedback {
        let mut whole = [0.0; 256];
        for (k, w) in whole.iter_mut().enumerate() {
            *w = a.powf(1.0 + stretch * k as f32);
        }
        Feedback { a, stretch, whole }
    }

    fn of(&self, step: f32) -> f32 {
        // Exactly the power below for a whole step (the same expression).
        if step.fract() == 0.0 && step < 256.0 {
            self.whole[step as usize]
        } else {
            self.a.powf(1.0 + self.stretch * step)
        }
    }
}

/// One first-order recursive filter along every row, forwards then
/// backwards, each step's feedback that of its brightness step.
fn horizontal_pass(f: &mut Array2<f32>, steps: &Array2<f32>, feedback: &Feedback) {
    let mut weights = Vec::new();
    for (mut fl, sl) in f.rows_mut().into_iter().zip(steps.rows()) {
        weights.clear();
        weights.extend(sl.iter().map(|&s| feedback.of(s)));
        for i in 1..fl.len() {
            fl[i] += weights[i] * (fl[i - 1] - fl[i]);
        }
        for i in (0..fl.len().saturating_sub(1)).rev() {
            fl[i] += weights[i + 1] * (fl[i + 1] - fl[i]);
        }
    }
}

/// The same filter along every column, a whole row at a time (the
/// columns of a row-major picture, read one by one, miss the cache).
fn vertical_pass(f: &mut Array2<f32>, steps: &Array2<f32>, feedback: &Feedback) {
    let h = f.nrows();
    let weights = steps.mapv(|s| feedback.of(s));
    // The row a step reads, copied into one buffer (not a new one a row).
    let mut prev = ndarray::Array1::<f32>::zeros(f.ncols());
    let mut blend = |to: usize, from: usize, w: usize| {
        prev.assign(&f.row(from));
        for ((v, &p), &a) in f.row_mut(to).iter_mut().zip(&prev).zip(weights.row(w)) {
            *v += a * (p - *v);
        }
    };
    for y in 1..h {
        blend(y, y - 1, y);
    }
    for y in (0..h.saturating_sub(1)).rev() {
        blend(y, y + 1, y + 1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn an_edge_of_the_guide_stops_the_spreading_a_flat_guide_does_not() {
        // A score of 1 on the left 12 columns of 80, beside a guide with a
        // 60-level edge at the same place: kept above 0.9 and below 0.05 on
        // either side. A flat guide spreads it: the left columns fall under
        // 0.8, 40 columns to the right rises above 0.1.
        let (h, w) = (16, 80);
        let input = Array2::from_shape_fn((h, w), |(_, x)| if x < 12 { 1.0f32 } else { 0.0 });
        let edge = Array2::from_shape_fn((h, w), |(_, x)| if x < 12 { 100.0f32 } else { 160.0 });
        let kept = domain_transform(&edge, &input, 40.0, 5.0, 3);
        for x in 0..w {
            let v = kept[[8, x]];
            assert!(if x < 12 { v > 0.9 } else { v < 0.05 }, "x {x}: {v}");
        }
        let flat = Array2::from_elem((h, w), 120.0f32);
        let spread = domain_transform(&flat, &input, 40.0, 5.0, 3);
        assert!(
            spread[[8, 0]] < 0.8 && spread[[8, 40]] > 0.1,
            "{:?}",
            spread.row(8)
        );
    }

    #[test]
    fn the_table_gives_the_powers_themselves() {
        let f = Feedback::new(0.93, 4.0);
        for step in [0.0f32, 1.0, 17.0, 255.0, 0.5, 256.0, 300.25] {
            assert_eq!(f.of(step), 0.93f32.powf(1.0 + 4.0 * step), "step {step}");
        }
    }

    proptest! {
        /// Every output is a weighted mean of inputs: within their range;
        /// a constant stays constant.
        #[test]
        fn outputs_stay_within_the_inputs_range(
            seed in 0u64..1000, sigma_s in 1.0f32..60.0, sigma_r in 1.0f32..50.0, c in -5.0f32..5.0,
        ) {
            let noise = |x: usize, y: usize, k: u64| {
                ((x as u64 * 31 + y as u64 * 17 + seed * 7 + k) % 97) as f32
            };
            let guide = Array2::from_shape_fn((11, 19), |(y, x)| noise(x, y, 0) * 2.0);
            let input = Array2::from_shape_fn((11, 19), |(y, x)| noise(x, y, 5) - 40.0);
            let out = domain_transform(&guide, &input, sigma_s, sigma_r, 3);
            let (lo, hi) = input.iter().fold((f32::MAX, f32::MIN), |(l, h), &v| (l.min(v), h.max(v)));
            prop_assert!(out.iter().all(|&v| v >= lo - 1e-3 && v <= hi + 1e-3));
            let constant = Array2::from_elem((11, 19), c);
            let still = domain_transform(&guide, &constant, sigma_s, sigma_r, 3);
            prop_assert!(still.iter().all(|&v| (v - c).abs() < 1e-4));
        }
    }
}
