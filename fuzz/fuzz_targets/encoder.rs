//! Any bytes made into frames and an encoder configuration
//! (`mocomp::fuzzing::EncoderCase`): the encoder returns a stream or an
//! error, never panics, and the decoder's frames equal its reconstructions.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mocomp::fuzzing::EncoderCase;

fuzz_target!(|data: &[u8]| {
    let case = EncoderCase::from_bytes(data);
    if let Err(e) = case.check() {
        panic!("{e}: {:?} on {} frames", case.options, case.frames.len());
    }
});
