//! Weighted prediction (FORMAT.md section 12): a P frame may scale and
//! offset each plane of its reference before predicting from it, so that a
//! fade or a change of light costs a few header bits instead of a residual
//! in every macroblock (H.264's explicit weighted prediction, applied to
//! the reference picture rather than to each prediction, which is the same
//! up to rounding and lets every motion tool use it unchanged).

use crate::bits::{BitError, BitReader, BitWriter};
use crate::picture::Frame;

pub use crate::consts::{MAX_OFFSET, WEIGHT_ONE};

/// One plane's weight: `s' = Clip(((s * scale + 32) >> 6) + offset)`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlaneWeight {
    /// Scale in 64ths, 0..=255.
    pub scale: u8,
    /// Offset, -255..=255.
    pub offset: i16,
}

impl PlaneWeight {
    /// The identity.
    pub const ONE: PlaneWeight = PlaneWeight { scale: 64, offset: 0 };

    /// `sample` weighted.
    #[inline]
    pub fn apply(self, sample: u8) -> u8 {
        let v = ((i32::from(sample) * i32::from(self.scale) + WEIGHT_ONE / 2) >> 6) + i32::from(self.offset);
        v.clamp(0, 255) as u8
    }
}

/// The weights of a frame's three planes (Y, Cb, Cr); `None` where a plane
/// is not weighted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Weights(pub [Option<PlaneWeight>; 3]);

impl Weights {
    /// No plane weighted.
    pub const NONE: Weights = Weights([None; 3]);

    /// Whether any plane is weighted.
    pub fn any(&self) -> bool {
        self.0.iter().any(Option::is_some)
    }

    /// `reference` with its weighted planes weighted, borders included
    /// (weighting commutes with the border's replication), into `out`
    /// (same size and padding).
    pub fn apply_into(&self, reference: &Frame, out: &mut Frame) {
        self.apply_rows(reference, out, 0..reference.height());
    }

    /// [`Weights::apply_into`] over the luma rows `luma_rows` (chroma: the
    /// rows under them) of `reference`, whose borders there are extended
    /// ([`crate::picture::Plane::extend_border_rows`]): the same samples of `out`
    /// as the whole frame's, borders included, when the rows come in runs
    /// from the top (a reference that arrives a band at a time). Luma rows
    /// start and end on even rows, or at the bottom.
    pub fn apply_rows(&self, reference: &Frame, out: &mut Frame, luma_rows: std::ops::Range<usize>) {
        for (i, w) in self.0.iter().enumerate() {
            let (src, dst) = (reference.plane(i), out.plane_mut(i));
            assert_eq!(
                (src.width(), src.height(), src.pad(), src.stride()),
                (dst.width(), dst.height(), dst.pad(), dst.stride()),
                "same geometry"
            );
            let rows = if i == 0 {
                luma_rows.clone()
            } else {
                let h = src.height();
                (luma_rows.start / 2).min(h)..luma_rows.end.div_ceil(2).min(h)
            };
            let span = src.rows_span(rows);
            let (from, to) = (&src.data()[span.clone()], &mut dst.data_mut()[span]);
            match w {
                Some(w) => weigh_samples(from, to, *w),
                None => to.copy_from_slice(from),
            }
        }
    }

    /// The header bits (FORMAT.md section 3).
    pub fn write(&self, w: &mut BitWriter) {
        for p in &self.0 {
            w.put_bit(p.is_some());
            if let Some(p) = p {
                w.put(u64::from(p.scale), 8);
                w.put_se(i32::from(p.offset));
            }
        }
    }

    /// Reads the header bits; `Err(Ok(what))` for values out of range.
    pub fn read(r: &mut BitReader<'_>) -> Result<Result<Weights, String>, BitError> {
        let mut out = Weights::NONE;
        for (i, slot) in out.0.iter_mut().enumerate() {
            if !r.get_bit()? {
                continue;
            }
            let scale = r.get(8)? as u8;
            let offset = r.get_se()?;
            if offset.abs() > MAX_OFFSET {
                return Ok(Err(format!(
                    "plane {i} weight offset {offset} outside -255..=255"
                )));
            }
            *slot = Some(PlaneWeight {
                scale,
                offset: offset as i16,
            });
        }
        Ok(Ok(out))
    }
}

/// [`PlaneWeight::apply`] of every sample of `src` into `dst`, in 16-bit
/// lanes the compiler vectorises (a table lookup a sample cannot be):
/// `s * scale + 32` stays below 2^16, the shifted value plus the offset
/// within i16, so the arithmetic is `apply`'s exactly.
fn weigh_samples(src: &[u8], dst: &mut [u8], w: PlaneWeight) {
    const _: () = assert!(WEIGHT_ONE == 64, "the shift below is log2(WEIGHT_ONE)");
    let (scale, offset) = (u16::from(w.scale), w.offset);
    for (d, &s) in dst.iter_mut().zip(src) {
        let v = ((u16::from(s) * scale + 32) >> 6) as i16 + offset;
        *d = v.clamp(0, 255) as u8;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_weighted_a_band_of_rows_at_a_time_is_the_whole_frame() {
        let mut reference = Frame::new(40, 30).unwrap();
        for (p, k) in [(0, 9), (1, 4), (2, 11)] {
            let plane = reference.plane_mut(p);
            for y in 0..plane.height() {
                for x in 0..plane.width() {
                    plane.set(x, y, (x * k + y * 5) as u8);
                }
            }
        }
        reference.extend_borders();
        let weights = Weights([
            Some(PlaneWeight {
                scale: 80,
                offset: -7,
            }),
            None,
            Some(PlaneWeight {
                scale: 60,
                offset: 12,
            }),
        ]);
        let mut whole = Frame::new(40, 30).unwrap();
        weights.apply_into(&reference, &mut whole);
        let mut banded = Frame::new(40, 30).unwrap();
        for rows in [0..2, 2..16, 16..30] {
            weights.apply_rows(&reference, &mut banded, rows);
        }
        for p in 0..3 {
            assert_eq!(
                whole.plane(p).data(),
                banded.plane(p).data(),
                "plane {p}, borders too"
            );
        }
    }

    #[test]
    fn a_plane_is_weighted_as_each_sample_alone() {
        let src: Vec<u8> = (0..=255).collect();
        let mut dst = vec![0u8; 256];
        for scale in 0..=255 {
            for offset in [-255, -200, -64, -1, 0, 1, 37, 128, 255] {
                let w = PlaneWeight { scale, offset };
                weigh_samples(&src, &mut dst, w);
                for (&s, &d) in src.iter().zip(&dst) {
                    assert_eq!(d, w.apply(s), "{s} by {w:?}");
                }
            }
        }
    }

    #[test]
    fn weights_scale_offset_and_clip() {
        let w = PlaneWeight {
            scale: 32,
            offset: 10,
        };
        assert_eq!(w.apply(100), 60);
        assert_eq!(w.apply(0), 10);
        assert_eq!(
            PlaneWeight {
                scale: 255,
                offset: 0
            }
            .apply(200),
            255
        );
        assert_eq!(
            PlaneWeight {
                scale: 64,
                offset: -20
            }
            .apply(10),
            0
        );
        for s in 0..=255u8 {
            assert_eq!(PlaneWeight::ONE.apply(s), s);
        }
    }

    #[test]
    fn a_weighted_reference_is_weighted_everywhere_borders_included() {
        let mut f = Frame::filled(20, 12, 100, 50, 200).unwrap();
        f.planes_mut()[0].set(3, 4, 30);
        f.extend_borders();
        let weights = Weights([
            Some(PlaneWeight {
                scale: 96,
                offset: -5,
            }),
            None,
            Some(PlaneWeight {
                scale: 64,
                offset: 20,
            }),
        ]);
        let mut out = Frame::new(20, 12).unwrap();
        weights.apply_into(&f, &mut out);
        assert_eq!(out.y().get(0, 0), 145);
        assert_eq!(out.y().get(3, 4), 40);
        assert_eq!(out.y().at(-5, -5), 145);
        assert_eq!(out.u().at(-3, 20), 50);
        assert_eq!(out.v().get(9, 5), 220);
    }

    #[test]
    fn header_bits_round_trip_and_bad_offsets_are_errors() {
        let weights = Weights([
            Some(PlaneWeight {
                scale: 0,
                offset: -255,
            }),
            None,
            Some(PlaneWeight {
                scale: 255,
                offset: 7,
            }),
        ]);
        let mut w = BitWriter::new();
        weights.write(&mut w);
        w.align();
        let bytes = w.into_bytes();
        assert_eq!(Weights::read(&mut BitReader::new(&bytes)), Ok(Ok(weights)));
        let mut w = BitWriter::new();
        w.put_bit(true);
        w.put(64, 8);
        w.put_se(300);
        w.align();
        let bytes = w.into_bytes();
        assert!(matches!(Weights::read(&mut BitReader::new(&bytes)), Ok(Err(_))));
    }
}
