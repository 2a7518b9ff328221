//! The sequence layer (FORMAT.md section 2): the sequence header, what
//! the samples mean (VUI), and the limits a decoder sets from it.

use crate::bits::{BitReader, BitWriter};
use crate::consts::{MAGIC, MB, SEQUENCE_HEADER_LEN, VERSION};
use crate::modes::MAX_REFS;
use crate::picture::{check_size, MAX_DIMENSION};

/// What the sequence header says.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SequenceHeader {
    /// Picture width in luma samples, 1..=16384.
    pub width: usize,
    /// Picture height in luma samples, 1..=16384.
    pub height: usize,
    /// Frame rate numerator (non-zero).
    pub fps_num: u32,
    /// Frame rate denominator (non-zero).
    pub fps_den: u32,
    /// Number of frames, or 0 when not known in advance.
    pub frame_count: u32,
    /// What the samples mean, for whoever shows the pictures; decoding
    /// does not use it.
    pub vui: Vui,
    /// The most references a P frame of the stream predicts from,
    /// 1..=[`MAX_REFS`]: how many decoded frames a decoder keeps.
    pub max_refs: u8,
}

/// Video usability information (as a codec's VUI): carried from the
/// source to the decoder's output, not used in decoding.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Vui {
    /// Sample (pixel) aspect ratio, width:height; 0:0 when unknown.
    pub sar: (u16, u16),
    /// The samples' range.
    pub range: ColourRange,
    /// Where chroma samples sit against luma.
    pub siting: ChromaSiting,
}

/// The range of the samples' values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ColourRange {
    /// Not said.
    #[default]
    Unknown = 0,
    /// Limited ("TV"): luma 16-235, chroma 16-240.
    Limited = 1,
    /// Full ("PC"): 0-255.
    Full = 2,
}

/// Where 4:2:0 chroma samples sit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ChromaSiting {
    /// Not said.
    #[default]
    Unknown = 0,
    /// Centred between the four luma samples (JPEG, MPEG-1).
    Centred = 1,
    /// Co-sited with the left luma samples, centred vertically (MPEG-2,
    /// H.264).
    Left = 2,
    /// PAL DV's siting.
    PalDv = 3,
}

/// Why a sequence header is refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum HeaderError {
    /// Fewer bytes than a header.
    #[error("stream of {0} bytes is shorter than the {SEQUENCE_HEADER_LEN}-byte sequence header")]
    Short(usize),
    /// Not `MOCO`.
    #[error("not a mocomp stream: it starts with {0:02x?}, not \"MOCO\"")]
    Magic([u8; 4]),
    /// Another version.
    #[error("stream version {0} is not supported (this decoder reads version {VERSION})")]
    Version(u8),
    /// A field out of range.
    #[error("sequence header: {what} = {value} is out of range")]
    Field {
        /// The field.
        what: &'static str,
        /// Its value.
        value: u64,
    },
}

impl SequenceHeader {
    /// Macroblock columns.
    pub fn mb_cols(&self) -> usize {
        self.width.div_ceil(MB)
    }

    /// Macroblock rows.
    pub fn mb_rows(&self) -> usize {
        self.height.div_ceil(MB)
    }

    /// Width of the coded (macroblock-aligned) picture.
    pub fn coded_width(&self) -> usize {
        self.mb_cols() * MB
    }

    /// Height of the coded (macroblock-aligned) picture.
    pub fn coded_height(&self) -> usize {
        self.mb_rows() * MB
    }

    /// The largest `frame_length` a frame of this size may declare: six
    /// times the raw coded picture (no valid frame comes near) plus 1 KiB.
    /// A decoder never buffers more than this per frame.
    pub fn max_frame_bytes(&self) -> u64 {
        let samples = (self.coded_width() * self.coded_height() * 3 / 2) as u64;
        6 * samples + 1024
    }

    /// Writes the header's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut w = BitWriter::new();
        w.put_bytes(&MAGIC);
        w.put(u64::from(VERSION), 8);
        w.put(self.width as u64 - 1, 16);
        w.put(self.height as u64 - 1, 16);
        w.put(1, 8); // chroma format: 4:2:0
        w.put(8, 8); // bit depth
        w.put(u64::from(self.fps_num), 32);
        w.put(u64::from(self.fps_den), 32);
        w.put(u64::from(self.frame_count), 32);
        w.put(u64::from(self.vui.sar.0), 16);
        w.put(u64::from(self.vui.sar.1), 16);
        w.put(self.vui.range as u64, 8);
        w.put(self.vui.siting as u64, 8);
        w.put(u64::from(self.max_refs), 8);
        w.into_bytes()
    }

    /// Parses and checks the first bytes of a stream.
    pub fn parse(bytes: &[u8]) -> Result<SequenceHeader, HeaderError> {
        if bytes.len() < SEQUENCE_HEADER_LEN {
            if bytes.len() >= 4 && bytes[..4] != MAGIC {
                return Err(HeaderError::Magic([bytes[0], bytes[1], bytes[2], bytes[3]]));
            }
            return Err(HeaderError::Short(bytes.len()));
        }
        let mut r = BitReader::new(&bytes[..SEQUENCE_HEADER_LEN]);
        let field = |r: &mut BitReader<'_>, n| r.get(n).map_err(|_| HeaderError::Short(bytes.len()));
        let magic = [bytes[0], bytes[1], bytes[2], bytes[3]];
        if magic != MAGIC {
            return Err(HeaderError::Magic(magic));
        }
        field(&mut r, 32)?;
        let version = field(&mut r, 8)? as u8;
        if version != VERSION {
            return Err(HeaderError::Version(version));
        }
        let width = field(&mut r, 16)? as usize + 1;
        let height = field(&mut r, 16)? as usize + 1;
        let check = |what: &'static str, value: u64, ok: bool| {
            if ok {
                Ok(())
            } else {
                Err(HeaderError::Field { what, value })
            }
        };
        check("width", width as u64, width <= MAX_DIMENSION)?;
        check("height", height as u64, height <= MAX_DIMENSION)?;
        let chroma = field(&mut r, 8)?;
        check("chroma_format", chroma, chroma == 1)?;
        let depth = field(&mut r, 8)?;
        check("bit_depth", depth, depth == 8)?;
        let fps_num = field(&mut r, 32)? as u32;
        check("fps_num", u64::from(fps_num), fps_num != 0)?;
        let fps_den = field(&mut r, 32)? as u32;
        check("fps_den", u64::from(fps_den), fps_den != 0)?;
        let frame_count = field(&mut r, 32)? as u32;
        let sar = (field(&mut r, 16)? as u16, field(&mut r, 16)? as u16);
        check("sar", u64::from(sar.0), (sar.0 == 0) == (sar.1 == 0))?;
        let range = match field(&mut r, 8)? {
            0 => ColourRange::Unknown,
            1 => ColourRange::Limited,
            2 => ColourRange::Full,
            v => {
                return Err(HeaderError::Field {
                    what: "colour_range",
                    value: v,
                })
            }
        };
        let siting = match field(&mut r, 8)? {
            0 => ChromaSiting::Unknown,
            1 => ChromaSiting::Centred,
            2 => ChromaSiting::Left,
            3 => ChromaSiting::PalDv,
            v => {
                return Err(HeaderError::Field {
                    what: "chroma_siting",
                    value: v,
                })
            }
        };
        let max_refs = field(&mut r, 8)? as u8;
        check(
            "max_refs",
            u64::from(max_refs),
            (1..=MAX_REFS).contains(&max_refs),
        )?;
        debug_assert!(check_size(width, height).is_ok());
        Ok(SequenceHeader {
            width,
            height,
            fps_num,
            fps_den,
            frame_count,
            vui: Vui { sar, range, siting },
            max_refs,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> SequenceHeader {
        SequenceHeader {
            width: 1921,
            height: 17,
            fps_num: 30000,
            fps_den: 1001,
            frame_count: 300,
            vui: Vui {
                sar: (64, 45),
                range: ColourRange::Limited,
                siting: ChromaSiting::Left,
            },
            max_refs: 3,
        }
    }

    #[test]
    fn the_header_is_its_fixed_size_and_reads_back() {
        let h = header();
        let bytes = h.to_bytes();
        assert_eq!(bytes.len(), SEQUENCE_HEADER_LEN);
        assert_eq!(&bytes[..4], &MAGIC);
        assert_eq!(SequenceHeader::parse(&bytes), Ok(h));
        // Coded sizes round up to whole macroblocks.
        assert_eq!((h.mb_cols(), h.mb_rows()), (121, 2));
        assert_eq!((h.coded_width(), h.coded_height()), (1936, 32));
        assert!(h.max_frame_bytes() > (1936 * 32 * 3 / 2) as u64);
    }

    #[test]
    fn every_bad_field_is_named() {
        let good = header().to_bytes();
        assert_eq!(SequenceHeader::parse(&good[..10]), Err(HeaderError::Short(10)));
        assert_eq!(SequenceHeader::parse(b"MOC"), Err(HeaderError::Short(3)));
        // Another format's file says so from its first four bytes.
        assert!(matches!(
            SequenceHeader::parse(b"RIFF"),
            Err(HeaderError::Magic(_))
        ));
        let with = |at: usize, v: u8| {
            let mut b = good.clone();
            b[at] = v;
            SequenceHeader::parse(&b)
        };
        assert_eq!(with(4, VERSION + 1), Err(HeaderError::Version(VERSION + 1)));
        // Width 65536 (above 16384), chroma format 0, 10 bits.
        assert!(matches!(
            with(5, 0xff),
            Err(HeaderError::Field { what: "width", .. })
        ));
        assert!(matches!(
            with(9, 0),
            Err(HeaderError::Field {
                what: "chroma_format",
                ..
            })
        ));
        assert!(matches!(
            with(10, 10),
            Err(HeaderError::Field {
                what: "bit_depth",
                ..
            })
        ));
        let mut zero_rate = header();
        zero_rate.fps_num = 0;
        assert!(matches!(
            SequenceHeader::parse(&zero_rate.to_bytes()),
            Err(HeaderError::Field { what: "fps_num", .. })
        ));
    }
}
