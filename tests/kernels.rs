//! SIMD kernels equal their scalar twins on random blocks, unaligned rows,
//! odd strides and picture edges.

use mocomp::codec::cpu;
use mocomp::codec::Plane;
use mocomp::me::cost;
use mocomp::me::dsp::{pixel, PixelDsp, PIXEL};
use proptest::prelude::*;

/// One CPU level's pixel table, with the level's name for messages.
struct Kernels {
    isa: &'static str,
    dsp: &'static PixelDsp,
}

impl std::ops::Deref for Kernels {
    type Target = PixelDsp;
    fn deref(&self) -> &PixelDsp {
        self.dsp
    }
}

/// The table of every level this CPU runs, scalar first.
fn available() -> Vec<Kernels> {
    cpu::available()
        .into_iter()
        .map(|l| Kernels {
            isa: l.name(),
            dsp: PIXEL.at(l),
        })
        .collect()
}

/// xorshift bytes, with runs of 0 and 255 to hit the extremes.
fn bytes(seed: u64, n: usize) -> Vec<u8> {
    let mut s = seed | 1;
    (0..n)
        .map(|i| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            match (i / 37) % 5 {
                0 => 0,
                1 => 255,
                _ => s as u8,
            }
        })
        .collect()
}

#[test]
fn every_kernel_set_equals_scalar_on_every_size() {
    let sets = available();
    assert!(sets.iter().any(|k| k.isa == "scalar"));
    let a = bytes(1, 200 * 80);
    let b = bytes(2, 200 * 80);
    for k in &sets {
        for w in [1, 3, 4, 8, 12, 16, 24, 32, 48, 64] {
            for h in [1, 2, 3, 4, 7, 8, 15, 16, 31, 32, 64] {
                // Unaligned starts and strides of every parity.
                for (oa, ob, sa, sb) in [
                    (0, 0, 64, 64),
                    (1, 3, 65, 97),
                    (7, 29, 131, 70),
                    (15, 16, 200, 199),
                ] {
                    if (h - 1) * sa.max(sb) + w + oa.max(ob) > a.len() || w > sa || w > sb {
                        continue;
                    }
                    let want = cost::sad(&a[oa..], sa, &b[ob..], sb, w, h);
                    assert_eq!(
                        (k.sad)(&a[oa..], sa, &b[ob..], sb, w, h),
                        want,
                        "{} {w}x{h} offsets ({oa},{ob})",
                        k.isa
                    );
                }
            }
        }
    }
}

#[test]
fn every_paired_4x4_satd_equals_scalar() {
    // Chunks of long runs: some all 0 or 255 (the extremes), some mixed.
    let (long_a, long_b) = (bytes(11, 32 * 400), bytes(12, 32 * 401));
    for seed in 0..400 {
        let chunk = |v: &[u8], at: usize| -> [u8; 32] { v[at..at + 32].try_into().unwrap() };
        let (a, b) = (chunk(&long_a, 32 * seed), chunk(&long_b, 32 * seed + 5));
        let want = [0, 4].map(|o| cost::satd(&a[o..], 8, &b[o..], 8, 4, 4));
        // Four tiles: this pair, then the next seed's.
        let c = chunk(&long_b, (32 * seed + 37) % (long_b.len() - 32));
        let quad = [b, c];
        let own = [0, 4].map(|o| cost::satd(&a[o..], 8, &c[o..], 8, 4, 4));
        for k in available() {
            assert_eq!((k.satd_4x4_pair)(&a, &b), want, "{} seed {seed}", k.isa);
            let four = (k.satd_4x4_quad)(&a, &quad);
            assert_eq!(
                four,
                [want[0], want[1], own[0], own[1]],
                "{} quad seed {seed}",
                k.isa
            );
        }
    }
}

#[test]
fn every_capped_16x16_satd_equals_scalar_and_keeps_its_promise() {
    let (long_a, long_b) = (bytes(21, 40 * 16 * 60), bytes(22, 40 * 16 * 61));
    for seed in 0..60 {
        let (a, b) = (&long_a[640 * seed..], &long_b[640 * seed + 3..]);
        let satd = cost::satd(a, 40, b, 40, 16, 16);
        for cap in [0, satd / 4, satd / 2, satd - 1, satd, u32::MAX] {
            let want = mocomp::me::dsp::satd_16x16_capped(a, 40, b, 40, cap);
            // The whole SATD up to the cap, a value above it past it.
            if satd <= cap {
                assert_eq!(want, satd, "seed {seed} cap {cap}");
            } else {
                assert!(
                    want > cap && want <= satd,
                    "seed {seed} cap {cap}: {want} of {satd}"
                );
            }
            for k in available() {
                assert_eq!(
                    (k.satd_16x16_capped)(a, 40, b, 40, cap),
                    want,
                    "{} seed {seed} cap {cap}",
                    k.isa
                );
            }
        }
    }
}

#[test]
fn blocks_at_picture_edges_read_only_their_slice() {
    // The last block of a padded plane ends exactly at the buffer's end.
    let p = Plane::from_fn(48, 32, |x, y| (x * 5 + y * 11) as u8).unwrap();
    let q = Plane::from_fn(48, 32, |x, y| (x * 3 + y * 7) as u8).unwrap();
    let (pad, stride) = (p.pad() as isize, p.stride());
    let last = p.index(48 + pad - 32, 32 + pad - 32);
    for k in available() {
        let got = (k.sad)(&p.data()[last..], stride, &q.data()[last..], stride, 32, 32);
        assert_eq!(
            got,
            cost::sad(&p.data()[last..], stride, &q.data()[last..], stride, 32, 32),
            "{}",
            k.isa
        );
    }
}

#[test]
fn the_dispatched_set_is_one_of_the_available_ones() {
    assert!(available().iter().any(|k| std::ptr::eq(k.dsp, pixel())));
}

proptest! {
    #[test]
    fn random_blocks_agree(
        seed in any::<u64>(),
        size in prop_oneof![Just(4usize), Just(8), Just(16), Just(32)],
        h in 1usize..=32, off in 0usize..32, extra in 0usize..40
    ) {
        let stride = size + extra;
        let a = bytes(seed, off + stride * h + size);
        let b = bytes(seed ^ 0xABCD, off + stride * h + size);
        let want = cost::sad(&a[off..], stride, &b[off / 2..], stride, size, h);
        let h4 = h - h % 4;
        let want_satd = cost::satd(&a[off..], stride, &b[off / 2..], stride, size, h4);
        for k in available() {
            prop_assert_eq!((k.sad)(&a[off..], stride, &b[off / 2..], stride, size, h), want);
            if h4 > 0 {
                prop_assert_eq!((k.satd)(&a[off..], stride, &b[off / 2..], stride, size, h4), want_satd);
            }
        }
    }
}
