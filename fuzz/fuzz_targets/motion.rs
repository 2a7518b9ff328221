//! Any bytes made into two planes and a block search or dense flow with
//! its parameters (`mocomp::fuzzing::MotionCase`): an error or a field of
//! the picture's shape with finite values, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mocomp::fuzzing::MotionCase;

fuzz_target!(|data: &[u8]| {
    let case = MotionCase::from_bytes(data);
    if let Err(e) = case.check() {
        panic!("{e}: {:?}", case.task);
    }
});
