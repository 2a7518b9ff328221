//! Pictures from and to image files: BT.601 luma and 4:2:0, size limits,
//! corrupt files.

use mocomp::codec::{Frame, Plane};
use mocomp::io::image::{read_frame, read_luma, write_frame, write_plane, write_rgb, ImageError};

#[test]
fn grey_planes_round_trip_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("grey.png");
    let plane = Plane::from_fn(13, 7, |x, y| (x * 19 + y * 31) as u8).unwrap();
    write_plane(&path, &plane).unwrap();
    assert_eq!(read_luma(&path).unwrap(), plane);
}

#[test]
fn colour_images_give_bt601_luma() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rgb.png");
    // Red, green, blue, white, and a mix: 0.299*200 + 0.587*100 + 0.114*50 = 124.2.
    let rgb = [255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255, 200, 100, 50];
    write_rgb(&path, 5, 1, &rgb).unwrap();
    assert_eq!(read_luma(&path).unwrap().to_packed(), vec![76, 150, 29, 255, 124]);
}

#[test]
fn frames_round_trip_through_rgb_closely() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("frame.png");
    // Odd size; chroma constant over each 2x2 block so nothing is lost to subsampling.
    let mut frame = Frame::new(7, 5).unwrap();
    for (p, plane) in frame.planes_mut().iter_mut().enumerate() {
        let scale = if p == 0 { 1 } else { 2 };
        for (y, row) in plane.rows_mut().enumerate() {
            for (x, s) in row.iter_mut().enumerate() {
                *s = match p {
                    0 => 60 + (x / 2 * 20 + y / 2 * 30) as u8,
                    1 => 110 + (x * 5 * scale) as u8,
                    _ => 140 - (y * 6 * scale) as u8,
                };
            }
        }
    }
    frame.extend_borders();
    write_frame(&path, &frame).unwrap();
    let back = read_frame(&path).unwrap();
    for p in 0..3 {
        for (a, b) in frame.plane(p).to_packed().iter().zip(back.plane(p).to_packed()) {
            assert!((*a as i32 - b as i32).abs() <= 2, "plane {p}: {a} vs {b}");
        }
    }
}

#[test]
fn oversized_images_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("wide.png");
    // 16385 x 1: over the width limit, cheap to write with the image crate directly.
    image::GrayImage::new(16385, 1).save(&path).unwrap();
    let err = read_luma(&path).unwrap_err();
    assert!(
        matches!(err, ImageError::Image(_) | ImageError::Size(_)),
        "{err:?}"
    );
}

#[test]
fn corrupt_and_missing_files_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.png");
    write_plane(&good, &Plane::from_fn(32, 32, |x, y| (x ^ y) as u8).unwrap()).unwrap();
    let bytes = std::fs::read(&good).unwrap();
    for (name, data) in [
        ("truncated.png", bytes[..bytes.len() / 2].to_vec()),
        ("garbage.png", b"not an image at all".to_vec()),
        ("empty.png", vec![]),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, data).unwrap();
        assert!(read_luma(&path).is_err(), "{name}");
        assert!(read_frame(&path).is_err(), "{name}");
    }
    assert!(matches!(
        read_luma(&dir.path().join("missing.png")),
        Err(ImageError::Io(_))
    ));
}

#[test]
fn a_failed_write_leaves_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.png");
    assert!(write_rgb(&path, 4, 4, &[0; 10]).is_err());
    assert!(!path.exists());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "no temporary file left behind"
    );
}
