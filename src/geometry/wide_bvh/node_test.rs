//! The node tests: a ray against all of a node's child boxes at once, four wide (SSE or scalar) or
//! eight wide (AVX).

use glam::Vec4;

use super::{NEAR_START, Node, NodeTest, RayBox, far_scale};
#[cfg(target_arch = "x86_64")]
use crate::simd::{Avx, HasAvx2};
use crate::simd::{Lanes, Plain, Portable};

/// Four-wide nodes need no instruction set beyond the baseline.
impl NodeTest<4> for Plain {
    type Lanes = Portable;
    #[inline(always)]
    fn test(self, n: &Node<4>, r: &RayBox, tmax: f32) -> (u32, [f32; 4]) {
        let p = &n.planes;
        let mut near = Vec4::splat(NEAR_START);
        let mut far = Vec4::INFINITY;
        for a in 0..3 {
            let (o, inv) = (Vec4::splat(r.origin[a]), Vec4::splat(r.inv_dir[a]));
            near = max_keep((Vec4::from_array(p[r.near[a]]) - o) * inv, near);
            far = min_keep((Vec4::from_array(p[r.far[a]]) - o) * inv, far);
        }
        let far = (far * far_scale()).min(Vec4::splat(tmax));
        (near.cmple(far).bitmask(), near.to_array())
    }
}

/// `max(a, b)`, returning `b` when `a` is NaN.
#[inline(always)]
pub(super) fn max_keep(a: Vec4, b: Vec4) -> Vec4 {
    #[cfg(target_arch = "x86_64")]
    {
        // maxps returns its second operand when either is NaN.
        // SAFETY: SSE is part of the x86_64 baseline, so the instruction always exists.
        Vec4::from(unsafe { std::arch::x86_64::_mm_max_ps(a.into(), b.into()) })
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        Vec4::from_array(std::array::from_fn(|i| if a[i] > b[i] { a[i] } else { b[i] }))
    }
}

/// `min(a, b)`, returning `b` when `a` is NaN.
#[inline(always)]
pub(super) fn min_keep(a: Vec4, b: Vec4) -> Vec4 {
    #[cfg(target_arch = "x86_64")]
    {
        // minps returns its second operand when either is NaN.
        // SAFETY: SSE is part of the x86_64 baseline, so the instruction always exists.
        Vec4::from(unsafe { std::arch::x86_64::_mm_min_ps(a.into(), b.into()) })
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        Vec4::from_array(std::array::from_fn(|i| if a[i] < b[i] { a[i] } else { b[i] }))
    }
}

#[cfg(target_arch = "x86_64")]
impl NodeTest<8> for HasAvx2 {
    type Lanes = Avx;
    #[inline(always)]
    fn test(self, n: &Node<8>, r: &RayBox, tmax: f32) -> (u32, [f32; 8]) {
        test8::<Avx>(self, n, r, tmax)
    }
}

/// The eight-child test in the portable lanes.
impl NodeTest<8> for Plain {
    type Lanes = Portable;
    #[inline(always)]
    fn test(self, n: &Node<8>, r: &RayBox, tmax: f32) -> (u32, [f32; 8]) {
        test8::<Portable>(self, n, r, tmax)
    }
}

/// The eight-child node test: the four-child one's operations in eight lanes (`L::WIDTH` is 8).
#[inline(always)]
fn test8<L: Lanes>(isa: L::Isa, n: &Node<8>, r: &RayBox, tmax: f32) -> (u32, [f32; 8]) {
    let mut entry = [0.0; 8];
    let mut near = L::splat(isa, NEAR_START);
    let mut far = L::splat(isa, f32::INFINITY);
    for a in 0..3 {
        let (o, inv) = (L::splat(isa, r.origin[a]), L::splat(isa, r.inv_dir[a]));
        // `max_keep` / `min_keep` return their second operand when either is NaN.
        near = L::load(isa, &n.planes[r.near[a]]).sub(o).mul(inv).max_keep(near);
        far = L::load(isa, &n.planes[r.far[a]]).sub(o).mul(inv).min_keep(far);
    }
    let far = far.mul(L::splat(isa, far_scale())).min_keep(L::splat(isa, tmax));
    near.store(&mut entry);
    (L::bits(near.le(far)), entry)
}
