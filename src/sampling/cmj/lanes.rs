//! CMJ patterns in SIMD lanes, a lane type's width of samples at a time, each lane bit for bit
//! the scalar sample: written once over [`SampleLanes`] and compiled per instruction set by
//! [`Lanes::compiled`](crate::simd::Lanes::compiled).

use glam::Vec2;

use super::{Cmj, Scrambles};
use crate::{
    sampling::{
        ONE_MINUS_EPSILON,
        hash::{Modulus, permute, permute_lanes, permute_pow2_lanes, permutes_in_lanes},
    },
    simd::{CompressLanes, Kernel, SampleLanes, U32Lanes},
};

/// The integer part of [`randfloat`](super::randfloat) in each lane, with its operations.
#[inline(always)]
fn randfloat_bits<V: U32Lanes>(i: V, p: V) -> V {
    let isa = i.isa();
    let u = |x: u32| V::splat(isa, x);
    let mut i = i.xor(p);
    i = i.xor(i.shr(u(17)));
    i = i.xor(i.shr(u(10)));
    i = i.mul(u(0xb365_34e5));
    i = i.xor(i.shr(u(12)));
    i = i.xor(i.shr(u(21)));
    i = i.mul(u(0x93fc_4795));
    i = i.xor(u(0xdf6e_307f));
    i = i.xor(i.shr(u(17)));
    i.mul(u(1).or(p.shr(u(18))))
}

/// [`randfloat`](super::randfloat) of each lane, with its operations, so each lane gets its
/// value.
#[inline(always)]
fn randfloat_lanes<L: SampleLanes>(i: L::U32, p: L::U32) -> L {
    let isa = i.isa();
    let f = L::from_u32(randfloat_bits(i, p)).mul(L::splat(isa, 1.0 / 4_294_967_808.0));
    f.min_keep(L::splat(isa, ONE_MINUS_EPSILON))
}

/// One pattern of a [`Cmj`], set up for `L::WIDTH` samples at a time: the sample order's
/// permutation and the two jitters per sample (three of the five hashes) computed in lanes; the
/// column and row shuffles looked up from sixteen-entry tables worked out once
/// ([`U32Lanes::lookup16`]) on a grid of at most 16 × 16, else permuted in lanes too. Each lane
/// does the scalar code's operations in its order, so every value is [`Cmj::sample`]'s.
pub(crate) struct PatternLanes<L: SampleLanes> {
    isa: L::Isa,
    sc: Scrambles,
    n: Modulus,
    cells: Cells,
    inv: [f32; 2],
    shuffles: Shuffles<L::U32>,
}

/// How a shuffled sample number splits into its grid column and row.
enum Cells {
    /// m − 1 and log₂ m, where n (and so m) is a power of two.
    Pow2 { mask: u32, shift: u32 },
    /// m, and ⌈2¹⁶ / m⌉: the row of a sample s < 256 is (s · that) >> 16, exactly.
    Small { m: u32, row_magic: u32 },
    /// m: the row of a sample s < 2²³ is the f32 quotient s / m truncated, exactly (s / m lies
    /// at least 1/m from the next integer above, farther than the quotient's rounding moves it).
    Divided { m: u32 },
}

/// The column and row shuffles of a pattern.
enum Shuffles<V: U32Lanes> {
    /// Column c's shuffled sub-column in entry c of the first table, row r's sub-row in entry r
    /// of the second (entries past m and k are never looked up).
    Tables(V::Table16, V::Table16),
    /// Each lane's column and row permuted in lanes ([`permute_lanes`]) over m and k.
    Permuted(Modulus, Modulus),
}

/// Largest pattern whose rows [`Cells::Divided`] finds exactly.
const DIVIDED_MAX: u32 = 1 << 23;

/// Whether [`PatternLanes`] gives `cmj`'s pattern with scrambles `sc` exactly: every
/// permutation it makes in lanes is [`permute`]'s ([`permutes_in_lanes`]), and its rows are
/// exact.
pub(super) fn takes_pattern(cmj: &Cmj, sc: &Scrambles) -> bool {
    permutes_in_lanes(cmj.n, sc.order)
        && (cmj.has_small_grid()
            || (cmj.n.get() <= DIVIDED_MAX && permutes_in_lanes(cmj.m, sc.x) && permutes_in_lanes(cmj.k, sc.y)))
}

impl<L: SampleLanes> PatternLanes<L> {
    /// Pattern `p` of `cmj`, which must take it in lanes ([`Cmj::in_lanes`]).
    #[inline(always)]
    pub(crate) fn new(isa: L::Isa, cmj: &Cmj, p: u32) -> Self {
        debug_assert!(cmj.in_lanes(p));
        let sc = Scrambles::new(p);
        let m = cmj.m.get();
        let cells = if cmj.n.is_power_of_two() {
            Cells::Pow2 { mask: cmj.m.mask(), shift: m.trailing_zeros() }
        } else if cmj.n.get() <= 256 {
            Cells::Small { m, row_magic: (1u32 << 16).div_ceil(m) }
        } else {
            Cells::Divided { m }
        };
        let shuffles = if cmj.has_small_grid() {
            Shuffles::Tables(shuffle_table::<L::U32>(isa, cmj.m, sc.x), shuffle_table::<L::U32>(isa, cmj.k, sc.y))
        } else {
            Shuffles::Permuted(cmj.m, cmj.k)
        };
        PatternLanes { isa, sc, n: cmj.n, cells, inv: cmj.inv, shuffles }
    }

    /// Each lane's sample `s` after the sample order's permutation.
    #[inline(always)]
    fn shuffled(&self, s: L::U32) -> L::U32 {
        permute_lanes(s, self.n, self.sc.order)
    }

    /// Samples `first, first + 1, …` (x lanes, y lanes); lanes past n hold values of no
    /// sample.
    #[inline(always)]
    fn points(&self, first: u32) -> (L, L) {
        self.points_of(self.shuffled(L::U32::consecutive(self.isa, first)))
    }

    /// The points of the shuffled samples `s` (each lane a sample's place in the pattern,
    /// after the sample order's permutation): x lanes, y lanes.
    #[inline(always)]
    fn points_of(&self, s: L::U32) -> (L, L) {
        let u = |x: u32| L::U32::splat(self.isa, x);
        let (col, row) = match self.cells {
            Cells::Pow2 { mask, shift } => (s.and(u(mask)), s.shr(u(shift))),
            // s < n ≤ 256: the quotient by multiplication is exact, the column s − row·m.
            Cells::Small { m, row_magic } => {
                let row = s.mul(u(row_magic)).shr(u(16));
                (s.add(row.mul(u(m.wrapping_neg()))), row)
            }
            Cells::Divided { m } => {
                let row = L::from_small_u32(s).div(L::splat(self.isa, m as f32)).truncate_small();
                (s.add(row.mul(u(m.wrapping_neg()))), row)
            }
        };
        let (sx, sy) = match self.shuffles {
            Shuffles::Tables(by_col, by_row) => (col.lookup16(by_col), row.lookup16(by_row)),
            Shuffles::Permuted(m, k) => (permute_lanes(col, m, self.sc.x), permute_lanes(row, k, self.sc.y)),
        };
        let jitter = [self.sc.jx, self.sc.jy].map(u);
        point_lanes(self.isa, s, [col, row], [sx, sy], jitter, self.inv)
    }
}

/// [`Cmj::point`](super::Cmj::point) in lanes: the point of each lane's shuffled sample `s` in
/// cell (col, row) of the grid, its sub-cell (sx, sy), jittered by the hashes seeded `jitter`,
/// on a grid of cell sizes `inv` (1/m, 1/k).
#[inline(always)]
fn point_lanes<L: SampleLanes>(
    isa: L::Isa,
    s: L::U32,
    [col, row]: [L::U32; 2],
    [sx, sy]: [L::U32; 2],
    [jx, jy]: [L::U32; 2],
    inv: [f32; 2],
) -> (L, L) {
    let (jx, jy) = (randfloat_lanes::<L>(s, jx), randfloat_lanes::<L>(s, jy));
    let [inv_m, inv_k] = inv.map(|v| L::splat(isa, v));
    // Grid indices are below 2²³: the conversion is exact.
    let f = |v| L::from_small_u32(v);
    let x = f(col).add(f(sy).add(jx).mul(inv_k)).mul(inv_m);
    let y = f(row).add(f(sx).add(jy).mul(inv_m)).mul(inv_k);
    let below_one = L::splat(isa, ONE_MINUS_EPSILON);
    (x.min_keep(below_one), y.min_keep(below_one))
}

/// [`Cmj::fill_each`](super::Cmj::fill_each) as a kernel over the lane type: sample
/// `samples[j]` of pattern `patterns[j]` into `out[j]`, for patterns of a power-of-two size,
/// each lane its own pattern's scrambles.
pub(super) struct FillEach<'a> {
    pub(super) cmj: &'a Cmj,
    pub(super) samples: &'a [u32],
    pub(super) patterns: &'a [u32],
    pub(super) out: &'a mut [Vec2],
}

impl<L: SampleLanes> Kernel<L> for FillEach<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self, isa: L::Isa) {
        let FillEach { cmj, samples, patterns, out } = self;
        debug_assert!(cmj.n.is_power_of_two());
        let u = |x: u32| L::U32::splat(isa, x);
        let (wn, wm, wk) = (cmj.n.mask(), cmj.m.mask(), cmj.k.mask());
        let shift = cmj.m.get().trailing_zeros();
        for ((samples, patterns), out) in
            samples.chunks(L::WIDTH).zip(patterns.chunks(L::WIDTH)).zip(out.chunks_mut(L::WIDTH))
        {
            let load = |values: &[u32]| {
                let mut lanes = [0; 16];
                lanes[..values.len()].copy_from_slice(values);
                L::U32::load(isa, &lanes)
            };
            // `Scrambles::new` of each lane's pattern.
            let p = load(patterns);
            let [order, x, y, jx, jy] = Scrambles::FACTORS.map(|f| p.mul(u(f)));
            let s = permute_pow2_lanes(load(samples), wn, order);
            let (col, row) = (s.and(u(wm)), s.shr(u(shift)));
            let (sx, sy) = (permute_pow2_lanes(col, wm, x), permute_pow2_lanes(row, wk, y));
            let (x, y) = point_lanes::<L>(isa, s, [col, row], [sx, sy], [jx, jy], cmj.inv);
            L::store_points(x, y, out);
        }
    }
}

/// The shuffle of `len` (at most 16) grid columns or rows by `seed` as a table: entry i holds
/// i's shuffled place ([`permute`]); entries past `len` are
/// never looked up.
#[inline(always)]
fn shuffle_table<V: U32Lanes>(isa: V::Isa, len: Modulus, seed: u32) -> V::Table16 {
    let mut entries = [0; 16];
    if len.is_power_of_two() {
        let w = len.mask();
        for from in (0..16).step_by(V::WIDTH) {
            permute_pow2_lanes(V::consecutive(isa, from as u32).and(V::splat(isa, w)), w, V::splat(isa, seed))
                .store(&mut entries[from..]);
        }
    } else {
        for (i, e) in (0..len.get()).zip(&mut entries) {
            *e = permute(i, len, seed);
        }
    }
    V::table16(isa, &entries)
}

/// [`Cmj::fill`] for a pattern taken in lanes ([`Cmj::in_lanes`]): `L::WIDTH` samples at a
/// time ([`PatternLanes::points`]), stored
/// as the `Vec2`s they are.
pub(super) struct FillPattern<'a> {
    pub(super) cmj: &'a Cmj,
    pub(super) first: u32,
    pub(super) p: u32,
    pub(super) out: &'a mut [Vec2],
}

impl<L: SampleLanes> Kernel<L> for FillPattern<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self, isa: L::Isa) {
        let FillPattern { cmj, first, p, out } = self;
        let grid = PatternLanes::<L>::new(isa, cmj, p);
        for (i, chunk) in out.chunks_mut(L::WIDTH).enumerate() {
            let (x, y) = grid.points(first + (L::WIDTH * i) as u32);
            L::store_points(x, y, chunk);
        }
    }
}

/// [`Cmj::fill_columns`] in lanes that store a partial vector ([`CompressLanes`]): samples
/// `first, first + 1, …` of pattern `p`, x into `xs` and y into `ys` (same length).
pub(super) struct FillColumns<'a> {
    pub(super) cmj: &'a Cmj,
    pub(super) first: u32,
    pub(super) p: u32,
    pub(super) xs: &'a mut [f32],
    pub(super) ys: &'a mut [f32],
}

impl<L: SampleLanes + CompressLanes> Kernel<L> for FillColumns<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self, isa: L::Isa) {
        let FillColumns { cmj, first, p, xs, ys } = self;
        assert_eq!(xs.len(), ys.len(), "one column per coordinate");
        let grid = PatternLanes::<L>::new(isa, cmj, p);
        for (i, (xs, ys)) in xs.chunks_mut(L::WIDTH).zip(ys.chunks_mut(L::WIDTH)).enumerate() {
            let (x, y) = grid.points(first + (L::WIDTH * i) as u32);
            x.store_partial(xs);
            y.store_partial(ys);
        }
    }
}

/// A pattern of a [`Cmj`] whose columns fall into quarters of [0, 1) ([`Cmj::has_quadrants`]),
/// its samples taken quadrant by quadrant, `L::WIDTH` slots at a time: slots
/// `q·n/4 … (q + 1)·n/4 − 1` hold the n/4 samples whose x lies in [q/4, (q + 1)/4) (their
/// coarse columns are the m/4 columns of that quarter). A cosine direction's azimuth is 2πx,
/// so consecutive slots make rays into one quarter of the hemisphere (for n/4 ≥ the width;
/// below it one packet spans the quarters in azimuth order), with no sort. Each sample keeps
/// the point [`Cmj::sample`] gives it: only the order in which they are made changes.
///
/// A slot's bits are (low to high) its column within the quarter, its row, its quarter; a
/// shuffled sample number's are its column within the quarter, its quarter, its row, so one
/// is a swap of bit fields of the other.
pub(crate) struct QuadrantPattern<'a, L: SampleLanes> {
    grid: PatternLanes<L>,
    /// Each slot's shuffled sample number ([`Cmj::quadrant_samples`] for this width).
    samples: &'a [u32; 256],
    /// Bits of the column within a quarter (log₂ m − 2) and of the row (log₂ k).
    bits: [u32; 2],
    /// Bits of a packet's slots that pick a column and a row.
    packet_bits: [u32; 2],
}

impl<'a, L: SampleLanes> QuadrantPattern<'a, L> {
    /// Pattern `p` of `cmj`, which must have quadrants ([`Cmj::has_quadrants`]).
    #[inline(always)]
    pub(crate) fn new(isa: L::Isa, cmj: &'a Cmj, p: u32) -> Self {
        debug_assert!(cmj.has_quadrants());
        let (bits, packet_bits) = quadrant_bits(cmj, L::WIDTH as u32);
        let samples = &cmj.quadrant_samples[usize::from(L::WIDTH == 16)];
        QuadrantPattern { grid: PatternLanes::new(isa, cmj, p), samples, bits, packet_bits }
    }

    /// The points of the slots of packet `packet` (`L::WIDTH` consecutive slots): x lanes, y
    /// lanes.
    #[inline(always)]
    pub(crate) fn points(&self, packet: usize) -> (L, L) {
        let at = L::WIDTH * packet;
        self.grid.points_of(L::U32::load(self.grid.isa, &self.samples[at..at + L::WIDTH]))
    }

    /// Which of the samples `L::WIDTH·group …` (in sample order, as [`Cmj::fill`] numbers
    /// them) lie in a marked slot, slot `t` being marked where bit `t % 16` of `marks[t / 16]`
    /// is set: bit k for the group's sample k.
    #[inline(always)]
    pub(crate) fn marked(&self, group: usize, marks: &[u32; 16]) -> u32 {
        let ([a, b], [pc, pr]) = (self.bits, self.packet_bits);
        let s = self.grid.shuffled(L::U32::consecutive(self.grid.isa, (L::WIDTH * group) as u32));
        let [col, quarter, row] = split_bits(s, [a, 2, b]);
        let [col_lo, col_hi, _] = split_bits(col, [pc, a - pc, 0]);
        let [row_lo, row_hi, _] = split_bits(row, [pr, b - pr, 0]);
        let rest = join_bits([col_hi, row_hi, quarter], [a - pc, b - pr, 2]);
        marked_lanes(join_bits([col_lo, row_lo, rest], [pc, pr, 0]), marks)
    }
}

/// The lanes whose slot (`slots`, one per lane, each below 256) is marked, slot `t` being
/// marked where bit `t % 16` of `marks[t / 16]` is set: bit k for lane k.
#[inline(always)]
fn marked_lanes<V: U32Lanes>(slots: V, marks: &[u32; 16]) -> u32 {
    let isa = slots.isa();
    let word = slots.shr(V::splat(isa, 4)).lookup16(V::table16(isa, marks));
    word.shr(slots.and(V::splat(isa, 15))).test(V::splat(isa, 1))
}

/// Each lane of `v` cut into three bit fields of `widths` bits, lowest first.
#[inline(always)]
fn split_bits<V: U32Lanes>(v: V, widths: [u32; 3]) -> [V; 3] {
    let isa = v.isa();
    let field = |shift: u32, bits: u32| v.shr(V::splat(isa, shift)).and(V::splat(isa, (1 << bits) - 1));
    let [a, b, c] = widths;
    [field(0, a), field(a, b), field(a + b, c)]
}

/// Three bit fields of `widths` bits joined in each lane, the first lowest: the inverse of
/// [`split_bits`].
#[inline(always)]
fn join_bits<V: U32Lanes>(fields: [V; 3], widths: [u32; 3]) -> V {
    let [x, y, z] = fields;
    let isa = x.isa();
    x.or(y.shl(V::splat(isa, widths[0]))).or(z.shl(V::splat(isa, widths[0] + widths[1])))
}

/// The bits of a quadrant pattern's slots ([`QuadrantPattern`]) for packets of `width` slots:
/// the bits of the column within a quarter and of the row, and those of a packet's slots that
/// pick a column and a row. At most half a packet's bits (rounded down) pick a column: one of
/// eight slots' three, two of sixteen slots' four.
pub(super) fn quadrant_bits(cmj: &Cmj, width: u32) -> ([u32; 2], [u32; 2]) {
    let [a, b] = [cmj.m.get().trailing_zeros() - 2, cmj.k.get().trailing_zeros()];
    let lanes = width.trailing_zeros();
    let column_bits = lanes / 2;
    let packet_bits = if a + b <= lanes {
        [a, b]
    } else {
        let columns = a.min(column_bits).max(lanes.saturating_sub(b));
        [columns, lanes - columns]
    };
    ([a, b], packet_bits)
}

/// Slot `t`'s shuffled sample number in a quadrant pattern of these bits: its column within
/// the quarter, row and quarter (the slot's fields, packet bits lowest) rearranged as column,
/// quarter, row.
pub(super) fn quadrant_sample(t: u32, [a, b]: [u32; 2], [pc, pr]: [u32; 2]) -> u32 {
    let field = |v: u32, shift: u32, bits: u32| (v >> shift) & ((1 << bits) - 1);
    let (col_lo, row_lo, rest) = (field(t, 0, pc), field(t, pc, pr), t >> (pc + pr));
    let (col_hi, row_hi, quarter) =
        (field(rest, 0, a - pc), field(rest, a - pc, b - pr), field(rest, a - pc + b - pr, 2));
    let col = col_lo | col_hi << pc;
    let row = row_lo | row_hi << pr;
    col | quarter << a | row << (a + 2)
}
