//! The encoder's options by name, as x264's `param_default_preset` and
//! `param_parse`: a configuration starts from a preset, then each option
//! given overrides it. The command line and Python both configure the
//! encoder through [`EncoderConfig::from_preset`] and
//! [`EncoderConfig::set`], so an option means the same, is checked the same
//! way and is refused with the same message in both.
//!
//! ```
//! use mocomp::encode::EncoderConfig;
//! let mut c = EncoderConfig::from_preset("fast").unwrap();
//! c.set("predictor", "block:hexbs").unwrap();
//! c.set("qp", "32").unwrap();
//! c.set("subpel-rd", "on").unwrap();
//! assert_eq!((c.qp, c.subpel_rd, c.predictor.label().as_str()), (32, true, "block:hexbs"));
//! assert!(c.set("qp", "52").is_err());
//! assert!(c.set("grid", "8").is_err()); // not an option of `block`
//! ```

use std::str::FromStr;

use super::config::{EncoderConfig, EncoderPreset, Partitions, Predictor};
use crate::codec::deblock::DeblockOffsets;
use crate::metrics::{Metric, Metrics};

/// Every option [`EncoderConfig::set`] takes, with what its value is
/// (names as `mocomp encode` spells them; `_` may stand for `-`).
pub const OPTIONS: [(&str, &str); 31] = [
    ("qp", "quantisation parameter, 0..=51"),
    ("gop", "I-frame period (0: only the first frame)"),
    (
        "predictor",
        "zero, block[:METHOD], flow-block[:FLOW], dense-lk|hs|dis|tvl1, obmc[:METHOD]",
    ),
    (
        "me",
        "block search of block and obmc: esa, tss, ntss, tdls, fss, ds, hexbs, epzs",
    ),
    ("range", "full-pel search range of block and obmc"),
    (
        "subpel",
        "sub-pel refinement of block and obmc: none, half, quarter",
    ),
    ("flow", "flow of flow-block and dense-*: lk, hs, dis, tvl1"),
    (
        "refine",
        "flow-block: search radius around the flow's vector, 0..=16",
    ),
    ("grid", "dense-*: motion grid spacing, 4, 8 or 16"),
    ("lambda-scale", "multiplies the mode decision's lambda"),
    ("rdoq", "rate-distortion optimised quantisation, on|off"),
    ("decision", "inter mode decision, fast|full"),
    ("ipratio", "quantiser step of P frames over I frames (> 0)"),
    (
        "deblock",
        "the in-loop deblocking filter, on|off, or on with offsets A:B (x264's, each -6..=6)",
    ),
    (
        "deblock-choice",
        "block P frames deblocked only where the filter lowered the error before, on|off",
    ),
    ("weightp", "weighted prediction, on|off"),
    ("refs", "references P frames may predict from, 1..=8 (block)"),
    (
        "refs-choice",
        "older references searched only while they saved enough before, on|off",
    ),
    ("subpel-rd", "sub-pel RD refinement (x264's subme 8), on|off"),
    (
        "split-margin",
        "splits searched and coded within 5/4 of the 16x16 estimate, on|off",
    ),
    (
        "split-search-margin",
        "splits searched where their candidates come within 1.1 of the 16x16 estimate, on|off",
    ),
    (
        "chroma-me",
        "chroma in the sub-pel search's cost (x264's), on|off",
    ),
    (
        "adaptive-pricing",
        "P frames' residual prices adapt through the frame, on|off",
    ),
    (
        "fast-pskip",
        "skip before the other modes where skip codes no level, on|off",
    ),
    (
        "early-pskip",
        "fast P-skip probed before the motion search beside skipped neighbours, on|off",
    ),
    ("8x8dct", "the 8x8 transform (and 8x8 intra), on|off"),
    (
        "luma-filter",
        "block P frames' luma interpolation: auto (per frame), sharp, smooth",
    ),
    (
        "partitions",
        "P frames' partitions: all, none, or a list of p8x8, i8x8, i4x4",
    ),
    (
        "i-partitions",
        "I frames' intra blocks: all, none (16x16 only), or a list of i8x8, i4x4",
    ),
    (
        "metrics",
        "quality metrics measured per frame: psnr, ssim, ms-ssim, psnr-hvs, ciede2000, vmaf, all",
    ),
    ("ssim", "SSIM measured per frame, on|off"),
];

/// `on`/`off` (and `true`/`false`, `1`/`0`, `yes`/`no`).
fn switch(value: &str) -> Result<bool, String> {
    match value.trim().to_ascii_lowercase().as_str() {
        "on" | "true" | "1" | "yes" => Ok(true),
        "off" | "false" | "0" | "no" => Ok(false),
        other => Err(format!("'{other}' is not on or off")),
    }
}

fn parse<T: FromStr>(value: &str) -> Result<T, String>
where
    T::Err: std::fmt::Display,
{
    value.trim().parse::<T>().map_err(|e| e.to_string())
}

impl EncoderConfig {
    /// The configuration of preset `name` (ultrafast, superfast, veryfast, faster, fast, medium, slow, slower)
    /// for the default predictor, as x264's `param_default_preset`.
    pub fn from_preset(name: &str) -> Result<EncoderConfig, String> {
        Ok(EncoderConfig::new().preset(name.parse::<EncoderPreset>()?))
    }

    /// Sets option `name` (one of [`OPTIONS`]) from its text, as x264's
    /// `param_parse`: the value checked, an unknown name, a bad value or
    /// an option the predictor does not have refused with a message.
    /// A new search predictor keeps the search settings the preset gave
    /// (sub-pel, range, window) and takes its own pattern.
    pub fn set(&mut self, name: &str, value: &str) -> Result<(), String> {
        // On a copy: a value the whole configuration refuses leaves it
        // as it was.
        let mut next = *self;
        next.apply(name, value)?;
        next.check()?;
        *self = next;
        Ok(())
    }

    fn apply(&mut self, name: &str, value: &str) -> Result<(), String> {
        let key = name.trim().replace('_', "-");
        let bad = |e: String| format!("{key}: {e}");
        match key.as_str() {
            "qp" => self.qp = parse(value).map_err(bad)?,
            "gop" => self.gop = parse(value).map_err(bad)?,
            "predictor" => *self = self.with_predictor(parse(value).map_err(bad)?),
            "me" | "range" | "subpel" => self.set_search(&key, value)?,
            "flow" | "refine" | "grid" => self.set_flow(&key, value)?,
            "lambda-scale" => self.lambda_scale = positive(parse(value).map_err(bad)?, &key)?,
            "rdoq" => self.rdoq = switch(value).map_err(bad)?,
            "decision" => self.decision = parse(value).map_err(bad)?,
            "ipratio" => self.ipratio = positive(parse(value).map_err(bad)?, &key)?,
            "deblock" => self.set_deblock(value).map_err(bad)?,
            "deblock-choice" => self.deblock_choice = switch(value).map_err(bad)?,
            "weightp" => self.weightp = switch(value).map_err(bad)?,
            "refs" => self.refs = parse(value).map_err(bad)?,
            "refs-choice" => self.refs_choice = switch(value).map_err(bad)?,
            "subpel-rd" => self.subpel_rd = switch(value).map_err(bad)?,
            "split-margin" => self.split_margin = switch(value).map_err(bad)?,
            "split-search-margin" => self.split_search_margin = switch(value).map_err(bad)?,
            "chroma-me" => self.chroma_me = switch(value).map_err(bad)?,
            "adaptive-pricing" => self.adaptive_pricing = switch(value).map_err(bad)?,
            "fast-pskip" => self.fast_pskip = switch(value).map_err(bad)?,
            "early-pskip" => self.early_pskip = switch(value).map_err(bad)?,
            "luma-filter" => self.luma_filter = parse(value).map_err(bad)?,
            "8x8dct" | "dct8x8" => self.transform_8x8 = switch(value).map_err(bad)?,
            "partitions" => self.partitions = parse::<Partitions>(value).map_err(bad)?,
            "i-partitions" => self.i_frame_partitions = intra_partitions(value).map_err(bad)?,
            "metrics" => self.metrics = parse::<Metrics>(value).map_err(bad)?,
            "ssim" => self.metrics = self.metrics.with(Metric::Ssim, switch(value).map_err(bad)?),
            _ => {
                let names: Vec<&str> = OPTIONS.iter().map(|o| o.0).collect();
                return Err(format!("unknown option '{name}' (options: {})", names.join(", ")));
            }
        }
        Ok(())
    }

    /// `deblock`: on, off, or on with x264's `A:B` (alpha/tc0 and beta
    /// offsets in its units: the frame header's are twice them).
    fn set_deblock(&mut self, value: &str) -> Result<(), String> {
        let Some((a, b)) = value.split_once(':') else {
            self.deblock = switch(value)?;
            return Ok(());
        };
        let half = |v: &str| -> Result<i8, String> {
            let v: i8 = parse(v)?;
            if v.abs() > DeblockOffsets::MAX / 2 {
                return Err(format!("offset {v} outside -6..=6"));
            }
            Ok(2 * v)
        };
        self.deblock = true;
        self.deblock_offsets = Some(DeblockOffsets {
            alpha: half(a)?,
            beta: half(b)?,
        });
        Ok(())
    }

    fn set_search(&mut self, key: &str, value: &str) -> Result<(), String> {
        let label = self.predictor.label();
        let s = self
            .predictor
            .search_mut()
            .ok_or_else(|| format!("{key} does not apply to predictor '{label}'"))?;
        let bad = |e: String| format!("{key}: {e}");
        match key {
            "me" => s.method = parse(value).map_err(bad)?,
            "range" => s.range = parse(value).map_err(bad)?,
            _ => s.subpel = parse(value).map_err(bad)?,
        }
        Ok(())
    }

    fn set_flow(&mut self, key: &str, value: &str) -> Result<(), String> {
        let label = self.predictor.label();
        let bad = |e: String| format!("{key}: {e}");
        match (&mut self.predictor, key) {
            (Predictor::FlowBlock { flow, .. } | Predictor::Dense { flow, .. }, "flow") => {
                *flow = parse(value).map_err(bad)?
            }
            (Predictor::FlowBlock { refine, .. }, "refine") => *refine = parse(value).map_err(bad)?,
            (Predictor::Dense { grid, .. }, "grid") => *grid = parse(value).map_err(bad)?,
            _ => return Err(format!("{key} does not apply to predictor '{label}'")),
        }
        Ok(())
    }
}

/// Intra partitions only: I frames have no inter blocks to split. `all`
/// (every partition, as the command line hands it on) is every intra one.
fn intra_partitions(value: &str) -> Result<Partitions, String> {
    let p = parse::<Partitions>(value)?;
    if p.p8x8 && p != Partitions::ALL {
        return Err("p8x8 is an inter partition: expected all, none, or a list of i8x8 and i4x4".into());
    }
    Ok(Partitions { p8x8: false, ..p })
}

fn positive(v: f64, key: &str) -> Result<f64, String> {
    if v > 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(format!("{key} {v} is not a positive number"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::encode::ModeDecision;

    #[test]
    fn a_preset_then_options_by_name_as_the_builder_gives() {
        let mut c = EncoderConfig::from_preset("slow").unwrap();
        for (k, v) in [
            ("predictor", "obmc:hexbs"),
            ("refs", "2"),
            ("rdoq", "off"),
            ("lambda_scale", "1.1"),
        ] {
            c.set(k, v).unwrap();
        }
        let mut want = EncoderConfig::new()
            .predictor("obmc:hexbs".parse().unwrap())
            .preset(EncoderPreset::Slow)
            .refs(2)
            .rdoq(false)
            .lambda_scale(1.1);
        want.decision = ModeDecision::Full;
        assert_eq!(c, want);
        // The slow preset's range 32 stayed with the new predictor.
        assert_eq!(c.predictor.search_mut().map(|s| s.range), Some(32));
    }

    #[test]
    fn every_option_is_taken_and_bad_ones_are_refused_by_name() {
        let good = [
            ("qp", "30"),
            ("gop", "12"),
            ("me", "esa"),
            ("range", "8"),
            ("subpel", "half"),
            ("lambda-scale", "1.2"),
            ("rdoq", "on"),
            ("decision", "fast"),
            ("ipratio", "1.2"),
            ("deblock", "off"),
            ("deblock-choice", "off"),
            ("weightp", "no"),
            ("refs", "3"),
            ("refs-choice", "off"),
            ("subpel-rd", "1"),
            ("split-margin", "on"),
            ("split-search-margin", "on"),
            ("chroma-me", "on"),
            ("adaptive-pricing", "off"),
            ("fast-pskip", "off"),
            ("early-pskip", "on"),
            ("8x8dct", "off"),
            ("luma-filter", "smooth"),
            ("partitions", "p8x8,i4x4"),
            ("i-partitions", "i8x8"),
            ("metrics", "ms-ssim"),
            ("ssim", "off"),
        ];
        let mut c = EncoderConfig::from_preset("medium").unwrap();
        for (k, v) in good {
            c.set(k, v).unwrap_or_else(|e| panic!("{k}={v}: {e}"));
        }
        c.set("predictor", "flow-block:dis").unwrap();
        c.set("refine", "2").unwrap();
        c.set("flow", "lk").unwrap();
        c.set("predictor", "dense-hs").unwrap();
        c.set("grid", "8").unwrap();
        let named: Vec<&str> = good
            .iter()
            .map(|g| g.0)
            .chain(["predictor", "refine", "flow", "grid"])
            .collect();
        assert!(
            OPTIONS.iter().all(|(o, _)| named.contains(o)),
            "an option without a case here"
        );
        for (k, v, says) in [
            ("qp", "52", "QP 52 is not in 0..=51"),
            ("refs", "9", "8"),
            ("range", "4", "does not apply"),
            ("rdoq", "maybe", "not on or off"),
            ("ipratio", "-1", "positive"),
            ("grid", "5", "4, 8 or 16"),
            ("luma-filter", "soft", "auto, sharp or smooth"),
            ("deblock", "7:0", "offset 7 outside -6..=6"),
            ("deblock", "1:x", "deblock"),
            ("colour", "red", "unknown option 'colour'"),
        ] {
            let err = c.clone().set(k, v).unwrap_err();
            assert!(err.contains(says), "{k}={v}: {err}");
        }
        assert!(EncoderConfig::from_preset("placebo").is_err());
    }

    #[test]
    fn deblock_takes_x264s_offsets_and_turns_the_filter_on() {
        let mut c = EncoderConfig::from_preset("medium").unwrap();
        c.set("deblock", "off").unwrap();
        c.set("deblock", "2:-1").unwrap();
        assert!(c.deblock);
        assert_eq!(c.deblock_offsets, Some(DeblockOffsets { alpha: 4, beta: -2 }));
        // on/off leave the offsets as they are.
        c.set("deblock", "on").unwrap();
        assert_eq!(c.deblock_offsets, Some(DeblockOffsets { alpha: 4, beta: -2 }));
    }
}
