//! Pictures: padded 8-bit planes and 4:2:0 frames.
//!
//! Every plane carries a border of `pad` pixels on each side. After the
//! visible pixels change, [`Plane::extend_border`] replicates the edge pixels
//! into the border, so motion compensation can read a block displaced outside
//! the picture with plain slice indexing (as x264 and H.264's "unrestricted
//! motion vectors" do). Readers in `mocomp::io` return planes whose borders
//! are already extended; code that writes pixels calls `extend_border` when
//! it is done.
//!
//! Sizes are checked before anything is allocated: a width or height of 0 or
//! above [`MAX_DIMENSION`] is an error, never an allocation attempt.

use std::fmt;

pub use crate::consts::MAX_DIMENSION;

/// Largest accepted border, in pixels.
pub const MAX_PAD: usize = 1024;

/// Rows are padded to a multiple of this many bytes (a cache line), so that
/// vector loads of whole rows never straddle two rows' worth of lines.
const STRIDE_ALIGN: usize = 64;

/// What can go wrong when making a picture.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PictureError {
    /// Width or height is zero.
    #[error("picture size {width}x{height} is empty: width and height must be at least 1")]
    Empty {
        /// Requested width.
        width: usize,
        /// Requested height.
        height: usize,
    },
    /// Width or height is above [`MAX_DIMENSION`].
    #[error("picture size {width}x{height} exceeds the maximum of {max}x{max}")]
    TooLarge {
        /// Requested width.
        width: usize,
        /// Requested height.
        height: usize,
        /// The limit, [`MAX_DIMENSION`].
        max: usize,
    },
    /// The border is wider than [`MAX_PAD`].
    #[error("plane border of {pad} pixels exceeds the maximum of {max}")]
    PadTooLarge {
        /// Requested border.
        pad: usize,
        /// The limit, [`MAX_PAD`].
        max: usize,
    },
    /// A packed buffer does not hold exactly `width * height` samples.
    #[error("a {width}x{height} plane needs {expected} bytes, got {actual}")]
    DataLength {
        /// Plane width.
        width: usize,
        /// Plane height.
        height: usize,
        /// `width * height`.
        expected: usize,
        /// Length of the buffer given.
        actual: usize,
    },
    /// Planes given to [`Frame::from_planes`] do not form a 4:2:0 frame.
    #[error("a {width}x{height} 4:2:0 frame needs {cw}x{ch} chroma planes, got {uw}x{uh} and {vw}x{vh}")]
    ChromaSize {
        /// Luma width.
        width: usize,
        /// Luma height.
        height: usize,
        /// Expected chroma width, `ceil(width / 2)`.
        cw: usize,
        /// Expected chroma height, `ceil(height / 2)`.
        ch: usize,
        /// U width given.
        uw: usize,
        /// U height given.
        uh: usize,
        /// V width given.
        vw: usize,
        /// V height given.
        vh: usize,
    },
}

/// Checks a picture size against the limits, before anything is allocated.
pub fn check_size(width: usize, height: usize) -> Result<(), PictureError> {
    if width == 0 || height == 0 {
        return Err(PictureError::Empty { width, height });
    }
    if width > MAX_DIMENSION || height > MAX_DIMENSION {
        return Err(PictureError::TooLarge {
            width,
            height,
            max: MAX_DIMENSION,
        });
    }
    Ok(())
}

/// One 8-bit sample plane with a replicated border.
///
/// ```
/// use mocomp_codec::picture::Plane;
/// let mut p = Plane::new(4, 3).unwrap();
/// p.row_mut(0).copy_from_slice(&[1, 2, 3, 4]);
/// p.extend_border();
/// assert_eq!(p.get(3, 0), 4);
/// // Outside the picture, the border repeats the nearest edge pixel.
/// assert_eq!(p.at(-5, -2), 1);
/// assert_eq!(p.pixel_clamped(1000, -1000), 4);
/// ```
#[derive(Clone)]
pub struct Plane {
    width: usize,
    height: usize,
    pad: usize,
    stride: usize,
    data: Vec<u8>,
}

impl Plane {
    /// Border of planes made by [`Plane::new`] and of luma in [`Frame::new`]:
    /// enough for a 64-pixel motion vector margin beyond a 16-pixel block
    /// rounded up to a macroblock, plus an 8-tap interpolation filter.
    pub const DEFAULT_PAD: usize = 96;

    /// A zero-filled plane with the default border.
    pub fn new(width: usize, height: usize) -> Result<Plane, PictureError> {
        Plane::with_padding(width, height, Plane::DEFAULT_PAD)
    }

    /// A zero-filled plane with a border of `pad` pixels on every side.
    pub fn with_padding(width: usize, height: usize, pad: usize) -> Result<Plane, PictureError> {
        check_size(width, height)?;
        if pad > MAX_PAD {
            return Err(PictureError::PadTooLarge { pad, max: MAX_PAD });
        }
        let stride = (width + 2 * pad).div_ceil(STRIDE_ALIGN) * STRIDE_ALIGN;
        let rows = height + 2 * pad;
        Ok(Plane {
            width,
            height,
            pad,
            stride,
            data: vec![0; stride * rows],
        })
    }

    /// A plane filled with one value (border included).
    pub fn filled(width: usize, height: usize, value: u8) -> Result<Plane, PictureError> {
        let mut p = Plane::new(width, height)?;
        p.data.fill(value);
        Ok(p)
    }

    /// A plane from `width * height` packed samples, rows top to bottom.
    pub fn from_packed(width: usize, height: usize, samples: &[u8]) -> Result<Plane, PictureError> {
        check_size(width, height)?;
        if samples.len() != width * height {
            return Err(PictureError::DataLength {
                width,
                height,
                expected: width * height,
                actual: samples.len(),
            });
        }
        let mut p = Plane::new(width, height)?;
        for (dst, src) in p.rows_mut().zip(samples.chunks_exact(width)) {
            dst.copy_from_slice(src);
        }
        p.extend_border();
        Ok(p)
    }

    /// A plane whose pixel (x, y) is `f(x, y)`, border extended.
    pub fn from_fn(
        width: usize,
        height: usize,
        mut f: impl FnMut(usize, usize) -> u8,
    ) -> Result<Plane, PictureError> {
        let mut p = Plane::new(width, height)?;
        for (y, row) in p.rows_mut().enumerate() {
            for (x, s) in row.iter_mut().enumerate() {
                *s = f(x, y);
            }
        }
        p.extend_border();
        Ok(p)
    }

    /// Visible width in pixels.
    #[inline]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Visible height in pixels.
    #[inline]
    pub fn height(&self) -> usize {
        self.height
    }

    /// Border width on each side, in pixels.
    #[inline]
    pub fn pad(&self) -> usize {
        self.pad
    }

    /// Distance in bytes between vertically adjacent samples.
    #[inline]
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// The whole buffer, border included; pixel (x, y) is at
    /// `self.index(x, y)`.
    #[inline]
    pub fn data(&self) -> &[u8] {
        &self.data
    }

    /// The whole buffer, mutable. Call [`Plane::extend_border`] after writing
    /// visible pixels.
    #[inline]
    pub fn data_mut(&mut self) -> &mut [u8] {
        &mut self.data
    }

    /// Buffer index of pixel (x, y); valid for `-pad <= x < width + pad` and
    /// `-pad <= y < height + pad`.
    #[inline]
    pub fn index(&self, x: isize, y: isize) -> usize {
        debug_assert!(self.in_padded(x, y), "({x}, {y}) outside the padded plane");
        let p = self.pad as isize;
        ((y + p) as usize) * self.stride + (x + p) as usize
    }

    /// Whether (x, y) lies inside the picture or its border.
    #[inline]
    pub fn in_padded(&self, x: isize, y: isize) -> bool {
        let p = self.pad as isize;
        x >= -p && y >= -p && x < self.width as isize + p && y < self.height as isize + p
    }

    /// The visible pixels of row `y`.
    #[inline]
    pub fn row(&self, y: usize) -> &[u8] {
        assert!(y < self.height, "row {y} of a plane of height {}", self.height);
        let start = (y + self.pad) * self.stride + self.pad;
        &self.data[start..start + self.width]
    }

    /// The visible pixels of row `y`, mutable.
    #[inline]
    pub fn row_mut(&mut self, y: usize) -> &mut [u8] {
        assert!(y < self.height, "row {y} of a plane of height {}", self.height);
        let start = (y + self.pad) * self.stride + self.pad;
        &mut self.data[start..start + self.width]
    }

    /// Row `y` (which may lie in the border, `-pad <= y < height + pad`)
    /// including its left and right borders: element `pad + x` is pixel x.
    #[inline]
    pub fn padded_row(&self, y: isize) -> &[u8] {
        let start = self.index(-(self.pad as isize), y);
        &self.data[start..start + self.width + 2 * self.pad]
    }

    /// The visible rows, top to bottom.
    pub fn rows(&self) -> impl ExactSizeIterator<Item = &[u8]> + '_ {
        let (pad, w) = (self.pad, self.width);
        self.data[pad * self.stride..]
            .chunks_exact(self.stride)
            .take(self.height)
            .map(move |r| &r[pad..pad + w])
    }

    /// The visible rows, top to bottom, mutable.
    pub fn rows_mut(&mut self) -> impl ExactSizeIterator<Item = &mut [u8]> + '_ {
        let (pad, w, h) = (self.pad, self.width, self.height);
        self.data[pad * self.stride..]
            .chunks_exact_mut(self.stride)
            .take(h)
            .map(move |r| &mut r[pad..pad + w])
    }

    /// Asks the processor to bring into cache the line holding column `x`
    /// of each of `rows` rows from row `y` (a hint: nothing is read,
    /// nothing can fault). Positions are clamped into the buffer, borders
    /// included; no row asks for nothing.
    #[inline]
    pub fn prefetch_rows(&self, x: isize, y: isize, rows: usize) {
        if rows == 0 {
            return;
        }
        let pad = self.pad as isize;
        let cx = (x + pad).clamp(0, self.stride as isize - 1) as usize;
        let total_rows = self.data.len() / self.stride;
        let top = (y + pad).clamp(0, total_rows as isize - 1) as usize;
        let end = (top + rows).min(total_rows);
        let first = top * self.stride + cx;
        let last = (end - 1) * self.stride + cx;
        crate::cpu::prefetch_every(&self.data, first, last, self.stride);
    }

    /// The `N`-wide block at (x, y) inside the picture, into `out` (rows
    /// of `N`, as many as it holds): one bounds check for the block, not
    /// one a row (a macroblock's source loads and reconstruction writes).
    #[inline]
    pub fn read_block<const N: usize>(&self, x: usize, y: usize, out: &mut [u8]) {
        let rows = out.len() / N;
        assert!(
            x + N <= self.width && y + rows <= self.height,
            "block outside the picture"
        );
        let start = (y + self.pad) * self.stride + self.pad + x;
        let stride = self.stride;
        let src = &self.data[start..start + (rows.max(1) - 1) * stride + N];
        // Rows by index into the checked block: an iterator of chunks of
        // `stride` samples cost 4x the instructions of the copies, and a
        // check a row (which the compiler did not drop) 2x.
        for (r, o) in out.chunks_exact_mut(N).enumerate() {
            // SAFETY: r < rows, so r * stride + N <= (rows - 1) * stride +
            // N, the checked block's length.
            o.copy_from_slice(unsafe { src.get_unchecked(r * stride..r * stride + N) });
        }
    }

    /// Writes `block` (rows of `N`) at (x, y) inside the picture, as
    /// [`Plane::read_block`] reads one. The border is not updated.
    #[inline]
    pub fn write_block<const N: usize>(&mut self, x: usize, y: usize, block: &[u8]) {
        let rows = block.len() / N;
        assert!(
            x + N <= self.width && y + rows <= self.height,
            "block outside the picture"
        );
        let start = (y + self.pad) * self.stride + self.pad + x;
        let stride = self.stride;
        let dst = &mut self.data[start..start + (rows.max(1) - 1) * stride + N];
        for (r, b) in block.chunks_exact(N).enumerate() {
            // SAFETY: as in `read_block`, the row lies inside the checked
            // block.
            unsafe { dst.get_unchecked_mut(r * stride..r * stride + N) }.copy_from_slice(b);
        }
    }

    /// Pixel (x, y) inside the picture.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> u8 {
        self.row(y)[x]
    }

    /// Sets pixel (x, y) inside the picture (the border is not updated).
    #[inline]
    pub fn set(&mut self, x: usize, y: usize, value: u8) {
        self.row_mut(y)[x] = value;
    }

    /// Pixel (x, y) read from the padded buffer: inside the picture or its
    /// border. Panics beyond the border.
    #[inline]
    pub fn at(&self, x: isize, y: isize) -> u8 {
        assert!(self.in_padded(x, y), "({x}, {y}) outside the padded plane");
        self.data[self.index(x, y)]
    }

    /// Pixel (x, y) with coordinates clamped to the picture: any (x, y),
    /// however far outside, reads the nearest edge pixel. Does not depend on
    /// the border being extended.
    #[inline]
    pub fn pixel_clamped(&self, x: isize, y: isize) -> u8 {
        let xc = x.clamp(0, self.width as isize - 1) as usize;
        let yc = y.clamp(0, self.height as isize - 1) as usize;
        self.get(xc, yc)
    }

    /// Replicates the edge pixels into the border: left and right first, then
    /// the top and bottom rows (corners take the corner pixel).
    pub fn extend_border(&mut self) {
        self.extend_border_rows(0..self.height);
    }

    /// [`Plane::extend_border`] as far as picture rows `rows` go: their
    /// left and right borders, the top border with the first row, the
    /// bottom one with the last. Rows extended in runs, top to bottom,
    /// leave the border [`Plane::extend_border`] leaves (a picture that
    /// arrives a band of rows at a time). Panics beyond the picture.
    pub fn extend_border_rows(&mut self, rows: std::ops::Range<usize>) {
        let (pad, w, h, stride) = (self.pad, self.width, self.height, self.stride);
        assert!(rows.end <= h, "rows {rows:?} of a plane {h} tall");
        if pad == 0 || rows.is_empty() {
            return;
        }
        let band = (pad + rows.start) * stride..(pad + rows.end) * stride;
        for row in self.data[band].chunks_exact_mut(stride) {
            let (left, right) = (row[pad], row[pad + w - 1]);
            row[..pad].fill(left);
            row[pad + w..pad + w + pad].fill(right);
        }
        let row_len = w + 2 * pad;
        if rows.start == 0 {
            let (top, rest) = self.data.split_at_mut(pad * stride);
            let first = &rest[..row_len];
            for r in top.chunks_exact_mut(stride) {
                r[..row_len].copy_from_slice(first);
            }
        }
        if rows.end == h {
            let (above, bottom) = self.data.split_at_mut((pad + h) * stride);
            let last = &above[(pad + h - 1) * stride..(pad + h - 1) * stride + row_len];
            for r in bottom.chunks_exact_mut(stride) {
                r[..row_len].copy_from_slice(last);
            }
        }
    }

    /// The bytes of [`Plane::data`] that hold picture rows `rows` with
    /// their left and right borders, and the top border with the first
    /// row, the bottom one with the last: what
    /// [`Plane::extend_border_rows`] of the same rows writes, in order.
    pub fn rows_span(&self, rows: std::ops::Range<usize>) -> std::ops::Range<usize> {
        let (pad, h, stride) = (self.pad, self.height, self.stride);
        assert!(
            rows.start <= rows.end && rows.end <= h,
            "rows {rows:?} of a plane {h} tall"
        );
        let first = if rows.start == 0 { 0 } else { pad + rows.start };
        let end = if rows.end == h {
            2 * pad + h
        } else {
            pad + rows.end
        };
        first * stride..end * stride
    }

    /// The top-left `width x height` of this plane as a new plane with a
    /// `pad`-pixel border, extended (as [`Plane::extend_border`] would):
    /// built row by row, never zero-filled first, since every byte is
    /// written once. Panics if the size exceeds this plane's.
    pub fn cropped(&self, width: usize, height: usize, pad: usize) -> Result<Plane, PictureError> {
        assert!(
            width <= self.width && height <= self.height,
            "crop {width}x{height} of a {}x{} plane",
            self.width,
            self.height
        );
        check_size(width, height)?;
        if pad > MAX_PAD {
            return Err(PictureError::PadTooLarge { pad, max: MAX_PAD });
        }
        let stride = (width + 2 * pad).div_ceil(STRIDE_ALIGN) * STRIDE_ALIGN;
        let mut data = Vec::with_capacity(stride * (height + 2 * pad));
        let mut push = |row: &[u8]| {
            let filled = data.len();
            data.resize(filled + pad, row[0]);
            data.extend_from_slice(row);
            data.resize(filled + 2 * pad + width, row[width - 1]);
            data.resize(filled + stride, 0);
        };
        let row = |y: usize| &self.row(y)[..width];
        for _ in 0..pad {
            push(row(0));
        }
        for y in 0..height {
            push(row(y));
        }
        for _ in 0..pad {
            push(row(height - 1));
        }
        Ok(Plane {
            width,
            height,
            pad,
            stride,
            data,
        })
    }

    /// Whether [`Plane::reshape`] can give the plane the size `width x
    /// height` (a valid size whose rows fit its stride as they are).
    pub fn reshapes_to(&self, width: usize, height: usize) -> bool {
        check_size(width, height).is_ok()
            && (width + 2 * self.pad).div_ceil(STRIDE_ALIGN) * STRIDE_ALIGN == self.stride
    }

    /// Gives the plane the size `width x height` in its own buffer, border
    /// and stride kept: a sample inside both sizes stays where it was, the
    /// others are unspecified, the border is not extended. The buffer keeps
    /// its capacity, so a plane made smaller and then larger again does not
    /// allocate (an encoder lends its coded-size frames out to be read at
    /// the picture's size, and takes them back without a copy). Returns
    /// false, changing nothing, where [`Plane::reshapes_to`] is false.
    pub fn reshape(&mut self, width: usize, height: usize) -> bool {
        if !self.reshapes_to(width, height) {
            return false;
        }
        let len = self.stride * (height + 2 * self.pad);
        // Grown to the size asked, not doubled as a `Vec` grows.
        self.data.reserve_exact(len.saturating_sub(self.data.len()));
        self.data.resize(len, 0);
        (self.width, self.height) = (width, height);
        true
    }

    /// Fills the plane beyond its top-left `width x height` with that
    /// part's right column and bottom row repeated (a picture padded to
    /// whole macroblocks); the border is not extended. Panics if the part
    /// is empty or larger than the plane.
    pub fn repeat_edges_beyond(&mut self, width: usize, height: usize) {
        assert!(
            (1..=self.width).contains(&width) && (1..=self.height).contains(&height),
            "edges of {width}x{height} in a {}x{} plane",
            self.width,
            self.height
        );
        for y in 0..height {
            let row = self.row_mut(y);
            let last = row[width - 1];
            row[width..].fill(last);
        }
        let (last, w) = (self.index(0, height as isize - 1), self.width);
        for y in height..self.height {
            let at = self.index(0, y as isize);
            self.data.copy_within(last..last + w, at);
        }
    }

    /// Sets every pixel, border included.
    pub fn fill(&mut self, value: u8) {
        self.data.fill(value);
    }

    /// The visible pixels packed row after row (`width * height` bytes).
    pub fn to_packed(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.width * self.height);
        for row in self.rows() {
            out.extend_from_slice(row);
        }
        out
    }

    /// Copies the visible pixels of `src` (same size) and extends the border.
    pub fn copy_from(&mut self, src: &Plane) {
        assert!(
            self.width == src.width && self.height == src.height,
            "copy_from: {}x{} into {}x{}",
            src.width,
            src.height,
            self.width,
            self.height
        );
        for (d, s) in self.rows_mut().zip(src.rows()) {
            d.copy_from_slice(s);
        }
        self.extend_border();
    }
}

/// Planes are equal when their sizes and visible pixels are; the border and
/// the stride do not count.
impl PartialEq for Plane {
    fn eq(&self, other: &Plane) -> bool {
        self.width == other.width
            && self.height == other.height
            && self.rows().zip(other.rows()).all(|(a, b)| a == b)
    }
}

impl Eq for Plane {}

impl fmt::Debug for Plane {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Plane({}x{}, pad {})", self.width, self.height, self.pad)
    }
}

/// An 8-bit 4:2:0 frame: luma `width x height`, two chroma planes of
/// `ceil(width / 2) x ceil(height / 2)`.
///
/// ```
/// use mocomp_codec::picture::Frame;
/// let f = Frame::new(5, 3).unwrap();
/// assert_eq!((f.u().width(), f.u().height()), (3, 2));
/// assert!(Frame::new(0, 10).is_err());
/// assert!(Frame::new(100_000, 10).is_err());
/// ```
#[derive(Clone, PartialEq, Eq)]
pub struct Frame {
    planes: [Plane; 3],
}

impl Frame {
    /// A black-level-zero frame (all samples 0) with the default borders:
    /// [`Plane::DEFAULT_PAD`] for luma and half of it for chroma.
    pub fn new(width: usize, height: usize) -> Result<Frame, PictureError> {
        Frame::with_padding(width, height, Plane::DEFAULT_PAD)
    }

    /// A zero-filled frame with `luma_pad` pixels of luma border and
    /// `ceil(luma_pad / 2)` of chroma border.
    pub fn with_padding(width: usize, height: usize, luma_pad: usize) -> Result<Frame, PictureError> {
        check_size(width, height)?;
        let (cw, ch) = Frame::chroma_size(width, height);
        let cpad = luma_pad.div_ceil(2);
        Ok(Frame {
            planes: [
                Plane::with_padding(width, height, luma_pad)?,
                Plane::with_padding(cw, ch, cpad)?,
                Plane::with_padding(cw, ch, cpad)?,
            ],
        })
    }

    /// A frame with every sample of each plane set to `y`, `u`, `v`.
    pub fn filled(width: usize, height: usize, y: u8, u: u8, v: u8) -> Result<Frame, PictureError> {
        let mut f = Frame::new(width, height)?;
        for (p, value) in f.planes.iter_mut().zip([y, u, v]) {
            p.fill(value);
        }
        Ok(f)
    }

    /// A frame from three planes, checking the 4:2:0 chroma size.
    pub fn from_planes(y: Plane, u: Plane, v: Plane) -> Result<Frame, PictureError> {
        let (width, height) = (y.width(), y.height());
        let (cw, ch) = Frame::chroma_size(width, height);
        let fits = |p: &Plane| p.width() == cw && p.height() == ch;
        if !fits(&u) || !fits(&v) {
            return Err(PictureError::ChromaSize {
                width,
                height,
                cw,
                ch,
                uw: u.width(),
                uh: u.height(),
                vw: v.width(),
                vh: v.height(),
            });
        }
        Ok(Frame { planes: [y, u, v] })
    }

    /// Chroma plane size of a 4:2:0 frame: `(ceil(w / 2), ceil(h / 2))`.
    #[inline]
    pub fn chroma_size(width: usize, height: usize) -> (usize, usize) {
        (width.div_ceil(2), height.div_ceil(2))
    }

    /// Luma width.
    #[inline]
    pub fn width(&self) -> usize {
        self.planes[0].width()
    }

    /// Luma height.
    #[inline]
    pub fn height(&self) -> usize {
        self.planes[0].height()
    }

    /// The luma plane.
    #[inline]
    pub fn y(&self) -> &Plane {
        &self.planes[0]
    }

    /// The first chroma plane (Cb).
    #[inline]
    pub fn u(&self) -> &Plane {
        &self.planes[1]
    }

    /// The second chroma plane (Cr).
    #[inline]
    pub fn v(&self) -> &Plane {
        &self.planes[2]
    }

    /// Plane `i`: 0 = Y, 1 = U, 2 = V.
    #[inline]
    pub fn plane(&self, i: usize) -> &Plane {
        &self.planes[i]
    }

    /// Plane `i`, mutable: 0 = Y, 1 = U, 2 = V.
    #[inline]
    pub fn plane_mut(&mut self, i: usize) -> &mut Plane {
        &mut self.planes[i]
    }

    /// All three planes, Y U V.
    #[inline]
    pub fn planes(&self) -> &[Plane; 3] {
        &self.planes
    }

    /// All three planes, mutable.
    #[inline]
    pub fn planes_mut(&mut self) -> &mut [Plane; 3] {
        &mut self.planes
    }

    /// Splits the frame into its Y, U, V planes.
    pub fn into_planes(self) -> [Plane; 3] {
        self.planes
    }

    /// Gives the frame the size `width x height` in its own buffers, as
    /// [`Plane::reshape`] does each plane (chroma at half the size): all
    /// three or, returning false, none.
    pub fn reshape(&mut self, width: usize, height: usize) -> bool {
        let (cw, ch) = Frame::chroma_size(width, height);
        let sizes = [(width, height), (cw, ch), (cw, ch)];
        if !self
            .planes
            .iter()
            .zip(sizes)
            .all(|(p, (w, h))| p.reshapes_to(w, h))
        {
            return false;
        }
        for (p, (w, h)) in self.planes.iter_mut().zip(sizes) {
            p.reshape(w, h);
        }
        true
    }

    /// Extends the border of every plane.
    pub fn extend_borders(&mut self) {
        for p in &mut self.planes {
            p.extend_border();
        }
    }
}

impl fmt::Debug for Frame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Frame({}x{} 4:2:0)", self.width(), self.height())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type Result = std::result::Result<(), PictureError>;

    #[test]
    fn a_reshaped_plane_keeps_its_samples_in_place_and_its_buffer() -> Result {
        // 90x60 and 96x64 share a stride (90 + 2 * 96 and 96 + 2 * 96 round
        // up to the same multiple of 64); 200 wide does not.
        let mut p = Plane::from_fn(96, 64, |x, y| (x * 3 + y * 5) as u8)?;
        let buffer = p.data().as_ptr();
        assert!(!p.reshapes_to(200, 64) && !p.reshape(200, 64) && p.width() == 96);
        assert!(!p.reshape(0, 10));
        assert!(p.reshape(90, 60));
        assert_eq!((p.width(), p.height()), (90, 60));
        assert!(p.reshape(96, 64));
        assert_eq!(p.data().as_ptr(), buffer, "grown back within its capacity");
        for (x, y) in [(0, 0), (89, 59), (95, 0), (0, 63), (95, 63)] {
            // Inside both sizes kept; outside 90x60, kept here too (nothing
            // wrote there), though the contract leaves it unspecified.
            assert_eq!(p.get(x, y), (x * 3 + y * 5) as u8, "({x}, {y})");
        }
        Ok(())
    }

    #[test]
    fn borders_extended_a_band_of_rows_at_a_time_are_the_whole_planes() -> Result {
        let mut whole = Plane::from_fn(37, 23, |x, y| (x * 7 + y * 13 + x * y) as u8)?;
        let mut banded = whole.clone();
        whole.extend_border();
        let mut spans = Vec::new();
        for rows in [0..1, 1..8, 8..8, 8..22, 22..23] {
            if !rows.is_empty() {
                spans.push(banded.rows_span(rows.clone()));
            }
            banded.extend_border_rows(rows);
        }
        assert_eq!(whole.data(), banded.data(), "every border sample");
        // The spans are the plane's rows in order, every one once.
        assert_eq!(spans.first().map(|s| s.start), Some(0));
        assert!(spans.windows(2).all(|w| w[0].end == w[1].start), "{spans:?}");
        assert_eq!(
            spans.last().map(|s| s.end),
            Some(whole.stride() * (23 + 2 * whole.pad()))
        );
        Ok(())
    }

    #[test]
    fn edges_are_repeated_beyond_the_picture() -> Result {
        let mut p = Plane::from_fn(
            96,
            64,
            |x, y| if x < 90 && y < 60 { (x + 2 * y) as u8 } else { 0 },
        )?;
        p.repeat_edges_beyond(90, 60);
        for y in 0..64 {
            for x in 0..96 {
                assert_eq!(p.get(x, y), (x.min(89) + 2 * y.min(59)) as u8, "({x}, {y})");
            }
        }
        Ok(())
    }

    #[test]
    fn a_frame_reshapes_all_its_planes_or_none() -> Result {
        let mut f = Frame::new(96, 64)?;
        assert!(f.reshape(90, 60));
        assert_eq!((f.u().width(), f.u().height()), (45, 30));
        // Luma 200 wide changes the stride: nothing changes.
        assert!(!f.reshape(200, 60));
        assert_eq!((f.width(), f.height(), f.v().width()), (90, 60, 45));
        Ok(())
    }

    #[test]
    fn blocks_read_and_written_are_the_pixels_at_their_place() -> Result {
        let mut p = Plane::from_fn(40, 24, |x, y| (x * 7 + y * 13) as u8)?;
        let mut block = [0u8; 16 * 8];
        p.read_block::<16>(24, 16, &mut block);
        for (k, &v) in block.iter().enumerate() {
            assert_eq!(v, p.get(24 + k % 16, 16 + k / 16));
        }
        let marks: Vec<u8> = (0..64).map(|k| 200 - k as u8).collect();
        p.write_block::<8>(32, 0, &marks);
        for y in 0..24 {
            for x in 0..40 {
                let want = if x >= 32 && y < 8 {
                    marks[y * 8 + x - 32]
                } else {
                    (x * 7 + y * 13) as u8
                };
                assert_eq!(p.get(x, y), want, "({x}, {y})");
            }
        }
        Ok(())
    }

    #[test]
    #[should_panic(expected = "outside the picture")]
    fn a_block_past_the_edge_is_refused() {
        // (A plane that cannot be made does not panic: the test fails.)
        if let Ok(p) = Plane::new(40, 24) {
            p.read_block::<16>(32, 0, &mut [0u8; 16 * 4]);
        }
    }

    fn ramp(w: usize, h: usize) -> std::result::Result<Plane, PictureError> {
        Plane::from_fn(w, h, |x, y| (x * 7 + y * 13) as u8)
    }

    #[test]
    fn sizes_are_checked_before_allocation() -> Result {
        assert_eq!(
            Plane::new(0, 5).unwrap_err(),
            PictureError::Empty { width: 0, height: 5 }
        );
        assert!(matches!(
            Plane::new(MAX_DIMENSION + 1, 1),
            Err(PictureError::TooLarge { .. })
        ));
        // usize::MAX would overflow any size computation: it must be refused first.
        assert!(Frame::new(usize::MAX, usize::MAX).is_err());
        assert!(Plane::with_padding(4, 4, MAX_PAD + 1).is_err());
        Ok(())
    }

    #[test]
    fn odd_and_tiny_sizes() -> Result {
        for (w, h) in [(1, 1), (1, 7), (3, 5), (17, 9)] {
            let f = Frame::new(w, h)?;
            assert_eq!((f.u().width(), f.u().height()), (w.div_ceil(2), h.div_ceil(2)));
            assert_eq!(f.v().width(), f.u().width());
        }
        Ok(())
    }

    #[test]
    fn border_replicates_nearest_edge_pixel() -> Result {
        let p = ramp(5, 4)?;
        let pad = p.pad() as isize;
        for y in -pad..4 + pad {
            for x in -pad..5 + pad {
                assert_eq!(p.at(x, y), p.pixel_clamped(x, y), "at ({x},{y})");
            }
        }
        Ok(())
    }

    #[test]
    fn padded_row_indexes_match() -> Result {
        let p = ramp(6, 3)?;
        let r = p.padded_row(-2);
        assert_eq!(r.len(), 6 + 2 * p.pad());
        assert_eq!(r[p.pad() + 4], p.get(4, 0));
        assert_eq!(p.padded_row(1)[p.pad()..p.pad() + 6], *p.row(1));
        Ok(())
    }

    #[test]
    fn packed_round_trip_and_length_check() -> Result {
        let data: Vec<u8> = (0..15).collect();
        let p = Plane::from_packed(5, 3, &data)?;
        assert_eq!(p.to_packed(), data);
        assert!(matches!(
            Plane::from_packed(5, 3, &data[..14]),
            Err(PictureError::DataLength {
                expected: 15,
                actual: 14,
                ..
            })
        ));
        Ok(())
    }

    #[test]
    fn equality_ignores_border_and_padding() -> Result {
        let a = ramp(7, 5)?;
        let mut b = Plane::with_padding(7, 5, 3)?;
        b.copy_from(&a);
        assert_eq!(a, b);
        b.set(6, 4, b.get(6, 4) ^ 1);
        assert_ne!(a, b);
        Ok(())
    }

    #[test]
    fn from_planes_checks_chroma_size() -> Result {
        let y = Plane::new(5, 5)?;
        let good = Plane::new(3, 3)?;
        assert!(Frame::from_planes(y.clone(), good.clone(), good.clone()).is_ok());
        let err = Frame::from_planes(y, Plane::new(2, 3)?, good).unwrap_err();
        assert!(err.to_string().contains("needs 3x3 chroma planes"), "{err}");
        Ok(())
    }

    #[test]
    fn cropped_equals_copy_then_extend_byte_for_byte() -> Result {
        let src = Plane::from_fn(37, 21, |x, y| (x * 7 + y * 13) as u8)?;
        for (w, h, pad) in [(37, 21, 96), (20, 9, 48), (1, 1, 0), (16, 16, 5)] {
            let mut want = Plane::with_padding(w, h, pad)?;
            for y in 0..h {
                want.row_mut(y).copy_from_slice(&src.row(y)[..w]);
            }
            want.extend_border();
            let got = src.cropped(w, h, pad)?;
            assert_eq!((got.stride, got.pad), (want.stride, want.pad));
            assert_eq!(got.data, want.data, "{w}x{h} pad {pad}");
        }
        Ok(())
    }

    /// A prefetch's position is clamped into the buffer: no position
    /// near or far outside the picture panics (an index out of the buffer
    /// would).
    #[test]
    fn a_prefetch_anywhere_inside_or_far_outside_does_not_panic() -> Result {
        for pad in [0, 8] {
            let p = Plane::with_padding(20, 12, pad)?;
            for (x, y, rows) in [
                (0, 0, 16),
                (-1000, -1000, 4),
                (1000, 1000, 40),
                (19, 11, 1),
                (5, -3, 30),
                (0, -1000, 0),
                (3, 4, 0),
            ] {
                p.prefetch_rows(x, y, rows);
            }
        }
        Ok(())
    }

    #[test]
    fn zero_pad_plane_works() -> Result {
        let mut p = Plane::with_padding(3, 2, 0)?;
        p.set(2, 1, 9);
        p.extend_border();
        assert_eq!(p.pixel_clamped(10, 10), 9);
        Ok(())
    }
}
