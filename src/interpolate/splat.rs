//! The flow from an intermediate time to both frames, by forward splatting
//! each frame's flow to where its pixels are at that time (bilinear
//! footprints, weighted against each other by how well the pixel's match
//! holds), with each splat's visibility: a pixel of frame 0 that the
//! forward-backward check finds occluded in frame 1 is seen only in frame 0.
//! Holes (surfaces neither frame's splats reach) take their neighbours'
//! flow.

use ndarray::Array2;

use crate::flow::warp::bilinear_clamped;
use crate::flow::Flow;

/// The flows from time `t` to frame 0 and to frame 1, and how much of each
/// pixel at time `t` is seen in frame 0 and in frame 1 (0 to 1).
pub struct Intermediate {
    /// Flow from time `t` to frame 0 (u, v).
    pub to0: (Array2<f32>, Array2<f32>),
    /// Flow from time `t` to frame 1.
    pub to1: (Array2<f32>, Array2<f32>),
    /// Share of the pixel seen in frame 0.
    pub seen0: Array2<f32>,
    /// Share seen in frame 1.
    pub seen1: Array2<f32>,
}

/// What each frame's pixels contribute: its flow to the other frame, the
/// match's photometric error, and whether it is occluded there.
pub struct Side<'a> {
    /// The frame's luma (0-255 floats).
    pub image: &'a Array2<f32>,
    /// The other frame's luma.
    pub other: &'a Array2<f32>,
    /// Flow to the other frame.
    pub flow: &'a Flow,
    /// Where the forward-backward check fails (occluded in the other).
    pub occluded: &'a Array2<bool>,
    /// The trajectory's second difference per pixel (flow to the other
    /// frame plus flow to the frame before this one), if known.
    pub acceleration: Option<&'a Flow>,
}

/// Per pixel: weight, flow to 0 (u, v), flow to 1 (u, v), seen in 0,
/// seen in 1; each but the weight summed times the weight.
type Cell = [f32; 7];

struct Accumulator {
    width: usize,
    height: usize,
    cells: Vec<Cell>,
}

impl Accumulator {
    fn new(width: usize, height: usize) -> Accumulator {
        Accumulator {
            width,
            height,
            cells: vec![[0.0; 7]; width * height],
        }
    }

    fn merge(mut self, other: Accumulator) -> Accumulator {
        for (a, b) in self.cells.iter_mut().zip(other.cells) {
            for (x, y) in a.iter_mut().zip(b) {
                *x += y;
            }
        }
        self
    }
}

/// How fast a splat's weight falls with its match's error (grey levels).
const ERROR_SCALE: f32 = 8.0;
/// A flow shorter than this (pixels) whose match is no better than no
/// motion's by this many grey levels is taken as no motion.
const STILL_RADIUS: f32 = 1.5;
const STILL_MARGIN: f32 = 1.0;

/// Splats both sides to time `t` in (0, 1) (the two sides on two threads).
pub fn intermediate(side0: &Side<'_>, side1: &Side<'_>, t: f32) -> Intermediate {
    let (h, w) = side0.image.dim();
    let (a, b) = rayon::join(
        || splat(Accumulator::new(w, h), side0, t, 0),
        || splat(Accumulator::new(w, h), side1, 1.0 - t, 1),
    );
    normalise(a.merge(b))
}

/// Splats one side: frame `from` (0 or 1) at fraction `s` of the way to
/// the other frame.
fn splat(mut acc: Accumulator, side: &Side<'_>, s: f32, from: usize) -> Accumulator {
    let (h, w) = side.image.dim();
    let prior = 1.0 - s;
    let image = side.image.as_slice().expect("standard layout");
    let other = side.other.as_slice().expect("standard layout");
    let (fu, fv) = (
        side.flow.u().as_slice().expect("standard layout"),
        side.flow.v().as_slice().expect("standard layout"),
    );
    let occluded = side.occluded.as_slice().expect("standard layout");
    let acc_uv = side.acceleration.map(|a| {
        (
            a.u().as_slice().expect("standard layout"),
            a.v().as_slice().expect("standard layout"),
        )
    });
    // Along a parabola through the frame before, this one and the other:
    // at fraction s, s * flow + (s^2 - s) / 2 * acceleration.
    let bend = 0.5 * (s * s - s);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let (mut u, mut v) = (fu[i], fv[i]);
            if !(u.is_finite() && v.is_finite()) {
                continue;
            }
            let mut err = (image[i] - bilinear_clamped(other, w, h, x as f32 + u, y as f32 + v)).abs();
            // Where staying put matches as well, the flow's sub-pixel noise
            // would only blur a still background: stay put.
            let still = (image[i] - other[i]).abs();
            if still <= err + STILL_MARGIN && u * u + v * v < STILL_RADIUS * STILL_RADIUS {
                (u, v, err) = (0.0, 0.0, still);
            }
            let weight = prior * (-err / ERROR_SCALE).exp() * if occluded[i] { 0.5 } else { 1.0 };
            let (du, dv) = match acc_uv {
                Some((au, av)) if u != 0.0 || v != 0.0 => (s * u + bend * au[i], s * v + bend * av[i]),
                _ => (s * u, s * v),
            };
            // Motion to frame 0 and to frame 1 of the surface at q.
            let (back, ahead) = ((-du, -dv), (u - du, v - dv));
            let (to0, to1) = if from == 0 { (back, ahead) } else { (ahead, back) };
            let seen = match (occluded[i], from) {
                (false, _) => [1.0, 1.0],
                (true, 0) => [1.0, 0.0],
                (true, _) => [0.0, 1.0],
            };
            let cell = [1.0, to0.0, to0.1, to1.0, to1.1, seen[0], seen[1]];
            deposit(&mut acc, (x as f32 + du, y as f32 + dv), weight, &cell);
        }
    }
    acc
}

fn deposit(acc: &mut Accumulator, (qx, qy): (f32, f32), weight: f32, cell: &Cell) {
    let (w, h) = (acc.width as i64, acc.height as i64);
    // Truncation after an offset is floor for anything above -1024.
    let (x0, y0) = ((qx + 1024.0) as i64 - 1024, (qy + 1024.0) as i64 - 1024);
    let (fx, fy) = (qx - x0 as f32, qy - y0 as f32);
    for (dy, wy) in [(0, 1.0 - fy), (1, fy)] {
        for (dx, wx) in [(0, 1.0 - fx), (1, fx)] {
            let (px, py) = (x0 + dx, y0 + dy);
            if px < 0 || py < 0 || px >= w || py >= h {
                continue;
            }
            let k = weight * wx * wy;
            let target = &mut acc.cells[(py * w + px) as usize];
            for (t, c) in target.iter_mut().zip(cell) {
                *t += k * c;
            }
        }
    }
}

/// Weighted means where anything landed; elsewhere the neighbours' (by
/// growing the known region a pixel at a time), and seen in both frames.
fn normalise(mut acc: Accumulator) -> Intermediate {
    let floor = 1e-3;
    for c in acc.cells.iter_mut() {
        if c[0] > floor {
            let k = c[0];
            for v in c[1..].iter_mut() {
                *v /= k;
            }
        }
    }
    let mut known: Vec<bool> = acc.cells.iter().map(|c| c[0] > floor).collect();
    fill_holes(&mut acc, &mut known);
    let (w, h) = (acc.width, acc.height);
    let plane = |k: usize| {
        Array2::from_shape_vec((h, w), acc.cells.iter().map(|c| c[k]).collect()).expect("w * h cells")
    };
    Intermediate {
        to0: (plane(1), plane(2)),
        to1: (plane(3), plane(4)),
        seen0: plane(5),
        seen1: plane(6),
    }
}

/// Holes take the mean of their known 8-neighbours, ring by ring; what is
/// left after a bounded number of rings (a picture with nothing known)
/// stays still and is seen in both frames.
fn fill_holes(acc: &mut Accumulator, known: &mut [bool]) {
    let (w, h) = (acc.width, acc.height);
    let mut holes: Vec<usize> = (0..w * h).filter(|&i| !known[i]).collect();
    for _ in 0..64 {
        if holes.is_empty() {
            return;
        }
        let mut filled = Vec::new();
        for &i in &holes {
            let (y, x) = (i / w, i % w);
            let mut sum: Cell = [0.0; 7];
            for yy in y.saturating_sub(1)..(y + 2).min(h) {
                for xx in x.saturating_sub(1)..(x + 2).min(w) {
                    if known[yy * w + xx] {
                        sum[0] += 1.0;
                        for (s, v) in sum[1..].iter_mut().zip(&acc.cells[yy * w + xx][1..]) {
                            *s += v;
                        }
                    }
                }
            }
            if sum[0] > 0.0 {
                let n = sum[0];
                filled.push((i, sum.map(|s| s / n)));
            }
        }
        for (i, cell) in filled {
            acc.cells[i] = cell;
            known[i] = true;
        }
        holes.retain(|&i| !known[i]);
    }
    for i in holes {
        acc.cells[i] = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0];
    }
}
