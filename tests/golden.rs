//! Golden streams: the bytes of a few encodings of the bundled samples,
//! pinned by hash, at every CPU level this machine runs
//! (`mocomp::codec::cpu`), so that "the same streams" after a refactor or
//! a new SIMD kernel is a test rather than a note in a commit. The
//! encodings take in every kernel family: block costs, interpolation,
//! half-pel planes, the macroblock coder, SSIM, and the flow kernels of
//! the flow predictors. A change of the
//! format or of an encoder decision changes a hash on purpose: then the
//! new hashes are taken (run with `MOCOMP_GOLDEN=print`) and the commit
//! says why.

use mocomp::codec::cpu;
use mocomp::encode::{Encoder, EncoderConfig, ModeDecision};
use mocomp::io::y4m::Y4mReader;

/// 64-bit FNV-1a: enough to tell streams apart, no dependency.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// The stream of the first `frames` frames of `sample` with `config`.
fn stream(sample: &str, frames: usize, config: EncoderConfig) -> Vec<u8> {
    let path = format!("{}/samples/{sample}", env!("CARGO_MANIFEST_DIR"));
    let all = Y4mReader::open(path.as_ref()).unwrap().read_all().unwrap();
    let first = &all[0];
    let mut encoder = Encoder::new(first.width(), first.height(), (25, 1), config).unwrap();
    let mut out = encoder.header();
    for f in all.iter().take(frames) {
        out.extend_from_slice(&encoder.encode(f).unwrap().bytes);
    }
    out.extend_from_slice(&Encoder::trailer());
    out
}

#[test]
fn streams_are_the_pinned_ones() {
    // Taken again when chroma planes gained their DC levels (FORMAT.md
    // sections 3.3 and 10.1), when inter chroma took x264's decimation
    // threshold (every stream codes chroma), and when intra 16x16
    // macroblocks gained their luma DC levels (every stream starts with
    // an I frame), and when fast P-skip after the search took x264's
    // rule alone (the searched vector the predicted one: block streams),
    // and when block P frames took what a frame thread knows when it
    // starts (weights from the top half, pricing contexts two frames
    // back, the luma filter learnt a frame later: every block stream),
    // and when the fast decision coded inter only where 16x16 intra does
    // not beat it by SATD (streams with intra in P frames), and when the
    // presets with RDOQ (the default configuration's, these streams')
    // took the base lambda as it is instead of 1.3 times it, and when the
    // full decision's early skip left skips that keep more than 16
    // lambdas of error (the one stream decided in full; 24 codes it
    // alike), and when intra blocks beside an intra neighbour were
    // searched within twice inter's SATD (the zero and dense-lk streams,
    // whose P frames have intra macroblocks), and when weights were kept
    // where they leave 0.9 of the block means' misfit rather than 0.8
    // (the zero, flow-block:lk and dense-lk streams: a chroma plane's
    // offset of one level, at 0.815, in one of their frames), and when
    // each sub-pel step of the block searches could move up to four
    // times instead of once (the block, block:esa, obmc and block:hexbs
    // streams), and when flow-block's refinement took the same walk (its
    // two streams), and when the candidates' own quarter-pel vectors
    // became starts of the sub-pel steps (the four block streams), and
    // when the default configuration (medium's) took a second reference,
    // searched while it pays (the three block streams), and when each
    // partition's search walked at full pel from its best candidate (the
    // five streams whose P frames split macroblocks), and when the 8x8
    // transform's RDOQ ran only where the plainly quantised 8x8 levels
    // come within the 4x4 coding's cost (the six streams whose P frames
    // try the 8x8 alternative with RDOQ), and when the frame header gained
    // the deblocking filter's offsets (every stream: two bits more in
    // each deblocked frame's header), and when the levels RDOQ lowers
    // were first rounded nearer the middle (every stream: the default
    // configuration has RDOQ), and when the default configuration
    // (medium's) left out the candidates' sub-pel starts (the four block
    // streams).
    let cases: [(&str, &str, u8, &str, u64); 8] = [
        ("synth_qcif.y4m", "zero", 30, "fast", 0xb76f3497c81dc90a),
        ("synth_qcif.y4m", "block", 27, "fast", 0x55007c8913d3fd99),
        ("synth_qcif.y4m", "block:esa", 22, "full", 0xea5ad19a9aa26f2a),
        ("synth_qcif.y4m", "flow-block:lk", 32, "fast", 0x4902ee616e69c7cd),
        ("synth_qcif.y4m", "dense-lk", 32, "fast", 0x4a92f0dce7a13a67),
        ("tree_qcif.y4m", "obmc", 27, "fast", 0xc243f930f5c50970),
        ("tree_qcif.y4m", "block:hexbs", 37, "fast", 0x2325de980a5dad9a),
        ("tree_qcif.y4m", "flow-block:dis", 30, "fast", 0x1ada6392e0b00cbc),
    ];
    let print = std::env::var("MOCOMP_GOLDEN").is_ok_and(|v| v == "print");
    let mut wrong = Vec::new();
    // The only test in this file (so in this process): setting the level
    // races with nothing.
    for level in cpu::available() {
        assert_eq!(cpu::set_level(level), level);
        for &(sample, predictor, qp, decision, pinned) in &cases {
            let decision = match decision {
                "full" => ModeDecision::Full,
                _ => ModeDecision::Fast,
            };
            let config = EncoderConfig::new()
                .qp(qp)
                .gop(4)
                .decision(decision)
                .predictor(predictor.parse().unwrap());
            let hash = fnv1a(&stream(sample, 6, config));
            let name = level.name();
            if print {
                println!("{name}: (\"{sample}\", \"{predictor}\", {qp}, ..., {hash:#018x}),");
            }
            if hash != pinned {
                wrong.push(format!(
                    "{name} {sample} {predictor} QP {qp}: {hash:#018x}, pinned {pinned:#018x}"
                ));
            }
        }
    }
    assert!(wrong.is_empty(), "streams changed:\n{}", wrong.join("\n"));
}
