//! Which quality metrics to compute: names as on the command line
//! (`psnr,ssim,ms-ssim,psnr-hvs,ciede2000,vmaf`), and the set of them.

use std::fmt;
use std::str::FromStr;

/// A quality metric.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Metric {
    /// Luma PSNR (always measured).
    Psnr,
    /// Luma SSIM.
    Ssim,
    /// Luma MS-SSIM ([`ms_ssim`](super::ms_ssim)).
    MsSsim,
    /// PSNR-HVS ([`psnr_hvs`](super::psnr_hvs)).
    PsnrHvs,
    /// CIEDE2000 ([`ciede2000`](super::ciede2000)).
    Ciede2000,
    /// VMAF, through an ffmpeg built with libvmaf ([`vmaf`](super::vmaf)).
    Vmaf,
}

impl Metric {
    /// Every metric, in the order of CSV columns.
    pub const ALL: [Metric; 6] = [
        Metric::Psnr,
        Metric::Ssim,
        Metric::MsSsim,
        Metric::PsnrHvs,
        Metric::Ciede2000,
        Metric::Vmaf,
    ];

    /// The command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Metric::Psnr => "psnr",
            Metric::Ssim => "ssim",
            Metric::MsSsim => "ms-ssim",
            Metric::PsnrHvs => "psnr-hvs",
            Metric::Ciede2000 => "ciede2000",
            Metric::Vmaf => "vmaf",
        }
    }

    /// The CSV column of its sequence figure.
    pub fn column(self) -> &'static str {
        match self {
            Metric::Psnr => "psnr_y",
            Metric::Ssim => "ssim",
            Metric::MsSsim => "ms_ssim",
            Metric::PsnrHvs => "psnr_hvs",
            Metric::Ciede2000 => "ciede2000",
            Metric::Vmaf => "vmaf",
        }
    }

    /// Whether the metric is a similarity in [0, 1] that BD tables turn
    /// into dB as `-10 log10(1 - x)` (AWCY's convention).
    pub fn is_similarity(self) -> bool {
        matches!(self, Metric::Ssim | Metric::MsSsim)
    }

    /// The value BD-rate curves use: dB for similarities, the figure
    /// itself otherwise (NaN stays NaN: not measured).
    pub fn curve_value(self, v: f64) -> f64 {
        if self.is_similarity() && !v.is_nan() {
            -10.0 * (1.0 - v).max(1e-10).log10()
        } else {
            v
        }
    }

    /// The unit of [`Metric::curve_value`].
    pub fn unit(self) -> &'static str {
        match self {
            Metric::Vmaf => "",
            _ => " dB",
        }
    }
}

impl fmt::Display for Metric {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Why a metric name was not understood.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown metric '{0}' (known: psnr, ssim, ms-ssim, psnr-hvs, ciede2000, vmaf)")]
pub struct UnknownMetric(pub String);

impl FromStr for Metric {
    type Err = UnknownMetric;

    fn from_str(s: &str) -> Result<Metric, UnknownMetric> {
        let key: String = s
            .trim()
            .to_ascii_lowercase()
            .chars()
            .filter(|c| !matches!(c, '-' | '_' | ' '))
            .collect();
        Ok(match key.as_str() {
            "psnr" | "psnry" => Metric::Psnr,
            "ssim" => Metric::Ssim,
            "msssim" => Metric::MsSsim,
            "psnrhvs" => Metric::PsnrHvs,
            "ciede2000" | "ciede" => Metric::Ciede2000,
            "vmaf" => Metric::Vmaf,
            _ => return Err(UnknownMetric(s.trim().to_string())),
        })
    }
}

/// A set of metrics. PSNR is always in it: it costs nothing beside the
/// encode and every table uses it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Metrics {
    bits: u8,
}

impl Default for Metrics {
    /// PSNR and SSIM, what mocomp has always reported.
    fn default() -> Metrics {
        Metrics::of(&[Metric::Psnr, Metric::Ssim])
    }
}

impl Metrics {
    /// PSNR alone.
    pub fn psnr_only() -> Metrics {
        Metrics::of(&[Metric::Psnr])
    }

    /// No metric, not even PSNR (`--metrics none`, as x264 without
    /// `--psnr`): an encode's time alone, every figure NaN.
    pub fn none() -> Metrics {
        Metrics { bits: 0 }
    }

    /// Whether no metric is measured.
    pub fn is_none(self) -> bool {
        self.bits == 0
    }

    /// PSNR and the given metrics.
    pub fn of(list: &[Metric]) -> Metrics {
        let mut m = Metrics { bits: 1 };
        for &x in list {
            m.bits |= 1 << x as u8;
        }
        m
    }

    /// Every metric computed in-process (all but VMAF).
    pub fn all_builtin() -> Metrics {
        Metrics::of(&Metric::ALL[..5])
    }

    /// Whether `m` is in the set.
    pub fn has(self, m: Metric) -> bool {
        self.bits & (1 << m as u8) != 0
    }

    /// The set with `m` added or removed.
    pub fn with(self, m: Metric, on: bool) -> Metrics {
        let bit = 1 << m as u8;
        Metrics {
            bits: if on || m == Metric::Psnr {
                self.bits | bit
            } else {
                self.bits & !bit
            },
        }
    }

    /// The metrics in the set, in [`Metric::ALL`]'s order.
    pub fn iter(self) -> impl Iterator<Item = Metric> {
        Metric::ALL.into_iter().filter(move |&m| self.has(m))
    }
}

impl FromStr for Metrics {
    type Err = UnknownMetric;

    /// A comma-separated list of names; `all` for every metric but VMAF;
    /// `none` alone for none.
    fn from_str(s: &str) -> Result<Metrics, UnknownMetric> {
        if s.trim().eq_ignore_ascii_case("none") {
            return Ok(Metrics::none());
        }
        let mut out = Metrics::psnr_only();
        for name in s.split(',').filter(|n| !n.trim().is_empty()) {
            if name.trim().eq_ignore_ascii_case("all") {
                out.bits |= Metrics::all_builtin().bits;
            } else {
                out = out.with(name.parse()?, true);
            }
        }
        Ok(out)
    }
}

impl fmt::Display for Metrics {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_none() {
            return f.write_str("none");
        }
        let names: Vec<&str> = self.iter().map(Metric::name).collect();
        f.write_str(&names.join(","))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_accept_awcy_spellings() {
        for m in Metric::ALL {
            assert_eq!(m.name().parse::<Metric>(), Ok(m));
        }
        assert_eq!("MSSSIM".parse::<Metric>(), Ok(Metric::MsSsim));
        assert_eq!("PSNRHVS".parse::<Metric>(), Ok(Metric::PsnrHvs));
        assert_eq!("ms_ssim".parse::<Metric>(), Ok(Metric::MsSsim));
        assert!("butteraugli".parse::<Metric>().is_err());
    }

    #[test]
    fn sets_always_hold_psnr() {
        let m: Metrics = "ms-ssim,ciede2000".parse().unwrap();
        assert!(m.has(Metric::Psnr) && m.has(Metric::MsSsim) && m.has(Metric::Ciede2000));
        assert!(!m.has(Metric::Ssim) && !m.has(Metric::Vmaf));
        assert_eq!(m.to_string(), "psnr,ms-ssim,ciede2000");
        assert!(m.with(Metric::Psnr, false).has(Metric::Psnr));
        // `none` alone is the empty set, PSNR included; within a list it
        // is not a metric.
        let none: Metrics = " None".parse().unwrap();
        assert!(none.is_none() && Metric::ALL.iter().all(|&m| !none.has(m)));
        assert_eq!(none.to_string(), "none");
        assert!("none,ssim".parse::<Metrics>().is_err());
        let all: Metrics = "all".parse().unwrap();
        assert_eq!(all, Metrics::all_builtin());
        assert!(!all.has(Metric::Vmaf));
    }

    #[test]
    fn similarities_become_decibels() {
        assert!((Metric::MsSsim.curve_value(0.99) - 20.0).abs() < 1e-9);
        assert_eq!(Metric::PsnrHvs.curve_value(41.5), 41.5);
        assert!(Metric::MsSsim.curve_value(f64::NAN).is_nan());
        assert_eq!(Metric::Ssim.curve_value(1.0), 100.0);
    }
}
