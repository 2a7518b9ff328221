//! Choosing a P frame's weighted prediction (the codec's
//! [`crate::codec::weight`]): a scale and an offset per plane that map the
//! reference's brightness and contrast onto the frame's, as x264's
//! `--weightp` guesses them (the ratio of the planes' mean deviations, then
//! the offset that matches the means), or an offset alone (the median
//! change of the block means), whichever explains the blocks better, kept
//! only where it explains the difference between the two frames better
//! than no weight does.

use crate::codec::picture::{Frame, Plane};
use crate::codec::weight::{PlaneWeight, Weights, MAX_OFFSET, WEIGHT_ONE};

/// A weight is kept when the 8x8 block means of the frame, predicted from
/// the reference's through it, are off by at most this share of what they
/// are off by without it: block means ignore texture, and a
/// brightness change shifts every block where motion moves few. Under a
/// flicker of one level over flat, noisy content (fish_1160) the share is
/// about 0.8, and a frame refused its weight keeps the level in every
/// skipped block (one frame: -1.4 dB). 0.9 rather than 0.8, with
/// [`MIN_SHARE`] beside it (`benches/pair.py`, the 28 sequences, one run):
/// medium -0.44 % on the mean (cup_vga_30 -5.1 %, ball_576 -2.7 %,
/// plant_qvga -1.8 %, coin_568 -1.7 %; none worse by 0.05 %), fast -0.41 %
/// (fish_1160 -4.2 %; cartoon_cif +0.3 %), ultrafast -0.17 % (plant_qvga
/// -4.0 %; cuts_cif +3.3 %: a chroma weight of under a level in its pan's
/// shot, that ultrafast's frames do not repay).
const KEEP_BELOW: f64 = 0.9;

/// ... and, a weight with a scale, when it moves the block means by this
/// many levels on average at least (a smaller change costs its header
/// bits for nothing, and the deviations' ratio is noisy on small planes:
/// 1.0 weighted a steady pan's chroma). An offset alone moves them by a
/// level at least: the median of many blocks' changes is no noise. It
/// lifted ball_576's second frame (one level of light, a title leaving)
/// from 47.7 to 50.1 dB in fewer bytes, and took 0.88 % off the bits of
/// the development set's mean (fish_1160 -13.3 %, coin_568 -4.0 %,
/// cup_vga_30 -3.7 %), none of its 28 sequences worse by more than 0.1 %.
const MIN_SHIFT: f64 = 1.5;

/// ... and where at least this share of the change the weight makes to
/// the block means is there beside what a small pan explains
/// ([`share_beside_pan`]): a pan over a gradient of light shifts every
/// block's mean alike too (a scene panned 0.75 px a frame under steady
/// light: a median change of one level, a share of about 0.5), which the
/// misfit's share let through at [`KEEP_BELOW`] 0.9.
const MIN_SHARE: f64 = 0.6;

/// ... and by at most this share of how much the frame's block means vary:
/// after a cut the weight matches the new shot's brightness, but the
/// blocks still differ as much as the shot's content does (cuts_cif's
/// cut: 1.6). A flicker over flat, noisy content leaves the block means
/// off by noise that is a fair share of their small spread (fish_1160:
/// 0.2-0.33, where 0.25 refused half its weights and the encoder coded
/// those frames intra: 0.5 took 40 % off its bits, the rest of the
/// development set within 0.7 %).
const CUT_ABOVE: f64 = 0.5;

/// The weights of `source` predicted from `reference` (both coded size),
/// measured on their top `luma_rows` rows (chroma: half as many; the whole
/// frame where it has fewer): an encoder's frame thread measures a frame's
/// weights once the reference's top half is final (ARCHITECTURE.md,
/// "Frame threads").
pub fn estimate(source: &Frame, reference: &Frame, luma_rows: usize) -> Weights {
    let mut out = Weights::NONE;
    for (i, slot) in out.0.iter_mut().enumerate() {
        let rows = if i == 0 { luma_rows } else { luma_rows.div_ceil(2) };
        *slot = plane_weight(source.plane(i), reference.plane(i), rows);
    }
    out
}

/// What the guess needs of a plane.
struct PlaneStats {
    mean: f64,
    /// Mean absolute deviation (it follows a change of light better than
    /// the standard deviation where dark parts clip: light_cif 7.3 % ->
    /// 1.8 % against x264 medium).
    deviation: f64,
    /// The means of the 8x8 blocks (partial ones at the edges included).
    block_means: Vec<f64>,
}

impl PlaneStats {
    /// The top `rows` rows of `p` (all where it has fewer).
    fn of(p: &Plane, rows: usize) -> PlaneStats {
        let (w, h) = (p.width(), p.height().min(rows));
        let cols = w.div_ceil(8);
        let mut block_sums = vec![0u32; cols * h.div_ceil(8)];
        let group_sums = crate::me::dsp::pixel().group_sums;
        for (band, sums) in block_sums.chunks_exact_mut(cols).enumerate() {
            let y0 = band * 8;
            let band_data = &p.data()[p.index(0, y0 as isize)..];
            group_sums(band_data, p.stride(), (w, (h - y0).min(8)), sums);
        }
        let sum = block_sums.iter().map(|&s| u64::from(s)).sum::<u64>();
        let n = (w * h) as f64;
        let mean = sum as f64 / n;
        // sum |v - mean| is linear in the mean between two integers (no
        // sample lies strictly between them): interpolated from the sums
        // of |v - cut| at the integers either side (one pass).
        let cut = mean.floor().clamp(0.0, 254.0) as u8;
        let [at_cut, above_cut] = abs_differences(p, h, cut);
        let frac = mean - f64::from(cut);
        let deviation = ((1.0 - frac) * at_cut as f64 + frac * above_cut as f64) / n;
        // Row by row: a block's place without two integer divisions per
        // block (`codec_tools_cif/estimate_weights` 72-79 us against 81-88).
        let mut block_means = Vec::with_capacity(block_sums.len());
        for (by, row) in block_sums.chunks_exact(cols).enumerate() {
            let rows = (h - by * 8).min(8);
            // Whole blocks' sums divided by their count; by a power of two
            // (most blocks: 64) that is a multiplication by its exact
            // reciprocal, the same value.
            let (whole, part) = row.split_at(w / 8);
            let count = (8 * rows) as f64;
            if (8 * rows).is_power_of_two() {
                let scale = 1.0 / count;
                block_means.extend(whole.iter().map(|&s| f64::from(s) * scale));
            } else {
                block_means.extend(whole.iter().map(|&s| f64::from(s) / count));
            }
            block_means.extend(part.iter().map(|&s| f64::from(s) / ((w % 8) * rows) as f64));
        }
        PlaneStats {
            mean,
            deviation,
            block_means,
        }
    }
}

/// sum |v - c| over a plane's top `h` rows for `c` and `c + 1`, in one pass: the
/// second differs from the first by one for every sample, up for those at
/// or below `c`, down for the rest.
fn abs_differences(p: &Plane, h: usize, c: u8) -> [u64; 2] {
    let w = p.width();
    let data = &p.data()[p.index(0, 0)..];
    let (at_c, at_or_below) = (crate::me::dsp::pixel().abs_count)(data, p.stride(), (w, h), c);
    let n = (w * h) as u64;
    [at_c, at_c + 2 * at_or_below - n]
}

fn plane_weight(source: &Plane, reference: &Plane, rows: usize) -> Option<PlaneWeight> {
    // Two planes' passes at once: they are work the frame's threads would
    // otherwise wait for.
    let (s, r) = rayon::join(
        || PlaneStats::of(source, rows),
        || PlaneStats::of(reference, rows),
    );
    let scale = if r.deviation > 0.5 {
        (f64::from(WEIGHT_ONE) * s.deviation / r.deviation)
            .round()
            .clamp(0.0, 255.0)
    } else {
        f64::from(WEIGHT_ONE)
    };
    let offset = (s.mean - scale / f64::from(WEIGHT_ONE) * r.mean).round();
    let (bs, br) = (&s.block_means, &r.block_means);
    let err = |f| misfit(bs, br, f);
    let line = |(scale, offset): (f64, f64)| move |r: f64| r * scale / f64::from(WEIGHT_ONE) + offset;
    // Where part of the picture changes (a title leaves), the deviations'
    // ratio follows that part; the median follows the rest.
    let clamp = |offset: f64| offset.clamp(-f64::from(MAX_OFFSET), f64::from(MAX_OFFSET));
    let guessed = (scale, clamp(offset));
    let lifted = (f64::from(WEIGHT_ONE), clamp(median_change(bs, br)));
    let (scale, offset) = if err(line(lifted)) < err(line(guessed)) {
        lifted
    } else {
        guessed
    };
    let w = PlaneWeight {
        scale: scale as u8,
        offset: offset as i16,
    };
    if w == PlaneWeight::ONE {
        return None;
    }
    let weigh = line((scale, offset));
    let weighted = err(weigh);
    let spread = bs.iter().map(|&b| (b - s.mean).abs()).sum::<f64>();
    let shift = br.iter().map(|&r| (weigh(r) - r).abs()).sum::<f64>();
    let keep = weighted < KEEP_BELOW * misfit(bs, br, |r| r)
        && weighted < CUT_ABOVE * spread
        && (w.scale == WEIGHT_ONE as u8 || shift >= MIN_SHIFT * br.len() as f64)
        && share_beside_pan(bs, br, source.width().div_ceil(8), weigh) >= MIN_SHARE;
    keep.then_some(w)
}

/// How far the block means `source` are from `f` of the reference's
/// (summed absolute differences); generic, not a `dyn Fn`, so that the
/// line is inlined into the loop over blocks.
fn misfit(source: &[f64], reference: &[f64], f: impl Fn(f64) -> f64) -> f64 {
    source
        .iter()
        .zip(reference)
        .map(|(&s, &r)| (s - f(r)).abs())
        .sum()
}

/// How much of the change `weigh` makes to the block means (`cols` blocks
/// a row) is in their changes: the coefficient `a` of their fit as
/// `a * (weigh(r) - r) + gx * dx + gy * dy`, `dx` and `dy` the reference's
/// block means' central differences (interior blocks), so that what a
/// small pan moves over a gradient of light is not taken for the weight's
/// change. Least absolute deviations (by reweighted least squares): a few
/// blocks that change by far more (a title leaving) weigh little. One
/// where the plane has no interior block (nothing to tell a pan from),
/// zero where the weight changes no block.
fn share_beside_pan(source: &[f64], reference: &[f64], cols: usize, weigh: impl Fn(f64) -> f64) -> f64 {
    let rows = reference.len() / cols;
    let samples: Vec<([f64; 3], f64)> = (1..rows.saturating_sub(1))
        .flat_map(|y| (1..cols.saturating_sub(1)).map(move |x| y * cols + x))
        .map(|i| {
            let dx = (reference[i + 1] - reference[i - 1]) / 2.0;
            let dy = (reference[i + cols] - reference[i - cols]) / 2.0;
            (
                [weigh(reference[i]) - reference[i], dx, dy],
                source[i] - reference[i],
            )
        })
        .collect();
    if samples.is_empty() {
        // Fewer than three block rows or columns: no pan to tell apart,
        // the other rules decide alone.
        return 1.0;
    }
    let mut fit = [1.0, 0.0, 0.0];
    for _ in 0..LAD_ROUNDS {
        let weighted = samples.iter().map(|(f, d)| {
            let off = (d - f.iter().zip(fit).map(|(a, b)| a * b).sum::<f64>()).abs();
            (*f, *d, 1.0 / off.max(0.1))
        });
        let Some(next) = least_squares(weighted) else {
            return 0.0;
        };
        let settled = (next[0] - fit[0]).abs() < LAD_SETTLED;
        fit = next;
        if settled {
            break;
        }
    }
    fit[0]
}

/// Rounds of [`share_beside_pan`]'s reweighting, at most ...
const LAD_ROUNDS: usize = 8;

/// ... stopped once the share moves by less than this in a round (on
/// fish_1160, a weight in most frames, the weights' estimate took 0.93 %
/// of medium's profile with eight rounds always, 0.41 % so; the same
/// streams on seven sequences).
const LAD_SETTLED: f64 = 0.005;

/// The weighted least-squares solution `c` of `f . c = d` over `samples`
/// (`(f, d, weight)`; three unknowns, Cramer's rule); none where singular.
fn least_squares(samples: impl Iterator<Item = ([f64; 3], f64, f64)>) -> Option<[f64; 3]> {
    let mut m = [[0.0f64; 3]; 3];
    let mut v = [0.0f64; 3];
    for (f, d, w) in samples {
        for ((row, va), fa) in m.iter_mut().zip(v.iter_mut()).zip(f) {
            *va += w * fa * d;
            for (mab, fb) in row.iter_mut().zip(f) {
                *mab += w * fa * fb;
            }
        }
    }
    let det3 = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    // A little ridge on the pan's two coefficients: where the reference's
    // block means have no gradient (a flat wall) no pan changes them, and
    // the fit is the weight's change alone.
    let ridge = 1e-6 * (1.0 + m[0][0]);
    m[1][1] += ridge;
    m[2][2] += ridge;
    let d = det3(m);
    // Singular against the diagonal's product (zero where the weight
    // changes no block).
    if d.abs() <= 1e-12 * m[0][0] * m[1][1] * m[2][2] {
        return None;
    }
    let mut c = [0.0; 3];
    for (k, ck) in c.iter_mut().enumerate() {
        let mut mk = m;
        for (row, va) in mk.iter_mut().zip(v) {
            row[k] = va;
        }
        *ck = det3(mk) / d;
    }
    Some(c)
}

/// The median of the block means' changes, rounded.
fn median_change(source: &[f64], reference: &[f64]) -> f64 {
    let mut changes: Vec<f64> = source.iter().zip(reference).map(|(&s, &r)| s - r).collect();
    if changes.is_empty() {
        return 0.0;
    }
    let middle = changes.len() / 2;
    changes.select_nth_unstable_by(middle, f64::total_cmp);
    changes[middle].round()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn textured(w: usize, h: usize, gain: f64, lift: f64) -> Frame {
        let y = Plane::from_fn(w, h, |x, y| {
            let v = 100.0 + 40.0 * ((x as f64 * 0.3).sin() + (y as f64 * 0.23).cos());
            (v * gain + lift).round().clamp(0.0, 255.0) as u8
        })
        .unwrap();
        let c = |v| Plane::filled(w / 2, h / 2, v).unwrap();
        Frame::from_planes(y, c(128), c(128)).unwrap()
    }

    #[test]
    fn a_change_of_light_is_found_and_no_change_gives_no_weight() {
        let dark = textured(64, 48, 1.0, 0.0);
        let bright = textured(64, 48, 1.25, 12.0);
        let w = estimate(&bright, &dark, usize::MAX);
        let y = w.0[0].expect("a luma weight");
        assert!((y.scale as i32 - 80).abs() <= 1, "{y:?}");
        // The weighted reference matches the frame to within rounding.
        let mut predicted = dark.clone();
        w.apply_into(&dark, &mut predicted);
        let worst = (0..48)
            .flat_map(|yy| (0..64).map(move |x| (x, yy)))
            .map(|(x, yy)| (i32::from(predicted.y().get(x, yy)) - i32::from(bright.y().get(x, yy))).abs())
            .max();
        assert!(worst <= Some(2), "{worst:?}");
        assert_eq!((w.0[1], w.0[2]), (None, None));
        assert_eq!(estimate(&dark, &dark, usize::MAX), Weights::NONE);
    }

    /// A flat, noisy picture (a lit tank seen by a lab camera): faint
    /// texture, `lift` added, noise of its own per `seed`.
    fn faint(w: usize, h: usize, lift: f64, seed: u32, shift: usize) -> Frame {
        let y = Plane::from_fn(w, h, |x, y| {
            let texture = 1.5 * ((((x + shift) / 16) + (y / 16)) % 3) as f64;
            let n = (x as u32).wrapping_mul(73_856_093)
                ^ (y as u32).wrapping_mul(19_349_663)
                ^ seed.wrapping_mul(83_492_791);
            let noise = f64::from(n.wrapping_mul(2_654_435_761) >> 28) / 15.0 * 6.0 - 3.0;
            (170.0 + texture + lift + noise).round() as u8
        })
        .unwrap();
        let c = |v| Plane::filled(w / 2, h / 2, v).unwrap();
        Frame::from_planes(y, c(128), c(128)).unwrap()
    }

    #[test]
    fn a_flicker_over_flat_noisy_content_is_weighted_and_a_cut_is_not() {
        // The light flickers by 7 levels between frames whose block means
        // vary little (fish_1160: a weight 40 % of the bits).
        let (before, after) = (faint(128, 96, 0.0, 1, 0), faint(128, 96, 7.0, 2, 0));
        let y = estimate(&after, &before, usize::MAX).0[0].expect("the flicker's weight");
        assert!((i32::from(y.offset) - 7).abs() <= 2, "{y:?}");
        // Other content brightened alike is a cut: no weight.
        let other = textured(128, 96, 1.0, 7.0);
        assert_eq!(estimate(&other, &before, usize::MAX).0[0], None);
    }

    #[test]
    fn the_weights_share_leaves_out_what_a_pan_moves_and_what_an_object_does() {
        // Block means of light that grows across the picture (ever faster)
        // and waves down it, read at `shift` blocks further right.
        let (cols, rows) = (24, 16);
        let light = |shift: f64| -> Vec<f64> {
            (0..rows * cols)
                .map(|i| {
                    let (x, y) = ((i % cols) as f64 + shift, (i / cols) as f64);
                    60.0 + 0.2 * x * x + 8.0 * (y * 0.7).sin()
                })
                .collect()
        };
        let reference = light(0.0);
        // A pan of a quarter block: most blocks a level or more brighter.
        let panned = light(0.25);
        assert!(median_change(&panned, &reference) >= 1.0);
        let lift = |r: f64| r + 2.0;
        assert!(share_beside_pan(&panned, &reference, cols, lift).abs() < 0.15);
        // The same pan two levels brighter, a tenth of the blocks covered
        // by something 40 levels brighter still.
        let lit: Vec<f64> = panned
            .iter()
            .enumerate()
            .map(|(i, v)| v + 2.0 + if i % 10 == 3 { 40.0 } else { 0.0 })
            .collect();
        assert!((share_beside_pan(&lit, &reference, cols, lift) - 1.0).abs() < 0.15);
        // ... and a weight of twice that change explains half of it.
        let more = |r: f64| r + 4.0;
        assert!((share_beside_pan(&lit, &reference, cols, more) - 0.5).abs() < 0.1);
        // On a flat wall no pan changes the means: the change is the light.
        let (wall, lit_wall) = (vec![90.0; rows * cols], vec![92.0; rows * cols]);
        assert!((share_beside_pan(&lit_wall, &wall, cols, lift) - 1.0).abs() < 0.01);
    }

    #[test]
    fn a_level_of_light_is_found_where_a_title_also_leaves() {
        // The frame after is one level brighter, and a title of two thin
        // bright strokes is gone (ball_576's first two frames).
        let plain = |lift: f64| textured(128, 96, 1.0, lift);
        let mut titled = plain(0.0);
        for y in [10, 20] {
            for x in 8..104 {
                titled.plane_mut(0).set(x, y, 250);
            }
        }
        let y = estimate(&plain(1.0), &titled, usize::MAX).0[0].expect("the change of light");
        assert_eq!((i32::from(y.scale), y.offset), (WEIGHT_ONE, 1), "{y:?}");
    }

    #[test]
    fn the_median_change_is_that_of_most_blocks() {
        let reference = [10.0, 20.0, 30.0, 40.0, 50.0];
        let source = [11.2, 21.0, 30.9, 90.0, 10.0];
        assert_eq!(median_change(&source, &reference), 1.0);
        assert_eq!(median_change(&[], &[]), 0.0);
    }
}
