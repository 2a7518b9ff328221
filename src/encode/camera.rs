//! The camera's motion from one source to the next, found before the
//! macroblocks' search on pictures reduced two to eight times (encoder
//! side, not normative): where the searches centre their windows. A hand-held
//! camera moves 20-40 px a frame and changes direction from frame to
//! frame; a window of 16 pels around zero misses it, and one around each
//! block's own predictors lets flat areas' vectors drift. x264 finds the
//! same large motion through its lookahead's half-size search.

use crate::codec::mv::Mv;
use crate::codec::{PictureError, Plane};
use crate::me::{self, MeConfig, Method, Metric};

/// How much smaller each side of the pictures the camera's motion is
/// found on may be, the most first: the most that leaves enough blocks
/// ([`scale_for`]).
const SCALES: [usize; 3] = [8, 4, 2];

/// Blocks of the reduced pictures (128x128 pels of the frame at the most):
/// a window row of their SADs is one kernel call ([`RANGE`]).
const BLOCK: usize = 16;

/// Search range on the reduced pictures (56 pels of the frame at the
/// most): a window row is then 15 positions, which the SAD kernel of
/// sixteen covers.
const RANGE: i32 = 7;

/// The reduction for `width x height` pictures: the largest that leaves
/// 4 x 3 blocks (1080p and 720p: 8; 640x360 and CIF: 4; QCIF: 2), none
/// for smaller pictures.
fn scale_for(width: usize, height: usize) -> Option<usize> {
    SCALES
        .into_iter()
        .find(|&s| width / s / BLOCK >= 4 && height / s / BLOCK >= 3)
}

/// The camera's motion from each source to the one before it, from the
/// sources reduced ([`scale_for`]; each reduced once).
#[derive(Default)]
pub(crate) struct CameraMotion {
    /// The previous source, reduced (none when too small to reduce).
    previous: Option<Plane>,
}

impl CameraMotion {
    /// The camera's motion from `source` (luma) to the source given the
    /// call before ([`camera_motion`]); zero for the first, and where the
    /// pictures are too small or differ in size.
    pub(crate) fn next(&mut self, source: &Plane) -> Result<Mv, PictureError> {
        let Some(scale) = scale_for(source.width(), source.height()) else {
            self.previous = None;
            return Ok(Mv::ZERO);
        };
        let (w, h) = (source.width() / scale, source.height() / scale);
        let mut small = reduce(source, scale, w, h)?;
        small.extend_border();
        let motion = match &self.previous {
            Some(previous) if (previous.width(), previous.height()) == (w, h) => {
                camera_motion(&small, previous, scale)
            }
            _ => Mv::ZERO,
        };
        self.previous = Some(small);
        Ok(motion)
    }
}

/// The camera's motion from `source` to `reference` (reduced `scale`
/// times, the same size, the reference's borders extended), quarter-pel
/// at full size, rounded to whole pels: the median of the vectors of
/// `BLOCK`-sided blocks found by exhaustive search, each block's counted
/// as zero unless its vector clearly beats zero (a flat wall matches
/// anywhere).
fn camera_motion(source: &Plane, reference: &Plane, scale: usize) -> Mv {
    let Some(vectors) = evidenced_vectors(source, reference) else {
        return Mv::ZERO;
    };
    let median = |component: fn(&Mv) -> i32| {
        let mut values: Vec<i32> = vectors.iter().map(component).collect();
        let middle = values.len() / 2;
        *values.select_nth_unstable(middle).1
    };
    // Reduced quarter pels times the scale, then whole pels (a window's
    // centre is a full-pel position).
    let whole = |v: i32| (v * scale as i32 + 2) >> 2;
    Mv::full_pel(whole(median(|v| v.x)), whole(median(|v| v.y)))
}

/// The reduced pictures' block vectors (quarter pels of the reduced
/// pictures), zero where zero does about as well.
fn evidenced_vectors(source: &Plane, reference: &Plane) -> Option<Vec<Mv>> {
    let field = me::estimate(source, reference, &search_config()).ok()?;
    let (cols, rows) = (source.width() / BLOCK, source.height() / BLOCK);
    let mut vectors = Vec::with_capacity(cols * rows);
    for row in 0..rows {
        for col in 0..cols {
            let still = still_sad(source, reference, col * BLOCK, row * BLOCK);
            let best = field.cost(col, row);
            // Zero unless the vector saves half a grey level a sample and
            // an eighth of the cost.
            let clear = still > best + (BLOCK * BLOCK / 2) as u32 + best / 8;
            vectors.push(if clear { field.vector(col, row) } else { Mv::ZERO });
        }
    }
    Some(vectors)
}

/// Exhaustive search by SAD, whole pels of the reduced pictures (the
/// median is then within four pels of the frame, well inside the window
/// it centres), a rate term keeping flat areas on their neighbours'
/// vector.
fn search_config() -> MeConfig {
    let mut cfg = MeConfig::new(Method::Esa, BLOCK, RANGE);
    cfg.metric = Metric::Sad;
    cfg.lambda = 16.0;
    cfg
}

/// The SAD of the `BLOCK`-sided block at (x, y) of `a` against the same
/// place in `b`.
fn still_sad(a: &Plane, b: &Plane, x: usize, y: usize) -> u32 {
    (y..y + BLOCK)
        .map(|r| {
            let (ra, rb) = (&a.row(r)[x..x + BLOCK], &b.row(r)[x..x + BLOCK]);
            ra.iter()
                .zip(rb)
                .map(|(&p, &q)| u32::from(p.abs_diff(q)))
                .sum::<u32>()
        })
        .sum()
}

/// The reduced pictures' border: what the search reads beyond them
/// (`RANGE + BLOCK + 8`, [`me::estimate`]'s check), not the default 96,
/// whose border held most of a reduced picture's samples and of the
/// search's box sums (which cover the whole buffer).
const REDUCED_PAD: usize = (RANGE as usize + BLOCK + 8).next_multiple_of(8);

/// `plane` reduced to `w x h` by the mean of each `scale x scale` square
/// (rounded): a square's rows added lane by lane first (sixteen-bit lanes
/// the compiler vectorises), then each square's columns.
fn reduce(plane: &Plane, scale: usize, w: usize, h: usize) -> Result<Plane, PictureError> {
    let mut out = Plane::with_padding(w, h, REDUCED_PAD)?;
    let area = (scale * scale) as u32;
    if scale == 8 {
        // The eighths (720p and larger): the pixel table's sums of eight
        // samples over eight rows are each square's sum.
        let group_sums = crate::me::dsp::pixel().group_sums;
        let mut sums = vec![0u32; w];
        for y in 0..h {
            let at = plane.index(0, (8 * y) as isize);
            group_sums(&plane.data()[at..], plane.stride(), (8 * w, 8), &mut sums);
            for (o, &sum) in out.row_mut(y).iter_mut().zip(&sums) {
                *o = ((sum + area / 2) / area) as u8;
            }
        }
        return Ok(out);
    }
    let mut columns = vec![0u16; w * scale];
    for y in 0..h {
        columns.fill(0);
        for i in 0..scale {
            add_row(&mut columns, &plane.row(scale * y + i)[..w * scale]);
        }
        for (o, square) in out.row_mut(y).iter_mut().zip(columns.chunks_exact(scale)) {
            let sum: u32 = square.iter().map(|&c| u32::from(c)).sum();
            *o = ((sum + area / 2) / area) as u8;
        }
    }
    Ok(out)
}

/// `sums[i] += row[i]` (at most eight rows are added: no overflow).
fn add_row(sums: &mut [u16], row: &[u8]) {
    for (s, &p) in sums.iter_mut().zip(row) {
        *s += u16::from(p);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A picture of blobs about 12 pels across (smooth random values on a
    /// 12-pel lattice), its content shifted by `(dx, dy)` whole pels.
    fn textured(w: usize, h: usize, (dx, dy): (i32, i32)) -> Plane {
        let lattice = |i: i64, j: i64| {
            let mut v = (i.wrapping_mul(73_856_093) ^ j.wrapping_mul(19_349_663)) as u64;
            v = v.wrapping_mul(0x9e37_79b9_7f4a_7c15);
            ((v >> 40) % 200) as f64 + 28.0
        };
        Plane::from_fn(w, h, |x, y| {
            let (x, y) = (
                (x as f64 - f64::from(dx)) / 12.0,
                (y as f64 - f64::from(dy)) / 12.0,
            );
            let (i, j) = (x.floor(), y.floor());
            let (fx, fy) = (x - i, y - j);
            let (i, j) = (i as i64, j as i64);
            let top = lattice(i, j) * (1.0 - fx) + lattice(i + 1, j) * fx;
            let bottom = lattice(i, j + 1) * (1.0 - fx) + lattice(i + 1, j + 1) * fx;
            (top * (1.0 - fy) + bottom * fy).round() as u8
        })
        .unwrap()
    }

    #[test]
    fn a_camera_shift_beyond_the_search_range_is_found_within_a_few_pels() {
        // Shifts of the whole picture, as a shaken camera's: the source at
        // (x, y) shows the reference at (x + dx, y + dy).
        // 640x384 is reduced eight times (reach 56 pels), CIF four (28).
        let cases = [
            ((640, 384), (0, 0)),
            ((640, 384), (24, -8)),
            ((640, 384), (-37, 13)),
            ((640, 384), (5, 41)),
            ((352, 288), (-22, 10)),
        ];
        for ((w, h), shift) in cases {
            let reference = textured(w, h, (0, 0));
            let source = textured(w, h, (-shift.0, -shift.1));
            let mut camera = CameraMotion::default();
            assert_eq!(camera.next(&reference).unwrap(), Mv::ZERO, "the first source");
            let found = camera.next(&source).unwrap();
            let (fx, fy) = (found.x / 4, found.y / 4);
            // Whole pels of the reduced pictures are up to eight of the
            // frame.
            assert!(
                (fx - shift.0).abs() <= 4 && (fy - shift.1).abs() <= 4,
                "{shift:?}: found ({fx}, {fy})"
            );
        }
    }

    #[test]
    fn a_still_flat_picture_with_one_moving_object_gives_zero() {
        // A flat wall (a gentle ramp) and a textured square that moves 24
        // pels: most blocks match anywhere, and count as still.
        let scene = |at: usize| {
            let texture = textured(64, 64, (0, 0));
            Plane::from_fn(640, 384, |x, y| {
                if (at..at + 64).contains(&x) && (64..128).contains(&y) {
                    texture.get(x - at, y - 64)
                } else {
                    (100 + x / 40) as u8
                }
            })
            .unwrap()
        };
        let mut camera = CameraMotion::default();
        camera.next(&scene(40)).unwrap();
        assert_eq!(camera.next(&scene(64)).unwrap(), Mv::ZERO);
    }

    #[test]
    fn blocks_that_match_nowhere_better_than_in_place_count_as_still() {
        // Two unrelated noise pictures (reduced): every block finds some
        // best vector, none clearly better than zero.
        let noise = |seed: u64| {
            Plane::from_fn(80, 48, |x, y| {
                let mut v = (x as u64 * 131 + y as u64 * 7919 + seed).wrapping_mul(0x9e37_79b9_7f4a_7c15);
                v ^= v >> 29;
                (118 + (v % 21)) as u8
            })
            .unwrap()
        };
        let (source, mut reference) = (noise(1), noise(2));
        reference.extend_border();
        let vectors = evidenced_vectors(&source, &reference).unwrap();
        assert!(vectors.iter().all(|&v| v == Mv::ZERO), "{vectors:?}");
        // The search alone moves them.
        let field = me::estimate(&source, &reference, &search_config()).unwrap();
        assert!(field.vectors().iter().any(|&v| v != Mv::ZERO));
    }

    #[test]
    fn pictures_too_small_to_reduce_give_zero() {
        let mut camera = CameraMotion::default();
        let narrow = 4 * 2 * BLOCK - 1;
        let p = textured(narrow, 256, (0, 0));
        let q = textured(narrow, 256, (9, 0));
        assert_eq!(camera.next(&p).unwrap(), Mv::ZERO);
        assert_eq!(camera.next(&q).unwrap(), Mv::ZERO);
    }

    #[test]
    fn the_reduction_is_the_largest_that_leaves_four_by_three_blocks() {
        for ((w, h), scale) in [
            ((1920, 1080), Some(8)),
            ((1280, 720), Some(8)),
            ((640, 360), Some(4)),
            ((352, 288), Some(4)),
            ((320, 240), Some(4)),
            ((176, 144), Some(2)),
            ((127, 500), None),
        ] {
            assert_eq!(scale_for(w, h), scale, "{w}x{h}");
        }
    }

    #[test]
    fn reduction_is_the_rounded_mean_of_each_square() {
        for scale in SCALES {
            let side = 2 * scale;
            let p = Plane::from_fn(side, side, |x, y| (x + side * y) as u8).unwrap();
            let r = reduce(&p, scale, 2, 2).unwrap();
            // The mean of x + side * y over a square is its centre's
            // value: x and y each average to the middle of their span.
            let centre = |i: usize, j: usize| {
                let mid = |k: usize| (k * scale) as f64 + (scale as f64 - 1.0) / 2.0;
                (mid(i) + side as f64 * mid(j) + 0.5).floor() as u8
            };
            for (i, j) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                assert_eq!(r.get(i, j), centre(i, j), "scale {scale}, square ({i}, {j})");
            }
        }
    }

    #[test]
    fn a_wide_reduction_is_the_rounded_mean_of_every_square() {
        // 37 squares a row: the SIMD sums' whole chunks and their rest.
        for scale in SCALES {
            let (w, h) = (37, 3);
            let noise = |x: usize, y: usize| ((x * 2_654_435_761 + y * 40_503) >> 7) as u8;
            let p = Plane::from_fn(w * scale, h * scale, noise).unwrap();
            let r = reduce(&p, scale, w, h).unwrap();
            let area = (scale * scale) as u32;
            for (i, j) in (0..h).flat_map(|j| (0..w).map(move |i| (i, j))) {
                let sum: u32 = (0..scale)
                    .flat_map(|dy| (0..scale).map(move |dx| (dx, dy)))
                    .map(|(dx, dy)| u32::from(p.get(i * scale + dx, j * scale + dy)))
                    .sum();
                let mean = ((sum + area / 2) / area) as u8;
                assert_eq!(r.get(i, j), mean, "scale {scale}, square ({i}, {j})");
            }
        }
    }
}
