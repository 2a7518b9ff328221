//! Procedural textures, defined on the whole plane so that any warp of them
//! can be rendered exactly: band-limited gradient noise at several scales,
//! hard straight edges, and regions where the fine detail fades out.

use std::f64::consts::TAU;

/// SplitMix64 finaliser: a well-mixed 64-bit hash. Used instead of a
/// generator crate so that samples stay identical across crate versions.
#[inline]
pub(crate) fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[inline]
pub(crate) fn hash3(seed: u64, a: i64, b: i64) -> u64 {
    mix64(mix64(seed ^ mix64(a as u64)) ^ (b as u64))
}

/// Uniform in [0, 1) from a hash.
#[inline]
pub(crate) fn unit(h: u64) -> f64 {
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// Standard normal from two hashes (Box-Muller).
#[inline]
pub(crate) fn gaussian(h1: u64, h2: u64) -> f64 {
    let u1 = unit(h1).max(1e-300);
    let u2 = unit(h2);
    (-2.0 * u1.ln()).sqrt() * (TAU * u2).cos()
}

/// Sixteen unit gradient directions, k * 22.5 degrees.
const GRADIENTS: [(f64, f64); 16] = {
    const C: f64 = 0.923_879_532_511_286_7; // cos 22.5 deg
    const S: f64 = 0.382_683_432_365_089_8; // sin 22.5 deg
    const H: f64 = std::f64::consts::FRAC_1_SQRT_2;
    [
        (1.0, 0.0),
        (C, S),
        (H, H),
        (S, C),
        (0.0, 1.0),
        (-S, C),
        (-H, H),
        (-C, S),
        (-1.0, 0.0),
        (-C, -S),
        (-H, -H),
        (-S, -C),
        (0.0, -1.0),
        (S, -C),
        (H, -H),
        (C, -S),
    ]
};

#[inline]
fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// Perlin gradient noise on the unit lattice, roughly in [-1, 1].
pub(crate) fn gradient_noise(seed: u64, x: f64, y: f64) -> f64 {
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (ix, iy) = (x0 as i64, y0 as i64);
    let corner = |dx: i64, dy: i64| {
        let (gx, gy) = GRADIENTS[(hash3(seed, ix + dx, iy + dy) & 15) as usize];
        gx * (fx - dx as f64) + gy * (fy - dy as f64)
    };
    let (sx, sy) = (fade(fx), fade(fy));
    let top = corner(0, 0) + sx * (corner(1, 0) - corner(0, 0));
    let bottom = corner(0, 1) + sx * (corner(1, 1) - corner(0, 1));
    1.4 * (top + sy * (bottom - top))
}

/// A straight edge: `step` is added on the side where `nx x + ny y > d`.
#[derive(Debug, Clone, Copy)]
struct Edge {
    nx: f64,
    ny: f64,
    d: f64,
    step: f64,
}

/// A scene texture: luma and chroma as functions of continuous coordinates.
#[derive(Debug, Clone)]
pub struct Texture {
    seed: u64,
    /// (wavelength in px, amplitude in levels) of each noise octave.
    octaves: Vec<(f64, f64)>,
    edges: Vec<Edge>,
    /// Wavelength of the mask that fades fine detail out (smooth regions).
    mask_wavelength: f64,
    mean: f64,
}

/// Luma and chroma of a texture at one point.
#[derive(Debug, Clone, Copy, Default)]
pub struct Sample {
    /// Luma, 0..255 scale (not clamped).
    pub y: f64,
    /// Cb, 0..255 scale.
    pub u: f64,
    /// Cr, 0..255 scale.
    pub v: f64,
}

impl Texture {
    /// A background-style texture: 1/f-like noise from 64 px down to 4 px
    /// wavelength, a few hard edges across a region of `extent` px around
    /// the origin, and low-detail patches.
    pub fn scene(seed: u64, extent: f64) -> Texture {
        let octaves = vec![(64.0, 30.0), (32.0, 26.0), (16.0, 24.0), (8.0, 22.0), (4.0, 14.0)];
        let edges = (0..6)
            .map(|k| {
                let h = hash3(seed, 1000 + k, 7);
                let angle = TAU * unit(h);
                let (nx, ny) = (angle.cos(), angle.sin());
                // Lines through points spread over the region.
                let px = extent * (unit(mix64(h)) - 0.2);
                let py = extent * (unit(mix64(h ^ 1)) - 0.2);
                let step = if k % 2 == 0 { 22.0 } else { -22.0 };
                Edge {
                    nx,
                    ny,
                    d: nx * px + ny * py,
                    step,
                }
            })
            .collect();
        Texture {
            seed,
            octaves,
            edges,
            mask_wavelength: 90.0,
            mean: 124.0,
        }
    }

    /// An object texture: busier and higher contrast than a scene, no edges
    /// inside (its outline is the edge), no smooth patches.
    pub fn object(seed: u64) -> Texture {
        Texture {
            seed,
            octaves: vec![(24.0, 45.0), (12.0, 36.0), (6.0, 26.0)],
            edges: Vec::new(),
            mask_wavelength: 0.0,
            mean: 140.0,
        }
    }

    /// The texture at (x, y).
    pub fn sample(&self, x: f64, y: f64) -> Sample {
        let mut detail = 0.0;
        let mut coarse = 0.0;
        for (i, &(wl, amp)) in self.octaves.iter().enumerate() {
            let n = amp * gradient_noise(self.seed.wrapping_add(i as u64), x / wl, y / wl);
            if i == 0 {
                coarse += n;
            } else {
                detail += n;
            }
        }
        if self.mask_wavelength > 0.0 {
            // Fine detail fades to nothing where the mask noise is low,
            // leaving smooth regions (the aperture problem, flat blocks).
            let m = gradient_noise(
                self.seed ^ 0xA5A5,
                x / self.mask_wavelength,
                y / self.mask_wavelength,
            );
            detail *= ((m + 0.4) * 3.0).clamp(0.0, 1.0);
        }
        let mut y_val = self.mean + coarse + detail;
        let mut edge_sum = 0.0;
        for e in &self.edges {
            if e.nx * x + e.ny * y > e.d {
                edge_sum += e.step;
            }
        }
        y_val += edge_sum;
        let u = 128.0 + 28.0 * gradient_noise(self.seed ^ 0x1111, x / 70.0, y / 70.0) + 0.3 * edge_sum;
        let v = 128.0 + 28.0 * gradient_noise(self.seed ^ 0x2222, x / 85.0, y / 85.0) - 0.3 * edge_sum;
        Sample { y: y_val, u, v }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gradients_are_unit_and_evenly_spaced() {
        for (k, &(c, s)) in GRADIENTS.iter().enumerate() {
            let a = k as f64 * TAU / 16.0;
            assert!((c - a.cos()).abs() < 1e-15 && (s - a.sin()).abs() < 1e-15);
        }
    }

    #[test]
    fn noise_is_zero_on_the_lattice_and_bounded() {
        for i in -5..5 {
            assert_eq!(gradient_noise(3, i as f64, (2 * i) as f64), 0.0);
        }
        let mut max = 0.0f64;
        for i in 0..20000 {
            let (x, y) = (i as f64 * 0.137, i as f64 * 0.071);
            max = max.max(gradient_noise(9, x, y).abs());
        }
        assert!(max <= 1.4 && max > 0.5, "{max}");
    }

    #[test]
    fn gaussian_has_unit_variance() {
        let n = 200_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for i in 0..n {
            let g = gaussian(mix64(i), mix64((i + 1) << 40));
            s += g;
            s2 += g * g;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!(mean.abs() < 0.01 && (var - 1.0).abs() < 0.02, "{mean} {var}");
    }
}
