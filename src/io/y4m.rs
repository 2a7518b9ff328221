//! YUV4MPEG2 (`.y4m`) reading and writing, frame by frame in constant memory.
//!
//! The header is read and checked here (and by the [`y4m`] crate), so
//! that every 8-bit 4:2:0 variant ffmpeg writes is accepted (`C420`,
//! `C420jpeg`, `C420mpeg2`, `C420paldv`, no `C` tag, `Ip`, `I?`, any `A`
//! tag, `X` extensions), anything else is refused with a message naming
//! what was found and how to convert it, and the picture size is checked
//! against [`MAX_DIMENSION`](crate::codec::MAX_DIMENSION) before any buffer
//! is allocated. Frames are read row by row into the frame given. A frame
//! cut short by the end of the input is an error naming the frame, never
//! mistaken for the end of the stream.
//!
//! ```
//! use mocomp::codec::Frame;
//! use mocomp::io::y4m::{Y4mInfo, Y4mReader, Y4mWriter};
//!
//! let info = Y4mInfo::new(6, 4, (30, 1));
//! let mut bytes = Vec::new();
//! let mut writer = Y4mWriter::new(&mut bytes, &info).unwrap();
//! writer.write_frame(&Frame::filled(6, 4, 100, 128, 128).unwrap()).unwrap();
//! drop(writer);
//!
//! let mut reader = Y4mReader::new(&bytes[..]).unwrap();
//! assert_eq!(reader.info().fps, (30, 1));
//! let frame = reader.read_frame().unwrap().unwrap();
//! assert_eq!(frame.y().get(5, 3), 100);
//! assert!(reader.read_frame().unwrap().is_none());
//! ```

use std::fmt;
use std::io::{self, BufRead, BufReader, Cursor, Read, Write};
use std::path::Path;

use crate::codec::picture::{check_size, Frame, PictureError};
use crate::codec::syntax::{ChromaSiting as Siting, ColourRange, SequenceHeader, Vui};

/// The conversion a user can run to get a stream mocomp reads.
pub const CONVERT_HINT: &str = "ffmpeg -i in -pix_fmt yuv420p -f yuv4mpegpipe out.y4m";

/// Longest header line accepted (as the `y4m` crate and ffmpeg allow).
const MAX_HEADER_LEN: usize = 1024;

const MAGIC: &[u8] = b"YUV4MPEG2 ";

/// Chroma sample position of a 4:2:0 stream (the `C` tag). The samples are
/// the same; only their siting differs, and it is kept when writing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ChromaSiting {
    /// `C420jpeg`: centred between luma samples (JPEG / MPEG-1). ffmpeg's
    /// `yuv420p` default; also what `C420` and a missing `C` tag mean.
    #[default]
    Jpeg,
    /// `C420`: written as the plain tag, read the same as `Jpeg`.
    Plain,
    /// `C420mpeg2`: co-sited horizontally, centred vertically (MPEG-2, H.264).
    Mpeg2,
    /// `C420paldv`: PAL DV siting.
    Paldv,
}

impl ChromaSiting {
    /// The header tag, e.g. `C420jpeg`.
    pub fn tag(self) -> &'static str {
        match self {
            ChromaSiting::Jpeg => "C420jpeg",
            ChromaSiting::Plain => "C420",
            ChromaSiting::Mpeg2 => "C420mpeg2",
            ChromaSiting::Paldv => "C420paldv",
        }
    }
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// What a Y4M stream header says.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Y4mInfo {
    /// Luma width.
    pub width: usize,
    /// Luma height.
    pub height: usize,
    /// Frame rate as numerator, denominator (`F30000:1001`).
    pub fps: (u64, u64),
    /// Pixel aspect ratio (`A1:1`); `(0, 0)` means unknown, as in `A0:0`.
    pub aspect: (u64, u64),
    /// Chroma siting from the `C` tag.
    pub siting: ChromaSiting,
    /// The `X` extension tags, without the `X` (e.g. `COLORRANGE=LIMITED`),
    /// kept in order so that writing preserves them.
    pub extensions: Vec<String>,
}

impl Y4mInfo {
    /// A header for a `width x height` 4:2:0 stream at `fps`, square pixels,
    /// centred chroma.
    pub fn new(width: usize, height: usize, fps: (u64, u64)) -> Y4mInfo {
        Y4mInfo {
            width,
            height,
            fps,
            aspect: (1, 1),
            siting: ChromaSiting::Jpeg,
            extensions: Vec::new(),
        }
    }

    /// Frames per second as a float.
    pub fn fps_f64(&self) -> f64 {
        self.fps.0 as f64 / self.fps.1 as f64
    }

    /// What the header says about the samples, as a stream carries it: the
    /// pixel aspect ratio (reduced; 0:0 when unknown or beyond 16 bits),
    /// the chroma siting and `XCOLORRANGE`.
    pub fn vui(&self) -> Vui {
        let (a, b) = self.aspect;
        let g = gcd(a, b).max(1);
        let sar = match (u16::try_from(a / g), u16::try_from(b / g)) {
            (Ok(x), Ok(y)) if x > 0 && y > 0 => (x, y),
            _ => (0, 0),
        };
        let range = match self.color_range() {
            Some("LIMITED") => ColourRange::Limited,
            Some("FULL") => ColourRange::Full,
            _ => ColourRange::Unknown,
        };
        let siting = match self.siting {
            ChromaSiting::Jpeg => Siting::Centred,
            ChromaSiting::Plain => Siting::Unknown,
            ChromaSiting::Mpeg2 => Siting::Left,
            ChromaSiting::Paldv => Siting::PalDv,
        };
        Vui { sar, range, siting }
    }

    /// The header of the pictures a stream with `seq` decodes to: size,
    /// rate, and what its VUI says (`A0:0`, plain `C420` and no
    /// `XCOLORRANGE` where it says nothing). An encode's reconstruction is
    /// written with the same header.
    pub fn for_sequence(seq: &SequenceHeader) -> Y4mInfo {
        let fps = (u64::from(seq.fps_num), u64::from(seq.fps_den));
        Y4mInfo::with_vui(seq.width, seq.height, fps, seq.vui)
    }

    /// The header a stream coded from this one decodes to (the tags a
    /// stream does not carry left out).
    pub fn as_decoded(&self) -> Y4mInfo {
        Y4mInfo::with_vui(self.width, self.height, self.fps, self.vui())
    }

    fn with_vui(width: usize, height: usize, fps: (u64, u64), v: Vui) -> Y4mInfo {
        let mut info = Y4mInfo::new(width, height, fps);
        info.aspect = (u64::from(v.sar.0), u64::from(v.sar.1));
        info.siting = match v.siting {
            Siting::Unknown => ChromaSiting::Plain,
            Siting::Centred => ChromaSiting::Jpeg,
            Siting::Left => ChromaSiting::Mpeg2,
            Siting::PalDv => ChromaSiting::Paldv,
        };
        match v.range {
            ColourRange::Limited => info.extensions.push("COLORRANGE=LIMITED".into()),
            ColourRange::Full => info.extensions.push("COLORRANGE=FULL".into()),
            ColourRange::Unknown => {}
        }
        info
    }

    /// The `XCOLORRANGE=` value, if present (`FULL` or `LIMITED`).
    pub fn color_range(&self) -> Option<&str> {
        self.extensions.iter().find_map(|x| x.strip_prefix("COLORRANGE="))
    }

    /// Bytes of one frame's samples (Y, U, V; without the `FRAME` line).
    pub fn frame_bytes(&self) -> u64 {
        let (cw, ch) = Frame::chroma_size(self.width, self.height);
        (self.width * self.height + 2 * cw * ch) as u64
    }

    /// Parses a header line (without its newline), checking everything mocomp
    /// needs before a byte of frame data is read or allocated.
    pub fn parse(line: &[u8]) -> Result<Y4mInfo, Y4mError> {
        let rest = line.strip_prefix(MAGIC).ok_or(Y4mError::NotY4m)?;
        let mut width = None;
        let mut height = None;
        let mut fps = (25, 1); // what ffmpeg assumes when F is missing
        let mut aspect = (1, 1); // no A tag: square pixels (the y4m crate omits A1:1)
        let mut siting = ChromaSiting::Jpeg;
        let mut extensions = Vec::new();
        for token in rest.split(|&b| b == b' ').filter(|t| !t.is_empty()) {
            // Split off the tag byte before decoding: the value may be any
            // bytes, and a tag may be the start of a multi-byte character.
            let text = String::from_utf8_lossy(token);
            let value_text = String::from_utf8_lossy(&token[1..]);
            let value = value_text.as_ref();
            match token[0] {
                b'W' => width = Some(parse_uint(&text, value)?),
                b'H' => height = Some(parse_uint(&text, value)?),
                b'F' => {
                    fps = parse_ratio(&text, value)?;
                    if fps.0 == 0 || fps.1 == 0 {
                        return Err(Y4mError::BadHeader(format!(
                            "frame rate '{text}' must have a non-zero numerator and denominator"
                        )));
                    }
                }
                b'A' => aspect = parse_ratio(&text, value)?,
                b'I' => match value {
                    "p" | "?" => {}
                    "t" | "b" | "m" => {
                        let kind = match value {
                            "t" => "interlaced, top field first",
                            "b" => "interlaced, bottom field first",
                            _ => "mixed progressive and interlaced",
                        };
                        return Err(Y4mError::Unsupported {
                            found: text.into_owned(),
                            what: kind.to_owned(),
                        });
                    }
                    _ => return Err(Y4mError::BadHeader(format!("unknown interlacing tag '{text}'"))),
                },
                b'C' => siting = parse_colorspace(value)?,
                b'X' => extensions.push(value.to_owned()),
                _ => {} // unknown tags are ignored, as the format asks
            }
        }
        let width = width.ok_or_else(|| Y4mError::BadHeader("no width (W) tag".into()))?;
        let height = height.ok_or_else(|| Y4mError::BadHeader("no height (H) tag".into()))?;
        check_size(width, height)?;
        Ok(Y4mInfo {
            width,
            height,
            fps,
            aspect,
            siting,
            extensions,
        })
    }
}

fn parse_uint(token: &str, value: &str) -> Result<usize, Y4mError> {
    // Digits only: the size check must see the number, not an overflow.
    if value.is_empty() || value.len() > 12 || !value.bytes().all(|b| b.is_ascii_digit()) {
        return Err(Y4mError::BadHeader(format!("'{token}' is not a valid size")));
    }
    value
        .parse()
        .map_err(|_| Y4mError::BadHeader(format!("'{token}' is not a valid size")))
}

fn parse_ratio(token: &str, value: &str) -> Result<(u64, u64), Y4mError> {
    let bad = || Y4mError::BadHeader(format!("'{token}' is not a ratio like 30000:1001"));
    let (n, d) = value.split_once(':').ok_or_else(bad)?;
    let digits = |s: &str| !s.is_empty() && s.len() <= 12 && s.bytes().all(|b| b.is_ascii_digit());
    if !digits(n) || !digits(d) {
        return Err(bad());
    }
    Ok((n.parse().map_err(|_| bad())?, d.parse().map_err(|_| bad())?))
}

fn parse_colorspace(value: &str) -> Result<ChromaSiting, Y4mError> {
    let siting = match value {
        "420jpeg" => ChromaSiting::Jpeg,
        "420" => ChromaSiting::Plain,
        "420mpeg2" => ChromaSiting::Mpeg2,
        "420paldv" => ChromaSiting::Paldv,
        other => {
            let subsampling = if other.starts_with("mono") {
                "monochrome"
            } else if other.starts_with("444alpha") {
                "4:4:4 with alpha"
            } else if other.starts_with("444") {
                "4:4:4"
            } else if other.starts_with("422") {
                "4:2:2"
            } else if other.starts_with("420") {
                "4:2:0"
            } else if other.starts_with("411") {
                "4:1:1"
            } else {
                "an unknown colour space"
            };
            let depth = other
                .rsplit_once('p')
                .and_then(|(_, bits)| bits.parse::<u32>().ok())
                .or_else(|| other.strip_prefix("mono").and_then(|b| b.parse().ok()));
            let what = match depth {
                Some(bits) => format!("{subsampling} at {bits} bits per sample"),
                None => subsampling.to_owned(),
            };
            return Err(Y4mError::Unsupported {
                found: format!("C{other}"),
                what,
            });
        }
    };
    Ok(siting)
}

/// What can go wrong reading or writing Y4M.
#[derive(Debug, thiserror::Error)]
pub enum Y4mError {
    /// The underlying reader or writer failed.
    #[error(transparent)]
    Io(#[from] io::Error),
    /// Nothing to read.
    #[error("empty input: not a Y4M stream")]
    Empty,
    /// The input does not start with `YUV4MPEG2 `.
    #[error("not a Y4M stream (it does not start with 'YUV4MPEG2 ')")]
    NotY4m,
    /// No newline within the first 1024 bytes.
    #[error("Y4M header longer than {MAX_HEADER_LEN} bytes or without a newline")]
    HeaderTooLong,
    /// A malformed header tag.
    #[error("bad Y4M header: {0}")]
    BadHeader(String),
    /// A well-formed stream mocomp does not handle.
    #[error("unsupported Y4M stream: {found} ({what}); mocomp reads 8-bit 4:2:0 progressive video, convert with: {CONVERT_HINT}")]
    Unsupported {
        /// The tag found, e.g. `C422`.
        found: String,
        /// What it means, e.g. `4:2:2`.
        what: String,
    },
    /// The header's picture size is out of range.
    #[error("bad Y4M header: {0}")]
    Size(PictureError),
    /// The input ends inside a frame.
    #[error("frame {frame} is truncated: the input ends after {got} of its {expected} bytes")]
    Truncated {
        /// Index of the frame, from 0.
        frame: usize,
        /// Bytes of it present, `FRAME` line included.
        got: u64,
        /// Bytes a whole frame takes, with a bare `FRAME` line.
        expected: u64,
    },
    /// Something other than a `FRAME` line where a frame should start.
    #[error("frame {frame}: expected a 'FRAME' line, found something else")]
    BadFrameHeader {
        /// Index of the frame, from 0.
        frame: usize,
    },
    /// A frame given to the writer does not match the stream size.
    #[error("frame is {got_w}x{got_h}, the stream is {width}x{height}")]
    FrameSize {
        /// Stream width.
        width: usize,
        /// Stream height.
        height: usize,
        /// Frame width.
        got_w: usize,
        /// Frame height.
        got_h: usize,
    },
}

/// Counts the bytes handed out, so that the end of the input inside a frame
/// can be told from the end between frames.
struct Counting<R> {
    inner: R,
    count: u64,
}

impl<R: Read> Read for Counting<R> {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.count += n as u64;
        Ok(n)
    }

    // Passed on: the default reads into the first buffer alone, a row a
    // call; passed on, a frame's rows are asked of the file by `readv`.
    fn read_vectored(&mut self, bufs: &mut [io::IoSliceMut<'_>]) -> io::Result<usize> {
        let n = self.inner.read_vectored(bufs)?;
        self.count += n as u64;
        Ok(n)
    }
}

impl<R: BufRead> BufRead for Counting<R> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        self.inner.fill_buf()
    }

    fn consume(&mut self, n: usize) {
        self.count += n as u64;
        self.inner.consume(n);
    }
}

/// The input's buffer: `FRAME` lines, and frames smaller than it, are
/// read through it (a frame's worth read whole into a buffer of its own
/// went through memory twice); larger frames' rows past it are read
/// straight from the input (`read_rows`).
const READ_BUFFER: usize = 64 << 10;

/// A `FRAME` line's longest (its parameters are not used).
const MAX_FRAME_LINE: usize = 1024;

/// Reads a Y4M stream frame by frame; one frame's worth of memory whatever
/// the stream's length.
pub struct Y4mReader<R: Read> {
    reader: Counting<BufReader<R>>,
    info: Y4mInfo,
    /// The `FRAME` line being read.
    line: Vec<u8>,
    frames_read: usize,
}

impl Y4mReader<Box<dyn Read + Send>> {
    /// Opens a Y4M file, or standard input for `-`.
    pub fn open(path: &Path) -> Result<Self, Y4mError> {
        Y4mReader::new(super::open_input(path)?)
    }
}

impl<R: Read> Y4mReader<R> {
    /// Reads and checks the stream header.
    pub fn new(reader: R) -> Result<Self, Y4mError> {
        let mut reader = BufReader::with_capacity(READ_BUFFER, reader);
        let mut line = Vec::with_capacity(128);
        (&mut reader)
            .take(MAX_HEADER_LEN as u64)
            .read_until(b'\n', &mut line)?;
        if line.is_empty() {
            return Err(Y4mError::Empty);
        }
        if line.last() != Some(&b'\n') {
            return Err(if line.starts_with(MAGIC) || MAGIC.starts_with(&line) {
                Y4mError::HeaderTooLong
            } else {
                Y4mError::NotY4m
            });
        }
        let info = Y4mInfo::parse(&line[..line.len() - 1])?;
        // The y4m crate checks the header too (from memory): what it
        // refuses is refused here.
        let limits = y4m::Limits {
            bytes: info.frame_bytes() as usize,
        };
        y4m::Decoder::new_with_limits(Cursor::new(line), limits).map_err(|e| match e {
            y4m::Error::IoError(e) => Y4mError::Io(e),
            other => Y4mError::BadHeader(other.to_string()),
        })?;
        Ok(Y4mReader {
            reader: Counting {
                inner: reader,
                count: 0,
            },
            info,
            line: Vec::with_capacity(64),
            frames_read: 0,
        })
    }

    /// The stream header.
    pub fn info(&self) -> &Y4mInfo {
        &self.info
    }

    /// How many frames have been read so far.
    pub fn frames_read(&self) -> usize {
        self.frames_read
    }

    /// The next frame, or `None` at the end of the stream.
    pub fn read_frame(&mut self) -> Result<Option<Frame>, Y4mError> {
        let mut frame = Frame::new(self.info.width, self.info.height)?;
        Ok(self.read_frame_into(&mut frame)?.then_some(frame))
    }

    /// Reads the next frame into `frame` (of the stream's size), reusing its
    /// buffers; returns `false` at the end of the stream.
    pub fn read_frame_into(&mut self, frame: &mut Frame) -> Result<bool, Y4mError> {
        let read = self.read_pictures_into(frame)?;
        if read {
            for plane in frame.planes_mut() {
                plane.extend_border();
            }
        }
        Ok(read)
    }

    /// [`Y4mReader::read_frame_into`] of the pictures alone: the planes'
    /// borders are left as they were, for a caller that makes its own (the
    /// encoder pads its sources to the coded size).
    pub fn read_pictures_into(&mut self, frame: &mut Frame) -> Result<bool, Y4mError> {
        check_frame_size(&self.info, frame)?;
        let start = self.reader.count;
        let index = self.frames_read;
        let truncated = |reader: &Counting<BufReader<R>>, info: &Y4mInfo| Y4mError::Truncated {
            frame: index,
            got: reader.count - start,
            expected: info.frame_bytes() + 6,
        };
        self.line.clear();
        (&mut self.reader)
            .take(MAX_FRAME_LINE as u64)
            .read_until(b'\n', &mut self.line)?;
        match frame_line(&self.line) {
            FrameLine::End => return Ok(false),
            FrameLine::Cut => return Err(truncated(&self.reader, &self.info)),
            FrameLine::Bad => return Err(Y4mError::BadFrameHeader { frame: index }),
            FrameLine::Frame => {}
        }
        let rows = frame.planes_mut().iter_mut().flat_map(|p| p.rows_mut());
        match read_rows(&mut self.reader, rows.collect()) {
            Ok(()) => {}
            Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => {
                return Err(truncated(&self.reader, &self.info))
            }
            Err(e) => return Err(Y4mError::Io(e)),
        }
        self.frames_read += 1;
        Ok(true)
    }

    /// Reads the whole stream into memory (for small inputs and tests).
    pub fn read_all(mut self) -> Result<Vec<Frame>, Y4mError> {
        let mut frames = Vec::new();
        while let Some(f) = self.read_frame()? {
            frames.push(f);
        }
        Ok(frames)
    }
}

/// Fills `rows` from the input: what the buffer holds first, the rest
/// read straight into the rows (`readv`), past the buffer whenever the
/// rest is at least the buffer's size. Through the buffer, a frame was
/// copied twice, by the kernel into the buffer and from it into the rows:
/// the second copy was 2 % of the samples of an ultrafast encode of
/// dog_1080p.
fn read_rows<R: Read>(reader: &mut Counting<BufReader<R>>, mut rows: Vec<&mut [u8]>) -> io::Result<()> {
    let mut first = 0;
    while let Some(row) = rows.get_mut(first) {
        let buffered = reader.inner.buffer();
        if buffered.is_empty() {
            break;
        }
        let n = buffered.len().min(row.len());
        row[..n].copy_from_slice(&buffered[..n]);
        reader.consume(n);
        let rest = &mut std::mem::take(row)[n..];
        if rest.is_empty() {
            first += 1;
        } else {
            *row = rest;
        }
    }
    let mut slices: Vec<io::IoSliceMut> = rows[first..].iter_mut().map(|r| io::IoSliceMut::new(r)).collect();
    let mut left = &mut slices[..];
    while !left.is_empty() {
        match reader.read_vectored(left) {
            Ok(0) => return Err(io::ErrorKind::UnexpectedEof.into()),
            Ok(n) => io::IoSliceMut::advance_slices(&mut left, n),
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

/// What a `FRAME` line read up to its newline (or the end of the input)
/// is.
#[derive(Debug, PartialEq, Eq)]
enum FrameLine {
    /// Nothing: the stream ended between frames.
    End,
    /// `FRAME`, with parameters or none.
    Frame,
    /// The input ended inside a line that was becoming a `FRAME` line.
    Cut,
    /// Anything else.
    Bad,
}

fn frame_line(line: &[u8]) -> FrameLine {
    const FRAME: &[u8] = b"FRAME";
    let Some(text) = line.strip_suffix(b"\n") else {
        let begun = FRAME.starts_with(line) || line.starts_with(FRAME);
        return match line.len() {
            0 => FrameLine::End,
            n if begun && n < MAX_FRAME_LINE => FrameLine::Cut,
            _ => FrameLine::Bad,
        };
    };
    match text.strip_prefix(FRAME) {
        Some([] | [b' ', ..]) => FrameLine::Frame,
        _ => FrameLine::Bad,
    }
}

impl<R: Read> Iterator for Y4mReader<R> {
    type Item = Result<Frame, Y4mError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.read_frame().transpose()
    }
}

impl<R: Read> fmt::Debug for Y4mReader<R> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Y4mReader")
            .field("info", &self.info)
            .field("frames_read", &self.frames_read)
            .finish()
    }
}

/// Writes a Y4M stream frame by frame, keeping the header's frame rate,
/// aspect, chroma siting and `X` tags. Each frame is written straight through
/// to `W`; whoever owns `W` flushes it (or commits an [`OutputFile`]) after
/// the writer is dropped.
///
/// [`OutputFile`]: crate::io::OutputFile
pub struct Y4mWriter<W: Write> {
    writer: W,
    info: Y4mInfo,
}

impl<W: Write> Y4mWriter<W> {
    /// Writes the stream header. Every tag is written, `A1:1` included
    /// (the y4m crate leaves it out, and ffmpeg reads a missing `A` as an
    /// unknown aspect ratio), so a header read and written is the same.
    pub fn new(mut writer: W, info: &Y4mInfo) -> Result<Self, Y4mError> {
        check_size(info.width, info.height)?;
        if let Some(x) = info.extensions.iter().find(|x| x.contains(char::is_whitespace)) {
            return Err(Y4mError::BadHeader(format!(
                "extension tag 'X{x}' contains a space"
            )));
        }
        let mut line = format!(
            "YUV4MPEG2 W{} H{} F{}:{} Ip A{}:{} {}",
            info.width,
            info.height,
            info.fps.0,
            info.fps.1,
            info.aspect.0,
            info.aspect.1,
            info.siting.tag()
        );
        for x in &info.extensions {
            line.push_str(" X");
            line.push_str(x);
        }
        line.push('\n');
        writer.write_all(line.as_bytes())?;
        Ok(Y4mWriter {
            writer,
            info: info.clone(),
        })
    }

    /// The stream header being written.
    pub fn info(&self) -> &Y4mInfo {
        &self.info
    }

    /// Appends one frame.
    pub fn write_frame(&mut self, frame: &Frame) -> Result<(), Y4mError> {
        check_frame_size(&self.info, frame)?;
        self.writer.write_all(b"FRAME\n")?;
        for plane in frame.planes() {
            for row in plane.rows() {
                self.writer.write_all(row)?;
            }
        }
        Ok(())
    }

    /// The writer the frames went to.
    pub fn into_inner(self) -> W {
        self.writer
    }
}

fn check_frame_size(info: &Y4mInfo, frame: &Frame) -> Result<(), Y4mError> {
    if frame.width() != info.width || frame.height() != info.height {
        return Err(Y4mError::FrameSize {
            width: info.width,
            height: info.height,
            got_w: frame.width(),
            got_h: frame.height(),
        });
    }
    Ok(())
}

/// A size error in a header, said once (the variant's message holds it; it
/// is not also its source, or error chains would repeat it).
impl From<PictureError> for Y4mError {
    fn from(e: PictureError) -> Y4mError {
        Y4mError::Size(e)
    }
}

#[cfg(test)]
mod tests {
    use super::{
        frame_line, FrameLine, Y4mError, Y4mInfo, Y4mReader, Y4mWriter, MAX_FRAME_LINE, READ_BUFFER,
    };
    use crate::codec::{Frame, Plane};
    use std::io::{self, Read};

    /// An input handing out at most 5 bytes a call (a pipe at its
    /// slowest), one buffer at a time.
    struct Trickle<'a>(&'a [u8]);

    impl Read for Trickle<'_> {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            let n = buf.len().min(self.0.len()).min(5);
            buf[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            Ok(n)
        }
    }

    #[test]
    fn frames_larger_than_the_buffer_are_read_whole_from_a_file_and_a_trickle() {
        // Each frame over 1.5 buffers, so that its rows are read partly from
        // the buffer and partly past it, a row cut at the buffer's end.
        let (w, h) = (254, 260);
        let info = Y4mInfo::new(w, h, (25, 1));
        assert!(info.frame_bytes() as usize > READ_BUFFER * 3 / 2);
        let frames: Vec<Frame> = (0..3)
            .map(|k| {
                let plane = |pw, ph, salt: usize| {
                    Plane::from_fn(pw, ph, |x, y| ((x * 7 + y * 13 + k * 29 + salt) % 251) as u8).unwrap()
                };
                Frame::from_planes(plane(w, h, 0), plane(w / 2, h / 2, 1), plane(w / 2, h / 2, 2)).unwrap()
            })
            .collect();
        let mut bytes = Vec::new();
        let mut writer = Y4mWriter::new(&mut bytes, &info).unwrap();
        frames.iter().for_each(|f| writer.write_frame(f).unwrap());
        drop(writer);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.y4m");
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(Y4mReader::open(&path).unwrap().read_all().unwrap(), frames);
        assert_eq!(
            Y4mReader::new(Trickle(&bytes)).unwrap().read_all().unwrap(),
            frames
        );
        // Cut inside the last frame's rows past the buffer: an error that
        // counts the bytes there were.
        let frame_bytes = info.frame_bytes() as usize + 6;
        let cut = bytes.len() - 1000;
        std::fs::write(&path, &bytes[..cut]).unwrap();
        let mut reader = Y4mReader::open(&path).unwrap();
        let mut frame = Frame::new(w, h).unwrap();
        assert!(reader.read_frame_into(&mut frame).unwrap());
        assert!(reader.read_frame_into(&mut frame).unwrap());
        match reader.read_frame_into(&mut frame) {
            Err(Y4mError::Truncated {
                frame: 2,
                got,
                expected,
            }) => {
                assert_eq!((got, expected), ((frame_bytes - 1000) as u64, frame_bytes as u64))
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn pictures_read_alone_leave_the_borders_as_they_were() {
        let picture = Frame::from_planes(
            crate::codec::Plane::from_fn(6, 4, |x, y| (10 * x + y) as u8).unwrap(),
            crate::codec::Plane::from_fn(3, 2, |x, y| (100 + x + 5 * y) as u8).unwrap(),
            crate::codec::Plane::from_fn(3, 2, |x, y| (200 + x + 5 * y) as u8).unwrap(),
        )
        .unwrap();
        let info = Y4mInfo::new(6, 4, (25, 1));
        let mut bytes = Vec::new();
        Y4mWriter::new(&mut bytes, &info)
            .unwrap()
            .write_frame(&picture)
            .unwrap();
        let read = |pictures_only: bool| {
            let mut reader = Y4mReader::new(&bytes[..]).unwrap();
            let mut frame = Frame::filled(6, 4, 7, 7, 7).unwrap();
            let got = match pictures_only {
                true => reader.read_pictures_into(&mut frame).unwrap(),
                false => reader.read_frame_into(&mut frame).unwrap(),
            };
            assert!(got && frame == picture, "the pictures read");
            frame
        };
        // Beyond the left edge: the filled frame's border, or the edge's
        // sample once extended.
        assert_eq!(read(true).y().at(-1, 2), 7);
        assert_eq!(read(false).y().at(-1, 2), picture.y().get(0, 2));
    }

    #[test]
    fn frame_lines_are_told_from_ends_cuts_and_garbage() {
        let cases: [(&[u8], FrameLine); 10] = [
            (b"", FrameLine::End),
            (b"FRAME\n", FrameLine::Frame),
            (b"FRAME Ip XA=1\n", FrameLine::Frame),
            (b"FRA", FrameLine::Cut),
            (b"FRAME", FrameLine::Cut),
            (b"FRAME Ip", FrameLine::Cut),
            (b"FRAMES\n", FrameLine::Bad),
            (b"JUNK\n", FrameLine::Bad),
            (b"JUN", FrameLine::Bad),
            (b"\n", FrameLine::Bad),
        ];
        for (line, want) in cases {
            assert_eq!(frame_line(line), want, "{:?}", String::from_utf8_lossy(line));
        }
        // A line as long as the reader takes, with no newline: not a frame.
        let long = [b"FRAME ".as_slice(), &[b'x'; MAX_FRAME_LINE - 6]].concat();
        assert_eq!(frame_line(&long), FrameLine::Bad);
    }
}
