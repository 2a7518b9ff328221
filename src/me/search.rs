//! The search patterns: full-pel search per method, then sub-pel refinement.

use super::halfpel::PhaseWindow;
use super::pipeline::SharedGrid;
use super::sea::max_diff;
use super::{Candidate, Method, Metric, MotionField, SearchContext, Subpel};
use crate::codec::mv::Mv;

/// Candidate vectors from neighbouring blocks, for predictive methods.
pub(crate) struct Neighbours {
    /// At most the predictor, three neighbours and three prior vectors
    /// (and zero, for [`Neighbours::list`]).
    candidates: [Mv; 8],
    len: usize,
}

impl Neighbours {
    /// The left, top and top-right blocks of `field` (final when read: see
    /// [`super::pipeline`]), the median predictor, and the co-located,
    /// right and lower blocks of the previous field.
    pub(crate) fn of(field: &SharedGrid, prior: Option<&MotionField>, col: usize, row: usize) -> Neighbours {
        let mut n = Neighbours {
            candidates: [Mv::ZERO; 8],
            len: 0,
        };
        n.push(field.predictor(col, row));
        if col > 0 {
            n.push(field.vector(col - 1, row));
        }
        if row > 0 {
            n.push(field.vector(col, row - 1));
            if col + 1 < field.cols() {
                n.push(field.vector(col + 1, row - 1));
            }
        }
        if let Some(p) = prior {
            n.push(p.vector(col, row));
            if col + 1 < p.cols() {
                n.push(p.vector(col + 1, row));
            }
            if row + 1 < p.rows() {
                n.push(p.vector(col, row + 1));
            }
        }
        n
    }

    /// The predicted vector `mvp`, then `others` (at most six), then zero
    /// (x264's candidates: a still background is found even where the
    /// neighbours' vectors drifted).
    pub(crate) fn list(mvp: Mv, others: impl IntoIterator<Item = Mv>) -> Neighbours {
        let mut n = Neighbours::single(mvp);
        for mv in others.into_iter().take(6) {
            n.push(mv);
        }
        n.push(Mv::ZERO);
        n
    }

    /// Only `mv` (a seeded search's predicted vector).
    pub(crate) fn single(mv: Mv) -> Neighbours {
        let mut n = Neighbours {
            candidates: [Mv::ZERO; 8],
            len: 0,
        };
        n.push(mv);
        n
    }

    fn push(&mut self, mv: Mv) {
        self.candidates[self.len] = mv;
        self.len += 1;
    }

    pub(crate) fn candidates(&self) -> &[Mv] {
        &self.candidates[..self.len]
    }
}

/// One bit per position of the search window: on the stack up to range 32,
/// the presets' (a search per block would otherwise allocate and free every
/// time).
#[allow(clippy::large_enum_variant)] // the array is on the stack on purpose
enum Seen {
    Stack([u64; SEEN_STACK_WORDS]),
    Heap(Vec<u64>),
}

/// The words of a window of range 32: 65 x 65 bits.
const SEEN_STACK_WORDS: usize = (65 * 65usize).div_ceil(64);

impl Seen {
    fn new(bits: usize) -> Seen {
        let words = bits.div_ceil(64);
        if words <= SEEN_STACK_WORDS {
            Seen::Stack([0; SEEN_STACK_WORDS])
        } else {
            Seen::Heap(vec![0; words])
        }
    }

    fn words(&mut self) -> &mut [u64] {
        match self {
            Seen::Stack(w) => w,
            Seen::Heap(w) => w,
        }
    }
}

/// A walk over full-pel positions of the window (`range` around the
/// context's origin), remembering the best and which positions were already
/// evaluated.
struct Walk<'s, 'p> {
    s: &'s SearchContext<'p>,
    origin: (i32, i32),
    range: i32,
    side: usize,
    seen: Seen,
    best: Candidate,
}

impl<'s, 'p> Walk<'s, 'p> {
    fn new(s: &'s SearchContext<'p>) -> Walk<'s, 'p> {
        let range = s.cfg.range;
        let side = (2 * range + 1) as usize;
        let mut walk = Walk {
            s,
            origin: s.origin,
            range,
            side,
            seen: Seen::new(side * side),
            best: Candidate {
                cost: u64::MAX,
                mv: Mv::ZERO,
            },
        };
        walk.try_at(s.origin.0, s.origin.1);
        walk
    }

    /// Evaluates (dx, dy) if inside the window and new; true if it became the best.
    #[inline]
    fn try_at(&mut self, dx: i32, dy: i32) -> bool {
        // From the window's corner: one unsigned comparison per axis.
        let (wx, wy) = (dx - self.origin.0 + self.range, dy - self.origin.1 + self.range);
        let side = self.side as u32;
        if wx as u32 >= side || wy as u32 >= side {
            return false;
        }
        if !self.mark_seen(wx as usize, wy as usize) {
            return false;
        }
        let cost = self.s.full_pel_cost(dx, dy, self.best.cost);
        if cost > self.best.cost {
            return false;
        }
        let c = Candidate {
            cost,
            mv: Mv::full_pel(dx, dy),
        };
        let better = c.beats(&self.best);
        if better {
            self.best = c;
        }
        better
    }

    /// Marks window position (wx, wy) (from the window's corner) seen;
    /// false if it already was.
    #[inline]
    fn mark_seen(&mut self, wx: usize, wy: usize) -> bool {
        let i = wy * self.side + wx;
        let (word, bit) = (&mut self.seen.words()[i / 64], 1u64 << (i % 64));
        let new = *word & bit == 0;
        *word |= bit;
        new
    }

    /// Evaluates (dx, dy), with `rate` its rate term, where the caller
    /// knows the position lies in the window and the block inside the
    /// reference's buffer at `at` (its index there): [`Walk::try_at`]
    /// without the checks, for the survivors of successive elimination.
    /// Not marked seen: evaluating a position twice changes nothing (its
    /// cost is the same, and only a strictly better key replaces the best).
    #[inline]
    fn try_inside(&mut self, dx: i32, dy: i32, at: usize, rate: u64) {
        let cap = self.best.cost.saturating_sub(rate).min(u64::from(u32::MAX)) as u32;
        let cost = u64::from(self.s.distortion_at(at, cap)) + rate;
        self.keep_if_better(dx, dy, cost);
    }

    /// Whether a position of row `dy` with its column in `dxs` can beat
    /// the best: always, unless the best costs nothing, when only the
    /// tie-break (the shorter vector first) can, so only positions no
    /// farther from the zero vector than the best's. On flat areas (a black
    /// border, a dark scene) every position costs nothing; this keeps the
    /// exhaustive search from comparing each of them.
    fn could_improve_on(&self, dy: i32, dxs: std::ops::RangeInclusive<i32>) -> bool {
        if self.best.cost > 0 {
            return true;
        }
        let nearest = if dxs.contains(&0) {
            0
        } else {
            dxs.start().abs().min(dxs.end().abs())
        };
        let length = |x: i32, y: i32| i64::from(4 * x).pow(2) + i64::from(4 * y).pow(2);
        let best = i64::from(self.best.mv.x).pow(2) + i64::from(self.best.mv.y).pow(2);
        length(nearest, dy) <= best
    }

    /// Makes (dx, dy) at `cost` the best if it beats it (the tie-break
    /// only on equal costs).
    #[inline]
    fn keep_if_better(&mut self, dx: i32, dy: i32, cost: u64) {
        if cost > self.best.cost {
            return;
        }
        let c = Candidate {
            cost,
            mv: Mv::full_pel(dx, dy),
        };
        if cost < self.best.cost || c.beats(&self.best) {
            self.best = c;
        }
    }

    /// The best position so far, full-pel.
    fn centre(&self) -> (i32, i32) {
        (self.best.mv.x / 4, self.best.mv.y / 4)
    }

    /// The best position so far, full-pel, from the window's centre.
    fn offset_from_origin(&self) -> (i32, i32) {
        let (cx, cy) = self.centre();
        (cx - self.origin.0, cy - self.origin.1)
    }

    /// Evaluates `offsets * step` around the current best; true if it moved.
    fn pattern(&mut self, offsets: &[(i32, i32)], step: i32) -> bool {
        let (cx, cy) = self.centre();
        let mut moved = false;
        for &(ox, oy) in offsets {
            moved |= self.try_at(cx + ox * step, cy + oy * step);
        }
        moved
    }
}

/// The eight steps around a position.
pub(crate) const SQUARE: [(i32, i32); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];
const CROSS: [(i32, i32); 4] = [(0, -1), (-1, 0), (1, 0), (0, 1)];
const LARGE_DIAMOND: [(i32, i32); 8] = [
    (0, -2),
    (-1, -1),
    (1, -1),
    (-2, 0),
    (2, 0),
    (-1, 1),
    (1, 1),
    (0, 2),
];
const HEXAGON: [(i32, i32); 6] = [(-1, -2), (1, -2), (-2, 0), (2, 0), (-1, 2), (1, 2)];

/// The full-pel search of one block.
pub(crate) fn full_pel(s: &SearchContext<'_>, neighbours: &Neighbours) -> Candidate {
    let mut w = Walk::new(s);
    let r = s.cfg.range;
    let (ox, oy) = s.origin;
    // Half the range, rounded (ffmpeg's ROUNDED_DIV(range, 2)): the first step
    // of the logarithmic searches.
    let half = (r + 1) / 2;
    match s.cfg.method {
        Method::Esa => exhaustive(&mut w, (ox, oy), r),
        Method::Tss => {
            let mut step = half;
            while step > 0 {
                w.pattern(&SQUARE, step);
                step /= 2;
            }
        }
        Method::Ntss => {
            let mut step = half;
            w.pattern(&SQUARE, step);
            w.pattern(&SQUARE, 1);
            let (cx, cy) = w.offset_from_origin();
            if (cx, cy) == (0, 0) {
                return w.best;
            }
            if cx.abs() <= 1 && cy.abs() <= 1 {
                // The minimum is next to the centre: its neighbours, then stop.
                w.pattern(&SQUARE, 1);
                return w.best;
            }
            step /= 2;
            while step > 0 {
                w.pattern(&SQUARE, step);
                step /= 2;
            }
        }
        Method::Tdls => {
            let mut step = half;
            while step > 0 {
                if !w.pattern(&CROSS, step) {
                    step /= 2;
                }
            }
        }
        Method::Fss => {
            let mut step = 2;
            while step > 0 {
                if !w.pattern(&SQUARE, step) {
                    step /= 2;
                }
            }
        }
        Method::Ds => {
            while w.pattern(&LARGE_DIAMOND, 1) {}
            w.pattern(&CROSS, 1);
        }
        Method::Hexbs => {
            while w.pattern(&HEXAGON, 1) {}
            w.pattern(&CROSS, 1);
        }
        Method::Epzs => {
            for mv in neighbours.candidates() {
                // Quarter-pel candidates, rounded to the nearest full pel.
                let (dx, dy) = super::nearest_full_pel(*mv);
                w.try_at(dx, dy);
            }
            while w.pattern(&CROSS, 1) {}
            // Every position near the best (MeConfig::window): flat shapes
            // over smooth backgrounds leave the descent in a local minimum.
            let r = w.s.cfg.window;
            if r > 0 {
                let centre = w.centre();
                exhaustive(&mut w, centre, r);
                while w.pattern(&CROSS, 1) {}
            }
        }
    }
    w.best
}

/// The quadrant bounds of an exhaustive window, and the least of each of
/// its rows.
#[derive(Default)]
struct WindowBounds {
    all: Vec<u16>,
    row_least: Vec<u16>,
}

thread_local! {
    /// The bounds' buffers, reused from block to block.
    static BOUNDS: std::cell::RefCell<WindowBounds> = std::cell::RefCell::new(WindowBounds::default());
}

/// Every position within `r` of `centre` (inside the walk's window): all of
/// them, or with the reference's quadrant sums (successive elimination,
/// [`super::sea`]) only those whose lower bound does not exceed the best
/// cost so far. The same minimum either way: a position skipped costs more
/// than one evaluated, and the tie-break is an order of its own.
fn exhaustive(w: &mut Walk<'_, '_>, (cx, cy): (i32, i32), r: i32) {
    // The window, clipped to the walk's.
    let (ox, oy, range) = (w.origin.0, w.origin.1, w.range);
    let (xs, ys) = (
        (cx - r).max(ox - range)..=(cx + r).min(ox + range),
        (cy - r).max(oy - range)..=(cy + r).min(oy + range),
    );
    let sums =
        w.s.sums
            .filter(|_| super::sea::pays(w.s.cfg.full_pel_metric(), r));
    let Some(sums) = sums else {
        for dy in ys {
            if !by_row_kernel(w, xs.clone(), dy) {
                for dx in xs.clone() {
                    w.try_at(dx, dy);
                }
            }
        }
        return;
    };
    // Bounds where the block lies inside the reference's buffer; elsewhere
    // (a window past the border) every position is evaluated.
    let [x0, x1, y0, y1] = w.s.in_place;
    let (bx, by) = (
        (*xs.start()).max(x0)..=(*xs.end()).min(x1),
        (*ys.start()).max(y0)..=(*ys.end()).min(y1),
    );
    if bx != xs || by != ys {
        for dy in ys {
            for dx in xs.clone() {
                if !(bx.contains(&dx) && by.contains(&dy)) {
                    w.try_at(dx, dy);
                }
            }
        }
    }
    if bx.is_empty() || by.is_empty() {
        return;
    }
    BOUNDS.with(|cell| {
        let mut bounds = std::mem::take(&mut *cell.borrow_mut());
        eliminate(w, sums, (bx, by), &mut bounds);
        *cell.borrow_mut() = bounds;
    });
}

/// Evaluates the positions `xs` of row `dy` (inside the walk's window) by
/// the row kernel's sixteen 16x16 SADs from the first (SAD, uncapped, the
/// sixteen blocks inside the reference's buffer): the cost of about two
/// SADs for a window row of up to sixteen. Marks them seen, as
/// [`Walk::try_at`] does; false (nothing done) where the kernel does not
/// apply. The same best as evaluating them one by one: the tie-break is an
/// order of its own.
fn by_row_kernel(w: &mut Walk<'_, '_>, xs: std::ops::RangeInclusive<i32>, dy: i32) -> bool {
    let s = w.s;
    let [x0, x1, y0, y1] = s.in_place;
    let x_lo = *xs.start();
    let usable = s.cfg.successive_elimination
        && s.cfg.full_pel_metric() == Metric::Sad
        && s.cfg.block == 16
        && s.capped.is_none()
        && xs.end() - x_lo < 16
        && x_lo >= x0
        && x_lo + 15 <= x1
        && (y0..=y1).contains(&dy);
    if !usable {
        return false;
    }
    let (at, stride) = (
        s.reference.index(s.x + x_lo as isize, s.y + dy as isize),
        s.reference.stride(),
    );
    let data = &s.reference.data()[at..];
    if data.len() < 15 * stride + 32 {
        return false;
    }
    let mut sads = [0u32; 16];
    let least = (super::dsp::pixel().sad_16x16_row)(s.block, s.cur.stride(), data, stride, &mut sads);
    let wy = (dy - w.origin.1 + w.range) as usize;
    let check = u64::from(least) <= w.best.cost;
    for dx in xs {
        let wx = (dx - w.origin.0 + w.range) as usize;
        if !w.mark_seen(wx, wy) || !check {
            continue;
        }
        let sad = u64::from(sads[(dx - x_lo) as usize]);
        if sad <= w.best.cost {
            w.keep_if_better(dx, dy, sad + s.rate(Mv::full_pel(dx, dy)));
        }
    }
    true
}

/// Successive elimination over the positions `xs` x `ys`, all with the
/// block inside the reference's buffer: their quadrant bounds, the least
/// bound's position first (it sets a best that rules out most), then every
/// position whose bound does not exceed the best so far, in raster order.
fn eliminate(
    w: &mut Walk<'_, '_>,
    sums: &super::sea::QuadrantSums,
    (xs, ys): (std::ops::RangeInclusive<i32>, std::ops::RangeInclusive<i32>),
    bounds: &mut WindowBounds,
) {
    use super::sea::{current_sums, RowBounds};
    let s = w.s;
    let b = s.cfg.block;
    let (metric, samples) = (s.cfg.full_pel_metric(), (b * b / 4) as u32);
    let rows = RowBounds {
        sums,
        current: current_sums(s.block, s.cur.stride(), b, super::dsp::pixel()),
        ads: super::dsp::pixel().ads,
    };
    let (x_lo, y_lo) = (*xs.start(), *ys.start());
    let width = (xs.end() - x_lo + 1) as usize;
    // Every entry is written by the bounds below: no clearing.
    bounds.all.resize(width * ys.clone().count(), 0);
    bounds.row_least.clear();
    for (dy, row) in ys.clone().zip(bounds.all.chunks_exact_mut(width)) {
        let at = s.reference.index(s.x + x_lo as isize, s.y + dy as isize);
        bounds.row_least.push(rows.row(at, width, row));
    }
    let (corner, stride) = (
        s.reference.index(s.x + x_lo as isize, s.y + y_lo as isize),
        s.reference.stride(),
    );
    // The first position of the least bound, found from the rows' least.
    let min = bounds.row_least.iter().fold(u16::MAX, |m, &d| m.min(d));
    let least_row = bounds.row_least.iter().position(|&d| d == min).unwrap_or(0);
    let line = &bounds.all[least_row * width..(least_row + 1) * width];
    let least_col = line.iter().position(|&d| d == min).unwrap_or(0);
    w.try_at(x_lo + least_col as i32, y_lo + least_row as i32);
    let window = Survivors {
        corner: (x_lo, y_lo),
        at: corner,
        stride,
        metric,
        samples,
        // 16x16 SADs a row of 16 positions at a time where the kernel
        // pays: noisy content leaves most positions above their bound.
        row_kernel: (metric == Metric::Sad && s.cfg.block == 16 && s.capped.is_none())
            .then(|| super::dsp::pixel().sad_16x16_row),
    };
    for (row, (line, &least)) in bounds.all.chunks_exact(width).zip(&bounds.row_least).enumerate() {
        // Most rows hold no survivor: their least bound says so.
        if u64::from(least) <= max_diff(metric, w.best.cost, samples) {
            window.evaluate_row(w, row, line);
        }
    }
}

/// Where the positions of an exhaustive window lie, and how their
/// distortion is computed, for [`eliminate`].
struct Survivors {
    /// The window's first position (dx, dy).
    corner: (i32, i32),
    /// The reference's buffer index of the first position's block.
    at: usize,
    stride: usize,
    metric: Metric,
    samples: u32,
    row_kernel: Option<super::dsp::SadRowFn>,
}

/// Surviving positions in a run of 16 from which the row kernel is used.
const ROW_KERNEL_FROM: usize = 2;

impl Survivors {
    /// Evaluates the positions of window row `row` (bounds `line`) whose
    /// bound does not exceed the best so far, in runs of 16: most runs hold
    /// none (their count, a vector operation, is taken first).
    fn evaluate_row(&self, w: &mut Walk<'_, '_>, row: usize, line: &[u16]) {
        let s = w.s;
        let dy = self.corner.1 + row as i32;
        let limit_of = |best: u64| max_diff(self.metric, best, self.samples).min(u64::from(u16::MAX)) as u16;
        let mut start = 0;
        while start < line.len() {
            let first = start;
            let run = &line[first..(first + 16).min(line.len())];
            start = first + 16;
            let dxs = self.corner.0 + first as i32..=self.corner.0 + (first + run.len() - 1) as i32;
            if !w.could_improve_on(dy, dxs) {
                continue;
            }
            let limit = limit_of(w.best.cost);
            let survivors = run.iter().filter(|&&d| d <= limit).count();
            if survivors == 0 {
                continue;
            }
            let at = self.at + row * self.stride + first;
            let data = &s.reference.data()[at..];
            let kernel = self.row_kernel.filter(|_| {
                survivors >= ROW_KERNEL_FROM && run.len() == 16 && data.len() >= 15 * self.stride + 32
            });
            if let Some(kernel) = kernel {
                let mut sads = [0u32; 16];
                let least = kernel(s.block, s.cur.stride(), data, self.stride, &mut sads);
                // Only a SAD within the best so far can make a better cost:
                // most runs hold none.
                let best = w.best.cost;
                if u64::from(least) > best {
                    continue;
                }
                let mut within = (0..16).fold(0u32, |m, j| m | u32::from(u64::from(sads[j]) <= best) << j);
                while within != 0 {
                    let j = within.trailing_zeros() as usize;
                    within &= within - 1;
                    let dx = self.corner.0 + (first + j) as i32;
                    w.keep_if_better(dx, dy, u64::from(sads[j]) + s.rate(Mv::full_pel(dx, dy)));
                }
                continue;
            }
            for (j, &d) in run.iter().enumerate() {
                let best = w.best.cost;
                if d > limit_of(best) {
                    continue;
                }
                let dx = self.corner.0 + (first + j) as i32;
                // The rate term only where the distortion's bound leaves room.
                let rate = s.rate(Mv::full_pel(dx, dy));
                if super::sea::bound_for(self.metric, u32::from(d), self.samples) + rate > best {
                    continue;
                }
                w.try_inside(dx, dy, at + j, rate);
            }
        }
    }
}

/// Half-pel, then quarter-pel refinement around the full-pel best, on the
/// codec's interpolation: at each step the four neighbours across, then the
/// one diagonal between the better horizontal and the better vertical of
/// them (five candidates instead of the square's eight; on the encoder's
/// three test sequences the square bought 0.2 % in BD-rate at most, for
/// 60 % more sub-pel work), again around the new best while it moves, up
/// to [`MeConfig::subpel_moves`](super::MeConfig::subpel_moves) times a
/// step.
pub(crate) fn refine(s: &SearchContext<'_>, best: Candidate) -> Candidate {
    let mut refinement = Refinement::new(best);
    refinement.run(s, None);
    refinement.best
}

/// A sub-pel refinement under way ([`refine`]), which may be taken a part
/// at a time: the best so far, the step being taken and its moves so far.
pub(crate) struct Refinement {
    pub best: Candidate,
    step: usize,
    moves: u8,
}

/// How far a step's candidates may lie from the full-pel position a
/// half-pel patch is filled around, in quarter pels, before and after it:
/// the blocks one pel before it and at it, and the sample after each
/// (`halfpel::with_patch`).
const PATCH_REACH: (i32, i32) = (-4, 3);

impl Refinement {
    pub(crate) fn new(best: Candidate) -> Refinement {
        Refinement {
            best,
            step: 0,
            moves: 0,
        }
    }

    /// Takes the refinement's steps; with `centre` (the full-pel position
    /// a patch holds), only while each step's candidates lie within
    /// [`PATCH_REACH`] of it. True once the refinement is done; false
    /// where the next step needs a patch around the best instead.
    pub(crate) fn run(&mut self, s: &SearchContext<'_>, centre: Option<(i32, i32)>) -> bool {
        let steps: &[i32] = match s.cfg.subpel {
            Subpel::None => return true,
            Subpel::Half => &[2],
            Subpel::Quarter => &[2, 1],
        };
        let window = s
            .halfpel
            .and_then(|h| h.window(s.reference, (s.x, s.y), s.cfg.block));
        super::with_scratch(s.cfg.block, |scratch| {
            self.steps(s, steps, centre, window.as_ref(), scratch)
        })
    }

    /// [`Refinement::run`]'s walk through `steps`, its candidates
    /// predicted into `scratch` where they need it.
    fn steps(
        &mut self,
        s: &SearchContext<'_>,
        steps: &[i32],
        centre: Option<(i32, i32)>,
        window: Option<&PhaseWindow<'_>>,
        scratch: &mut [u8],
    ) -> bool {
        while let Some(&step) = steps.get(self.step) {
            if self.moves < s.cfg.subpel_moves {
                let fits = |v: i32, c: i32| {
                    let at = v - 4 * c;
                    at - step >= PATCH_REACH.0 && at + step <= PATCH_REACH.1
                };
                if centre.is_some_and(|(cx, cy)| !(fits(self.best.mv.x, cx) && fits(self.best.mv.y, cy))) {
                    return false;
                }
                let before = self.best.mv;
                sub_pel_step(s, step, &mut self.best, window, scratch);
                self.moves += 1;
                if self.best.mv != before {
                    continue;
                }
            }
            (self.step, self.moves) = (self.step + 1, 0);
        }
        true
    }
}

/// One sub-pel step of `step` quarter pels around `best` (see [`refine`]).
fn sub_pel_step(
    s: &SearchContext<'_>,
    step: i32,
    best: &mut Candidate,
    window: Option<&PhaseWindow<'_>>,
    scratch: &mut [u8],
) {
    let centre = best.mv;
    let mut try_offset = |(ox, oy): (i32, i32), best: &mut Candidate| -> u64 {
        let mv = Mv::new(centre.x + ox * step, centre.y + oy * step);
        let c = Candidate {
            cost: s.sub_pel_cost_in(window, mv, scratch),
            mv,
        };
        if c.beats(best) {
            *best = c;
        }
        c.cost
    };
    let [up, left, right, down] = CROSS.map(|o| try_offset(o, best));
    let dx = if left <= right { -1 } else { 1 };
    let dy = if up <= down { -1 } else { 1 };
    try_offset((dx, dy), best);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec::Plane;
    use crate::me::{MeConfig, SearchContext};

    /// A block predicted at a known quarter-pel vector 1.75 and 1.25 pels
    /// from where the refinement starts: one move a step stops short of
    /// it (a half and a quarter pel at most), four moves reach it exactly.
    #[test]
    fn sub_pel_moves_walk_to_a_vector_beyond_one_step() {
        let mut reference = Plane::from_fn(64, 64, |x, y| {
            let (x, y) = (x as f64, y as f64);
            (128.0 + 60.0 * (x / 6.0).sin() * (y / 7.0).cos()).round() as u8
        })
        .unwrap();
        reference.extend_border();
        let truth = Mv::new(7, -5);
        let cur = crate::me::tests::block_moved_by(&reference, 24, truth);
        let found = |moves: u8| {
            let cfg = MeConfig {
                subpel: Subpel::Quarter,
                metric: Metric::Satd,
                subpel_moves: moves,
                ..MeConfig::new(Method::Epzs, 16, 16)
            };
            let s = SearchContext::new(&cur, &reference, (24, 24), &cfg);
            let mut scratch = [0u8; 256];
            let start = Candidate {
                cost: s.sub_pel_cost(Mv::ZERO, &mut scratch),
                mv: Mv::ZERO,
            };
            refine(&s, start)
        };
        let once = found(1);
        assert!(once.mv.x.abs() <= 3 && once.mv.y.abs() <= 3, "{:?}", once.mv);
        let walked = found(4);
        assert_eq!((walked.mv, walked.cost), (truth, 0));
        for moves in [0, crate::me::MAX_SUBPEL_MOVES + 1] {
            let cfg = MeConfig {
                subpel_moves: moves,
                ..MeConfig::new(Method::Epzs, 16, 16)
            };
            assert_eq!(cfg.check(), Err(crate::me::MeError::SubpelMoves(moves)));
        }
    }
}
