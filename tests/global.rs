//! Global motion against camera motion known independently of the code:
//! exact correspondences under each model with outliers, noisy ones, and
//! pictures rendered analytically under a known homography, seen through
//! dense flow, block vectors and feature matches.

use mocomp::codec::Plane;
use mocomp::features::{match_pictures, MatchParams};
use mocomp::flow::{FlowEstimator, FlowMethod, FlowOptions, Preset};
use mocomp::global::sources::{PairCorrespondences, Source};
use mocomp::global::{estimate, sources, Correspondence, GlobalError, GlobalParams, Model, Transform};
use mocomp::me::{self, MeConfig, Method, Subpel};
use mocomp::raster::plane_to_array;

/// A small deterministic generator (xorshift).
struct Random(u64);

impl Random {
    fn unit(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn truths() -> [(Model, Transform); 4] {
    [
        (
            Model::Translation,
            Transform([1.0, 0.0, 7.25, 0.0, 1.0, -3.5, 0.0, 0.0, 1.0]),
        ),
        (
            Model::Similarity,
            Transform([0.985, -0.026, 9.0, 0.026, 0.985, -12.0, 0.0, 0.0, 1.0]),
        ),
        (
            Model::Affine,
            Transform([1.03, 0.04, -5.0, -0.02, 0.96, 8.0, 0.0, 0.0, 1.0]),
        ),
        (
            Model::Homography,
            Transform([1.02, 0.03, -6.0, 0.01, 0.99, 5.0, 4e-5, -3e-5, 1.0]),
        ),
    ]
}

/// Largest distance between where `a` and `b` take the corners of a
/// `w x h` picture: the error of a camera model in pixels.
fn corner_error(a: &Transform, b: &Transform, w: f64, h: f64) -> f64 {
    [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
        .iter()
        .map(|&(x, y)| {
            let (p, q) = (a.apply(x, y).unwrap(), b.apply(x, y).unwrap());
            (p.0 - q.0).hypot(p.1 - q.1)
        })
        .fold(0.0, f64::max)
}

/// `n` correspondences of `truth` over a 640x480 picture, with Gaussian-ish
/// noise of `sigma` pixels; a share `outliers` of them moved anywhere.
fn scattered(
    truth: &Transform,
    n: usize,
    sigma: f64,
    outliers: f64,
    seed: u64,
) -> (Vec<Correspondence>, Vec<bool>) {
    let mut r = Random(seed);
    let mut points = Vec::new();
    let mut good = Vec::new();
    for _ in 0..n {
        let (x, y) = (r.unit() * 640.0, r.unit() * 480.0);
        let (mut u, mut v) = truth.apply(x, y).unwrap();
        // Sum of uniforms: near-Gaussian noise.
        let mut noise = || (0..4).map(|_| r.unit() - 0.5).sum::<f64>() * sigma * 3f64.sqrt();
        u += noise();
        v += noise();
        let wrong = r.unit() < outliers;
        if wrong {
            u += 20.0 + r.unit() * 60.0;
            v -= 15.0 + r.unit() * 40.0;
        }
        points.push(Correspondence::new((x, y), (u, v)));
        good.push(!wrong);
    }
    (points, good)
}

#[test]
fn each_model_is_recovered_exactly_through_a_third_of_outliers() {
    for (model, truth) in truths() {
        let (points, good) = scattered(&truth, 300, 0.0, 0.35, 11);
        let fit = estimate(&points, &GlobalParams::new(model)).unwrap();
        assert!(
            corner_error(&fit.transform, &truth, 640.0, 480.0) < 1e-6,
            "{model}: {:?}",
            fit.transform
        );
        assert_eq!(fit.inliers, good, "{model}");
        assert!(fit.rms < 1e-6);
        // The same input and seed, the same result.
        assert_eq!(estimate(&points, &GlobalParams::new(model)).unwrap(), fit);
    }
}

#[test]
fn noisy_correspondences_give_the_model_within_a_fraction_of_a_pixel() {
    // Noise of 0.5 px on every point and 40 % outliers: the corners within
    // 0.25 px (0.4 for a homography; a few hundred points average the
    // noise down), the outliers
    // all outside, nearly every good point inside a 2 px threshold.
    for (model, truth) in truths() {
        let (points, good) = scattered(&truth, 400, 0.5, 0.4, 5);
        let params = GlobalParams {
            threshold: 2.0,
            ..GlobalParams::new(model)
        };
        let fit = estimate(&points, &params).unwrap();
        let e = corner_error(&fit.transform, &truth, 640.0, 480.0);
        // A homography's eight parameters extrapolate the noise to the
        // corners more.
        let bound = if model == Model::Homography { 0.4 } else { 0.25 };
        assert!(e < bound, "{model}: corners {e:.3} px off");
        let caught = fit.inliers.iter().zip(&good).filter(|&(&i, &g)| i && !g).count();
        let kept = fit.inliers.iter().zip(&good).filter(|&(&i, &g)| i && g).count();
        assert_eq!(caught, 0, "{model}");
        assert!(
            kept as f64 > 0.95 * good.iter().filter(|&&g| g).count() as f64,
            "{model}"
        );
        assert!(fit.rms > 0.2 && fit.rms < 1.0, "{model}: rms {}", fit.rms);
    }
}

#[test]
fn too_few_degenerate_or_bad_settings_are_errors() {
    let one = vec![Correspondence::new((1.0, 2.0), (3.0, 4.0))];
    assert!(matches!(
        estimate(&one, &GlobalParams::new(Model::Affine)),
        Err(GlobalError::TooFewPoints { need: 3, have: 1, .. })
    ));
    let same = vec![Correspondence::new((5.0, 5.0), (6.0, 5.0)); 12];
    assert!(matches!(
        estimate(&same, &GlobalParams::new(Model::Homography)),
        Err(GlobalError::Degenerate(_))
    ));
    let fit = estimate(&same, &GlobalParams::new(Model::Translation)).unwrap();
    assert_eq!(fit.transform.apply(0.0, 0.0), Some((1.0, 0.0)));
    let nan = vec![Correspondence::new((f64::NAN, 0.0), (0.0, 0.0)); 12];
    assert!(matches!(
        estimate(&nan, &GlobalParams::new(Model::Translation)),
        Err(GlobalError::TooFewPoints { have: 0, .. })
    ));
    for threshold in [0.0, -1.0, f64::NAN] {
        let p = GlobalParams {
            threshold,
            ..GlobalParams::new(Model::Affine)
        };
        assert!(matches!(estimate(&same, &p), Err(GlobalError::Params(_))));
    }
}

/// A band-limited texture, and the pair it makes under `truth` (the second
/// picture at `p` shows the first at `truth^-1(p)`), rendered analytically.
fn warped_pair(w: usize, h: usize, truth: &Transform) -> (Plane, Plane) {
    use std::f64::consts::TAU;
    let texture = |x: f64, y: f64| {
        128.0
            + 35.0 * (TAU * x / 23.0 + 0.4).cos() * (TAU * y / 31.0).sin()
            + 25.0 * (TAU * (x + 2.0 * y) / 41.0).sin()
            + 20.0 * (TAU * (3.0 * x - y) / 37.0 + 1.0).cos()
            + 15.0 * (TAU * x / 11.0).sin() * (TAU * y / 13.0 + 0.7).cos()
    };
    let inverse = truth.inverse().unwrap();
    let first = Plane::from_fn(w, h, |x, y| {
        texture(x as f64, y as f64).round().clamp(0.0, 255.0) as u8
    })
    .unwrap();
    let second = Plane::from_fn(w, h, |x, y| {
        let (u, v) = inverse.apply(x as f64, y as f64).unwrap();
        texture(u, v).round().clamp(0.0, 255.0) as u8
    })
    .unwrap();
    (first, second)
}

#[test]
fn a_known_camera_motion_is_found_through_flow_vectors_and_matches() {
    let (w, h) = (320, 240);
    // Rotation about the centre by 1 degree, zoom 1.02, a shift of (6, -4),
    // a slight perspective.
    let (c, s) = (1f64.to_radians().cos() * 1.02, 1f64.to_radians().sin() * 1.02);
    let (cx, cy) = (160.0, 120.0);
    let truth = Transform([
        c,
        -s,
        cx - c * cx + s * cy + 6.0,
        s,
        c,
        cy - s * cx - c * cy - 4.0,
        2e-5,
        -1e-5,
        1.0,
    ]);
    let (first, second) = warped_pair(w, h, &truth);
    let (a, b) = (plane_to_array(&first), plane_to_array(&second));

    // DIS as the global-motion sources run it (finer on small pictures).
    let flow = FlowEstimator::new(&FlowOptions {
        method: FlowMethod::Dis,
        preset: Preset::Medium,
        fine_on_small: true,
        ..FlowOptions::default()
    })
    .unwrap()
    .compute(&a, &b);
    let mut vectors = MeConfig::new(Method::Esa, 16, 12);
    vectors.subpel = Subpel::Quarter;
    let field = me::estimate(&second, &first, &vectors).unwrap();
    let matches = match_pictures(&a, &b, &MatchParams::default());
    for (source, points, bound) in [
        ("flow", sources::from_flow(&flow, 8), 0.3),
        ("vectors", sources::from_vectors(&field), 0.6),
        ("matches", sources::from_matches(&matches), 0.6),
    ] {
        assert!(points.len() >= 40, "{source}: {} points", points.len());
        let fit = estimate(&points, &GlobalParams::new(Model::Homography)).unwrap();
        let e = corner_error(&fit.transform, &truth, w as f64, h as f64);
        assert!(e < bound, "{source}: corners {e:.3} px off");
        assert!(
            fit.inlier_count * 2 > points.len(),
            "{source}: {} of {}",
            fit.inlier_count,
            points.len()
        );
        // An affine map or a similarity cannot hold the perspective (about
        // 1.3 px at the far corner): worse, but close.
        for (model, within) in [(Model::Affine, 2.0), (Model::Similarity, 3.0)] {
            let params = GlobalParams {
                threshold: 2.0,
                ..GlobalParams::new(model)
            };
            let e = corner_error(
                &estimate(&points, &params).unwrap().transform,
                &truth,
                w as f64,
                h as f64,
            );
            assert!(e > 0.5 && e < within, "{source} {model}: corners {e:.3} px off");
        }
    }
}

#[test]
fn an_object_moving_against_the_camera_is_outside_the_inliers() {
    // The camera shifts everything by (3, 2); a 60x60 square moves by
    // (-9, 7) instead. Flow correspondences inside the square are outliers.
    let truth = Transform([1.0, 0.0, 3.0, 0.0, 1.0, 2.0, 0.0, 0.0, 1.0]);
    let (first, background) = warped_pair(256, 192, &truth);
    let object = Transform([1.0, 0.0, -9.0, 0.0, 1.0, 7.0, 0.0, 0.0, 1.0]);
    let (_, moved) = warped_pair(256, 192, &object);
    let inside = |x: f64, y: f64| (100.0..160.0).contains(&x) && (70.0..130.0).contains(&y);
    let second = Plane::from_fn(256, 192, |x, y| {
        if inside(x as f64, y as f64) {
            moved.get(x, y)
        } else {
            background.get(x, y)
        }
    })
    .unwrap();
    let flow = FlowEstimator::new(&FlowOptions {
        fine_on_small: true,
        ..FlowOptions::default()
    })
    .unwrap()
    .compute(&plane_to_array(&first), &plane_to_array(&second));
    let points = sources::from_flow(&flow, 4);
    let fit = estimate(&points, &GlobalParams::new(Model::Affine)).unwrap();
    assert!(
        corner_error(&fit.transform, &truth, 256.0, 192.0) < 0.2,
        "{:?}",
        fit.transform
    );
    // Well inside the square (the object's interior in the second picture,
    // away from its edges): no inlier.
    let deep = |c: &Correspondence| {
        let (x, y) = c.to;
        (110.0..150.0).contains(&x) && (80.0..120.0).contains(&y)
    };
    let in_object: Vec<bool> = points
        .iter()
        .zip(&fit.inliers)
        .filter(|(c, _)| deep(c))
        .map(|(_, &i)| i)
        .collect();
    assert!(in_object.len() > 50);
    assert!(
        in_object.iter().all(|&i| !i),
        "{} of {} inside the object follow the camera",
        in_object.iter().filter(|&&i| i).count(),
        in_object.len()
    );
}

#[test]
fn a_second_motion_a_pixel_away_does_not_pull_the_fit() {
    // A still shot's background (the left two fifths and the top rows,
    // vectors 0.05 px from the camera's motion) and a face filling the
    // rest that moves about a pixel further, unevenly (up to 0.9 px from
    // its own mean): both within reach of a reweighting at the
    // threshold's scale, which followed the face (1.09 px off at the
    // corners); the inliers' own scale keeps to the background (0.06).
    let truth = Transform([0.9998, -0.0175, 4.0, 0.0175, 0.9998, -3.0, 0.0, 0.0, 1.0]);
    let mut r = Random(23);
    let mut points = Vec::new();
    for y in (8..480).step_by(16) {
        for x in (8..640).step_by(16) {
            let (x, y) = (f64::from(x), f64::from(y));
            let (u, v) = truth.apply(x, y).unwrap();
            let (du, dv) = if x < 256.0 || y < 96.0 {
                ((r.unit() - 0.5) * 0.1, (r.unit() - 0.5) * 0.1)
            } else {
                (1.2 + (r.unit() - 0.5) * 1.8, 0.5 + (r.unit() - 0.5) * 1.8)
            };
            points.push(Correspondence::new((x, y), (u + du, v + dv)));
        }
    }
    let fit = estimate(&points, &GlobalParams::new(Model::Similarity)).unwrap();
    let e = corner_error(&fit.transform, &truth, 640.0, 480.0);
    assert!(e < 0.1, "corners {e:.3} px off");
}

#[test]
fn flat_places_weigh_little_so_their_guessed_vectors_do_not_bias_the_fit() {
    // The left half textured, the right half flat: a dense flow's vectors
    // there are the smoothness term's guess, here the camera's shift
    // (3, -2) off by (0.5, 0.4), within RANSAC's threshold of it.
    let (w, h) = (320, 240);
    let (textured, _) = warped_pair(w, h, &Transform::IDENTITY);
    let picture = Plane::from_fn(w, h, |x, y| if x < w / 2 { textured.get(x, y) } else { 128 }).unwrap();
    let truth = Transform([1.0, 0.0, 3.0, 0.0, 1.0, -2.0, 0.0, 0.0, 1.0]);
    let mut points = Vec::new();
    for y in (4..h).step_by(8) {
        for x in (4..w).step_by(8) {
            let (x, y) = (x as f64, y as f64);
            let off = if x < (w / 2) as f64 {
                (0.0, 0.0)
            } else {
                (0.5, 0.4)
            };
            points.push(Correspondence::new((x, y), (x + 3.0 + off.0, y - 2.0 + off.1)));
        }
    }
    let params = GlobalParams::new(Model::Similarity);
    let error = |points: &[Correspondence]| {
        let fit = estimate(points, &params).unwrap();
        corner_error(&fit.transform, &truth, w as f64, h as f64)
    };
    let unweighted = error(&points);
    sources::weigh_by_texture(&mut points, &plane_to_array(&picture));
    // Well inside either half: flat places weigh nothing.
    let weight_at = |x: f64| points.iter().find(|c| c.from == (x, 124.0)).unwrap().weight;
    assert!(
        weight_at(76.0) > 0.1 && weight_at(252.0) < 1e-3,
        "{} {}",
        weight_at(76.0),
        weight_at(252.0)
    );
    let weighted = error(&points);
    assert!(
        unweighted > 0.2 && weighted < 0.02,
        "corners {unweighted:.3} px off unweighted, {weighted:.3} weighted"
    );
}

/// Two windows of one random texture (detail at 3, 8 and 24 px, no
/// period a block search could lock onto at a wrong shift), the second's
/// content moved by whole pixels `(dx, dy)`.
fn panned_pair(w: usize, h: usize, dx: i64, dy: i64) -> (Plane, Plane) {
    let mut r = Random(77);
    let margin = 64;
    let (bw, bh) = (w + 2 * margin, h + 2 * margin);
    let mut big = vec![128.0f64; bw * bh];
    for (cell, amplitude) in [(3usize, 30.0), (8, 40.0), (24, 50.0)] {
        let (gw, gh) = (bw / cell + 2, bh / cell + 2);
        let grid: Vec<f64> = (0..gw * gh).map(|_| r.unit() - 0.5).collect();
        for y in 0..bh {
            for x in 0..bw {
                let (fx, fy) = (x as f64 / cell as f64, y as f64 / cell as f64);
                let (ix, iy) = (fx as usize, fy as usize);
                let (ax, ay) = (fx - ix as f64, fy - iy as f64);
                let g = |i: usize, j: usize| grid[j * gw + i];
                let v = (g(ix, iy) * (1.0 - ax) + g(ix + 1, iy) * ax) * (1.0 - ay)
                    + (g(ix, iy + 1) * (1.0 - ax) + g(ix + 1, iy + 1) * ax) * ay;
                big[y * bw + x] += amplitude * v;
            }
        }
    }
    let window = |ox: i64, oy: i64| {
        Plane::from_fn(w, h, |x, y| {
            let (bx, by) = ((x as i64 + ox) as usize, (y as i64 + oy) as usize);
            big[by * bw + bx].round().clamp(0.0, 255.0) as u8
        })
        .unwrap()
    };
    let m = margin as i64;
    (window(m, m), window(m - dx, m - dy))
}

#[test]
fn auto_takes_flow_where_the_blocks_fit_no_motion() {
    // A pan of 44 px, beyond the block search's range of 32: no block
    // finds it, while DIS's pyramid does. On a small shift the blocks fit.
    let params = GlobalParams::new(Model::Translation);
    for (dx, expected) in [(44, Source::Flow), (5, Source::Blocks)] {
        let truth = Transform([1.0, 0.0, dx as f64, 0.0, 1.0, -3.0, 0.0, 0.0, 1.0]);
        let (first, second) = panned_pair(320, 240, dx, -3);
        let mut auto = PairCorrespondences::new(Source::Auto, Preset::Medium);
        let pair = auto.fit(&first, &second, &params).unwrap();
        assert_eq!(pair.source, expected, "shift {dx}");
        let fit = pair.camera().expect("the camera's motion");
        let e = corner_error(&fit.transform, &truth, 320.0, 240.0);
        assert!(e < 0.25, "shift {dx}: corners {e:.3} px off");
        if expected == Source::Flow {
            // The blocks alone: nothing most of them follow.
            let blocks = PairCorrespondences::new(Source::Blocks, Preset::Medium)
                .fit(&first, &second, &params)
                .unwrap();
            assert!(blocks.camera().is_none(), "{:?}", blocks.fit);
        }
    }
}
