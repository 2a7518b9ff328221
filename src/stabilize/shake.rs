//! A known camera shake added to a still-camera clip: test material for a
//! stabiliser, with the truth to score it against. Each output frame is a
//! window of its input frame, shifted and turned about the centre by a
//! random offset of its own (uniform, independent from frame to frame),
//! cut small enough that the input's border never shows.

use super::path::{Centre, Pose};
use crate::codec::Frame;
use crate::global::Transform;
use crate::imgproc::warp::{warp_frame, Border};

/// How hard the camera shakes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShakeParams {
    /// Largest shift of a frame from the still camera, pixels (each axis).
    pub translation: f64,
    /// Largest rotation, degrees.
    pub rotation: f64,
    /// Seed of the offsets.
    pub seed: u64,
}

impl Default for ShakeParams {
    /// 12 pixels and 1.5 degrees.
    fn default() -> ShakeParams {
        ShakeParams {
            translation: 12.0,
            rotation: 1.5,
            seed: 1,
        }
    }
}

/// The output size for a `width` x `height` input: the largest even size,
/// as centred as the input allows, whose every corner stays inside the
/// input under any offset within `params`.
pub fn output_size(width: usize, height: usize, params: &ShakeParams) -> (usize, usize) {
    let (sin, cos) = params.rotation.to_radians().abs().sin_cos();
    let t = params.translation.abs();
    let fits = |ow: f64, oh: f64| {
        let reach_x = (ow - 1.0) / 2.0 * cos + (oh - 1.0) / 2.0 * sin + t;
        let reach_y = (ow - 1.0) / 2.0 * sin + (oh - 1.0) / 2.0 * cos + t;
        reach_x <= (width as f64 - 1.0) / 2.0 - 2.0 && reach_y <= (height as f64 - 1.0) / 2.0 - 2.0
    };
    let mut cut = 0;
    while cut < width.min(height) / 2 {
        let (ow, oh) = (width - 2 * cut, height - 2 * cut);
        if fits(ow as f64, oh as f64) {
            return (ow & !1, oh & !1);
        }
        cut += 1;
    }
    (2, 2)
}

/// `frames` offsets: each frame's pose of the shaken window on the still
/// input (centred coordinates), uniform within `params`.
pub fn offsets(frames: usize, params: &ShakeParams) -> Vec<Pose> {
    let mut state = params.seed ^ 0x5851_f42d_4c95_7f2d;
    let mut uniform = move || {
        // splitmix64: independent of the platform, fixed for a seed.
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    (0..frames)
        .map(|_| Pose {
            x: uniform() * params.translation,
            y: uniform() * params.translation,
            angle: uniform() * params.rotation.to_radians(),
            log_scale: 0.0,
        })
        .collect()
}

/// The shaken frame: the `out_w` x `out_h` window of `frame` at `offset`.
pub fn shaken(frame: &Frame, offset: &Pose, out_w: usize, out_h: usize) -> Frame {
    let (inner, outer) = (
        Centre::new(out_w, out_h),
        Centre::new(frame.width(), frame.height()),
    );
    let ((ix, iy), (ox, oy)) = (inner.half(), outer.half());
    let from_output = Transform([1.0, 0.0, -ix, 0.0, 1.0, -iy, 0.0, 0.0, 1.0]);
    let to_input = Transform([1.0, 0.0, ox, 0.0, 1.0, oy, 0.0, 0.0, 1.0]);
    let map = to_input.then_after(&offset.transform().then_after(&from_output));
    warp_frame(frame, out_w, out_h, &map.0, Border::Replicate)
}

/// The motion from shaken frame `t` to shaken frame `t - 1` in pixel
/// coordinates of the output, for a still input: `S_(t-1)^-1 S_t`.
pub fn true_motion(offsets: &[Pose], t: usize, out_w: usize, out_h: usize) -> Transform {
    let c = Centre::new(out_w, out_h);
    let prev = offsets[t - 1]
        .transform()
        .inverse()
        .expect("a rotation is regular");
    c.to_pixels(&prev.then_after(&offsets[t].transform()))
}
