//! Per-frame and per-sequence statistics of an encode.

use serde::Serialize;

use crate::metrics::psnr_from_mse;

/// What one frame cost and gave.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FrameStats {
    /// Frame number, from 0.
    pub index: usize,
    /// `I` or `P`.
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
    /// PSNR of the reconstruction, dB.
    pub psnr_y: f64,
    /// Cb PSNR, dB.
    pub psnr_u: f64,
    /// Cr PSNR, dB.
    pub psnr_v: f64,
    /// Luma SSIM as x264 and ffmpeg's `ssim` filter compute it
    /// ([`ssim_8x8`](crate::metrics::ssim_8x8)); NaN when not measured.
    pub ssim: f64,
    /// Luma MS-SSIM (NaN when not measured, as the next three).
    pub ms_ssim: f64,
    /// PSNR-HVS of the planes combined, dB.
    pub psnr_hvs: f64,
    /// CIEDE2000, dB.
    pub ciede2000: f64,
    /// VMAF (set after the encode by callers that measure it).
    pub vmaf: f64,
    /// Luma PSNR of the prediction before the residual, dB.
    pub prediction_psnr_y: f64,
    /// Macroblocks skipped.
    pub skip_mbs: usize,
    /// Macroblocks inter-coded with a residual or a vector.
    pub inter_mbs: usize,
    /// Macroblocks intra-coded.
    pub intra_mbs: usize,
    /// Motion estimation or flow time, ms.
    pub me_ms: f64,
    /// Time to code the frame, ms (the quality measurements not included).
    pub total_ms: f64,
}

impl FrameStats {
    /// The CSV header of [`FrameStats::csv_row`].
    pub const CSV_HEADER: &'static str =
        "frame,type,qp,bytes,bits_header,bits_motion,bits_residual,psnr_y,psnr_u,psnr_v,\
ssim,prediction_psnr_y,skip_mbs,inter_mbs,intra_mbs,me_ms,total_ms,ms_ssim,psnr_hvs,ciede2000,vmaf";

    /// One CSV row.
    pub fn csv_row(&self) -> String {
        format!(
            "{},{},{},{},{},{},{},{:.4},{:.4},{:.4},{:.6},{:.4},{},{},{},{:.3},{:.3}",
            self.index,
            self.frame_type,
            self.qp,
            self.bytes,
            self.bits_header,
            self.bits_motion,
            self.bits_residual,
            self.psnr_y,
            self.psnr_u,
            self.psnr_v,
            self.ssim,
            self.prediction_psnr_y,
            self.skip_mbs,
            self.inter_mbs,
            self.intra_mbs,
            self.me_ms,
            self.total_ms
        ) + &[
            (self.ms_ssim, 6),
            (self.psnr_hvs, 4),
            (self.ciede2000, 4),
            (self.vmaf, 4),
        ]
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
    /// Frames coded.
    pub frames: usize,
    /// Stream size, bytes (sequence header and end marker included).
    pub bytes: u64,
    /// Bit rate at the sequence's frame rate, kbit/s.
    pub kbps: f64,
    /// Mean over frames of luma PSNR, dB (as ffmpeg's psnr stats and HM).
    pub psnr_y: f64,
    /// Luma PSNR of the mean over frames of the MSE, dB (ffmpeg's psnr
    /// summary, x264's "Global"): a black or repeated frame, coded
    /// exactly, does not lift it as it lifts the mean of frames.
    pub psnr_y_mse: f64,
    /// Mean Cb PSNR, dB.
    pub psnr_u: f64,
    /// Mean Cr PSNR, dB.
    pub psnr_v: f64,
    /// Mean over frames of luma SSIM as x264 and ffmpeg compute it (NaN
    /// when not measured, as the next four).
    pub ssim: f64,
    /// Mean over frames of luma MS-SSIM.
    pub ms_ssim: f64,
    /// Mean over frames of PSNR-HVS, dB.
    pub psnr_hvs: f64,
    /// Mean over frames of CIEDE2000, dB.
    pub ciede2000: f64,
    /// Mean over frames of VMAF.
    pub vmaf: f64,
    /// Header bits (the sequence header and end marker included).
    pub bits_header: u64,
    /// Motion bits.
    pub bits_motion: u64,
    /// Residual bits.
    pub bits_residual: u64,
    /// Coding time, ms (reading and writing files not included).
    pub encode_ms: f64,
    /// Of which motion estimation or flow, ms.
    pub me_ms: f64,
    /// Frames per second coded.
    pub fps: f64,
}

/// The MSE (peak 255) a PSNR stands for.
fn mse_from_psnr(psnr: f64) -> f64 {
    255.0 * 255.0 / 10f64.powf(psnr / 10.0)
}

/// Adds frames up into a [`Summary`].
#[derive(Debug, Clone)]
pub struct SummaryBuilder {
    frame_rate: f64,
    s: Summary,
}

impl SummaryBuilder {
    /// At `frame_rate` frames per second, with `stream_bytes` outside the
    /// frames (sequence header, end marker).
    pub fn new(frame_rate: f64, stream_bytes: usize) -> SummaryBuilder {
        SummaryBuilder {
            frame_rate,
            s: Summary {
                frames: 0,
                bytes: stream_bytes as u64,
                kbps: 0.0,
                psnr_y: 0.0,
                psnr_y_mse: 0.0,
                psnr_u: 0.0,
                psnr_v: 0.0,
                ssim: 0.0,
                ms_ssim: 0.0,
                psnr_hvs: 0.0,
                ciede2000: 0.0,
                vmaf: 0.0,
                bits_header: 8 * stream_bytes as u64,
                bits_motion: 0,
                bits_residual: 0,
                encode_ms: 0.0,
                me_ms: 0.0,
                fps: 0.0,
            },
        }
    }

    /// Frames so far.
    pub fn frames(&self) -> usize {
        self.s.frames
    }

    /// Adds a frame.
    pub fn push(&mut self, f: &FrameStats) {
        let s = &mut self.s;
        s.frames += 1;
        s.bytes += f.bytes as u64;
        s.psnr_y += f.psnr_y;
        // Summed as MSE here; made a PSNR in `finish`.
        s.psnr_y_mse += mse_from_psnr(f.psnr_y);
        s.psnr_u += f.psnr_u;
        s.psnr_v += f.psnr_v;
        s.ssim += f.ssim;
        s.ms_ssim += f.ms_ssim;
        s.psnr_hvs += f.psnr_hvs;
        s.ciede2000 += f.ciede2000;
        s.vmaf += f.vmaf;
        s.bits_header += f.bits_header;
        s.bits_motion += f.bits_motion;
        s.bits_residual += f.bits_residual;
        s.encode_ms += f.total_ms;
        s.me_ms += f.me_ms;
    }

    /// The means and rates.
    pub fn finish(&self) -> Summary {
        let mut s = self.s;
        let n = s.frames.max(1) as f64;
        s.psnr_y /= n;
        s.psnr_y_mse = psnr_from_mse(s.psnr_y_mse / n);
        s.psnr_u /= n;
        s.psnr_v /= n;
        s.ssim /= n;
        s.ms_ssim /= n;
        s.psnr_hvs /= n;
        s.ciede2000 /= n;
        s.vmaf /= n;
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
            psnr_y: 40.0,
            psnr_u: 42.0,
            psnr_v: 43.0,
            ssim: 0.9,
            ms_ssim: 0.95,
            psnr_hvs: f64::NAN,
            ciede2000: f64::NAN,
            vmaf: f64::NAN,
            prediction_psnr_y: 20.0,
            skip_mbs: 0,
            inter_mbs: 0,
            intra_mbs: 99,
            me_ms: 0.0,
            total_ms: 10.0,
        };
        b.push(&f);
        b.push(&FrameStats { psnr_y: 30.0, ..f });
        let s = b.finish();
        // 2000 bytes over 2 frames at 25 fps = 16000 bits in 0.08 s.
        assert_eq!(s.bytes, 2000);
        assert!((s.kbps - 200.0).abs() < 1e-9);
        assert!((s.psnr_y - 35.0).abs() < 1e-12);
        assert_eq!(s.bits_header, 24 * 8 + 200);
        assert!((s.fps - 100.0).abs() < 1e-9);
        // Measured metrics are averaged; the others stay NaN and their
        // CSV cells empty.
        assert!((s.ms_ssim - 0.95).abs() < 1e-12 && s.psnr_hvs.is_nan());
        assert!(f.csv_row().ends_with(",0.950000,,,"), "{}", f.csv_row());
        assert_eq!(
            f.csv_row().split(',').count(),
            FrameStats::CSV_HEADER.split(',').count()
        );
    }
}
