//! The stream format's constants in one place (FORMAT.md): its markers,
//! its limits and the sizes everything else is counted in. The modules
//! that use them re-export theirs under the names they have always had.

/// The first four bytes of every stream.
pub const MAGIC: [u8; 4] = *b"MOCO";

/// The format version this code writes and reads.
pub const VERSION: u8 = 3;

/// Bytes of the sequence header.
pub const SEQUENCE_HEADER_LEN: usize = 30;

/// Byte that starts a frame.
pub const FRAME_START: u8 = 0xA5;

/// Byte that ends the stream.
pub const STREAM_END: u8 = 0x5A;

/// Macroblock size in luma samples.
pub const MB: usize = 16;

/// Largest accepted width or height, in luma pixels.
pub const MAX_DIMENSION: usize = 16384;

/// Highest quantisation parameter.
pub const MAX_QP: u8 = 51;

/// The most references a P frame can predict from.
pub const MAX_REFS: u8 = 8;

/// Largest coded vector component magnitude, quarter-pel: 4096 pixels.
pub const MV_LIMIT: i32 = 1 << 14;

/// Motion grid spacings the format allows.
pub const SPACINGS: [usize; 3] = [4, 8, 16];

/// Largest level magnitude the syntax allows (far above what 8-bit
/// residuals quantise to at QP 0, about 1700).
pub const MAX_LEVEL: u32 = 1 << 15;

/// The denominator of a weight: a weight of 64 is a scale of 1.
pub const WEIGHT_ONE: i32 = 64;

/// The largest weighted-prediction offset magnitude.
pub const MAX_OFFSET: i32 = 255;
