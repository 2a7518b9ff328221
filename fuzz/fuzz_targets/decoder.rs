//! Any bytes to the decoder: an error or frames, never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use mocomp_codec::decoder::Decoder;

fuzz_target!(|data: &[u8]| {
    // Small pictures only, so that each input runs fast: larger ones are the
    // same code on more macroblocks. (The header's size is otherwise free.)
    if let Ok(mut decoder) = Decoder::new(data) {
        let s = decoder.sequence();
        if s.width * s.height > 128 * 128 {
            return;
        }
        while let Ok(Some(_)) = decoder.next_frame() {}
    }
});
