//! Streams end to end: hand-built streams against hand-computed pictures,
//! syntax round trips, decoding equal to the reconstruction the writer side
//! made for every motion tool, and malformed input: clear errors, never a
//! panic, over more than 10,000 mutated, truncated and random streams.

use mocomp_codec::deblock::{deblock_frame, DeblockOffsets, DeblockStrength, MbEdgeInfo};
use mocomp_codec::decoder::{decode, DecodeError};
use mocomp_codec::entropy::RangeEncoder;
use mocomp_codec::interp::LumaFilter;
use mocomp_codec::intra::IntraMode;
use mocomp_codec::intra4x4::{Intra4x4Mode, LumaIntra, CODING_ORDER};
use mocomp_codec::modes::{MbMode, ModeCoder, VectorSyntax};
use mocomp_codec::mv::Mv;
use mocomp_codec::partition::{RefMv, Split};
use mocomp_codec::picture::{Frame, Plane};
use mocomp_codec::recon::{
    crop, frame_vectors, predict_inter_blocks, predict_intra, reconstruct_mb, InterContext,
};
use mocomp_codec::residual::MbResidual;
use mocomp_codec::syntax::{
    read_frame, write_frame, write_stream, CodedMb, EntropyState, FrameHeader, FrameSyntax, FrameType,
    MbKind, MotionTool, SequenceHeader, SEQUENCE_HEADER_LEN,
};
use mocomp_codec::transform::{dequantize, forward_4x4, inverse_4x4, quantize, quantize_luma_dc};
use mocomp_codec::transform8x8::{dequantize_8x8, forward_8x8, inverse_8x8, quantize_8x8};
use mocomp_codec::warp::{warp_frame, MotionGrid};
use mocomp_codec::weight::{PlaneWeight, Weights};

fn seq(width: usize, height: usize, frames: u32) -> SequenceHeader {
    SequenceHeader {
        width,
        height,
        fps_num: 30,
        fps_den: 1,
        frame_count: frames,
        vui: Default::default(),
        max_refs: 3,
    }
}

fn intra_dc() -> MbKind {
    MbKind::Intra {
        luma: LumaIntra::Whole(IntraMode::Dc),
        chroma: IntraMode::Dc,
    }
}

/// Macroblock (x, y) intra in 4x4 blocks, every mode somewhere: block k
/// in mode `(k + seed) % 9` where it has that mode's neighbours, else DC.
fn intra4x4(x: usize, y: usize, cols: usize, seed: usize) -> MbKind {
    let mut modes = [Intra4x4Mode::Dc; 16];
    for (k, m) in modes.iter_mut().enumerate() {
        let (above, left, _) = mocomp_codec::intra4x4::neighbours(k, x, y, cols);
        let want = Intra4x4Mode::ALL[(k + seed) % 9];
        if want.is_available(above, left) {
            *m = want;
        }
    }
    MbKind::Intra {
        luma: LumaIntra::Blocks(modes),
        chroma: IntraMode::Dc,
    }
}

/// The luma prediction of a macroblock in 4x4 blocks as a writer makes it:
/// each block predicted from the reconstruction so far, its levels the
/// quantised difference to the source, reconstructed before the next.
fn code_intra4x4_luma(
    source: &Plane,
    recon: &Frame,
    (mb_x, mb_y): (usize, usize),
    modes: &[Intra4x4Mode; 16],
    qp: u8,
    levels: &mut [[[i32; 4]; 4]; 16],
) -> [u8; 256] {
    let (mut own, mut pred) = ([0u8; 256], [0u8; 256]);
    for k in CODING_ORDER {
        let mut block = [0u8; 16];
        let e = mocomp_codec::intra4x4::edges(recon.y(), &own, mb_x, mb_y, k);
        mocomp_codec::intra4x4::predict(modes[k], &e, &mut block);
        let (bx, by) = (4 * (k % 4), 4 * (k / 4));
        let mut diff = [[0i32; 4]; 4];
        for r in 0..4 {
            for c in 0..4 {
                let s = source.get(mb_x * 16 + bx + c, mb_y * 16 + by + r);
                diff[r][c] = i32::from(s) - i32::from(block[r * 4 + c]);
            }
        }
        let mut c = forward_4x4(&diff);
        quantize(&mut c, qp, 1.0 / 3.0);
        levels[k] = c;
        dequantize(&mut c, qp);
        let res = inverse_4x4(&c);
        for r in 0..4 {
            for col in 0..4 {
                let i = (by + r) * 16 + bx + col;
                pred[i] = block[r * 4 + col];
                own[i] = (i32::from(block[r * 4 + col]) + res[r][col]).clamp(0, 255) as u8;
            }
        }
    }
    pred
}

/// Macroblock (x, y) intra in 8x8 blocks: block q in mode `(q + seed) %
/// 9` where it has that mode's neighbours, else DC.
fn intra8x8(x: usize, y: usize, cols: usize, seed: usize) -> MbKind {
    let modes = std::array::from_fn(|q| {
        let (above, left, _) = mocomp_codec::intra8x8::neighbours(q, x, y, cols);
        let want = Intra4x4Mode::ALL[(q + seed) % 9];
        if want.is_available(above, left) {
            want
        } else {
            Intra4x4Mode::Dc
        }
    });
    MbKind::Intra {
        luma: LumaIntra::Blocks8(modes),
        chroma: IntraMode::Dc,
    }
}

/// The luma prediction of a macroblock in 8x8 blocks as a writer makes it:
/// each block predicted from the reconstruction so far, its levels the
/// quantised difference to the source in the 8x8 transform, reconstructed
/// before the next.
fn code_intra8x8_luma(
    source: &Plane,
    recon: &Frame,
    (mb_x, mb_y): (usize, usize),
    modes: &[Intra4x4Mode; 4],
    qp: u8,
    levels: &mut [[[i32; 8]; 8]; 4],
) -> [u8; 256] {
    let (mut own, mut pred) = ([0u8; 256], [0u8; 256]);
    for q in 0..4 {
        let mut block = [0u8; 64];
        let e = mocomp_codec::intra8x8::edges(recon.y(), &own, mb_x, mb_y, q);
        mocomp_codec::intra8x8::predict(modes[q], &e, &mut block);
        let (bx, by) = (8 * (q % 2), 8 * (q / 2));
        let diff: [[i32; 8]; 8] = std::array::from_fn(|r| {
            std::array::from_fn(|c| {
                let s = source.get(mb_x * 16 + bx + c, mb_y * 16 + by + r);
                i32::from(s) - i32::from(block[r * 8 + c])
            })
        });
        let mut c = forward_8x8(&diff);
        quantize_8x8(&mut c, qp, 1.0 / 3.0);
        levels[q] = c;
        dequantize_8x8(&mut c, qp);
        let res = inverse_8x8(&c);
        for r in 0..8 {
            for col in 0..8 {
                let i = (by + r) * 16 + bx + col;
                pred[i] = block[r * 8 + col];
                own[i] = (i32::from(block[r * 8 + col]) + res[r][col]).clamp(0, 255) as u8;
            }
        }
    }
    pred
}

fn empty(kind: MbKind) -> CodedMb {
    CodedMb::without_residual(kind)
}

fn i_header(qp: u8) -> FrameHeader {
    FrameHeader {
        frame_type: FrameType::Intra,
        qp,
        tool: MotionTool::Block,
        refs: 1,
        deblock: false,
        deblock_offsets: DeblockOffsets::ZERO,
        weights: Weights::NONE,
        luma_filter: LumaFilter::Sharp,
    }
}

fn p_header(qp: u8, tool: MotionTool) -> FrameHeader {
    FrameHeader {
        frame_type: FrameType::Inter,
        qp,
        tool,
        refs: 1,
        deblock: false,
        deblock_offsets: DeblockOffsets::ZERO,
        weights: Weights::NONE,
        luma_filter: LumaFilter::Sharp,
    }
}

fn plane_is(p: &Plane, f: impl Fn(usize, usize) -> u8) {
    for y in 0..p.height() {
        for x in 0..p.width() {
            assert_eq!(p.get(x, y), f(x, y), "({x}, {y})");
        }
    }
}

#[test]
fn hand_built_intra_frame() {
    // One macroblock, DC with no neighbours: 128. A first luma DC level of
    // 4 at QP 28 (the 4x4 Hadamard of [4, 0, ...] is 4 everywhere): each
    // block's DC coefficient (4 * 16 << 4 + 2) >> 2 = 256, inverse
    // transform (256 + 32) >> 6 = 4 everywhere; an AC level of 1 in block
    // 5's position (0, 1) adds its basis function there.
    let s = seq(16, 16, 1);
    let mut residual = MbResidual::default();
    residual.luma_dc[0] = 4;
    residual.luma[5][0][1] = 1;
    let mb = CodedMb::new(intra_dc(), residual);
    let frame = FrameSyntax {
        header: i_header(28),
        grid: None,
        mbs: vec![mb],
    };
    let (bytes, _) = write_stream(&s, &[frame]);
    let (header, frames) = decode(&bytes).unwrap();
    assert_eq!(header, s);
    assert_eq!(frames.len(), 1);
    // Block 5's AC level dequantises to 13 << 4 = 208; with its DC of 256
    // the inverse gives columns of 4 + (+-208 or +-104) / 64 rounded.
    let mut ac = [[0; 4]; 4];
    ac[0][1] = 1;
    dequantize(&mut ac, 28);
    ac[0][0] = 256;
    let block5 = inverse_4x4(&ac);
    plane_is(frames[0].y(), |x, y| {
        if (4..8).contains(&x) && (4..8).contains(&y) {
            (128 + block5[y - 4][x - 4]) as u8
        } else {
            132
        }
    });
    plane_is(frames[0].u(), |_, _| 128);
    plane_is(frames[0].v(), |_, _| 128);
}

/// An I frame of two macroblocks: left 128, right 132 (a first luma DC
/// level that adds 4 to every block of the right one).
fn two_tone_intra() -> FrameSyntax {
    let mut residual = MbResidual::default();
    residual.luma_dc[0] = 4;
    let right = CodedMb::new(intra_dc(), residual);
    FrameSyntax {
        header: i_header(28),
        grid: None,
        mbs: vec![empty(intra_dc()), right],
    }
}

#[test]
fn hand_built_inter_and_skip() {
    // Reference: x < 16 -> 128, x >= 16 -> 132 (the right macroblock's DC
    // from its left neighbour is 128, plus 4).
    let s = seq(32, 16, 2);
    // MB 0 moves 8 px right (32 quarter-pel): columns 8..24 of the
    // reference. MB 1 is skipped: its predicted vector is MB 0's (only the
    // left neighbour exists), so it reads columns 24..40, the last 8 being
    // the edge repeated: all 132.
    let p = FrameSyntax {
        header: p_header(28, MotionTool::Block),
        grid: None,
        mbs: vec![
            empty(MbKind::Inter {
                mv: RefMv::previous(Mv::full_pel(8, 0)),
            }),
            empty(MbKind::Skip),
        ],
    };
    let (bytes, counts) = write_stream(&s, &[two_tone_intra(), p]);
    assert!(counts.motion > 0 && counts.residual > 0);
    let (_, frames) = decode(&bytes).unwrap();
    plane_is(frames[0].y(), |x, _| if x < 16 { 128 } else { 132 });
    plane_is(frames[1].y(), |x, _| if x < 8 { 128 } else { 132 });
    plane_is(frames[1].u(), |_, _| 128);
}

#[test]
fn hand_built_prediction_from_an_older_reference() {
    // Frame 1 moves frame 0 (128 | 132 at x = 16) 8 px left: 128 | 132 at
    // x = 8. Frame 2's left macroblock copies reference 1 (frame 0) and
    // its right one reference 0 (frame 1): 128 | 132 at x = 16 again.
    let s = seq(32, 16, 3);
    let inter = |mv, ref_idx| {
        empty(MbKind::Inter {
            mv: RefMv::new(mv, ref_idx),
        })
    };
    let p1 = FrameSyntax {
        header: p_header(28, MotionTool::Block),
        grid: None,
        mbs: vec![inter(Mv::full_pel(8, 0), 0), empty(MbKind::Skip)],
    };
    let p2 = FrameSyntax {
        header: FrameHeader {
            refs: 2,
            ..p_header(28, MotionTool::Block)
        },
        grid: None,
        mbs: vec![inter(Mv::ZERO, 1), inter(Mv::ZERO, 0)],
    };
    let (bytes, _) = write_stream(&s, &[two_tone_intra(), p1, p2]);
    let (_, frames) = decode(&bytes).unwrap();
    plane_is(frames[1].y(), |x, _| if x < 8 { 128 } else { 132 });
    plane_is(frames[2].y(), |x, _| if x < 16 { 128 } else { 132 });
}

#[test]
fn hand_built_intra_in_a_p_frame_and_obmc_and_grid() {
    let s = seq(32, 16, 4);
    // Intra in a P frame: horizontal from the left macroblock's last column.
    let p_intra = FrameSyntax {
        header: p_header(28, MotionTool::Block),
        grid: None,
        mbs: vec![
            empty(MbKind::Skip),
            empty(MbKind::Intra {
                luma: LumaIntra::Whole(IntraMode::Horizontal),
                chroma: IntraMode::Dc,
            }),
        ],
    };
    // OBMC with every vector zero: a copy.
    let p_obmc = FrameSyntax {
        header: p_header(30, MotionTool::Obmc),
        grid: None,
        mbs: vec![empty(MbKind::Inter { mv: RefMv::default() }), empty(MbKind::Skip)],
    };
    // A grid of constant (-4, 0) px: every pixel takes the one 4 px to its left.
    let mut grid = MotionGrid::new(32, 16, 16).unwrap();
    for r in 0..grid.rows() {
        for c in 0..grid.cols() {
            grid.set(c, r, Mv::full_pel(-4, 0));
        }
    }
    let p_grid = FrameSyntax {
        header: p_header(30, MotionTool::Grid(16)),
        grid: Some(grid),
        mbs: vec![empty(MbKind::Skip), empty(MbKind::Inter { mv: RefMv::default() })],
    };
    let (bytes, _) = write_stream(&s, &[two_tone_intra(), p_intra, p_obmc, p_grid]);
    let (_, frames) = decode(&bytes).unwrap();
    // Frame 1: the left half skips (copy: 128), the right repeats column 15: 128.
    plane_is(frames[1].y(), |_, _| 128);
    plane_is(frames[2].y(), |_, _| 128);
    let two = two_tone_intra();
    let (bytes, _) = write_stream(
        &seq(32, 16, 2),
        &[two, {
            let mut g = MotionGrid::new(32, 16, 16).unwrap();
            for r in 0..g.rows() {
                for c in 0..g.cols() {
                    g.set(c, r, Mv::full_pel(-4, 0));
                }
            }
            FrameSyntax {
                header: p_header(30, MotionTool::Grid(16)),
                grid: Some(g),
                mbs: vec![empty(MbKind::Skip), empty(MbKind::Skip)],
            }
        }],
    );
    let (_, frames) = decode(&bytes).unwrap();
    // Shifted right by 4: the edge between 128 and 132 moves from 16 to 20.
    plane_is(frames[1].y(), |x, _| if x < 20 { 128 } else { 132 });
}

/// A small encoder for tests: every macroblock's kind comes from `choose`;
/// residuals are the quantised difference to the prediction, so pictures
/// carry real content. `references`: the frames since the last I frame,
/// the latest first. Returns the syntax and the writer side's own
/// reconstruction (coded size).
fn code_frame(
    s: &SequenceHeader,
    source: &Frame,
    references: &[Frame],
    header: FrameHeader,
    grid: Option<MotionGrid>,
    choose: &dyn Fn(usize, usize) -> MbKind,
) -> (FrameSyntax, Frame) {
    let (cols, rows) = (s.mb_cols(), s.mb_rows());
    // The writer side's weighting: each sample of the padded reference
    // through the formula, written out here.
    let weighted = references.first().map(|r| {
        let mut out = r.clone();
        for (i, w) in header.weights.0.iter().enumerate() {
            if let Some(w) = w {
                for v in out.plane_mut(i).data_mut() {
                    let x = ((i32::from(*v) * i32::from(w.scale) + 32) >> 6) + i32::from(w.offset);
                    *v = x.clamp(0, 255) as u8;
                }
            }
        }
        out
    });
    let reference = weighted.as_ref();
    // Weights apply to reference 0 only.
    let list: Vec<&Frame> = reference
        .into_iter()
        .chain(references.iter().skip(1))
        .take(usize::from(header.refs))
        .collect();
    let kinds: Vec<MbKind> = (0..cols * rows).map(|i| choose(i % cols, i / cols)).collect();
    let mut syntax = FrameSyntax {
        header,
        grid,
        mbs: kinds.iter().map(|&k| empty(k)).collect(),
    };
    let vectors = frame_vectors(s, &syntax);
    let mut recon = Frame::new(s.coded_width(), s.coded_height()).unwrap();
    let warped = match (&syntax.grid, reference) {
        (Some(g), Some(r)) => {
            let mut w = Frame::new(s.coded_width(), s.coded_height()).unwrap();
            warp_frame(r, g, &mut w);
            Some(w)
        }
        _ => None,
    };
    for (i, kind) in kinds.iter().enumerate() {
        let (mb_x, mb_y) = (i % cols, i / cols);
        let mut residual = MbResidual::default();
        let pred = match *kind {
            MbKind::Intra {
                luma: LumaIntra::Whole(luma),
                chroma,
            } => predict_intra(&recon, mb_x, mb_y, luma, chroma),
            MbKind::Intra {
                luma: LumaIntra::Blocks(modes),
                chroma,
            } => {
                let mut pred = predict_intra(&recon, mb_x, mb_y, IntraMode::Dc, chroma);
                let at = (mb_x, mb_y);
                pred.luma = code_intra4x4_luma(source.y(), &recon, at, &modes, header.qp, &mut residual.luma);
                pred
            }
            MbKind::Intra {
                luma: LumaIntra::Blocks8(modes),
                chroma,
            } => {
                let mut pred = predict_intra(&recon, mb_x, mb_y, IntraMode::Dc, chroma);
                let mut b8 = Box::new([[[0i32; 8]; 8]; 4]);
                pred.luma = code_intra8x8_luma(source.y(), &recon, (mb_x, mb_y), &modes, header.qp, &mut b8);
                if b8.as_flattened().as_flattened().iter().any(|&v| v != 0) {
                    residual.luma8 = Some(b8);
                }
                pred
            }
            _ => {
                let ctx = InterContext {
                    references: &list,
                    tool: header.tool,
                    luma_filter: header.luma_filter,
                    vectors: &vectors,
                    warped: warped.as_ref(),
                    mb_cols: cols,
                };
                predict_inter_blocks(&ctx, mb_x, mb_y, &vectors[i].map(Option::unwrap_or_default))
            }
        };
        if *kind != MbKind::Skip {
            let block = |plane: &Plane, pred: &[u8], size: usize, bx: usize, by: usize| {
                let mut b = [[0i32; 4]; 4];
                for r in 0..4 {
                    for c in 0..4 {
                        let (x, y) = (mb_x * size + bx * 4 + c, mb_y * size + by * 4 + r);
                        b[r][c] = plane.get(x, y) as i32 - pred[(by * 4 + r) * size + bx * 4 + c] as i32;
                    }
                }
                b
            };
            let in_blocks = matches!(
                kind,
                MbKind::Intra {
                    luma: LumaIntra::Blocks(_) | LumaIntra::Blocks8(_),
                    ..
                }
            );
            let intra = matches!(kind, MbKind::Intra { .. });
            // Every other inter macroblock codes its luma in the 8x8
            // transform (when levels are left).
            if !intra && (mb_x + mb_y) % 2 == 0 {
                let mut b8 = Box::new([[[0i32; 8]; 8]; 4]);
                for (q, levels) in b8.iter_mut().enumerate() {
                    let diff: [[i32; 8]; 8] = std::array::from_fn(|r| {
                        std::array::from_fn(|c| {
                            let (x, y) = ((q % 2) * 8 + c, (q / 2) * 8 + r);
                            source.y().get(mb_x * 16 + x, mb_y * 16 + y) as i32 - pred.luma[y * 16 + x] as i32
                        })
                    });
                    *levels = forward_8x8(&diff);
                    quantize_8x8(levels, header.qp, 1.0 / 6.0);
                }
                if b8.as_flattened().as_flattened().iter().any(|&v| v != 0) {
                    residual.luma8 = Some(b8);
                }
            }
            for k in (0..16).filter(|_| !in_blocks && residual.luma8.is_none()) {
                let mut c = forward_4x4(&block(source.y(), &pred.luma, 16, k % 4, k / 4));
                let dc = c[0][0];
                quantize(&mut c, header.qp, 1.0 / 3.0);
                // Intra 16x16: the blocks' DC coefficients coded apart.
                if intra {
                    residual.luma_dc[k] = dc;
                    c[0][0] = 0;
                }
                residual.luma[k] = c;
            }
            if intra && !in_blocks {
                residual.luma_dc = quantize_luma_dc(residual.luma_dc, header.qp, 1.0 / 3.0);
            }
            for p in 0..2 {
                for k in 0..4 {
                    let mut c = forward_4x4(&block(source.plane(p + 1), &pred.chroma[p], 8, k % 2, k / 2));
                    quantize(&mut c, mocomp_codec::recon::chroma_qp(header.qp), 1.0 / 3.0);
                    residual.chroma[p][k] = c;
                }
            }
        }
        reconstruct_mb(&pred, &residual, header.qp, &mut recon, mb_x, mb_y);
        syntax.mbs[i] = CodedMb::new(*kind, residual);
    }
    if header.deblock {
        let info = MbEdgeInfo::of_frame(&syntax, &vectors);
        deblock_frame(&mut recon, &info, DeblockStrength::of(&header));
    }
    recon.extend_borders();
    (syntax, recon)
}

/// A textured source frame of the coded size.
fn source(s: &SequenceHeader, t: usize) -> Frame {
    let f = |x: usize, y: usize, k: usize| {
        let (x, y) = ((x + 3 * t) as f64, (y + t) as f64);
        (128.0 + 60.0 * ((x * 0.21 + k as f64).sin() * (y * 0.17).cos()) + 20.0 * ((x + y) * 0.05).sin())
            as u8
    };
    let (w, h) = (s.coded_width(), s.coded_height());
    let (cw, ch) = (w / 2, h / 2);
    Frame::from_planes(
        Plane::from_fn(w, h, |x, y| f(x, y, 0)).unwrap(),
        Plane::from_fn(cw, ch, |x, y| f(2 * x, 2 * y, 1) / 2 + 64).unwrap(),
        Plane::from_fn(cw, ch, |x, y| f(2 * x, 2 * y, 2) / 2 + 64).unwrap(),
    )
    .unwrap()
}

/// A stream of 5 frames (I, then P with each tool and a mix of kinds; the
/// last predicting from three references) and the writer side's
/// reconstructions, cropped.
fn coded_stream(width: usize, height: usize, qp: u8) -> (Vec<u8>, Vec<Frame>) {
    let s = seq(width, height, 5);
    let mut frames = Vec::new();
    let mut recons: Vec<Frame> = Vec::new();
    let mut grid = MotionGrid::new(s.coded_width(), s.coded_height(), 8).unwrap();
    for r in 0..grid.rows() {
        for c in 0..grid.cols() {
            grid.set(c, r, Mv::new(-12 + (c as i32 % 3), -4 + (r as i32 % 2) * 3));
        }
    }
    let tools = [
        (FrameType::Intra, MotionTool::Block),
        (FrameType::Inter, MotionTool::Block),
        (FrameType::Inter, MotionTool::Obmc),
        (FrameType::Inter, MotionTool::Grid(8)),
        (FrameType::Inter, MotionTool::Block),
    ];
    for (t, (ft, tool)) in tools.into_iter().enumerate() {
        let refs = if t == 4 { 3 } else { 1 };
        let header = FrameHeader {
            frame_type: ft,
            qp,
            tool,
            refs,
            deblock: t % 2 == 1,
            // The deblocked frames with offsets each way.
            deblock_offsets: match t {
                1 => DeblockOffsets { alpha: 4, beta: -2 },
                3 => DeblockOffsets { alpha: -6, beta: 12 },
                _ => DeblockOffsets::ZERO,
            },
            // Frames 2 to 4 weight some planes (an offset that clips, a
            // scale that darkens).
            weights: match t {
                2 => Weights([
                    Some(PlaneWeight {
                        scale: 80,
                        offset: -30,
                    }),
                    None,
                    Some(PlaneWeight {
                        scale: 64,
                        offset: 200,
                    }),
                ]),
                3 | 4 => Weights([Some(PlaneWeight { scale: 40, offset: 3 }), None, None]),
                _ => Weights::NONE,
            },
            // The last block frame interpolates with the smooth filter.
            luma_filter: if t == 4 {
                LumaFilter::Smooth
            } else {
                LumaFilter::Sharp
            },
        };
        let g = matches!(tool, MotionTool::Grid(_)).then(|| grid.clone());
        let cols = s.mb_cols();
        let choose = move |x: usize, y: usize| -> MbKind {
            if ft == FrameType::Intra {
                let mode = |m: usize| {
                    [
                        IntraMode::Dc,
                        IntraMode::Vertical,
                        IntraMode::Horizontal,
                        IntraMode::Plane,
                    ][m]
                };
                let pick = (x + 2 * y + t) % 4;
                let ok = match pick {
                    1 => y > 0,
                    2 => x > 0,
                    3 => x > 0 && y > 0,
                    _ => true,
                };
                let m = if ok { mode(pick) } else { IntraMode::Dc };
                match (x + y + t) % 5 {
                    1 => return intra4x4(x, y, cols, x + 3 * y),
                    3 => return intra8x8(x, y, cols, x + 2 * y),
                    _ => {}
                }
                return MbKind::Intra {
                    luma: LumaIntra::Whole(m),
                    chroma: m,
                };
            }
            match (x + y + t) % 5 {
                0 => MbKind::Skip,
                1 => match (x + t) % 3 {
                    0 => intra4x4(x, y, cols, x + y + t),
                    1 => intra8x8(x, y, cols, x + y + t),
                    _ => intra_dc(),
                },
                _ if matches!(tool, MotionTool::Grid(_)) => MbKind::Inter { mv: RefMv::default() },
                // Block frames split some macroblocks, every way, each
                // partition with its own vector and reference.
                4 if tool == MotionTool::Block => {
                    let split = Split::ALL[(x + 2 * y) % 3];
                    let mut mvs = [RefMv::default(); 4];
                    for (k, mv) in mvs.iter_mut().enumerate().take(split.parts().len()) {
                        *mv = RefMv::new(
                            Mv::new(-9 + 7 * k as i32 + x as i32, 3 - 5 * k as i32 + y as i32),
                            ((x + k) % usize::from(refs)) as u8,
                        );
                    }
                    MbKind::Split { split, mvs }
                }
                k => MbKind::Inter {
                    mv: RefMv::new(
                        Mv::new(-13 + 3 * k as i32, 5 - (x as i32 % 3)),
                        ((x + 2 * y) % usize::from(refs)) as u8,
                    ),
                },
            }
        };
        let since_intra: Vec<Frame> = recons.iter().rev().cloned().collect();
        let (syntax, recon) = code_frame(&s, &source(&s, t), &since_intra, header, g, &choose);
        frames.push(syntax);
        recons.push(recon);
    }
    let (bytes, _) = write_stream(&s, &frames);
    let cropped = recons.iter().map(|r| crop(r, width, height).unwrap()).collect();
    (bytes, cropped)
}

#[test]
fn decoding_equals_the_writer_sides_reconstruction() {
    for (w, h, qp) in [
        (48, 32, 26),
        (35, 19, 12),
        (16, 16, 40),
        (1, 1, 30),
        (50, 7, 0),
        (33, 40, 51),
    ] {
        let (bytes, recons) = coded_stream(w, h, qp);
        let (_, frames) = decode(&bytes).unwrap();
        assert_eq!(frames, recons, "{w}x{h} at QP {qp}");
    }
}

#[test]
fn syntax_round_trips() {
    // Bytes -> syntax -> bytes: every frame of coded streams comes back identical.
    for (w, h, qp) in [(48, 32, 20), (35, 19, 3)] {
        let (bytes, _) = coded_stream(w, h, qp);
        let s = SequenceHeader::parse(&bytes).unwrap();
        let mut at = SEQUENCE_HEADER_LEN;
        let (mut frames, mut t8) = (0, 0);
        let (mut read_state, mut write_state) = (EntropyState::new(), EntropyState::new());
        while bytes[at] == 0xA5 {
            let len = u32::from_be_bytes(bytes[at + 1..at + 5].try_into().unwrap()) as usize;
            let original = &bytes[at..at + 5 + len];
            let fresh = read_frame(&s, &original[5..], &mut EntropyState::new());
            let syntax = read_frame(&s, &original[5..], &mut read_state).unwrap();
            t8 += syntax.mbs.iter().filter(|m| m.residual().transform_8x8()).count();
            // P frames start from the contexts the previous frame left:
            // read from the initial ones, they say something else.
            if syntax.header.frame_type == FrameType::Inter {
                assert_ne!(fresh.ok(), Some(syntax.clone()), "frame {frames}");
            } else {
                assert_eq!(fresh.ok(), Some(syntax.clone()), "frame {frames}");
            }
            assert_eq!(
                write_frame(&s, &syntax, &mut write_state).0,
                original,
                "frame {frames}"
            );
            at += 5 + len;
            frames += 1;
        }
        assert_eq!((frames, bytes[at], at + 1), (5, 0x5A, bytes.len()));
        assert!(t8 > 3, "{t8} macroblocks in the 8x8 transform");
    }
}

fn expect_err(bytes: &[u8]) -> DecodeError {
    match decode(bytes) {
        Err(e) => e,
        Ok(_) => panic!("decoded a stream that should fail"),
    }
}

#[test]
fn malformed_streams_are_clear_errors() {
    let (good, _) = coded_stream(48, 32, 26);
    // Bad magic, other version, size out of range.
    let mut b = good.clone();
    b[0] = b'X';
    assert!(expect_err(&b).to_string().contains("not a mocomp stream"));
    let mut b = good.clone();
    b[4] = 2;
    assert!(expect_err(&b).to_string().contains("version 2 is not supported"));
    let mut b = good.clone();
    b[5] = 0xFF; // width - 1 = 0xFF?? > 16383
    assert!(expect_err(&b).to_string().contains("width"));
    // VUI values outside their codes, a half-known aspect ratio.
    for (at, value, what) in [(27, 3, "colour_range"), (28, 4, "chroma_siting"), (25, 0, "sar")] {
        let mut b = good.clone();
        b[at] = value;
        if what == "sar" {
            b[26] = 1; // 0:1
        }
        assert!(expect_err(&b).to_string().contains(what), "{what}");
    }
    // No references, or more than a P frame can have.
    for refs in [0, 9] {
        let mut b = good.clone();
        b[29] = refs;
        assert!(expect_err(&b).to_string().contains("max_refs"), "{refs}");
    }
    // A P frame predicting from more frames than were decoded since the
    // I frame, or than the sequence keeps.
    let s = seq(16, 16, 0);
    let p = |refs| FrameSyntax {
        header: FrameHeader {
            refs,
            ..p_header(30, MotionTool::Block)
        },
        grid: None,
        mbs: vec![empty(MbKind::Skip)],
    };
    let i = FrameSyntax {
        header: i_header(30),
        grid: None,
        mbs: vec![empty(intra_dc())],
    };
    let (b, _) = write_stream(&s, &[i.clone(), p(1), p(2), p(3)]);
    assert_eq!(decode(&b).unwrap().1.len(), 4);
    let (b, _) = write_stream(&s, &[i.clone(), p(1), p(3)]);
    assert!(expect_err(&b)
        .to_string()
        .contains("predicting from 3 references, with 2 decoded"));
    let (b, _) = write_stream(&s, &[i.clone(), p(1), p(2), i.clone(), p(2)]);
    assert!(expect_err(&b)
        .to_string()
        .contains("with 1 decoded since the last I frame"));
    let (b, _) = write_stream(&s, &[i, p(1), p(2), p(3), p(4)]);
    assert!(expect_err(&b).to_string().contains("more than the sequence's 3"));
    // A wrong start code.
    let mut b = good.clone();
    b[30] = 0x00;
    assert!(matches!(
        expect_err(&b),
        DecodeError::StartCode { byte: 30, found: 0 }
    ));
    // A frame length beyond any frame of this size.
    let mut b = good.clone();
    b[31..35].copy_from_slice(&u32::MAX.to_be_bytes());
    assert!(matches!(
        expect_err(&b),
        DecodeError::FrameLength { frame: 0, .. }
    ));
    // Data after the end marker; a missing end marker.
    let mut b = good.clone();
    b.push(0);
    assert!(matches!(expect_err(&b), DecodeError::TrailingData { .. }));
    let b = &good[..good.len() - 1];
    assert!(matches!(expect_err(b), DecodeError::Truncated { .. }));
    // The header announces 5 frames: 4 or 6 are errors.
    let mut b = good.clone();
    b[22] = 4;
    assert!(matches!(
        expect_err(&b),
        DecodeError::FrameCount { expected: 4, .. }
    ));
    let mut b = good.clone();
    b[22] = 6;
    assert!(matches!(
        expect_err(&b),
        DecodeError::FrameCount {
            expected: 6,
            found: 5
        }
    ));
    // The largest picture with ten bytes of frame: an error, at once (the
    // decoder holds per-macroblock syntax sparsely, so this allocates little).
    let mut b = seq(16384, 16384, 0).to_bytes();
    b.push(0xA5);
    b.extend_from_slice(&10u32.to_be_bytes());
    b.extend_from_slice(&[0x0F; 10]);
    b.push(0x5A);
    assert!(matches!(expect_err(&b), DecodeError::Syntax { frame: 0, .. }));
    // Every truncation is an error, never a panic.
    for cut in 0..good.len() {
        assert!(decode(&good[..cut]).is_err(), "cut at {cut}");
    }
}

#[test]
fn invalid_frame_syntax_is_located() {
    let s = seq(32, 16, 0);
    let frame = |header, mbs| FrameSyntax {
        header,
        grid: None,
        mbs,
    };
    let stream = |f: &FrameSyntax| {
        let mut b = s.to_bytes();
        b.extend(write_frame(&s, f, &mut EntropyState::new()).0);
        b.push(0x5A);
        b
    };
    // A P frame first.
    let p_first = frame(
        p_header(20, MotionTool::Block),
        vec![empty(MbKind::Skip), empty(MbKind::Skip)],
    );
    let e = expect_err(&stream(&p_first));
    assert!(e.to_string().contains("no frame before it"), "{e}");
    // Vertical intra on the top row, and an 8x8 block predicted from the
    // left in the first column: written by hand, since the writer would
    // not produce them. Payload: type 0, qp 20, tool 0 and alignment (two
    // bytes), then the range-coded modes of macroblock 0.
    let hand_written = |mode: &MbMode| {
        let mut w = mocomp_codec::bits::BitWriter::new();
        w.put(0, 1);
        w.put(20, 6);
        w.put(0, 2);
        w.align();
        let mut payload = w.into_bytes();
        let mut enc = RangeEncoder::new();
        ModeCoder::new(2, 1).write(&mut enc, 0, 0, false, VectorSyntax::None, mode);
        payload.extend(enc.finish());
        let mut b = s.to_bytes();
        b.push(0xA5);
        b.extend_from_slice(&(payload.len() as u32).to_be_bytes());
        b.extend_from_slice(&payload);
        b.push(0x5A);
        b
    };
    let vertical = MbMode::Intra {
        luma: LumaIntra::Whole(IntraMode::Vertical), // no row above
        chroma: IntraMode::Dc,
    };
    use Intra4x4Mode::{Dc, HorizontalUp};
    let left_in_first_column = MbMode::Intra {
        luma: LumaIntra::Blocks8([Dc, Dc, HorizontalUp, Dc]), // block 2 has no left
        chroma: IntraMode::Dc,
    };
    for (mode, what) in [
        (vertical, "Vertical needs neighbours"),
        (
            left_in_first_column,
            "8x8 intra modes [Dc, Dc, HorizontalUp, Dc] need neighbours",
        ),
    ] {
        let e = expect_err(&hand_written(&mode));
        // Located in the range-coded partition, which starts at byte 30.
        assert!(
            matches!(&e, DecodeError::Syntax { frame: 0, byte, .. } if *byte >= 30),
            "{e:?}"
        );
        assert!(e.to_string().contains(what), "{e}");
    }
    // Junk after the last macroblock (a few bytes could be read as more
    // levels; a hundred cannot), and non-zero bits aligning the header.
    let i = frame(i_header(20), vec![empty(intra_dc()), empty(intra_dc())]);
    let with_frame = |fb: Vec<u8>| {
        let mut fb = fb;
        let len = (fb.len() - 5) as u32;
        fb[1..5].copy_from_slice(&len.to_be_bytes());
        let mut b = s.to_bytes();
        b.extend(fb);
        b.push(0x5A);
        b
    };
    let (mut fb, _) = write_frame(&s, &i, &mut EntropyState::new());
    fb.extend_from_slice(&[0x6B; 100]);
    let e = expect_err(&with_frame(fb));
    assert!(
        e.to_string()
            .contains("does not end where its last macroblock does"),
        "{e}"
    );
    let (mut fb, _) = write_frame(&s, &i, &mut EntropyState::new());
    fb[6] |= 1; // the last of the seven alignment bits after 9 header bits
    let e = expect_err(&with_frame(fb));
    assert!(
        e.to_string().contains("non-zero bits after the frame header"),
        "{e}"
    );
}

/// xorshift64*: deterministic pseudo-random numbers for the mutation test.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

#[test]
fn ten_thousand_mutated_streams_never_panic() {
    let seeds: Vec<Vec<u8>> = [(48, 32, 26), (35, 19, 8), (16, 16, 45)]
        .iter()
        .map(|&(w, h, qp)| coded_stream(w, h, qp).0)
        .collect();
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let (mut ok, mut err) = (0, 0);
    for i in 0..12_000 {
        let mut b = seeds[i % seeds.len()].clone();
        match rng.below(6) {
            0 => {
                // Flip 1 to 8 bits anywhere after the sequence header.
                for _ in 0..1 + rng.below(8) {
                    let at = SEQUENCE_HEADER_LEN + rng.below(b.len() - SEQUENCE_HEADER_LEN);
                    b[at] ^= 1 << rng.below(8);
                }
            }
            1 => b.truncate(rng.below(b.len())),
            2 => {
                let at = rng.below(b.len());
                b.insert(at, rng.next() as u8);
            }
            3 => {
                let at = rng.below(b.len());
                b.remove(at);
            }
            4 => {
                // Overwrite a run with random bytes.
                let at = SEQUENCE_HEADER_LEN + rng.below(b.len() - SEQUENCE_HEADER_LEN);
                let n = (1 + rng.below(16)).min(b.len() - at);
                for k in 0..n {
                    b[at + k] = rng.next() as u8;
                }
            }
            _ => {
                // A valid header, then random bytes.
                b.truncate(23);
                let n = rng.below(400);
                b.extend((0..n).map(|_| rng.next() as u8));
            }
        }
        match decode(&b) {
            Ok(_) => ok += 1,
            Err(_) => err += 1,
        }
    }
    assert_eq!(ok + err, 12_000);
    // Mutations must mostly break streams, and some survive (flips in levels).
    assert!(err > 6_000 && ok > 50, "ok {ok}, err {err}");
}

/// Writes the streams above as seeds for the decoder fuzz target:
/// `MOCOMP_FUZZ_SEEDS=fuzz/seeds/decoder cargo test -p mocomp-codec --test stream -- --ignored`
#[test]
#[ignore = "writes files; run by hand to seed the fuzzer"]
fn write_fuzz_seeds() {
    let Ok(dir) = std::env::var("MOCOMP_FUZZ_SEEDS") else {
        return;
    };
    std::fs::create_dir_all(&dir).unwrap();
    for (i, (w, h, qp)) in [(16, 16, 30), (48, 32, 26), (35, 19, 8), (17, 9, 45), (1, 1, 20)]
        .into_iter()
        .enumerate()
    {
        let (bytes, _) = coded_stream(w, h, qp);
        std::fs::write(format!("{dir}/stream_{i}.mcv"), bytes).unwrap();
    }
}

/// Inputs the fuzzer once crashed the decoder with (`codec/tests/regressions/`):
/// each must now be a clean error.
#[test]
fn fuzzer_findings_stay_fixed() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/regressions");
    let mut n = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let bytes = std::fs::read(entry.unwrap().path()).unwrap();
        assert!(decode(&bytes).is_err());
        n += 1;
    }
    assert!(n >= 1);
}
