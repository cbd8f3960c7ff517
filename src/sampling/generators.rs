//! The RTGU sampler families (Suffern ch. 5), each producing one set of `n` points on [0,1)².
//!
//! Grid-based patterns (regular, jittered, multi-jittered) use an `m × k` grid with `m·k = n`,
//! `m` the largest divisor of `n` not above √n, so any sample count is honoured exactly.

use glam::Vec2;

use crate::random::SplitMix64;

/// Which pattern a sample set follows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum SamplerKind {
    /// Cell centres of a grid; identical in every pixel.
    Regular,
    /// Independent uniform points.
    Random,
    /// One uniform point per grid cell.
    Jittered,
    /// One point per row and per column of an n × n grid (Latin hypercube).
    NRooks,
    /// Jittered and n-rooks at once (Chiu, Shirley, Wang 1994).
    MultiJittered,
    /// (i/n, radical inverse of i), XOR-scrambled per set so that sets differ.
    Hammersley,
    /// Kensler's correlated multi-jittered patterns (computed per sample, no stored sets).
    /// The default: lowest or near-lowest RMSE in `hemi error` on both analytic scenes, at
    /// any spp (see the README).
    #[default]
    CorrelatedMultiJittered,
    /// Owen-scrambled Sobol' in Morton pixel order (pbrt-v4's ZSobol): blue-noise error.
    ZSobol,
}

impl SamplerKind {
    /// Every kind, in declaration order.
    pub const ALL: [SamplerKind; 8] = [
        SamplerKind::Regular,
        SamplerKind::Random,
        SamplerKind::Jittered,
        SamplerKind::NRooks,
        SamplerKind::MultiJittered,
        SamplerKind::Hammersley,
        SamplerKind::CorrelatedMultiJittered,
        SamplerKind::ZSobol,
    ];

    /// The kind's command-line name.
    pub fn name(self) -> &'static str {
        match self {
            SamplerKind::Regular => "regular",
            SamplerKind::Random => "random",
            SamplerKind::Jittered => "jittered",
            SamplerKind::NRooks => "n-rooks",
            SamplerKind::MultiJittered => "multi-jittered",
            SamplerKind::Hammersley => "hammersley",
            SamplerKind::CorrelatedMultiJittered => "cmj",
            SamplerKind::ZSobol => "zsobol",
        }
    }

    /// Parses a command-line name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Whether samples come from precomputed sets rather than being computed per sample.
    pub fn uses_stored_sets(self) -> bool {
        !matches!(self, SamplerKind::ZSobol | SamplerKind::CorrelatedMultiJittered)
    }

    /// Appends one set of `n` points of this pattern to `out` (nothing for computed kinds).
    pub fn generate(self, n: u32, rng: &mut SplitMix64, out: &mut Vec<Vec2>) {
        match self {
            SamplerKind::Regular => regular(n, out),
            SamplerKind::Random => out.extend((0..n).map(|_| Vec2::new(rng.next_f32(), rng.next_f32()))),
            SamplerKind::Jittered => jittered(n, rng, out),
            SamplerKind::NRooks => n_rooks(n, rng, out),
            SamplerKind::MultiJittered => multi_jittered(n, rng, out),
            SamplerKind::Hammersley => hammersley(n, rng, out),
            SamplerKind::CorrelatedMultiJittered | SamplerKind::ZSobol => {}
        }
    }
}

/// Splits `n` into an `m × k` grid (m columns, k rows), m ≤ k, as square as `n` allows.
pub fn grid_shape(n: u32) -> (u32, u32) {
    let mut m = (n as f64).sqrt() as u32;
    while m > 1 && !n.is_multiple_of(m) {
        m -= 1;
    }
    let m = m.max(1);
    (m, n / m)
}

/// Clamps a coordinate into [0,1) so that `x + jitter` rounding up to 1.0 cannot escape.
#[inline]
fn below_one(x: f32) -> f32 {
    x.min(super::ONE_MINUS_EPSILON)
}

fn regular(n: u32, out: &mut Vec<Vec2>) {
    let (m, k) = grid_shape(n);
    for j in 0..k {
        for i in 0..m {
            out.push(Vec2::new((i as f32 + 0.5) / m as f32, (j as f32 + 0.5) / k as f32));
        }
    }
}

fn jittered(n: u32, rng: &mut SplitMix64, out: &mut Vec<Vec2>) {
    let (m, k) = grid_shape(n);
    for j in 0..k {
        for i in 0..m {
            let x = (i as f32 + rng.next_f32()) / m as f32;
            let y = (j as f32 + rng.next_f32()) / k as f32;
            out.push(Vec2::new(below_one(x), below_one(y)));
        }
    }
}

fn shuffle(values: &mut [f32], rng: &mut SplitMix64) {
    for i in (1..values.len()).rev() {
        let j = rng.below(i as u32 + 1) as usize;
        values.swap(i, j);
    }
}

fn n_rooks(n: u32, rng: &mut SplitMix64, out: &mut Vec<Vec2>) {
    let nf = n as f32;
    let mut xs: Vec<f32> = (0..n).map(|i| below_one((i as f32 + rng.next_f32()) / nf)).collect();
    let ys: Vec<f32> = (0..n).map(|i| below_one((i as f32 + rng.next_f32()) / nf)).collect();
    shuffle(&mut xs, rng);
    out.extend(xs.into_iter().zip(ys).map(|(x, y)| Vec2::new(x, y)));
}

/// Chiu–Shirley–Wang multi-jittering on an m × k grid: the canonical arrangement, then x
/// shuffled within each grid column and y within each grid row, which keeps both the coarse
/// (m × k) and the fine (n × n) stratification.
fn multi_jittered(n: u32, rng: &mut SplitMix64, out: &mut Vec<Vec2>) {
    let (m, k) = grid_shape(n);
    let (m, k) = (m as usize, k as usize);
    let nf = n as f32;
    let start = out.len();
    // Cell (i, j): column i of m, row j of k. Canonical placement:
    // x = (i + (j + r)/k)/m, y = (j + (i + r)/m)/k.
    for j in 0..k {
        for i in 0..m {
            let x = (i * k + j) as f32 + rng.next_f32();
            let y = (j * m + i) as f32 + rng.next_f32();
            out.push(Vec2::new(x / nf, y / nf));
        }
    }
    let cells = &mut out[start..];
    // Shuffle x among the cells of each grid column (same i, rows j vary).
    for i in 0..m {
        for j in (1..k).rev() {
            let t = rng.below(j as u32 + 1) as usize;
            let (a, b) = (j * m + i, t * m + i);
            let (xa, xb) = (cells[a].x, cells[b].x);
            cells[a].x = xb;
            cells[b].x = xa;
        }
    }
    // Shuffle y among the cells of each grid row (same j, columns i vary).
    for j in 0..k {
        for i in (1..m).rev() {
            let t = rng.below(i as u32 + 1) as usize;
            let (a, b) = (j * m + i, j * m + t);
            let (ya, yb) = (cells[a].y, cells[b].y);
            cells[a].y = yb;
            cells[b].y = ya;
        }
    }
    for p in cells.iter_mut() {
        *p = Vec2::new(below_one(p.x), below_one(p.y));
    }
}

/// Van der Corput radical inverse in base 2 of `i`, as 32 fixed-point bits.
#[inline]
pub fn radical_inverse_bits(i: u32) -> u32 {
    i.reverse_bits()
}

fn hammersley(n: u32, rng: &mut SplitMix64, out: &mut Vec<Vec2>) {
    // A random offset of x inside its own 1/n stratum and a random digital shift (XOR) of y
    // keep the (0, m, 2)-net structure for n = 2^m while making every set different.
    let offset_x = rng.next_f32() as f64;
    let shift_y = rng.next_u64() as u32;
    let scale = 1.0 / 4_294_967_296.0f64;
    for i in 0..n {
        let x = (i as f64 + offset_x) / n as f64;
        let y = (radical_inverse_bits(i) ^ shift_y) as f64 * scale;
        out.push(Vec2::new(below_one(x as f32), below_one(y as f32)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn set(kind: SamplerKind, n: u32, seed: u64) -> Vec<Vec2> {
        let mut out = Vec::new();
        kind.generate(n, &mut SplitMix64::new(seed), &mut out);
        out
    }

    #[test]
    fn every_sample_lies_in_the_unit_square() {
        for kind in SamplerKind::ALL.into_iter().filter(|k| k.uses_stored_sets()) {
            for n in [1, 2, 7, 16, 64, 100, 256] {
                for seed in 0..20 {
                    let s = set(kind, n, seed);
                    assert_eq!(s.len(), n as usize, "{kind:?}");
                    for p in s {
                        assert!((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y), "{kind:?} {p}");
                    }
                }
            }
        }
    }

    fn one_per_stratum(values: impl Iterator<Item = f32>, strata: u32) -> bool {
        let mut count = vec![0; strata as usize];
        for v in values {
            count[(v * strata as f32) as usize] += 1;
        }
        count.iter().all(|&c| c == 1)
    }

    #[test]
    fn n_rooks_has_one_sample_per_row_and_column() {
        for n in [5, 16, 33] {
            for seed in 0..10 {
                let s = set(SamplerKind::NRooks, n, seed);
                assert!(one_per_stratum(s.iter().map(|p| p.x), n));
                assert!(one_per_stratum(s.iter().map(|p| p.y), n));
            }
        }
    }

    #[test]
    fn multi_jittered_is_stratified_coarse_and_fine() {
        for n in [16, 64, 12, 100] {
            let (m, k) = grid_shape(n);
            for seed in 0..10 {
                let s = set(SamplerKind::MultiJittered, n, seed);
                assert!(one_per_stratum(s.iter().map(|p| p.x), n), "fine x, n={n}");
                assert!(one_per_stratum(s.iter().map(|p| p.y), n), "fine y, n={n}");
                let mut cells = vec![0; n as usize];
                for p in &s {
                    let i = (p.x * m as f32) as u32;
                    let j = (p.y * k as f32) as u32;
                    cells[(j * m + i) as usize] += 1;
                }
                assert!(cells.iter().all(|&c| c == 1), "coarse grid, n={n}");
            }
        }
    }

    #[test]
    fn jittered_and_regular_fill_every_grid_cell() {
        for kind in [SamplerKind::Jittered, SamplerKind::Regular] {
            let s = set(kind, 36, 3);
            let mut cells = [0; 36];
            for p in &s {
                cells[(p.y * 6.0) as usize * 6 + (p.x * 6.0) as usize] += 1;
            }
            assert!(cells.iter().all(|&c| c == 1), "{kind:?}");
        }
    }

    #[test]
    fn hammersley_is_a_net_in_every_elementary_interval() {
        // For n = 2^m every base-2 elementary interval of area 1/n holds exactly one point.
        let n = 256u32;
        for seed in 0..5 {
            let s = set(SamplerKind::Hammersley, n, seed);
            for bx in 0..=8 {
                let (sx, sy) = (1u32 << bx, 1u32 << (8 - bx));
                let mut cells = vec![0; n as usize];
                for p in &s {
                    let i = (p.x * sx as f32) as u32;
                    let j = (p.y * sy as f32) as u32;
                    cells[(j * sx + i) as usize] += 1;
                }
                assert!(cells.iter().all(|&c| c == 1), "interval {sx}x{sy}, seed {seed}");
            }
        }
    }

    #[test]
    fn grid_shape_is_exact() {
        assert_eq!(grid_shape(16), (4, 4));
        assert_eq!(grid_shape(8), (2, 4));
        assert_eq!(grid_shape(7), (1, 7));
        assert_eq!(grid_shape(1), (1, 1));
    }
}
