//! Single-ray traversal: any hit and closest hit, front to back.

use super::{LEAF, NodeTest, RayBox, WideBvh, far_scale};
use crate::geometry::{
    counters::{Event, count},
    ray::Ray,
};
use crate::simd::prefetch;

/// Each traversal takes the node test's token (`test`), which proves the CPU may run it.
impl<const W: usize> WideBvh<W> {
    /// Any-hit traversal: calls `leaf(first, count, stack)` for leaves the ray enters, in no
    /// particular order, until one returns true. Uses `stack` above its current length only.
    #[inline(always)]
    pub(crate) fn occluded(
        &self,
        test: impl NodeTest<W>,
        ray: &Ray,
        stack: &mut Vec<(u32, f32)>,
        leaf: impl FnMut(u32, u32, &mut Vec<(u32, f32)>) -> bool,
    ) -> bool {
        self.occluded_from(test, 0, ray, stack, leaf)
    }

    /// [`WideBvh::occluded`] of the subtree under node `start`.
    #[inline(always)]
    pub(crate) fn occluded_from(
        &self,
        test: impl NodeTest<W>,
        start: u32,
        ray: &Ray,
        stack: &mut Vec<(u32, f32)>,
        leaf: impl FnMut(u32, u32, &mut Vec<(u32, f32)>) -> bool,
    ) -> bool {
        self.occluded_from_touch(test, start, ray, stack, leaf, |_, _| {})
    }

    /// [`WideBvh::occluded_from`], calling `touch(first, count)` for each leaf as soon as
    /// the ray is known to enter it, before visiting any of the node's children (to prefetch
    /// its primitives); the child nodes it enters are prefetched at the same point.
    #[inline(always)]
    pub(crate) fn occluded_from_touch(
        &self,
        test: impl NodeTest<W>,
        start: u32,
        ray: &Ray,
        stack: &mut Vec<(u32, f32)>,
        mut leaf: impl FnMut(u32, u32, &mut Vec<(u32, f32)>) -> bool,
        touch: impl Fn(u32, u32),
    ) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let r = RayBox::new(ray);
        let base = stack.len();
        let mut node = start;
        loop {
            count(Event::NodeTest);
            let n = &self.nodes[node as usize];
            let (mut mask, _) = test.test(n, &r, ray.tmax);
            let mut hits = mask;
            while hits != 0 {
                let i = hits.trailing_zeros() as usize;
                hits &= hits - 1;
                if n.count[i] > 0 {
                    touch(n.child[i], n.count[i]);
                } else {
                    prefetch(&self.nodes[n.child[i] as usize]);
                }
            }
            let mut next = None;
            while mask != 0 {
                let i = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if n.count[i] > 0 {
                    count(Event::LeafTest);
                    if leaf(n.child[i], n.count[i], stack) {
                        stack.truncate(base);
                        return true;
                    }
                } else if next.is_none() {
                    next = Some(n.child[i]);
                } else {
                    stack.push((n.child[i], 0.0));
                }
            }
            node = match next {
                Some(c) => c,
                None => {
                    if stack.len() == base {
                        return false;
                    }
                    match stack.pop() {
                        Some((c, _)) => c,
                        None => return false,
                    }
                }
            };
        }
    }

    /// Closest-hit traversal, front to back: calls `leaf(first, count, ray, stack)` for leaves
    /// the ray enters before `ray.tmax`, nearest entry first; `leaf` shrinks `ray.tmax` to the
    /// hits it finds. Uses `stack` above its current length only. A box is pruned only when its
    /// computed entry lies past `ray.tmax` by more than the node test's rounding bound (the
    /// factor that widens its exit), so a hit at exactly `ray.tmax`'s distance on a box's
    /// boundary is never lost to rounding, whatever order the leaves come in: this and
    /// the packet traversal (`closest_packet`) always find the same closest distance.
    #[inline(always)]
    pub(crate) fn closest(
        &self,
        test: impl NodeTest<W>,
        ray: &mut Ray,
        stack: &mut Vec<(u32, f32)>,
        mut leaf: impl FnMut(u32, u32, &mut Ray, &mut Vec<(u32, f32)>),
    ) {
        if self.nodes.is_empty() {
            return;
        }
        let r = RayBox::new(ray);
        let base = stack.len();
        let mut item = 0u32;
        loop {
            if item & LEAF != 0 {
                count(Event::LeafTest);
                let n = &self.nodes[((item & !LEAF) >> 3) as usize];
                let slot = (item & 7) as usize;
                leaf(n.child[slot], n.count[slot], ray, stack);
            } else {
                count(Event::NodeTest);
                let n = &self.nodes[item as usize];
                let (mut mask, near) = test.test(n, &r, ray.tmax * far_scale());
                if mask != 0 {
                    let code = |i: usize| if n.count[i] > 0 { LEAF | (item << 3) | i as u32 } else { n.child[i] };
                    // Hit children sorted by entry distance (insertion sort of at most W).
                    let mut hits = [(0u32, 0f32); W];
                    let mut k = 0;
                    while mask != 0 {
                        let i = mask.trailing_zeros() as usize;
                        mask &= mask - 1;
                        let entry = (code(i), near[i]);
                        let mut j = k;
                        while j > 0 && hits[j - 1].1 > entry.1 {
                            hits[j] = hits[j - 1];
                            j -= 1;
                        }
                        hits[j] = entry;
                        k += 1;
                    }
                    for &h in hits[1..k].iter().rev() {
                        stack.push(h);
                    }
                    item = hits[0].0;
                    continue;
                }
            }
            loop {
                if stack.len() == base {
                    return;
                }
                match stack.pop() {
                    Some((i, d)) if d <= ray.tmax * far_scale() => {
                        item = i;
                        break;
                    }
                    Some(_) => continue,
                    None => return,
                }
            }
        }
    }
}
