//! Any bytes to the .flo reader: an error or a flow field, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = mocomp::io::flo::read_flo_from(data);
});
