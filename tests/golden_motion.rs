//! Golden motion and metrics: the bits of every dense flow method at every
//! preset, every block search method, the sparse matches and the picture
//! metrics on the bundled samples, pinned by hash at every CPU level this
//! machine runs, so that a restructuring or a new kernel that changes a
//! flow, a vector or a figure is a failing test (tests/golden.rs does the
//! same for streams). A deliberate change takes the hashes again
//! (`MOCOMP_GOLDEN=print cargo test --test golden_motion -- --nocapture`)
//! and its commit says why.

use mocomp::codec::cpu;
use mocomp::codec::Frame;
use mocomp::features::{match_pictures, MatchParams};
use mocomp::flow::{FlowEstimator, FlowMethod, FlowOptions, Preset};
use mocomp::io::y4m::Y4mReader;
use mocomp::me::{estimate, MeConfig, Method, Metric, Subpel};
use mocomp::metrics::{FrameQuality, Metrics};
use mocomp::raster::plane_to_array;

/// 64-bit FNV-1a over a stream of 64-bit words.
#[derive(Clone, Copy)]
struct Hash(u64);

impl Hash {
    fn new() -> Hash {
        Hash(0xcbf2_9ce4_8422_2325)
    }
    fn word(&mut self, w: u64) {
        for b in w.to_le_bytes() {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    fn f32s<'a>(&mut self, v: impl IntoIterator<Item = &'a f32>) {
        v.into_iter().for_each(|x| self.word(u64::from(x.to_bits())));
    }
}

fn frames(sample: &str, n: usize) -> Vec<Frame> {
    let path = format!("{}/samples/{sample}", env!("CARGO_MANIFEST_DIR"));
    let all = Y4mReader::open(path.as_ref()).unwrap().read_all().unwrap();
    all.into_iter().take(n).collect()
}

/// Every figure, one hash per family: (name, hash).
fn figures(pair: &[Frame]) -> Vec<(&'static str, u64)> {
    let (a, b) = (&pair[0], &pair[1]);
    let (fa, fb) = (plane_to_array(a.y()), plane_to_array(b.y()));
    let mut out = Vec::new();
    let mut flow = Hash::new();
    for method in FlowMethod::ALL {
        for preset in Preset::ALL {
            let options = FlowOptions {
                method,
                preset,
                ..FlowOptions::default()
            };
            let f = FlowEstimator::new(&options).unwrap().compute(&fa, &fb);
            flow.f32s(f.u());
            flow.f32s(f.v());
        }
    }
    out.push(("flow", flow.0));
    let mut vectors = Hash::new();
    for method in Method::ALL {
        for (metric, subpel, lambda) in [
            (Metric::Sad, Subpel::None, 0.0),
            (Metric::Satd, Subpel::Quarter, 4.0),
        ] {
            let cfg = MeConfig {
                metric,
                subpel,
                lambda,
                ..MeConfig::new(method, 16, 16)
            };
            let field = estimate(b.y(), a.y(), &cfg).unwrap();
            for by in 0..field.rows() {
                for bx in 0..field.cols() {
                    let v = field.vector(bx, by);
                    vectors.word(((v.x as u32 as u64) << 32) | u64::from(v.y as u32));
                    vectors.word(u64::from(field.cost(bx, by)));
                }
            }
        }
    }
    out.push(("block vectors", vectors.0));
    let mut matches = Hash::new();
    for m in match_pictures(&fa, &fb, &MatchParams::default()) {
        matches.f32s(&[m.x1, m.y1, m.x2, m.y2]);
        matches.word(u64::from(m.distance));
    }
    out.push(("matches", matches.0));
    let q = FrameQuality::measure_with(a, b, Metrics::all_builtin());
    let mut metrics = Hash::new();
    for v in [
        q.psnr.y,
        q.psnr.u,
        q.psnr.v,
        q.ssim,
        q.ms_ssim,
        q.psnr_hvs,
        q.psnr_hvs_y,
        q.ciede2000,
    ]
    .into_iter()
    .chain(q.psnr.mse)
    {
        metrics.word(v.to_bits());
    }
    metrics.word(mocomp::metrics::ssim_8x8(a.y(), b.y()).to_bits());
    out.push(("metrics", metrics.0));
    out
}

#[test]
fn flows_vectors_matches_and_metrics_are_the_pinned_ones() {
    let pinned: [(&str, [u64; 4]); 2] = [
        (
            "synth_qcif.y4m",
            [
                0xe5c1d001d0f6a715,
                0x11f1d4bcf10788b8,
                0xa2fb325df39cca87,
                0x036c795b6b600177,
            ],
        ),
        (
            "tree_qcif.y4m",
            [
                0x37574881266b7aa3,
                0x9bb4fee41451bfa5,
                0xe9545a0776768122,
                0xcb1d65653d1b8f5e,
            ],
        ),
    ];
    let print = std::env::var("MOCOMP_GOLDEN").is_ok_and(|v| v == "print");
    let mut wrong = Vec::new();
    // The only test in this file (so in this process): setting the level
    // races with nothing.
    for level in cpu::available() {
        assert_eq!(cpu::set_level(level), level);
        for (sample, hashes) in &pinned {
            let got = figures(&frames(sample, 2));
            if print {
                let list: Vec<String> = got.iter().map(|(_, h)| format!("{h:#018x}")).collect();
                println!("{}: (\"{sample}\", [{}]),", level.name(), list.join(", "));
            }
            for ((name, h), want) in got.iter().zip(hashes) {
                if h != want {
                    wrong.push(format!(
                        "{} {sample} {name}: {h:#018x}, pinned {want:#018x}",
                        level.name()
                    ));
                }
            }
        }
    }
    assert!(wrong.is_empty(), "figures changed:\n{}", wrong.join("\n"));
}
