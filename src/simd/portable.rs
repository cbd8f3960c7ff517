//! Eight lanes in a plain array, with no intrinsics: the lanes the eight-lane kernels run in
//! where AVX2 is not allowed, and the reference the vector lane types are tested against. Each
//! method is the scalar operation lane by lane (the compiler may vectorise the loops); masks
//! are bit sets.

#[cfg(target_arch = "x86_64")]
use glam::Vec2;
use glam::Vec3A;

#[cfg(target_arch = "x86_64")]
use super::{BitLanes, CompressLanes, SampleLanes, U32Lanes};
use super::{FusedLanes, Kernel, Lanes, Plain};

/// Eight f32 lanes in an array.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Portable(pub(crate) [f32; 8]);

impl Portable {
    /// `f` of each lane.
    #[inline(always)]
    fn map(self, f: impl Fn(f32) -> f32) -> Self {
        Portable(lanes(|k| f(self.0[k])))
    }

    /// `f` of each pair of lanes.
    #[inline(always)]
    fn zip(self, b: Self, f: impl Fn(f32, f32) -> f32) -> Self {
        Portable(lanes(|k| f(self.0[k], b.0[k])))
    }

    /// The lanes where `f` holds.
    #[inline(always)]
    fn test(self, b: Self, f: impl Fn(f32, f32) -> bool) -> u32 {
        (0..8).fold(0, |m, k| m | u32::from(f(self.0[k], b.0[k])) << k)
    }
}

/// The lanes `f(0)`, …, `f(7)`: a plain loop, which inlines where `std::array::from_fn` and
/// `map` were left out of line.
#[inline(always)]
fn lanes<T: Copy + Default>(f: impl Fn(usize) -> T) -> [T; 8] {
    let mut out = [T::default(); 8];
    for (k, out) in out.iter_mut().enumerate() {
        *out = f(k);
    }
    out
}

/// Every lane of a mask.
const ALL: u32 = 0xff;

impl Lanes for Portable {
    const WIDTH: usize = 8;
    type Mask = u32;
    type Isa = Plain;

    #[inline(always)]
    fn isa(self) -> Plain {
        Plain
    }

    #[inline(always)]
    fn splat(_: Plain, x: f32) -> Self {
        Portable([x; 8])
    }
    #[inline(always)]
    fn places(_: Plain, groups: &[u32; 4], start: &[u32; 4], none: u32) -> [u32; 16] {
        super::lanes::places8(groups, start, none)
    }
    #[inline(always)]
    fn load(_: Plain, x: &[f32]) -> Self {
        Portable(lanes(|k| x[k]))
    }
    #[inline(always)]
    fn lane(&self, j: usize) -> f32 {
        self.0[j]
    }
    #[inline(always)]
    fn store(self, out: &mut [f32]) {
        out[..8].copy_from_slice(&self.0);
    }
    #[inline(always)]
    fn add_to(x: Self, y: Self, z: Self, out: &mut [Vec3A]) {
        for (k, out) in out[..8].iter_mut().enumerate() {
            *out += Vec3A::new(x.0[k], y.0[k], z.0[k]);
        }
    }
    #[inline(always)]
    fn add(self, b: Self) -> Self {
        self.zip(b, |a, b| a + b)
    }
    #[inline(always)]
    fn sub(self, b: Self) -> Self {
        self.zip(b, |a, b| a - b)
    }
    #[inline(always)]
    fn mul(self, b: Self) -> Self {
        self.zip(b, |a, b| a * b)
    }
    #[inline(always)]
    fn div(self, b: Self) -> Self {
        self.zip(b, |a, b| a / b)
    }
    #[inline(always)]
    fn neg(self) -> Self {
        self.map(|a| -a)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        self.map(f32::sqrt)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        self.map(f32::abs)
    }
    #[inline(always)]
    fn max_keep(self, b: Self) -> Self {
        self.zip(b, |a, b| if a > b { a } else { b })
    }
    #[inline(always)]
    fn min_keep(self, b: Self) -> Self {
        self.zip(b, |a, b| if a < b { a } else { b })
    }
    #[inline(always)]
    fn lt(self, b: Self) -> u32 {
        self.test(b, |a, b| a < b)
    }
    #[inline(always)]
    fn gt(self, b: Self) -> u32 {
        self.test(b, |a, b| a > b)
    }
    #[inline(always)]
    fn le(self, b: Self) -> u32 {
        self.test(b, |a, b| a <= b)
    }
    #[inline(always)]
    fn ne(self, b: Self) -> u32 {
        self.test(b, |a, b| a != b)
    }
    #[inline(always)]
    fn eq_or_nan(self, b: Self) -> u32 {
        self.test(b, |a, b| a == b || a.is_nan() || b.is_nan())
    }
    #[inline(always)]
    fn select(self, m: u32, if_set: Self) -> Self {
        Portable(lanes(|k| if m >> k & 1 != 0 { if_set.0[k] } else { self.0[k] }))
    }
    #[inline(always)]
    fn and(a: u32, b: u32) -> u32 {
        a & b
    }
    #[inline(always)]
    fn or(a: u32, b: u32) -> u32 {
        a | b
    }
    #[inline(always)]
    fn andnot(a: u32, b: u32) -> u32 {
        !a & b & ALL
    }
    #[inline(always)]
    fn least(self) -> f32 {
        self.0.into_iter().fold(f32::INFINITY, |m, a| if a < m { a } else { m })
    }
    #[inline(always)]
    fn greatest(self) -> f32 {
        self.0.into_iter().fold(f32::NEG_INFINITY, |m, a| if a > m { a } else { m })
    }
    #[inline(always)]
    fn bits(m: u32) -> u32 {
        m & ALL
    }
    #[inline(always)]
    fn mask(_: Plain, bits: u32) -> u32 {
        bits & ALL
    }
    #[inline]
    fn compiled<K: Kernel<Self>>(isa: Plain, kernel: K) -> K::Output {
        kernel.run(isa)
    }
    #[inline(never)]
    fn compiled_apart<K: Kernel<Self>>(isa: Plain, kernel: K) -> K::Output {
        kernel.run(isa)
    }
}

impl FusedLanes for Portable {
    #[inline(always)]
    fn mul_add(self, b: Self, c: Self) -> Self {
        Portable(lanes(|k| fused(self.0[k], b.0[k], c.0[k])))
    }
}

#[cfg(target_arch = "x86_64")]
impl CompressLanes for Portable {
    #[inline(always)]
    fn load_partial(_: Plain, x: &[f32]) -> Self {
        Portable(lanes(|k| x.get(k).copied().unwrap_or(0.0)))
    }
    #[inline(always)]
    fn compress_store(self, m: u32, out: &mut [f32]) {
        let lanes = (0..8).filter(|&k| m >> k & 1 != 0);
        for (out, k) in out[..(m & ALL).count_ones() as usize].iter_mut().zip(lanes) {
            *out = self.0[k];
        }
    }
    #[inline(always)]
    fn compress_indices(_: Plain, base: u32, m: u32, out: &mut [u32]) {
        let lanes = (0..8).filter(|&k| m >> k & 1 != 0);
        for (out, k) in out[..(m & ALL).count_ones() as usize].iter_mut().zip(lanes) {
            *out = base + k;
        }
    }
    #[inline(always)]
    fn store_partial(self, out: &mut [f32]) {
        for (out, &x) in out.iter_mut().zip(&self.0) {
            *out = x;
        }
    }
}

#[cfg(target_arch = "x86_64")]
impl BitLanes for Portable {
    #[inline(always)]
    fn copysign(self, sign: Self) -> Self {
        self.zip(sign, f32::copysign)
    }
    /// By the definition's branches ([`crate::math::step_float`]).
    #[inline(always)]
    fn step_away(self, o: Self) -> Self {
        self.zip(o, crate::math::step_float)
    }
}

/// `a·b + c` rounded once, as `f32::mul_add`, without its library call where no FMA
/// instruction is compiled in: the product is exact in f64 and the sum rounds once there, and
/// rounding that to f32 is the single rounding unless the f64 sum lies on an f32 halfway point
/// or is an f32 subnormal, where the grid differs; those rare sums take `f32::mul_add`.
#[inline(always)]
fn fused(a: f32, b: f32, c: f32) -> f32 {
    let r = f64::from(a) * f64::from(b) + f64::from(c);
    let halfway = r.to_bits() & 0x1fff_ffff == 0x1000_0000;
    let subnormal = r != 0.0 && r.abs() < f64::from(f32::MIN_POSITIVE);
    if halfway || subnormal { a.mul_add(b, c) } else { r as f32 }
}

/// Eight u32 lanes in an array: [`Portable`]'s u32 lanes ([`SampleLanes::U32`]), each method
/// the scalar operation lane by lane, wrapping as the vector types wrap.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PortableU32(pub(crate) [u32; 8]);

#[cfg(target_arch = "x86_64")]
impl PortableU32 {
    /// `f` of each pair of lanes.
    #[inline(always)]
    fn zip(self, b: Self, f: impl Fn(u32, u32) -> u32) -> Self {
        PortableU32(lanes(|k| f(self.0[k], b.0[k])))
    }
}

/// Shifts by 32 or more give 0, as the vector shifts (`vpsrlvd`, `vpsllvd`) do.
#[cfg(target_arch = "x86_64")]
impl U32Lanes for PortableU32 {
    const WIDTH: usize = 8;
    type Table16 = [u32; 16];
    type Isa = Plain;

    #[inline(always)]
    fn isa(self) -> Plain {
        Plain
    }
    #[inline(always)]
    fn splat(_: Plain, x: u32) -> Self {
        PortableU32([x; 8])
    }
    #[inline(always)]
    fn consecutive(_: Plain, first: u32) -> Self {
        PortableU32(lanes(|k| first.wrapping_add(k as u32)))
    }
    #[inline(always)]
    fn xor(self, b: Self) -> Self {
        self.zip(b, |a, b| a ^ b)
    }
    #[inline(always)]
    fn and(self, b: Self) -> Self {
        self.zip(b, |a, b| a & b)
    }
    #[inline(always)]
    fn add(self, b: Self) -> Self {
        self.zip(b, u32::wrapping_add)
    }
    #[inline(always)]
    fn mul(self, b: Self) -> Self {
        self.zip(b, u32::wrapping_mul)
    }
    #[inline(always)]
    fn shr(self, n: Self) -> Self {
        self.zip(n, |a, n| a.checked_shr(n).unwrap_or(0))
    }
    #[inline(always)]
    fn shl(self, n: Self) -> Self {
        self.zip(n, |a, n| a.checked_shl(n).unwrap_or(0))
    }
    #[inline(always)]
    fn or(self, b: Self) -> Self {
        self.zip(b, |a, b| a | b)
    }
    #[inline(always)]
    fn load(_: Plain, x: &[u32]) -> Self {
        PortableU32(lanes(|k| x[k]))
    }
    #[inline(always)]
    fn store(self, out: &mut [u32]) {
        out[..8].copy_from_slice(&self.0);
    }
    #[inline(always)]
    fn table16(_: Plain, entries: &[u32; 16]) -> [u32; 16] {
        *entries
    }
    #[inline(always)]
    fn lookup16(self, table: [u32; 16]) -> Self {
        PortableU32(lanes(|k| table[(self.0[k] & 15) as usize]))
    }
    #[inline(always)]
    fn test(self, b: Self) -> u32 {
        (0..8).fold(0, |m, k| m | u32::from(self.0[k] & b.0[k] != 0) << k)
    }
}

#[cfg(target_arch = "x86_64")]
impl SampleLanes for Portable {
    type U32 = PortableU32;

    #[inline(always)]
    fn from_u32(i: PortableU32) -> Self {
        Portable(lanes(|k| i.0[k] as f32))
    }
    #[inline(always)]
    fn from_small_u32(i: PortableU32) -> Self {
        Portable(lanes(|k| i.0[k] as f32))
    }
    #[inline(always)]
    fn truncate_small(self) -> PortableU32 {
        PortableU32(std::array::from_fn(|k| self.0[k] as u32))
    }
    #[inline(always)]
    fn store_points(x: Self, y: Self, out: &mut [Vec2]) {
        for (k, out) in out.iter_mut().take(8).enumerate() {
            *out = Vec2::new(x.0[k], y.0[k]);
        }
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use crate::{
        random::SplitMix64,
        simd::{Avx, HasAvx2},
    };

    /// Every operation of the portable lanes gives the AVX lanes' bits, infinities and signed
    /// zeros included, and NaN where they give NaN (where the CPU has AVX2).
    #[test]
    fn portable_lanes_give_the_avx_bits() {
        crate::simd::both_widths(same_as_avx, |_| {});
    }

    /// [`portable_lanes_give_the_avx_bits`].
    fn same_as_avx(isa: HasAvx2) {
        let mut rng = SplitMix64::new(3);
        let special = [0.0, -0.0, 1.0, -2.5, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 1e-40];
        let mut v = || {
            std::array::from_fn::<f32, 8, _>(|_| {
                let r = rng.next_f32();
                if r < 0.3 { special[(r * 26.0) as usize % 8] } else { (r - 0.6) * 10.0 }
            })
        };
        // Bits, every NaN as one (which NaN an operation of two NaNs returns is not specified).
        let bits = |x: [f32; 8]| x.map(|x| if x.is_nan() { u32::MAX } else { x.to_bits() });
        for _ in 0..2_000 {
            let (a, b, c) = (v(), v(), v());
            let (pa, pb, pc) = (Portable(a), Portable(b), Portable(c));
            let (xa, xb, xc) = (Avx::load(isa, &a), Avx::load(isa, &b), Avx::load(isa, &c));
            let same = |p: Portable, x: Avx, what: &str| {
                let x: [f32; 8] = std::array::from_fn(|k| x.lane(k));
                assert_eq!(bits(p.0), bits(x), "{what} of {a:?}, {b:?}");
            };
            same(pa.add(pb), xa.add(xb), "add");
            same(pa.sub(pb), xa.sub(xb), "sub");
            same(pa.mul(pb), xa.mul(xb), "mul");
            same(pa.div(pb), xa.div(xb), "div");
            same(pa.neg(), xa.neg(), "neg");
            same(pa.abs(), xa.abs(), "abs");
            same(pa.max_keep(pb), xa.max_keep(xb), "max_keep");
            same(pa.min_keep(pb), xa.min_keep(xb), "min_keep");
            same(pa.mul_add(pb, pc), xa.mul_add(xb, xc), "mul_add");
            let masks = [
                (pa.lt(pb), Avx::bits(xa.lt(xb))),
                (pa.gt(pb), Avx::bits(xa.gt(xb))),
                (pa.le(pb), Avx::bits(xa.le(xb))),
                (pa.ne(pb), Avx::bits(xa.ne(xb))),
                (pa.eq_or_nan(pb), Avx::bits(xa.eq_or_nan(xb))),
            ];
            for (i, (p, x)) in masks.into_iter().enumerate() {
                assert_eq!(Portable::bits(p), x, "comparison {i} of {a:?}, {b:?}");
            }
            let m = pa.lt(pb);
            same(pa.select(m, pc), xa.select(xa.lt(xb), xc), "select");
            let n = pc.gt(pb);
            let xn = xc.gt(xb);
            assert_eq!(Portable::bits(Portable::and(m, n)), Avx::bits(Avx::and(xa.lt(xb), xn)));
            assert_eq!(Portable::bits(Portable::or(m, n)), Avx::bits(Avx::or(xa.lt(xb), xn)));
            assert_eq!(Portable::bits(Portable::andnot(m, n)), Avx::bits(Avx::andnot(xa.lt(xb), xn)));
            let k = a[0].to_bits() & 0xff;
            assert_eq!(Portable::bits(Portable::mask(Plain, k)), Avx::bits(Avx::mask(isa, k)));
            if a.iter().all(|x| !x.is_nan()) {
                assert_eq!(pa.least(), xa.least());
                assert_eq!(pa.greatest(), xa.greatest());
            }
            let mut sums = [Vec3A::ONE; 8];
            let mut want = sums;
            Portable::add_to(pa, pb, pc, &mut sums);
            Avx::add_to(xa, xb, xc, &mut want);
            let lanes = |v: &[Vec3A; 8]| v.map(|v| glam::Vec4::from(std::arch::x86_64::__m128::from(v)).to_array());
            assert_eq!(format!("{:?}", lanes(&sums)), format!("{:?}", lanes(&want)));
            same(pa.copysign(pb), xa.copysign(xb), "copysign");
        }
    }
}

#[cfg(test)]
mod fused_tests {
    use super::fused;
    use crate::random::SplitMix64;

    /// The fused multiply-add rounds once, as `f32::mul_add` (the correctly rounded one):
    /// where the f64 sum lands on an f32 halfway point it does not round to even again, and
    /// it is right for subnormal results, random ones and products far from the sum.
    #[test]
    fn fused_rounds_once() {
        let up = 1.0 + 2f32.powi(-11) + 2f32.powi(-23);
        let a = 1.0 + 2f32.powi(-12);
        // a² = 1 + 2⁻¹¹ + 2⁻²⁴, a halfway point; 2⁻⁶⁰ lifts it above, below f64's spacing.
        assert_eq!(fused(a, a, 2f32.powi(-60)), up);
        assert_eq!(fused(a, a, -2f32.powi(-60)), 1.0 + 2f32.powi(-11));
        let tiny = 2f32.powi(-70);
        assert_eq!(fused(tiny, tiny * 1.5, 2f32.powi(-149)), tiny.mul_add(tiny * 1.5, 2f32.powi(-149)));
        let mut rng = SplitMix64::new(5);
        for i in 0..100_000 {
            let x = |rng: &mut SplitMix64| f32::from_bits(rng.next_u64() as u32);
            let (a, b, c) = (x(&mut rng), x(&mut rng), x(&mut rng));
            let (got, want) = (fused(a, b, c), a.mul_add(b, c));
            assert!(got.to_bits() == want.to_bits() || (got.is_nan() && want.is_nan()), "{i}: {a} {b} {c}");
        }
    }
}
