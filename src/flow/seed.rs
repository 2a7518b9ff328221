//! A dense start from sparse matches (as LDOF, DeepFlow and EpicFlow
//! start their dense methods from matches): each pixel takes the
//! displacement of the nearest match.

use ndarray::Array2;
use rayon::prelude::*;

use super::Flow;
use crate::features::Match;

/// A dense `width x height` flow from matches: each pixel takes the
/// displacement of the nearest match (computed per 4x4 block). A start for
/// a dense method, which tries each vector and keeps what fits; `None`
/// without matches.
pub fn matches_to_flow(matches: &[Match], width: usize, height: usize) -> Option<Flow> {
    if matches.is_empty() || width == 0 || height == 0 {
        return None;
    }
    const BLOCK: usize = 4;
    let (bw, bh) = (width.div_ceil(BLOCK), height.div_ceil(BLOCK));
    let grid = Buckets::new(matches, width, height);
    let nearest: Vec<(f32, f32)> = (0..bw * bh)
        .into_par_iter()
        .map(|b| {
            let cx = ((b % bw) * BLOCK) as f32 + 0.5 * (BLOCK - 1) as f32;
            let cy = ((b / bw) * BLOCK) as f32 + 0.5 * (BLOCK - 1) as f32;
            let m = &matches[grid.nearest(matches, cx, cy)];
            (m.x2 - m.x1, m.y2 - m.y1)
        })
        .collect();
    let at = |y: usize, x: usize| nearest[(y / BLOCK) * bw + x / BLOCK];
    let u = Array2::from_shape_fn((height, width), |(y, x)| at(y, x).0);
    let v = Array2::from_shape_fn((height, width), |(y, x)| at(y, x).1);
    Some(Flow::from_uv(u, v))
}

/// The matches bucketed by their first point on a grid of square cells,
/// for nearest-match queries that look at a few cells, not every match.
struct Buckets {
    cell: f32,
    cols: usize,
    rows: usize,
    cells: Vec<Vec<usize>>,
}

impl Buckets {
    fn new(matches: &[Match], width: usize, height: usize) -> Buckets {
        // About two matches per cell on average.
        let area = (width * height) as f32 / (matches.len() as f32 / 2.0).max(1.0);
        let cell = area.sqrt().max(4.0);
        let cols = (width as f32 / cell).ceil().max(1.0) as usize;
        let rows = (height as f32 / cell).ceil().max(1.0) as usize;
        let mut cells = vec![Vec::new(); cols * rows];
        let index = |x: f32, n: usize| ((x / cell).floor().max(0.0) as usize).min(n - 1);
        for (k, m) in matches.iter().enumerate() {
            cells[index(m.y1, rows) * cols + index(m.x1, cols)].push(k);
        }
        Buckets {
            cell,
            cols,
            rows,
            cells,
        }
    }

    /// Index of the match nearest to (x, y): rings of cells outwards until
    /// no unvisited cell can hold a closer one. Ties go to the lower index.
    fn nearest(&self, matches: &[Match], x: f32, y: f32) -> usize {
        let (cx, cy) = (
            ((x / self.cell) as usize).min(self.cols - 1) as isize,
            ((y / self.cell) as usize).min(self.rows - 1) as isize,
        );
        let (mut best, mut at) = (f32::INFINITY, usize::MAX);
        for r in 0..=self.cols.max(self.rows) as isize {
            // Every point outside the rings searched so far is at least
            // (r - 1) cells away.
            let reach = (r - 1).max(0) as f32 * self.cell;
            if reach * reach > best {
                break;
            }
            for gy in cy - r..=cy + r {
                for gx in cx - r..=cx + r {
                    let on_ring = (gy - cy).abs() == r || (gx - cx).abs() == r;
                    if !on_ring || gx < 0 || gy < 0 || gx >= self.cols as isize || gy >= self.rows as isize {
                        continue;
                    }
                    for &k in &self.cells[gy as usize * self.cols + gx as usize] {
                        let d = (matches[k].x1 - x).powi(2) + (matches[k].y1 - y).powi(2);
                        if d < best || (d == best && k < at) {
                            (best, at) = (d, k);
                        }
                    }
                }
            }
        }
        at
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_nearest_match_fills_each_block() {
        let m = |x1: f32, y1: f32, du: f32| Match {
            x1,
            y1,
            x2: x1 + du,
            y2: y1,
            distance: 0,
        };
        let f = matches_to_flow(&[m(2.0, 2.0, 5.0), m(30.0, 2.0, -3.0)], 32, 8).unwrap();
        assert_eq!(f.get(0, 0), (5.0, 0.0));
        assert_eq!(f.get(31, 7), (-3.0, 0.0));
        assert!(matches_to_flow(&[], 8, 8).is_none());
    }

    #[test]
    fn the_buckets_find_what_a_full_scan_finds() {
        // Scattered matches, queries everywhere: the bucketed nearest is
        // the brute-force nearest (ties to the lower index in both).
        let matches: Vec<Match> = (0..97)
            .map(|k| {
                let (x, y) = (((k * 37) % 301) as f32 + 0.25, ((k * 53) % 211) as f32);
                Match {
                    x1: x,
                    y1: y,
                    x2: x,
                    y2: y,
                    distance: 0,
                }
            })
            .collect();
        let grid = Buckets::new(&matches, 301, 211);
        for qy in (0..211).step_by(7) {
            for qx in (0..301).step_by(5) {
                let (x, y) = (qx as f32, qy as f32);
                let d = |m: &Match| (m.x1 - x).powi(2) + (m.y1 - y).powi(2);
                let brute = (0..matches.len())
                    .min_by(|&a, &b| d(&matches[a]).total_cmp(&d(&matches[b])).then(a.cmp(&b)))
                    .unwrap();
                assert_eq!(grid.nearest(&matches, x, y), brute, "query ({x}, {y})");
            }
        }
    }
}
