//! Pairs of pictures made from real photographs under motion known
//! exactly: a flow benchmark with ground truth on real texture.
//!
//! A pair is a background photograph seen by a camera that moves between
//! the two frames (translation, zoom and rotation: a similarity), with
//! layers in front cut from other photographs (ellipses, with soft
//! edges), each moving its own way and hiding what is behind. Frame 2 can
//! change brightness and contrast (with a horizontal ramp, like light that
//! changes across the scene), both frames can carry sensor noise, and
//! frame 2 can be blurred (defocus). The forward flow of every pixel of
//! frame 1 follows from the maps in closed form, and so does whether the
//! point it shows is hidden in frame 2 (occluded) or leaves the picture.
//!
//! Pixels are the mean of 2x2 bicubic samples of the photographs (the
//! layers' edges anti-aliased). A pixel is left out of the ground truth
//! (invalid) where it mixes two layers.

use ndarray::Array2;

use super::texture::{gaussian, hash3};
use super::Affine;
use crate::flow::warp::sample_bicubic;
use crate::flow::Flow;
use crate::imgproc::pyramid::blur;

/// Where a layer is in a frame: the point of its source picture at
/// `centre` (source coordinates) appears at `at` (picture coordinates),
/// scaled by `scale` and turned by `rotate_deg` (clockwise on screen).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Picture position of the source centre.
    pub at: (f64, f64),
    /// Scale from source to picture.
    pub scale: f64,
    /// Rotation, degrees.
    pub rotate_deg: f64,
}

impl Pose {
    /// A pose at `at`, unscaled and unrotated.
    pub fn at(x: f64, y: f64) -> Pose {
        Pose {
            at: (x, y),
            scale: 1.0,
            rotate_deg: 0.0,
        }
    }

    /// This pose moved by (dx, dy), zoomed by `zoom` and turned by `deg`.
    pub fn moved(self, dx: f64, dy: f64, zoom: f64, deg: f64) -> Pose {
        Pose {
            at: (self.at.0 + dx, self.at.1 + dy),
            scale: self.scale * zoom,
            rotate_deg: self.rotate_deg + deg,
        }
    }

    /// The map from picture coordinates to source coordinates.
    fn to_source(self, centre: (f64, f64)) -> Affine {
        let (s, c) = self.rotate_deg.to_radians().sin_cos();
        let k = 1.0 / self.scale;
        // src = centre + R(-theta) (p - at) / scale
        let (a, b, cc, d) = (k * c, k * s, -k * s, k * c);
        let (px, py) = self.at;
        Affine {
            m: [
                [a, b, centre.0 - a * px - b * py],
                [cc, d, centre.1 - cc * px - d * py],
            ],
        }
    }
}

/// A layer in front of the background: an ellipse of a source picture.
#[derive(Debug, Clone, PartialEq)]
pub struct LayerSpec {
    /// Index of the source picture.
    pub source: usize,
    /// Centre of the ellipse in the source picture.
    pub centre: (f64, f64),
    /// Semi-axes of the ellipse, source pixels.
    pub radii: (f64, f64),
    /// Pose in frame 1 and frame 2.
    pub poses: [Pose; 2],
}

/// Everything that defines a pair.
#[derive(Debug, Clone, PartialEq)]
pub struct PairSpec {
    /// Name (a folder name).
    pub name: String,
    /// Picture width.
    pub width: usize,
    /// Picture height.
    pub height: usize,
    /// Index of the background picture.
    pub background: usize,
    /// Camera: the pose of the background's centre in frame 1 and frame 2.
    pub camera: [Pose; 2],
    /// Layers, back to front.
    pub layers: Vec<LayerSpec>,
    /// Frame 2's photometric change, `gain * v + bias + ramp * (x / w - 0.5)`:
    /// the contrast factor.
    pub gain: f64,
    /// The brightness offset, levels.
    pub bias: f64,
    /// The change from the left edge to the right, levels.
    pub ramp: f64,
    /// Standard deviation of the Gaussian noise of both frames, levels.
    pub noise: f64,
    /// Standard deviation of the Gaussian blur of frame 2, px (0 = none).
    pub blur: f64,
    /// Seed of the noise.
    pub seed: u64,
}

impl PairSpec {
    /// A pair of the background alone, still, no changes.
    pub fn new(name: &str, width: usize, height: usize, background: usize, camera: [Pose; 2]) -> PairSpec {
        PairSpec {
            name: name.to_owned(),
            width,
            height,
            background,
            camera,
            layers: Vec::new(),
            gain: 1.0,
            bias: 0.0,
            ramp: 0.0,
            noise: 0.0,
            blur: 0.0,
            seed: 1,
        }
    }
}

/// A rendered pair and its ground truth.
#[derive(Debug, Clone)]
pub struct RenderedPair {
    /// The first picture, grey levels rounded to whole numbers.
    pub frame1: Array2<f32>,
    /// The second picture.
    pub frame2: Array2<f32>,
    /// Forward flow of frame 1; invalid where a pixel mixes layers.
    pub flow: Flow,
    /// Frame-1 pixels whose point is hidden in frame 2 or leaves it.
    pub occluded: Array2<bool>,
}

/// The soft coverage of an ellipse at a source point: 1 inside, 0 outside,
/// linear over one source pixel across the edge.
fn coverage(layer: &LayerSpec, (sx, sy): (f64, f64)) -> f64 {
    let (rx, ry) = layer.radii;
    let (dx, dy) = (sx - layer.centre.0, sy - layer.centre.1);
    let r = ((dx / rx).powi(2) + (dy / ry).powi(2)).sqrt();
    // Distance to the edge in source pixels, approximately.
    let to_edge = (1.0 - r) * rx.min(ry);
    (to_edge + 0.5).clamp(0.0, 1.0)
}

struct Maps {
    background: Affine,
    layers: Vec<Affine>,
}

impl PairSpec {
    fn maps(&self, sources: &[Array2<f32>], frame: usize) -> Maps {
        let bg = &sources[self.background];
        let centre = ((bg.ncols() as f64 - 1.0) / 2.0, (bg.nrows() as f64 - 1.0) / 2.0);
        Maps {
            background: self.camera[frame].to_source(centre),
            layers: self
                .layers
                .iter()
                .map(|l| l.poses[frame].to_source(l.centre))
                .collect(),
        }
    }

    /// The topmost layer covering picture point p (its index + 1; 0 = the
    /// background), and its coverage there.
    fn top_layer(&self, maps: &Maps, x: f64, y: f64) -> (usize, f64) {
        for (k, (l, m)) in self.layers.iter().zip(&maps.layers).enumerate().rev() {
            let c = coverage(l, m.apply(x, y));
            if c > 0.0 {
                return (k + 1, c);
            }
        }
        (0, 1.0)
    }

    fn render_frame(&self, sources: &[Array2<f32>], frame: usize) -> Array2<f32> {
        let maps = self.maps(sources, frame);
        let sample = |src: &Array2<f32>, m: &Affine, x: f64, y: f64| {
            let (sx, sy) = m.apply(x, y);
            f64::from(sample_bicubic(src, sx as f32, sy as f32))
        };
        Array2::from_shape_fn((self.height, self.width), |(y, x)| {
            let mut acc = 0.0;
            for (ox, oy) in [(-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)] {
                let (px, py) = (x as f64 + ox, y as f64 + oy);
                let mut value = sample(&sources[self.background], &maps.background, px, py);
                for (l, m) in self.layers.iter().zip(&maps.layers) {
                    let c = coverage(l, m.apply(px, py));
                    if c > 0.0 {
                        value += c * (sample(&sources[l.source], m, px, py) - value);
                    }
                }
                acc += value;
            }
            (acc / 4.0) as f32
        })
    }

    /// Renders the pair from its source pictures (grey levels 0..255).
    /// Panics if an index names no source.
    pub fn render(&self, sources: &[Array2<f32>]) -> RenderedPair {
        let mut frame1 = self.render_frame(sources, 0);
        let mut frame2 = self.render_frame(sources, 1);
        if self.blur > 0.0 {
            frame2 = blur(&frame2, self.blur as f32);
        }
        let w = self.width as f64;
        for mut row in frame2.rows_mut() {
            for (x, v) in row.iter_mut().enumerate() {
                *v = (self.gain * f64::from(*v) + self.bias + self.ramp * (x as f64 / w - 0.5)) as f32;
            }
        }
        for (t, f) in [&mut frame1, &mut frame2].into_iter().enumerate() {
            if self.noise > 0.0 {
                for ((y, x), v) in f.indexed_iter_mut() {
                    let h1 = hash3(self.seed.wrapping_add(t as u64 * 7919), x as i64, y as i64);
                    let h2 = hash3(self.seed.wrapping_add(t as u64 * 7919 + 1), x as i64, y as i64);
                    *v += (self.noise * gaussian(h1, h2)) as f32;
                }
            }
            f.mapv_inplace(|v| v.round().clamp(0.0, 255.0));
        }
        let (flow, occluded) = self.ground_truth(sources);
        RenderedPair {
            frame1,
            frame2,
            flow,
            occluded,
        }
    }

    /// The exact forward flow of frame 1 and its occlusion mask.
    pub fn ground_truth(&self, sources: &[Array2<f32>]) -> (Flow, Array2<bool>) {
        let (m1, m2) = (self.maps(sources, 0), self.maps(sources, 1));
        let (w, h) = (self.width, self.height);
        let mut u = Array2::zeros((h, w));
        let mut v = Array2::zeros((h, w));
        let mut valid = Array2::from_elem((h, w), true);
        let mut occluded = Array2::from_elem((h, w), false);
        for y in 0..h {
            for x in 0..w {
                let (px, py) = (x as f64, y as f64);
                let (layer, c) = self.top_layer(&m1, px, py);
                let (to_src, from_src) = if layer == 0 {
                    (m1.background, m2.background.inverse())
                } else {
                    (m1.layers[layer - 1], m2.layers[layer - 1].inverse())
                };
                let (sx, sy) = to_src.apply(px, py);
                let (qx, qy) = from_src.apply(sx, sy);
                u[[y, x]] = (qx - px) as f32;
                v[[y, x]] = (qy - py) as f32;
                valid[[y, x]] = c >= 1.0;
                let outside = qx < 0.0 || qy < 0.0 || qx > (w - 1) as f64 || qy > (h - 1) as f64;
                occluded[[y, x]] = outside || self.top_layer(&m2, qx, qy).0 != layer;
            }
        }
        (Flow::from_parts(u, v, valid), occluded)
    }
}

/// The benchmark's pairs over `n` source pictures of at least
/// `width + 320` x `height + 200` pixels (each case takes its background from one
/// picture and its layers from the others): per picture, small motion,
/// large and very large translations, rotation and zoom, occluding layers,
/// a lighting change with noise, and noise with blur.
pub fn benchmark_pairs(n: usize, width: usize, height: usize) -> Vec<PairSpec> {
    let (cx, cy) = (width as f64 / 2.0, height as f64 / 2.0);
    let mut out = Vec::new();
    for k in 0..n {
        // Vary the figures by picture so no two cases repeat a motion.
        let s = 1.0 + 0.08 * (k % 8) as f64;
        let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
        let still = Pose::at(cx, cy);
        let case = |name: &str, second: Pose| PairSpec {
            seed: 1000 + k as u64,
            ..PairSpec::new(&format!("p{k}_{name}"), width, height, k, [still, second])
        };
        out.push(case("small", still.moved(2.3 * s, -1.4 * sign, 1.01, 0.5 * sign)));
        out.push(case("large", still.moved(-31.0 * s * sign, 17.5 * s, 1.0, 0.0)));
        out.push(case("huge", still.moved(88.0 * s, -47.0 * s * sign, 1.0, 0.0)));
        out.push(case(
            "rotzoom",
            still.moved(9.0 * sign, 6.0, 1.06 + 0.02 * s, 4.0 * s * sign),
        ));
        let other = |j: usize| (k + j) % n;
        let mut layered = case("layers", still.moved(-5.0 * sign, 3.2 * s, 1.0, 0.0));
        for (j, (ax, ay, dx, dy, rot)) in [
            (0.3, 0.35, 24.0 * s, -13.0, 3.0),
            (0.7, 0.6, -29.0, -19.0 * s * sign, -2.0),
        ]
        .into_iter()
        .enumerate()
        {
            let src = other(j + 1);
            let first = Pose::at(width as f64 * ax, height as f64 * ay);
            layered.layers.push(LayerSpec {
                source: src,
                centre: (cx + 40.0 * j as f64, cy - 30.0 * j as f64),
                radii: (0.16 * width as f64, 0.2 * height as f64),
                poses: [first, first.moved(dx, dy, 1.0, rot)],
            });
        }
        out.push(layered);
        let mut light = case("light", still.moved(14.0 * s * sign, -8.5, 1.0, 0.0));
        (light.gain, light.bias, light.ramp, light.noise) = (0.78, 22.0, 30.0 * sign, 1.5);
        out.push(light);
        let mut degraded = case("noiseblur", still.moved(-19.0, 11.0 * s * sign, 1.02, 0.0));
        (degraded.noise, degraded.blur) = (4.0, 1.2);
        out.push(degraded);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::warp::sample_bicubic;

    fn smooth_source(w: usize, h: usize, seed: f32) -> Array2<f32> {
        Array2::from_shape_fn((h, w), |(y, x)| {
            let (x, y) = (x as f32, y as f32);
            128.0
                + 50.0 * (x / 9.0 + seed).sin() * (y / 13.0).cos()
                + 30.0 * ((x + 2.0 * y) / 17.0 - seed).cos()
        })
    }

    #[test]
    fn poses_map_their_centre_and_invert() {
        let p = Pose::at(50.0, 40.0).moved(3.0, -2.0, 1.2, 30.0);
        let m = p.to_source((10.0, 20.0));
        let (sx, sy) = m.apply(53.0, 38.0);
        assert!((sx - 10.0).abs() < 1e-9 && (sy - 20.0).abs() < 1e-9);
        // One picture pixel is 1/scale source pixels.
        let (ax, ay) = m.apply(54.0, 38.0);
        assert!(((ax - sx).hypot(ay - sy) - 1.0 / 1.2).abs() < 1e-9);
    }

    #[test]
    fn frame_two_warped_back_by_the_truth_is_frame_one_where_visible() {
        let sources: Vec<_> = (0..3).map(|k| smooth_source(600, 400, k as f32)).collect();
        for spec in benchmark_pairs(3, 240, 160).into_iter().take(7) {
            let spec = PairSpec {
                noise: 0.0,
                blur: 0.0,
                gain: 1.0,
                bias: 0.0,
                ramp: 0.0,
                ..spec
            };
            let pair = spec.render(&sources);
            let (mut err, mut n) = (0.0, 0);
            for ((y, x), &occ) in pair.occluded.indexed_iter() {
                if occ || !pair.flow.is_valid(x, y) {
                    continue;
                }
                let (u, v) = pair.flow.get(x, y);
                let warped = sample_bicubic(&pair.frame2, x as f32 + u, y as f32 + v);
                err += f64::from((warped - pair.frame1[[y, x]]).abs());
                n += 1;
            }
            assert!(n > 1000, "{}: {n} visible pixels", spec.name);
            let mean = err / n as f64;
            assert!(mean < 1.5, "{}: mean warp error {mean}", spec.name);
        }
    }

    #[test]
    fn layers_occlude_and_move_as_specified() {
        let sources: Vec<_> = (0..3).map(|k| smooth_source(600, 400, k as f32)).collect();
        let spec = benchmark_pairs(3, 240, 160)
            .into_iter()
            .find(|s| s.name == "p0_layers")
            .unwrap();
        let (flow, occluded) = spec.ground_truth(&sources);
        let l = &spec.layers[0];
        let (x, y) = (l.poses[0].at.0 as usize, l.poses[0].at.1 as usize);
        let (u, v) = flow.get(x, y);
        let want = (
            l.poses[1].at.0 - l.poses[0].at.0,
            l.poses[1].at.1 - l.poses[0].at.1,
        );
        assert!((f64::from(u) - want.0).abs() < 1e-3 && (f64::from(v) - want.1).abs() < 1e-3);
        let hidden = occluded.iter().filter(|&&o| o).count();
        assert!(hidden > 100 && hidden < 240 * 160 / 2, "{hidden} occluded pixels");
        assert!(flow.valid_count() < 240 * 160, "layer edges are left out");
    }
}
