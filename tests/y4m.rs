//! Y4M reading and writing: every 8-bit 4:2:0 header variant ffmpeg writes,
//! refusals with a useful message, and malformed or truncated streams.

use mocomp::codec::Frame;
use mocomp::io::y4m::{ChromaSiting, Y4mError, Y4mInfo, Y4mReader, Y4mWriter, CONVERT_HINT};
use proptest::prelude::*;
use std::io::{self, IoSliceMut, Read};

/// Sample `i` of plane `p` of frame `f`: distinct per position and frame.
fn sample(f: usize, p: usize, i: usize) -> u8 {
    (i * 7 + p * 50 + f * 13) as u8
}

/// A stream with the given header tags and `frames` frames of w x h.
fn stream(tags: &str, w: usize, h: usize, frames: usize) -> Vec<u8> {
    let mut out = format!("YUV4MPEG2 {tags}\n").into_bytes();
    let (cw, ch) = Frame::chroma_size(w, h);
    for f in 0..frames {
        out.extend_from_slice(b"FRAME\n");
        for (p, n) in [(0, w * h), (1, cw * ch), (2, cw * ch)] {
            out.extend((0..n).map(|i| sample(f, p, i)));
        }
    }
    out
}

fn check_frames(bytes: &[u8], w: usize, h: usize, frames: usize) -> Y4mInfo {
    check_frames_from(bytes, w, h, frames)
}

fn check_frames_from(input: impl Read, w: usize, h: usize, frames: usize) -> Y4mInfo {
    let reader = Y4mReader::new(input).unwrap();
    let info = reader.info().clone();
    let all = reader.read_all().unwrap();
    assert_eq!(all.len(), frames);
    for (f, frame) in all.iter().enumerate() {
        assert_eq!((frame.width(), frame.height()), (w, h));
        for p in 0..3 {
            let got = frame.plane(p).to_packed();
            let want: Vec<u8> = (0..got.len()).map(|i| sample(f, p, i)).collect();
            assert_eq!(got, want, "frame {f} plane {p}");
        }
    }
    info
}

#[test]
fn every_420_variant_ffmpeg_writes_is_read() {
    let cases: &[(&str, ChromaSiting)] = &[
        ("W8 H6 F30:1 Ip A1:1 C420jpeg XYSCSS=420JPEG", ChromaSiting::Jpeg),
        (
            "W8 H6 F30:1 Ip A0:0 C420jpeg XYSCSS=420JPEG XCOLORRANGE=LIMITED",
            ChromaSiting::Jpeg,
        ),
        (
            "W8 H6 F25:1 Ip A1:1 C420mpeg2 XYSCSS=420MPEG2",
            ChromaSiting::Mpeg2,
        ),
        (
            "W8 H6 F25:1 Ip A59:54 C420paldv XYSCSS=420PALDV",
            ChromaSiting::Paldv,
        ),
        ("W8 H6 F30:1 C420", ChromaSiting::Plain),
        ("W8 H6 F30:1", ChromaSiting::Jpeg),
        ("W8 H6 F30000:1001 I? A0:0", ChromaSiting::Jpeg),
        (
            "W8 H6 F24:1 Ip C420jpeg XCOLORRANGE=FULL XFOO=bar",
            ChromaSiting::Jpeg,
        ),
        ("H6 W8 C420mpeg2 F60:1", ChromaSiting::Mpeg2),
    ];
    for &(tags, siting) in cases {
        let info = check_frames(&stream(tags, 8, 6, 3), 8, 6, 3);
        assert_eq!(info.siting, siting, "{tags}");
    }
    let info = check_frames(
        &stream("W8 H6 F30000:1001 A59:54 XCOLORRANGE=FULL", 8, 6, 1),
        8,
        6,
        1,
    );
    assert_eq!(info.fps, (30000, 1001));
    assert_eq!(info.aspect, (59, 54));
    assert_eq!(info.color_range(), Some("FULL"));
    // A missing F tag means 25 fps, as in ffmpeg.
    assert_eq!(check_frames(&stream("W8 H6", 8, 6, 1), 8, 6, 1).fps, (25, 1));
}

#[test]
fn odd_and_tiny_sizes_are_read() {
    for (w, h) in [(1, 1), (7, 5), (1, 9), (33, 2)] {
        check_frames(&stream(&format!("W{w} H{h} F30:1 C420jpeg"), w, h, 2), w, h, 2);
    }
}

#[test]
fn frame_lines_with_parameters_are_read() {
    let mut bytes = stream("W4 H2 F30:1", 4, 2, 1);
    let pos = bytes.windows(6).position(|w| w == b"FRAME\n").unwrap();
    bytes.splice(pos + 5..pos + 5, b" Ip XFOO=1".iter().copied());
    check_frames(&bytes, 4, 2, 1);
}

fn header_error(tags: &str) -> Y4mError {
    Y4mReader::new(&stream(tags, 4, 4, 1)[..]).unwrap_err()
}

#[test]
fn other_formats_are_refused_with_a_conversion_hint() {
    let cases = [
        ("C422", "4:2:2"),
        ("C444", "4:4:4"),
        ("Cmono", "monochrome"),
        ("C420p10", "4:2:0 at 10 bits"),
        ("C422p12", "4:2:2 at 12 bits"),
        ("C444alpha", "4:4:4 with alpha"),
        ("C411", "4:1:1"),
        ("Cmono16", "monochrome at 16 bits"),
        ("C420p16", "4:2:0 at 16 bits"),
    ];
    for (tag, what) in cases {
        let msg = header_error(&format!("W4 H4 F30:1 {tag}")).to_string();
        assert!(msg.contains(tag) && msg.contains(what), "{tag}: {msg}");
        assert!(msg.contains(CONVERT_HINT), "{tag}: {msg}");
    }
    for (tag, what) in [
        ("It", "top field first"),
        ("Ib", "bottom field first"),
        ("Im", "mixed"),
    ] {
        let msg = header_error(&format!("W4 H4 F30:1 {tag} C420jpeg")).to_string();
        assert!(
            msg.contains(tag) && msg.contains(what) && msg.contains(CONVERT_HINT),
            "{msg}"
        );
    }
}

#[test]
fn non_ascii_header_tokens_are_errors_not_panics() {
    // A token starting with a multi-byte UTF-8 character, and invalid UTF-8.
    for line in [
        &b"YUV4MPEG2 W4 H4 \xc3\xa9x\n"[..],
        b"YUV4MPEG2 W\xff H4\n",
        b"YUV4MPEG2 W4 H4 C\xe2\x82\xac\n",
    ] {
        let _ = Y4mReader::new(line);
    }
    assert!(
        Y4mReader::new(&b"YUV4MPEG2 W4 H4 \xc3\xa9x\n"[..]).is_ok(),
        "unknown tags are ignored"
    );
    assert!(matches!(
        Y4mReader::new(&b"YUV4MPEG2 W\xff H4\n"[..]),
        Err(Y4mError::BadHeader(_))
    ));
}

#[test]
fn malformed_headers_are_errors() {
    let bad = [
        "F30:1 H4",                 // no width
        "W4 F30:1",                 // no height
        "W0 H4",                    // empty
        "W4 H0",                    // empty
        "Wabc H4",                  // not a number
        "W-4 H4",                   // negative
        "W4 H4 F30:0",              // zero denominator
        "W4 H4 F30",                // not a ratio
        "W4 H4 Ix",                 // unknown interlacing
        "W99999999999999999999 H4", // overflows
    ];
    for tags in bad {
        let err = header_error(tags);
        assert!(
            matches!(err, Y4mError::BadHeader(_) | Y4mError::Size(_)),
            "{tags}: {err:?}"
        );
    }
}

#[test]
fn absurd_sizes_are_refused_before_allocation() {
    let err = Y4mReader::new(&b"YUV4MPEG2 W16385 H16 F30:1\nFRAME\n"[..]).unwrap_err();
    assert!(err.to_string().contains("exceeds the maximum"), "{err}");
    let err = Y4mReader::new(&b"YUV4MPEG2 W100000000 H100000000 F30:1\n"[..]).unwrap_err();
    assert!(matches!(err, Y4mError::Size(_)), "{err:?}");
    // The largest legal size with almost no data: a clean truncation error.
    let mut reader = Y4mReader::new(&b"YUV4MPEG2 W16384 H16384 F30:1\nFRAME\nabc"[..]).unwrap();
    assert!(matches!(
        reader.read_frame(),
        Err(Y4mError::Truncated { frame: 0, .. })
    ));
}

#[test]
fn not_y4m_and_empty_inputs_are_errors() {
    assert!(matches!(Y4mReader::new(&b""[..]), Err(Y4mError::Empty)));
    assert!(matches!(
        Y4mReader::new(&b"\x89PNG\r\n\x1a\n...."[..]),
        Err(Y4mError::NotY4m)
    ));
    assert!(matches!(
        Y4mReader::new(&b"YUV4MPEG3 W4 H4\n"[..]),
        Err(Y4mError::NotY4m)
    ));
    assert!(matches!(
        Y4mReader::new(&b"YUV4MPEG2 W4 H4"[..]),
        Err(Y4mError::HeaderTooLong)
    ));
    let long = format!("YUV4MPEG2 W4 H4 X{}\n", "a".repeat(2000));
    assert!(matches!(
        Y4mReader::new(long.as_bytes()),
        Err(Y4mError::HeaderTooLong)
    ));
}

#[test]
fn a_truncated_last_frame_is_an_error_naming_it() {
    let full = stream("W8 H6 F30:1", 8, 6, 3);
    let frame_len = 6 + 8 * 6 + 2 * 4 * 3;
    let header_len = full.len() - 3 * frame_len;
    // Cut inside the data of frame 2, and inside its FRAME line.
    for cut in [full.len() - 1, full.len() - 30, header_len + 2 * frame_len + 3] {
        let mut reader = Y4mReader::new(&full[..cut]).unwrap();
        assert!(reader.read_frame().unwrap().is_some());
        assert!(reader.read_frame().unwrap().is_some());
        let err = reader.read_frame().unwrap_err();
        assert!(matches!(err, Y4mError::Truncated { frame: 2, .. }), "{err:?}");
        assert!(err.to_string().contains("frame 2 is truncated"), "{err}");
    }
    // Cut exactly between frames: a clean end.
    let reader = Y4mReader::new(&full[..header_len + 2 * frame_len]).unwrap();
    assert_eq!(reader.read_all().unwrap().len(), 2);
}

#[test]
fn garbage_where_a_frame_should_start_is_an_error() {
    let mut bytes = stream("W4 H2 F30:1", 4, 2, 1);
    bytes.extend_from_slice(b"JUNK\n0123456789012345");
    let mut reader = Y4mReader::new(&bytes[..]).unwrap();
    reader.read_frame().unwrap();
    assert!(matches!(
        reader.read_frame(),
        Err(Y4mError::BadFrameHeader { frame: 1 })
    ));
}

#[test]
fn writing_keeps_rate_aspect_siting_and_extensions() {
    let src = stream(
        "W7 H5 F30000:1001 A0:0 C420mpeg2 XYSCSS=420MPEG2 XCOLORRANGE=FULL",
        7,
        5,
        2,
    );
    let reader = Y4mReader::new(&src[..]).unwrap();
    let info = reader.info().clone();
    let frames = reader.read_all().unwrap();
    let mut out = Vec::new();
    let mut writer = Y4mWriter::new(&mut out, &info).unwrap();
    for f in &frames {
        writer.write_frame(f).unwrap();
    }
    drop(writer);
    let back = Y4mReader::new(&out[..]).unwrap();
    assert_eq!(back.info(), &info);
    assert_eq!(back.read_all().unwrap(), frames);
    // Square pixels round-trip too, though the y4m crate leaves out A1:1.
    let square = Y4mInfo::new(4, 4, (25, 1));
    let mut out = Vec::new();
    drop(Y4mWriter::new(&mut out, &square).unwrap());
    assert_eq!(Y4mReader::new(&out[..]).unwrap().info(), &square);
}

#[test]
fn the_writer_refuses_frames_of_another_size() {
    let mut out = Vec::new();
    let mut writer = Y4mWriter::new(&mut out, &Y4mInfo::new(8, 8, (30, 1))).unwrap();
    let err = writer.write_frame(&Frame::new(8, 6).unwrap()).unwrap_err();
    assert!(matches!(err, Y4mError::FrameSize { .. }), "{err:?}");
}

#[test]
fn bundled_real_clips_read_with_their_headers() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("samples");
    let a = Y4mReader::open(&dir.join("tree_qcif.y4m")).unwrap();
    assert_eq!((a.info().aspect, a.info().siting), ((0, 0), ChromaSiting::Jpeg));
    assert_eq!(a.info().color_range(), Some("LIMITED"));
    assert_eq!(a.read_all().unwrap().len(), 6);
    let b = Y4mReader::open(&dir.join("tree_qcif_mpeg4.y4m")).unwrap();
    assert_eq!((b.info().fps, b.info().siting), ((15, 1), ChromaSiting::Mpeg2));
}

proptest! {
    #[test]
    fn write_then_read_gives_the_same_frames(
        w in 1usize..24, h in 1usize..24, n in 1usize..4, seed in any::<u64>()
    ) {
        let info = Y4mInfo::new(w, h, (30, 1));
        let frames: Vec<Frame> = (0..n as u64)
            .map(|f| {
                let mut fr = Frame::new(w, h).unwrap();
                for (p, plane) in fr.planes_mut().iter_mut().enumerate() {
                    for (y, row) in plane.rows_mut().enumerate() {
                        for (x, s) in row.iter_mut().enumerate() {
                            let k = seed ^ (f << 40) ^ ((p as u64) << 32) ^ ((y as u64) << 16) ^ x as u64;
                            *s = (k.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 56) as u8;
                        }
                    }
                }
                fr.extend_borders();
                fr
            })
            .collect();
        let mut bytes = Vec::new();
        let mut writer = Y4mWriter::new(&mut bytes, &info).unwrap();
        for f in &frames {
            writer.write_frame(f).unwrap();
        }
        drop(writer);
        let back = Y4mReader::new(&bytes[..]).unwrap().read_all().unwrap();
        prop_assert_eq!(back, frames);
    }

    #[test]
    fn any_bytes_after_a_valid_header_never_panic(tail in proptest::collection::vec(any::<u8>(), 0..300)) {
        let mut bytes = b"YUV4MPEG2 W5 H3 F30:1\n".to_vec();
        bytes.extend(tail);
        if let Ok(reader) = Y4mReader::new(&bytes[..]) {
            for r in reader {
                if r.is_err() {
                    break;
                }
            }
        }
    }

    #[test]
    fn any_header_line_never_panics(line in "YUV4MPEG2 [ -~]{0,80}\n") {
        let _ = Y4mReader::new(line.as_bytes()).map(|r| r.read_all());
    }

    #[test]
    fn any_header_bytes_never_panic(tail in proptest::collection::vec(any::<u8>(), 0..120)) {
        let mut bytes = b"YUV4MPEG2 ".to_vec();
        bytes.extend(tail.iter().map(|&b| if b == b'\n' { b' ' } else { b }));
        bytes.push(b'\n');
        let _ = Y4mReader::new(&bytes[..]).map(|r| r.read_all());
    }
}

/// An input that gives at most `most` bytes a call, across as many rows
/// as a vectored read asks for, and is interrupted every third call (as
/// a pipe and a signal may).
struct Trickle<'a> {
    data: &'a [u8],
    most: usize,
    calls: usize,
}

impl Trickle<'_> {
    fn interrupted(&mut self) -> bool {
        self.calls += 1;
        self.calls % 3 == 0
    }
}

impl Read for Trickle<'_> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.read_vectored(&mut [IoSliceMut::new(buf)])
    }

    fn read_vectored(&mut self, bufs: &mut [IoSliceMut<'_>]) -> io::Result<usize> {
        if self.interrupted() {
            return Err(io::ErrorKind::Interrupted.into());
        }
        let mut given = 0;
        for buf in bufs {
            let n = buf.len().min(self.most - given).min(self.data.len());
            buf[..n].copy_from_slice(&self.data[..n]);
            self.data = &self.data[n..];
            given += n;
        }
        Ok(given)
    }
}

#[test]
fn frames_larger_than_the_read_buffer_come_whole_from_short_and_interrupted_reads() {
    // 320 x 240: 115 200 bytes a frame, beyond the reader's 64 KiB
    // buffer, so most rows are read straight into the frame.
    let (w, h) = (320, 240);
    let full = stream("W320 H240 F30:1", w, h, 3);
    for most in [usize::MAX, 70_000, 4097, 333] {
        let input = Trickle {
            data: &full,
            most,
            calls: 0,
        };
        check_frames_from(input, w, h, 3);
    }
    // Cut 1000 bytes before the end: frame 2 truncated, with the bytes it
    // had (its FRAME line and all but the last 1000 of its samples).
    let frame_len = 6 + w * h * 3 / 2;
    let input = Trickle {
        data: &full[..full.len() - 1000],
        most: 4097,
        calls: 0,
    };
    let mut reader = Y4mReader::new(input).unwrap();
    assert!(reader.read_frame().unwrap().is_some());
    assert!(reader.read_frame().unwrap().is_some());
    let err = reader.read_frame().unwrap_err();
    assert!(
        matches!(err, Y4mError::Truncated { frame: 2, got, expected } if got == (frame_len - 1000) as u64 && expected == frame_len as u64),
        "{err:?}"
    );
}
