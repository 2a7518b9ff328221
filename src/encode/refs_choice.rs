//! How many references each block P frame searches, chosen from what the
//! older references gave the frames before it: a second reference costs
//! its search on every macroblock, and pays on some footage (a webcam
//! repeating frames, an animation drawn on alternate frames, a pan coming
//! back) and not on most (a still scene under a flickering light, where
//! the blocks that take it bring the deblocking across two references
//! over detail). Each frame that searched the older references measures
//! how much of its macroblocks' estimates they saved; once [`HOLD`]
//! frames in a row have saved under [`MIN_SHARE`], the frames after
//! search the first reference alone, but every [`PROBE`]-th frame
//! searches them all to measure again. Learnt from frames two back (as
//! the luma filter and the deblocking are), so the stream is the same for
//! any number of threads.

/// What a frame's older references saved its macroblocks' decisions:
/// over the macroblocks analysed beyond skip, the estimates (SATD +
/// sqrt(lambda) * bits) by which the best candidate into an older
/// reference beat the best into the first (`saved`), and the best
/// estimates themselves (`total`). Whole numbers, summed in any order to
/// the same sums.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub(super) struct OlderGain {
    pub saved: u64,
    pub total: u64,
}

impl OlderGain {
    /// One macroblock's: `first` the best estimate into the first
    /// reference, `older` the best into an older one (infinite: none).
    pub fn of(first: f64, older: f64) -> OlderGain {
        if !first.is_finite() {
            return OlderGain::default();
        }
        let best = first.min(older);
        OlderGain {
            saved: (first - best).round() as u64,
            total: best.round() as u64,
        }
    }

    /// The sum of two.
    pub fn plus(self, other: OlderGain) -> OlderGain {
        OlderGain {
            saved: self.saved + other.saved,
            total: self.total + other.total,
        }
    }
}

/// The share of a frame's estimates the older references must save for
/// the frames after it to search them. Medium with two references against
/// one, on the 28 sequences and four of other kinds (`benches/pair.py`,
/// their first 60 frames, one run): 0.03 -0.95 % for 1.045x the wall time
/// (birds_720p -6.3 %, album_160 -6.2 %, pan_cif -5.1 %; fish_1160
/// +0.0 %, fastpan_cif +1.6 %), 0.02 -0.91 % for 1.062x (fish_1160
/// +2.3 %), 0.01 -1.18 % for 1.080x (fish_1160 +5.6 %, handheld_vga
/// +3.0 %); both searched in every frame -1.55 % for 1.16x (fish_1160
/// +4.2 %, cartoon_cif +4.1 %). A choice lagging one frame (a scratch
/// build, one thread only, 0.01) took -1.31 % for 1.067x, fish_1160
/// +0.45 % against +5.6 % lagging two: the lag a frame thread needs costs
/// fish_1160's flicker most, and 0.03 leaves it where one reference has it.
const MIN_SHARE: f64 = 0.03;

/// Every this many frames, a frame searches every reference whatever was
/// measured before, to measure again.
pub(super) const PROBE: usize = 4;

/// How many frames in a row that searched the older references must
/// find them not paying before the frames after stop searching them. A
/// shaking camera comes back to where it was a few frames before now and
/// then (cuts_cif's third shot, slow at QP 27: a frame of 237 bytes with
/// its older references, 4,189 without), and the frames between save
/// little.
/// Medium against the one-frame rule (`benches/pair.py`, the 28
/// sequences and the four kinds, 60 frames, one run): 3 -0.16 % for
/// 1.001x the wall time (light_cif -2.1 %, cuts_cif -0.9 %, album_160
/// -0.7 %; fish_1160 +0.5 %, fastpan_cif +0.4 %), 2 -0.00 % for 0.993x
/// (handheld_vga +1.2 %), 5 -0.26 % for 1.016x (handheld_vga +2.2 %).
/// In slow (three references) the choice with 3 took +0.17 % for 0.924x
/// (cuts_cif +1.5 %, +8.6 % with the one-frame rule), measured again
/// after the skip's check beside older references (the same command)
/// +0.09 % (pchip +0.04 %) for 0.931x (coin_568 -6.2 %; static_noise_cif
/// +2.8 %): slow chooses as medium does.
const HOLD: u8 = 3;

/// How many more frames the older references are searched for (the
/// probes apart), from what the frames that searched them measured.
#[derive(Debug, Clone, Copy)]
pub(super) struct RefsChooser {
    /// Frames that searched the older references and may still find them
    /// not paying before they are left.
    hold: u8,
}

impl Default for RefsChooser {
    /// Every reference until a frame says otherwise.
    fn default() -> RefsChooser {
        RefsChooser { hold: 1 }
    }
}

impl RefsChooser {
    /// The references frame `index` searches, of `max`.
    pub fn refs(&self, index: usize, max: u8) -> u8 {
        match self.hold > 0 || index % PROBE == 0 {
            true => max,
            false => max.min(1),
        }
    }

    /// Learns from a coded frame: what its older references saved, if it
    /// searched any.
    pub fn learn(&mut self, gain: Option<OlderGain>) {
        if let Some(g) = gain {
            let paid = g.saved as f64 > MIN_SHARE * g.total as f64;
            self.hold = if paid { HOLD } else { self.hold.saturating_sub(1) };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_macroblock_gains_what_the_older_reference_saves() {
        assert_eq!(OlderGain::of(100.4, 60.0), OlderGain { saved: 40, total: 60 });
        assert_eq!(OlderGain::of(100.0, 120.0), OlderGain { saved: 0, total: 100 });
        assert_eq!(
            OlderGain::of(100.0, f64::INFINITY),
            OlderGain { saved: 0, total: 100 }
        );
        // Not analysed beyond skip: nothing either way.
        assert_eq!(OlderGain::of(f64::INFINITY, 5.0), OlderGain::default());
        let sum = OlderGain::of(100.0, 60.0).plus(OlderGain::of(50.0, 80.0));
        assert_eq!(
            sum,
            OlderGain {
                saved: 40,
                total: 110
            }
        );
    }

    #[test]
    fn older_references_are_searched_while_they_pay_and_probed_when_not() {
        let mut c = RefsChooser::default();
        assert!((1..9).all(|i| c.refs(i, 2) == 2), "every reference at first");
        // 1 % saved: not worth the search.
        c.learn(Some(OlderGain {
            saved: 10,
            total: 1000,
        }));
        let refs: Vec<u8> = (1..9).map(|i| c.refs(i, 3)).collect();
        assert_eq!(refs, [1, 1, 1, 3, 1, 1, 1, 3], "probes every {PROBE}th frame");
        // A frame that searched the first alone says nothing.
        c.learn(None);
        assert_eq!(c.refs(5, 2), 1);
        // 5 % saved: searched again.
        c.learn(Some(OlderGain {
            saved: 50,
            total: 1000,
        }));
        assert_eq!(c.refs(5, 2), 2);
        // One reference allowed: one, whatever was learnt.
        assert_eq!(c.refs(4, 1), 1);
    }

    #[test]
    fn older_references_that_paid_are_kept_until_enough_frames_say_they_do_not() {
        let mut c = RefsChooser::default();
        let paid = OlderGain {
            saved: 50,
            total: 1000,
        };
        let not = OlderGain {
            saved: 10,
            total: 1000,
        };
        c.learn(Some(paid));
        // Frame 5 (not a probe) asked after each lesson.
        let mut seen = Vec::new();
        for _ in 0..usize::from(HOLD) {
            seen.push(c.refs(5, 2));
            c.learn(Some(not));
        }
        seen.push(c.refs(5, 2));
        let mut want = vec![2; usize::from(HOLD)];
        want.push(1);
        assert_eq!(seen, want, "searched until {HOLD} frames in a row did not pay");
        // One frame paying again is enough to search them again, for as
        // long.
        c.learn(Some(paid));
        c.learn(Some(not));
        assert_eq!(c.refs(5, 2), 2);
    }
}
