//! The node tests: a ray against all of a node's child boxes at once, four wide (SSE or scalar) or
//! eight wide (AVX).

use glam::Vec4;

use super::{NEAR_START, Node, NodeTest, RayBox, far_scale};

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
        // builds only after detecting AVX.
        unsafe { test8_avx(self, r, tmax) }
    }
}

/// The eight-child node test: the four-child one's operations in 256-bit registers.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
#[inline]
fn test8_avx(n: &Node<8>, r: &RayBox, tmax: f32) -> (u32, [f32; 8]) {
    use std::arch::x86_64::*;
    // SAFETY: each row of `planes` is eight contiguous f32.
    let load = |row: usize| unsafe { _mm256_loadu_ps(n.planes[row].as_ptr()) };
    let mut near = _mm256_set1_ps(NEAR_START);
    let mut far = _mm256_set1_ps(f32::INFINITY);
    for a in 0..3 {
        let (o, inv) = (_mm256_set1_ps(r.origin[a]), _mm256_set1_ps(r.inv_dir[a]));
        // vmaxps / vminps return their second operand when either is NaN.
        near = _mm256_max_ps(_mm256_mul_ps(_mm256_sub_ps(load(r.near[a]), o), inv), near);
        far = _mm256_min_ps(_mm256_mul_ps(_mm256_sub_ps(load(r.far[a]), o), inv), far);
    }
    let far = _mm256_min_ps(_mm256_mul_ps(far, _mm256_set1_ps(far_scale())), _mm256_set1_ps(tmax));
    let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
    let mut entry = [0.0; 8];
    // SAFETY: `entry` holds eight f32.
    unsafe { _mm256_storeu_ps(entry.as_mut_ptr(), near) };
    (mask, entry)
}
