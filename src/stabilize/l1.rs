//! The L1-optimal camera path (Grundmann, Kwatra and Essa, "Auto-directed
//! video stabilization with robust L1 optimal camera paths", CVPR 2011;
//! OpenCV's `LpMotionStabilizer`): a linear programme over each frame's
//! crop transform `B_t` (a similarity from the crop window, in centred
//! coordinates, to the input frame) that minimises the weighted L1 norms
//! of the stabilised path's first, second and third differences, subject
//! to the crop window staying inside every input frame.
//!
//! With `M_t` the motion from frame `t` to `t - 1`, the stabilised path is
//! `P_t = C_t B_t` and its step `P_t^-1 P_(t+1)` is near the identity when
//! `M_(t+1) B_(t+1) - B_t` is near zero: that residual is linear in the
//! unknowns, so its L1 norm (and its differences') is an LP.

use microlp::{ComparisonOp, OptimizationDirection, Problem, Variable};

use super::path::Centre;
use crate::global::Transform;

/// Weights of the three difference orders (Grundmann et al.'s 10, 1, 100)
/// and of a residual's linear part against its shift (100: a 0.01 change
/// of scale or rotation costs as much as a one-pixel shift).
const ORDER_WEIGHTS: [f64; 3] = [10.0, 1.0, 100.0];
const LINEAR_WEIGHT: f64 = 100.0;
/// How far the crop transform's scale and rotation may stray from the
/// identity (Grundmann's proximity constraints; the scale not below
/// 1, or the path would buy smoothness with a tighter crop).
const SCALE_RANGE: (f64, f64) = (0.995, 1.1);
const ROTATION_RANGE: f64 = 0.1;
/// A small pull of each crop transform towards the identity, so that among
/// equally smooth paths the one nearest the camera's wins (without it a
/// constant rotation or offset of the whole video would cost nothing).
const ANCHOR_WEIGHT: f64 = 0.01;

/// One frame's unknowns: `B = [a -b tx; b a ty]`.
#[derive(Clone, Copy)]
struct Unknowns {
    a: Variable,
    b: Variable,
    tx: Variable,
    ty: Variable,
}

/// A linear expression: terms and a constant.
#[derive(Clone, Default)]
struct Expr {
    terms: Vec<(Variable, f64)>,
    constant: f64,
}

impl Expr {
    fn minus(&self, other: &Expr) -> Expr {
        let mut terms = self.terms.clone();
        terms.extend(other.terms.iter().map(|&(v, c)| (v, -c)));
        terms.sort_by_key(|t| t.0.idx());
        let mut merged: Vec<(Variable, f64)> = Vec::with_capacity(terms.len());
        for (v, c) in terms {
            match merged.last_mut() {
                Some(last) if last.0 == v => last.1 += c,
                _ => merged.push((v, c)),
            }
        }
        Expr {
            terms: merged,
            constant: self.constant - other.constant,
        }
    }
}

/// The four independent entries of `M B - B'` for similarities `B`, `B'`
/// and `M`'s linear part `[m0 m1; m3 m4]` and shift `(m2, m5)`:
/// `(MB)_00 - a'`, `(MB)_10 - b'`, `(MB)_02 - tx'`, `(MB)_12 - ty'`.
fn step_residual(m: &Transform, next: &Unknowns, this: &Unknowns) -> [Expr; 4] {
    let m = &m.0;
    let e = |terms: Vec<(Variable, f64)>, constant: f64| Expr { terms, constant };
    let mb = [
        e(vec![(next.a, m[0]), (next.b, m[1])], 0.0),
        e(vec![(next.a, m[3]), (next.b, m[4])], 0.0),
        e(vec![(next.tx, m[0]), (next.ty, m[1])], m[2]),
        e(vec![(next.tx, m[3]), (next.ty, m[4])], m[5]),
    ];
    let b = [this.a, this.b, this.tx, this.ty].map(|v| e(vec![(v, 1.0)], 0.0));
    std::array::from_fn(|i| mb[i].minus(&b[i]))
}

/// Adds `weight * |expr|` to the objective through a slack variable.
fn add_abs(problem: &mut Problem, expr: &Expr, weight: f64) {
    let slack = problem.add_var(weight, (0.0, f64::INFINITY));
    for sign in [1.0, -1.0] {
        let mut terms: Vec<(Variable, f64)> = expr.terms.iter().map(|&(v, c)| (v, sign * c)).collect();
        terms.push((slack, -1.0));
        problem.add_constraint(terms.as_slice(), ComparisonOp::Le, -sign * expr.constant);
    }
}

/// The crop window's corners (the output's, scaled by `ratio`) mapped by
/// `B` stay inside the input frame.
fn add_crop(problem: &mut Problem, u: &Unknowns, centre: &Centre, ratio: f64) {
    let (hw, hh) = centre.half();
    for (cx, cy) in [(-hw, -hh), (hw, -hh), (-hw, hh), (hw, hh)] {
        let (cx, cy) = (cx * ratio, cy * ratio);
        let x = [(u.a, cx), (u.b, -cy), (u.tx, 1.0)];
        let y = [(u.b, cx), (u.a, cy), (u.ty, 1.0)];
        for (terms, bound) in [(x, hw), (y, hh)] {
            problem.add_constraint(&terms[..], ComparisonOp::Le, bound);
            problem.add_constraint(&terms[..], ComparisonOp::Ge, -bound);
        }
    }
}

/// Solves for each frame's crop transform (centred; crop window
/// coordinates to input) with the window `ratio` times the frame;
/// `motions[t - 1]` is `M_t` in centred coordinates. `None` if no path
/// keeps that window inside every frame, or the solver fails.
pub fn solve(motions: &[Transform], centre: &Centre, ratio: f64, rotate: bool) -> Option<Vec<Transform>> {
    if motions.len() < WINDOW {
        return solve_window(motions, centre, ratio, rotate, &[]);
    }
    // The LP's cost grows with the square of its length: solve overlapping
    // windows, each starting from the frames the one before settled.
    let n = motions.len() + 1;
    let mut crops: Vec<Transform> = Vec::with_capacity(n);
    let mut start = 0;
    loop {
        let end = (start + WINDOW).min(n);
        let fixed = &crops[start..crops.len()];
        let window = solve_window(&motions[start..end - 1], centre, ratio, rotate, fixed)?;
        let keep = if end == n { end } else { start + STEP + SETTLED };
        crops.extend_from_slice(&window[crops.len() - start..keep - start]);
        if end == n {
            return Some(crops);
        }
        start += STEP;
    }
}

/// Frames per LP window, how far each window moves on, and how many of
/// its first frames the window before settled.
const WINDOW: usize = 48;
const STEP: usize = 32;
const SETTLED: usize = 3;

/// [`solve`] over one window whose first `fixed.len()` crop transforms
/// are given.
fn solve_window(
    motions: &[Transform],
    centre: &Centre,
    ratio: f64,
    rotate: bool,
    fixed: &[Transform],
) -> Option<Vec<Transform>> {
    let n = motions.len() + 1;
    let mut problem = Problem::new(OptimizationDirection::Minimize);
    let rot = if rotate { ROTATION_RANGE } else { 0.0 };
    let scale = if rotate { SCALE_RANGE } else { (1.0, 1.0) };
    let free = (f64::NEG_INFINITY, f64::INFINITY);
    let unknowns: Vec<Unknowns> = (0..n)
        .map(|i| match fixed.get(i) {
            Some(b) => {
                let m = &b.0;
                Unknowns {
                    a: problem.add_var(0.0, (m[0], m[0])),
                    b: problem.add_var(0.0, (m[3], m[3])),
                    tx: problem.add_var(0.0, (m[2], m[2])),
                    ty: problem.add_var(0.0, (m[5], m[5])),
                }
            }
            None => Unknowns {
                a: problem.add_var(0.0, scale),
                b: problem.add_var(0.0, (-rot, rot)),
                tx: problem.add_var(0.0, free),
                ty: problem.add_var(0.0, free),
            },
        })
        .collect();
    for u in &unknowns {
        add_crop(&mut problem, u, centre, ratio);
        let single = |v: Variable, c: f64| Expr {
            terms: vec![(v, 1.0)],
            constant: -c,
        };
        for (e, w) in [
            (single(u.a, 1.0), LINEAR_WEIGHT),
            (single(u.b, 0.0), LINEAR_WEIGHT),
            (single(u.tx, 0.0), 1.0),
            (single(u.ty, 0.0), 1.0),
        ] {
            add_abs(&mut problem, &e, ANCHOR_WEIGHT * w);
        }
    }
    let mut order: Vec<[Expr; 4]> = (0..n - 1)
        .map(|t| step_residual(&motions[t], &unknowns[t + 1], &unknowns[t]))
        .collect();
    for weight in ORDER_WEIGHTS {
        for residual in &order {
            for (k, e) in residual.iter().enumerate() {
                add_abs(&mut problem, e, weight * if k < 2 { LINEAR_WEIGHT } else { 1.0 });
            }
        }
        order = order
            .windows(2)
            .map(|w| std::array::from_fn(|k| w[1][k].minus(&w[0][k])))
            .collect();
    }
    let solution = problem.solve().ok()?.into_solution().ok()?;
    Some(
        unknowns
            .iter()
            .map(|u| {
                let [a, b, tx, ty] = [u.a, u.b, u.tx, u.ty].map(|v| solution.var_value(v));
                Transform([a, -b, tx, b, a, ty, 0.0, 0.0, 1.0])
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shift(x: f64, y: f64) -> Transform {
        Transform([1.0, 0.0, x, 0.0, 1.0, y, 0.0, 0.0, 1.0])
    }

    #[test]
    fn a_still_camera_with_jitter_gets_a_still_path() {
        // Shifts alternating by +-4 pixels: the best path stays put, so each
        // crop transform undoes its frame's offset exactly.
        let centre = Centre::new(201, 151);
        let offsets: Vec<f64> = (0..30).map(|t| if t % 2 == 0 { 0.0 } else { 4.0 }).collect();
        let motions: Vec<Transform> = (1..30).map(|t| shift(offsets[t - 1] - offsets[t], 0.0)).collect();
        let crops = solve(&motions, &centre, 0.9, true).expect("feasible");
        for t in 1..30 {
            // P_t = C_t B_t: the same for every frame.
            let step = (crops[t].0[2] - offsets[t]) - (crops[t - 1].0[2] - offsets[t - 1]);
            assert!(step.abs() < 1e-6, "frame {t}: {step}");
            assert!(
                crops[t].0[1].abs() < 1e-9 && (crops[t].0[0] - crops[0].0[0]).abs() < 1e-9,
                "{:?}",
                crops[t]
            );
        }
    }

    #[test]
    fn a_long_still_shot_is_solved_in_windows_and_stays_still() {
        // 150 frames of jitter: several windows, the same still path.
        let centre = Centre::new(201, 151);
        let offsets: Vec<f64> = (0..150).map(|t| [0.0, 4.0, -3.0, 2.0][t % 4]).collect();
        let motions: Vec<Transform> = (1..150)
            .map(|t| shift(offsets[t - 1] - offsets[t], 0.0))
            .collect();
        let crops = solve(&motions, &centre, 0.9, true).expect("feasible");
        assert_eq!(crops.len(), 150);
        for t in 1..150 {
            let step = (crops[t].0[2] - offsets[t]) - (crops[t - 1].0[2] - offsets[t - 1]);
            assert!(step.abs() < 1e-6, "frame {t}: {step}");
        }
    }

    #[test]
    fn the_window_bounds_the_correction() {
        // Jumps of 20 pixels back and forth: a window of 90 % of a
        // 101-pixel frame leaves 5 pixels each side, and the path uses them.
        let centre = Centre::new(101, 81);
        let jitter: Vec<Transform> = (0..9)
            .map(|t| shift(if t % 2 == 0 { 20.0 } else { -20.0 }, 0.0))
            .collect();
        let crops = solve(&jitter, &centre, 0.9, false).expect("feasible");
        assert!(crops.iter().all(|b| b.0[2].abs() <= 5.0 + 1e-6));
        assert!(crops.iter().any(|b| b.0[2].abs() > 4.9));
        // A window larger than the frame fits nowhere.
        assert!(solve(&jitter, &centre, 1.05, false).is_none());
    }
}
