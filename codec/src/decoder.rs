//! The decoder: a stream in, frames out, one at a time.
//!
//! Every malformed input is an [`DecodeError`] saying what is wrong and
//! where (byte, and bit within it); nothing in any byte string makes it
//! panic, and it never buffers more than one frame's declared length, which
//! is itself bounded by the picture size.
//!
//! ```
//! use mocomp_codec::decoder::{decode, DecodeError};
//! assert!(matches!(decode(b"not a stream"), Err(DecodeError::Header(_))));
//! ```

use std::io::{self, Read};

use crate::picture::{Frame, PictureError};
use crate::recon::{crop, reconstruct_frame};
use crate::syntax::{
    read_frame, EntropyState, FrameSyntax, FrameType, HeaderError, SequenceHeader, FRAME_START,
    SEQUENCE_HEADER_LEN, STREAM_END,
};

/// What can be wrong with a stream.
#[derive(Debug, thiserror::Error)]
pub enum DecodeError {
    /// Reading failed.
    #[error(transparent)]
    Io(#[from] io::Error),
    /// The sequence header is wrong.
    #[error(transparent)]
    Header(#[from] HeaderError),
    /// The stream ends early.
    #[error("the stream ends at byte {byte}, inside {what}")]
    Truncated {
        /// What was being read.
        what: &'static str,
        /// Where the stream ends.
        byte: u64,
    },
    /// Neither a frame nor the end marker.
    #[error("byte {byte}: expected a frame (0xa5) or the end marker (0x5a), found 0x{found:02x}")]
    StartCode {
        /// Where.
        byte: u64,
        /// The byte found.
        found: u8,
    },
    /// A frame longer than any frame of this size can be.
    #[error("frame {frame} at byte {byte} declares {length} bytes, more than the {max} a frame of this size can need")]
    FrameLength {
        /// Frame index.
        frame: usize,
        /// Where its start code is.
        byte: u64,
        /// Its declared length.
        length: u64,
        /// The bound.
        max: u64,
    },
    /// Invalid syntax inside a frame.
    #[error("frame {frame}: {what} (byte {byte}, bit {bit})")]
    Syntax {
        /// Frame index.
        frame: usize,
        /// Absolute byte position.
        byte: u64,
        /// Bit within that byte, 0 = most significant.
        bit: u8,
        /// What is wrong.
        what: String,
    },
    /// The frame count in the header and the frames present differ.
    #[error("the sequence header announces {expected} frames, the stream holds {found}")]
    FrameCount {
        /// Announced.
        expected: u32,
        /// Present.
        found: usize,
    },
    /// Bytes after the end marker.
    #[error("data after the end marker at byte {byte}")]
    TrailingData {
        /// Where the extra data starts.
        byte: u64,
    },
    /// A picture could not be made (cannot happen for a valid header).
    #[error(transparent)]
    Picture(#[from] PictureError),
}

/// Decodes a stream frame by frame.
pub struct Decoder<R: Read> {
    reader: R,
    seq: SequenceHeader,
    /// The decoded frames a P frame can predict from, the latest first:
    /// those since the last I frame, at most the sequence's `max_refs`.
    references: Vec<Frame>,
    /// Contexts carried from frame to frame.
    entropy: EntropyState,
    frames: usize,
    offset: u64,
    finished: bool,
}

fn read_up_to(reader: &mut impl Read, buf: &mut [u8]) -> io::Result<usize> {
    let mut got = 0;
    while got < buf.len() {
        match reader.read(&mut buf[got..]) {
            Ok(0) => break,
            Ok(n) => got += n,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(got)
}

impl<R: Read> Decoder<R> {
    /// Reads and checks the sequence header.
    pub fn new(mut reader: R) -> Result<Decoder<R>, DecodeError> {
        let mut head = [0u8; SEQUENCE_HEADER_LEN];
        let got = read_up_to(&mut reader, &mut head)?;
        let seq = SequenceHeader::parse(&head[..got])?;
        Ok(Decoder {
            reader,
            seq,
            references: Vec::new(),
            entropy: EntropyState::new(),
            frames: 0,
            offset: SEQUENCE_HEADER_LEN as u64,
            finished: false,
        })
    }

    /// The sequence header.
    pub fn sequence(&self) -> &SequenceHeader {
        &self.seq
    }

    /// Frames decoded so far.
    pub fn frames_decoded(&self) -> usize {
        self.frames
    }

    /// The next frame's syntax, or `None` at the end marker.
    pub fn next_syntax(&mut self) -> Result<Option<FrameSyntax>, DecodeError> {
        if self.finished || !self.frame_starts()? {
            return Ok(None);
        }
        let (payload, payload_start) = self.frame_payload()?;
        let syntax = read_frame(&self.seq, &payload, &mut self.entropy).map_err(|e| DecodeError::Syntax {
            frame: self.frames,
            byte: payload_start + (e.bit / 8) as u64,
            bit: (e.bit % 8) as u8,
            what: e.what,
        })?;
        self.check_references(&syntax, payload_start)?;
        Ok(Some(syntax))
    }

    /// Reads the next start code: `true` for a frame, `false` at the end
    /// marker (after checking the frame count and that nothing follows).
    fn frame_starts(&mut self) -> Result<bool, DecodeError> {
        let start = self.offset;
        let mut code = [0u8; 1];
        if read_up_to(&mut self.reader, &mut code)? == 0 {
            return Err(DecodeError::Truncated {
                what: "the frame start code or the end marker",
                byte: start,
            });
        }
        self.offset += 1;
        let expected = self.seq.frame_count;
        match code[0] {
            STREAM_END => {
                self.finished = true;
                if expected != 0 && expected as usize != self.frames {
                    return Err(DecodeError::FrameCount {
                        expected,
                        found: self.frames,
                    });
                }
                if read_up_to(&mut self.reader, &mut code)? != 0 {
                    return Err(DecodeError::TrailingData { byte: self.offset });
                }
                Ok(false)
            }
            FRAME_START if expected != 0 && self.frames >= expected as usize => {
                Err(DecodeError::FrameCount {
                    expected,
                    found: self.frames + 1,
                })
            }
            FRAME_START => Ok(true),
            found => Err(DecodeError::StartCode { byte: start, found }),
        }
    }

    /// The frame's length and payload (the length checked against the
    /// sequence's largest frame before any byte is read), with the
    /// payload's offset in the stream.
    fn frame_payload(&mut self) -> Result<(Vec<u8>, u64), DecodeError> {
        let start = self.offset - 1;
        let mut len = [0u8; 4];
        if read_up_to(&mut self.reader, &mut len)? < 4 {
            return Err(DecodeError::Truncated {
                what: "a frame length",
                byte: self.offset,
            });
        }
        self.offset += 4;
        let length = u64::from(u32::from_be_bytes(len));
        let max = self.seq.max_frame_bytes();
        if length > max {
            return Err(DecodeError::FrameLength {
                frame: self.frames,
                byte: start,
                length,
                max,
            });
        }
        // Grows with the data actually present, up to the checked length.
        let mut payload = Vec::new();
        (&mut self.reader).take(length).read_to_end(&mut payload)?;
        let payload_start = self.offset;
        self.offset += payload.len() as u64;
        if (payload.len() as u64) < length {
            return Err(DecodeError::Truncated {
                what: "a frame",
                byte: self.offset,
            });
        }
        Ok((payload, payload_start))
    }

    /// A P frame's references: no more than the sequence allows, nor than
    /// the frames decoded since the last I frame.
    fn check_references(&self, syntax: &FrameSyntax, payload_start: u64) -> Result<(), DecodeError> {
        let h = &syntax.header;
        let available = self.references.len();
        let what = if h.refs > self.seq.max_refs {
            format!(
                "a P frame predicting from {} references, more than the sequence's {}",
                h.refs, self.seq.max_refs
            )
        } else if h.frame_type == FrameType::Inter && usize::from(h.refs) > available {
            if available == 0 {
                "a P frame with no frame before it to predict from".into()
            } else {
                format!(
                    "a P frame predicting from {} references, with {available} decoded since the last I frame",
                    h.refs
                )
            }
        } else {
            return Ok(());
        };
        Err(DecodeError::Syntax {
            frame: self.frames,
            byte: payload_start,
            bit: 0,
            what,
        })
    }

    /// Reconstructs `syntax` and keeps it as the latest reference.
    fn reconstruct(&mut self, syntax: &FrameSyntax) -> Result<&Frame, DecodeError> {
        let recon = reconstruct_frame(&self.seq, syntax, &self.references)?;
        self.frames += 1;
        if syntax.header.frame_type == FrameType::Intra {
            self.references.clear();
        }
        self.references.truncate(usize::from(self.seq.max_refs) - 1);
        self.references.insert(0, recon);
        Ok(&self.references[0])
    }

    /// The next frame at the coded (macroblock-aligned) size, as the
    /// reference for the next one; `None` at the end marker.
    pub fn next_coded_frame(&mut self) -> Result<Option<&Frame>, DecodeError> {
        let Some(syntax) = self.next_syntax()? else {
            return Ok(None);
        };
        self.reconstruct(&syntax).map(Some)
    }

    /// The next frame's syntax and its picture, cropped to the picture
    /// size (what stream analysis reads); `None` at the end.
    pub fn next_frame_with_syntax(&mut self) -> Result<Option<(FrameSyntax, Frame)>, DecodeError> {
        let Some(syntax) = self.next_syntax()? else {
            return Ok(None);
        };
        let (w, h) = (self.seq.width, self.seq.height);
        let frame = crop(self.reconstruct(&syntax)?, w, h)?;
        Ok(Some((syntax, frame)))
    }

    /// The next frame, cropped to the picture size; `None` at the end.
    pub fn next_frame(&mut self) -> Result<Option<Frame>, DecodeError> {
        let (w, h) = (self.seq.width, self.seq.height);
        match self.next_coded_frame()? {
            Some(coded) => Ok(Some(crop(coded, w, h)?)),
            None => Ok(None),
        }
    }
}

/// Decodes a whole stream held in memory.
pub fn decode(bytes: &[u8]) -> Result<(SequenceHeader, Vec<Frame>), DecodeError> {
    let mut decoder = Decoder::new(bytes)?;
    let mut frames = Vec::new();
    while let Some(f) = decoder.next_frame()? {
        frames.push(f);
    }
    Ok((*decoder.sequence(), frames))
}
