//! The in-loop deblocking filter (FORMAT.md section 11): H.264's edge
//! filter (its clause 8.7, tables 8-16 and 8-17) on every 4x4 block edge
//! of the coded picture, as HEVC orders it: all vertical edges of the
//! picture first, left to right, then all horizontal ones, top to bottom.
//! How hard an edge is filtered (its boundary strength) follows from the
//! macroblocks on either side: intra, coded coefficients, vectors apart.
//!
//! The filter runs once a frame is reconstructed; intra prediction inside
//! the frame reads the samples before it, so encoder and decoder both
//! filter the whole frame at the end.

use std::ops::Range;

use crate::dsp::lf::{lf, Edge, LfLevel};
use crate::partition::MbVectors;
use crate::picture::{Frame, Plane};
use crate::residual::MbResidual;
use crate::syntax::{CodedMb, FrameHeader, FrameSyntax, MbKind, MotionTool};
use crate::transform::chroma_qp;

/// The frame header's offsets of the filter's thresholds (FORMAT.md
/// section 11), H.264's FilterOffsetA and FilterOffsetB: added to the QP
/// to index alpha and tc0 (`alpha`) and beta (`beta`). Positive offsets
/// filter more edges and move samples further (x264's `--deblock A:B` is
/// half of each).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct DeblockOffsets {
    /// Added to the QP to index alpha and tc0.
    pub alpha: i8,
    /// Added to the QP to index beta.
    pub beta: i8,
}

impl DeblockOffsets {
    /// No offsets: the thresholds at the QP.
    pub const ZERO: DeblockOffsets = DeblockOffsets { alpha: 0, beta: 0 };

    /// The largest offset either way (H.264's range).
    pub const MAX: i8 = 12;

    /// Both offsets `offset`.
    pub fn both(offset: i8) -> DeblockOffsets {
        DeblockOffsets {
            alpha: offset,
            beta: offset,
        }
    }

    /// Whether both lie within [`DeblockOffsets::MAX`] either way.
    pub fn in_range(self) -> bool {
        self.alpha.abs() <= Self::MAX && self.beta.abs() <= Self::MAX
    }
}

/// How hard a frame is deblocked: its QP and its header's offsets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeblockStrength {
    /// The frame's QP.
    pub qp: u8,
    /// The header's offsets.
    pub offsets: DeblockOffsets,
}

impl DeblockStrength {
    /// The strength `header` gives.
    pub fn of(header: &FrameHeader) -> DeblockStrength {
        DeblockStrength {
            qp: header.qp,
            offsets: header.deblock_offsets,
        }
    }

    /// The luma edges' threshold indices.
    fn luma(self) -> LfLevel {
        LfLevel::new(self.qp, (self.offsets.alpha, self.offsets.beta))
    }

    /// The chroma edges' (from the chroma QP).
    fn chroma(self) -> LfLevel {
        LfLevel::new(chroma_qp(self.qp), (self.offsets.alpha, self.offsets.beta))
    }
}

/// A QP alone: no offsets.
impl From<u8> for DeblockStrength {
    fn from(qp: u8) -> DeblockStrength {
        DeblockStrength {
            qp,
            offsets: DeblockOffsets::ZERO,
        }
    }
}

/// Bit `k` set where luma 4x4 block `k` has a level.
fn luma_coded_bits(residual: &MbResidual) -> u16 {
    residual
        .luma_coded()
        .iter()
        .enumerate()
        .fold(0, |bits, (k, &c)| bits | u16::from(c) << k)
}

/// What the boundary strength needs of one macroblock.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MbEdgeInfo {
    /// Intra-coded.
    pub intra: bool,
    /// Its 8x8 blocks' vectors (raster order), where vectors are compared
    /// (block and OBMC frames).
    pub mvs: MbVectors,
    /// Bit `by * 4 + bx`: luma 4x4 block (bx, by) has a non-zero level
    /// (all four of an 8x8 transform block with levels).
    pub coded: u16,
    /// Its luma uses the 8x8 transform: the edges inside its 8x8 blocks
    /// are not block edges and are not filtered.
    pub transform_8x8: bool,
}

impl MbEdgeInfo {
    /// The information of macroblock `mb` of a frame using `tool`, whose
    /// vector (for its neighbours' prediction) is `mv`.
    pub fn of(kind: &MbKind, residual: &MbResidual, tool: MotionTool, mvs: MbVectors) -> MbEdgeInfo {
        MbEdgeInfo::with_coded(kind, residual, luma_coded_bits(residual), tool, mvs)
    }

    /// [`MbEdgeInfo::of`] of a coded macroblock: one without levels (most
    /// of a P frame's) read no further than its kind.
    pub fn of_coded(mb: &CodedMb, tool: MotionTool, mvs: MbVectors) -> MbEdgeInfo {
        let coded = mb.levels().map_or(0, luma_coded_bits);
        MbEdgeInfo::with_coded(&mb.kind, mb.residual(), coded, tool, mvs)
    }

    /// [`MbEdgeInfo::of`] with the luma blocks' coded bits known.
    fn with_coded(
        kind: &MbKind,
        residual: &MbResidual,
        coded: u16,
        tool: MotionTool,
        mvs: MbVectors,
    ) -> MbEdgeInfo {
        MbEdgeInfo {
            intra: matches!(kind, MbKind::Intra { .. }),
            mvs: if matches!(tool, MotionTool::Grid(_)) {
                [None; 4]
            } else {
                mvs
            },
            coded,
            transform_8x8: kind.luma_transform_8x8(residual),
        }
    }

    /// Every macroblock of `frame`, with `vectors` from
    /// [`crate::recon::frame_vectors`] (a macroblock without levels, most
    /// of a P frame's, read no further than its kind).
    pub fn of_frame(frame: &FrameSyntax, vectors: &[MbVectors]) -> Vec<MbEdgeInfo> {
        let tool = frame.header.tool;
        frame
            .mbs
            .iter()
            .zip(vectors)
            .map(|(mb, &mv)| MbEdgeInfo::of_coded(mb, tool, mv))
            .collect()
    }

    #[cfg(test)]
    fn coded_at(&self, bx: usize, by: usize) -> bool {
        self.coded >> (by * 4 + bx) & 1 == 1
    }
}

/// The boundary strength of the edge between luma 4x4 blocks `p` (left or
/// above) and `q`, in block units, on a picture `mb_cols` macroblocks wide
/// (the definition [`Strengths::set_row`] is tested against).
#[cfg(test)]
fn strength(info: &[MbEdgeInfo], mb_cols: usize, p: (usize, usize), q: (usize, usize)) -> u8 {
    let mb = |(bx, by): (usize, usize)| &info[(by / 4) * mb_cols + bx / 4];
    let mb_edge = (p.0 / 4, p.1 / 4) != (q.0 / 4, q.1 / 4);
    let inner = |(x, y): (usize, usize)| (x % 4, y % 4);
    strength_between((mb(p), inner(p)), (mb(q), inner(q)), mb_edge, p.1 == q.1)
}

/// [`strength`] of blocks `p` and `q` given by their macroblocks and their
/// positions in them (`mb_edge`: in different macroblocks; `vertical`: the
/// edge between them is vertical).
#[cfg(test)]
fn strength_between(
    (mp, (px, py)): (&MbEdgeInfo, (usize, usize)),
    (mq, (qx, qy)): (&MbEdgeInfo, (usize, usize)),
    mb_edge: bool,
    vertical: bool,
) -> u8 {
    // Inside a macroblock, an edge before an odd block column (vertical
    // edges) or row (horizontal) cuts an 8x8 block.
    let inside_8x8 = if vertical { qx % 2 == 1 } else { qy % 2 == 1 };
    if !mb_edge && mq.transform_8x8 && inside_8x8 {
        return 0;
    }
    if mp.intra || mq.intra {
        return if mb_edge { 4 } else { 3 };
    }
    if mp.coded_at(px, py) || mq.coded_at(qx, qy) {
        return 2;
    }
    // Motion is compared per 8x8 block (within a 16x16 macroblock it is
    // one, so only partitions' and macroblocks' edges can differ).
    let motion = |m: &MbEdgeInfo, x: usize, y: usize| m.mvs[(y / 2) * 2 + x / 2];
    match (motion(mp, px, py), motion(mq, qx, qy)) {
        (Some(a), Some(b))
            if a.ref_idx != b.ref_idx || (a.mv.x - b.mv.x).abs() >= 4 || (a.mv.y - b.mv.y).abs() >= 4 =>
        {
            1
        }
        _ => 0,
    }
}

/// The boundary strength of every luma 4x4 block edge of a frame, found
/// once for its three planes: `vertical[bx * rows + by]` of the edge left
/// of block (bx, by), `horizontal[by * cols + bx]` of the edge above it
/// (0 on the picture's border, which is not an edge). Each is laid out
/// along its edges, so that the four strengths of a macroblock's length
/// of edge are one read ([`Strengths::down`], [`Strengths::along`]).
struct Strengths {
    cols: usize,
    rows: usize,
    vertical: Vec<u8>,
    horizontal: Vec<u8>,
}

impl Strengths {
    /// All strengths 0, for a picture of `cols x rows` luma 4x4 blocks.
    fn zero((cols, rows): (usize, usize)) -> Strengths {
        Strengths {
            cols,
            rows,
            vertical: vec![0; cols * rows],
            horizontal: vec![0; cols * rows],
        }
    }

    /// The strength of the edge left of block (bx, by).
    #[cfg(test)]
    fn vertical_at(&self, bx: usize, by: usize) -> u8 {
        self.vertical[bx * self.rows + by]
    }

    /// The strength of the edge above block (bx, by).
    #[cfg(test)]
    fn horizontal_at(&self, bx: usize, by: usize) -> u8 {
        self.horizontal[by * self.cols + bx]
    }

    /// The strengths of the vertical edge left of blocks (bx, by) ...
    /// (bx, by + 3).
    #[inline]
    fn down(&self, bx: usize, by: usize) -> [u8; 4] {
        let at = bx * self.rows + by;
        let four = &self.vertical[at..at + 4];
        [four[0], four[1], four[2], four[3]]
    }

    /// The strengths of the horizontal edge above blocks (bx, by) ...
    /// (bx + 3, by).
    #[inline]
    fn along(&self, bx: usize, by: usize) -> [u8; 4] {
        let at = by * self.cols + bx;
        let four = &self.horizontal[at..at + 4];
        [four[0], four[1], four[2], four[3]]
    }

    /// The strengths of the edges left of and above the blocks of
    /// macroblock row `my`, whose records are `row`, below `above` (row
    /// `my - 1`'s; none for the top row).
    fn set_row(&mut self, my: usize, row: &[MbEdgeInfo], above: Option<&[MbEdgeInfo]>) {
        let cols = self.cols;
        for (mx, m) in row.iter().enumerate() {
            let left = mx.checked_sub(1).map(|l| &row[l]);
            let masks = EdgeMasks::of(m, left, above.map(|a| &a[mx]));
            let corner = 4 * my * cols + 4 * mx;
            // Most of a P frame: no edge of the macroblock filtered.
            let [vertical, horizontal] = if masks.all_zero() {
                [[0; 16]; 2]
            } else {
                masks.strengths()
            };
            for k in 0..4 {
                let at = corner + k * cols;
                self.horizontal[at..at + 4].copy_from_slice(&horizontal[4 * k..4 * k + 4]);
                // Column k of the macroblock's blocks, down.
                let at = (4 * mx + k) * self.rows + 4 * my;
                let column = [0, 1, 2, 3].map(|y| vertical[4 * y + k]);
                self.vertical[at..at + 4].copy_from_slice(&column);
            }
        }
    }
}

/// The strengths of the edges left of and above a macroblock's sixteen
/// 4x4 blocks, as bit masks over the blocks (bit `y * 4 + x`), one per
/// rule of [`strength_between`] (the definition the tests hold them to):
/// the masks hold a macroblock's 32 edges in a few operations instead of a
/// decision per edge.
struct EdgeMasks {
    /// Edges that exist: inside the picture, and inside the macroblock
    /// not cutting an 8x8 transform block.
    edges: [u16; 2],
    /// Of those, the edges with intra on a side (strength 4 on the
    /// macroblock's edge, 3 inside it).
    intra: [u16; 2],
    /// Levels on a side (strength 2).
    coded: [u16; 2],
    /// Motion differing across (strength 1).
    motion: [u16; 2],
}

/// The blocks of column 0 and of row 0 of a macroblock.
const COLUMN_0: u16 = 0x1111;
const ROW_0: u16 = 0x000f;

impl EdgeMasks {
    /// Vertical (index 0) and horizontal (1) edges of macroblock `m`, its
    /// `left` and `above` neighbours where there are.
    fn of(m: &MbEdgeInfo, left: Option<&MbEdgeInfo>, above: Option<&MbEdgeInfo>) -> EdgeMasks {
        // Inside: the edges after columns (rows) 0-2, or only the 8x8
        // blocks' middle one in the 8x8 transform.
        let inner = if m.transform_8x8 {
            [0x4444, 0x0f00]
        } else {
            [0xeeee, 0xfff0]
        };
        let c = m.coded;
        let mut masks = EdgeMasks {
            edges: inner,
            intra: if m.intra { inner } else { [0; 2] },
            coded: [(c | c << 1) & inner[0], (c | c << 4) & inner[1]],
            // Inside, motion differs only across the 8x8 blocks' middles:
            // blocks 0 | 1 and 2 | 3 (vertical), 0 | 2 and 1 | 3.
            motion: [
                differs(m.mvs[0], m.mvs[1]) & 0x0044 | differs(m.mvs[2], m.mvs[3]) & 0x4400,
                differs(m.mvs[0], m.mvs[2]) & 0x0300 | differs(m.mvs[1], m.mvs[3]) & 0x0c00,
            ],
        };
        // The macroblock's own edge in direction `d` (its blocks `outer`)
        // beside neighbour `n`, whose blocks across it are coded as
        // `n_coded` (moved onto `outer`) and whose motion differs by
        // `motion`.
        let mut beside = |d: usize, outer: u16, n: &MbEdgeInfo, n_coded: u16, motion: u16| {
            masks.edges[d] |= outer;
            if m.intra || n.intra {
                masks.intra[d] |= outer;
            }
            masks.coded[d] |= (n_coded | c) & outer;
            masks.motion[d] |= motion;
        };
        if let Some(l) = left {
            let motion = differs(l.mvs[1], m.mvs[0]) & 0x0011 | differs(l.mvs[3], m.mvs[2]) & 0x1100;
            beside(0, COLUMN_0, l, l.coded >> 3, motion);
        }
        if let Some(a) = above {
            let motion = differs(a.mvs[2], m.mvs[0]) & 0x0003 | differs(a.mvs[3], m.mvs[1]) & 0x000c;
            beside(1, ROW_0, a, a.coded >> 12, motion);
        }
        masks
    }

    /// Whether every edge's strength is 0.
    fn all_zero(&self) -> bool {
        (0..2).all(|d| (self.intra[d] | self.coded[d] | self.motion[d]) & self.edges[d] == 0)
    }

    /// The strength of each block's left (index 0) and upper (1) edge:
    /// the strongest rule that holds, a row of four blocks at a time in
    /// the bytes of a word (each rule's mask made exclusive of the
    /// stronger ones, so that the sum is the strongest's value).
    fn strengths(&self) -> [[u8; 16]; 2] {
        std::array::from_fn(|d| {
            let outer = if d == 0 { COLUMN_0 } else { ROW_0 };
            let intra = self.intra[d] & self.edges[d];
            let coded = self.coded[d] & self.edges[d] & !intra;
            let motion = self.motion[d] & self.edges[d] & !intra & !coded;
            let mut out = [0u8; 16];
            for (y, row) in out.chunks_exact_mut(4).enumerate() {
                let bytes = |mask: u16| SPREAD[usize::from(mask >> (4 * y) & 15)];
                let s = 3 * bytes(intra) + bytes(intra & outer) + 2 * bytes(coded) + bytes(motion);
                row.copy_from_slice(&s.to_le_bytes());
            }
            out
        })
    }
}

/// Byte `k` of `SPREAD[n]` is bit `k` of `n`: four blocks' bits as four
/// bytes.
const SPREAD: [u32; 16] = {
    let mut table = [0u32; 16];
    let mut n = 0;
    while n < 16 {
        let mut k = 0;
        while k < 4 {
            table[n] |= ((n as u32 >> k) & 1) << (8 * k);
            k += 1;
        }
        n += 1;
    }
    table
};

/// All bits where the two 8x8 blocks' motion differs by H.264's rule
/// (another reference, or a component a pel or more apart), none
/// elsewhere (an intra block's or a grid frame's, which have no vector).
fn differs(a: Option<crate::partition::RefMv>, b: Option<crate::partition::RefMv>) -> u16 {
    match (a, b) {
        (Some(a), Some(b))
            if a.ref_idx != b.ref_idx || (a.mv.x - b.mv.x).abs() >= 4 || (a.mv.y - b.mv.y).abs() >= 4 =>
        {
            u16::MAX
        }
        _ => 0,
    }
}

/// Filters macroblock rows `rows` of one plane: `sub` is 1 for luma and
/// 2 for chroma (a chroma sample covers 2x2 luma samples; chroma edges
/// lie on every other luma edge, each chroma row taking the strength of
/// the luma row it covers). The strength is one per piece of edge along
/// a 4x4 luma block (4 luma lines, 2 chroma ones); the kernel takes a
/// macroblock's length of edge, four pieces, at once.
///
/// A line across a vertical edge is filtered only by the vertical edges
/// of its own row, and a horizontal edge reads and writes no further
/// than 4 lines either side, inside its macroblock row and the bottom of
/// the one above. So the picture's order (every vertical edge left to
/// right, then every horizontal one top to bottom) is kept by filtering
/// macroblock rows top to bottom, each row's vertical edges left to
/// right and then its horizontal ones (its top edge first) top to bottom
/// in each macroblock column.
fn filter_plane(plane: &mut Plane, strengths: &Strengths, level: LfLevel, sub: usize, rows: Range<usize>) {
    if !Edge::filters_at(level) {
        return;
    }
    if sub == 1 {
        filter_plane_sized::<1>(plane, strengths, level, rows);
    } else {
        filter_plane_sized::<2>(plane, strengths, level, rows);
    }
}

/// [`filter_plane`] with the plane's subsampling known when compiled.
fn filter_plane_sized<const SUB: usize>(
    plane: &mut Plane,
    strengths: &Strengths,
    level: LfLevel,
    rows: Range<usize>,
) {
    let filter_mb_edge = lf().filter_mb_edge;
    let layout = Layout::of(plane);
    let data = plane.data_mut();
    each_edge::<SUB>(layout, strengths, rows, |at, bs| {
        filter_mb_edge(data, at, bs, level, SUB == 1)
    });
}

/// Both chroma planes' edges of macroblock rows `rows`, each edge of the
/// two at once (a plane's edge fills half of the kernel's lanes).
fn filter_chroma_planes(
    u: &mut Plane,
    v: &mut Plane,
    strengths: &Strengths,
    level: LfLevel,
    rows: Range<usize>,
) {
    if !Edge::filters_at(level) {
        return;
    }
    let filter_chroma_edge = lf().filter_chroma_edge;
    let layout = Layout::of(u);
    assert!(layout == Layout::of(v), "chroma planes laid out alike");
    let (u, v) = (u.data_mut(), v.data_mut());
    each_edge::<2>(layout, strengths, rows, |at, bs| {
        filter_chroma_edge(u, v, at, bs, level)
    });
}

/// A plane's size, row stride and the index of its sample (0, 0).
#[derive(Clone, Copy, PartialEq, Eq)]
struct Layout {
    width: usize,
    height: usize,
    stride: usize,
    origin: usize,
}

impl Layout {
    fn of(plane: &Plane) -> Layout {
        Layout {
            width: plane.width(),
            height: plane.height(),
            stride: plane.stride(),
            origin: plane.index(0, 0),
        }
    }
}

/// Each macroblock's length of edge in macroblock rows `rows` of a plane
/// with subsampling `SUB` known when compiled (the strengths' positions
/// from shifts), in the order of filtering ([`filter_plane`]), to `edge`
/// as the kernels take it: `((first, step, line_step), strengths)`. An
/// edge of four 0 strengths, most of a still or skipped picture's, is
/// passed over.
fn each_edge<const SUB: usize>(
    l: Layout,
    strengths: &Strengths,
    rows: Range<usize>,
    mut edge: impl FnMut((usize, usize, usize), [u8; 4]),
) {
    let mb = 16 / SUB;
    let (top, bottom) = (
        rows.start.saturating_mul(mb).min(l.height),
        rows.end.saturating_mul(mb).min(l.height),
    );
    for y0 in (top..bottom).step_by(mb) {
        for x in (4..l.width).step_by(4) {
            let bx = x * SUB / 4;
            // The four pieces' strengths are those of four luma blocks
            // down (a chroma piece is a luma block's half).
            let bs = strengths.down(bx, y0 * SUB / 4);
            if bs != [0; 4] {
                edge((l.origin + y0 * l.stride + x, 1, l.stride), bs);
            }
        }
        for x0 in (0..l.width).step_by(mb) {
            // The picture's top is no edge.
            for y in (y0.max(4)..y0 + mb).step_by(4) {
                let bs = strengths.along(x0 * SUB / 4, y * SUB / 4);
                if bs != [0; 4] {
                    edge((l.origin + y * l.stride + x0, l.stride, 1), bs);
                }
            }
        }
    }
}

/// The deblocking of one frame, plane by plane: the planes are filtered
/// independently of each other, so a caller may filter them at once on
/// several threads. The strengths may be given a macroblock row at a time
/// ([`FrameDeblocker::progressive`]) and the rows filtered as they come:
/// the same samples as the whole frame's filter.
pub struct FrameDeblocker {
    strengths: Strengths,
    mb_cols: usize,
    strength: DeblockStrength,
}

impl FrameDeblocker {
    /// The filter of a frame of coded size `width x height`, coded at
    /// `strength` (a QP, or a QP and offsets) with macroblocks `info` in
    /// raster order.
    pub fn new(
        info: &[MbEdgeInfo],
        (width, height): (usize, usize),
        strength: impl Into<DeblockStrength>,
    ) -> FrameDeblocker {
        let mut out = FrameDeblocker::progressive((width, height), strength);
        assert_eq!(
            info.len(),
            out.mb_cols * (height / 16),
            "one record per macroblock"
        );
        let mut above = None;
        for (my, row) in info.chunks_exact(out.mb_cols.max(1)).enumerate() {
            out.set_row(my, row, above);
            above = Some(row);
        }
        out
    }

    /// The filter of a frame of coded size `width x height` coded at
    /// `strength`, its macroblocks' records to be given row by row
    /// ([`Self::set_row`]).
    pub fn progressive(
        (width, height): (usize, usize),
        strength: impl Into<DeblockStrength>,
    ) -> FrameDeblocker {
        FrameDeblocker {
            strengths: Strengths::zero((width / 4, height / 4)),
            mb_cols: width / 16,
            strength: strength.into(),
        }
    }

    /// The strength it filters at.
    pub fn strength(&self) -> DeblockStrength {
        self.strength
    }

    /// Macroblock row `my`'s records `row` (raster order), below `above`
    /// (row `my - 1`'s; none for the top row).
    pub fn set_row(&mut self, my: usize, row: &[MbEdgeInfo], above: Option<&[MbEdgeInfo]>) {
        assert_eq!(row.len(), self.mb_cols, "one record per macroblock of the row");
        assert!(
            4 * (my + 1) * self.strengths.cols <= self.strengths.vertical.len(),
            "row {my} in the frame"
        );
        self.strengths.set_row(my, row, above);
    }

    /// Deblocks plane `index` (0 luma, 1 and 2 chroma) of the frame in
    /// place. Borders are not extended.
    pub fn filter(&self, plane: &mut Plane, index: usize) {
        self.filter_rows(plane, index, 0..usize::MAX);
    }

    /// Deblocks macroblock rows `rows` of plane `index` in place, their
    /// records given: the whole frame's filter where every row is
    /// filtered once, top to bottom. A row's filter changes the three
    /// lines above it, and reads the row's own samples as reconstructed
    /// (so the row below must have been predicted from them first).
    pub fn filter_rows(&self, plane: &mut Plane, index: usize, rows: Range<usize>) {
        self.filter_rows_at(plane, index, rows, self.strength);
    }

    /// [`Self::filter_rows`] at `strength` instead of the frame's (an
    /// encoder trying other offsets on a copy).
    pub fn filter_rows_at(
        &self,
        plane: &mut Plane,
        index: usize,
        rows: Range<usize>,
        strength: DeblockStrength,
    ) {
        if index == 0 {
            filter_plane(plane, &self.strengths, strength.luma(), 1, rows);
        } else {
            filter_plane(plane, &self.strengths, strength.chroma(), 2, rows);
        }
    }

    /// Deblocks both chroma planes in place, the same as [`Self::filter`]
    /// on each, in about half the time where the kernel takes both.
    pub fn filter_chroma(&self, u: &mut Plane, v: &mut Plane) {
        self.filter_chroma_rows(u, v, 0..usize::MAX);
    }

    /// [`Self::filter_chroma`] of macroblock rows `rows` (as
    /// [`Self::filter_rows`]).
    pub fn filter_chroma_rows(&self, u: &mut Plane, v: &mut Plane, rows: Range<usize>) {
        filter_chroma_planes(u, v, &self.strengths, self.strength.chroma(), rows);
    }
}

/// Deblocks `frame` (coded size), coded at `strength` (a QP, or a QP and
/// offsets) with macroblocks `info` in raster order, in place. Borders
/// are not extended.
pub fn deblock_frame(frame: &mut Frame, info: &[MbEdgeInfo], strength: impl Into<DeblockStrength>) {
    let deblocker = FrameDeblocker::new(info, (frame.width(), frame.height()), strength);
    let [y, u, v] = frame.planes_mut();
    deblocker.filter(y, 0);
    deblocker.filter_chroma(u, v);
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::mv::Mv;
    use crate::partition::RefMv;

    fn inter(mv: Mv, coded: u16) -> MbEdgeInfo {
        MbEdgeInfo {
            intra: false,
            mvs: [Some(RefMv::previous(mv)); 4],
            coded,
            transform_8x8: false,
        }
    }

    /// Macroblocks of every kind, mostly plain inter ones in runs.
    fn random_info(cols: usize, rows: usize, seed: u32) -> Vec<MbEdgeInfo> {
        let mut seed = seed;
        let mut next = |n: u32| {
            seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
            (seed >> 16) % n
        };
        (0..cols * rows)
            .map(|_| {
                let mv = |k: u32| Mv::new([0, 4, -3, 9][k as usize], [0, 0, 5, -4][k as usize]);
                let shared = next(4);
                let mut m = inter(mv(shared), 0);
                // Each trait on its own or together (levels in the 8x8
                // transform beside a partition, intra in 8x8 blocks, a
                // grid frame's missing vectors).
                if next(6) == 0 {
                    m.intra = true;
                    m.mvs = [None; 4];
                }
                if next(3) == 0 {
                    m.coded = next(1 << 16) as u16;
                }
                for _ in 0..next(3) {
                    let other = [
                        Some(RefMv::previous(mv(next(4)))),
                        None,
                        Some(RefMv {
                            ref_idx: 1,
                            mv: mv(shared),
                        }),
                    ];
                    m.mvs[next(4) as usize] = other[next(3) as usize];
                }
                if next(4) == 0 {
                    m.transform_8x8 = true;
                }
                m
            })
            .collect()
    }

    /// A picture of 4x4 blocks a few levels apart (steps the filter
    /// smooths), with a little noise.
    fn blocky_frame(width: usize, height: usize, seed: u32) -> Frame {
        let mut f = Frame::new(width, height).unwrap();
        let mut seed = seed;
        let mut next = |n: u32| {
            seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12345);
            (seed >> 16) % n
        };
        let levels: Vec<u32> = (0..(width / 4 + 1) * (height / 4 + 1))
            .map(|_| 90 + next(24))
            .collect();
        for (p, plane) in f.planes_mut().iter_mut().enumerate() {
            let sub = if p == 0 { 1 } else { 2 };
            for y in 0..plane.height() {
                for x in 0..plane.width() {
                    let block = (y * sub / 4) * (width / 4 + 1) + x * sub / 4;
                    plane.set(x, y, (levels[block] + next(3)) as u8);
                }
            }
        }
        f
    }

    /// The filter in the picture's order, as FORMAT.md states it: every
    /// vertical edge of a plane left to right, then every horizontal one
    /// top to bottom.
    fn deblock_in_picture_order(frame: &mut Frame, d: &FrameDeblocker) {
        let s = &d.strengths;
        for (p, plane) in frame.planes_mut().iter_mut().enumerate() {
            let (sub, level) = if p == 0 {
                (1, d.strength.luma())
            } else {
                (2, d.strength.chroma())
            };
            if !Edge::filters_at(level) {
                continue;
            }
            let l = Layout::of(plane);
            let data = plane.data_mut();
            let (piece, mb) = (4 / sub, 16 / sub);
            // Four pieces down a vertical edge, along a horizontal one.
            let down = |y: usize, x: usize| -> [u8; 4] {
                std::array::from_fn(|k| s.vertical_at(x * sub / 4, (y + k * piece) * sub / 4))
            };
            let along = |y: usize, x: usize| -> [u8; 4] {
                std::array::from_fn(|k| s.horizontal_at((x + k * piece) * sub / 4, y * sub / 4))
            };
            for y0 in (0..l.height).step_by(mb) {
                for x in (4..l.width).step_by(4) {
                    (lf().filter_mb_edge)(
                        data,
                        (l.origin + y0 * l.stride + x, 1, l.stride),
                        down(y0, x),
                        level,
                        sub == 1,
                    );
                }
            }
            for y in (4..l.height).step_by(4) {
                for x0 in (0..l.width).step_by(mb) {
                    (lf().filter_mb_edge)(
                        data,
                        (l.origin + y * l.stride + x0, l.stride, 1),
                        along(y, x0),
                        level,
                        sub == 1,
                    );
                }
            }
        }
    }

    #[test]
    fn rows_deblocked_as_they_come_are_the_pictures_order() {
        let (cols, rows) = (7, 6);
        for (seed, qp) in [(3, 36), (5, 44), (11, 28)] {
            let info = random_info(cols, rows, seed);
            let source = blocky_frame(16 * cols, 16 * rows, seed);
            let whole = FrameDeblocker::new(&info, (16 * cols, 16 * rows), qp);
            let mut expected = source.clone();
            deblock_in_picture_order(&mut expected, &whole);
            assert_ne!(expected, source, "the filter changed nothing to compare");
            let mut at_once = source.clone();
            deblock_frame(&mut at_once, &info, qp);
            assert_eq!(at_once, expected);
            // Records given a row at a time, rows filtered in runs of
            // 1, 2 and 3 as soon as their records are in.
            for run in 1..=3 {
                let mut d = FrameDeblocker::progressive((16 * cols, 16 * rows), qp);
                let mut out = source.clone();
                let mut done = 0;
                for my in 0..rows {
                    let above = my.checked_sub(1).map(|a| &info[a * cols..my * cols]);
                    d.set_row(my, &info[my * cols..(my + 1) * cols], above);
                    if my + 1 - done == run || my + 1 == rows {
                        let [y, u, v] = out.planes_mut();
                        d.filter_rows(y, 0, done..my + 1);
                        d.filter_chroma_rows(u, v, done..my + 1);
                        done = my + 1;
                    }
                }
                assert_eq!(out, expected, "runs of {run} rows, seed {seed}");
            }
        }
    }

    #[test]
    fn a_frames_strengths_are_each_edges_by_the_definition() {
        let (cols, rows) = (23, 17);
        let info = random_info(cols, rows, 17);
        let s = FrameDeblocker::new(&info, (16 * cols, 16 * rows), 30).strengths;
        for by in 0..4 * rows {
            for bx in 0..4 * cols {
                let v = if bx > 0 {
                    strength(&info, cols, (bx - 1, by), (bx, by))
                } else {
                    0
                };
                let h = if by > 0 {
                    strength(&info, cols, (bx, by - 1), (bx, by))
                } else {
                    0
                };
                assert_eq!(
                    (s.vertical_at(bx, by), s.horizontal_at(bx, by)),
                    (v, h),
                    "block ({bx}, {by})"
                );
            }
        }
    }

    #[test]
    fn strengths_follow_h264s_rules() {
        let intra = MbEdgeInfo {
            intra: true,
            mvs: [None; 4],
            coded: 0,
            transform_8x8: false,
        };
        let still = inter(Mv::ZERO, 0);
        // Two macroblocks side by side: block (3, y) | (4, y) is their edge.
        assert_eq!(strength(&[intra, still], 2, (3, 0), (4, 0)), 4);
        assert_eq!(strength(&[intra, still], 2, (0, 0), (1, 0)), 3);
        assert_eq!(strength(&[still, inter(Mv::ZERO, 1 << 4)], 2, (3, 1), (4, 1)), 2);
        assert_eq!(strength(&[still, inter(Mv::ZERO, 1 << 4)], 2, (3, 0), (4, 0)), 0);
        assert_eq!(strength(&[still, inter(Mv::new(4, 0), 0)], 2, (3, 0), (4, 0)), 1);
        assert_eq!(strength(&[still, inter(Mv::new(3, -3), 0)], 2, (3, 0), (4, 0)), 0);
        // Equal vectors into different references: bS 1.
        let other_reference = MbEdgeInfo {
            mvs: [Some(RefMv::new(Mv::ZERO, 1)); 4],
            ..still
        };
        assert_eq!(strength(&[still, other_reference], 2, (3, 0), (4, 0)), 1);
        // Inside one macroblock, vectors are one: no strength from them.
        assert_eq!(strength(&[inter(Mv::new(9, 9), 0)], 1, (0, 0), (1, 0)), 0);
        // ... unless it is split: its partitions' edge (x = 8) compares
        // their vectors, the 4x4 edges inside a partition do not.
        let split = MbEdgeInfo {
            mvs: [Mv::ZERO, Mv::new(0, 8), Mv::ZERO, Mv::new(0, 8)].map(|m| Some(RefMv::previous(m))),
            ..inter(Mv::ZERO, 0)
        };
        assert_eq!(strength(&[split], 1, (1, 2), (2, 2)), 1);
        assert_eq!(strength(&[split], 1, (0, 2), (1, 2)), 0);
        assert_eq!(strength(&[split], 1, (2, 1), (2, 2)), 0);
        // With the 8x8 transform, coded blocks inside an 8x8 block have no
        // edge between them; the 8x8 blocks' own edges keep theirs.
        let t8 = MbEdgeInfo {
            transform_8x8: true,
            ..inter(Mv::ZERO, 0xffff)
        };
        for (p, q, bs) in [
            ((0, 1), (1, 1), 0),
            ((2, 3), (3, 3), 0),
            ((1, 0), (1, 1), 0),
            ((1, 2), (1, 3), 0),
            ((1, 1), (2, 1), 2),
            ((3, 1), (3, 2), 2),
        ] {
            assert_eq!(strength(&[t8], 1, p, q), bs, "{p:?} {q:?}");
            let t4 = MbEdgeInfo {
                transform_8x8: false,
                ..t8
            };
            assert_eq!(strength(&[t4], 1, p, q), 2, "{p:?} {q:?}");
        }
    }

    #[test]
    fn intra_in_8x8_blocks_has_no_edges_inside_them_even_without_levels() {
        use crate::intra::IntraMode;
        use crate::intra4x4::{Intra4x4Mode, LumaIntra};
        use crate::residual::MbResidual;
        let kind = |luma| MbKind::Intra {
            luma,
            chroma: IntraMode::Dc,
        };
        let none = MbResidual::default();
        let in8 = MbEdgeInfo::of(
            &kind(LumaIntra::Blocks8([Intra4x4Mode::Dc; 4])),
            &none,
            MotionTool::Block,
            [None; 4],
        );
        let in4 = MbEdgeInfo::of(
            &kind(LumaIntra::Blocks([Intra4x4Mode::Dc; 16])),
            &none,
            MotionTool::Block,
            [None; 4],
        );
        // x = 4 inside 8x8 block 0; x = 8 between blocks 0 and 1.
        assert_eq!(strength(&[in8], 1, (0, 0), (1, 0)), 0);
        assert_eq!(strength(&[in8], 1, (1, 0), (2, 0)), 3);
        assert_eq!(strength(&[in4], 1, (0, 0), (1, 0)), 3);
    }

    #[test]
    fn edges_of_strength_0_and_flat_pictures_are_left_alone() {
        // Inter macroblocks with one vector and nothing coded: every bS is
        // 0, so even a blocky picture stays as it is.
        let mut blocky = Frame::new(32, 32).unwrap();
        for y in 0..32 {
            for x in 0..32 {
                blocky.planes_mut()[0].set(x, y, if (x / 4 + y / 4) % 2 == 0 { 100 } else { 104 });
            }
        }
        let before = blocky.clone();
        deblock_frame(&mut blocky, &[inter(Mv::new(6, 2), 0); 4], 40);
        assert_eq!(blocky, before);
        // Intra (bS 3 and 4) on a flat picture: nothing to smooth.
        let mut flat = Frame::filled(32, 32, 90, 128, 128).unwrap();
        let intra = MbEdgeInfo {
            intra: true,
            mvs: [None; 4],
            coded: 0,
            transform_8x8: false,
        };
        deblock_frame(&mut flat, &[intra; 4], 51);
        assert_eq!(flat, Frame::filled(32, 32, 90, 128, 128).unwrap());
        // The same blocky picture, intra at QP 40: its 4 px steps go.
        deblock_frame(&mut blocky, &[intra; 4], 40);
        assert_ne!(blocky, before);
    }

    /// One row across a vertical edge at x = 4 of an 8-wide picture,
    /// sixteen times, filtered at `level` with strength `bs`: the row.
    fn run_at(samples: [u8; 8], bs: u8, level: LfLevel) -> Vec<u8> {
        let mut d = samples.repeat(16);
        (crate::dsp::lf::LF.at(crate::cpu::CpuLevel::Scalar).filter_mb_edge)(
            &mut d,
            (4, 1, 8),
            [bs; 4],
            level,
            true,
        );
        let line = d[..8].to_vec();
        assert!(d.chunks(8).all(|l| l == line), "every line alike");
        line
    }

    #[test]
    fn the_headers_offsets_move_the_thresholds_as_h264s() {
        let step = [100, 100, 100, 100, 160, 160, 160, 160];
        // QP 36: alpha 50, a step of 60 is an edge and kept.
        assert_eq!(run_at(step, 2, LfLevel::at(36)), step);
        // indexA 36 + 6 (alpha 101): an artefact, smoothed.
        let smoothed = run_at(step, 2, LfLevel::new(36, (6, 0)));
        assert!(smoothed[3] > 100 && smoothed[4] < 160, "{smoothed:?}");
        // The same step at QP 44 (alpha 127) kept with alpha's offset -12
        // (indexA 32, alpha 36)...
        assert_eq!(run_at(step, 2, LfLevel::new(44, (-12, 0))), step);
        // ... and with beta's (indexB 32, beta 9) where the sides are not
        // flat within it, though alpha passes.
        let rough = [100, 100, 90, 100, 160, 170, 160, 160];
        assert_ne!(run_at(rough, 2, LfLevel::at(44)), rough);
        assert_eq!(run_at(rough, 2, LfLevel::new(44, (0, -12))), rough);
        // tc0 follows indexA: at bS 1 the move is bounded by tc0 + 1 with
        // flat sides (ap, aq both hold).
        let small = [100, 100, 100, 100, 130, 130, 130, 130];
        let moved = |level| {
            let line = run_at(small, 1, level);
            i32::from(line[3]) - 100
        };
        assert_eq!(moved(LfLevel::at(36)), 4, "tc0 2, plus 1 for each flat side");
        assert_eq!(
            moved(LfLevel::new(36, (12, 0))),
            11,
            "tc0 9: the step's own delta"
        );
        // Out of 0..=51 the indices clamp.
        assert_eq!(LfLevel::new(50, (12, 12)), LfLevel { a: 51, b: 51 });
        assert_eq!(LfLevel::new(5, (-12, -12)), LfLevel { a: 0, b: 0 });
    }

    #[test]
    fn a_step_below_alpha_is_smoothed_and_a_real_edge_kept() {
        // One row across a vertical edge at x = 4 of an 8-wide picture.
        let line = |p: u8, q: u8| [p, p, p, p, q, q, q, q];
        let run = |samples: [u8; 8], bs: u8, qp: u8| run_at(samples, bs, LfLevel::at(qp));
        // QP 36: alpha 63. A step of 10 is an artefact: smoothed into a
        // ramp that still rises, p0 and q0 moved by the same amount.
        let smoothed = run(line(100, 110), 2, 36);
        assert!(smoothed[3] > 100 && smoothed[4] < 110, "{smoothed:?}");
        assert!(smoothed.windows(2).all(|w| w[0] <= w[1]), "{smoothed:?}");
        assert_eq!(smoothed[3] - 100, 110 - smoothed[4]);
        // A step of 80 (above alpha) is an edge of the picture: kept.
        assert_eq!(run(line(60, 140), 4, 36), line(60, 140).to_vec());
        // Below QP 16 nothing is filtered.
        assert_eq!(run(line(100, 104), 4, 15), line(100, 104).to_vec());
        // bS 4 on a flat step: the strong filter spreads it over 3 samples
        // each side.
        let strong = run(line(100, 108), 4, 36);
        assert!(strong[1] > 100 && strong[6] < 108, "{strong:?}");
    }
}
