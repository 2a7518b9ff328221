//! Synthetic test sequences with exact ground-truth motion.
//!
//! A scene is a textured background seen by a moving camera, with objects in
//! front of it that move on their own and hide what is behind them. Every
//! layer moves by a known similarity transform per frame (translation, zoom,
//! rotation), so the true forward and backward flow of every pixel is known
//! in closed form, independently of any estimator. Pixels are rendered by
//! evaluating the continuous texture at 2x2 points inside the pixel
//! (anti-aliasing edges), plus optional sensor noise and a global brightness
//! change.
//!
//! A pixel's flow is marked invalid where the answer is not a single motion:
//! where it is hidden in the other frame (occlusion), where it moves outside
//! the picture, and where it straddles two layers.
//!
//! ```
//! use mocomp::synth::{Motion, SceneSpec, Synth};
//! // The scene slides by (2, -1) px per frame (see [`Motion`]).
//! let spec = SceneSpec::new("pan", 64, 48, 3).camera(Motion::translation(2.0, -1.0));
//! let synth = Synth::new(spec).unwrap();
//! assert_eq!(synth.forward_flow(0).get(10, 10), (2.0, -1.0));
//! assert_eq!(synth.backward_flow(1).get(10, 10), (-2.0, 1.0));
//! ```

pub mod photo;
mod texture;

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::codec::picture::{check_size, Frame, PictureError};
use crate::flow::Flow;
use crate::io::y4m::{ChromaSiting, Y4mError, Y4mInfo, Y4mWriter};
use crate::io::{flo, OutputFile};
pub use texture::Texture;
use texture::{gaussian, hash3};

/// A 2-D affine map `p -> A p + t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Affine {
    /// Row-major `[[a, b, tx], [c, d, ty]]`.
    pub m: [[f64; 3]; 2],
}

impl Affine {
    /// The identity.
    pub const IDENTITY: Affine = Affine {
        m: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
    };

    /// A translation.
    pub fn translation(tx: f64, ty: f64) -> Affine {
        Affine {
            m: [[1.0, 0.0, tx], [0.0, 1.0, ty]],
        }
    }

    /// Applies the map to (x, y).
    #[inline]
    pub fn apply(&self, x: f64, y: f64) -> (f64, f64) {
        let m = &self.m;
        (
            m[0][0] * x + m[0][1] * y + m[0][2],
            m[1][0] * x + m[1][1] * y + m[1][2],
        )
    }

    /// `self ∘ other`: first `other`, then `self`.
    pub fn then_after(&self, other: &Affine) -> Affine {
        let (a, b) = (&self.m, &other.m);
        let mut m = [[0.0; 3]; 2];
        for r in 0..2 {
            m[r][0] = a[r][0] * b[0][0] + a[r][1] * b[1][0];
            m[r][1] = a[r][0] * b[0][1] + a[r][1] * b[1][1];
            m[r][2] = a[r][0] * b[0][2] + a[r][1] * b[1][2] + a[r][2];
        }
        Affine { m }
    }

    /// The inverse map (the maps used here are similarities, never singular).
    pub fn inverse(&self) -> Affine {
        let m = &self.m;
        let det = m[0][0] * m[1][1] - m[0][1] * m[1][0];
        let (a, b, c, d) = (m[1][1] / det, -m[0][1] / det, -m[1][0] / det, m[0][0] / det);
        Affine {
            m: [
                [a, b, -(a * m[0][2] + b * m[1][2])],
                [c, d, -(c * m[0][2] + d * m[1][2])],
            ],
        }
    }
}

/// How a layer moves in the picture from one frame to the next: zoom by
/// `zoom` and rotate by `rotate_deg` about the layer's centre (the picture
/// centre for the camera, the object's centre for objects), then translate
/// by `translate` plus `wobble * sin(2 pi t / wobble_period)`.
///
/// These are motions of the picture content: `Motion::translation(2.0, 0.0)`
/// on the camera makes the scene slide 2 px to the right each frame (forward
/// flow (2, 0)). Positive rotation turns the x axis towards the y axis
/// (clockwise on screen, as y points down).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Motion {
    /// Translation per frame, px.
    pub translate: (f64, f64),
    /// Scale factor per frame (1 = none, above 1 = zoom in).
    pub zoom: f64,
    /// Rotation per frame, degrees.
    pub rotate_deg: f64,
    /// Amplitude of the sinusoidal part of the translation, px.
    pub wobble: (f64, f64),
    /// Period of the sinusoidal part, frames.
    pub wobble_period: f64,
}

impl Motion {
    /// No motion.
    pub const STILL: Motion = Motion {
        translate: (0.0, 0.0),
        zoom: 1.0,
        rotate_deg: 0.0,
        wobble: (0.0, 0.0),
        wobble_period: 1.0,
    };

    /// A constant translation of (dx, dy) px per frame.
    pub fn translation(dx: f64, dy: f64) -> Motion {
        Motion {
            translate: (dx, dy),
            ..Motion::STILL
        }
    }

    /// Adds a zoom factor per frame.
    pub fn with_zoom(self, zoom: f64) -> Motion {
        Motion { zoom, ..self }
    }

    /// Adds a rotation per frame, degrees.
    pub fn with_rotation(self, rotate_deg: f64) -> Motion {
        Motion { rotate_deg, ..self }
    }

    /// Adds a sinusoidal variation of the translation.
    pub fn with_wobble(self, amplitude: (f64, f64), period: f64) -> Motion {
        Motion {
            wobble: amplitude,
            wobble_period: period,
            ..self
        }
    }

    /// The picture-space map from frame `t` to frame `t + 1` for a layer
    /// whose centre is at `centre` in frame `t`.
    pub fn step(&self, t: usize, centre: (f64, f64)) -> Affine {
        let phase = (std::f64::consts::TAU * t as f64 / self.wobble_period).sin();
        let tx = self.translate.0 + self.wobble.0 * phase;
        let ty = self.translate.1 + self.wobble.1 * phase;
        let (s, c) = self.rotate_deg.to_radians().sin_cos();
        let (a, b, cc, d) = (self.zoom * c, -self.zoom * s, self.zoom * s, self.zoom * c);
        let (cx, cy) = centre;
        Affine {
            m: [
                [a, b, cx - a * cx - b * cy + tx],
                [cc, d, cy - cc * cx - d * cy + ty],
            ],
        }
    }
}

/// The outline of an object, in its own coordinates (centred on 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// An ellipse with these semi-axes, px.
    Ellipse {
        /// Horizontal semi-axis.
        rx: f64,
        /// Vertical semi-axis.
        ry: f64,
    },
    /// A rectangle with these half-sizes, px.
    Rect {
        /// Half width.
        hw: f64,
        /// Half height.
        hh: f64,
    },
}

impl Shape {
    #[inline]
    fn contains(&self, x: f64, y: f64) -> bool {
        match *self {
            Shape::Ellipse { rx, ry } => (x / rx).powi(2) + (y / ry).powi(2) <= 1.0,
            Shape::Rect { hw, hh } => x.abs() <= hw && y.abs() <= hh,
        }
    }
}

/// An object in front of the scene.
#[derive(Debug, Clone, PartialEq)]
pub struct ObjectSpec {
    /// Its outline.
    pub shape: Shape,
    /// Its centre in frame 0, picture coordinates.
    pub centre: (f64, f64),
    /// How it moves in the picture.
    pub motion: Motion,
    /// Seed of its texture.
    pub seed: u64,
}

/// Everything that defines a synthetic sequence.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneSpec {
    /// Name, used for file names.
    pub name: String,
    /// Picture width.
    pub width: usize,
    /// Picture height.
    pub height: usize,
    /// Number of frames.
    pub frames: usize,
    /// Frame rate (numerator, denominator).
    pub fps: (u64, u64),
    /// Seed of the background texture and the noise.
    pub seed: u64,
    /// Motion of the background in the picture.
    pub camera: Motion,
    /// Objects, back to front.
    pub objects: Vec<ObjectSpec>,
    /// Standard deviation of the Gaussian noise added to luma (chroma gets
    /// half), levels.
    pub noise_sigma: f64,
    /// Luma offset added per frame (a global brightness change), levels.
    pub brightness_step: f64,
}

impl SceneSpec {
    /// A still scene: no motion, no objects, no noise, 30 fps.
    pub fn new(name: &str, width: usize, height: usize, frames: usize) -> SceneSpec {
        SceneSpec {
            name: name.to_owned(),
            width,
            height,
            frames,
            fps: (30, 1),
            seed: 1,
            camera: Motion::STILL,
            objects: Vec::new(),
            noise_sigma: 0.0,
            brightness_step: 0.0,
        }
    }

    /// Sets the camera motion.
    pub fn camera(mut self, motion: Motion) -> SceneSpec {
        self.camera = motion;
        self
    }

    /// Adds an object in front of the others.
    pub fn object(mut self, shape: Shape, centre: (f64, f64), motion: Motion) -> SceneSpec {
        let seed = self
            .seed
            .wrapping_mul(31)
            .wrapping_add(100 + self.objects.len() as u64);
        self.objects.push(ObjectSpec {
            shape,
            centre,
            motion,
            seed,
        });
        self
    }

    /// Sets the luma noise standard deviation.
    pub fn noise(mut self, sigma: f64) -> SceneSpec {
        self.noise_sigma = sigma;
        self
    }

    /// Sets the brightness change per frame.
    pub fn brightness(mut self, step: f64) -> SceneSpec {
        self.brightness_step = step;
        self
    }

    /// Sets the texture and noise seed.
    pub fn seed(mut self, seed: u64) -> SceneSpec {
        self.seed = seed;
        self
    }
}

/// The samples that `mocomp samples` writes and the repository carries.
pub fn standard_scenes() -> Vec<SceneSpec> {
    vec![
        SceneSpec::new("synth_qcif", 176, 144, 10)
            .seed(7)
            .camera(
                Motion::translation(1.3, -0.6)
                    .with_zoom(1.004)
                    .with_rotation(0.25)
                    .with_wobble((0.5, 0.3), 7.0),
            )
            .object(
                Shape::Ellipse { rx: 22.0, ry: 15.0 },
                (48.0, 92.0),
                Motion::translation(2.6, -1.3).with_rotation(1.5),
            )
            .object(
                Shape::Rect { hw: 16.0, hh: 11.0 },
                (132.0, 42.0),
                Motion::translation(-3.4, 1.9),
            )
            .noise(1.0)
            .brightness(0.4),
        SceneSpec::new("synth_cif", 352, 288, 10)
            .seed(11)
            .camera(
                Motion::translation(2.2, 1.0)
                    .with_zoom(1.008)
                    .with_rotation(-0.3)
                    .with_wobble((0.8, 0.5), 9.0),
            )
            .object(
                Shape::Ellipse { rx: 40.0, ry: 28.0 },
                (96.0, 196.0),
                Motion::translation(4.5, -2.0).with_rotation(-1.0),
            )
            .object(
                Shape::Rect { hw: 36.0, hh: 24.0 },
                (262.0, 84.0),
                Motion::translation(-5.5, 2.5).with_zoom(1.01),
            )
            .object(
                Shape::Ellipse { rx: 14.0, ry: 14.0 },
                (40.0, 40.0),
                Motion::translation(7.0, 3.0),
            )
            .noise(1.2)
            .brightness(0.3),
    ]
}

/// A rendered-on-demand synthetic sequence.
#[derive(Debug, Clone)]
pub struct Synth {
    spec: SceneSpec,
    background: Texture,
    objects: Vec<Texture>,
    /// Picture-to-world map of the background in each frame.
    camera_inv: Vec<Affine>,
    /// Background step from frame t to t + 1.
    camera_step: Vec<Affine>,
    /// Picture-to-object map of each object in each frame: `[object][t]`.
    object_inv: Vec<Vec<Affine>>,
    /// Object step from frame t to t + 1: `[object][t]`.
    object_step: Vec<Vec<Affine>>,
}

/// Offsets of the 2x2 anti-aliasing points inside a pixel.
const SUBPIXELS: [(f64, f64); 4] = [(-0.25, -0.25), (0.25, -0.25), (-0.25, 0.25), (0.25, 0.25)];

impl Synth {
    /// Prepares a scene (nothing is rendered yet).
    pub fn new(spec: SceneSpec) -> Result<Synth, PictureError> {
        check_size(spec.width, spec.height)?;
        let n = spec.frames.max(1);
        let centre = ((spec.width as f64 - 1.0) / 2.0, (spec.height as f64 - 1.0) / 2.0);
        // World coordinates are frame 0's picture coordinates.
        let mut to_picture = Affine::IDENTITY;
        let mut camera_inv = Vec::with_capacity(n);
        let mut camera_step = Vec::with_capacity(n);
        for t in 0..n {
            camera_inv.push(to_picture.inverse());
            let step = spec.camera.step(t, centre);
            to_picture = step.then_after(&to_picture);
            camera_step.push(step);
        }
        let mut object_inv = Vec::new();
        let mut object_step = Vec::new();
        for obj in &spec.objects {
            let mut pose = Affine::translation(obj.centre.0, obj.centre.1);
            let (mut inv, mut steps) = (Vec::with_capacity(n), Vec::with_capacity(n));
            for t in 0..n {
                inv.push(pose.inverse());
                let step = obj.motion.step(t, pose.apply(0.0, 0.0));
                pose = step.then_after(&pose);
                steps.push(step);
            }
            object_inv.push(inv);
            object_step.push(steps);
        }
        let extent = spec.width.max(spec.height) as f64;
        Ok(Synth {
            background: Texture::scene(spec.seed, extent),
            objects: spec.objects.iter().map(|o| Texture::object(o.seed)).collect(),
            camera_inv,
            camera_step,
            object_inv,
            object_step,
            spec,
        })
    }

    /// The scene description.
    pub fn spec(&self) -> &SceneSpec {
        &self.spec
    }

    /// A Y4M header for the sequence (centred chroma, limited range).
    pub fn y4m_info(&self) -> Y4mInfo {
        Y4mInfo {
            siting: ChromaSiting::Jpeg,
            extensions: vec!["COLORRANGE=LIMITED".into()],
            ..Y4mInfo::new(self.spec.width, self.spec.height, self.spec.fps)
        }
    }

    /// The top layer at picture point (x, y) of frame t: 0 is the
    /// background, `k + 1` object `k`.
    #[inline]
    fn layer_at(&self, t: usize, x: f64, y: f64) -> usize {
        for (k, obj) in self.spec.objects.iter().enumerate().rev() {
            let (lx, ly) = self.object_inv[k][t].apply(x, y);
            if obj.shape.contains(lx, ly) {
                return k + 1;
            }
        }
        0
    }

    #[inline]
    fn texture_at(&self, t: usize, layer: usize, x: f64, y: f64) -> texture::Sample {
        if layer == 0 {
            let (wx, wy) = self.camera_inv[t].apply(x, y);
            self.background.sample(wx, wy)
        } else {
            let (lx, ly) = self.object_inv[layer - 1][t].apply(x, y);
            self.objects[layer - 1].sample(lx, ly)
        }
    }

    /// The mean of the texture over the 2x2 points of the pixel at (x, y).
    fn pixel(&self, t: usize, x: f64, y: f64) -> texture::Sample {
        let mut acc = texture::Sample::default();
        for (dx, dy) in SUBPIXELS {
            let (px, py) = (x + dx, y + dy);
            let s = self.texture_at(t, self.layer_at(t, px, py), px, py);
            acc.y += s.y;
            acc.u += s.u;
            acc.v += s.v;
        }
        texture::Sample {
            y: acc.y / 4.0,
            u: acc.u / 4.0,
            v: acc.v / 4.0,
        }
    }

    fn noise(&self, t: usize, plane: i64, x: usize, y: usize, sigma: f64) -> f64 {
        if sigma == 0.0 {
            return 0.0;
        }
        let key = (t as i64) << 40 | plane << 36 | (y as i64) << 18 | x as i64;
        sigma
            * gaussian(
                hash3(self.spec.seed ^ 0x5EED, key, 1),
                hash3(self.spec.seed ^ 0x5EED, key, 2),
            )
    }

    /// Renders frame `t` (`t < frames`).
    pub fn frame(&self, t: usize) -> Frame {
        assert!(t < self.spec.frames, "frame {t} of {}", self.spec.frames);
        let (w, h) = (self.spec.width, self.spec.height);
        let offset = self.spec.brightness_step * t as f64;
        let sigma = self.spec.noise_sigma;
        let mut frame = Frame::new(w, h).expect("size checked in Synth::new");
        let quantise = |v: f64| v.round().clamp(0.0, 255.0) as u8;
        let luma: Vec<Vec<u8>> = (0..h)
            .into_par_iter()
            .map(|y| {
                (0..w)
                    .map(|x| {
                        let s = self.pixel(t, x as f64, y as f64);
                        quantise(s.y + offset + self.noise(t, 0, x, y, sigma))
                    })
                    .collect()
            })
            .collect();
        for (dst, src) in frame.plane_mut(0).rows_mut().zip(&luma) {
            dst.copy_from_slice(src);
        }
        // Chroma sample (cx, cy) covers luma pixels 2cx..2cx+1, 2cy..2cy+1
        // (centred siting): the mean of those four pixels' chroma.
        let (cw, ch) = Frame::chroma_size(w, h);
        let chroma: Vec<Vec<(u8, u8)>> = (0..ch)
            .into_par_iter()
            .map(|cy| {
                (0..cw)
                    .map(|cx| {
                        let (x, y) = (2.0 * cx as f64 + 0.5, 2.0 * cy as f64 + 0.5);
                        let (mut u, mut v) = (0.0, 0.0);
                        for (dx, dy) in SUBPIXELS {
                            let (px, py) = (x + 2.0 * dx, y + 2.0 * dy);
                            let s = self.texture_at(t, self.layer_at(t, px, py), px, py);
                            u += s.u;
                            v += s.v;
                        }
                        (
                            quantise(u / 4.0 + self.noise(t, 1, cx, cy, sigma / 2.0)),
                            quantise(v / 4.0 + self.noise(t, 2, cx, cy, sigma / 2.0)),
                        )
                    })
                    .collect()
            })
            .collect();
        for (cy, row) in chroma.iter().enumerate() {
            for (cx, &(u, v)) in row.iter().enumerate() {
                frame.plane_mut(1).set(cx, cy, u);
                frame.plane_mut(2).set(cx, cy, v);
            }
        }
        frame.extend_borders();
        frame
    }

    /// Whether the picture point (x, y) of frame t and the four points half a
    /// pixel around it all show `layer`.
    fn cleanly_in(&self, t: usize, layer: usize, x: f64, y: f64) -> bool {
        [(0.0, 0.0), (-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)]
            .iter()
            .all(|&(dx, dy)| self.layer_at(t, x + dx, y + dy) == layer)
    }

    /// Exact flow of frame `from` towards frame `to` (adjacent frames):
    /// `frame_from(p) ~ frame_to(p + w(p))`.
    fn flow_between(&self, from: usize, to: usize) -> Flow {
        let (w, h) = (self.spec.width, self.spec.height);
        let forward = to == from + 1;
        let step_of = |layer: usize| {
            let step = if layer == 0 {
                self.camera_step[from.min(to)]
            } else {
                self.object_step[layer - 1][from.min(to)]
            };
            if forward {
                step
            } else {
                step.inverse()
            }
        };
        let steps: Vec<Affine> = (0..=self.spec.objects.len()).map(step_of).collect();
        let rows: Vec<Vec<(f32, f32, bool)>> = (0..h)
            .into_par_iter()
            .map(|y| {
                (0..w)
                    .map(|x| {
                        let (px, py) = (x as f64, y as f64);
                        let layer = self.layer_at(from, px, py);
                        let (qx, qy) = steps[layer].apply(px, py);
                        let inside = qx >= 0.0 && qy >= 0.0 && qx <= (w - 1) as f64 && qy <= (h - 1) as f64;
                        let valid = inside
                            && self.cleanly_in(from, layer, px, py)
                            && self.cleanly_in(to, layer, qx, qy);
                        ((qx - px) as f32, (qy - py) as f32, valid)
                    })
                    .collect()
            })
            .collect();
        let mut u = ndarray::Array2::zeros((h, w));
        let mut v = ndarray::Array2::zeros((h, w));
        let mut valid = ndarray::Array2::from_elem((h, w), false);
        for (y, row) in rows.iter().enumerate() {
            for (x, &(a, b, ok)) in row.iter().enumerate() {
                u[[y, x]] = a;
                v[[y, x]] = b;
                valid[[y, x]] = ok;
            }
        }
        Flow::from_parts(u, v, valid)
    }

    /// Exact forward flow from frame `t` to frame `t + 1`.
    pub fn forward_flow(&self, t: usize) -> Flow {
        assert!(
            t + 1 < self.spec.frames,
            "forward flow of frame {t} of {}",
            self.spec.frames
        );
        self.flow_between(t, t + 1)
    }

    /// Exact backward flow from frame `t` to frame `t - 1`: the motion a
    /// block search of frame `t` against frame `t - 1` should find.
    pub fn backward_flow(&self, t: usize) -> Flow {
        assert!(t >= 1 && t < self.spec.frames, "backward flow of frame {t}");
        self.flow_between(t, t - 1)
    }
}

/// Files written for one sample.
#[derive(Debug, Clone)]
pub struct WrittenSample {
    /// The Y4M file.
    pub y4m: PathBuf,
    /// The folder holding its flow files.
    pub flow_dir: PathBuf,
    /// Number of `.flo` files written.
    pub flow_files: usize,
}

/// File name of the forward flow from frame `t` to `t + 1`.
pub fn forward_flow_name(t: usize) -> String {
    format!("forward_{t:04}.flo")
}

/// File name of the backward flow from frame `t` to `t - 1`.
pub fn backward_flow_name(t: usize) -> String {
    format!("backward_{t:04}.flo")
}

/// What can go wrong writing a sample.
#[derive(Debug, thiserror::Error)]
pub enum SampleError {
    /// Writing the video.
    #[error(transparent)]
    Y4m(#[from] Y4mError),
    /// Writing a flow file.
    #[error(transparent)]
    Flo(#[from] flo::FloError),
    /// Bad scene size.
    #[error(transparent)]
    Size(#[from] PictureError),
    /// Creating the folder.
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

/// Writes `DIR/NAME.y4m` and, in `DIR/NAME/`, the forward flow of every
/// consecutive pair (`forward_0000.flo` is frame 0 to frame 1), and with
/// `backward` also the backward flows (`backward_0001.flo` is frame 1 to
/// frame 0).
pub fn write_sample(spec: &SceneSpec, dir: &Path, backward: bool) -> Result<WrittenSample, SampleError> {
    let synth = Synth::new(spec.clone())?;
    std::fs::create_dir_all(dir)?;
    let y4m_path = dir.join(format!("{}.y4m", spec.name));
    let flow_dir = dir.join(&spec.name);
    std::fs::create_dir_all(&flow_dir)?;
    let mut out = OutputFile::create(&y4m_path).map_err(Y4mError::Io)?;
    let mut writer = Y4mWriter::new(&mut out, &synth.y4m_info())?;
    for t in 0..spec.frames {
        writer.write_frame(&synth.frame(t))?;
    }
    drop(writer);
    out.commit().map_err(Y4mError::Io)?;
    let mut flow_files = 0;
    for t in 0..spec.frames.saturating_sub(1) {
        flo::write_flo(&flow_dir.join(forward_flow_name(t)), &synth.forward_flow(t))?;
        flow_files += 1;
        if backward {
            flo::write_flo(
                &flow_dir.join(backward_flow_name(t + 1)),
                &synth.backward_flow(t + 1),
            )?;
            flow_files += 1;
        }
    }
    Ok(WrittenSample {
        y4m: y4m_path,
        flow_dir,
        flow_files,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn affine_inverse_and_composition() {
        let m = Motion::translation(1.5, -2.0)
            .with_zoom(1.1)
            .with_rotation(30.0)
            .step(0, (10.0, 5.0));
        let id = m.then_after(&m.inverse());
        for r in 0..2 {
            for c in 0..3 {
                let want = if r == c { 1.0 } else { 0.0 };
                assert!((id.m[r][c] - want).abs() < 1e-12);
            }
        }
        // The centre moves only by the translation.
        let (x, y) = m.apply(10.0, 5.0);
        assert!((x - 11.5).abs() < 1e-12 && (y - 3.0).abs() < 1e-12);
    }

    #[test]
    fn rotation_turns_x_towards_y() {
        let m = Motion::STILL.with_rotation(90.0).step(0, (0.0, 0.0));
        let (x, y) = m.apply(1.0, 0.0);
        assert!(x.abs() < 1e-12 && (y - 1.0).abs() < 1e-12);
    }
}
