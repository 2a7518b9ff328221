//! Any bytes to the Y4M reader: an error or frames, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mocomp::io::y4m::Y4mReader;

fuzz_target!(|data: &[u8]| {
    if let Ok(reader) = Y4mReader::new(data) {
        // Frames are allocated at the header's size: keep inputs quick.
        if reader.info().width * reader.info().height > 256 * 256 {
            return;
        }
        for frame in reader {
            if frame.is_err() {
                break;
            }
        }
    }
});
