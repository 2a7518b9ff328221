//! The bitstream syntax, one file per level as the specification has
//! them (FORMAT.md): the sequence ([`sequence`]), the frame ([`frame`]:
//! headers, the writers, the reader) and the macroblock ([`macroblock`]),
//! and the errors of reading a frame ([`error`]). Everything is
//! re-exported here under the names it always had.

pub mod error;
pub mod frame;
pub mod macroblock;
pub mod sequence;

pub use crate::consts::{FRAME_START, MAGIC, MB, SEQUENCE_HEADER_LEN, STREAM_END, VERSION};
pub use error::SyntaxError;
pub use frame::{
    read_frame, vector_syntax, write_decided_frame, write_frame, write_stream, BitCounts, EntropyState,
    FrameHeader, FrameSyntax, FrameType, FrameWriter, MotionTool,
};
pub use macroblock::{intra_mode_allowed, luma_intra_allowed, mb_mode, mb_vectors, CodedMb, MbKind};
pub use sequence::{ChromaSiting, ColourRange, HeaderError, SequenceHeader, Vui};
