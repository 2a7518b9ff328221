//! Reconstruction (normative): prediction of each macroblock, plus its
//! dequantised, inverse-transformed residual. The decoder and the encoder
//! both call these functions, which is what makes the encoder's
//! reconstruction equal the decoder's output byte for byte.
//!
//! Pictures are reconstructed at the coded size (a whole number of
//! macroblocks); [`crop`] gives the visible picture.

use crate::deblock::{deblock_frame, DeblockStrength, MbEdgeInfo};
use crate::dsp::itx::itx;
use crate::interp::{predict_chroma, predict_luma, LumaFilter};
use crate::intra::{self, Neighbours};
use crate::intra4x4::{self, Intra4x4Mode, LumaIntra};
use crate::intra8x8;
use crate::mv::Mv;
use crate::obmc::{self, Neighbourhood};
use crate::partition::{MbVectors, RefMv};
use crate::picture::{Frame, PictureError, Plane};
use crate::residual::MbResidual;
use crate::syntax::{mb_vectors, CodedMb, FrameSyntax, FrameType, MbKind, MotionTool, SequenceHeader, MB};
use crate::transform::{dequantize_chroma_dc, dequantize_luma_dc, Block4};
use crate::transform8x8::Block8;
use crate::warp::warp_frame;

pub use crate::transform::chroma_qp;

/// The samples of one macroblock, a prediction or a reconstruction: 16x16
/// luma, two 8x8 chroma blocks.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MbSamples {
    /// Luma, row-major.
    pub luma: [u8; 256],
    /// Cb and Cr, row-major.
    pub chroma: [[u8; 64]; 2],
}

impl Default for MbSamples {
    fn default() -> MbSamples {
        MbSamples {
            luma: [0; 256],
            chroma: [[0; 64]; 2],
        }
    }
}

/// What inter prediction of a frame needs.
#[derive(Debug, Clone, Copy)]
pub struct InterContext<'a> {
    /// The frame's references (coded size), the previous frame first
    /// (FORMAT.md section 4).
    pub references: &'a [&'a Frame],
    /// The frame's motion tool.
    pub tool: MotionTool,
    /// The luma interpolation filter of block frames.
    pub luma_filter: LumaFilter,
    /// Every macroblock's vectors (`None` for intra), for OBMC.
    pub vectors: &'a [MbVectors],
    /// The whole reference warped by the grid, for grid frames.
    pub warped: Option<&'a Frame>,
    /// Macroblocks per row.
    pub mb_cols: usize,
}

/// Intra prediction of macroblock (mb_x, mb_y) from the reconstruction
/// so far. The modes must be allowed there
/// ([`crate::syntax::intra_mode_allowed`]); panics otherwise.
pub fn predict_intra(
    recon: &Frame,
    mb_x: usize,
    mb_y: usize,
    luma: intra::IntraMode,
    chroma: intra::IntraMode,
) -> MbSamples {
    let mut pred = MbSamples::default();
    predict_intra_plane(recon, 0, mb_x, mb_y, luma, &mut pred.luma);
    predict_intra_plane(recon, 1, mb_x, mb_y, chroma, &mut pred.chroma[0]);
    predict_intra_plane(recon, 2, mb_x, mb_y, chroma, &mut pred.chroma[1]);
    pred
}

/// The prediction of an intra macroblock whose luma is coded in 4x4
/// blocks (each predicted from the reconstruction of those before it, so
/// the macroblock's `residual` at `qp` takes part), chroma in `chroma`.
pub fn predict_intra4x4(
    recon: &Frame,
    (mb_x, mb_y): (usize, usize),
    modes: &[Intra4x4Mode; 16],
    chroma: intra::IntraMode,
    residual: &MbResidual,
    qp: u8,
) -> MbSamples {
    let luma = intra4x4::predict_mb(
        recon.y(),
        (mb_x, mb_y),
        modes,
        &residual.luma,
        |levels, own, at| add_block(levels, qp, own, MB, at),
    );
    with_intra_chroma(recon, (mb_x, mb_y), luma, chroma)
}

/// A macroblock's prediction: `luma`, and chroma predicted in `chroma`.
fn with_intra_chroma(
    recon: &Frame,
    (mb_x, mb_y): (usize, usize),
    luma: [u8; 256],
    chroma: intra::IntraMode,
) -> MbSamples {
    let mut pred = MbSamples {
        luma,
        ..MbSamples::default()
    };
    predict_intra_plane(recon, 1, mb_x, mb_y, chroma, &mut pred.chroma[0]);
    predict_intra_plane(recon, 2, mb_x, mb_y, chroma, &mut pred.chroma[1]);
    pred
}

/// The prediction of an intra macroblock whose luma is coded in 8x8
/// blocks (each predicted from the reconstruction of those before it, so
/// the macroblock's `residual` at `qp` takes part), chroma in `chroma`.
pub fn predict_intra8x8(
    recon: &Frame,
    (mb_x, mb_y): (usize, usize),
    modes: &[Intra4x4Mode; 4],
    chroma: intra::IntraMode,
    residual: &MbResidual,
    qp: u8,
) -> MbSamples {
    let luma = intra8x8::predict_mb(recon.y(), (mb_x, mb_y), modes, |q, own| {
        if let Some(b8) = &residual.luma8 {
            add_block8(&b8[q], qp, own, ((q % 2) * 8, (q / 2) * 8));
        }
    });
    with_intra_chroma(recon, (mb_x, mb_y), luma, chroma)
}

/// One plane of [`predict_intra`] (0 luma, 16x16; 1 and 2 chroma, 8x8),
/// into `out` (row stride the block's side).
pub fn predict_intra_plane(
    recon: &Frame,
    plane: usize,
    mb_x: usize,
    mb_y: usize,
    mode: intra::IntraMode,
    out: &mut [u8],
) {
    IntraEdges::of(recon, plane, mb_x, mb_y).predict(mode, out);
}

/// The reconstructed samples one plane of a macroblock is intra-predicted
/// from, gathered once: what an encoder trying every mode needs.
///
/// ```
/// use mocomp_codec::intra::IntraMode;
/// use mocomp_codec::recon::{predict_intra_plane, IntraEdges};
/// use mocomp_codec::Frame;
/// let recon = Frame::filled(32, 32, 90, 128, 128).unwrap();
/// let edges = IntraEdges::of(&recon, 0, 1, 1);
/// let (mut a, mut b) = ([0u8; 256], [0u8; 256]);
/// edges.predict(IntraMode::Plane, &mut a);
/// predict_intra_plane(&recon, 0, 1, 1, IntraMode::Plane, &mut b);
/// assert_eq!(a, b);
/// ```
#[derive(Debug, Clone)]
pub struct IntraEdges {
    size: usize,
    top: Option<[u8; MB]>,
    left: Option<[u8; MB]>,
    top_left: Option<u8>,
    at: (usize, usize),
}

impl IntraEdges {
    /// The edges of plane `plane` (0 luma, 1 and 2 chroma) of macroblock
    /// (mb_x, mb_y) in the reconstruction so far.
    pub fn of(recon: &Frame, plane: usize, mb_x: usize, mb_y: usize) -> IntraEdges {
        let size = if plane == 0 { MB } else { MB / 2 };
        let plane = recon.plane(plane);
        let (x0, y0) = (mb_x * size, mb_y * size);
        let top = (mb_y > 0).then(|| {
            let mut t = [0u8; MB];
            t[..size].copy_from_slice(&plane.row(y0 - 1)[x0..x0 + size]);
            t
        });
        let left = (mb_x > 0).then(|| {
            let mut l = [0u8; MB];
            for (r, v) in l[..size].iter_mut().enumerate() {
                *v = plane.get(x0 - 1, y0 + r);
            }
            l
        });
        let top_left = (mb_x > 0 && mb_y > 0).then(|| plane.get(x0 - 1, y0 - 1));
        IntraEdges {
            size,
            top,
            left,
            top_left,
            at: (mb_x, mb_y),
        }
    }

    /// The row above (its first `size` samples), if the block has one.
    pub fn top(&self) -> Option<&[u8; MB]> {
        self.top.as_ref()
    }

    /// The column to the left (its first `size` samples), if any.
    pub fn left(&self) -> Option<&[u8; MB]> {
        self.left.as_ref()
    }

    /// The DC mode's value.
    pub fn dc(&self) -> u8 {
        crate::dsp::ipred::dc_value(self.size, &self.neighbours())
    }

    fn neighbours(&self) -> Neighbours<'_> {
        Neighbours {
            top: self.top.as_ref().map(|t| &t[..self.size]),
            left: self.left.as_ref().map(|l| &l[..self.size]),
            top_left: self.top_left,
        }
    }

    /// The prediction in `mode` into `out` (row stride the block's side).
    /// The mode must be allowed here
    /// ([`crate::syntax::intra_mode_allowed`]); panics otherwise.
    pub fn predict(&self, mode: intra::IntraMode, out: &mut [u8]) {
        let done = intra::predict(mode, self.size, &self.neighbours(), out, self.size);
        assert!(
            done.is_ok(),
            "intra mode {mode:?} not allowed at macroblock {:?}",
            self.at
        );
    }
}

/// Inter prediction of macroblock (mb_x, mb_y) with motion `mv` (ignored
/// in grid frames).
pub fn predict_inter(ctx: &InterContext<'_>, mb_x: usize, mb_y: usize, mv: RefMv) -> MbSamples {
    predict_inter_blocks(ctx, mb_x, mb_y, &[mv; 4])
}

/// [`predict_inter`] into `pred` (every sample written): an encoder
/// predicting into a record it keeps saves the copy of a returned one.
pub fn predict_inter_into(ctx: &InterContext<'_>, mb_x: usize, mb_y: usize, mv: RefMv, pred: &mut MbSamples) {
    predict_inter_blocks_into(ctx, mb_x, mb_y, &[mv; 4], pred)
}

/// Block motion compensation of the `w x h` luma rectangle at (bx, by) in
/// macroblock (mb_x, mb_y), and of its chroma, with vector `mv`, into the
/// same place of `pred`.
fn predict_rect(
    (reference, filter): (&Frame, LumaFilter),
    (mb_x, mb_y): (usize, usize),
    (bx, by, w, h): (usize, usize, usize, usize),
    mv: Mv,
    pred: &mut MbSamples,
) {
    let (x, y) = ((mb_x * MB + bx) as isize, (mb_y * MB + by) as isize);
    predict_luma(
        filter,
        reference.y(),
        x,
        y,
        mv.x,
        mv.y,
        w,
        h,
        &mut pred.luma[by * MB + bx..],
        MB,
    );
    let (cx, cy, c) = (bx / 2, by / 2, MB / 2);
    for p in 0..2 {
        predict_chroma(
            reference.plane(p + 1),
            x / 2,
            y / 2,
            mv.x,
            mv.y,
            w / 2,
            h / 2,
            &mut pred.chroma[p][cy * c + cx..],
            c,
        );
    }
}

/// Inter prediction of macroblock (mb_x, mb_y) whose 8x8 blocks have the
/// motion `mvs` (raster order; block frames: each block predicted with
/// its own; OBMC frames: the first for the whole macroblock, from
/// reference 0; grid frames: ignored). Panics on a reference index past
/// the context's references.
pub fn predict_inter_blocks(ctx: &InterContext<'_>, mb_x: usize, mb_y: usize, mvs: &[RefMv; 4]) -> MbSamples {
    let mut pred = MbSamples::default();
    predict_inter_blocks_into(ctx, mb_x, mb_y, mvs, &mut pred);
    pred
}

/// [`predict_inter_blocks`] into `pred` (every sample written).
pub fn predict_inter_blocks_into(
    ctx: &InterContext<'_>,
    mb_x: usize,
    mb_y: usize,
    mvs: &[RefMv; 4],
    pred: &mut MbSamples,
) {
    let (x, y) = ((mb_x * MB) as isize, (mb_y * MB) as isize);
    let (cx, cy) = (x / 2, y / 2);
    let r = ctx.references[0];
    let mv = mvs[0].mv;
    match ctx.tool {
        MotionTool::Block => {
            // Samples depend only on their own vector: equal blocks are
            // predicted together, which is faster and gives the same.
            let rects: &[(usize, usize, usize, usize, usize)] = if mvs.iter().all(|&m| m == mvs[0]) {
                &[(0, 0, 0, 16, 16)]
            } else if mvs[0] == mvs[1] && mvs[2] == mvs[3] {
                &[(0, 0, 0, 16, 8), (2, 0, 8, 16, 8)]
            } else if mvs[0] == mvs[2] && mvs[1] == mvs[3] {
                &[(0, 0, 0, 8, 16), (1, 8, 0, 8, 16)]
            } else {
                &[(0, 0, 0, 8, 8), (1, 8, 0, 8, 8), (2, 0, 8, 8, 8), (3, 8, 8, 8, 8)]
            };
            for &(k, bx, by, w, h) in rects {
                let m = mvs[k];
                let reference = ctx.references[usize::from(m.ref_idx)];
                predict_rect(
                    (reference, ctx.luma_filter),
                    (mb_x, mb_y),
                    (bx, by, w, h),
                    m.mv,
                    pred,
                );
            }
        }
        MotionTool::Obmc => {
            let rows = ctx.vectors.len() / ctx.mb_cols;
            let mut around: Neighbourhood = [[None; 3]; 3];
            for (dy, row) in around.iter_mut().enumerate() {
                for (dx, slot) in row.iter_mut().enumerate() {
                    let (nx, ny) = (mb_x as isize + dx as isize - 1, mb_y as isize + dy as isize - 1);
                    if nx >= 0 && ny >= 0 && (nx as usize) < ctx.mb_cols && (ny as usize) < rows {
                        *slot = ctx.vectors[ny as usize * ctx.mb_cols + nx as usize][0].map(|m| m.mv);
                    }
                }
            }
            obmc::predict_block(r.y(), false, x, y, MB, mv, &around, &mut pred.luma, MB);
            for p in 0..2 {
                obmc::predict_block(
                    r.plane(p + 1),
                    true,
                    cx,
                    cy,
                    MB / 2,
                    mv,
                    &around,
                    &mut pred.chroma[p],
                    MB / 2,
                );
            }
        }
        MotionTool::Grid(_) => {
            let warped = ctx.warped.unwrap_or(r);
            let copy = |plane: &Plane, size: usize, out: &mut [u8]| {
                let (x0, y0) = (mb_x * size, mb_y * size);
                for row in 0..size {
                    out[row * size..(row + 1) * size].copy_from_slice(&plane.row(y0 + row)[x0..x0 + size]);
                }
            };
            copy(warped.y(), MB, &mut pred.luma);
            copy(warped.u(), MB / 2, &mut pred.chroma[0]);
            copy(warped.v(), MB / 2, &mut pred.chroma[1]);
        }
    }
}

/// Adds one 4x4 block of levels, dequantised at `qp`, to the prediction
/// held in `out` (a `stride`-wide block) at (bx, by), clipping; a block
/// without levels leaves it as it is. By the transform kernels of the CPU
/// level in force ([`crate::dsp::itx`]).
#[inline]
pub fn add_block(levels: &Block4, qp: u8, out: &mut [u8], stride: usize, at: (usize, usize)) {
    (itx().add_4x4)(levels, qp, out, stride, at)
}

/// Adds one 8x8 block of levels, dequantised at `qp`, to the macroblock's
/// luma prediction `out` at sample (x, y), clipping.
#[inline]
pub fn add_block8(levels: &Block8, qp: u8, out: &mut [u8; 256], at: (usize, usize)) {
    (itx().add_8x8)(levels, qp, out, at)
}

/// Adds a macroblock's four 8x8 luma blocks of levels (quadrant `qy * 2 +
/// qx`), dequantised at `qp`, to its luma prediction `out`, clipping.
pub fn add_luma8(blocks: &[Block8; 4], qp: u8, out: &mut [u8; 256]) {
    for (q, levels) in blocks.iter().enumerate() {
        add_block8(levels, qp, out, ((q % 2) * 8, (q / 2) * 8));
    }
}

/// The samples macroblock coding gives: `pred` plus `residual` dequantised
/// at `qp` (chroma at [`chroma_qp`]), in a macroblock-shaped block.
#[inline]
pub fn reconstruct_samples(pred: &MbSamples, residual: &MbResidual, qp: u8) -> MbSamples {
    let mut out = pred.clone();
    add_residual(&mut out, residual, qp);
    out
}

/// [`reconstruct_samples`] in place: `residual` dequantised at `qp`
/// added to the prediction `out` (an encoder's record, not copied out of
/// a returned one).
pub fn add_residual(out: &mut MbSamples, residual: &MbResidual, qp: u8) {
    match &residual.luma8 {
        Some(b8) => add_luma8(b8, qp, &mut out.luma),
        // Only intra 16x16 macroblocks have luma DC levels apart.
        None if residual.luma_dc != [0; 16] => {
            add_luma_with_dc(&residual.luma, &residual.luma_dc, qp, &mut out.luma)
        }
        None => {
            for (i, levels) in residual.luma.iter().enumerate() {
                add_block(levels, qp, &mut out.luma, MB, ((i % 4) * 4, (i / 4) * 4));
            }
        }
    }
    let cqp = chroma_qp(qp);
    for (p, plane) in out.chroma.iter_mut().enumerate() {
        add_chroma_plane(&residual.chroma[p], cqp, plane);
    }
}

/// Adds a chroma plane's four blocks of levels to its prediction `out`
/// (8x8), clipping: each block's position (0, 0) holds one of the plane's
/// DC levels ([`dequantize_chroma_dc`]), the rest its AC levels
/// (FORMAT.md section 10.1).
pub fn add_chroma_plane(blocks: &[Block4; 4], qp: u8, out: &mut [u8; 64]) {
    // Most planes have no level at all.
    if blocks.as_flattened().as_flattened().iter().all(|&v| v == 0) {
        return;
    }
    let levels = blocks.each_ref().map(|b| b[0][0]);
    let dc = if levels == [0; 4] {
        levels
    } else {
        dequantize_chroma_dc(levels, qp)
    };
    add_blocks_with_dc(blocks, &dc, qp, out, 2);
}

/// Adds an intra 16x16 macroblock's luma to its prediction `out`,
/// clipping: its sixteen blocks' AC levels (`blocks`, position 0 unused)
/// and their DC coefficients from its luma DC levels `dc_levels`
/// ([`dequantize_luma_dc`]; FORMAT.md section 10.1).
pub fn add_luma_with_dc(blocks: &[Block4; 16], dc_levels: &[i32; 16], qp: u8, out: &mut [u8; 256]) {
    let dc = if *dc_levels == [0; 16] {
        [0; 16]
    } else {
        dequantize_luma_dc(*dc_levels, qp)
    };
    add_blocks_with_dc(blocks, &dc, qp, out, 4);
}

/// Adds 4x4 blocks (`per_row` a row, filling `out` of that many blocks
/// across) to `out`: each block's AC levels (its position 0 not read),
/// dequantised at `qp`, with its dequantised DC coefficient `dc[k]`.
fn add_blocks_with_dc(blocks: &[Block4], dc: &[i32], qp: u8, out: &mut [u8], per_row: usize) {
    let stride = 4 * per_row;
    for (k, levels) in blocks.iter().enumerate() {
        let mut ac = *levels;
        ac[0][0] = 0;
        let at = ((k % per_row) * 4, (k / per_row) * 4);
        match (ac.as_flattened().iter().any(|&v| v != 0), dc[k]) {
            (false, 0) => {}
            // The inverse transform of a DC coefficient alone is that
            // coefficient in every place.
            (false, d) => {
                let add = (d + 32) >> 6;
                for y in 0..4 {
                    for v in &mut out[(at.1 + y) * stride + at.0..][..4] {
                        *v = (i32::from(*v) + add).clamp(0, 255) as u8;
                    }
                }
            }
            (true, 0) => add_block(&ac, qp, out, stride, at),
            (true, d) => (itx().add_4x4_dc)(&ac, d, qp, out, stride, at),
        }
    }
}

/// Writes macroblock-shaped `samples` to macroblock (mb_x, mb_y) of `recon`.
/// Borders are not extended.
pub fn write_mb(samples: &MbSamples, recon: &mut Frame, mb_x: usize, mb_y: usize) {
    let (x0, y0) = (mb_x * MB, mb_y * MB);
    recon.plane_mut(0).write_block::<MB>(x0, y0, &samples.luma);
    for p in 0..2 {
        recon
            .plane_mut(p + 1)
            .write_block::<8>(x0 / 2, y0 / 2, &samples.chroma[p]);
    }
}

/// Writes macroblock (mb_x, mb_y) of `recon`: `pred` plus `residual`
/// dequantised at `qp` (chroma at [`chroma_qp`]). Borders are not extended.
pub fn reconstruct_mb(
    pred: &MbSamples,
    residual: &MbResidual,
    qp: u8,
    recon: &mut Frame,
    mb_x: usize,
    mb_y: usize,
) {
    write_mb(&reconstruct_samples(pred, residual, qp), recon, mb_x, mb_y);
}

/// The vectors of every macroblock of a frame (`None` for intra).
pub fn frame_vectors(seq: &SequenceHeader, frame: &FrameSyntax) -> Vec<MbVectors> {
    let cols = seq.mb_cols();
    let mut vectors = Vec::with_capacity(frame.mbs.len());
    for (i, mb) in frame.mbs.iter().enumerate() {
        let v = mb_vectors(&mb.kind, &vectors, i % cols, i / cols, cols);
        vectors.push(v);
    }
    vectors
}

/// Reconstructs a whole frame at the coded size, borders extended. P frames
/// need their references, the previous frame first (at least the
/// header's `refs` of them; panics with fewer, the decoder checks first).
pub fn reconstruct_frame(
    seq: &SequenceHeader,
    frame: &FrameSyntax,
    references: &[Frame],
) -> Result<Frame, PictureError> {
    let (cols, w, h) = (seq.mb_cols(), seq.coded_width(), seq.coded_height());
    let mut recon = Frame::new(w, h)?;
    let header = &frame.header;
    let weighted = match references.first() {
        Some(r) if header.weights.any() => {
            let mut out = r.clone();
            header.weights.apply_into(r, &mut out);
            Some(out)
        }
        _ => None,
    };
    // Weights apply to reference 0 alone (FORMAT.md section 12).
    let list: Vec<&Frame> = weighted
        .iter()
        .chain(references.iter().skip(usize::from(weighted.is_some())))
        .take(usize::from(header.refs))
        .collect();
    let reference = list.first().copied();
    assert!(
        header.frame_type == FrameType::Intra || list.len() == usize::from(header.refs),
        "a P frame needs its references"
    );
    let vectors = frame_vectors(seq, frame);
    let warped = match (&frame.grid, reference) {
        (Some(grid), Some(r)) => {
            let mut out = Frame::new(w, h)?;
            warp_frame(r, grid, &mut out);
            Some(out)
        }
        _ => None,
    };
    let inter = reference.map(|_| InterContext {
        references: &list,
        tool: header.tool,
        luma_filter: header.luma_filter,
        vectors: &vectors,
        warped: warped.as_ref(),
        mb_cols: cols,
    });
    for (i, mb) in frame.mbs.iter().enumerate() {
        let (mb_x, mb_y) = (i % cols, i / cols);
        let pred = predict_mb(mb, (mb_x, mb_y), &recon, inter.as_ref(), header.qp);
        reconstruct_mb(&pred, mb.residual(), header.qp, &mut recon, mb_x, mb_y);
    }
    if header.deblock {
        deblock_frame(
            &mut recon,
            &MbEdgeInfo::of_frame(frame, &vectors),
            DeblockStrength::of(header),
        );
    }
    recon.extend_borders();
    Ok(recon)
}

/// Macroblock (mb_x, mb_y)'s prediction as [`reconstruct_frame`] makes
/// it: intra from `recon` (the macroblocks before it reconstructed), inter
/// from `inter` (none in an I frame, where every macroblock is intra).
fn predict_mb(
    mb: &CodedMb,
    (mb_x, mb_y): (usize, usize),
    recon: &Frame,
    inter: Option<&InterContext<'_>>,
    qp: u8,
) -> MbSamples {
    match (mb.kind, inter) {
        (
            MbKind::Intra {
                luma: LumaIntra::Whole(luma),
                chroma,
            },
            _,
        ) => predict_intra(recon, mb_x, mb_y, luma, chroma),
        (
            MbKind::Intra {
                luma: LumaIntra::Blocks(modes),
                chroma,
            },
            _,
        ) => predict_intra4x4(recon, (mb_x, mb_y), &modes, chroma, mb.residual(), qp),
        (
            MbKind::Intra {
                luma: LumaIntra::Blocks8(modes),
                chroma,
            },
            _,
        ) => predict_intra8x8(recon, (mb_x, mb_y), &modes, chroma, mb.residual(), qp),
        (_, Some(ctx)) => {
            let i = mb_y * ctx.mb_cols + mb_x;
            predict_inter_blocks(ctx, mb_x, mb_y, &ctx.vectors[i].map(Option::unwrap_or_default))
        }
        (_, None) => MbSamples::default(),
    }
}

/// A coded-size frame's visible `width x height` part.
pub fn crop(frame: &Frame, width: usize, height: usize) -> Result<Frame, PictureError> {
    crop_reusing(frame, width, height, None)
}

/// Whether `f` is a frame [`crop`] gives at `width x height`: its size and
/// borders.
pub fn holds_crop(f: &Frame, width: usize, height: usize) -> bool {
    (f.width(), f.height()) == (width, height)
        && f.y().pad() == Plane::DEFAULT_PAD
        && f.plane(1).pad() == Plane::DEFAULT_PAD.div_ceil(2)
}

/// The top-left part of `src` the size of `dst`, into `dst`, its border
/// extended: one plane of [`crop`] (planes may go to several threads).
pub fn crop_plane_into(src: &Plane, dst: &mut Plane) {
    let w = dst.width();
    for r in 0..dst.height() {
        dst.row_mut(r).copy_from_slice(&src.row(r)[..w]);
    }
    dst.extend_border();
}

/// [`crop`] written into `reuse` when it is a frame of `width x height`
/// with the borders [`crop`] gives (a frame [`crop`] returned earlier):
/// no allocation, and none of the page faults a fresh one costs.
pub fn crop_reusing(
    frame: &Frame,
    width: usize,
    height: usize,
    reuse: Option<Frame>,
) -> Result<Frame, PictureError> {
    if let Some(mut out) = reuse.filter(|f| holds_crop(f, width, height)) {
        for p in 0..3 {
            crop_plane_into(frame.plane(p), out.plane_mut(p));
        }
        return Ok(out);
    }
    // The borders of Frame::new: the default for luma, half for chroma.
    let (cw, ch) = Frame::chroma_size(width, height);
    let pad = Plane::DEFAULT_PAD;
    Frame::from_planes(
        frame.y().cropped(width, height, pad)?,
        frame.plane(1).cropped(cw, ch, pad.div_ceil(2))?,
        frame.plane(2).cropped(cw, ch, pad.div_ceil(2))?,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crop_into_a_reused_frame_equals_a_fresh_crop() -> Result<(), PictureError> {
        let coded = |seed: usize| -> Result<Frame, PictureError> {
            let mut f = Frame::new(48, 32)?;
            for p in 0..3 {
                let plane = f.plane_mut(p);
                for y in 0..plane.height() {
                    for (x, v) in plane.row_mut(y).iter_mut().enumerate() {
                        *v = ((x * 7 + y * 13 + seed * 29 + p * 5) % 256) as u8;
                    }
                }
            }
            f.extend_borders();
            Ok(f)
        };
        let (a, b) = (coded(1)?, coded(2)?);
        let fresh = crop(&b, 37, 23)?;
        let reused = crop_reusing(&b, 37, 23, Some(crop(&a, 37, 23)?))?;
        assert_eq!(reused, fresh);
        // Borders too, where the reuse could leave the old picture's.
        for p in 0..3 {
            let pad = fresh.plane(p).pad() as isize;
            for (x, y) in [(-pad, -pad), (-1, 3), (40, 30), (36 + pad, 22 + pad)] {
                let (x, y) = (
                    x.min(fresh.plane(p).width() as isize + pad - 1),
                    y.min(fresh.plane(p).height() as isize + pad - 1),
                );
                assert_eq!(
                    reused.plane(p).at(x, y),
                    fresh.plane(p).at(x, y),
                    "plane {p} ({x}, {y})"
                );
            }
        }
        // A frame of another size is not reused, and the result is right.
        assert_eq!(crop_reusing(&b, 37, 23, Some(crop(&a, 30, 20)?))?, fresh);
        Ok(())
    }
}
