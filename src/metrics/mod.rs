//! Quality and error measures: PSNR and SSIM of pictures, errors of flow
//! fields against ground truth, and per-sequence summaries.

mod flow_error;
mod psnr;
mod ssim;
mod ssim_8x8;

pub use flow_error::{flow_errors, FlowErrors};
pub use psnr::{frame_psnr, mse, psnr, psnr_from_mse, squared_difference_sum, sse, FramePsnr, PSNR_CAP_DB};
pub use ssim::ssim;
pub use ssim_8x8::ssim_8x8;

use serde::Serialize;

use crate::codec::Frame;

/// The quality of one decoded or predicted frame against its source.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FrameQuality {
    /// PSNR of each plane.
    pub psnr: FramePsnr,
    /// SSIM of the luma plane.
    pub ssim: f64,
}

impl FrameQuality {
    /// PSNR of every plane and luma SSIM of `test` against `reference`.
    pub fn measure(reference: &Frame, test: &Frame) -> FrameQuality {
        FrameQuality {
            psnr: frame_psnr(reference, test),
            ssim: ssim(reference.y(), test.y()),
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
    /// Mean over frames of luma SSIM.
    pub ssim: f64,
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
    ssim: f64,
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
        self.ssim += q.ssim;
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
            ssim: self.ssim / n,
        })
    }
}
