//! A 4-wide BVH collapsed from an obvhs BVH2, with the four child boxes of a node stored as
//! structure-of-arrays and tested against a ray at once (SSE on x86_64, scalar elsewhere).
//!
//! The node test keeps the semantics of the scalar slab test it replaces, bit for bit on every
//! decision: a zero direction component gives 0·∞ = NaN exactly when the origin lies on that
//! slab's plane, and such a bound leaves the slab unbounded (the NaN lane is dropped by the
//! min/max, which return their second operand when the first is NaN); the far distance is
//! widened by 2γ(3) (Ize 2013) so rounding never culls a true hit. Each axis takes its near
//! and far planes by the sign of the direction, which for a box with min ≤ max gives the
//! same values as min/max of the two slab distances and lets an empty slot be an inverted box
//! that no ray enters.

use glam::Vec4;
use obvhs::{aabb::Aabb, bvh2::node::Bvh2Node};

use super::ray::Ray;
use crate::math::gamma;

/// Leaf references on the traversal stack: `LEAF | (node << 2) | slot`.
const LEAF: u32 = 1 << 31;

/// Four children: their boxes (min x, y, z, max x, y, z; four lanes each) and what they hold.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct Node4 {
    planes: [Vec4; 6],
    /// Node index of an inner child, or first primitive of a leaf.
    child: [u32; 4],
    /// Primitives in a leaf child; 0 for an inner child or an empty slot.
    count: [u32; 4],
}

/// A ray's constants for the 4-wide node test.
#[derive(Clone, Copy)]
pub struct Ray4 {
    origin: [Vec4; 3],
    inv_dir: [Vec4; 3],
    near: [usize; 3],
    far: [usize; 3],
}

impl Ray4 {
    /// The node-test constants of `ray`.
    #[inline(always)]
    pub fn new(ray: &Ray) -> Self {
        let o = ray.origin;
        let inv = ray.inv_dir;
        // inv_dir is never ±0 or NaN for a finite direction; its sign picks the near plane.
        let (nx, ny, nz) =
            (usize::from(inv.x < 0.0) * 3, 1 + usize::from(inv.y < 0.0) * 3, 2 + usize::from(inv.z < 0.0) * 3);
        Ray4 {
            origin: [Vec4::splat(o.x), Vec4::splat(o.y), Vec4::splat(o.z)],
            inv_dir: [Vec4::splat(inv.x), Vec4::splat(inv.y), Vec4::splat(inv.z)],
            near: [nx, ny, nz],
            far: [(nx + 3) % 6, (ny + 3) % 6, (nz + 3) % 6],
        }
    }
}

/// `max(a, b)`, returning `b` when `a` is NaN.
#[inline(always)]
fn max_keep(a: Vec4, b: Vec4) -> Vec4 {
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
fn min_keep(a: Vec4, b: Vec4) -> Vec4 {
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

impl Node4 {
    const EMPTY: Node4 = Node4 {
        planes: [
            Vec4::INFINITY,
            Vec4::INFINITY,
            Vec4::INFINITY,
            Vec4::NEG_INFINITY,
            Vec4::NEG_INFINITY,
            Vec4::NEG_INFINITY,
        ],
        child: [0; 4],
        count: [0; 4],
    };

    fn set(&mut self, slot: usize, aabb: &Aabb) {
        for a in 0..3 {
            self.planes[a][slot] = aabb.min[a];
            self.planes[a + 3][slot] = aabb.max[a];
        }
    }

    /// Which children the ray enters before `tmax` (bit i for child i) and their entry distances.
    #[inline(always)]
    fn test(&self, r: &Ray4, tmax: f32) -> (u32, Vec4) {
        let p = &self.planes;
        let mut near = Vec4::ZERO;
        let mut far = Vec4::INFINITY;
        for a in 0..3 {
            near = max_keep((p[r.near[a]] - r.origin[a]) * r.inv_dir[a], near);
            far = min_keep((p[r.far[a]] - r.origin[a]) * r.inv_dir[a], far);
        }
        let far = (far * (1.0 + 2.0 * gamma(3))).min(Vec4::splat(tmax));
        (near.cmple(far).bitmask(), near)
    }
}

/// A 4-wide BVH whose leaves are ranges of a primitive array in the BVH2's leaf order.
#[derive(Clone, Debug, Default)]
pub struct Bvh4 {
    nodes: Vec<Node4>,
}

impl Bvh4 {
    /// Collapses a BVH2 (root at 0, children of an inner node at `first_index` and the next):
    /// each node takes in turn the inner child of largest surface area apart until it has four.
    pub fn from_bvh2(bvh2: &[Bvh2Node]) -> Self {
        let Some(root) = bvh2.first() else { return Bvh4::default() };
        let mut nodes = vec![Node4::EMPTY];
        // (BVH2 node whose children fill node4, node4)
        let mut todo = vec![(0usize, 0usize)];
        if root.prim_count > 0 {
            nodes[0].set(0, root.aabb());
            nodes[0].child[0] = root.first_index;
            nodes[0].count[0] = root.prim_count;
            todo.clear();
        }
        while let Some((n, out)) = todo.pop() {
            let first = bvh2[n].first_index as usize;
            let mut kids = vec![first, first + 1];
            while kids.len() < 4 {
                let widest = kids
                    .iter()
                    .enumerate()
                    .filter(|&(_, &k)| bvh2[k].prim_count == 0)
                    .max_by(|a, b| bvh2[*a.1].aabb().half_area().total_cmp(&bvh2[*b.1].aabb().half_area()))
                    .map(|(i, _)| i);
                let Some(i) = widest else { break };
                let k = kids.remove(i);
                let f = bvh2[k].first_index as usize;
                kids.insert(i, f + 1);
                kids.insert(i, f);
            }
            for (slot, &k) in kids.iter().enumerate() {
                let node = &bvh2[k];
                nodes[out].set(slot, node.aabb());
                if node.prim_count > 0 {
                    nodes[out].child[slot] = node.first_index;
                    nodes[out].count[slot] = node.prim_count;
                } else {
                    nodes[out].child[slot] = nodes.len() as u32;
                    todo.push((k, nodes.len()));
                    nodes.push(Node4::EMPTY);
                }
            }
        }
        Bvh4 { nodes }
    }

    /// Replaces every leaf's (first, count) by `f(first, count)`, visiting leaves in node order.
    pub fn map_leaves(&mut self, mut f: impl FnMut(u32, u32) -> (u32, u32)) {
        for node in &mut self.nodes {
            for slot in 0..4 {
                if node.count[slot] > 0 {
                    (node.child[slot], node.count[slot]) = f(node.child[slot], node.count[slot]);
                }
            }
        }
    }

    /// Number of nodes.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Whether there are no nodes.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Any-hit traversal: calls `leaf(first, count, stack)` for leaves the ray enters, in no
    /// particular order, until one returns true. Uses `stack` above its current length only.
    #[inline(always)]
    pub fn occluded(
        &self,
        ray: &Ray,
        stack: &mut Vec<(u32, f32)>,
        mut leaf: impl FnMut(u32, u32, &mut Vec<(u32, f32)>) -> bool,
    ) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let r = Ray4::new(ray);
        let base = stack.len();
        let mut node = 0u32;
        loop {
            let n = &self.nodes[node as usize];
            let (mut mask, _) = n.test(&r, ray.tmax);
            let mut next = None;
            while mask != 0 {
                let i = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if n.count[i] > 0 {
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
    /// hits it finds. Uses `stack` above its current length only.
    #[inline(always)]
    pub fn closest(
        &self,
        ray: &mut Ray,
        stack: &mut Vec<(u32, f32)>,
        mut leaf: impl FnMut(u32, u32, &mut Ray, &mut Vec<(u32, f32)>),
    ) {
        if self.nodes.is_empty() {
            return;
        }
        let r = Ray4::new(ray);
        let base = stack.len();
        let mut item = 0u32;
        loop {
            if item & LEAF != 0 {
                let n = &self.nodes[((item & !LEAF) >> 2) as usize];
                let slot = (item & 3) as usize;
                leaf(n.child[slot], n.count[slot], ray, stack);
            } else {
                let n = &self.nodes[item as usize];
                let (mut mask, near) = n.test(&r, ray.tmax);
                if mask != 0 {
                    let near = near.to_array();
                    let code = |i: usize| if n.count[i] > 0 { LEAF | (item << 2) | i as u32 } else { n.child[i] };
                    // Hit children sorted by entry distance (insertion sort of at most four).
                    let mut hits = [(0u32, 0f32); 4];
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
                    Some((i, d)) if d <= ray.tmax => {
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
