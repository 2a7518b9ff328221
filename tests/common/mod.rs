//! Helpers shared by the integration tests.

use mocomp::flow::Flow;
use mocomp::metrics::flow_errors;
use mocomp::raster::plane_to_array;
use mocomp::synth::photo::{benchmark_pairs, RenderedPair};
use mocomp::synth::{Motion, SceneSpec, Synth};
use ndarray::Array2;

/// Frames 0 and 1 of a `w x h` noise-free synthetic scene (texture at
/// every scale) translated by (dx, dy), and the exact flow.
pub fn translated(w: usize, h: usize, dx: f64, dy: f64) -> (Array2<f32>, Array2<f32>, Flow) {
    let s = Synth::new(
        SceneSpec::new("t", w, h, 2)
            .seed(6)
            .camera(Motion::translation(dx, dy)),
    )
    .unwrap();
    (
        plane_to_array(s.frame(0).y()),
        plane_to_array(s.frame(1).y()),
        s.forward_flow(0),
    )
}

/// EPE over the valid pixels that are visible in frame 2.
#[allow(dead_code)] // not every test file uses it
pub fn visible_epe(est: &Flow, gt: &Flow, occluded: &Array2<bool>) -> f64 {
    let mut visible = gt.clone();
    let (_, _, valid) = visible.parts_mut();
    valid.zip_mut_with(occluded, |v, &o| *v = *v && !o);
    flow_errors(est, &visible).unwrap().epe
}

/// The benchmark generator's pair `name` (`benchmark_pairs(3, w, h)`) on
/// procedural texture: three sources rendered by the scene generator with
/// seeds `seed..seed + 3`, 320 x 200 px larger than the pairs as the
/// generator needs.
#[allow(dead_code)] // not every test file uses it
pub fn generated(name: &str, w: usize, h: usize, seed: u64) -> RenderedPair {
    let sources: Vec<Array2<f32>> = (0..3)
        .map(|k| {
            plane_to_array(
                Synth::new(SceneSpec::new("src", w + 320, h + 200, 1).seed(seed + k))
                    .unwrap()
                    .frame(0)
                    .y(),
            )
        })
        .collect();
    let spec = benchmark_pairs(3, w, h)
        .into_iter()
        .find(|s| s.name == name)
        .unwrap();
    spec.render(&sources)
}
