//! Half-pel planes of a reference, for sub-pel search (x264's approach).
//!
//! The three half-pel phases (horizontal, vertical, both) are computed once
//! per reference with the codec's own filter, so every half-pel candidate
//! costs a copy; a quarter-pel candidate is the rounded average of its two
//! nearest full- or half-pel samples, as H.264 interpolates. That average
//! only approximates the codec's 8-tap quarter-pel filter: the search uses
//! it to rank candidates, and what the encoder then predicts with is the
//! codec's exact interpolation.

use std::cell::RefCell;

use super::dsp::{average_rows, copy_rows, fill_halfpel, pixel, PixelDsp};
use crate::codec::interp::predict_luma;
use crate::codec::mv::Mv;
use crate::codec::Plane;

thread_local! {
    /// Planes of earlier references, reused: a search per frame would
    /// otherwise fault in three fresh planes every time.
    static SPARE: RefCell<Vec<Plane>> = const { RefCell::new(Vec::new()) };
}

/// A plane of this size and border from the spares, or a new one.
fn take_plane(w: usize, h: usize, pad: usize) -> Option<Plane> {
    let reused = SPARE.with(|s| {
        let mut s = s.borrow_mut();
        let i = s
            .iter()
            .position(|p| (p.width(), p.height(), p.pad()) == (w, h, pad))?;
        Some(s.swap_remove(i))
    });
    reused.or_else(|| Plane::with_padding(w, h, pad).ok())
}

/// How far beyond a sample the 8-tap filter reads (3 before, 4 after).
const FILTER_REACH: usize = 4;

/// The reference's half-pel phases over the picture and a margin around it.
pub(crate) struct HalfPel {
    /// Horizontal, vertical and diagonal half-pel samples: entry (x, y) is
    /// the sample at (x + 1/2, y), (x, y + 1/2), (x + 1/2, y + 1/2).
    /// (Only the picture and margin are written; nothing reads beyond.)
    planes: Vec<Plane>,
    /// How far outside the picture the planes are filled.
    margin: isize,
    /// The kernels that made the planes and average them.
    dsp: &'static PixelDsp,
}

impl HalfPel {
    /// The half-pel planes of `reference`, filled `margin` pixels beyond
    /// each edge; `margin + 4` must not exceed the reference's border.
    pub fn new(reference: &Plane, margin: usize) -> Option<HalfPel> {
        let (w, h, pad) = (reference.width(), reference.height(), reference.pad());
        if margin + FILTER_REACH > pad {
            return None;
        }
        let mut planes = Vec::with_capacity(3);
        for _ in 0..3 {
            planes.push(take_plane(w, h, pad)?);
        }
        let dsp = pixel();
        // A band per worker: the planes are most of what a frame's motion
        // analysis does on one thread before its rows start.
        let bands = rayon::current_num_threads();
        fill_halfpel(dsp.halfpel_planes, reference, margin, &mut planes, bands);
        Some(HalfPel {
            planes,
            margin: margin as isize,
            dsp,
        })
    }

    /// How far beyond the picture the planes are filled.
    pub fn margin(&self) -> usize {
        self.margin as usize
    }

    /// Whether the `b x b` block at (bx, by), and one sample around it,
    /// lies inside `reference`'s filled margin.
    fn reaches(&self, reference: &Plane, bx: isize, by: isize, b: usize) -> bool {
        let (w, h) = (reference.width() as isize, reference.height() as isize);
        let b = b as isize;
        bx > -self.margin && by > -self.margin && bx + b < w + self.margin && by + b < h + self.margin
    }

    /// The `b x b` block at (x, y) displaced by the quarter-pel vector
    /// (mvx, mvy) where it lies on the half-pel grid (both components
    /// even): its samples where they are, in the reference or one of its
    /// planes, and their stride, with no copy (as x264's `get_ref`);
    /// `None` at a quarter-pel position or beyond the filled margin.
    pub fn block_in_place<'a>(
        &'a self,
        reference: &'a Plane,
        (x, y): (isize, isize),
        (mvx, mvy): (i32, i32),
        b: usize,
    ) -> Option<(&'a [u8], usize)> {
        let (bx, by) = (x + (mvx >> 2) as isize, y + (mvy >> 2) as isize);
        if (mvx | mvy) & 1 != 0 || !self.reaches(reference, bx, by, b) {
            return None;
        }
        let plane = match (mvx & 3, mvy & 3) {
            (0, 0) => reference,
            (2, 0) => &self.planes[0],
            (0, 2) => &self.planes[1],
            _ => &self.planes[2],
        };
        Some((&plane.data()[plane.index(bx, by)..], plane.stride()))
    }

    /// The `b x b` block at (x, y) displaced by the quarter-pel vector
    /// (mvx, mvy), into `out`; `false` (nothing written) when it reaches
    /// beyond the filled margin.
    #[allow(clippy::too_many_arguments)]
    pub fn predict<'a>(
        &'a self,
        reference: &'a Plane,
        x: isize,
        y: isize,
        mvx: i32,
        mvy: i32,
        b: usize,
        out: &mut [u8],
    ) -> bool {
        let (bx, by) = (x + (mvx >> 2) as isize, y + (mvy >> 2) as isize);
        // Samples read: one beyond the block on each side at most.
        if !self.reaches(reference, bx, by, b) {
            return false;
        }
        let (fx, fy) = (mvx & 3, mvy & 3);
        // A point of the half-pel grid, in quarter-pels from (bx, by):
        // its plane and integer offset.
        let point = |px: i32, py: i32| -> (&'a Plane, isize, isize) {
            let plane = match (px & 3, py & 3) {
                (0, 0) => reference,
                (2, 0) => &self.planes[0],
                (0, 2) => &self.planes[1],
                _ => &self.planes[2],
            };
            (plane, bx + (px >> 2) as isize, by + (py >> 2) as isize)
        };
        let rows = |(p, px, py): (&'a Plane, isize, isize)| (&p.data()[p.index(px, py)..], p.stride());
        // The macroblock and partition sizes through the table; 8 passed
        // as a constant, so that the rows have a length the compiler knows.
        let copy = |(a, sa): (&[u8], usize), out: &mut [u8]| match b {
            16 => (self.dsp.copy_16x16)(a, sa, out),
            8 => copy_rows(8, a, sa, out),
            _ => copy_rows(b, a, sa, out),
        };
        let average = |from, to, out: &mut [u8]| match b {
            16 => (self.dsp.average_16x16)(rows(from), rows(to), out),
            8 => (self.dsp.average_8x8)(rows(from), rows(to), out),
            _ => average_rows(b, rows(from), rows(to), out),
        };
        match (fx & 1, fy & 1) {
            (0, 0) => copy(rows(point(fx, fy)), out),
            (1, 0) => average(point(fx - 1, fy), point(fx + 1, fy), out),
            (0, 1) => average(point(fx, fy - 1), point(fx, fy + 1), out),
            _ => average(point(2, 4 * (fy / 2)), point(4 * (fx / 2), 2), out),
        }
        true
    }
}

/// The `b x b` block of `reference` at (x, y) displaced by the
/// quarter-pel vector `mv`, and its stride: where it lies on the half-pel
/// grid, in place ([`HalfPel::block_in_place`]); else predicted into
/// `scratch` (`b * b` samples), on `halfpel`'s planes where they reach
/// ([`HalfPel::predict`]) or else by the codec's filter.
pub fn block_or_predicted<'a>(
    halfpel: Option<&'a HalfPel>,
    reference: &'a Plane,
    (x, y): (isize, isize),
    mv: Mv,
    b: usize,
    scratch: &'a mut [u8],
) -> (&'a [u8], usize) {
    if let Some(found) = halfpel.and_then(|h| h.block_in_place(reference, (x, y), (mv.x, mv.y), b)) {
        return found;
    }
    if !halfpel.is_some_and(|h| h.predict(reference, x, y, mv.x, mv.y, b, scratch)) {
        predict_luma(reference, x, y, mv.x, mv.y, b, b, scratch, b);
    }
    (scratch, b)
}

impl Drop for HalfPel {
    fn drop(&mut self) {
        SPARE.with(|s| {
            let mut s = s.borrow_mut();
            s.append(&mut self.planes);
            // Enough for two sizes in turn; older ones go.
            let excess = s.len().saturating_sub(6);
            s.drain(..excess);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn textured(w: usize, h: usize) -> Plane {
        Plane::from_fn(w, h, |x, y| {
            let (x, y) = (x as f64, y as f64);
            (128.0 + 60.0 * (x * 0.31).sin() * (y * 0.23).cos() + 30.0 * ((x + 2.0 * y) * 0.11).sin()) as u8
        })
        .unwrap()
    }

    #[test]
    fn half_pel_phases_equal_the_codec_and_quarter_pel_is_close() {
        let r = textured(64, 48);
        let hp = HalfPel::new(&r, 32).unwrap();
        let (mut a, mut b) = ([0u8; 256], [0u8; 256]);
        for mvy in -9..=9 {
            for mvx in -9..=9 {
                for (x, y) in [(0, 0), (16, 16), (48, 32)] {
                    assert!(hp.predict(&r, x, y, mvx, mvy, 16, &mut a));
                    predict_luma(&r, x, y, mvx, mvy, 16, 16, &mut b, 16);
                    let in_place = hp.block_in_place(&r, (x, y), (mvx, mvy), 16);
                    if mvx % 2 == 0 && mvy % 2 == 0 {
                        assert_eq!(a, b, "half-pel ({mvx}, {mvy}) at ({x}, {y})");
                        // The same samples where they lie.
                        let (samples, stride) = in_place.expect("a half-pel block in place");
                        for row in 0..16 {
                            assert_eq!(samples[row * stride..][..16], a[row * 16..][..16]);
                        }
                    } else {
                        assert!(in_place.is_none());
                        // The average of neighbours against the 8-tap
                        // filter: close on a smooth texture.
                        let worst = a.iter().zip(&b).map(|(&u, &v)| u.abs_diff(v)).max().unwrap();
                        assert!(worst <= 3, "quarter-pel ({mvx}, {mvy}): {worst}");
                    }
                }
            }
        }
        // Every sample of the three planes, on a picture of odd size.
        let r = textured(37, 21);
        let hp = HalfPel::new(&r, 16).unwrap();
        let mut one = [0u8; 1];
        for (p, (mvx, mvy)) in [(2, 0), (0, 2), (2, 2)].into_iter().enumerate() {
            for y in -16..21 + 16 {
                for x in -16..37 + 16 {
                    predict_luma(&r, x, y, mvx, mvy, 1, 1, &mut one, 1);
                    assert_eq!(hp.planes[p].at(x, y), one[0], "phase {p} at ({x}, {y})");
                }
            }
        }
        let r = textured(64, 48);
        let hp = HalfPel::new(&r, 32).unwrap();
        // Beyond the margin: refused, so that the caller uses the codec.
        assert!(!hp.predict(&r, 0, 0, -4 * 40, 0, 16, &mut a));
        assert!(hp.block_in_place(&r, (0, 0), (-4 * 40, 0), 16).is_none());
    }

    #[test]
    fn averages_round_half_up() {
        // The scalar rounding: (u + v + 1) >> 1, at every level's kernels.
        for level in crate::codec::cpu::available() {
            let dsp = super::super::dsp::PIXEL.at(level);
            let mut y = [0u8; 256];
            (dsp.average_16x16)((&[255u8; 256], 16), (&[0u8; 256], 16), &mut y);
            assert!(y.iter().all(|&v| v == 128), "{level:?}");
            (dsp.average_8x8)((&[3u8; 64], 8), (&[0u8; 64], 8), &mut y[..64]);
            assert!(y[..64].iter().all(|&v| v == 2), "{level:?}");
        }
    }
}
