//! Middlebury `.flo` files: round trips, unknown-flow marking, malformed files.

use std::io::Write;

use mocomp::flow::Flow;
use mocomp::io::flo::{self, FloError, UNKNOWN_FLOW};
use ndarray::Array2;
use proptest::prelude::*;

fn header(w: i32, h: i32) -> Vec<u8> {
    let mut b = b"PIEH".to_vec();
    b.extend_from_slice(&w.to_le_bytes());
    b.extend_from_slice(&h.to_le_bytes());
    b
}

fn file_with(bytes: &[u8]) -> tempfile::NamedTempFile {
    let mut f = tempfile::NamedTempFile::new().unwrap();
    f.write_all(bytes).unwrap();
    f
}

#[test]
fn layout_is_middlebury() {
    let flow = Flow::from_fn(2, 1, |x, _| (x as f32 + 0.5, -2.0));
    let mut bytes = Vec::new();
    flo::write_flo_to(&mut bytes, &flow).unwrap();
    // The magic reads as the float 202021.25.
    assert_eq!(f32::from_le_bytes(bytes[0..4].try_into().unwrap()), 202021.25);
    let floats: Vec<f32> = bytes[12..]
        .chunks(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert_eq!(&bytes[4..12], &[2, 0, 0, 0, 1, 0, 0, 0]);
    assert_eq!(floats, vec![0.5, -2.0, 1.5, -2.0]);
}

#[test]
fn unknown_flow_reads_as_invalid() {
    let mut bytes = header(4, 1);
    for (u, v) in [(1e9f32, 0.0f32), (1.5e9, 0.0), (0.0, -2e9), (f32::NAN, 1.0)] {
        bytes.extend_from_slice(&u.to_le_bytes());
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    let flow = flo::read_flo_from(&bytes[..]).unwrap();
    assert_eq!(
        flow.valid().iter().copied().collect::<Vec<_>>(),
        vec![true, false, false, false]
    );
    assert_eq!(flow.get(1, 0), (0.0, 0.0), "invalid pixels hold zero motion");
}

#[test]
fn invalid_pixels_are_written_as_unknown_and_read_back_invalid() {
    let mut valid = Array2::from_elem((3, 4), true);
    valid[[1, 2]] = false;
    let flow = Flow::from_parts(
        Array2::from_elem((3, 4), 1.25),
        Array2::from_elem((3, 4), -0.5),
        valid,
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("f.flo");
    flo::write_flo(&path, &flow).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let at = 12 + 8 * (4 + 2);
    assert_eq!(
        f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()),
        UNKNOWN_FLOW
    );
    assert_eq!(flo::read_flo(&path).unwrap(), flow);
}

#[test]
fn malformed_files_are_clear_errors() {
    let mut good = header(3, 2);
    good.extend(std::iter::repeat_n(0u8, 48));
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("empty", vec![]),
        ("short header", b"PIEH\x03\x00".to_vec()),
        ("bad magic", [b"HEIP".as_slice(), &good[4..]].concat()),
        ("zero width", [header(0, 2), vec![0; 48]].concat()),
        ("negative height", [header(3, -2), vec![0; 48]].concat()),
        ("huge size", header(1 << 30, 1 << 30)),
        (
            "too large for the limit",
            [header(20000, 1), vec![0; 160000]].concat(),
        ),
        ("truncated data", good[..good.len() - 1].to_vec()),
        ("trailing data", [good.clone(), vec![0]].concat()),
        (
            "header promises more than present",
            [header(100, 100), vec![0; 48]].concat(),
        ),
    ];
    for (what, bytes) in cases {
        let from_file = flo::read_flo(file_with(&bytes).path()).unwrap_err();
        let from_stream = flo::read_flo_from(&bytes[..]).unwrap_err();
        for err in [&from_file, &from_stream] {
            assert!(!matches!(err, FloError::Io(_)), "{what}: {err:?}");
            assert!(!err.to_string().is_empty());
        }
    }
    let err = flo::read_flo_from(&[header(100, 100), vec![0; 48]].concat()[..]).unwrap_err();
    assert!(err.to_string().contains("needs 80012 bytes, it has 60"), "{err}");
    let err = flo::read_flo_from(&header(3, -2)[..]).unwrap_err();
    assert!(err.to_string().contains("3x-2"), "{err}");
}

#[test]
fn a_missing_file_is_an_io_error() {
    assert!(matches!(
        flo::read_flo(std::path::Path::new("/no/such/file.flo")),
        Err(FloError::Io(_))
    ));
}

proptest! {
    #[test]
    fn round_trip_keeps_values_and_mask(
        w in 1usize..20, h in 1usize..20,
        values in proptest::collection::vec((-500.0f32..500.0, -500.0f32..500.0, any::<bool>()), 400)
    ) {
        let mut u = Array2::zeros((h, w));
        let mut v = Array2::zeros((h, w));
        let mut valid = Array2::from_elem((h, w), true);
        for y in 0..h {
            for x in 0..w {
                let (a, b, ok) = values[y * w + x];
                u[[y, x]] = a;
                v[[y, x]] = b;
                valid[[y, x]] = ok;
            }
        }
        let flow = Flow::from_parts(u, v, valid);
        let mut bytes = Vec::new();
        flo::write_flo_to(&mut bytes, &flow).unwrap();
        prop_assert_eq!(bytes.len(), 12 + 8 * w * h);
        prop_assert_eq!(flo::read_flo_from(&bytes[..]).unwrap(), flow);
    }

    #[test]
    fn any_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
        let _ = flo::read_flo_from(&bytes[..]);
        let mut with_magic = b"PIEH".to_vec();
        with_magic.extend(&bytes);
        let _ = flo::read_flo_from(&with_magic[..]);
    }
}
