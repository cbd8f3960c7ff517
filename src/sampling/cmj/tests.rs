use super::*;
#[cfg(target_arch = "x86_64")]
use crate::simd::Lanes;

#[test]
fn cmj_is_stratified_on_the_grid_and_both_axes() {
    for n in [16u32, 12, 64] {
        let (m, k) = grid_shape(n);
        for p in [1u32, 99, 12345] {
            let pts: Vec<[f32; 2]> = (0..n).map(|s| Cmj::new(n).sample(s, p)).collect();
            let mut cells = vec![0; n as usize];
            let mut xs = vec![0; n as usize];
            let mut ys = vec![0; n as usize];
            for [x, y] in &pts {
                cells[((y * k as f32) as u32 * m + (x * m as f32) as u32) as usize] += 1;
                xs[(x * n as f32) as usize] += 1;
                ys[(y * n as f32) as usize] += 1;
            }
            assert!(cells.iter().all(|&c| c == 1), "grid, n={n}");
            assert!(xs.iter().all(|&c| c == 1) && ys.iter().all(|&c| c == 1), "1-D, n={n}");
        }
    }
}

/// Every fill path gives `sample`'s values: the pattern in portable lanes and each vector copy
/// this CPU has (AVX-512 and AVX2 lanes, any n, patterns whose permutations would wrap
/// excepted; column and row shuffles from tables up to a 16 × 16 grid, permuted in lanes
/// beyond), the portable loop, and the dispatch. So do the columns, wherever they are computed.
#[test]
fn fill_gives_the_samples_of_sample() {
    type Fill = fn(&Cmj, u32, u32, &mut [Vec2]);
    let mut fills: Vec<(&str, Fill)> = vec![("fill", Cmj::fill), ("portable", |c, f, p, o| c.fill_portable(f, p, o))];
    #[cfg(target_arch = "x86_64")]
    {
        use crate::simd::{Avx, Avx512, HasAvx2, HasAvx512, Plain, Portable};
        fills.push(("portable lanes", |c, f, p, o| {
            if c.in_lanes(p) {
                Portable::compiled(Plain, FillPattern { cmj: c, first: f, p, out: o })
            } else {
                c.fill_portable(f, p, o)
            }
        }));
        if HasAvx2::on_cpu().is_some() {
            fills.push(("avx2", |c, f, p, o| match HasAvx2::on_cpu() {
                Some(isa) if c.in_lanes(p) => Avx::compiled(isa, FillPattern { cmj: c, first: f, p, out: o }),
                _ => c.fill_portable(f, p, o),
            }));
        }
        if HasAvx512::on_cpu().is_some() {
            fills.push(("avx512", |c, f, p, o| match HasAvx512::on_cpu() {
                Some(isa) if c.in_lanes(p) => Avx512::compiled(isa, FillPattern { cmj: c, first: f, p, out: o }),
                _ => c.fill_portable(f, p, o),
            }));
        }
    }
    // This pattern's sample order is seeded u32::MAX − 7: for n > 8 not a power of two it must
    // leave the lanes (the permutation's last step wraps around 2³²).
    let near_wrap = (u32::MAX - 7).wrapping_mul(inverse_odd(0x5163_3e2d));
    assert_eq!(Scrambles::new(near_wrap).order, u32::MAX - 7);
    for n in [1u32, 2, 3, 7, 8, 12, 16, 17, 24, 32, 48, 64, 100, 128, 192, 200, 240, 256, 320, 999, 1000, 1024, 5000] {
        let cmj = Cmj::new(n);
        for p in [0u32, 1, 99, 0xdead_beef, near_wrap] {
            for first in [0, n / 3, n - 1] {
                for (name, fill) in &fills {
                    let mut out = vec![Vec2::NAN; (n - first) as usize];
                    fill(&cmj, first, p, &mut out);
                    for (s, v) in (first..).zip(&out) {
                        assert_eq!(v.to_array(), cmj.sample(s, p), "{name}: n {n}, p {p}, s {s}");
                    }
                }
                let (mut xs, mut ys) = (vec![f32::NAN; (n - first) as usize], vec![f32::NAN; (n - first) as usize]);
                if cmj.fill_columns(first, p, &mut xs, &mut ys) {
                    for (s, (&x, &y)) in (first..).zip(xs.iter().zip(&ys)) {
                        assert_eq!([x, y], cmj.sample(s, p), "columns: n {n}, p {p}, s {s}");
                    }
                } else {
                    #[cfg(target_arch = "x86_64")]
                    assert!(!cmj.in_lanes(p), "n {n}: columns refused");
                    assert!(xs.iter().chain(&ys).all(|v| v.is_nan()), "refused, yet written");
                }
            }
        }
    }
}

/// The slot tables of both packet widths, on every CPU (the patterns' own test below runs
/// each width only where the CPU has its lanes): each is a permutation of the samples, and
/// slot t holds a sample of quarter t / (n/4), its coarse column in that quarter of the m.
#[cfg(target_arch = "x86_64")]
#[test]
fn quadrant_slot_tables_put_each_sample_once_in_its_quarter() {
    for n in [16u32, 32, 64, 128, 256] {
        let cmj = Cmj::new(n);
        let (m, a) = (cmj.m.get(), cmj.m.get().trailing_zeros() - 2);
        for (w, table) in cmj.quadrant_samples.iter().enumerate() {
            let mut seen = vec![false; n as usize];
            for (t, &s) in table[..n as usize].iter().enumerate() {
                assert!(s < n && !seen[s as usize], "n {n}, width {}: sample {s} twice or out of range", 8 << w);
                seen[s as usize] = true;
                // The shuffled sample number's bits: column within the quarter, quarter, row;
                // the low a + 2 are the coarse column.
                let column = s & ((4 << a) - 1);
                assert_eq!(column / (m / 4), t as u32 / (n / 4), "n {n}, width {}: slot {t}", 8 << w);
            }
            assert!(table[n as usize..].iter().all(|&s| s == 0), "n {n}: entries past n");
        }
    }
}

/// A quadrant pattern's slots hold every sample of the pattern once, each at
/// [`Cmj::sample`]'s point, quarter by quarter of x (so of the azimuth 2πx); and a mark on
/// a slot reads back on exactly the sample whose point that slot holds. For the portable
/// lanes and each vector width this CPU has: eight lanes (AVX2) and sixteen (AVX-512).
#[cfg(target_arch = "x86_64")]
#[test]
fn quadrant_patterns_hold_each_sample_once_in_its_quarter() {
    for n in [4u32, 8, 12, 16, 32, 64, 128, 256, 512] {
        let cmj = Cmj::new(n);
        let splits = [16, 32, 64, 128, 256].contains(&n);
        assert_eq!(cmj.has_quadrants(), splits, "n {n}");
        if !splits {
            continue;
        }
        for p in [0u32, 1, 99, 0xdead_beef] {
            pattern_slots_hold_their_samples::<crate::simd::Portable>(crate::simd::Plain, &cmj, p);
            if let Some(isa) = crate::simd::HasAvx2::on_cpu() {
                pattern_slots_hold_their_samples::<crate::simd::Avx>(isa, &cmj, p);
            }
            if let Some(isa) = crate::simd::HasAvx512::on_cpu() {
                pattern_slots_hold_their_samples::<crate::simd::Avx512>(isa, &cmj, p);
            }
        }
    }
}

/// [`slots_hold_their_samples`] for pattern `p` of `cmj` in `L`'s lanes.
#[cfg(target_arch = "x86_64")]
fn pattern_slots_hold_their_samples<L: crate::simd::SampleLanes>(isa: L::Isa, cmj: &Cmj, p: u32) {
    let pattern = QuadrantPattern::<L>::new(isa, cmj, p);
    let points = |packet| {
        let (mut x, mut y) = (vec![0.0f32; L::WIDTH], vec![0.0f32; L::WIDTH]);
        let (xs, ys) = pattern.points(packet);
        xs.store(&mut x);
        ys.store(&mut y);
        (x, y)
    };
    let marked = |g, marks: &[u32; 16]| pattern.marked(g, marks);
    slots_hold_their_samples(cmj, p, L::WIDTH, points, marked);
}

/// The checks of the test above for one pattern `p` of `cmj` taken `width` slots at a time
/// (n / `width` packets): `points(packet)` gives a packet's x and y, `marked(group, marks)`
/// the samples of a group that `marks` (bit t % 16 of word t / 16 for slot t) marks.
#[cfg(target_arch = "x86_64")]
fn slots_hold_their_samples(
    cmj: &Cmj,
    p: u32,
    width: usize,
    points: impl Fn(usize) -> (Vec<f32>, Vec<f32>),
    marked: impl Fn(usize, &[u32; 16]) -> u32,
) {
    let n = cmj.n.get();
    let packets = n as usize / width;
    // Each slot's point, bit for bit.
    let slots: Vec<[f32; 2]> = (0..packets)
        .flat_map(|packet| {
            let (x, y) = points(packet);
            x.into_iter().zip(y).map(|(x, y)| [x, y])
        })
        .collect();
    let samples: Vec<[f32; 2]> = (0..n).map(|s| cmj.sample(s, p)).collect();
    let quarter = n as usize / 4;
    for (t, point) in slots.iter().enumerate() {
        let q = (t / quarter) as f32;
        assert!((q / 4.0..(q + 1.0) / 4.0).contains(&point[0]), "n {n}, p {p}: slot {t} at x {}", point[0]);
        let owners: Vec<usize> = (0..n as usize).filter(|&s| samples[s] == *point).collect();
        assert_eq!(owners.len(), 1, "n {n}, p {p}: slot {t} holds no single sample");
        // A mark on this slot alone reads back on its sample alone.
        let mut marks = [0u32; 16];
        marks[t / 16] = 1 << (t % 16);
        let marked: Vec<usize> = (0..packets)
            .flat_map(|g| {
                let bits = marked(g, &marks);
                (0..width).filter(move |k| bits & (1 << k) != 0).map(move |k| width * g + k)
            })
            .collect();
        assert_eq!(marked, owners, "n {n}, p {p}, width {width}: slot {t}");
    }
}

/// The inverse of odd `a` modulo 2³² (Newton's iteration: each step doubles the correct bits).
fn inverse_odd(a: u32) -> u32 {
    let mut x = a;
    for _ in 0..5 {
        x = x.wrapping_mul(2u32.wrapping_sub(a.wrapping_mul(x)));
    }
    x
}
