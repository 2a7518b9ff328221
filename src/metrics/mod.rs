//! Quality and error measures: PSNR, SSIM, MS-SSIM, PSNR-HVS, CIEDE2000
//! (and VMAF through ffmpeg) of pictures, errors of flow fields against
//! ground truth, and per-sequence summaries.

mod ciede2000;
pub mod dsp;
mod flow_error;
mod ms_ssim;
mod psnr;
mod psnr_hvs;
mod select;
mod ssim;
mod ssim_8x8;
pub mod vmaf;

pub use ciede2000::ciede2000;
pub use flow_error::{flow_errors, FlowErrors};
pub use ms_ssim::ms_ssim;
pub use psnr::{frame_psnr, mse, psnr, psnr_from_mse, squared_difference_sum, sse, FramePsnr, PSNR_CAP_DB};
pub use psnr_hvs::{psnr_hvs, PsnrHvs};
pub use select::{Metric, Metrics, UnknownMetric};
pub use ssim::ssim;
pub use ssim_8x8::ssim_8x8;

use serde::Serialize;

use crate::codec::{Frame, Plane};

/// Which SSIM a quality record holds: Wang et al.'s with an 11x11
/// Gaussian window (scikit-image's, what `mocomp psnr` reports), or x264's
/// over 8x8 windows at 4-pixel steps (what encoders and ffmpeg's `ssim`
/// filter report, a twelfth of the cost: the encoder's).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum SsimWindow {
    /// [`ssim`]: Gaussian 11x11, sigma 1.5.
    #[default]
    Gaussian,
    /// [`ssim_8x8`]: x264's and ffmpeg's.
    Blocks8x8,
}

/// What a quality record measures: the metrics (PSNR unless none) and
/// which SSIM.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct QualitySettings {
    /// The metrics to measure.
    pub metrics: Metrics,
    /// The SSIM's window.
    pub ssim: SsimWindow,
}

/// The quality of one decoded or predicted frame against its source: the
/// one record every report reads (the encoder's frame statistics, `mocomp
/// psnr`, the RD sweep, Python). A metric that was not asked for is NaN.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FrameQuality {
    /// PSNR of each plane (`psnr_y`, `psnr_u`, `psnr_v` and `mse` when
    /// serialised).
    #[serde(flatten)]
    pub psnr: FramePsnr,
    /// SSIM of the luma plane (the window [`QualitySettings::ssim`] chose).
    pub ssim: f64,
    /// MS-SSIM of the luma plane ([`ms_ssim`]).
    pub ms_ssim: f64,
    /// PSNR-HVS of the three planes combined, dB ([`psnr_hvs`]).
    pub psnr_hvs: f64,
    /// PSNR-HVS of the luma plane, dB.
    pub psnr_hvs_y: f64,
    /// CIEDE2000, dB ([`ciede2000`]).
    pub ciede2000: f64,
    /// VMAF (set by the caller from [`vmaf::vmaf`], which works on whole
    /// sequences).
    pub vmaf: f64,
}

impl FrameQuality {
    /// PSNR of every plane and luma SSIM (Gaussian) of `test` against
    /// `reference`.
    pub fn measure(reference: &Frame, test: &Frame) -> FrameQuality {
        FrameQuality::measure_with(reference, test, Metrics::default())
    }

    /// PSNR of every plane and the in-process metrics of `which` (SSIM
    /// Gaussian; VMAF is left NaN).
    pub fn measure_with(reference: &Frame, test: &Frame, which: Metrics) -> FrameQuality {
        FrameQuality::measure_as(
            reference,
            test,
            &QualitySettings {
                metrics: which,
                ssim: SsimWindow::Gaussian,
            },
        )
    }

    /// The record `settings` asks for: every quality figure of the
    /// project is measured here.
    pub fn measure_as(reference: &Frame, test: &Frame, settings: &QualitySettings) -> FrameQuality {
        let which = settings.metrics;
        let when = |m: Metric, f: &dyn Fn() -> f64| if which.has(m) { f() } else { f64::NAN };
        let hvs = which.has(Metric::PsnrHvs).then(|| psnr_hvs(reference, test));
        let ssim_of = |a: &Plane, b: &Plane| match settings.ssim {
            SsimWindow::Gaussian => ssim(a, b),
            SsimWindow::Blocks8x8 => ssim_8x8(a, b),
        };
        FrameQuality {
            psnr: if which.has(Metric::Psnr) {
                frame_psnr(reference, test)
            } else {
                FramePsnr::from_mse([f64::NAN; 3])
            },
            ssim: when(Metric::Ssim, &|| ssim_of(reference.y(), test.y())),
            ms_ssim: when(Metric::MsSsim, &|| ms_ssim(reference.y(), test.y())),
            psnr_hvs: hvs.map_or(f64::NAN, |h| h.total),
            psnr_hvs_y: hvs.map_or(f64::NAN, |h| h.y),
            ciede2000: when(Metric::Ciede2000, &|| ciede2000(reference, test)),
            vmaf: f64::NAN,
        }
    }

    /// The figure of `metric` (luma PSNR for [`Metric::Psnr`]).
    pub fn value(&self, metric: Metric) -> f64 {
        match metric {
            Metric::Psnr => self.psnr.y,
            Metric::Ssim => self.ssim,
            Metric::MsSsim => self.ms_ssim,
            Metric::PsnrHvs => self.psnr_hvs,
            Metric::Ciede2000 => self.ciede2000,
            Metric::Vmaf => self.vmaf,
        }
    }
}

/// Sequence figures over frames: PSNR as the mean of per-frame PSNRs (as HM
/// and ffmpeg's `psnr` stats report it), and beside it the PSNR of the mean
/// MSE (what ffmpeg's `psnr` summary line prints as `y:`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SequenceQuality {
    /// Frames measured.
    pub frames: usize,
    /// Mean over frames of luma PSNR (dB).
    pub psnr_y: f64,
    /// Mean over frames of Cb PSNR (dB).
    pub psnr_u: f64,
    /// Mean over frames of Cr PSNR (dB).
    pub psnr_v: f64,
    /// Mean over frames of the 6:1:1 weighted PSNR (dB).
    pub psnr_yuv: f64,
    /// Luma PSNR of the MSE averaged over frames (dB).
    pub psnr_y_mse: f64,
    /// Cb PSNR of the MSE averaged over frames (dB).
    pub psnr_u_mse: f64,
    /// Cr PSNR of the MSE averaged over frames (dB).
    pub psnr_v_mse: f64,
    /// Mean over frames of luma SSIM (NaN when not measured, as the
    /// following).
    pub ssim: f64,
    /// Mean over frames of luma MS-SSIM.
    pub ms_ssim: f64,
    /// Mean over frames of PSNR-HVS, dB.
    pub psnr_hvs: f64,
    /// Mean over frames of luma PSNR-HVS, dB.
    pub psnr_hvs_y: f64,
    /// Mean over frames of CIEDE2000, dB.
    pub ciede2000: f64,
    /// Mean over frames of VMAF.
    pub vmaf: f64,
}

impl SequenceQuality {
    /// The figure of `metric` (mean luma PSNR for [`Metric::Psnr`]).
    pub fn value(&self, metric: Metric) -> f64 {
        match metric {
            Metric::Psnr => self.psnr_y,
            Metric::Ssim => self.ssim,
            Metric::MsSsim => self.ms_ssim,
            Metric::PsnrHvs => self.psnr_hvs,
            Metric::Ciede2000 => self.ciede2000,
            Metric::Vmaf => self.vmaf,
        }
    }

    /// A record of `frames` frames with every figure unknown (NaN): what
    /// a peer's CSV row fills in as far as it has columns.
    pub fn unknown(frames: usize) -> SequenceQuality {
        SequenceQuality {
            frames,
            psnr_y: f64::NAN,
            psnr_u: f64::NAN,
            psnr_v: f64::NAN,
            psnr_yuv: f64::NAN,
            psnr_y_mse: f64::NAN,
            psnr_u_mse: f64::NAN,
            psnr_v_mse: f64::NAN,
            ssim: f64::NAN,
            ms_ssim: f64::NAN,
            psnr_hvs: f64::NAN,
            psnr_hvs_y: f64::NAN,
            ciede2000: f64::NAN,
            vmaf: f64::NAN,
        }
    }
}

/// Accumulates [`FrameQuality`] values into a [`SequenceQuality`].
///
/// ```
/// use mocomp::codec::Frame;
/// use mocomp::metrics::{FrameQuality, QualityAccumulator};
/// let a = Frame::filled(16, 16, 100, 128, 128).unwrap();
/// let b = Frame::filled(16, 16, 101, 128, 128).unwrap();
/// let mut acc = QualityAccumulator::default();
/// acc.push(&FrameQuality::measure(&a, &b));
/// acc.push(&FrameQuality::measure(&a, &a));
/// let s = acc.summary().unwrap();
/// // Mean of 48.13 dB (MSE 1) and the 100 dB cap...
/// assert!((s.psnr_y - (48.1308 + 100.0) / 2.0).abs() < 1e-3);
/// // ...while the mean MSE of 0.5 gives 51.14 dB.
/// assert!((s.psnr_y_mse - 51.1411).abs() < 1e-3);
/// ```
#[derive(Debug, Clone, Default)]
pub struct QualityAccumulator {
    frames: usize,
    psnr: [f64; 3],
    psnr_yuv: f64,
    mse: [f64; 3],
    /// Sums of ssim, ms_ssim, psnr_hvs, psnr_hvs_y, ciede2000, vmaf.
    others: [f64; 6],
}

impl QualityAccumulator {
    /// Adds one frame.
    pub fn push(&mut self, q: &FrameQuality) {
        self.frames += 1;
        for (i, (p, m)) in [q.psnr.y, q.psnr.u, q.psnr.v]
            .into_iter()
            .zip(q.psnr.mse)
            .enumerate()
        {
            self.psnr[i] += p;
            self.mse[i] += m;
        }
        self.psnr_yuv += q.psnr.yuv();
        for (sum, v) in
            self.others
                .iter_mut()
                .zip([q.ssim, q.ms_ssim, q.psnr_hvs, q.psnr_hvs_y, q.ciede2000, q.vmaf])
        {
            *sum += v;
        }
    }

    /// Frames added so far.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// The sequence figures, or `None` before any frame was added.
    pub fn summary(&self) -> Option<SequenceQuality> {
        if self.frames == 0 {
            return None;
        }
        let n = self.frames as f64;
        Some(SequenceQuality {
            frames: self.frames,
            psnr_y: self.psnr[0] / n,
            psnr_u: self.psnr[1] / n,
            psnr_v: self.psnr[2] / n,
            psnr_yuv: self.psnr_yuv / n,
            psnr_y_mse: psnr_from_mse(self.mse[0] / n),
            psnr_u_mse: psnr_from_mse(self.mse[1] / n),
            psnr_v_mse: psnr_from_mse(self.mse[2] / n),
            ssim: self.others[0] / n,
            ms_ssim: self.others[1] / n,
            psnr_hvs: self.others[2] / n,
            psnr_hvs_y: self.others[3] / n,
            ciede2000: self.others[4] / n,
            vmaf: self.others[5] / n,
        })
    }
}
