//! The node tests: a ray against all of a node's child boxes at once, four wide (SSE or scalar) or
//! eight wide (AVX).

use glam::Vec4;

use super::{NEAR_START, Node, NodeTest, RayBox, far_scale};
#[cfg(target_arch = "x86_64")]
use crate::simd::Lanes;

impl NodeTest<4> for Node<4> {
    #[inline(always)]
    fn test(&self, r: &RayBox, tmax: f32) -> (u32, [f32; 4]) {
        let p = &self.planes;
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
impl NodeTest<8> for Node<8> {
    #[inline(always)]
    fn test(&self, r: &RayBox, tmax: f32) -> (u32, [f32; 8]) {
        // SAFETY: a `Node<8>` exists only inside a `WideBvh<8>`, which `WideBvh::<8>::from_bvh2`
        // builds only after detecting AVX2 ([`crate::simd::avx2`]).
        unsafe { test8::<crate::simd::Avx>(self, r, tmax) }
    }
}

/// The eight-child node test: the four-child one's operations in eight lanes (`L::WIDTH` is 8).
///
/// # Safety
/// The CPU must have `L`'s instruction set.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn test8<L: Lanes>(n: &Node<8>, r: &RayBox, tmax: f32) -> (u32, [f32; 8]) {
    let mut entry = [0.0; 8];
    // SAFETY: the caller's CPU has `L`'s instruction set.
    let mask = unsafe {
        let mut near = L::splat(NEAR_START);
        let mut far = L::splat(f32::INFINITY);
        for a in 0..3 {
            let (o, inv) = (L::splat(r.origin[a]), L::splat(r.inv_dir[a]));
            // `max_keep` / `min_keep` return their second operand when either is NaN.
            near = L::load(&n.planes[r.near[a]]).sub(o).mul(inv).max_keep(near);
            far = L::load(&n.planes[r.far[a]]).sub(o).mul(inv).min_keep(far);
        }
        let far = far.mul(L::splat(far_scale())).min_keep(L::splat(tmax));
        near.store(&mut entry);
        L::bits(near.le(far))
    };
    (mask, entry)
}
