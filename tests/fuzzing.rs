//! The fuzz targets' cases as property tests (`mocomp::fuzzing`): random
//! bytes made into encoder inputs and configurations, and into motion
//! estimation and flow inputs, a bounded number of cases on every change
//! (the libFuzzer targets in `fuzz/` search the same space for hours).
//! The seed corpus of the fuzz targets runs here too, so what a fuzzer
//! once found stays fixed.

use mocomp::fuzzing::{EncoderCase, MotionCase};
use proptest::prelude::*;

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn any_encoder_input_decodes_to_the_encoders_reconstruction(data in prop::collection::vec(any::<u8>(), 0..160)) {
        let case = EncoderCase::from_bytes(&data);
        prop_assert!(case.check().is_ok(), "{:?}: {:?}", case.options, case.check());
    }

    #[test]
    fn any_motion_input_gives_an_error_or_a_finite_field_of_its_shape(data in prop::collection::vec(any::<u8>(), 0..96)) {
        let case = MotionCase::from_bytes(&data);
        prop_assert!(case.check().is_ok(), "{:?}: {:?}", case.task, case.check());
    }
}

/// Every seed of the fuzz targets (and every input a fuzzer found and
/// was fixed for, once copied there).
#[test]
fn the_fuzz_seeds_pass() {
    let dir = |t: &str| {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("fuzz/seeds")
            .join(t)
    };
    let mut n = 0;
    for (target, run) in [
        (
            "encoder",
            (|d: &[u8]| EncoderCase::from_bytes(d).check()) as fn(&[u8]) -> Result<(), String>,
        ),
        ("motion", |d: &[u8]| MotionCase::from_bytes(d).check()),
    ] {
        for entry in std::fs::read_dir(dir(target)).unwrap() {
            let path = entry.unwrap().path();
            let data = std::fs::read(&path).unwrap();
            assert_eq!(run(&data), Ok(()), "{}", path.display());
            n += 1;
        }
    }
    assert!(n >= 10, "only {n} seeds");
}

/// Writes the decoder's seeds from the encoder, a stream for every
/// predictor with the slow preset's tools on small pictures (references,
/// partitions, 8x8 intra, weights, deblocking on and off):
/// `MOCOMP_FUZZ_SEEDS=fuzz/seeds/decoder cargo test --test fuzzing -- --ignored`.
#[test]
#[ignore = "writes files; run by hand to seed the decoder's fuzzer"]
fn write_decoder_seeds_from_the_encoder() {
    let Ok(dir) = std::env::var("MOCOMP_FUZZ_SEEDS") else {
        return;
    };
    let mut written = 0;
    for i in 0u8..24 {
        // Sizes up to 48x40, four frames, the slow preset (byte 7: preset 3).
        let mut data = vec![0, 8 + i % 40, 0, 3 + i % 37, 0, 3, 0, 3, 0, i, 0, 20 + i];
        data.extend((0..80).map(|k| (k as u8).wrapping_mul(37).wrapping_add(i)));
        let case = EncoderCase::from_bytes(&data);
        if let Some((stream, _)) = case.encode() {
            std::fs::write(format!("{dir}/encoder_{i:02}.mcv"), stream).unwrap();
            written += 1;
        }
    }
    assert!(written >= 20, "{written} streams");
}
