use ndarray::Array2;

/// A dense 2-D motion field with a validity mask.
///
/// `u` is the horizontal and `v` the vertical displacement in pixels, indexed
/// `[[y, x]]`; a pixel whose motion is unknown (occluded, outside the other
/// frame, or stored as "unknown" in a `.flo` file) has `valid == false` and
/// `u = v = 0`. Forward flow from frame 1 to frame 2 means
/// `frame1(p) ~ frame2(p + w(p))`.
///
/// ```
/// use mocomp::flow::Flow;
/// let f = Flow::from_fn(4, 3, |x, _y| (x as f32 * 0.5, -1.0));
/// assert_eq!(f.get(2, 1), (1.0, -1.0));
/// assert_eq!(f.valid_count(), 12);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Flow {
    u: Array2<f32>,
    v: Array2<f32>,
    valid: Array2<bool>,
}

impl Flow {
    /// Zero motion everywhere, all valid.
    pub fn zeros(width: usize, height: usize) -> Flow {
        Flow::from_uv(Array2::zeros((height, width)), Array2::zeros((height, width)))
    }

    /// A field from its components, all valid. Panics if the shapes differ.
    pub fn from_uv(u: Array2<f32>, v: Array2<f32>) -> Flow {
        assert!(
            u.dim() == v.dim(),
            "flow components of different shapes: u {:?}, v {:?}",
            u.dim(),
            v.dim()
        );
        // All valid: no pass over the components to zero invalid pixels
        // (3 % of the perf samples of DIS ultrafast on smile_360p).
        let valid = Array2::from_elem(u.dim(), true);
        Flow { u, v, valid }
    }

    /// A field from its components and validity mask. Panics if the shapes
    /// differ. Invalid pixels are set to zero motion.
    pub fn from_parts(mut u: Array2<f32>, mut v: Array2<f32>, valid: Array2<bool>) -> Flow {
        assert!(
            u.dim() == v.dim() && u.dim() == valid.dim(),
            "flow components of different shapes: u {:?}, v {:?}, valid {:?}",
            u.dim(),
            v.dim(),
            valid.dim()
        );
        ndarray::Zip::from(&mut u)
            .and(&mut v)
            .and(&valid)
            .for_each(|u, v, &ok| {
                if !ok {
                    *u = 0.0;
                    *v = 0.0;
                }
            });
        Flow { u, v, valid }
    }

    /// Its components, to be written over whole, every pixel marked valid:
    /// the field made `width x height`, its buffers kept where it is that
    /// size already (as OpenCV's `calc` reuses its output), for a method
    /// that writes a new field into the one a frame loop keeps.
    pub(crate) fn overwrite_all_valid(
        &mut self,
        width: usize,
        height: usize,
    ) -> (&mut Array2<f32>, &mut Array2<f32>) {
        if self.u.dim() == (height, width) {
            self.valid.fill(true);
        } else {
            *self = Flow::zeros(width, height);
        }
        (&mut self.u, &mut self.v)
    }

    /// A field whose motion at (x, y) is `f(x, y)`, all valid.
    pub fn from_fn(width: usize, height: usize, mut f: impl FnMut(usize, usize) -> (f32, f32)) -> Flow {
        let mut u = Array2::zeros((height, width));
        let mut v = Array2::zeros((height, width));
        for y in 0..height {
            for x in 0..width {
                let (a, b) = f(x, y);
                u[[y, x]] = a;
                v[[y, x]] = b;
            }
        }
        Flow::from_uv(u, v)
    }

    /// Width in pixels.
    pub fn width(&self) -> usize {
        self.u.ncols()
    }

    /// Height in pixels.
    pub fn height(&self) -> usize {
        self.u.nrows()
    }

    /// Horizontal component, `[[y, x]]`.
    pub fn u(&self) -> &Array2<f32> {
        &self.u
    }

    /// Vertical component, `[[y, x]]`.
    pub fn v(&self) -> &Array2<f32> {
        &self.v
    }

    /// Validity mask, `[[y, x]]`.
    pub fn valid(&self) -> &Array2<bool> {
        &self.valid
    }

    /// Mutable components and mask (keep invalid pixels at zero motion).
    pub fn parts_mut(&mut self) -> (&mut Array2<f32>, &mut Array2<f32>, &mut Array2<bool>) {
        (&mut self.u, &mut self.v, &mut self.valid)
    }

    /// Splits into `(u, v, valid)`.
    pub fn into_parts(self) -> (Array2<f32>, Array2<f32>, Array2<bool>) {
        (self.u, self.v, self.valid)
    }

    /// The flow as (u, v) pairs row by row into `out` (`2 h w` floats, the
    /// layout of OpenCV's flow and of .flo files), NaN where not valid.
    /// Panics if `out` has another length.
    pub fn write_interleaved(&self, out: &mut [f32]) {
        assert_eq!(out.len(), 2 * self.u.len(), "write_interleaved: output size");
        let (u, v) = (self.u.as_standard_layout(), self.v.as_standard_layout());
        let valid = self.valid.as_standard_layout();
        // Slices, so that the loop vectorises (element-wise iteration of
        // the arrays cost a fast flow 7 % of its time).
        let (Some(u), Some(v), Some(valid)) = (u.as_slice(), v.as_slice(), valid.as_slice()) else {
            unreachable!("standard layout is contiguous")
        };
        for (((o, &u), &v), &ok) in out.chunks_exact_mut(2).zip(u).zip(v).zip(valid) {
            let nan_or = |x: f32| if ok { x } else { f32::NAN };
            o[0] = nan_or(u);
            o[1] = nan_or(v);
        }
    }

    /// Motion at (x, y).
    pub fn get(&self, x: usize, y: usize) -> (f32, f32) {
        (self.u[[y, x]], self.v[[y, x]])
    }

    /// Whether the motion at (x, y) is known.
    pub fn is_valid(&self, x: usize, y: usize) -> bool {
        self.valid[[y, x]]
    }

    /// Number of valid pixels.
    pub fn valid_count(&self) -> usize {
        self.valid.iter().filter(|&&ok| ok).count()
    }

    /// Largest motion magnitude over valid pixels (0 if none is valid).
    pub fn max_magnitude(&self) -> f32 {
        ndarray::Zip::from(&self.u)
            .and(&self.v)
            .and(&self.valid)
            .fold(0.0f32, |m, &u, &v, &ok| if ok { m.max(u.hypot(v)) } else { m })
    }

    /// Mean motion magnitude over valid pixels (0 if none is valid).
    pub fn mean_magnitude(&self) -> f64 {
        let (sum, n) = ndarray::Zip::from(&self.u).and(&self.v).and(&self.valid).fold(
            (0.0f64, 0usize),
            |(s, n), &u, &v, &ok| {
                if ok {
                    (s + f64::from(u.hypot(v)), n + 1)
                } else {
                    (s, n)
                }
            },
        );
        if n == 0 {
            0.0
        } else {
            sum / n as f64
        }
    }
}
