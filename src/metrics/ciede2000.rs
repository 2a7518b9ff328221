//! CIEDE2000 colour difference (Sharma, Wu, Dalal 2005) as libvmaf's
//! `ciede` (after Daala's `dump_ciede2000`) computes it, which AWCY reports
//! as "CIEDE2000".
//!
//! Every luma position with its nearest chroma samples is converted from
//! limited-range BT.709 Y'CbCr to sRGB-like R'G'B', linearised, taken to
//! CIE XYZ and L*a*b* (D65 white), and the two pictures' colours compared
//! with CIEDE2000 at weights kL = 0.65, kC = 1, kH = 4 (Daala's, tuned for
//! video). The figure is `45 - 20 log10(mean dE)`: higher is better, like
//! PSNR; identical pictures score 100.

use rayon::prelude::*;

use crate::codec::Frame;

/// The score of identical pictures (and the cap).
const IDENTICAL: f64 = 100.0;

/// A colour in CIE L*a*b*.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Lab {
    l: f64,
    a: f64,
    b: f64,
}

/// CIEDE2000 of `test` against `reference` (4:2:0 frames of one size), dB
/// as above. Panics if the sizes differ.
///
/// ```
/// use mocomp::codec::Frame;
/// let a = Frame::filled(16, 16, 100, 128, 128).unwrap();
/// assert_eq!(mocomp::metrics::ciede2000(&a, &a), 100.0);
/// let b = Frame::filled(16, 16, 100, 140, 128).unwrap();
/// assert!(mocomp::metrics::ciede2000(&a, &b) < 45.0);
/// ```
pub fn ciede2000(reference: &Frame, test: &Frame) -> f64 {
    assert!(
        reference.width() == test.width() && reference.height() == test.height(),
        "ciede2000: frames of different sizes"
    );
    let (w, h) = (reference.width(), reference.height());
    // The rows' sums added in order: rayon's own sum splits the work as
    // its threads steal it, and floating-point addition in another order
    // moved the last digit from one call to the next.
    let rows: Vec<f64> = (0..h)
        .into_par_iter()
        .map(|y| row_difference(reference, test, y))
        .collect();
    let sum: f64 = rows.iter().sum();
    let mean = sum / (w * h) as f64;
    if mean <= 0.0 {
        return IDENTICAL;
    }
    (45.0 - 20.0 * mean.log10()).min(IDENTICAL)
}

/// Sum of dE over row `y`.
fn row_difference(a: &Frame, b: &Frame, y: usize) -> f64 {
    let (ya, ua, va) = (a.y().row(y), a.u().row(y / 2), a.v().row(y / 2));
    let (yb, ub, vb) = (b.y().row(y), b.u().row(y / 2), b.v().row(y / 2));
    let mut sum = 0.0;
    for x in 0..a.width() {
        let p = (ya[x], ua[x / 2], va[x / 2]);
        let q = (yb[x], ub[x / 2], vb[x / 2]);
        if p != q {
            sum += delta_e_2000(to_lab(p), to_lab(q));
        }
    }
    sum
}

/// Limited-range BT.709 Y'CbCr (8 bits) to L*a*b*.
fn to_lab((y, u, v): (u8, u8, u8)) -> Lab {
    let y = (f64::from(y) - 16.0) / 219.0;
    let u = (f64::from(u) - 128.0) / 224.0;
    let v = (f64::from(v) - 128.0) / 224.0;
    let r = linear(y + 1.28033 * v);
    let g = linear(y - 0.21482 * u - 0.38059 * v);
    let b = linear(y + 2.12798 * u);
    // Linear sRGB primaries to XYZ, then relative to the D65 white.
    let x = (0.4124564390896921 * r + 0.357576077643909 * g + 0.18043748326639894 * b) / 0.95047;
    let yy = 0.21267285140562248 * r + 0.715152155287818 * g + 0.07217499330655958 * b;
    let z = (0.019333895582329317 * r + 0.119192025881303 * g + 0.9503040785363677 * b) / 1.08883;
    let (fx, fy, fz) = (lab_f(x), lab_f(yy), lab_f(z));
    Lab {
        l: 116.0 * fy - 16.0,
        a: 500.0 * (fx - fy),
        b: 200.0 * (fy - fz),
    }
}

/// The sRGB transfer inverted, with Daala's threshold (10/255) between the
/// linear and the power segments.
fn linear(c: f64) -> f64 {
    if c > 10.0 / 255.0 {
        ((c + 0.055) / 1.055).powf(2.4)
    } else {
        c / 12.92
    }
}

/// CIE's cube root with its linear segment near black.
fn lab_f(t: f64) -> f64 {
    const EPSILON: f64 = 216.0 / 24389.0;
    const KAPPA: f64 = 24389.0 / 27.0;
    if t > EPSILON {
        t.cbrt()
    } else {
        (KAPPA * t + 16.0) / 116.0
    }
}

/// CIEDE2000 between two colours with Daala's weights.
fn delta_e_2000(c1: Lab, c2: Lab) -> f64 {
    delta_e_2000_weighted(c1, c2, [0.65, 1.0, 4.0])
}

/// CIEDE2000 with weights kL, kC, kH.
fn delta_e_2000_weighted(c1: Lab, c2: Lab, [kl, kc, kh]: [f64; 3]) -> f64 {
    use std::f64::consts::PI;
    let pow7 = |v: f64| v.powi(7);
    let chroma = |c: Lab| c.a.hypot(c.b);
    let c_bar = (chroma(c1) + chroma(c2)) / 2.0;
    let g = 0.5 * (1.0 - (pow7(c_bar) / (pow7(c_bar) + pow7(25.0))).sqrt());
    let (a1, a2) = ((1.0 + g) * c1.a, (1.0 + g) * c2.a);
    let (cp1, cp2) = (a1.hypot(c1.b), a2.hypot(c2.b));
    let hue = |b: f64, a: f64| {
        if a == 0.0 && b == 0.0 {
            0.0
        } else {
            b.atan2(a).rem_euclid(2.0 * PI)
        }
    };
    let (h1, h2) = (hue(c1.b, a1), hue(c2.b, a2));
    let dh = if cp1 * cp2 == 0.0 {
        0.0
    } else if (h2 - h1).abs() <= PI {
        h2 - h1
    } else if h2 <= h1 {
        h2 - h1 + 2.0 * PI
    } else {
        h2 - h1 - 2.0 * PI
    };
    let d_l = c2.l - c1.l;
    let d_c = cp2 - cp1;
    let d_h = 2.0 * (cp1 * cp2).sqrt() * (dh / 2.0).sin();
    let l_bar = (c1.l + c2.l) / 2.0;
    let cp_bar = (cp1 + cp2) / 2.0;
    let h_bar = if cp1 * cp2 == 0.0 {
        h1 + h2
    } else if (h1 - h2).abs() > PI {
        (h1 + h2 + 2.0 * PI) / 2.0
    } else {
        (h1 + h2) / 2.0
    };
    let t = 1.0 - 0.17 * (h_bar - PI / 6.0).cos()
        + 0.24 * (2.0 * h_bar).cos()
        + 0.32 * (3.0 * h_bar + PI / 30.0).cos()
        - 0.20 * (4.0 * h_bar - 63.0 * PI / 180.0).cos();
    let s_l = 1.0 + 0.015 * (l_bar - 50.0).powi(2) / (20.0 + (l_bar - 50.0).powi(2)).sqrt();
    let s_c = 1.0 + 0.045 * cp_bar;
    let s_h = 1.0 + 0.015 * cp_bar * t;
    let rotation = (h_bar.to_degrees() - 275.0) / 25.0;
    let r_t = -2.0
        * (pow7(cp_bar) / (pow7(cp_bar) + pow7(25.0))).sqrt()
        * (60.0 * (-rotation * rotation).exp()).to_radians().sin();
    let (l, c, h) = (d_l / (kl * s_l), d_c / (kc * s_c), d_h / (kh * s_h));
    (l * l + c * c + h * h + r_t * c * h).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lab(l: f64, a: f64, b: f64) -> Lab {
        Lab { l, a, b }
    }

    #[test]
    fn sharma_wu_dalal_test_pairs() {
        // Pairs 1, 7, 17 and 25 of their table 1, at kL = kC = kH = 1.
        let pairs = [
            (lab(50.0, 2.6772, -79.7751), lab(50.0, 0.0, -82.7485), 2.0425),
            (lab(50.0, 0.0, 0.0), lab(50.0, -1.0, 2.0), 2.3669),
            (lab(50.0, 2.5, 0.0), lab(73.0, 25.0, -18.0), 27.1492),
            (
                lab(60.2574, -34.0099, 36.2677),
                lab(60.4626, -34.1751, 39.4387),
                1.2644,
            ),
        ];
        for (c1, c2, want) in pairs {
            let d = delta_e_2000_weighted(c1, c2, [1.0; 3]);
            assert!((d - want).abs() < 5e-5, "{d} {want}");
            assert!((delta_e_2000_weighted(c2, c1, [1.0; 3]) - d).abs() < 1e-9);
        }
    }

    #[test]
    fn daala_weights_divide_lightness_and_hue() {
        // Only lightness differs, at l_bar = 50 (S_L = 1): dE = dL / 0.65.
        let d = delta_e_2000(lab(40.0, 0.0, 0.0), lab(60.0, 0.0, 0.0));
        assert!((d - 20.0 / 0.65).abs() < 1e-12);
        // Only chroma differs (same hue): the weights leave it alone.
        let (c1, c2) = (lab(50.0, 10.0, 0.0), lab(50.0, 12.0, 0.0));
        assert!((delta_e_2000(c1, c2) - delta_e_2000_weighted(c1, c2, [1.0; 3])).abs() < 1e-12);
    }

    #[test]
    fn grey_maps_to_neutral_lab() {
        let grey = to_lab((126, 128, 128));
        assert!(grey.a.abs() < 1e-9 && grey.b.abs() < 1e-9);
        let white = to_lab((235, 128, 128));
        assert!((white.l - 100.0).abs() < 1e-3, "{white:?}");
        let black = to_lab((16, 128, 128));
        assert!(black.l.abs() < 1e-9, "{black:?}");
    }
}
