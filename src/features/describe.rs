//! Binary descriptors: 256 intensity comparisons between point pairs of a
//! smoothed patch (BRIEF, Calonder et al. 2010), the pattern turned by the
//! keypoint's orientation (steered BRIEF, as ORB does).

use std::sync::OnceLock;

use ndarray::Array2;

use super::detect::{Keypoint, BORDER};

/// 256 bits.
pub type Descriptor = [u64; 4];

/// Number of bits that differ.
#[inline(always)]
pub fn hamming(a: &Descriptor, b: &Descriptor) -> u32 {
    a.iter().zip(b).map(|(x, y)| (x ^ y).count_ones()).sum()
}

/// Half-side of the square the pattern's points are drawn in.
const PATCH_RADIUS: f32 = 13.0;

/// The comparison pattern: 256 pairs of offsets, drawn once from an
/// isotropic Gaussian (sigma a fifth of the patch side, as BRIEF's best
/// pattern), clipped to the patch, with a fixed generator so every build
/// and every run compares the same points.
fn pattern() -> &'static [[f32; 4]; 256] {
    static PATTERN: OnceLock<[[f32; 4]; 256]> = OnceLock::new();
    PATTERN.get_or_init(|| {
        // xorshift64*: small, fixed, good enough for a sampling pattern.
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut uniform = move || {
            state ^= state >> 12;
            state ^= state << 25;
            state ^= state >> 27;
            ((state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 40) as f32 + 0.5) / (1u64 << 24) as f32
        };
        let sigma = 2.0 * PATCH_RADIUS / 5.0;
        let mut gauss = move || {
            // Box-Muller.
            let (a, b) = (uniform(), uniform());
            let g = (-2.0 * a.ln()).sqrt() * (std::f32::consts::TAU * b).cos();
            (g * sigma).clamp(-PATCH_RADIUS, PATCH_RADIUS)
        };
        let mut out = [[0f32; 4]; 256];
        for p in out.iter_mut() {
            *p = [gauss(), gauss(), gauss(), gauss()];
        }
        out
    })
}

/// The descriptor of a keypoint found on `smoothed` (its pyramid level,
/// blurred), at level position (x, y).
pub(super) fn describe(smoothed: &Array2<f32>, kp: &Keypoint) -> Descriptor {
    let scale = (1usize << kp.level) as f32;
    let (x, y) = ((kp.x + 0.5) / scale - 0.5, (kp.y + 0.5) / scale - 0.5);
    let (s, c) = kp.angle.sin_cos();
    let (h, w) = smoothed.dim();
    // The rotated pattern reaches PATCH_RADIUS * sqrt(2) < BORDER.
    debug_assert!(x >= BORDER as f32 - 1.0 && y >= BORDER as f32 - 1.0);
    let at = |dx: f32, dy: f32| {
        let px = (x + c * dx - s * dy).round().clamp(0.0, (w - 1) as f32) as usize;
        let py = (y + s * dx + c * dy).round().clamp(0.0, (h - 1) as f32) as usize;
        smoothed[[py, px]]
    };
    let mut d = [0u64; 4];
    for (i, &[ax, ay, bx, by]) in pattern().iter().enumerate() {
        if at(ax, ay) < at(bx, by) {
            d[i / 64] |= 1 << (i % 64);
        }
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pattern_is_spread_and_fixed() {
        let p = pattern();
        let spread = p.iter().map(|q| q[0].abs()).sum::<f32>() / 256.0;
        assert!(spread > 2.0 && spread < 8.0, "{spread}");
        assert!(p.iter().all(|q| q.iter().all(|v| v.abs() <= PATCH_RADIUS)));
        assert_ne!(p[0], p[1]);
    }

    #[test]
    fn hamming_counts_differing_bits() {
        assert_eq!(hamming(&[0, 0, 0, 0], &[1, 3, 0, u64::MAX]), 67);
    }

    #[test]
    fn a_turned_picture_keeps_its_descriptor() {
        // A blob pattern around (40, 40), and the same turned 90 degrees:
        // with the keypoint angles turned too, the bits agree.
        let f = |x: f32, y: f32| 128.0 + 60.0 * (x / 3.0).sin() * (y / 4.0).cos() + 0.5 * x;
        let a = Array2::from_shape_fn((81, 81), |(y, x)| f(x as f32 - 40.0, y as f32 - 40.0));
        let b = Array2::from_shape_fn((81, 81), |(y, x)| f(y as f32 - 40.0, 40.0 - x as f32));
        let kp = |angle| Keypoint {
            x: 40.0,
            y: 40.0,
            level: 0,
            angle,
            response: 1.0,
        };
        let (da, db) = (
            describe(&a, &kp(0.0)),
            describe(&b, &kp(std::f32::consts::FRAC_PI_2)),
        );
        assert!(hamming(&da, &db) < 20, "{}", hamming(&da, &db));
        let unturned = describe(&b, &kp(0.0));
        assert!(hamming(&da, &unturned) > 60, "{}", hamming(&da, &unturned));
    }
}
