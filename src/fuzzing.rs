//! Cases for fuzzing and property tests, as rav1e's `fuzzing.rs`: bytes
//! made into an input the library must survive, and the check of what it
//! gave. The libFuzzer targets (`fuzz/fuzz_targets/`) and the property
//! tests (`tests/fuzzing.rs`) run the same cases, so a failure found by
//! one replays in the other.
//!
//! - [`EncoderCase`]: a picture size (1x1, odd, not a multiple of 16), a
//!   few frames of content (random, flat, gradients, shifted copies, hard
//!   cuts, light ramps) and an encoder configuration from every option's
//!   legal range. [`EncoderCase::check`]: the encoder returns a stream or
//!   a clear error, and the decoder's frames equal the encoder's
//!   reconstructions byte for byte.
//! - [`MotionCase`]: two planes of any size and content, a block search
//!   or a dense flow method with its parameters. [`MotionCase::check`]:
//!   an error or a result of the right shape with finite values, and a
//!   block search's field the same with successive elimination as
//!   without.

use ndarray::Array2;

use crate::codec::decoder::decode;
use crate::codec::{Frame, Plane};
use crate::encode::{encode_sequence, EncoderConfig, SequenceInfo};
use crate::flow::{FlowEstimator, FlowMethod, FlowOptions, Preset};
use crate::me::{estimate, MeConfig, Method, Metric, Subpel};
use crate::raster::plane_to_array;

/// Bytes read one field at a time; past the end every field is 0.
struct Bytes<'a>(&'a [u8]);

impl Bytes<'_> {
    fn byte(&mut self) -> u8 {
        match self.0.split_first() {
            Some((&b, rest)) => {
                self.0 = rest;
                b
            }
            None => 0,
        }
    }

    /// A value in `0..n`.
    fn below(&mut self, n: usize) -> usize {
        let v = usize::from(self.byte()) << 8 | usize::from(self.byte());
        v % n.max(1)
    }

    /// One of `items`.
    fn pick<T: Copy>(&mut self, items: &[T]) -> T {
        items[self.below(items.len())]
    }

    fn coin(&mut self) -> bool {
        self.byte() & 1 == 1
    }
}

/// Content of a frame, from the frame before it where it says so.
#[derive(Debug, Clone, Copy)]
enum Content {
    Random,
    Flat,
    Gradient,
    /// The previous frame moved by a vector (a new one where there is none).
    Shifted(isize, isize),
    /// A hard cut: unrelated random content.
    Cut,
    /// The previous frame with its light raised or lowered.
    Light(i16),
}

fn content(b: &mut Bytes<'_>) -> Content {
    match b.below(6) {
        0 => Content::Random,
        1 => Content::Flat,
        2 => Content::Gradient,
        3 => Content::Shifted(b.below(17) as isize - 8, b.below(17) as isize - 8),
        4 => Content::Cut,
        _ => Content::Light(b.below(81) as i16 - 40),
    }
}

/// A plane of `w x h` samples of `kind`, from `prev` where it moves or
/// relights it; `seed` makes the random ones.
fn plane(w: usize, h: usize, kind: Content, prev: Option<&Plane>, seed: u64) -> Plane {
    let mut s = seed | 1;
    let mut random = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        s as u8
    };
    let made = match (kind, prev) {
        (Content::Flat, _) => Plane::filled(w, h, (seed % 256) as u8),
        (Content::Gradient, _) => Plane::from_fn(w, h, |x, y| ((x * 255) / w.max(2) + y * 3) as u8),
        (Content::Shifted(dx, dy), Some(p)) => {
            Plane::from_fn(w, h, |x, y| p.pixel_clamped(x as isize - dx, y as isize - dy))
        }
        (Content::Light(d), Some(p)) => {
            Plane::from_fn(w, h, |x, y| (i16::from(p.get(x, y)) + d).clamp(0, 255) as u8)
        }
        _ => Plane::from_fn(w, h, |_, _| random()),
    };
    made.unwrap_or_else(|_| unreachable!("sizes within 1..=80"))
}

/// Frames of `w x h` whose contents the bytes choose.
fn frames(b: &mut Bytes<'_>, w: usize, h: usize, n: usize) -> Vec<Frame> {
    let mut out: Vec<Frame> = Vec::with_capacity(n);
    for t in 0..n {
        let kind = content(b);
        let prev = out.last();
        let planes: Vec<Plane> = (0..3)
            .map(|p| {
                let (pw, ph) = if p == 0 {
                    (w, h)
                } else {
                    (w.div_ceil(2), h.div_ceil(2))
                };
                plane(
                    pw,
                    ph,
                    kind,
                    prev.map(|f| f.plane(p)),
                    (t * 3 + p) as u64 + 7 * w as u64,
                )
            })
            .collect();
        let [y, u, v]: [Plane; 3] = planes.try_into().unwrap_or_else(|_| unreachable!("three planes"));
        out.push(Frame::from_planes(y, u, v).unwrap_or_else(|_| unreachable!("4:2:0 planes")));
    }
    out
}

/// Every predictor, with each search method and flow.
const PREDICTORS: [&str; 19] = [
    "zero",
    "block:esa",
    "block:tss",
    "block:ntss",
    "block:tdls",
    "block:fss",
    "block:ds",
    "block:hexbs",
    "block:epzs",
    "obmc:epzs",
    "obmc:hexbs",
    "flow-block:lk",
    "flow-block:hs",
    "flow-block:dis",
    "flow-block:tvl1",
    "dense-lk",
    "dense-hs",
    "dense-dis",
    "dense-tvl1",
];

/// One encoder input: frames and a configuration by name.
#[derive(Debug, Clone)]
pub struct EncoderCase {
    /// The frames (all of one size).
    pub frames: Vec<Frame>,
    /// The preset.
    pub preset: &'static str,
    /// Options by name, in order ([`EncoderConfig::set`]).
    pub options: Vec<(&'static str, String)>,
}

impl EncoderCase {
    /// The case the bytes choose.
    pub fn from_bytes(data: &[u8]) -> EncoderCase {
        let mut b = Bytes(data);
        let (w, h) = (1 + b.below(72), 1 + b.below(56));
        let n = 1 + b.below(5);
        let preset = b.pick(&[
            "ultrafast",
            "superfast",
            "veryfast",
            "faster",
            "fast",
            "medium",
            "slow",
            "slower",
        ]);
        let predictor = b.pick(&PREDICTORS);
        let mut options = vec![
            ("qp", b.below(52).to_string()),
            ("predictor", predictor.to_string()),
            ("gop", b.below(4).to_string()),
        ];
        let on = |b: &mut Bytes<'_>| if b.coin() { "on" } else { "off" }.to_string();
        // Each option given or left to the preset, by one byte.
        let mut maybe = |b: &mut Bytes<'_>, name: &'static str, value: &dyn Fn(&mut Bytes<'_>) -> String| {
            if b.coin() {
                let v = value(b);
                options.push((name, v));
            }
        };
        maybe(&mut b, "rdoq", &on);
        maybe(&mut b, "decision", &|b| b.pick(&["fast", "full"]).to_string());
        maybe(&mut b, "deblock", &|b| {
            b.pick(&["on", "off", "1:1", "-2:3", "6:-6"]).to_string()
        });
        maybe(&mut b, "weightp", &on);
        maybe(&mut b, "subpel-rd", &on);
        maybe(&mut b, "early-pskip", &on);
        maybe(&mut b, "8x8dct", &on);
        maybe(&mut b, "partitions", &|b| {
            b.pick(&["all", "none", "p8x8", "i8x8", "i4x4", "p8x8,i4x4", "i8x8,i4x4"])
                .to_string()
        });
        maybe(&mut b, "i-partitions", &|b| {
            b.pick(&["all", "none", "i8x8", "i4x4"]).to_string()
        });
        maybe(&mut b, "lambda-scale", &|b| {
            format!("{}", 0.25 + b.below(12) as f64 * 0.25)
        });
        maybe(&mut b, "ipratio", &|b| {
            format!("{}", 1.0 + b.below(8) as f64 * 0.25)
        });
        if predictor.starts_with("block") {
            maybe(&mut b, "refs", &|b| (1 + b.below(4)).to_string());
        }
        if predictor.starts_with("block") || predictor.starts_with("obmc") {
            maybe(&mut b, "range", &|b| (1 + b.below(24)).to_string());
            maybe(&mut b, "subpel", &|b| {
                b.pick(&["none", "half", "quarter"]).to_string()
            });
        }
        if predictor.starts_with("flow-block") {
            maybe(&mut b, "refine", &|b| b.below(5).to_string());
        }
        if predictor.starts_with("dense") {
            maybe(&mut b, "grid", &|b| b.pick(&[4, 8, 16]).to_string());
        }
        maybe(&mut b, "adaptive-pricing", &on);
        if predictor.starts_with("block") {
            maybe(&mut b, "chroma-me", &on);
        }
        EncoderCase {
            frames: frames(&mut b, w, h, n),
            preset,
            options,
        }
    }

    /// The configuration, or why the options were refused.
    pub fn config(&self) -> Result<EncoderConfig, String> {
        let mut c = EncoderConfig::from_preset(self.preset)?;
        for (name, value) in &self.options {
            c.set(name, value)?;
        }
        Ok(c)
    }

    /// The stream and the encoder's reconstructions, or `None` when the
    /// options or the encoder refused the input (with an error).
    pub fn encode(&self) -> Option<(Vec<u8>, Vec<Frame>)> {
        let config = self.config().ok()?;
        let first = &self.frames[0];
        let info = SequenceInfo {
            width: first.width(),
            height: first.height(),
            fps: (25, 1),
            vui: Default::default(),
        };
        let mut stream = Vec::new();
        let mut recons = Vec::new();
        encode_sequence(
            &mut self.frames.iter(),
            info,
            config,
            None,
            &mut stream,
            |coded| {
                recons.extend(coded.recon.clone());
                Ok(())
            },
        )
        .ok()?;
        Some((stream, recons))
    }

    /// Encodes the frames and decodes the stream: `Ok` when the encoder
    /// refused the input with an error or when the decoder gives back
    /// exactly the encoder's reconstructions; `Err` says what differs.
    /// (A panic is a failure too: the caller's harness sees it.)
    pub fn check(&self) -> Result<(), String> {
        let Some((stream, recons)) = self.encode() else {
            return Ok(());
        };
        let (_, decoded) = decode(&stream).map_err(|e| format!("its own stream does not decode: {e}"))?;
        if decoded.len() != recons.len() {
            return Err(format!(
                "{} frames decoded, {} coded",
                decoded.len(),
                recons.len()
            ));
        }
        for (t, (d, r)) in decoded.iter().zip(&recons).enumerate() {
            for p in 0..3 {
                if d.plane(p).rows().ne(r.plane(p).rows()) {
                    return Err(format!(
                        "frame {t}, plane {p}: the decoder's samples differ from the encoder's"
                    ));
                }
            }
        }
        Ok(())
    }
}

/// What a motion case estimates.
#[derive(Debug, Clone)]
pub enum MotionTask {
    /// A block search.
    Blocks(MeConfig),
    /// A dense flow method.
    Flow(FlowOptions),
}

/// Two planes and an estimator of the motion between them.
#[derive(Debug, Clone)]
pub struct MotionCase {
    /// The current picture.
    pub current: Plane,
    /// The reference.
    pub reference: Plane,
    /// What runs on them.
    pub task: MotionTask,
}

impl MotionCase {
    /// The case the bytes choose.
    pub fn from_bytes(data: &[u8]) -> MotionCase {
        let mut b = Bytes(data);
        let (w, h) = (1 + b.below(64), 1 + b.below(64));
        let first = content(&mut b);
        let current = plane(w, h, first, None, b.byte().into());
        let second = content(&mut b);
        let reference = plane(w, h, second, Some(&current), b.byte().into());
        let task = if b.coin() {
            let mut cfg = MeConfig::new(
                b.pick(&Method::ALL),
                b.pick(&[1, 2, 4, 8, 16, 32, 64]),
                b.below(70) as i32,
            );
            cfg.subpel = b.pick(&[Subpel::None, Subpel::Half, Subpel::Quarter]);
            cfg.metric = b.pick(&Metric::ALL);
            cfg.lambda = b.pick(&[0.0, 1.0, 12.5, -1.0, f64::NAN]);
            cfg.window = b.below(6) as i32;
            cfg.full_pel_sad = b.coin();
            MotionTask::Blocks(cfg)
        } else {
            let mut o = FlowOptions {
                method: b.pick(&FlowMethod::ALL),
                preset: b.pick(&Preset::ALL),
                ..FlowOptions::default()
            };
            let choose = |b: &mut Bytes<'_>| b.coin();
            if choose(&mut b) {
                o.levels = Some(b.below(8));
            }
            if choose(&mut b) {
                o.sigma = Some(b.pick(&[0.0, 0.5, 2.0, 9.0, 11.0]));
            }
            if choose(&mut b) {
                o.iterations = Some(b.below(12));
            }
            if choose(&mut b) {
                o.alpha = Some(b.pick(&[0.0, 1.0, 30.0, 1e5]));
            }
            if choose(&mut b) {
                o.warps = Some(b.below(4));
            }
            if choose(&mut b) {
                o.finest = Some(b.below(4));
            }
            o.global_search = choose(&mut b);
            o.matches = choose(&mut b);
            MotionTask::Flow(o)
        };
        MotionCase {
            current,
            reference,
            task,
        }
    }

    /// Runs the task: `Ok` for a refusal with an error or a result of the
    /// picture's shape with finite values; `Err` says what is wrong.
    pub fn check(&self) -> Result<(), String> {
        let (w, h) = (self.current.width(), self.current.height());
        match &self.task {
            MotionTask::Blocks(cfg) => {
                let Ok(field) = estimate(&self.current, &self.reference, cfg) else {
                    return Ok(());
                };
                let b = field.block();
                if (field.cols(), field.rows()) != (w.div_ceil(b), h.div_ceil(b)) {
                    return Err(format!(
                        "{}x{} blocks for a {w}x{h} picture",
                        field.cols(),
                        field.rows()
                    ));
                }
                // Full-pel candidates lie within the range; sub-pel steps
                // add less than a pixel.
                let reach = 4 * (cfg.range + 1);
                if field
                    .vectors()
                    .iter()
                    .any(|v| v.x.abs() > reach || v.y.abs() > reach)
                {
                    return Err(format!("a vector beyond the range {}", cfg.range));
                }
                // Successive elimination skips only what cannot win: the
                // same field as evaluating every position.
                let plain = MeConfig {
                    successive_elimination: false,
                    ..*cfg
                };
                match estimate(&self.current, &self.reference, &plain) {
                    Ok(p) if p.vectors() == field.vectors() && p.costs() == field.costs() => Ok(()),
                    Ok(_) => Err("successive elimination changed the field".into()),
                    Err(e) => Err(format!("only the search without elimination failed: {e}")),
                }
            }
            MotionTask::Flow(options) => {
                let Ok(mut estimator) = FlowEstimator::new(options) else {
                    return Ok(());
                };
                let (a, b): (Array2<f32>, Array2<f32>) =
                    (plane_to_array(&self.current), plane_to_array(&self.reference));
                let flow = estimator.compute(&a, &b);
                if (flow.width(), flow.height()) != (w, h) {
                    return Err(format!(
                        "a {}x{} flow for a {w}x{h} picture",
                        flow.width(),
                        flow.height()
                    ));
                }
                if flow.u().iter().chain(flow.v()).any(|x| !x.is_finite()) {
                    return Err("a flow value that is not finite".into());
                }
                Ok(())
            }
        }
    }
}
