//! Where and why a frame's syntax cannot be read.

use crate::bits::BitError;

/// Why a frame's payload is invalid; `bit` counts from the first bit after
/// the frame's length field.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{what} at bit {bit} of the frame")]
pub struct SyntaxError {
    /// What is wrong.
    pub what: String,
    /// Where.
    pub bit: usize,
}

impl From<BitError> for SyntaxError {
    fn from(e: BitError) -> SyntaxError {
        let bit = match e {
            BitError::EndOfData { pos, .. }
            | BitError::ExpGolombTooLong { pos }
            | BitError::ExpGolombRange { pos } => pos,
        };
        SyntaxError {
            what: e.to_string(),
            bit,
        }
    }
}

pub(super) fn invalid(what: String, bit: usize) -> SyntaxError {
    SyntaxError { what, bit }
}
