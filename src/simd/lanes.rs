//! Lane types: a vector of f32 lanes with a mask of one bit per lane, one implementation per
//! instruction set ([`super::Avx`], [`super::Avx512`], [`super::Portable`]). Each operation is one
//! IEEE operation of the scalar code (no fused multiply-adds unless asked for), so a lane computes
//! bit for bit what the scalar code does.
//!
//! The methods are safe: a lane value proves the CPU has its type's instruction set (it is made
//! only by constructors that take the type's token, [`Lanes::Isa`], or from other values), and
//! constructors without a value take the token. Each is `#[inline(always)]`, so its intrinsics
//! are compiled into the `#[target_feature]` copy of the kernel that calls it
//! ([`Lanes::compiled`]).

#[cfg(target_arch = "x86_64")]
use glam::Vec2;
use glam::Vec3A;

use super::Kernel;
#[cfg(target_arch = "x86_64")]
use super::U32Lanes;

/// A vector of f32 lanes, one per ray or sample of a packet, with a mask of one bit per lane.
pub(crate) trait Lanes: Copy {
    /// Lanes per vector.
    const WIDTH: usize;
    /// A lane mask (itself a proof of the instruction set where it is a vector).
    type Mask: Copy;
    /// The token that proves the CPU has this type's instruction set.
    type Isa: Copy;

    /// The token these lanes prove.
    fn isa(self) -> Self::Isa;
    /// `x` in every lane.
    fn splat(isa: Self::Isa, x: f32) -> Self;
    /// Each lane's place in a run laid out group by group: for lane k in `groups[q]` (disjoint
    /// masks), `start[q]` plus the number of lanes below k in `groups[q]`; `none` for a lane
    /// in no group.
    fn places(isa: Self::Isa, groups: &[u32; 4], start: &[u32; 4], none: u32) -> [u32; 16];
    /// `x[0..WIDTH]`.
    fn load(isa: Self::Isa, x: &[f32]) -> Self;
    /// Writes the lanes to `out[0..WIDTH]`.
    fn store(self, out: &mut [f32]);
    /// Lane `j` (below `WIDTH`), read from where `self` lies in memory.
    fn lane(&self, j: usize) -> f32;
    /// Adds lane k of `x`, `y` and `z` to `out[k]`, for a full vector of `out` (`WIDTH`
    /// elements); the fourth lane of each element gets z's lane, as [`Vec3A::new`] gives it.
    fn add_to(x: Self, y: Self, z: Self, out: &mut [Vec3A]);
    /// `self + b`.
    fn add(self, b: Self) -> Self;
    /// `self − b`.
    fn sub(self, b: Self) -> Self;
    /// `self · b`.
    fn mul(self, b: Self) -> Self;
    /// `self / b`.
    fn div(self, b: Self) -> Self;
    /// `−self`.
    fn neg(self) -> Self;
    /// `√self`, correctly rounded.
    fn sqrt(self) -> Self;
    /// `|self|`.
    fn abs(self) -> Self;
    /// `max(self, b)`, `b` where either is NaN (`maxps`).
    fn max_keep(self, b: Self) -> Self;
    /// `min(self, b)`, `b` where either is NaN (`minps`).
    fn min_keep(self, b: Self) -> Self;
    /// `self < b` (false for NaN).
    fn lt(self, b: Self) -> Self::Mask;
    /// `self > b` (false for NaN).
    fn gt(self, b: Self) -> Self::Mask;
    /// `self ≤ b` (false for NaN).
    fn le(self, b: Self) -> Self::Mask;
    /// `self != b`, or either is NaN.
    fn ne(self, b: Self) -> Self::Mask;
    /// `self == b`, or either is NaN.
    fn eq_or_nan(self, b: Self) -> Self::Mask;
    /// `if_set` in the lanes of `m`, `self` elsewhere.
    fn select(self, m: Self::Mask, if_set: Self) -> Self;
    /// Lanes in both masks.
    fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// Lanes in either mask.
    fn or(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// Lanes in `b` and not in `a`.
    fn andnot(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// The least lane (of numbers, none NaN).
    fn least(self) -> f32;
    /// The greatest lane (of numbers, none NaN).
    fn greatest(self) -> f32;
    /// Bit `i` set for lane `i` in the mask.
    fn bits(m: Self::Mask) -> u32;
    /// The mask with lane `i` set for bit `i` of `bits`.
    fn mask(isa: Self::Isa, bits: u32) -> Self::Mask;
    /// Runs `kernel` compiled for this type's instruction set: the one place a kernel gets its
    /// `#[target_feature]` copy, out of line unless the compiler inlines it into a caller
    /// compiled for the same set.
    fn compiled<K: Kernel<Self>>(isa: Self::Isa, kernel: K) -> K::Output;
    /// [`Lanes::compiled`], never inlined: for a kernel whose set-up must run where it is
    /// called, not be hoisted into its caller's loops.
    fn compiled_apart<K: Kernel<Self>>(isa: Self::Isa, kernel: K) -> K::Output;
}

/// The dot product of two vectors of lanes, `a₀b₀ + a₁b₁ + a₂b₂` summed in that order (as
/// glam's `Vec3A::dot`), so that each lane has the scalar code's bits.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn dot3<L: Lanes>(a: &[L; 3], b: &[L; 3]) -> L {
    a[0].mul(b[0]).add(a[1].mul(b[1])).add(a[2].mul(b[2]))
}

/// Lanes that pack the lanes of a mask together (AVX-512's compress), for sorting a vector of
/// samples into runs by mask without a permutation table.
pub(crate) trait CompressLanes: Lanes {
    /// `x[..n]` in the first `n` lanes and 0 in the rest, for `n` the lesser of `x.len()` and
    /// `WIDTH`; reads nothing past `x`.
    fn load_partial(isa: Self::Isa, x: &[f32]) -> Self;
    /// Writes the lanes of `m` (bit k for lane k), in lane order, to `out[..m.count_ones()]`,
    /// and nothing else.
    fn compress_store(self, m: u32, out: &mut [f32]);
    /// Writes `base + k` for each lane k of `m`, in lane order, to `out[..m.count_ones()]`, and
    /// nothing else.
    fn compress_indices(isa: Self::Isa, base: u32, m: u32, out: &mut [u32]);
    /// Writes the first `n` lanes to `out[..n]`, for `n` the lesser of `out.len()` and `WIDTH`,
    /// and nothing else.
    fn store_partial(self, out: &mut [f32]);
}

/// Lanes that work on their floats' bits: signs and neighbouring floats, for shading frames and
/// ray origins set up in lanes.
pub(crate) trait BitLanes: Lanes {
    /// Each lane with the magnitude of this one and the sign of `sign`'s (`f32::copysign`).
    fn copysign(self, sign: Self) -> Self;
    /// Each lane moved one float the way `o`'s lane points: up where it is positive, down where
    /// it is negative, unchanged otherwise (the geometry's `step_away`, bit for bit, NaN
    /// included).
    fn step_away(self, o: Self) -> Self;
}

/// Lanes with u32 lanes of the same width ([`U32Lanes`]), for the samplers: their integer
/// hashes and shuffle tables run in the u32 lanes, and their points come out in these.
#[cfg(target_arch = "x86_64")]
pub(crate) trait SampleLanes: Lanes {
    /// u32 lanes of this width.
    type U32: U32Lanes<Isa = Self::Isa>;
    /// Each lane of `i` rounded to the nearest f32, as `i as f32` rounds it.
    fn from_u32(i: Self::U32) -> Self;
    /// [`SampleLanes::from_u32`] of lanes below 2³¹, which a signed conversion gives exactly.
    fn from_small_u32(i: Self::U32) -> Self;
    /// Each lane (a number in [0, 2³¹)) truncated toward zero, as `x as u32` truncates it.
    fn truncate_small(self) -> Self::U32;
    /// Writes lane k of `x` and of `y` as `out[k]`, for each k below `out.len()` and `WIDTH`,
    /// and nothing else.
    fn store_points(x: Self, y: Self, out: &mut [Vec2]);
}

/// Lanes with a fused multiply-add (one rounding), for [`FusedPacket`]'s node test.
///
/// [`FusedPacket`]: crate::geometry::wide_bvh::FusedPacket
pub(crate) trait FusedLanes: Lanes {
    /// `self · b + c`, rounded once.
    fn mul_add(self, b: Self, c: Self) -> Self;
}

/// [`Lanes::places`] for eight lanes, one lane at a time: what the eight-lane types share (with
/// AVX2's bit counts inlined where it is compiled for them).
#[inline(always)]
pub(crate) fn places8(groups: &[u32; 4], start: &[u32; 4], none: u32) -> [u32; 16] {
    let mut at = [none; 16];
    for (k, at) in at[..8].iter_mut().enumerate() {
        let below = (1u32 << k) - 1;
        for (lanes, start) in groups.iter().zip(start) {
            if lanes >> k & 1 != 0 {
                *at = start + (lanes & below).count_ones();
            }
        }
    }
    at
}

/// Trait methods of a lane type whose bodies call its instruction set's intrinsics: each made
/// safe and `#[inline(always)]`, its body one `unsafe` block.
macro_rules! isa_methods {
    ($($(#[$m:meta])* fn $name:ident($($arg:tt)*) $(-> $ret:ty)? $body:block)*) => {
        $(
            $(#[$m])*
            #[inline(always)]
            fn $name($($arg)*) $(-> $ret)? {
                // SAFETY: every such method takes a lane value or a token of its type, which
                // proves the CPU has the type's instruction set (`simd::token`); inlined, the
                // intrinsics compile into the `#[target_feature]` copy of the kernel calling it.
                // Memory accesses carry their own notes.
                #[allow(unused_unsafe)]
                unsafe {
                    $body
                }
            }
        )*
    };
}
pub(crate) use isa_methods;

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::{BitLanes, CompressLanes};
    use crate::{
        random::SplitMix64,
        simd::{Avx, Avx512, Plain, Portable},
    };

    /// Compression keeps the lanes of the mask in lane order and writes nothing past them; a
    /// partial load fills the lanes past the slice with 0; a partial store writes the first
    /// lanes and nothing past `out`: in the portable lanes, and in AVX2's and AVX-512's where
    /// the CPU has them.
    #[test]
    fn compression_and_partial_moves_keep_to_their_lanes() {
        packs::<Portable>(Plain);
        crate::simd::both_widths(packs::<Avx>, packs::<Avx512>);
    }

    /// [`compression_and_partial_moves_keep_to_their_lanes`] in lanes `L`: every mask of eight
    /// lanes, or none, all and 498 random ones of sixteen.
    fn packs<L: CompressLanes>(isa: L::Isa) {
        let w = L::WIDTH;
        let all = (1u32 << w) - 1;
        let x: Vec<f32> = (0..w).map(|k| k as f32 * 1.5 - 4.0).collect();
        let mut rng = SplitMix64::new(7);
        let masks: Vec<u32> = if w == 8 {
            (0..=all).collect()
        } else {
            [0, all].into_iter().chain((2..500).map(|_| (rng.next_u64() as u32) & all)).collect()
        };
        for m in masks {
            let kept: Vec<usize> = (0..w).filter(|k| m >> k & 1 != 0).collect();
            let (mut floats, mut indices) = (vec![-7.0f32; w + 1], vec![u32::MAX; w + 1]);
            L::load(isa, &x).compress_store(m, &mut floats);
            L::compress_indices(isa, 100, m, &mut indices);
            for (j, &k) in kept.iter().enumerate() {
                assert_eq!((floats[j], indices[j]), (x[k], 100 + k as u32), "{w} lanes, mask {m:#x}, place {j}");
            }
            assert!(floats[kept.len()..].iter().all(|&f| f == -7.0), "{w} lanes, mask {m:#x}: wrote past its lanes");
            assert!(
                indices[kept.len()..].iter().all(|&i| i == u32::MAX),
                "{w} lanes, mask {m:#x}: wrote past its lanes"
            );
        }
        for len in 0..=w {
            let lanes = L::load_partial(isa, &x[..len]);
            let want: Vec<f32> = (0..w).map(|k| if k < len { x[k] } else { 0.0 }).collect();
            assert_eq!((0..w).map(|k| lanes.lane(k)).collect::<Vec<f32>>(), want, "{w} lanes, load of {len}");
        }
        for len in 0..=w + 1 {
            let mut out = vec![-1.0f32; w + 2];
            L::load(isa, &x).store_partial(&mut out[..len]);
            let want: Vec<f32> = (0..w + 2).map(|k| if k < len.min(w) { x[k] } else { -1.0 }).collect();
            assert_eq!(out, want, "{w} lanes, store of {len}");
        }
    }

    /// `step_away` moves each lane as [`step_float`](crate::math::step_float) does
    /// (`next_float_up` for a positive offset, `next_float_down` for a negative one, else
    /// nothing), bit for bit on zeros, infinities, NaN, subnormals, the largest floats and
    /// random bits: in the portable lanes, and in AVX2's and AVX-512's where the CPU has them.
    #[test]
    fn step_away_is_next_float_up_or_down_in_every_lane() {
        steps::<Portable>(Plain);
        crate::simd::both_widths(steps::<Avx>, steps::<Avx512>);
    }

    /// [`step_away_is_next_float_up_or_down_in_every_lane`] in lanes `L`.
    fn steps<L: BitLanes>(isa: L::Isa) {
        let w = L::WIDTH;
        let mut values = vec![0.0, -0.0, 1.0, -1.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, -f32::NAN];
        values.extend([f32::MIN_POSITIVE, -f32::MIN_POSITIVE, 1e-45, -1e-45, f32::MAX, f32::MIN, 1e3, -2.5e-7]);
        let mut rng = SplitMix64::new(5);
        values.extend((0..1000).map(|_| f32::from_bits(rng.next_u64() as u32)));
        let offsets = [1e-7, -1e-7, 0.0, -0.0, f32::NAN, f32::INFINITY, f32::NEG_INFINITY];
        for start in 0..values.len() {
            let v: Vec<f32> = (0..w).map(|k| values[(start + k * 7) % values.len()]).collect();
            let o: Vec<f32> = (0..w).map(|k| offsets[(start + k) % offsets.len()]).collect();
            let got = L::load(isa, &v).step_away(L::load(isa, &o));
            for k in 0..w {
                let want = crate::math::step_float(v[k], o[k]);
                assert_eq!(
                    got.lane(k).to_bits(),
                    want.to_bits(),
                    "{w} lanes: v = {:e} ({:#x}), o = {}",
                    v[k],
                    v[k].to_bits(),
                    o[k]
                );
            }
        }
    }
}
