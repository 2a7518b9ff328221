//! Per-frame and per-sequence statistics of an encode: rate, time and the
//! quality record ([`FrameQuality`], [`SequenceQuality`]) every report
//! reads.

use serde::Serialize;

use crate::metrics::{FrameQuality, QualityAccumulator, SequenceQuality};

/// What one frame cost and gave.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FrameStats {
    /// Frame number, from 0 (`frame` in the CSV and Python, as the
    /// analysis names it).
    #[serde(rename = "frame")]
    pub index: usize,
    /// `I` or `P` (`type`).
    #[serde(rename = "type")]
    pub frame_type: char,
    /// The frame's quantisation parameter.
    pub qp: u8,
    /// Bytes in the stream.
    pub bytes: usize,
    /// Framing, frame header, macroblock types, skip runs, intra modes.
    pub bits_header: u64,
    /// Vector differences and grid vectors.
    pub bits_motion: u64,
    /// Coded block patterns and levels.
    pub bits_residual: u64,
    /// The reconstruction's quality (SSIM as x264 and ffmpeg's `ssim`
    /// filter compute it; the metrics not asked for NaN; VMAF set after
    /// the encode by callers that measure it).
    #[serde(flatten)]
    pub quality: FrameQuality,
    /// Luma PSNR of the prediction before the residual, dB.
    pub prediction_psnr_y: f64,
    /// Macroblocks skipped.
    pub skip_mbs: usize,
    /// Macroblocks inter-coded with a residual or a vector.
    pub inter_mbs: usize,
    /// Macroblocks intra-coded.
    pub intra_mbs: usize,
    /// Motion estimation or flow time before the macroblock decision, ms
    /// (`block` frames search every reference inside the decision: only
    /// the previous frame's half-pel planes are counted here).
    pub me_ms: f64,
    /// Time to code the frame, ms (the quality measurements not
    /// included): from its start to its end, which on frame threads
    /// overlaps the frames beside it and holds the waits for their rows.
    pub total_ms: f64,
}

impl FrameStats {
    /// The CSV header of [`FrameStats::csv_row`].
    pub const CSV_HEADER: &'static str =
        "frame,type,qp,bytes,bits_header,bits_motion,bits_residual,psnr_y,psnr_u,psnr_v,\
ssim,prediction_psnr_y,skip_mbs,inter_mbs,intra_mbs,me_ms,total_ms,ms_ssim,psnr_hvs,ciede2000,vmaf";

    /// One CSV row.
    pub fn csv_row(&self) -> String {
        let q = &self.quality;
        format!(
            "{},{},{},{},{},{},{},{:.4},{:.4},{:.4},{:.6},{:.4},{},{},{},{:.3},{:.3}",
            self.index,
            self.frame_type,
            self.qp,
            self.bytes,
            self.bits_header,
            self.bits_motion,
            self.bits_residual,
            q.psnr.y,
            q.psnr.u,
            q.psnr.v,
            q.ssim,
            self.prediction_psnr_y,
            self.skip_mbs,
            self.inter_mbs,
            self.intra_mbs,
            self.me_ms,
            self.total_ms
        ) + &[(q.ms_ssim, 6), (q.psnr_hvs, 4), (q.ciede2000, 4), (q.vmaf, 4)]
            .iter()
            .map(|&(v, d)| {
                if v.is_nan() {
                    ",".to_string()
                } else {
                    format!(",{v:.d$}")
                }
            })
            .collect::<String>()
    }
}

/// A whole encode.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Summary {
    /// Stream size, bytes (sequence header and end marker included).
    pub bytes: u64,
    /// Bit rate at the sequence's frame rate, kbit/s.
    pub kbps: f64,
    /// The quality over the frames: means of the per-frame figures, and
    /// the PSNR of the mean MSE (ffmpeg's psnr summary, x264's "Global")
    /// from the frames' true MSE; its `frames` are the frames coded.
    #[serde(flatten)]
    pub quality: SequenceQuality,
    /// Header bits (the sequence header and end marker included).
    pub bits_header: u64,
    /// Motion bits.
    pub bits_motion: u64,
    /// Residual bits.
    pub bits_residual: u64,
    /// Coding time, ms (reading and writing files not included).
    pub encode_ms: f64,
    /// Of which motion estimation or flow before the macroblock decision,
    /// ms (as [`FrameStats::me_ms`]).
    pub me_ms: f64,
    /// Frames per second coded.
    pub fps: f64,
}

/// Adds frames up into a [`Summary`].
#[derive(Debug, Clone)]
pub struct SummaryBuilder {
    frame_rate: f64,
    s: Summary,
    quality: QualityAccumulator,
}

impl SummaryBuilder {
    /// At `frame_rate` frames per second, with `stream_bytes` outside the
    /// frames (sequence header, end marker).
    pub fn new(frame_rate: f64, stream_bytes: usize) -> SummaryBuilder {
        SummaryBuilder {
            frame_rate,
            s: Summary {
                bytes: stream_bytes as u64,
                kbps: 0.0,
                quality: SequenceQuality::unknown(0),
                bits_header: 8 * stream_bytes as u64,
                bits_motion: 0,
                bits_residual: 0,
                encode_ms: 0.0,
                me_ms: 0.0,
                fps: 0.0,
            },
            quality: QualityAccumulator::default(),
        }
    }

    /// Frames so far.
    pub fn frames(&self) -> usize {
        self.quality.frames()
    }

    /// Adds a frame.
    pub fn push(&mut self, f: &FrameStats) {
        let s = &mut self.s;
        s.bytes += f.bytes as u64;
        self.quality.push(&f.quality);
        s.bits_header += f.bits_header;
        s.bits_motion += f.bits_motion;
        s.bits_residual += f.bits_residual;
        s.encode_ms += f.total_ms;
        s.me_ms += f.me_ms;
    }

    /// The means and rates.
    pub fn finish(&self) -> Summary {
        let mut s = self.s;
        let n = self.frames().max(1) as f64;
        s.quality = self.quality.summary().unwrap_or(SequenceQuality::unknown(0));
        s.kbps = s.bytes as f64 * 8.0 / (n / self.frame_rate) / 1000.0;
        s.fps = if s.encode_ms > 0.0 {
            n / (s.encode_ms / 1000.0)
        } else {
            0.0
        };
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::FramePsnr;

    /// The MSE (peak 255) of a PSNR.
    fn mse_of(psnr: f64) -> f64 {
        255.0 * 255.0 / 10f64.powf(psnr / 10.0)
    }

    #[test]
    fn kbps_follows_the_frame_rate_and_means_are_per_frame() {
        let mut b = SummaryBuilder::new(25.0, 24);
        let f = FrameStats {
            index: 0,
            frame_type: 'I',
            qp: 28,
            bytes: 988,
            bits_header: 100,
            bits_motion: 0,
            bits_residual: 7708,
            quality: FrameQuality {
                psnr: FramePsnr::from_mse([mse_of(40.0), mse_of(42.0), mse_of(43.0)]),
                ssim: 0.9,
                ms_ssim: 0.95,
                psnr_hvs: f64::NAN,
                psnr_hvs_y: f64::NAN,
                ciede2000: f64::NAN,
                vmaf: f64::NAN,
            },
            prediction_psnr_y: 20.0,
            skip_mbs: 0,
            inter_mbs: 0,
            intra_mbs: 99,
            me_ms: 0.0,
            total_ms: 10.0,
        };
        b.push(&f);
        let mut g = f;
        g.quality.psnr = FramePsnr::from_mse([mse_of(30.0), mse_of(42.0), mse_of(43.0)]);
        b.push(&g);
        let s = b.finish();
        // 2000 bytes over 2 frames at 25 fps = 16000 bits in 0.08 s.
        assert_eq!(s.bytes, 2000);
        assert!((s.kbps - 200.0).abs() < 1e-9);
        assert!((s.quality.psnr_y - 35.0).abs() < 1e-9);
        // The PSNR of the mean MSE, from the frames' own MSE.
        let mean_mse = (mse_of(40.0) + mse_of(30.0)) / 2.0;
        assert!((s.quality.psnr_y_mse - 10.0 * (255.0f64 * 255.0 / mean_mse).log10()).abs() < 1e-9);
        assert_eq!(s.bits_header, 24 * 8 + 200);
        assert!((s.fps - 100.0).abs() < 1e-9);
        // Measured metrics are averaged; the others stay NaN and their
        // CSV cells empty.
        assert!((s.quality.ms_ssim - 0.95).abs() < 1e-12 && s.quality.psnr_hvs.is_nan());
        assert!(f.csv_row().ends_with(",0.950000,,,"), "{}", f.csv_row());
        assert_eq!(
            f.csv_row().split(',').count(),
            FrameStats::CSV_HEADER.split(',').count()
        );
    }
}
