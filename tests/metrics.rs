//! Metrics against hand computation and against independent implementations
//! (ffmpeg's psnr and ssim filters, scikit-image's SSIM) on a real pair.
//! The reference figures come from `samples/reference/make_tree_reference.sh`;
//! those of MS-SSIM, PSNR-HVS, CIEDE2000 (libvmaf's, which AWCY reports)
//! from `samples/reference/make_libvmaf_reference.sh`.

use std::path::Path;

use mocomp::codec::{Frame, Plane};
use mocomp::flow::Flow;
use mocomp::io::y4m::Y4mReader;
use mocomp::metrics::{
    ciede2000, flow_errors, frame_psnr, ms_ssim, psnr, psnr_hvs, sse, ssim, ssim_8x8, FrameQuality, Metrics,
    QualityAccumulator, PSNR_CAP_DB,
};
use ndarray::Array2;

fn samples() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("samples")
}

fn reference() -> serde_json::Value {
    let text = std::fs::read_to_string(samples().join("reference/tree_qcif_mpeg4.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

fn real_pair() -> (Vec<Frame>, Vec<Frame>) {
    let read = |n: &str| Y4mReader::open(&samples().join(n)).unwrap().read_all().unwrap();
    (read("tree_qcif.y4m"), read("tree_qcif_mpeg4.y4m"))
}

#[test]
fn psnr_of_a_hand_computed_case() {
    // 4x2 planes; differences 0,1,2,3 / 4,0,0,-6: SSE = 1+4+9+16+36 = 66, MSE = 8.25.
    let a = Plane::from_packed(4, 2, &[10, 10, 10, 10, 10, 10, 10, 10]).unwrap();
    let b = Plane::from_packed(4, 2, &[10, 11, 12, 13, 14, 10, 10, 4]).unwrap();
    assert_eq!(sse(&a, &b), 66);
    let want = 10.0 * (255.0f64 * 255.0 / 8.25).log10(); // 38.9663 dB
    assert!((psnr(&a, &b) - want).abs() < 1e-12);
    assert!((want - 38.9663).abs() < 1e-4);
}

#[test]
fn identical_planes_give_the_finite_cap() {
    let a = Plane::filled(5, 5, 77).unwrap();
    assert_eq!(psnr(&a, &a), PSNR_CAP_DB);
    let f = Frame::filled(5, 5, 1, 2, 3).unwrap();
    let p = frame_psnr(&f, &f);
    assert_eq!((p.y, p.u, p.v, p.yuv()), (100.0, 100.0, 100.0, 100.0));
}

#[test]
fn yuv_psnr_is_weighted_six_one_one() {
    let a = Frame::filled(8, 8, 100, 100, 100).unwrap();
    let b = Frame::filled(8, 8, 101, 102, 104).unwrap(); // MSE 1, 4, 16
    let p = frame_psnr(&a, &b);
    let db = |mse: f64| 10.0 * (65025.0 / mse).log10();
    assert!((p.yuv() - (6.0 * db(1.0) + db(4.0) + db(16.0)) / 8.0).abs() < 1e-12);
}

#[test]
fn psnr_matches_ffmpeg_on_a_real_pair() {
    let r = reference();
    let (a, b) = real_pair();
    let per_frame = r["ffmpeg_psnr_per_frame"].as_array().unwrap();
    assert_eq!(per_frame.len(), a.len());
    let mut acc = QualityAccumulator::default();
    for ((fa, fb), ff) in a.iter().zip(&b).zip(per_frame) {
        let q = FrameQuality::measure(fa, fb);
        // ffmpeg prints per-frame values with two decimals.
        for (ours, key) in [
            (q.psnr.y, "psnr_y"),
            (q.psnr.u, "psnr_u"),
            (q.psnr.v, "psnr_v"),
            (q.psnr.mse[0], "mse_y"),
        ] {
            let theirs = ff[key].as_f64().unwrap();
            assert!(
                (ours - theirs).abs() <= 0.005 + 1e-9,
                "{key}: {ours} vs ffmpeg {theirs}"
            );
        }
        acc.push(&q);
    }
    let s = acc.summary().unwrap();
    // Sequence PSNR as rd_ffmpeg.sh computes it: the mean of ffmpeg's per-frame values.
    let ff_mean = per_frame
        .iter()
        .map(|f| f["psnr_y"].as_f64().unwrap())
        .sum::<f64>()
        / per_frame.len() as f64;
    assert!((s.psnr_y - ff_mean).abs() < 0.01, "{} vs {ff_mean}", s.psnr_y);
    // ffmpeg's summary line (PSNR of the mean MSE) has six decimals.
    let avg = &r["ffmpeg_psnr_of_mean_mse"];
    for (ours, key) in [(s.psnr_y_mse, "y"), (s.psnr_u_mse, "u"), (s.psnr_v_mse, "v")] {
        let theirs = avg[key].as_f64().unwrap();
        assert!((ours - theirs).abs() < 1e-5, "{key}: {ours} vs ffmpeg {theirs}");
    }
}

#[test]
fn ssim_matches_scikit_image_on_a_real_pair() {
    // Same definition (Gaussian 11x11, sigma 1.5, population statistics,
    // mean over the valid region), both in double precision: they agree to
    // about 1e-15 here; the bound is 1e-9.
    let r = reference();
    let (a, b) = real_pair();
    let want = r["skimage_ssim_y_per_frame"].as_array().unwrap();
    assert_eq!(want.len(), a.len());
    for ((fa, fb), w) in a.iter().zip(&b).zip(want) {
        let (ours, theirs) = (ssim(fa.y(), fb.y()), w.as_f64().unwrap());
        assert!((ours - theirs).abs() < 1e-9, "{ours} vs scikit-image {theirs}");
    }
}

#[test]
fn ssim_8x8_matches_ffmpeg_on_a_real_pair_and_on_it_darkened() {
    // ffmpeg prints six decimals; it sums windows in single precision.
    let r = reference();
    let (a, b) = real_pair();
    let dark = |f: &Frame| Plane::from_fn(f.width(), f.height(), |x, y| f.y().get(x, y) / 32).unwrap();
    for (key, darken) in [
        ("ffmpeg_ssim_y_per_frame", false),
        ("ffmpeg_ssim_y_dark_per_frame", true),
    ] {
        let want = r[key].as_array().unwrap();
        assert_eq!(want.len(), a.len());
        for ((fa, fb), w) in a.iter().zip(&b).zip(want) {
            let ours = if darken {
                ssim_8x8(&dark(fa), &dark(fb))
            } else {
                ssim_8x8(fa.y(), fb.y())
            };
            let theirs = w.as_f64().unwrap();
            assert!((ours - theirs).abs() < 2e-6, "{key}: {ours} vs ffmpeg {theirs}");
        }
    }
}

#[test]
fn ssim_is_symmetric_and_falls_with_distortion() {
    let (a, b) = real_pair();
    let (pa, pb) = (a[0].y(), b[0].y());
    assert!((ssim(pa, pb) - ssim(pb, pa)).abs() < 1e-12);
    assert_eq!(ssim(pa, pa), 1.0);
    // More noise, lower SSIM.
    let noisy = |amp: i32| {
        Plane::from_fn(pa.width(), pa.height(), |x, y| {
            let n = ((x * 7919 + y * 104729) % 17) as i32 - 8;
            (pa.get(x, y) as i32 + n * amp / 8).clamp(0, 255) as u8
        })
        .unwrap()
    };
    let s: Vec<f64> = [2, 8, 32].iter().map(|&amp| ssim(pa, &noisy(amp))).collect();
    assert!(s[0] > s[1] && s[1] > s[2], "{s:?}");
}

#[test]
fn flow_errors_of_hand_computed_fields() {
    // Ground truth (1, 0) on the left column, (3, 4) on the right, one invalid pixel.
    let gt_u = ndarray::arr2(&[[1.0f32, 3.0], [1.0, 3.0]]);
    let gt_v = ndarray::arr2(&[[0.0f32, 4.0], [0.0, 4.0]]);
    let mut valid = Array2::from_elem((2, 2), true);
    valid[[1, 1]] = false;
    let gt = Flow::from_parts(gt_u, gt_v, valid);
    let est = Flow::zeros(2, 2);
    let e = flow_errors(&est, &gt).unwrap();
    assert_eq!(e.pixels, 3);
    // EPE: 1, 5, 1 -> 7/3.
    assert!((e.epe - 7.0 / 3.0).abs() < 1e-12);
    // AE: acos(1/sqrt(2)) = 45 deg twice; acos(1/sqrt(26)) = 78.690 deg once.
    let ae_far = (1.0f64 / 26.0f64.sqrt()).acos().to_degrees();
    assert!((e.ae - (45.0 + 45.0 + ae_far) / 3.0).abs() < 1e-9);
    assert!((ae_far - 78.690).abs() < 1e-3);
    assert!((e.r1 - 100.0 / 3.0).abs() < 1e-12, "EPE exactly 1 is not above 1");
    assert!((e.r3 - 100.0 / 3.0).abs() < 1e-12);
    // A perfect estimate has zero error; no valid pixel gives None.
    let perfect = flow_errors(&gt, &gt).unwrap();
    assert_eq!((perfect.epe, perfect.ae, perfect.r1), (0.0, 0.0, 0.0));
    let none = Flow::from_parts(
        Array2::zeros((1, 1)),
        Array2::zeros((1, 1)),
        Array2::from_elem((1, 1), false),
    );
    assert!(flow_errors(&none, &none).is_none());
}

#[test]
fn angular_error_sees_small_motion_differences_epe_does_not_scale() {
    // The 1 as third component makes AE sensitive to errors on small motion.
    let gt = Flow::from_fn(1, 1, |_, _| (0.1, 0.0));
    let est = Flow::from_fn(1, 1, |_, _| (0.2, 0.0));
    let e = flow_errors(&est, &gt).unwrap();
    let want = ((0.02f64 + 1.0) / ((0.01f64 + 1.0) * (0.04 + 1.0)).sqrt())
        .acos()
        .to_degrees();
    assert!((e.ae - want).abs() < 1e-6 && (e.epe - 0.1).abs() < 1e-6);
}

fn libvmaf_reference() -> Vec<serde_json::Value> {
    let text = std::fs::read_to_string(samples().join("reference/libvmaf_metrics.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["pairs"].as_array().unwrap().clone()
}

/// Each libvmaf pair's frames and its reference figures.
fn libvmaf_pairs() -> Vec<(Vec<Frame>, Vec<Frame>, serde_json::Value)> {
    let read = |n: &serde_json::Value| {
        Y4mReader::open(&samples().join(n.as_str().unwrap()))
            .unwrap()
            .read_all()
            .unwrap()
    };
    libvmaf_reference()
        .into_iter()
        .map(|p| (read(&p["reference"]), read(&p["test"]), p))
        .collect()
}

fn per_frame(v: &serde_json::Value, key: &str) -> Vec<f64> {
    v[key]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn psnr_hvs_matches_libvmaf_on_real_pairs() {
    for (a, b, r) in libvmaf_pairs() {
        let (y, total) = (per_frame(&r, "psnr_hvs_y"), per_frame(&r, "psnr_hvs"));
        let (cb, cr) = (per_frame(&r, "psnr_hvs_cb"), per_frame(&r, "psnr_hvs_cr"));
        assert_eq!(y.len(), a.len());
        for i in 0..a.len() {
            let got = psnr_hvs(&a[i], &b[i]);
            for (g, w) in [
                (got.y, y[i]),
                (got.cb, cb[i]),
                (got.cr, cr[i]),
                (got.total, total[i]),
            ] {
                assert!(
                    (g - w).abs() < 1e-4,
                    "{}: frame {i}: {g} against libvmaf's {w}",
                    r["test"]
                );
            }
        }
    }
}

#[test]
fn ciede2000_matches_libvmaf_on_real_pairs() {
    for (a, b, r) in libvmaf_pairs() {
        for (i, want) in per_frame(&r, "ciede2000").into_iter().enumerate() {
            let got = ciede2000(&a[i], &b[i]);
            assert!(
                (got - want).abs() < 1e-4,
                "{}: frame {i}: {got} against {want}",
                r["test"]
            );
        }
    }
}

#[test]
fn ms_ssim_matches_libvmaf_on_a_real_pair() {
    let pairs = libvmaf_pairs();
    let (a, b, r) = pairs
        .iter()
        .find(|(_, _, r)| r.get("float_ms_ssim").is_some())
        .unwrap();
    for (i, want) in per_frame(r, "float_ms_ssim").into_iter().enumerate() {
        let got = ms_ssim(a[i].y(), b[i].y());
        // libvmaf filters in single precision with taps rounded to 6 digits.
        assert!((got - want).abs() < 5e-5, "frame {i}: {got} against {want}");
    }
}

#[test]
fn measure_with_computes_only_what_is_asked() {
    let (a, b) = real_pair();
    let q = FrameQuality::measure_with(&a[0], &b[0], "ms-ssim,ciede2000".parse::<Metrics>().unwrap());
    assert!(q.ssim.is_nan() && q.psnr_hvs.is_nan() && q.vmaf.is_nan());
    assert!(q.ms_ssim > 0.9 && q.ms_ssim < 1.0, "{q:?}");
    assert_eq!(q.ciede2000, ciede2000(&a[0], &b[0]));
    let all = FrameQuality::measure_with(&a[0], &b[0], Metrics::all_builtin());
    assert_eq!(all.psnr_hvs, psnr_hvs(&a[0], &b[0]).total);
    assert_eq!(all.ssim, FrameQuality::measure(&a[0], &b[0]).ssim);
}

#[test]
fn the_new_metrics_fall_as_distortion_grows() {
    // Same picture, more and more noise: each metric must rank them.
    let clean = libvmaf_pairs().swap_remove(1).0.swap_remove(0);
    let noisy = |amp: i32| {
        let mut f = clean.clone();
        for p in 0..3 {
            let plane = f.plane_mut(p);
            for y in 0..plane.height() {
                for x in 0..plane.width() {
                    let n = ((x * 7919 + y * 104_729 + p * 31) % 17) as i32 - 8;
                    let v = i32::from(plane.get(x, y)) + n * amp / 8;
                    plane.set(x, y, v.clamp(0, 255) as u8);
                }
            }
        }
        f
    };
    let (mild, strong) = (noisy(2), noisy(8));
    let all = Metrics::all_builtin();
    let (qm, qs) = (
        FrameQuality::measure_with(&clean, &mild, all),
        FrameQuality::measure_with(&clean, &strong, all),
    );
    assert!(
        qm.ms_ssim > qs.ms_ssim && qm.psnr_hvs > qs.psnr_hvs && qm.ciede2000 > qs.ciede2000,
        "{qm:?} {qs:?}"
    );
    let same = FrameQuality::measure_with(&clean, &clean, all);
    assert_eq!((same.psnr_hvs, same.ciede2000), (PSNR_CAP_DB, 100.0));
    assert!((same.ms_ssim - 1.0).abs() < 1e-12);
}

#[test]
fn vmaf_through_ffmpeg_matches_libvmaf_where_there_is_one() {
    // Runs where an ffmpeg with libvmaf exists (MOCOMP_FFMPEG or the PATH);
    // elsewhere the error must say what is missing.
    let (a, b, r) = libvmaf_pairs().swap_remove(1);
    match mocomp::metrics::vmaf::vmaf(&a, &b) {
        Ok(got) => {
            let want = per_frame(&r, "vmaf");
            assert_eq!(got.len(), want.len());
            for (g, w) in got.iter().zip(&want) {
                // Another libvmaf build may round differently; the model is the same.
                assert!((g - w).abs() < 0.05, "{got:?} against {want:?}");
            }
        }
        Err(e) => {
            // CI brings an ffmpeg with libvmaf and says so: there it must work.
            assert!(std::env::var_os("MOCOMP_REQUIRE_VMAF").is_none(), "{e}");
            assert!(matches!(e, mocomp::metrics::vmaf::VmafError::NoLibvmaf), "{e}");
        }
    }
}
