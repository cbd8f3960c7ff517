//! CMJ patterns in SIMD lanes: eight or sixteen samples at a time, each lane bit for bit the
//! scalar sample.

use super::{Cmj, Scrambles};
use crate::sampling::ONE_MINUS_EPSILON;
#[cfg(target_arch = "x86_64")]
use crate::{sampling::hash::permute_pow2_lanes, simd::U32Lanes};

/// The integer part of [`randfloat`](super::randfloat) in each lane, with its operations.
///
/// # Safety
/// The CPU must have `V`'s instruction set.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn randfloat_bits<V: U32Lanes>(i: V, p: u32) -> V {
    // SAFETY: the caller's CPU has `V`'s instruction set.
    unsafe {
        let u = |x: u32| V::splat(x);
        let mut i = i.xor(u(p));
        i = i.xor(i.shr(u(17)));
        i = i.xor(i.shr(u(10)));
        i = i.mul(u(0xb365_34e5));
        i = i.xor(i.shr(u(12)));
        i = i.xor(i.shr(u(21)));
        i = i.mul(u(0x93fc_4795));
        i = i.xor(u(0xdf6e_307f));
        i = i.xor(i.shr(u(17)));
        i.mul(u(1 | p >> 18))
    }
}

/// [`randfloat`](super::randfloat) of each of sixteen lanes (AVX-512F), with its operations, so each lane gets its
/// value.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
fn randfloat_lanes(i: std::arch::x86_64::__m512i, p: u32) -> std::arch::x86_64::__m512 {
    use std::arch::x86_64::*;
    // SAFETY: this function is compiled for AVX-512F.
    let i = unsafe { randfloat_bits(i, p) };
    let f = _mm512_mul_ps(_mm512_cvtepu32_ps(i), _mm512_set1_ps(1.0 / 4_294_967_808.0));
    _mm512_min_ps(f, _mm512_set1_ps(ONE_MINUS_EPSILON))
}

/// [`randfloat`](super::randfloat) of each of eight lanes (AVX2). AVX2 has no unsigned conversion: the high and
/// low halves convert exactly and their sum rounds once, which is the conversion's rounding.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn randfloat_lanes8(i: std::arch::x86_64::__m256i, p: u32) -> std::arch::x86_64::__m256 {
    use std::arch::x86_64::*;
    // SAFETY: this function is compiled for AVX2.
    let i = unsafe { randfloat_bits(i, p) };
    let high = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srli_epi32::<16>(i)), _mm256_set1_ps(65_536.0));
    let low = _mm256_cvtepi32_ps(_mm256_and_si256(i, _mm256_set1_epi32(0xffff)));
    let f = _mm256_mul_ps(_mm256_add_ps(high, low), _mm256_set1_ps(1.0 / 4_294_967_808.0));
    _mm256_min_ps(f, _mm256_set1_ps(ONE_MINUS_EPSILON))
}
/// One pattern of a [`Cmj`] whose n is a power of two on a grid of at most 16 × 16, set up
/// for sixteen samples at a time in AVX-512 lanes: the sample order's permutation and the two
/// jitters per sample (three of the five hashes) computed in lanes, the column and row
/// shuffles looked up from tables of sixteen lanes worked out once. Each lane does the scalar
/// code's operations in its order, so every value is [`Cmj::sample`]'s.
#[cfg(target_arch = "x86_64")]
pub(crate) struct SmallGrid16 {
    sc: Scrambles,
    masks: [u32; 3],
    shift: u32,
    inv: [f32; 2],
    /// Column c's shuffled sub-column in lane c (lanes past m hold values never looked up).
    by_col: std::arch::x86_64::__m512i,
    /// Row r's shuffled sub-row in lane r.
    by_row: std::arch::x86_64::__m512i,
}

#[cfg(target_arch = "x86_64")]
impl SmallGrid16 {
    /// Pattern `p` of `cmj`, which must have a small grid ([`Cmj::has_small_grid16`]).
    #[target_feature(enable = "avx512f")]
    #[inline]
    pub(super) fn new(cmj: &Cmj, p: u32) -> Self {
        use std::arch::x86_64::*;

        debug_assert!(cmj.has_small_grid16());
        let sc = Scrambles::new(p);
        let (wm, wk) = (cmj.m.mask(), cmj.k.mask());
        let iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
        // SAFETY (both calls): this function is compiled for AVX-512F.
        let by_col = unsafe { permute_pow2_lanes(_mm512_and_si512(iota, _mm512_set1_epi32(wm as i32)), wm, sc.x) };
        let by_row = unsafe { permute_pow2_lanes(_mm512_and_si512(iota, _mm512_set1_epi32(wk as i32)), wk, sc.y) };
        SmallGrid16 {
            sc,
            masks: [cmj.n.mask(), wm, wk],
            shift: cmj.m.get().trailing_zeros(),
            inv: cmj.inv,
            by_col,
            by_row,
        }
    }

    /// Samples `first..first + 16` (x lanes, y lanes); lanes past n hold values of no sample.
    #[target_feature(enable = "avx512f")]
    #[inline]
    pub(super) fn points(&self, first: u32) -> (std::arch::x86_64::__m512, std::arch::x86_64::__m512) {
        // SAFETY: this function is compiled for AVX-512F.
        self.points_of(unsafe { permute_pow2_lanes(consecutive16(first), self.masks[0], self.sc.order) })
    }

    /// The points of the shuffled samples `s` (each lane a sample's place in the pattern,
    /// after the sample order's permutation): x lanes, y lanes.
    #[target_feature(enable = "avx512f")]
    #[inline]
    fn points_of(&self, s: std::arch::x86_64::__m512i) -> (std::arch::x86_64::__m512, std::arch::x86_64::__m512) {
        use std::arch::x86_64::*;

        let u = |x: u32| _mm512_set1_epi32(x as i32);
        let wm = self.masks[1];
        let (col, row) = (_mm512_and_si512(s, u(wm)), _mm512_srlv_epi32(s, u(self.shift)));
        let sx = _mm512_permutexvar_epi32(col, self.by_col);
        let sy = _mm512_permutexvar_epi32(row, self.by_row);
        let (jx, jy) = (randfloat_lanes(s, self.sc.jx), randfloat_lanes(s, self.sc.jy));
        let [inv_m, inv_k] = self.inv.map(|v| _mm512_set1_ps(v));
        let f = |v| _mm512_cvtepu32_ps(v);
        let x = _mm512_mul_ps(_mm512_add_ps(f(col), _mm512_mul_ps(_mm512_add_ps(f(sy), jx), inv_k)), inv_m);
        let y = _mm512_mul_ps(_mm512_add_ps(f(row), _mm512_mul_ps(_mm512_add_ps(f(sx), jy), inv_m)), inv_k);
        let below_one = _mm512_set1_ps(ONE_MINUS_EPSILON);
        (_mm512_min_ps(x, below_one), _mm512_min_ps(y, below_one))
    }
}

/// A pattern's grid set up for SIMD lanes: [`SmallGrid16`] (sixteen lanes, AVX-512F) or
/// [`SmallGrid8`] (eight, AVX2). Every method needs the grid's instruction set.
#[cfg(target_arch = "x86_64")]
pub(crate) trait GridLanes: Sized {
    /// Lanes of u32.
    type Index: U32Lanes;
    /// Lanes of f32.
    type Point: Copy;
    /// Lanes per vector.
    const WIDTH: u32;
    /// Most bits of a packet's slots that pick a column ([`QuadrantPattern`]).
    const PACKET_COLUMN_BITS: u32;
    /// Pattern `p` of `cmj`, which must have a small grid ([`Cmj::has_small_grid16`]).
    unsafe fn new(cmj: &Cmj, p: u32) -> Self;
    /// `first, first + 1, …` in lanes.
    unsafe fn consecutive(first: u32) -> Self::Index;
    /// The points of the shuffled samples `s`: x lanes, y lanes.
    unsafe fn points_of(&self, s: Self::Index) -> (Self::Point, Self::Point);
    /// Each lane's sample `s` after the sample order's permutation.
    unsafe fn shuffled(&self, s: Self::Index) -> Self::Index;
    /// The lanes whose slot (`slots`, one per lane, each below 256) is marked, slot `t` being
    /// marked where bit `t % 16` of `marks[t / 16]` is set.
    unsafe fn marked_lanes(slots: Self::Index, marks: &[u32; 16]) -> u32;
}

#[cfg(target_arch = "x86_64")]
impl GridLanes for SmallGrid16 {
    type Index = std::arch::x86_64::__m512i;
    type Point = std::arch::x86_64::__m512;
    const WIDTH: u32 = 16;
    const PACKET_COLUMN_BITS: u32 = 2;
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn new(cmj: &Cmj, p: u32) -> Self {
        SmallGrid16::new(cmj, p)
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn consecutive(first: u32) -> Self::Index {
        consecutive16(first)
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn points_of(&self, s: Self::Index) -> (Self::Point, Self::Point) {
        SmallGrid16::points_of(self, s)
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn shuffled(&self, s: Self::Index) -> Self::Index {
        // SAFETY: this function is compiled for AVX-512F.
        unsafe { permute_pow2_lanes(s, self.masks[0], self.sc.order) }
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn marked_lanes(slots: Self::Index, marks: &[u32; 16]) -> u32 {
        use std::arch::x86_64::*;

        let u = |x: u32| _mm512_set1_epi32(x as i32);
        // SAFETY: the load reads the sixteen entries of `marks`.
        let marks = unsafe { _mm512_loadu_si512(marks.as_ptr().cast()) };
        let word = _mm512_permutexvar_epi32(_mm512_srli_epi32::<4>(slots), marks);
        let bit = _mm512_srlv_epi32(word, _mm512_and_si512(slots, u(15)));
        _mm512_test_epi32_mask(bit, u(1)).into()
    }
}

/// [`SmallGrid16`] eight samples at a time in AVX2 lanes: the same hashes in lanes, each
/// sixteen-entry shuffle table held in two registers and looked up by two lane permutes and a
/// blend ([`lookup16`]). Every value is [`Cmj::sample`]'s.
#[cfg(target_arch = "x86_64")]
pub(crate) struct SmallGrid8 {
    sc: Scrambles,
    masks: [u32; 3],
    shift: u32,
    inv: [f32; 2],
    /// Column c's shuffled sub-column in lane c % 8 of entry c / 8 (lanes past m hold values
    /// never looked up).
    by_col: [std::arch::x86_64::__m256i; 2],
    /// Row r's shuffled sub-row, likewise.
    by_row: [std::arch::x86_64::__m256i; 2],
}

#[cfg(target_arch = "x86_64")]
impl GridLanes for SmallGrid8 {
    type Index = std::arch::x86_64::__m256i;
    type Point = std::arch::x86_64::__m256;
    const WIDTH: u32 = 8;
    const PACKET_COLUMN_BITS: u32 = 1;

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn new(cmj: &Cmj, p: u32) -> Self {
        use std::arch::x86_64::*;

        debug_assert!(cmj.has_small_grid16());
        let sc = Scrambles::new(p);
        let (wm, wk) = (cmj.m.mask(), cmj.k.mask());
        // SAFETY: this function is compiled for AVX2.
        let table = |w: u32, seed: u32| {
            [0, 8].map(|from| unsafe {
                permute_pow2_lanes(_mm256_and_si256(consecutive8(from), _mm256_set1_epi32(w as i32)), w, seed)
            })
        };
        SmallGrid8 {
            by_col: table(wm, sc.x),
            by_row: table(wk, sc.y),
            sc,
            masks: [cmj.n.mask(), wm, wk],
            shift: cmj.m.get().trailing_zeros(),
            inv: cmj.inv,
        }
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn consecutive(first: u32) -> Self::Index {
        consecutive8(first)
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn points_of(&self, s: Self::Index) -> (Self::Point, Self::Point) {
        use std::arch::x86_64::*;

        let u = |x: u32| _mm256_set1_epi32(x as i32);
        let (col, row) = (_mm256_and_si256(s, u(self.masks[1])), _mm256_srlv_epi32(s, u(self.shift)));
        let (sx, sy) = (lookup16(self.by_col, col), lookup16(self.by_row, row));
        let (jx, jy) = (randfloat_lanes8(s, self.sc.jx), randfloat_lanes8(s, self.sc.jy));
        let [inv_m, inv_k] = self.inv.map(|v| _mm256_set1_ps(v));
        // Grid indices are small: the signed conversion is exact.
        let f = |v| _mm256_cvtepi32_ps(v);
        let x = _mm256_mul_ps(_mm256_add_ps(f(col), _mm256_mul_ps(_mm256_add_ps(f(sy), jx), inv_k)), inv_m);
        let y = _mm256_mul_ps(_mm256_add_ps(f(row), _mm256_mul_ps(_mm256_add_ps(f(sx), jy), inv_m)), inv_k);
        let below_one = _mm256_set1_ps(ONE_MINUS_EPSILON);
        (_mm256_min_ps(x, below_one), _mm256_min_ps(y, below_one))
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn shuffled(&self, s: Self::Index) -> Self::Index {
        // SAFETY: this function is compiled for AVX2.
        unsafe { permute_pow2_lanes(s, self.masks[0], self.sc.order) }
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn marked_lanes(slots: Self::Index, marks: &[u32; 16]) -> u32 {
        use std::arch::x86_64::*;

        let u = |x: u32| _mm256_set1_epi32(x as i32);
        // SAFETY: the loads read the sixteen entries of `marks`.
        let table = unsafe {
            let words = marks.as_ptr().cast::<__m256i>();
            [_mm256_loadu_si256(words), _mm256_loadu_si256(words.add(1))]
        };
        let word = lookup16(table, _mm256_srli_epi32::<4>(slots));
        let bit = _mm256_and_si256(_mm256_srlv_epi32(word, _mm256_and_si256(slots, u(15))), u(1));
        _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(bit, u(1)))) as u32
    }
}

/// Entry `i` (0 to 15) of a sixteen-entry table held as two registers of eight, in each lane.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn lookup16(table: [std::arch::x86_64::__m256i; 2], i: std::arch::x86_64::__m256i) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    // The permutes read the low three bits of each index.
    let (low, high) = (_mm256_permutevar8x32_epi32(table[0], i), _mm256_permutevar8x32_epi32(table[1], i));
    _mm256_blendv_epi8(low, high, _mm256_cmpgt_epi32(i, _mm256_set1_epi32(7)))
}

/// `first, first + 1, …, first + 7` in eight lanes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
pub(super) fn consecutive8(first: u32) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    _mm256_add_epi32(_mm256_set1_epi32(first as i32), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7))
}

/// A pattern of a [`Cmj`] whose columns fall into quarters of [0, 1) ([`Cmj::has_quadrants`]),
/// its samples taken quadrant by quadrant, `G::WIDTH` slots at a time: slots
/// `q·n/4 … (q + 1)·n/4 − 1` hold the n/4 samples whose x lies in [q/4, (q + 1)/4) (their
/// coarse columns are the m/4 columns of that quarter). A cosine direction's azimuth is 2πx,
/// so consecutive slots make rays into one quarter of the hemisphere (for n/4 ≥ the width;
/// below it one packet spans the quarters in azimuth order), with no sort. Each sample keeps
/// the point [`Cmj::sample`] gives it: only the order in which they are made changes.
///
/// A slot's bits are (low to high) its column within the quarter, its row, its quarter; a
/// shuffled sample number's are its column within the quarter, its quarter, its row, so one
/// is a swap of bit fields of the other.
#[cfg(target_arch = "x86_64")]
pub(crate) struct QuadrantPattern<'a, G> {
    grid: G,
    /// Each slot's shuffled sample number ([`Cmj::quadrant_samples`] for this width).
    samples: &'a [u32; 256],
    /// Bits of the column within a quarter (log₂ m − 2) and of the row (log₂ k).
    bits: [u32; 2],
    /// Bits of a packet's slots that pick a column and a row.
    packet_bits: [u32; 2],
}

#[cfg(target_arch = "x86_64")]
impl<'a, G: GridLanes> QuadrantPattern<'a, G> {
    /// Pattern `p` of `cmj`, which must have quadrants ([`Cmj::has_quadrants`]).
    ///
    /// # Safety
    /// The CPU must have `G`'s instruction set.
    #[inline(always)]
    pub(crate) unsafe fn new(cmj: &'a Cmj, p: u32) -> Self {
        debug_assert!(cmj.has_quadrants());
        let (bits, packet_bits) = quadrant_bits(cmj, G::WIDTH, G::PACKET_COLUMN_BITS);
        let samples = &cmj.quadrant_samples[usize::from(G::WIDTH == 16)];
        // SAFETY: the caller's CPU has `G`'s instruction set.
        QuadrantPattern { grid: unsafe { G::new(cmj, p) }, samples, bits, packet_bits }
    }

    /// The points of the slots of packet `packet` (`G::WIDTH` consecutive slots): x lanes, y
    /// lanes.
    ///
    /// # Safety
    /// The CPU must have `G`'s instruction set.
    #[inline(always)]
    pub(crate) unsafe fn points(&self, packet: usize) -> (G::Point, G::Point) {
        let at = G::WIDTH as usize * packet;
        // SAFETY: the caller's CPU has `G`'s instruction set.
        unsafe { self.grid.points_of(G::Index::load(&self.samples[at..at + G::WIDTH as usize])) }
    }

    /// Which of the samples `G::WIDTH·group …` (in sample order, as [`Cmj::fill`] numbers
    /// them) lie in a marked slot, slot `t` being marked where bit `t % 16` of `marks[t / 16]`
    /// is set: bit k for the group's sample k.
    ///
    /// # Safety
    /// The CPU must have `G`'s instruction set.
    #[inline(always)]
    pub(crate) unsafe fn marked(&self, group: usize, marks: &[u32; 16]) -> u32 {
        let ([a, b], [pc, pr]) = (self.bits, self.packet_bits);
        // SAFETY: the caller's CPU has `G`'s instruction set.
        unsafe {
            let s = self.grid.shuffled(G::consecutive(G::WIDTH * group as u32));
            let [col, quarter, row] = split_bits(s, [a, 2, b]);
            let [col_lo, col_hi, _] = split_bits(col, [pc, a - pc, 0]);
            let [row_lo, row_hi, _] = split_bits(row, [pr, b - pr, 0]);
            let rest = join_bits([col_hi, row_hi, quarter], [a - pc, b - pr, 2]);
            G::marked_lanes(join_bits([col_lo, row_lo, rest], [pc, pr, 0]), marks)
        }
    }
}

/// `first, first + 1, …, first + 15` in sixteen lanes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
fn consecutive16(first: u32) -> std::arch::x86_64::__m512i {
    use std::arch::x86_64::*;
    let iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    _mm512_add_epi32(_mm512_set1_epi32(first as i32), iota)
}

/// Each lane of `v` cut into three bit fields of `widths` bits, lowest first.
///
/// # Safety
/// The CPU must have `V`'s instruction set.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn split_bits<V: U32Lanes>(v: V, widths: [u32; 3]) -> [V; 3] {
    // SAFETY: the caller's CPU has `V`'s instruction set.
    let field = |shift: u32, bits: u32| unsafe { v.shr(V::splat(shift)).and(V::splat((1 << bits) - 1)) };
    let [a, b, c] = widths;
    [field(0, a), field(a, b), field(a + b, c)]
}

/// Three bit fields of `widths` bits joined in each lane, the first lowest: the inverse of
/// [`split_bits`].
///
/// # Safety
/// The CPU must have `V`'s instruction set.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn join_bits<V: U32Lanes>(fields: [V; 3], widths: [u32; 3]) -> V {
    let [x, y, z] = fields;
    // SAFETY: the caller's CPU has `V`'s instruction set.
    unsafe { x.or(y.shl(V::splat(widths[0]))).or(z.shl(V::splat(widths[0] + widths[1]))) }
}

/// The bits of a quadrant pattern's slots ([`QuadrantPattern`]) for packets of `width` slots
/// with at most `column_bits` of them picking a column: the bits of the column within a quarter
/// and of the row, and those of a packet's slots that pick a column and a row.
#[cfg(target_arch = "x86_64")]
pub(super) fn quadrant_bits(cmj: &Cmj, width: u32, column_bits: u32) -> ([u32; 2], [u32; 2]) {
    let [a, b] = [cmj.m.get().trailing_zeros() - 2, cmj.k.get().trailing_zeros()];
    let lanes = width.trailing_zeros();
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
#[cfg(target_arch = "x86_64")]
pub(super) fn quadrant_sample(t: u32, [a, b]: [u32; 2], [pc, pr]: [u32; 2]) -> u32 {
    let field = |v: u32, shift: u32, bits: u32| (v >> shift) & ((1 << bits) - 1);
    let (col_lo, row_lo, rest) = (field(t, 0, pc), field(t, pc, pr), t >> (pc + pr));
    let (col_hi, row_hi, quarter) =
        (field(rest, 0, a - pc), field(rest, a - pc, b - pr), field(rest, a - pc + b - pr, 2));
    let col = col_lo | col_hi << pc;
    let row = row_lo | row_hi << pr;
    col | quarter << a | row << (a + 2)
}
