//! The macroblock layer (FORMAT.md section 3): what a macroblock is coded
//! as, its vectors and mode-layer view, the intra modes its position
//! allows, and the reading of one macroblock from the range-coded
//! partition.

use super::error::{invalid, SyntaxError};
use crate::entropy::RangeDecoder;
use crate::intra::IntraMode;
use crate::intra4x4::{self, LumaIntra};
use crate::intra8x8;
use crate::modes::{MbMode, ModeCoder, VectorSyntax};
use crate::mv::{Mv, MV_LIMIT};
use crate::mvpred::{mv_prediction, mv_prediction_into, walk_partitions};
use crate::partition::{MbVectors, RefMv, Split};
use crate::residual::{MbResidual, ResidualCoder, ResidualError, ResidualSyntax};

/// How one macroblock is coded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MbKind {
    /// The prediction alone: the predicted vector (block, OBMC) or the warp
    /// (grid); no residual.
    Skip,
    /// Motion-compensated prediction plus residual. `mv` is the vector
    /// and its reference (block, OBMC); ignored (zero) with a grid.
    Inter {
        /// The macroblock's motion.
        mv: RefMv,
    },
    /// Motion-compensated prediction of each partition plus residual
    /// (block frames).
    Split {
        /// How the macroblock is split.
        split: Split,
        /// Each partition's motion in coding order; entries past the
        /// split's partitions are zero.
        mvs: [RefMv; 4],
    },
    /// Intra prediction plus residual.
    Intra {
        /// Luma mode(s): one 16x16 mode or sixteen 4x4 ones.
        luma: LumaIntra,
        /// Chroma 8x8 mode.
        chroma: IntraMode,
    },
}

impl MbKind {
    /// The syntax of its residual (section 3.3).
    pub fn residual_syntax(&self) -> ResidualSyntax {
        match self {
            MbKind::Intra {
                luma: LumaIntra::Blocks8(_),
                ..
            } => ResidualSyntax::Intra8x8,
            MbKind::Intra {
                luma: LumaIntra::Whole(_),
                ..
            } => ResidualSyntax::Intra16x16,
            MbKind::Intra { .. } => ResidualSyntax::Intra,
            _ => ResidualSyntax::Inter,
        }
    }

    /// Whether the luma of a macroblock of this kind with these levels is
    /// in the 8x8 transform (section 10.2): always for 8x8 intra, for inter
    /// when it says so.
    pub fn luma_transform_8x8(&self, residual: &MbResidual) -> bool {
        self.residual_syntax() == ResidualSyntax::Intra8x8 || residual.transform_8x8()
    }
}

/// One coded macroblock.
///
/// Levels are stored only when some are non-zero, so a frame of many
/// skipped macroblocks (which a few bytes can declare) stays small.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CodedMb {
    /// How it is predicted.
    pub kind: MbKind,
    /// Its levels (`None`: skipped, or none coded).
    pub(super) residual: Option<Box<MbResidual>>,
}

/// All-zero levels.
static NO_RESIDUAL: MbResidual = MbResidual {
    luma: [[[0; 4]; 4]; 16],
    chroma: [[[[0; 4]; 4]; 4]; 2],
    luma8: None,
    luma_dc: [0; 16],
};

impl CodedMb {
    /// A macroblock of `kind` with these levels.
    pub fn new(kind: MbKind, residual: MbResidual) -> CodedMb {
        CodedMb {
            kind,
            residual: (!residual.is_empty()).then(|| Box::new(residual)),
        }
    }

    /// [`CodedMb::new`] with levels already on the heap (kept there, not
    /// copied).
    pub fn with_levels(kind: MbKind, residual: Box<MbResidual>) -> CodedMb {
        CodedMb {
            kind,
            residual: (!residual.is_empty()).then_some(residual),
        }
    }

    /// A macroblock of `kind` without residual.
    pub fn without_residual(kind: MbKind) -> CodedMb {
        CodedMb { kind, residual: None }
    }

    /// Its levels where any was coded.
    pub fn levels(&self) -> Option<&MbResidual> {
        self.residual.as_deref()
    }

    /// Its levels (all zero when none were coded).
    pub fn residual(&self) -> &MbResidual {
        self.residual.as_deref().unwrap_or(&NO_RESIDUAL)
    }
}

/// The vectors a macroblock's 8x8 blocks use: its own for inter, the
/// prediction for skip, none for intra (which counts as unavailable to its
/// neighbours). `done` holds the vectors of the macroblocks before it in
/// raster order.
pub fn mb_vectors(kind: &MbKind, done: &[MbVectors], mb_x: usize, mb_y: usize, mb_cols: usize) -> MbVectors {
    match kind {
        MbKind::Skip => [Some(RefMv::previous(mv_prediction(done, mb_x, mb_y, mb_cols))); 4],
        MbKind::Inter { mv } => [Some(*mv); 4],
        MbKind::Split { split, mvs } => split.block_vectors(mvs).map(Some),
        MbKind::Intra { .. } => [None; 4],
    }
}

/// The mode layer's view of macroblock (mb_x, mb_y): its vectors as
/// differences from their predictions (zero when the frame codes none).
/// `done` holds the vectors of the macroblocks before it.
pub fn mb_mode(
    kind: &MbKind,
    done: &[MbVectors],
    (mb_x, mb_y, mb_cols): (usize, usize, usize),
    vectors: VectorSyntax,
) -> MbMode {
    match *kind {
        MbKind::Skip => MbMode::Skip,
        MbKind::Inter { mv } => MbMode::Inter {
            mvd: if vectors.any() {
                mv.mv - mv_prediction_into(done, (mb_x, mb_y, mb_cols), mv.ref_idx)
            } else {
                Mv::ZERO
            },
            ref_idx: mv.ref_idx,
        },
        MbKind::Split { split, mvs } => {
            let mut mvds = [Mv::ZERO; 4];
            walk_partitions(split, done, (mb_x, mb_y, mb_cols), |k, predict| {
                mvds[k] = mvs[k].mv - predict(mvs[k].ref_idx);
                Some(mvs[k])
            });
            MbMode::Split {
                split,
                mvds,
                refs: mvs.map(|m| m.ref_idx),
            }
        }
        MbKind::Intra { luma, chroma } => MbMode::Intra { luma, chroma },
    }
}

/// Panics unless a frame coding `syntax` can hold `kind` (an encoder bug).
pub(super) fn check_kind(kind: &MbKind, syntax: VectorSyntax) {
    match *kind {
        MbKind::Inter { mv } => {
            assert!(
                syntax.any() || mv == RefMv::default(),
                "inter macroblocks of grid frames have no vector"
            );
            assert!(mv.mv.in_range(), "vector {mv:?} out of range");
            assert!(
                mv.ref_idx < syntax.refs(),
                "reference {} of {}",
                mv.ref_idx,
                syntax.refs()
            );
        }
        MbKind::Split { split, mvs } => {
            assert!(syntax.per_partition(), "only block frames split macroblocks");
            let n = split.parts().len();
            assert!(
                mvs[..n]
                    .iter()
                    .all(|m| m.mv.in_range() && m.ref_idx < syntax.refs()),
                "vectors {mvs:?} out of range"
            );
            assert!(
                mvs[n..].iter().all(|&mv| mv == RefMv::default()),
                "unused partition vectors"
            );
        }
        _ => {}
    }
}

/// Whether intra `mode` has its neighbours at macroblock (mb_x, mb_y):
/// the row above exists below the top row, the column to the left right of
/// the first column, the corner with both.
pub fn intra_mode_allowed(mode: IntraMode, mb_x: usize, mb_y: usize) -> bool {
    match mode {
        IntraMode::Vertical => mb_y > 0,
        IntraMode::Horizontal => mb_x > 0,
        IntraMode::Dc => true,
        IntraMode::Plane => mb_x > 0 && mb_y > 0,
    }
}

/// Whether macroblock (mb_x, mb_y) of a picture `mb_cols` macroblocks
/// wide has the neighbours of its luma intra modes: the 16x16 mode's, or
/// each 4x4 block's (inside the macroblock, its blocks above and to the
/// left).
pub fn luma_intra_allowed(luma: &LumaIntra, mb_x: usize, mb_y: usize, mb_cols: usize) -> bool {
    match luma {
        LumaIntra::Whole(mode) => intra_mode_allowed(*mode, mb_x, mb_y),
        LumaIntra::Blocks(modes) => modes.iter().enumerate().all(|(k, m)| {
            let (above, left, _) = intra4x4::neighbours(k, mb_x, mb_y, mb_cols);
            m.is_available(above, left)
        }),
        LumaIntra::Blocks8(modes) => modes.iter().enumerate().all(|(q, m)| {
            let (above, left, _) = intra8x8::neighbours(q, mb_x, mb_y, mb_cols);
            m.is_available(above, left)
        }),
    }
}

pub(super) fn check_vector(mv: Option<Mv>, bit: usize) -> Result<Mv, SyntaxError> {
    match mv {
        Some(mv) if mv.in_range() => Ok(mv),
        Some(mv) => Err(invalid(
            format!("vector ({}, {}) beyond +-{MV_LIMIT}", mv.x, mv.y),
            bit,
        )),
        None => Err(invalid(
            "a vector difference beyond the syntax's range".into(),
            bit,
        )),
    }
}

/// The range-coded partition of one frame as it is read: the decoder, the
/// coders, and where errors are located.
pub(super) struct PartitionReader<'a> {
    pub(super) dec: RangeDecoder<'a>,
    pub(super) modes: ModeCoder,
    pub(super) residual: ResidualCoder,
    /// The partition's first byte in the payload.
    pub(super) start: usize,
    pub(super) len: usize,
}

impl PartitionReader<'_> {
    /// The bit position of the byte being read, for errors.
    pub(super) fn at(&self) -> usize {
        8 * (self.start + self.dec.position().min(self.len))
    }

    /// Macroblock (mb_x, mb_y): its mode, then its residual; `vectors`
    /// holds the vectors of the macroblocks before it.
    pub(super) fn macroblock(
        &mut self,
        (syntax, inter_frame): (VectorSyntax, bool),
        vectors: &[MbVectors],
        (mb_x, mb_y, cols): (usize, usize, usize),
    ) -> Result<CodedMb, SyntaxError> {
        let kind = match self.modes.read(&mut self.dec, mb_x, mb_y, inter_frame, syntax) {
            None => {
                return Err(invalid(
                    "a vector difference beyond the syntax's range".into(),
                    self.at(),
                ))
            }
            Some(MbMode::Skip) => return Ok(CodedMb::without_residual(MbKind::Skip)),
            Some(MbMode::Inter { mvd, ref_idx }) => {
                let mv = if syntax.any() {
                    let predicted = mv_prediction_into(vectors, (mb_x, mb_y, cols), ref_idx);
                    check_vector(predicted.checked_add(mvd), self.at())?
                } else {
                    Mv::ZERO
                };
                MbKind::Inter {
                    mv: RefMv::new(mv, ref_idx),
                }
            }
            Some(MbMode::Split { split, mvds, refs }) => {
                let mut mvs = [RefMv::default(); 4];
                let mut error = None;
                walk_partitions(
                    split,
                    vectors,
                    (mb_x, mb_y, cols),
                    |k, predict| match check_vector(predict(refs[k]).checked_add(mvds[k]), self.at()) {
                        Ok(mv) => {
                            mvs[k] = RefMv::new(mv, refs[k]);
                            Some(mvs[k])
                        }
                        Err(e) => {
                            error = Some(e);
                            None
                        }
                    },
                );
                if let Some(e) = error {
                    return Err(e);
                }
                MbKind::Split { split, mvs }
            }
            Some(MbMode::Intra { luma, chroma }) => {
                if !luma_intra_allowed(&luma, mb_x, mb_y, cols) {
                    let what = match luma {
                        LumaIntra::Whole(mode) => format!("luma intra mode {mode:?} needs"),
                        LumaIntra::Blocks(modes) => format!("luma 4x4 intra modes {modes:?} need"),
                        LumaIntra::Blocks8(modes) => format!("luma 8x8 intra modes {modes:?} need"),
                    };
                    return Err(invalid(
                        format!("{what} neighbours outside the picture"),
                        self.at(),
                    ));
                }
                if !intra_mode_allowed(chroma, mb_x, mb_y) {
                    return Err(invalid(
                        format!("chroma intra mode {chroma:?} needs neighbours outside the picture"),
                        self.at(),
                    ));
                }
                MbKind::Intra { luma, chroma }
            }
        };
        let levels = self
            .residual
            .read(&mut self.dec, mb_x, mb_y, kind.residual_syntax());
        let levels = levels.map_err(|e| match e {
            ResidualError::Range { what, value, .. } => {
                invalid(format!("{what} = {value} out of range"), self.at())
            }
        })?;
        Ok(CodedMb::new(kind, levels))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::partition::Split;

    #[test]
    fn intra_modes_need_the_neighbours_their_position_has() {
        for (at, v, h, plane) in [
            ((0, 0), false, false, false),
            ((3, 0), false, true, false),
            ((0, 2), true, false, false),
            ((1, 1), true, true, true),
        ] {
            assert!(intra_mode_allowed(IntraMode::Dc, at.0, at.1), "DC at {at:?}");
            assert_eq!(
                intra_mode_allowed(IntraMode::Vertical, at.0, at.1),
                v,
                "vertical at {at:?}"
            );
            assert_eq!(
                intra_mode_allowed(IntraMode::Horizontal, at.0, at.1),
                h,
                "horizontal at {at:?}"
            );
            assert_eq!(
                intra_mode_allowed(IntraMode::Plane, at.0, at.1),
                plane,
                "plane at {at:?}"
            );
        }
    }

    #[test]
    fn a_macroblocks_vectors_and_mode_as_its_kind_says() {
        let mv = |x, y| RefMv::previous(Mv::new(x, y));
        // Macroblock (1, 0) of a row of 2: its left neighbour moved by (8, -4).
        let done = [[Some(mv(8, -4)); 4]];
        assert_eq!(mb_vectors(&MbKind::Skip, &done, 1, 0, 2), [Some(mv(8, -4)); 4]);
        let inter = MbKind::Inter { mv: mv(10, -4) };
        assert_eq!(mb_vectors(&inter, &done, 1, 0, 2), [Some(mv(10, -4)); 4]);
        let intra = MbKind::Intra {
            luma: LumaIntra::Whole(IntraMode::Dc),
            chroma: IntraMode::Dc,
        };
        assert_eq!(mb_vectors(&intra, &done, 1, 0, 2), [None; 4]);
        // The mode codes the difference from the prediction, none in grid
        // frames.
        let syntax = VectorSyntax::ONE_REFERENCE;
        assert_eq!(
            mb_mode(&inter, &done, (1, 0, 2), syntax),
            MbMode::Inter {
                mvd: Mv::new(2, 0),
                ref_idx: 0
            }
        );
        assert_eq!(
            mb_mode(&inter, &done, (1, 0, 2), VectorSyntax::None),
            MbMode::Inter {
                mvd: Mv::ZERO,
                ref_idx: 0
            }
        );
        let split = MbKind::Split {
            split: Split::Vertical,
            mvs: [mv(8, -4), mv(0, 4), RefMv::default(), RefMv::default()],
        };
        let MbMode::Split { mvds, .. } = mb_mode(&split, &done, (1, 0, 2), syntax) else {
            panic!("a split macroblock's mode is a split");
        };
        assert_eq!(mvds[0], Mv::ZERO, "the left partition predicts from the left");
    }

    #[test]
    fn vectors_past_the_limit_are_errors_at_their_bit() {
        assert_eq!(
            check_vector(Some(Mv::new(MV_LIMIT, -MV_LIMIT)), 9),
            Ok(Mv::new(MV_LIMIT, -MV_LIMIT))
        );
        let e = check_vector(Some(Mv::new(MV_LIMIT + 1, 0)), 17).unwrap_err();
        assert_eq!(e.bit, 17);
        assert!(check_vector(None, 3).is_err());
    }
}
