//! Conversions between 8-bit planes and `ndarray` float fields, the two
//! picture forms of mocomp: padded `u8` planes for coding and block search,
//! `f32` arrays (`[[y, x]]`) for flow, gradients and pyramids.

use ndarray::Array2;

use crate::codec::picture::{PictureError, Plane};

/// The visible pixels of a plane as floats in 0..=255, `[[y, x]]`.
pub fn plane_to_array(plane: &Plane) -> Array2<f32> {
    let mut out = Array2::zeros((plane.height(), plane.width()));
    for (mut dst, src) in out.rows_mut().into_iter().zip(plane.rows()) {
        for (d, &s) in dst.iter_mut().zip(src) {
            *d = f32::from(s);
        }
    }
    out
}

/// The visible pixels of a plane, `[[y, x]]`.
pub fn plane_to_u8_array(plane: &Plane) -> Array2<u8> {
    let mut out = Array2::zeros((plane.height(), plane.width()));
    for (mut dst, src) in out.rows_mut().into_iter().zip(plane.rows()) {
        dst.iter_mut().zip(src).for_each(|(d, &s)| *d = s);
    }
    out
}

/// A plane from a float field: rounded to nearest, clamped to 0..=255.
pub fn array_to_plane(values: &Array2<f32>) -> Result<Plane, PictureError> {
    let (h, w) = values.dim();
    let mut plane = Plane::new(w, h)?;
    for (dst, src) in plane.rows_mut().zip(values.rows()) {
        for (d, &s) in dst.iter_mut().zip(src.iter()) {
            *d = s.round().clamp(0.0, 255.0) as u8;
        }
    }
    plane.extend_border();
    Ok(plane)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_is_exact() {
        let p = Plane::from_fn(7, 3, |x, y| (x * 31 + y * 90) as u8).unwrap();
        assert_eq!(array_to_plane(&plane_to_array(&p)).unwrap(), p);
    }

    #[test]
    fn values_are_rounded_and_clamped() {
        let a = ndarray::arr2(&[[-3.0f32, 0.49, 0.5, 254.6, 300.0]]);
        assert_eq!(array_to_plane(&a).unwrap().to_packed(), vec![0, 0, 1, 255, 255]);
    }
}
