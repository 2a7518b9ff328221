//! Block matching against motion known independently of the search:
//! integer and sub-pel translations of synthetic scenes.

use mocomp::codec::mv::Mv;
use mocomp::codec::Plane;
use mocomp::me::{estimate, lambda_for_qp, search_around, MeConfig, Method, Metric, MotionField, Subpel};
use mocomp::synth::{Motion, SceneSpec, Synth};

/// Frames 1 and 0 (current, reference) of a noise-free synthetic scene
/// translated by (dx, dy) px per frame.
fn translated_pair(w: usize, h: usize, dx: f64, dy: f64, seed: u64) -> (Plane, Plane) {
    let s = Synth::new(
        SceneSpec::new("t", w, h, 2)
            .seed(seed)
            .camera(Motion::translation(dx, dy)),
    )
    .unwrap();
    let (f0, f1) = (s.frame(0), s.frame(1));
    (f1.y().clone(), f0.y().clone())
}

/// A picture whose matching cost rises like a cone around the true vector:
/// one isotropic Gaussian blob (sigma 4) in the middle of every 16x16 block,
/// moved by (shift_x, shift_y). This is the smooth, unimodal cost the fast
/// searches are designed for. (Smooth textures with long wavelengths are
/// not: within a block they are nearly a ramp, whose cost has a valley
/// along the ramp's level lines, and the patterns stop in the valley.)
fn blobs(w: usize, h: usize, shift_x: f64, shift_y: f64) -> Plane {
    Plane::from_fn(w, h, |x, y| {
        let (x, y) = (x as f64 - shift_x, y as f64 - shift_y);
        let mut v = 40.0;
        for by in -1..=(h / 16) as i32 {
            for bx in -1..=(w / 16) as i32 {
                let (cx, cy) = (16.0 * f64::from(bx) + 8.0, 16.0 * f64::from(by) + 8.0);
                v += 180.0 * (-((x - cx).powi(2) + (y - cy).powi(2)) / 32.0).exp();
            }
        }
        v.round() as u8
    })
    .unwrap()
}

/// A band-limited picture with detail in every direction, moved by a
/// sub-pixel amount exactly (rendered analytically).
fn waves(w: usize, h: usize, shift_x: f64, shift_y: f64) -> Plane {
    use std::f64::consts::TAU;
    Plane::from_fn(w, h, |x, y| {
        let (x, y) = (x as f64 - shift_x, y as f64 - shift_y);
        (128.0
            + 30.0 * (TAU * x / 11.0 + 0.3).cos()
            + 30.0 * (TAU * y / 9.0 + 1.1).cos()
            + 25.0 * (TAU * (x + y) / 15.0).sin()
            + 20.0 * (TAU * (x - 2.0 * y) / 23.0).cos())
        .round() as u8
    })
    .unwrap()
}

/// Blocks whose displaced position stays inside the picture and whose
/// pixels vary (variance above 25).
fn interior_textured(cur: &Plane, block: usize, mv: (i32, i32), range: i32) -> Vec<(usize, usize)> {
    let (cols, rows) = (cur.width() / block, cur.height() / block);
    let mut out = Vec::new();
    for r in 0..rows {
        for c in 0..cols {
            let (x, y) = ((c * block) as i32, (r * block) as i32);
            let inside = x + mv.0 - range >= 0
                && y + mv.1 - range >= 0
                && x + mv.0 + range + block as i32 <= cur.width() as i32
                && y + mv.1 + range + block as i32 <= cur.height() as i32;
            let vals: Vec<f64> = (0..block * block)
                .map(|i| f64::from(cur.get(c * block + i % block, r * block + i / block)))
                .collect();
            let mean = vals.iter().sum::<f64>() / vals.len() as f64;
            let var = vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / vals.len() as f64;
            if inside && var > 25.0 {
                out.push((c, r));
            }
        }
    }
    out
}

#[test]
fn esa_finds_integer_translations_exactly() {
    for (dx, dy, block, range) in [
        (3, -2, 16, 7),
        (-6, 5, 8, 8),
        (12, 9, 16, 16),
        (-1, 0, 4, 3),
        (20, -15, 32, 24),
    ] {
        let (cur, reference) = translated_pair(160, 128, dx as f64, dy as f64, 3);
        let field = estimate(&cur, &reference, &MeConfig::new(Method::Esa, block, range)).unwrap();
        let blocks = interior_textured(&cur, block, (-dx, -dy), 0);
        assert!(blocks.len() > 10, "too few blocks to test");
        for (c, r) in blocks {
            assert_eq!(
                field.vector(c, r),
                Mv::full_pel(-dx, -dy),
                "block ({c},{r}), shift ({dx},{dy})"
            );
            assert_eq!(field.cost(c, r), 0);
        }
    }
}

#[test]
fn fast_methods_find_translations_within_their_reach_on_smooth_cost_pictures() {
    // Range 8: every shift below is within every method's documented reach
    // (hexbs needs a pixel of room inside the window for its hexagon).
    for method in Method::ALL {
        for (dx, dy) in [(3, -2), (-5, 4), (0, 6), (7, -7), (1, 1), (-6, -3), (2, 7)] {
            let reference = blobs(128, 128, 0.0, 0.0);
            let cur = blobs(128, 128, dx as f64, dy as f64);
            let field = estimate(&cur, &reference, &MeConfig::new(method, 16, 8)).unwrap();
            let blocks = interior_textured(&cur, 16, (-dx, -dy), 0);
            assert!(blocks.len() > 5);
            let wrong: Vec<_> = blocks
                .iter()
                .filter(|&&(c, r)| field.vector(c, r) != Mv::full_pel(-dx, -dy))
                .collect();
            assert!(wrong.is_empty(), "{method} shift ({dx},{dy}): wrong at {wrong:?}");
        }
    }
}

#[test]
fn quarter_pel_refinement_lands_within_a_quarter_pixel() {
    for (dx, dy) in [(1.25, -0.5), (-2.75, 1.0), (0.5, 0.25), (3.75, -1.25)] {
        let (cur, reference) = (waves(160, 128, dx, dy), waves(160, 128, 0.0, 0.0));
        let mut cfg = MeConfig::new(Method::Esa, 16, 6);
        cfg.subpel = Subpel::Quarter;
        let field = estimate(&cur, &reference, &cfg).unwrap();
        let blocks = interior_textured(&cur, 16, (0, 0), 8);
        assert!(blocks.len() > 10);
        let (tx, ty) = (-dx * 4.0, -dy * 4.0);
        for &(c, r) in &blocks {
            let v = field.vector(c, r);
            assert!(
                (f64::from(v.x) - tx).abs() <= 1.0 && (f64::from(v.y) - ty).abs() <= 1.0,
                "shift ({dx},{dy}): block ({c},{r}) found {v:?}, want ({tx},{ty}) quarter-pel"
            );
        }
        // Half-pel refinement lands within half a pixel, on even quarter-pel values.
        cfg.subpel = Subpel::Half;
        let field = estimate(&cur, &reference, &cfg).unwrap();
        for &(c, r) in &blocks {
            let v = field.vector(c, r);
            assert!((f64::from(v.x) - tx).abs() <= 2.0 && (f64::from(v.y) - ty).abs() <= 2.0);
            assert!(v.x % 2 == 0 && v.y % 2 == 0);
        }
    }
}

#[test]
fn esa_is_never_beaten() {
    let s = Synth::new(mocomp::synth::standard_scenes().remove(0)).unwrap();
    let (cur, reference) = (s.frame(4), s.frame(3));
    for metric in Metric::ALL {
        for range in [4, 9] {
            let cfg = |m| MeConfig {
                metric,
                ..MeConfig::new(m, 8, range)
            };
            let best = estimate(cur.y(), reference.y(), &cfg(Method::Esa)).unwrap();
            for m in Method::ALL {
                let other = estimate(cur.y(), reference.y(), &cfg(m)).unwrap();
                for (i, (&e, &o)) in best.costs().iter().zip(other.costs()).enumerate() {
                    assert!(e <= o, "{metric} range {range}: esa {e} > {m} {o} at block {i}");
                }
            }
        }
    }
}

fn with_threads(n: usize, f: impl FnOnce() -> MotionField + Send) -> MotionField {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .unwrap()
        .install(f)
}

#[test]
fn parallel_results_equal_serial_ones() {
    let s = Synth::new(mocomp::synth::standard_scenes().remove(0)).unwrap();
    let (cur, reference) = (s.frame(6), s.frame(5));
    for method in Method::ALL {
        let mut cfg = MeConfig::new(method, 8, 12);
        cfg.subpel = Subpel::Quarter;
        cfg.lambda = lambda_for_qp(Metric::Sad, 28);
        let one = with_threads(1, || estimate(cur.y(), reference.y(), &cfg).unwrap());
        // Rows in a pipeline (each block reads its top-right neighbour):
        // any number of threads, several times, the same field.
        for threads in [2, 3, 4, 2, 3, 4] {
            let many = with_threads(threads, || estimate(cur.y(), reference.y(), &cfg).unwrap());
            assert_eq!(one, many, "{method} on {threads} threads");
        }
    }
}

#[test]
fn ties_go_to_the_shortest_vector_then_raster_order() {
    // A flat picture: every candidate costs 0, so (0, 0) wins.
    let flat = Plane::filled(64, 64, 90).unwrap();
    let field = estimate(&flat, &flat, &MeConfig::new(Method::Esa, 16, 8)).unwrap();
    assert!(field.vectors().iter().all(|&v| v == Mv::ZERO));
    // Vertical stripes of period 4: shifts of -4, 0, +4 columns all match;
    // the current picture is moved by 2, so -2 and +2 tie: raster order
    // (dy, then dx) picks dx = -2.
    let stripes = |shift: usize| {
        Plane::from_fn(64, 64, move |x, _| if (x + shift) % 4 < 2 { 40 } else { 200 }).unwrap()
    };
    let field = estimate(&stripes(2), &stripes(0), &MeConfig::new(Method::Esa, 16, 3)).unwrap();
    assert_eq!(field.vector(1, 1), Mv::full_pel(-2, 0));
}

#[test]
fn a_large_rate_term_pulls_vectors_to_the_predictor() {
    let (cur, reference) = translated_pair(128, 96, 2.0, 1.0, 9);
    let mut cfg = MeConfig::new(Method::Esa, 16, 6);
    let free = estimate(&cur, &reference, &cfg).unwrap();
    assert!(
        free.vectors()
            .iter()
            .filter(|&&v| v == Mv::full_pel(-2, -1))
            .count()
            > 20
    );
    cfg.lambda = 1e5;
    let priced = estimate(&cur, &reference, &cfg).unwrap();
    // With vectors this expensive, each block takes its predictor (all zero).
    assert!(
        priced.vectors().iter().all(|&v| v == Mv::ZERO),
        "{:?}",
        priced.vectors()
    );
}

#[test]
fn bad_configurations_are_errors() {
    let p = Plane::new(32, 32).unwrap();
    assert!(estimate(&p, &p, &MeConfig::new(Method::Esa, 12, 8)).is_err());
    assert!(estimate(&p, &p, &MeConfig::new(Method::Esa, 16, 0)).is_err());
    assert!(estimate(&p, &p, &MeConfig::new(Method::Esa, 16, 65)).is_err());
    assert!(estimate(
        &p,
        &Plane::new(32, 16).unwrap(),
        &MeConfig::new(Method::Esa, 16, 8)
    )
    .is_err());
    let thin = Plane::with_padding(32, 32, 16).unwrap();
    assert!(estimate(&thin, &thin, &MeConfig::new(Method::Esa, 16, 8)).is_err());
    for m in Method::ALL {
        assert_eq!(m.name().parse::<Method>(), Ok(m));
    }
    assert!("umh".parse::<Method>().is_err());
}

#[test]
fn a_seeded_search_finds_large_shifts_its_window_alone_could_not() {
    // A 19.25 x -13.5 px shift, beyond the range-3 window around zero: from
    // a seed a few pixels off (a flow's error), the search lands within a
    // quarter pixel; every fast method too, on the same window.
    let (dx, dy) = (19.25, -13.5);
    let (cur, reference) = (waves(160, 128, dx, dy), waves(160, 128, 0.0, 0.0));
    let (tx, ty) = (-dx * 4.0, -dy * 4.0);
    let seed = Mv::new(tx as i32 + 9, ty as i32 - 6);
    let blocks = interior_textured(&cur, 16, (-20, 14), 4);
    assert!(blocks.len() > 4, "too few blocks to test");
    for method in [Method::Esa, Method::Epzs, Method::Hexbs] {
        let mut cfg = MeConfig::new(method, 16, 3);
        cfg.subpel = Subpel::Quarter;
        cfg.metric = Metric::Satd;
        for &(c, r) in &blocks {
            let best = search_around(&cur, &reference, (c * 16, r * 16), seed, Mv::ZERO, &cfg).unwrap();
            let v = best.mv;
            assert!(
                (f64::from(v.x) - tx).abs() <= 1.0 && (f64::from(v.y) - ty).abs() <= 1.0,
                "{method} block ({c},{r}): {v:?}, want ({tx},{ty})"
            );
        }
    }
}

#[test]
fn a_seeded_search_keeps_an_exact_seed_and_survives_seeds_past_the_border() {
    let (cur, reference) = (waves(96, 96, 1.75, -0.5), waves(96, 96, 0.0, 0.0));
    let mut cfg = MeConfig::new(Method::Esa, 16, 2);
    cfg.subpel = Subpel::Quarter;
    let exact = Mv::new(-7, 2);
    let best = search_around(&cur, &reference, (32, 32), exact, Mv::ZERO, &cfg).unwrap();
    assert_eq!(best.mv, exact);
    // Far past the 32-pixel border: read clamped, as the decoder would; the
    // window stays around the seed.
    let far = Mv::full_pel(-400, 300);
    let best = search_around(&cur, &reference, (0, 80), far, Mv::ZERO, &cfg).unwrap();
    assert!((best.mv.x - far.x).abs() <= 2 * 4 + 3 && (best.mv.y - far.y).abs() <= 2 * 4 + 3);
    // A block outside the picture is an error, not a panic.
    assert!(search_around(&cur, &reference, (90, 0), exact, Mv::ZERO, &cfg).is_err());
}

/// Flat shapes crossing a smooth background, as in cartoons: the
/// background moves (1, 0), the shapes (5, -3) and (-4, 4).
fn cartoon(shift: bool) -> Plane {
    let (w, h) = (128usize, 96usize);
    Plane::from_fn(w, h, |x, y| {
        let t = if shift { 1.0 } else { 0.0 };
        let inside = |cx: f64, cy: f64, dx: f64, dy: f64, r: f64| {
            (x as f64 - (cx + dx * t)).abs() < r && (y as f64 - (cy + dy * t)).abs() < r
        };
        if inside(40.0, 40.0, 5.0, -3.0, 14.0) {
            200
        } else if inside(90.0, 60.0, -4.0, 4.0, 12.0) {
            60
        } else {
            (90.0 + 0.4 * (x as f64 - t) + 0.3 * y as f64) as u8
        }
    })
    .unwrap()
}

#[test]
fn epzs_window_never_loses_and_closes_on_exhaustive_search_for_flat_shapes() {
    let (reference, cur) = (cartoon(false), cartoon(true));
    let run = |method: Method, window: i32| {
        let mut cfg = MeConfig::new(method, 16, 8);
        cfg.window = window;
        estimate(&cur, &reference, &cfg).unwrap()
    };
    let (plain, windowed, esa) = (run(Method::Epzs, 0), run(Method::Epzs, 4), run(Method::Esa, 0));
    // The window only adds candidates to the same walk: no block gets worse.
    for (i, (a, b)) in plain.costs().iter().zip(windowed.costs()).enumerate() {
        assert!(b <= a, "block {i}: {b} > {a}");
    }
    let total = |f: &MotionField| f.costs().iter().map(|&c| u64::from(c)).sum::<u64>();
    let (p, w, e) = (total(&plain), total(&windowed), total(&esa));
    assert!(w < p, "the window finds nothing: {w} against {p}");
    // ... and takes most of the way to exhaustive search.
    assert!(w - e < (p - e) / 2, "plain {p}, windowed {w}, exhaustive {e}");
}

/// Pictures where successive elimination could go wrong: noise against
/// unrelated noise (bounds weak, costs close), a shifted noisy copy (one
/// sharp minimum), flat areas and stripes (many positions tie exactly, so
/// the tie-break decides), and the cartoon (flat shapes on a ramp).
fn elimination_cases() -> Vec<(&'static str, Plane, Plane)> {
    let noise = |seed: u64, w: usize, h: usize| {
        let mut s = seed;
        let v: Vec<u8> = (0..w * h)
            .map(|_| {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (s >> 56) as u8
            })
            .collect();
        Plane::from_fn(w, h, |x, y| v[y * w + x]).unwrap()
    };
    let (w, h) = (80, 64);
    let base = noise(3, w + 16, h + 16);
    let shifted = |dx: usize, dy: usize, grain: u8| {
        let n = noise(9, w, h);
        Plane::from_fn(w, h, |x, y| {
            base.get(x + dx, y + dy)
                .saturating_add(n.get(x, y) % grain.max(1))
        })
        .unwrap()
    };
    let flat = |x: usize, y: usize| {
        if (20..36).contains(&x) && (16..30).contains(&y) {
            180
        } else {
            90
        }
    };
    vec![
        ("unrelated noise", noise(1, w, h), noise(2, w, h)),
        ("shifted noisy copy", shifted(5, 3, 6), shifted(0, 0, 1)),
        (
            "flat with a patch",
            Plane::from_fn(w, h, |x, y| flat(x + 2, y)).unwrap(),
            Plane::from_fn(w, h, flat).unwrap(),
        ),
        (
            "stripes",
            Plane::from_fn(w, h, |x, _| if x % 4 < 2 { 200 } else { 30 }).unwrap(),
            Plane::from_fn(w, h, |x, _| if (x + 1) % 4 < 2 { 200 } else { 30 }).unwrap(),
        ),
        ("cartoon", cartoon(true), cartoon(false)),
    ]
}

#[test]
fn successive_elimination_gives_exactly_the_vectors_of_plain_exhaustive_search() {
    // Every block size, metric (full-pel SAD or not), rate term and sub-pel
    // step, in exhaustive search and EPZS's window: the same vector and cost
    // for every block as evaluating every position, ties included.
    let mut compared = 0;
    for (name, cur, reference) in elimination_cases() {
        for block in [4, 8, 16, 32] {
            for metric in Metric::ALL {
                for (full_pel_sad, lambda, subpel) in [
                    (false, 0.0, Subpel::None),
                    (true, lambda_for_qp(metric, 30), Subpel::Quarter),
                    (false, lambda_for_qp(metric, 22), Subpel::Half),
                ] {
                    // Windows where elimination runs for every metric, and
                    // EPZS's small window (the row kernel's, for 16x16 SAD).
                    for (method, window) in [(Method::Esa, 0), (Method::Epzs, 7), (Method::Epzs, 3)] {
                        let mut cfg = MeConfig::new(method, block, 9);
                        (cfg.metric, cfg.full_pel_sad, cfg.lambda, cfg.subpel, cfg.window) =
                            (metric, full_pel_sad, lambda, subpel, window);
                        let fast = estimate(&cur, &reference, &cfg).unwrap();
                        cfg.successive_elimination = false;
                        let plain = estimate(&cur, &reference, &cfg).unwrap();
                        let what = format!(
                            "{name}: {method} {block}x{block} {metric:?} sad {full_pel_sad} lambda {lambda}"
                        );
                        let differ = (0..fast.vectors().len()).find(|&i| {
                            (fast.vectors()[i], fast.costs()[i]) != (plain.vectors()[i], plain.costs()[i])
                        });
                        if let Some(i) = differ {
                            let (f, p) = (
                                (fast.vectors()[i], fast.costs()[i]),
                                (plain.vectors()[i], plain.costs()[i]),
                            );
                            panic!("{what}, block {i}: {f:?} against plain {p:?}");
                        }
                        compared += fast.vectors().len();
                    }
                }
            }
        }
    }
    assert!(compared > 5000, "{compared} blocks compared");
}
