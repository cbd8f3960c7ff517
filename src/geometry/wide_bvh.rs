//! A wide BVH collapsed from an obvhs BVH2, with the child boxes of a node stored as
//! structure-of-arrays and tested against a ray at once: four children per node with SSE (the
//! x86_64 baseline; scalar elsewhere), or eight with AVX, built only where the CPU has it.
//!
//! The node test keeps the semantics of the scalar slab test it replaces, bit for bit on every
//! decision and at either width: a zero direction component gives 0·∞ = NaN exactly when the
//! origin lies on that slab's plane, and such a bound leaves the slab unbounded (the NaN lane
//! is dropped by the min/max, which return their second operand when the first is NaN); the
//! far distance is widened by 2γ(3) (Ize 2013) so rounding never culls a true hit. Each axis
//! takes its near and far planes by the sign of the direction, which for a box with min ≤ max
//! gives the same values as min/max of the two slab distances and lets an empty slot be an
//! inverted box that no ray enters.

use glam::Vec4;
use obvhs::{aabb::Aabb, bvh2::node::Bvh2Node};

use super::{
    counters::{Event, count},
    ray::Ray,
};
#[cfg(target_arch = "x86_64")]
use crate::geometry::lanes::{FusedLanes, Lanes, RayLanes};
use crate::math::gamma;

/// Asks the CPU to start loading `x`'s cache lines (a hint; no effect on results).
#[inline(always)]
pub(crate) fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    {
        let p = (x as *const T).cast::<i8>();
        for line in (0..std::mem::size_of::<T>()).step_by(64) {
            // SAFETY: a prefetch never faults, and `line` stays inside `x`.
            unsafe { std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p.add(line)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}

/// Leaf references on the closest-hit stack: `LEAF | (node << 3) | slot`.
const LEAF: u32 = 1 << 31;

/// `W` children: their boxes (min x, y, z, max x, y, z; `W` lanes each) and what they hold.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct Node<const W: usize> {
    planes: [[f32; W]; 6],
    /// Node index of an inner child, or first primitive of a leaf.
    child: [u32; W],
    /// Primitives in a leaf child; 0 for an inner child or an empty slot.
    count: [u32; W],
}

/// A ray's constants for the node test.
#[derive(Clone, Copy)]
pub struct RayBox {
    origin: [f32; 3],
    inv_dir: [f32; 3],
    near: [usize; 3],
    far: [usize; 3],
}

impl RayBox {
    /// The node-test constants of `ray`.
    #[inline(always)]
    pub fn new(ray: &Ray) -> Self {
        let inv = ray.inv_dir;
        // inv_dir is never ±0 or NaN for a finite direction; its sign picks the near plane.
        let (near, far) = plane_rows(inv.cmplt(glam::Vec3A::ZERO).bitmask());
        RayBox { origin: ray.origin.to_array(), inv_dir: inv.to_array(), near, far }
    }
}

/// The rows of a node's planes that are the near and far planes on each axis for a direction
/// negative on the axes of `negative` (bit a for axis a): row a (the minimum) is the near plane
/// where the direction is positive, row a + 3 (the maximum) where it is negative.
#[inline(always)]
fn plane_rows(negative: u32) -> ([usize; 3], [usize; 3]) {
    let neg = |a: usize| ((negative >> a) & 1) as usize;
    (std::array::from_fn(|a| a + 3 * neg(a)), std::array::from_fn(|a| a + 3 - 3 * neg(a)))
}

/// The ray–children test of a node of width `W`.
pub trait NodeTest<const W: usize> {
    /// Which children the ray enters before `tmax` (bit i for child i) and their entry distances.
    fn test(&self, r: &RayBox, tmax: f32) -> (u32, [f32; W]);
}

/// Where the entry distance starts: the smallest positive f32, so a child whose exit distance
/// is 0 or less is not entered. It can hold only hits at t ≤ 0, which every primitive test
/// rejects: this skips, for instance, the flat leaf box of a plane that a ray starts on.
const NEAR_START: f32 = f32::from_bits(1);

/// How far past the computed exit distance a box still counts as entered (Ize 2013).
#[inline(always)]
fn far_scale() -> f32 {
    1.0 + 2.0 * gamma(3)
}

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

impl<const W: usize> Node<W> {
    const EMPTY: Self = {
        let mut planes = [[f32::INFINITY; W]; 6];
        planes[3] = [f32::NEG_INFINITY; W];
        planes[4] = [f32::NEG_INFINITY; W];
        planes[5] = [f32::NEG_INFINITY; W];
        Node { planes, child: [0; W], count: [0; W] }
    };

    fn set(&mut self, slot: usize, aabb: &Aabb) {
        for a in 0..3 {
            self.planes[a][slot] = aabb.min[a];
            self.planes[a + 3][slot] = aabb.max[a];
        }
    }
}

/// Most children a wide node may have, plus one (slot counts index arrays directly).
const SLOTS: usize = 9;

/// For each node of a BVH2, the least total surface area of the wide nodes its subtree needs
/// when it may take up to `i` slots of its parent's wide node, and how it spends them.
struct SlotPlan {
    /// `cost[n][i]`, for `i` in 1..=W: with one slot, the node is a leaf (cost 0) or a wide
    /// node of its own; with more, its two children may share them instead.
    cost: Vec<[f32; SLOTS]>,
    /// `left[n][i]`: slots the first child gets when node `n` hands its `i` slots to its
    /// children; 0 when it does better with fewer slots.
    left: Vec<[u8; SLOTS]>,
}

impl SlotPlan {
    /// The plan for `bvh2` (root at 0, an inner node's children at `first_index` and the next)
    /// and nodes of `width` children. Costs are filled children first: where every inner
    /// node's children come after it (the binned builder's layout), in reverse array order, one
    /// sequential pass (the dragon's plan 60–64 → 13–19 ms against the order below); else in
    /// reverse breadth-first order.
    fn new(bvh2: &[Bvh2Node], width: usize) -> Self {
        if children_after_parents(bvh2) {
            Self::filled(bvh2, width, (0..bvh2.len()).rev())
        } else {
            Self::filled(bvh2, width, breadth_first(bvh2).into_iter().rev())
        }
    }

    /// [`SlotPlan::new`], visiting the nodes in the order `children_first` gives (every
    /// node after its children).
    fn filled(bvh2: &[Bvh2Node], width: usize, children_first: impl Iterator<Item = usize>) -> Self {
        debug_assert!((2..SLOTS).contains(&width));
        let mut plan = SlotPlan { cost: vec![[0.0; SLOTS]; bvh2.len()], left: vec![[0; SLOTS]; bvh2.len()] };
        for n in children_first {
            let node = &bvh2[n];
            if node.prim_count > 0 {
                continue;
            }
            let first = node.first_index as usize;
            let mut cost = [0.0; SLOTS];
            let mut left = [0; SLOTS];
            cost[1] = node.aabb().half_area() + plan.shared(first, width).0;
            for i in 2..=width {
                let (shared, k) = plan.shared(first, i);
                (cost[i], left[i]) = if shared < cost[i - 1] { (shared, k as u8) } else { (cost[i - 1], 0) };
            }
            plan.cost[n] = cost;
            plan.left[n] = left;
        }
        plan
    }

    /// The least cost of children `first` and `first + 1` sharing `slots` slots, and the
    /// first child's share (the smallest of equals).
    fn shared(&self, first: usize, slots: usize) -> (f32, usize) {
        let (l, r) = (&self.cost[first], &self.cost[first + 1]);
        (1..slots).map(|k| (l[k] + r[slots - k], k)).fold((f32::INFINITY, 1), |a, b| if b.0 < a.0 { b } else { a })
    }

    /// Fills `kids` with the BVH2 nodes that become the children of inner node `n`'s wide node
    /// of `width` slots, in BVH2 order. `todo` is scratch space.
    fn fill(&self, bvh2: &[Bvh2Node], n: usize, width: usize, kids: &mut Vec<usize>, todo: &mut Vec<(usize, usize)>) {
        kids.clear();
        let first = bvh2[n].first_index as usize;
        let k = self.shared(first, width).1;
        // (node, slots it may take); the second child is taken after the first.
        todo.clear();
        todo.extend([(first + 1, width - k), (first, k)]);
        while let Some((m, mut slots)) = todo.pop() {
            while slots > 1 && self.left[m][slots] == 0 {
                slots -= 1;
            }
            if slots == 1 || bvh2[m].prim_count > 0 {
                kids.push(m);
            } else {
                let f = bvh2[m].first_index as usize;
                let k = self.left[m][slots] as usize;
                todo.extend([(f + 1, slots - k), (f, k)]);
            }
        }
    }
}

/// Whether every inner node of `bvh2` has its children after it in the array.
fn children_after_parents(bvh2: &[Bvh2Node]) -> bool {
    bvh2.iter()
        .enumerate()
        .all(|(i, n)| n.prim_count > 0 || (n.first_index as usize > i && n.first_index as usize + 1 < bvh2.len()))
}

/// The nodes of `bvh2` reachable from the root, parents before children.
fn breadth_first(bvh2: &[Bvh2Node]) -> Vec<usize> {
    let mut order = vec![0usize];
    let mut i = 0;
    while i < order.len() {
        let n = &bvh2[order[i]];
        i += 1;
        if n.prim_count == 0 {
            order.extend([n.first_index as usize, n.first_index as usize + 1]);
        }
    }
    order
}

/// A BVH of `W` children per node whose leaves are ranges of a primitive array in the BVH2's
/// leaf order.
#[derive(Clone, Debug)]
pub struct WideBvh<const W: usize> {
    nodes: Vec<Node<W>>,
    /// The root's box (the union of its children's): nothing lies outside it.
    bounds: Aabb,
}

impl<const W: usize> Default for WideBvh<W> {
    fn default() -> Self {
        WideBvh { nodes: Vec::new(), bounds: Aabb::empty() }
    }
}

/// Four children per node: available everywhere.
pub type Bvh4 = WideBvh<4>;

/// Eight children per node: built only where the CPU has AVX.
pub type Bvh8 = WideBvh<8>;

impl Bvh4 {
    /// Collapses a BVH2 (root at 0, children of an inner node at `first_index` and the next).
    pub fn from_bvh2(bvh2: &[Bvh2Node]) -> Self {
        Self::collapse(bvh2)
    }
}

impl Bvh8 {
    /// Collapses a BVH2 as [`Bvh4::from_bvh2`] does, or `None` where the CPU lacks the
    /// eight-lane copies' instruction sets (x86-64-v3: AVX2, FMA, BMI1/2, LZCNT, POPCNT).
    pub fn from_bvh2(bvh2: &[Bvh2Node]) -> Option<Self> {
        #[cfg(target_arch = "x86_64")]
        if crate::simd::avx2() {
            return Some(Self::collapse(bvh2));
        }
        let _ = bvh2;
        None
    }
}

impl<const W: usize> WideBvh<W> {
    /// Collapses `bvh2` into nodes of up to `W` children. Every BVH2 leaf stays a leaf, so the
    /// surface area heuristic's cost of the wide tree varies only with the inner nodes kept:
    /// they are chosen by dynamic programming to make the sum of their surface areas least
    /// (Ylitie et al. 2017, §4.1), where filling each node with the children of largest area
    /// (what this did before) can keep more than it needs. Trace system at 64 spp against
    /// that: the dragon −6 % (fastest and median of nine), Sponza 0 to −9 %, the other peer
    /// scenes within noise; same images.
    fn collapse(bvh2: &[Bvh2Node]) -> Self {
        let Some(root) = bvh2.first() else { return WideBvh::default() };
        if root.prim_count > 0 {
            let mut node = Node::EMPTY;
            node.set(0, root.aabb());
            node.child[0] = root.first_index;
            node.count[0] = root.prim_count;
            return WideBvh { nodes: vec![node], bounds: *root.aabb() };
        }
        // One wide node per BVH2 inner node at most, so the pushes below never reallocate.
        let mut nodes = crate::huge_pages::vec_on_huge_pages(bvh2.len() / 2 + 1);
        nodes.push(Node::EMPTY);
        let plan = SlotPlan::new(bvh2, W);
        // (BVH2 node whose subtree fills the wide node, wide node)
        let mut todo = vec![(0usize, 0usize)];
        let (mut kids, mut scratch) = (Vec::with_capacity(W), Vec::with_capacity(W));
        while let Some((n, out)) = todo.pop() {
            plan.fill(bvh2, n, W, &mut kids, &mut scratch);
            for (slot, &k) in kids.iter().enumerate() {
                let node = &bvh2[k];
                nodes[out].set(slot, node.aabb());
                if node.prim_count > 0 {
                    nodes[out].child[slot] = node.first_index;
                    nodes[out].count[slot] = node.prim_count;
                } else {
                    nodes[out].child[slot] = nodes.len() as u32;
                    todo.push((k, nodes.len()));
                    nodes.push(Node::EMPTY);
                }
            }
        }
        WideBvh { nodes, bounds: *root.aabb() }
    }

    /// Replaces every leaf's (first, count) by `f(first, count)`, visiting leaves in node order.
    pub fn map_leaves(&mut self, mut f: impl FnMut(u32, u32) -> (u32, u32)) {
        for node in &mut self.nodes {
            for slot in 0..W {
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

    /// Bytes held by the nodes.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * size_of::<Node<W>>()
    }
}

impl<const W: usize> WideBvh<W>
where
    Node<W>: NodeTest<W>,
{
    /// Any-hit traversal: calls `leaf(first, count, stack)` for leaves the ray enters, in no
    /// particular order, until one returns true. Uses `stack` above its current length only.
    #[inline(always)]
    pub fn occluded(
        &self,
        ray: &Ray,
        stack: &mut Vec<(u32, f32)>,
        leaf: impl FnMut(u32, u32, &mut Vec<(u32, f32)>) -> bool,
    ) -> bool {
        self.occluded_from(0, ray, stack, leaf)
    }

    /// [`WideBvh::occluded`] of the subtree under node `start`.
    #[inline(always)]
    pub fn occluded_from(
        &self,
        start: u32,
        ray: &Ray,
        stack: &mut Vec<(u32, f32)>,
        leaf: impl FnMut(u32, u32, &mut Vec<(u32, f32)>) -> bool,
    ) -> bool {
        self.occluded_from_touch(start, ray, stack, leaf, |_, _| {})
    }

    /// [`WideBvh::occluded_from`], calling `touch(first, count)` for each leaf as soon as
    /// the ray is known to enter it, before visiting any of the node's children (to prefetch
    /// its primitives); the child nodes it enters are prefetched at the same point.
    #[inline(always)]
    pub fn occluded_from_touch(
        &self,
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
            let (mut mask, _) = n.test(&r, ray.tmax);
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
    pub fn closest(
        &self,
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
                let (mut mask, near) = n.test(&r, ray.tmax * far_scale());
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

/// A packet of rays in SIMD lanes ([`Lanes`]: eight with AVX, sixteen with AVX-512), for
/// [`WideBvh::occluded_packet`].
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(crate) struct RayPacket<L: Lanes> {
    origin: [L; 3],
    inv_dir: [L; 3],
    /// The lanes whose direction is negative on each axis: they take a box's maximum as their
    /// near plane.
    negative: [L::Mask; 3],
    tmax: L,
}

#[cfg(target_arch = "x86_64")]
impl<L: Lanes> RayPacket<L> {
    /// The node-test constants of a packet's rays.
    ///
    /// # Safety
    /// The CPU must have `L`'s instruction set.
    #[inline(always)]
    pub(crate) unsafe fn new(rays: &RayLanes<L>) -> Self {
        // SAFETY: the caller's CPU has `L`'s instruction set.
        unsafe {
            let zero = L::splat(0.0);
            let inv = rays.inv_dir;
            RayPacket {
                origin: rays.origin,
                inv_dir: inv,
                negative: [inv[0].lt(zero), inv[1].lt(zero), inv[2].lt(zero)],
                tmax: rays.tmax,
            }
        }
    }
}

/// The node test of a packet traversal: which of the packet's lanes enter each of a node's
/// eight children (bit i for lane i).
#[cfg(target_arch = "x86_64")]
pub(crate) trait PacketNodeTest {
    /// Writes to `entered` the lanes that enter each child of `n`. (An out-parameter: a
    /// returned array was copied to the caller's with one wide load of the eight narrow stores
    /// just made, which the CPU cannot forward from its store buffer and so waits for.)
    ///
    /// # Safety
    /// The CPU must have the packet's lane instruction set.
    unsafe fn enter(&self, n: &Node<8>, entered: &mut [u32; 8]);
}

#[cfg(target_arch = "x86_64")]
impl<L: Lanes> PacketNodeTest for RayPacket<L> {
    #[inline(always)]
    unsafe fn enter(&self, n: &Node<8>, entered: &mut [u32; 8]) {
        // Every child's test first, with no branch between them: each is a chain of dependent
        // operations ending in a lane mask, and eight independent chains overlap where a branch
        // on each mask would stall on it (an empty slot is an inverted box, which no ray enters).
        // (Loops, not closures: a closure is compiled without the caller's instruction set.)
        for (c, e) in entered.iter_mut().enumerate() {
            // SAFETY: the caller's CPU has `L`'s instruction set.
            *e = unsafe { n.test_packet(c, self, self.tmax) };
        }
    }
}

/// An occlusion packet's node test by fused multiply-adds: a plane's distance
/// `(p − o)·inv` is `fma(p, inv, −o·inv)`, one operation where [`RayPacket`] takes a
/// subtraction and a multiplication. Its constant `−o·inv`, worked out once per packet, is
/// moved by `4u·|o·inv|` (u = 2⁻²⁴) down for near planes and up for far ones, more than its two
/// roundings can move it, so the computed near plane is never past the exact one nor the far
/// plane before it, up to one rounding relative to the distance, which the exit's widening by
/// `1 + 2γ₃` covers. So every box a ray truly enters is entered, and occlusion answers, which
/// come from the leaves, are unchanged; but the boxes grow by about `4u·|o|` in world units
/// (2.4e-4 at 1,000 from the world's origin), so a packet may visit leaves its rays' own tests
/// would skip, more of them the farther from the origin the scene lies. A direction component
/// of exactly 0 makes that axis's distances NaN, which the tests ignore (the box is not culled
/// on that axis). Where the live rays share an octant, each plane is read straight from the
/// node, without a blend. This moves work from the floating-point adders, which the node test
/// keeps busiest (its maxima, minima and compares run there), to the multipliers.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(crate) struct FusedPacket<L: Lanes> {
    inv_dir: [L; 3],
    /// `−o·inv`, moved down (for near planes) and up (for far planes).
    near_offset: [L; 3],
    far_offset: [L; 3],
    negative: [L::Mask; 3],
    /// The rows of every live ray's near and far planes, where they all share an octant.
    octant: Option<([usize; 3], [usize; 3])>,
    tmax: L,
}

#[cfg(target_arch = "x86_64")]
impl<L: FusedLanes> FusedPacket<L> {
    /// The node-test constants of the packet `rays`, whose live lanes are `live`.
    ///
    /// # Safety
    /// The CPU must have `L`'s instruction set.
    #[inline(always)]
    pub(crate) unsafe fn new(rays: &RayLanes<L>, live: u32) -> Self {
        // SAFETY: the caller's CPU has `L`'s instruction set.
        unsafe {
            let zero = L::splat(0.0);
            // 4u = 2⁻²²: scaling by a power of two is exact (short of underflow, where the
            // offsets' roundings are exact too).
            let margin = L::splat(f32::EPSILON * 2.0);
            let mut near_offset = [zero; 3];
            let mut far_offset = [zero; 3];
            let mut negative = [L::mask(0); 3];
            let mut bits = [0u32; 3];
            for a in 0..3 {
                let od = rays.origin[a].mul(rays.inv_dir[a]);
                let moved = od.abs().mul(margin);
                near_offset[a] = od.neg().sub(moved);
                far_offset[a] = od.neg().add(moved);
                negative[a] = rays.inv_dir[a].lt(zero);
                bits[a] = L::bits(negative[a]) & live;
            }
            let octant = bits
                .iter()
                .all(|&b| b == 0 || b == live)
                .then(|| plane_rows((0..3).fold(0, |m, a| m | ((bits[a] != 0) as u32) << a)));
            FusedPacket { inv_dir: rays.inv_dir, near_offset, far_offset, negative, octant, tmax: rays.tmax }
        }
    }

    /// The lanes that enter a child whose (near, far) planes on each axis are `planes`, in each
    /// lane's own choice of rows.
    ///
    /// # Safety
    /// The CPU must have `L`'s instruction set.
    #[inline(always)]
    unsafe fn lanes_entering(&self, planes: [(L, L); 3]) -> u32 {
        // SAFETY: the caller's CPU has `L`'s instruction set.
        unsafe {
            let mut near = L::splat(NEAR_START);
            let mut far = L::splat(f32::INFINITY);
            for (a, (near_plane, far_plane)) in planes.into_iter().enumerate() {
                // maxps / minps return their second operand when either is NaN.
                near = near_plane.mul_add(self.inv_dir[a], self.near_offset[a]).max_keep(near);
                far = far_plane.mul_add(self.inv_dir[a], self.far_offset[a]).min_keep(far);
            }
            let far = far.mul(L::splat(far_scale())).min_keep(self.tmax);
            L::bits(near.le(far))
        }
    }
}

#[cfg(target_arch = "x86_64")]
impl<L: FusedLanes> PacketNodeTest for FusedPacket<L> {
    #[inline(always)]
    unsafe fn enter(&self, n: &Node<8>, entered: &mut [u32; 8]) {
        // (Loops, not closures: a closure is compiled without the caller's instruction set.)
        // SAFETY (all blocks): the caller's CPU has `L`'s instruction set.
        let mut planes = unsafe { [(L::splat(0.0), L::splat(0.0)); 3] };
        if let Some((near_row, far_row)) = self.octant {
            for (c, e) in entered.iter_mut().enumerate() {
                for (a, plane) in planes.iter_mut().enumerate() {
                    *plane = unsafe { (L::splat(n.planes[near_row[a]][c]), L::splat(n.planes[far_row[a]][c])) };
                }
                *e = unsafe { self.lanes_entering(planes) };
            }
        } else {
            for (c, e) in entered.iter_mut().enumerate() {
                for (a, plane) in planes.iter_mut().enumerate() {
                    *plane = unsafe { n.lane_planes::<L>(c, a, self.negative[a]) };
                }
                *e = unsafe { self.lanes_entering(planes) };
            }
        }
    }
}

/// Entries of the packet traversal's stack, which lives on the call stack; a subtree that
/// would overflow it is traversed ray by ray instead. The unit tests use four, so that the
/// overflow path is taken all the time there and checked like the others.
#[cfg(target_arch = "x86_64")]
const PACKET_STACK: usize = if cfg!(test) { 4 } else { 128 };

/// Fewest live rays for which a node is tested with the packet; fewer go on ray by ray. A
/// packet test costs about as much per child as a single ray's test of all eight children, so
/// the break-even is a few rays; 3 to 7 measured the same within noise (±5 %).
#[cfg(target_arch = "x86_64")]
pub(crate) const PACKET_MIN_LANES: u32 = 4;

#[cfg(target_arch = "x86_64")]
impl Node<8> {
    /// Child `c`'s near and far planes on axis `a` in each lane: its maximum and minimum in the
    /// lanes of `negative` (directions negative on the axis), its minimum and maximum elsewhere.
    ///
    /// # Safety
    /// The CPU must have `L`'s instruction set.
    #[inline(always)]
    unsafe fn lane_planes<L: Lanes>(&self, c: usize, a: usize, negative: L::Mask) -> (L, L) {
        // SAFETY: the caller's CPU has `L`'s instruction set.
        unsafe {
            let (lo, hi) = (L::splat(self.planes[a][c]), L::splat(self.planes[a + 3][c]));
            (lo.select(negative, hi), hi.select(negative, lo))
        }
    }

    /// The lanes of `p` that enter child `c`: the eight-child test's operations per ray, each
    /// ray's near and far planes picked by its own direction's signs, so every lane decides
    /// exactly as [`NodeTest::test`] does for that ray.
    ///
    /// # Safety
    /// The CPU must have `L`'s instruction set.
    #[inline(always)]
    unsafe fn test_packet<L: Lanes>(&self, c: usize, p: &RayPacket<L>, tmax: L) -> u32 {
        // SAFETY: the caller's CPU has `L`'s instruction set.
        unsafe {
            let mut near = L::splat(NEAR_START);
            let mut far = L::splat(f32::INFINITY);
            for a in 0..3 {
                let (near_plane, far_plane) = self.lane_planes::<L>(c, a, p.negative[a]);
                // maxps / minps return their second operand when either is NaN.
                near = near_plane.sub(p.origin[a]).mul(p.inv_dir[a]).max_keep(near);
                far = far_plane.sub(p.origin[a]).mul(p.inv_dir[a]).min_keep(far);
            }
            let far = far.mul(L::splat(far_scale())).min_keep(tmax);
            L::bits(near.le(far))
        }
    }
}

#[cfg(target_arch = "x86_64")]
impl WideBvh<8> {
    /// Any-hit traversal of a packet of rays together (Wald et al. 2001; Embree's hybrid
    /// traversal): each node is tested against all the packet's live rays at once (by `p`),
    /// and rays go on one at a time from a node fewer than [`PACKET_MIN_LANES`] of them enter.
    ///
    /// `live` holds the lanes to answer, traced from node `start` (the root, or a node under
    /// which lie all the leaves they can reach: [`WideBvh::entry_node_of`]).
    /// `leaf(first, count, lanes, stack)` tests a leaf against `lanes` and returns those it
    /// blocks; `single(node, lane, stack)` answers one ray from node `node`. Both may use
    /// `stack` above its length. Returns the blocked lanes.
    ///
    /// # Safety
    /// The CPU must have the packet's instruction set (and AVX, for this eight-wide tree).
    #[inline(always)]
    pub(crate) unsafe fn occluded_packet(
        &self,
        p: &impl PacketNodeTest,
        start: u32,
        live: u32,
        stack: &mut Vec<(u32, f32)>,
        mut leaf: impl FnMut(u32, u32, u32, &mut Vec<(u32, f32)>) -> u32,
        mut single: impl FnMut(u32, usize, &mut Vec<(u32, f32)>) -> bool,
    ) -> u32 {
        if self.nodes.is_empty() || live == 0 {
            return 0;
        }
        let mut open = live;
        // (node, lanes that entered it). Left uninitialised: zeroing it cost a 1 KiB memset per
        // packet, and only entries below `len` are ever read.
        let mut todo = [std::mem::MaybeUninit::<(u32, u32)>::uninit(); PACKET_STACK];
        let mut tested = [0u32; 8];
        let mut len = 1;
        todo[0].write((start, live));
        // The lanes of `lanes` that `single` finds blocked, each ray going on alone from `node`.
        let mut alone = |node: u32, mut lanes: u32, stack: &mut Vec<(u32, f32)>| {
            let mut blocked = 0;
            while lanes != 0 {
                let lane = lanes.trailing_zeros() as usize;
                lanes &= lanes - 1;
                count(Event::LoneRay);
                if single(node, lane, stack) {
                    blocked |= 1 << lane;
                }
            }
            blocked
        };
        while len > 0 {
            len -= 1;
            // SAFETY: every entry below `len` was written before `len` passed it.
            let (node, lanes) = unsafe { todo[len].assume_init() };
            let lanes = lanes & open;
            if lanes.count_ones() < PACKET_MIN_LANES {
                open &= !alone(node, lanes, stack);
                if open == 0 {
                    break;
                }
                continue;
            }
            count(Event::PacketNodeTest);
            let n = &self.nodes[node as usize];
            // SAFETY: the caller's CPU has the packet's instruction set.
            unsafe { p.enter(n, &mut tested) };
            for (c, &t) in tested.iter().enumerate() {
                // Only rays that entered this node, and are not yet blocked, go on to its children.
                let entered = t & lanes & open;
                if entered == 0 {
                    continue;
                }
                if n.count[c] > 0 {
                    open &= !leaf(n.child[c], n.count[c], entered, stack);
                    if open == 0 {
                        return live;
                    }
                } else if len < PACKET_STACK {
                    // Popped only after this node's other children: time for the load.
                    prefetch(&self.nodes[n.child[c] as usize]);
                    todo[len].write((n.child[c], entered));
                    len += 1;
                } else {
                    open &= !alone(n.child[c], entered, stack);
                }
            }
        }
        live & !open
    }

    /// The node an any-hit packet traversal of the lanes `live` of `rays` may start from: the
    /// deepest node under which lie all leaves whose boxes overlap their segments' box (cut
    /// where they leave the tree's bounds: [`RayLanes::segments_box`]), found by going down
    /// while exactly one child of a node overlaps it and that child is not a leaf (the root
    /// where there is no such box). `None` where that box overlaps no leaf, so nothing can
    /// block the rays. No leaf a ray's segment can meet lies outside that subtree, so every
    /// ray gets the answer it gets from the root; each packet saves the node tests of the way
    /// down, which all its rays would take.
    ///
    /// # Safety
    /// The CPU must have `L`'s instruction set and AVX2.
    #[inline(always)]
    pub(crate) unsafe fn entry_node_of<L: Lanes>(&self, rays: &RayLanes<L>, live: u32) -> Option<u32> {
        // SAFETY: the caller's CPU has `L`'s instruction set and AVX2.
        match unsafe { rays.segments_box(live, &self.bounds) } {
            Some((lo, hi)) => unsafe { self.entry_node(lo, hi) },
            None => (!self.nodes.is_empty()).then_some(0),
        }
    }

    /// The deepest node under which lie all leaves whose boxes overlap `lo..hi` (going down
    /// while exactly one child overlaps it and is not a leaf), or `None` where no child of a
    /// node on that way does.
    ///
    /// # Safety
    /// The CPU must have AVX2.
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    pub(crate) unsafe fn entry_node(&self, lo: glam::Vec3A, hi: glam::Vec3A) -> Option<u32> {
        use std::arch::x86_64::*;
        if self.nodes.is_empty() {
            return None;
        }
        let mut node = 0u32;
        loop {
            let n = &self.nodes[node as usize];
            // SAFETY: each row of `planes` is eight contiguous f32.
            let load = |row: usize| unsafe { _mm256_loadu_ps(n.planes[row].as_ptr()) };
            // An empty slot's inverted box overlaps nothing.
            let mut overlaps = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
            for a in 0..3 {
                let below = _mm256_cmp_ps::<_CMP_LE_OQ>(load(a), _mm256_set1_ps(hi[a]));
                let above = _mm256_cmp_ps::<_CMP_GE_OQ>(load(a + 3), _mm256_set1_ps(lo[a]));
                overlaps = _mm256_and_ps(overlaps, _mm256_and_ps(below, above));
            }
            let overlap = _mm256_movemask_ps(overlaps) as u32;
            if overlap == 0 {
                return None;
            }
            let c = overlap.trailing_zeros() as usize;
            if overlap & (overlap - 1) != 0 || n.count[c] > 0 {
                return Some(node);
            }
            node = n.child[c];
        }
    }

    /// Closest-hit traversal of a packet of rays together: each node is tested against all the
    /// packet's live rays at once, each against its own closest distance so far
    /// (`hits.tmax[lane]`), and the children are visited nearest first for the packet's first
    /// live ray. `leaf(first, count, lanes, hits)` tests a leaf against `lanes` and offers
    /// `hits` what it finds. Returns the lanes whose subtree overflowed the packet's stack,
    /// which the caller must trace alone.
    ///
    /// Every ray reaches every leaf its own [`WideBvh::closest`] could find its hit in (a leaf
    /// whose box it enters before its current `tmax`), so `tmax` ends at each ray's closest hit;
    /// which of several hits at exactly that distance is found first may differ.
    ///
    /// # Safety
    /// The CPU must have `L`'s instruction set (and AVX, for this eight-wide tree).
    #[inline(always)]
    pub(crate) unsafe fn closest_packet<L: Lanes, T>(
        &self,
        p: &RayPacket<L>,
        first_ray: &Ray,
        live: u32,
        hits: &mut LaneHits<T>,
        mut leaf: impl FnMut(u32, u32, u32, &mut LaneHits<T>),
    ) -> u32 {
        if self.nodes.is_empty() || live == 0 {
            return 0;
        }
        let order = RayBox::new(first_ray);
        let mut overflow = 0;
        let mut todo = [std::mem::MaybeUninit::<(u32, u32)>::uninit(); PACKET_STACK];
        let mut len = 1;
        todo[0].write((0, live));
        // SAFETY (all blocks below): the caller's CPU has `L`'s instruction set.
        let widened = |tmax: &[f32; 16]| unsafe { L::load(&tmax[..]).mul(L::splat(far_scale())) };
        let mut tmax_lanes = widened(&hits.tmax);
        while len > 0 {
            len -= 1;
            // SAFETY: every entry below `len` was written before `len` passed it.
            let (node, lanes) = unsafe { todo[len].assume_init() };
            count(Event::PacketNodeTest);
            let n = &self.nodes[node as usize];
            let mut tested = [0u32; 8];
            for (c, t) in tested.iter_mut().enumerate() {
                *t = unsafe { n.test_packet(c, p, tmax_lanes) } & lanes;
            }
            // Leaves now; inner children pushed farthest first (for the first ray), so that the
            // nearest is popped next.
            let (_, entry) = n.test(&order, f32::INFINITY);
            let mut inner = [(0usize, 0f32); 8];
            let mut k = 0;
            for (c, &entered) in tested.iter().enumerate() {
                if entered == 0 {
                    continue;
                }
                if n.count[c] > 0 {
                    leaf(n.child[c], n.count[c], entered, hits);
                    tmax_lanes = widened(&hits.tmax);
                } else {
                    let mut j = k;
                    while j > 0 && inner[j - 1].1 < entry[c] {
                        inner[j] = inner[j - 1];
                        j -= 1;
                    }
                    inner[j] = (c, entry[c]);
                    k += 1;
                }
            }
            for &(c, _) in &inner[..k] {
                if len < PACKET_STACK {
                    todo[len].write((n.child[c], tested[c]));
                    len += 1;
                } else {
                    overflow |= tested[c];
                }
            }
        }
        overflow
    }
}

/// A packet's closest hits so far, lane by lane, for [`WideBvh::closest_packet`].
#[cfg(target_arch = "x86_64")]
pub(crate) struct LaneHits<T> {
    /// Each lane's closest distance so far (its ray's `tmax` at first).
    pub tmax: [f32; 16],
    /// Each lane's closest hit so far.
    pub best: [Option<T>; 16],
    /// Lanes offered a second hit at exactly their closest distance so far: which one a
    /// single-ray traversal keeps depends on its order, so the caller traces them alone.
    pub tied: u32,
}

#[cfg(target_arch = "x86_64")]
impl<T: Copy> LaneHits<T> {
    /// No hits yet for `rays` (up to sixteen), each lane's closest distance its ray's `tmax`.
    pub fn new(rays: &[Ray]) -> Self {
        let mut tmax = [0.0; 16];
        for (t, ray) in tmax.iter_mut().zip(rays) {
            *t = ray.tmax;
        }
        LaneHits { tmax, best: [None; 16], tied: 0 }
    }

    /// Lane `k`'s ray from `rays`, reaching one step past its closest distance so far, so that
    /// a hit at exactly that distance is seen too (and offered as a tie).
    #[inline(always)]
    pub fn probe(&self, rays: &[Ray], k: usize) -> Ray {
        rays[k].with_tmax(self.tmax[k].next_up())
    }

    /// Offers lane `k` a hit at `t` found by its [`LaneHits::probe`]: kept if closer than its
    /// closest so far (clearing a tie there), else (exactly as close) a tie.
    #[inline(always)]
    pub fn offer(&mut self, k: usize, t: f32, hit: T) {
        if t < self.tmax[k] {
            self.tmax[k] = t;
            self.best[k] = Some(hit);
            self.tied &= !(1 << k);
        } else {
            self.tied |= 1 << k;
        }
    }
}

#[cfg(test)]
mod tests {
    use std::{
        cell::{Cell, RefCell},
        collections::BTreeSet,
        time::Duration,
    };

    use glam::{Vec3, Vec3A};
    use obvhs::{BvhBuildParams, bvh2::builder::build_bvh2};

    use super::*;
    use crate::random::SplitMix64;

    /// Leaves as (first, count).
    type Leaves = BTreeSet<(u32, u32)>;

    /// The leaves whose own box the ray enters in [0, tmax], by the scalar slab test (with the
    /// same exit widening and NaN rule as the node tests).
    fn brute_force(bvh2: &[Bvh2Node], ray: &Ray) -> Leaves {
        let (o, inv) = (ray.origin.to_array(), ray.inv_dir.to_array());
        let mut leaves = Leaves::new();
        for node in bvh2.iter().filter(|n| n.prim_count > 0) {
            let (mut near, mut far) = (NEAR_START, f32::INFINITY);
            for a in 0..3 {
                let (t0, t1) = ((node.aabb().min[a] - o[a]) * inv[a], (node.aabb().max[a] - o[a]) * inv[a]);
                let (tn, tf) = if inv[a] < 0.0 { (t1, t0) } else { (t0, t1) };
                near = if tn > near { tn } else { near };
                far = if tf < far { tf } else { far };
            }
            if near <= (far * far_scale()).min(ray.tmax) {
                leaves.insert((node.first_index, node.prim_count));
            }
        }
        leaves
    }

    /// The leaves `tree` visits with a callback that never reports a hit, by both traversals.
    fn visited<const W: usize>(tree: &WideBvh<W>, ray: &Ray) -> (Leaves, Leaves)
    where
        Node<W>: NodeTest<W>,
    {
        let mut stack = Vec::new();
        let mut any = Leaves::new();
        tree.occluded(ray, &mut stack, |first, count, _| {
            assert!(any.insert((first, count)), "leaf ({first}, {count}) visited twice");
            false
        });
        let mut nearest = Leaves::new();
        tree.closest(&mut ray.clone(), &mut stack, |first, count, _, _| {
            assert!(nearest.insert((first, count)), "leaf ({first}, {count}) visited twice");
        });
        assert!(stack.is_empty());
        (any, nearest)
    }

    #[test]
    fn a_ray_leaving_a_flat_box_it_starts_on_enters_no_leaf() {
        // A floor of flat boxes at y = 0 and one box above it.
        let mut boxes: Vec<Aabb> = (0..16)
            .map(|i| Aabb::new(Vec3::new(i as f32, 0.0, 0.0).into(), Vec3::new(i as f32 + 1.0, 0.0, 1.0).into()))
            .collect();
        boxes.push(Aabb::new(Vec3::new(3.0, 2.0, 0.0).into(), Vec3::new(4.0, 3.0, 1.0).into()));
        let bvh2 = build_bvh2(&boxes, BvhBuildParams::medium_build(), &mut Duration::default()).nodes;
        let up = Ray::new(Vec3A::new(3.5, 0.0, 0.5), Vec3A::new(0.0, 1.0, 0.2).normalize(), f32::INFINITY);
        let down = Ray::new(Vec3A::new(3.5, 1.0, 0.5), Vec3A::new(0.0, -1.0, 0.2).normalize(), f32::INFINITY);
        let four = Bvh4::from_bvh2(&bvh2);
        let (up4, down4) = (visited(&four, &up).0, visited(&four, &down).0);
        assert_eq!(up4.len(), 1, "only the box above, not the floor under the origin: {up4:?}");
        assert_eq!(down4.len(), 1, "the floor box the ray comes down on: {down4:?}");
        assert_ne!(up4, down4);
        if let Some(eight) = Bvh8::from_bvh2(&bvh2) {
            assert_eq!((visited(&eight, &up).0, visited(&eight, &down).0), (up4, down4));
        }
    }

    /// Eight rays from one point, traversed as a packet: every ray must visit exactly the
    /// leaves it enters (by brute force), whether it went through a leaf with the packet, on
    /// its own from a node few rays entered, or both.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn a_packet_visits_exactly_the_leaves_each_ray_enters() {
        use crate::geometry::lanes::{Avx, Avx512};
        for (offset, size) in [(0.0, 1.0), (3.0e4, 1.0e-2)] {
            let (bvh2, tree) = packet_test_scene(offset, size);
            let Some(tree) = tree else {
                eprintln!("no AVX on this CPU: packets are not used and not tested");
                return;
            };
            // SAFETY: the eight-wide tree exists, so the CPU has AVX; AVX-512 is checked.
            unsafe {
                packets_visit_the_leaves_rays_enter::<Avx, _>(
                    &bvh2,
                    &tree,
                    offset,
                    size,
                    |r, _| RayPacket::new(r),
                    true,
                );
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                unsafe {
                    let general = |r: &RayLanes<Avx512>, _| RayPacket::new(r);
                    packets_visit_the_leaves_rays_enter::<Avx512, _>(&bvh2, &tree, offset, size, general, true);
                }
            } else {
                eprintln!("no AVX-512 on this CPU: sixteen-lane packets are not used and not tested");
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn a_fused_packet_visits_every_leaf_each_ray_truly_enters() {
        use crate::geometry::lanes::{Avx, Avx512};
        for (offset, size) in [(0.0, 1.0), (3.0e4, 1.0e-2)] {
            let (bvh2, tree) = packet_test_scene(offset, size);
            let Some(tree) = tree else {
                eprintln!("no AVX2 on this CPU: packets are not used and not tested");
                return;
            };
            // SAFETY: the eight-wide tree exists, so the CPU has AVX2 and FMA.
            unsafe {
                let fused = |r: &RayLanes<Avx>, live| FusedPacket::new(r, live);
                packets_visit_the_leaves_rays_enter::<Avx, _>(&bvh2, &tree, offset, size, fused, false);
            }
            if !std::arch::is_x86_feature_detected!("avx512f") {
                eprintln!("no AVX-512 on this CPU: sixteen-lane fused packets are not used and not tested");
                continue;
            }
            // SAFETY: the CPU has AVX-512F (checked above) and AVX2.
            unsafe {
                let fused = |r: &RayLanes<Avx512>, live| FusedPacket::new(r, live);
                packets_visit_the_leaves_rays_enter::<Avx512, _>(&bvh2, &tree, offset, size, fused, false);
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    /// 3,000 random boxes of up to 1.5·`size` in a cube of 20·`size` around (`offset`, 0, 0),
    /// plus eight flat ones on y = 0, as a BVH2 and its eight-wide tree (`None` without AVX).
    fn packet_test_scene(offset: f32, size: f32) -> (Vec<Bvh2Node>, Option<Bvh8>) {
        let mut rng = SplitMix64::new(17);
        let base = Vec3::new(offset, 0.0, 0.0);
        let mut point = |scale: f32| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * scale * size;
        let mut boxes: Vec<Aabb> = (0..3_000)
            .map(|_| {
                let min = base + point(20.0) - 10.0 * size;
                Aabb::new(min.into(), (min + point(1.5)).into())
            })
            .collect();
        // Flat boxes some packets start on.
        boxes.extend((0..8).map(|i| {
            let x = offset + i as f32 * size;
            Aabb::new(Vec3A::new(x, 0.0, 0.0), Vec3A::new(x + size, 0.0, size))
        }));
        let bvh2 = build_bvh2(&boxes, BvhBuildParams::medium_build(), &mut Duration::default()).nodes;
        let tree = Bvh8::from_bvh2(&bvh2);
        (bvh2, tree)
    }

    #[cfg(target_arch = "x86_64")]
    /// The leaves whose box the ray truly enters, in f64 from its origin and direction (not its
    /// rounded reciprocal), with strict comparisons: boxes the ray only touches are left out.
    fn truly_entered(bvh2: &[Bvh2Node], ray: &Ray) -> Leaves {
        let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
        let mut leaves = Leaves::new();
        'nodes: for node in bvh2.iter().filter(|n| n.prim_count > 0) {
            let (lo, hi) = (node.aabb().min.as_dvec3(), node.aabb().max.as_dvec3());
            let (mut near, mut far) = (0.0f64, f64::from(ray.tmax));
            for a in 0..3 {
                if d[a] == 0.0 {
                    if o[a] <= lo[a] || o[a] >= hi[a] {
                        continue 'nodes;
                    }
                    continue;
                }
                let (t0, t1) = ((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]);
                near = near.max(t0.min(t1));
                far = far.min(t0.max(t1));
            }
            if near < far {
                leaves.insert((node.first_index, node.prim_count));
            }
        }
        leaves
    }

    /// [`a_packet_visits_exactly_the_leaves_each_ray_enters`] for packets of `L::WIDTH` rays
    /// tested by `test(rays, live)`: with `exact`, each lane visits exactly the leaves of its
    /// own ray's node test ([`brute_force`]); else every leaf it truly enters
    /// ([`truly_entered`]) and only leaves whose box, grown by a thousandth of `size`, its own
    /// node test enters.
    ///
    /// # Safety
    /// The CPU must have `L`'s instruction set and AVX.
    #[cfg(target_arch = "x86_64")]
    unsafe fn packets_visit_the_leaves_rays_enter<L: crate::geometry::lanes::Lanes, P: PacketNodeTest>(
        bvh2: &[Bvh2Node],
        tree: &Bvh8,
        offset: f32,
        size: f32,
        test: impl Fn(&RayLanes<L>, u32) -> P,
        exact: bool,
    ) {
        let mut rng = SplitMix64::new(18);
        let (packet_leaves, single_leaves) = (Cell::new(0), Cell::new(0));
        let all = (1u32 << L::WIDTH) - 1;
        let grown: Vec<Bvh2Node> = bvh2
            .iter()
            .map(|n| {
                // The fused test's boxes grow by about 4u·|o| (twice that, to be safe).
                let grow = 1e-3 * size + 8.0 * f32::EPSILON * offset.abs();
                let (min, max) = (n.aabb().min - grow, n.aabb().max + grow);
                Bvh2Node::new(Aabb::new(min, max), n.prim_count, n.first_index)
            })
            .collect();
        let base = Vec3A::new(offset, 0.0, 0.0);
        for p in 0..300 {
            let origin = if p % 5 == 0 {
                base + Vec3A::new(rng.next_f32() * 8.0, 0.0, rng.next_f32()) * size
            } else {
                base + (Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 24.0 - 12.0) * size
            };
            let rays: Vec<Ray> = (0..L::WIDTH)
                .map(|i| {
                    let mut dir = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
                    if i % 3 == 0 {
                        dir[(i + p) % 3] = 0.0;
                    }
                    let tmax = if i % 2 == 0 { f32::INFINITY } else { rng.next_f32() * 20.0 * size };
                    Ray::new(origin, dir.normalize_or(Vec3A::Y), tmax)
                })
                .collect();
            let live = if p % 7 == 0 { 0b1011_0110_1101_0110 & all } else { all };
            let seen = RefCell::new(vec![Leaves::new(); L::WIDTH]);
            let visit = |lane: usize, leaf: (u32, u32), count: &Cell<usize>| {
                assert!(seen.borrow_mut()[lane].insert(leaf), "lane {lane} visits leaf {leaf:?} twice");
                count.set(count.get() + 1);
            };
            let mut stack = Vec::new();
            // SAFETY: the caller's CPU has `L`'s instruction set and AVX.
            let blocked = unsafe {
                tree.occluded_packet(
                    &test(&L::rays(&rays), live),
                    0,
                    live,
                    &mut stack,
                    |first, count, lanes, _| {
                        for lane in (0..L::WIDTH).filter(|k| lanes & (1 << k) != 0) {
                            visit(lane, (first, count), &packet_leaves);
                        }
                        0
                    },
                    |node, lane, stack| {
                        tree.occluded_from(node, &rays[lane], stack, |first, count, _| {
                            visit(lane, (first, count), &single_leaves);
                            false
                        })
                    },
                )
            };
            assert_eq!(blocked, 0);
            for (lane, ray) in rays.iter().enumerate() {
                let seen = &seen.borrow()[lane];
                let at = format!("{} lanes, offset {offset}, packet {p}, lane {lane}", L::WIDTH);
                if live & (1 << lane) == 0 {
                    assert!(seen.is_empty(), "{at}");
                } else if exact {
                    assert_eq!(*seen, brute_force(bvh2, ray), "{at}");
                } else {
                    let truly = truly_entered(bvh2, ray);
                    assert!(seen.is_superset(&truly), "{at}: misses {:?}", truly.difference(seen).collect::<Vec<_>>());
                    // (A direction component of 0 leaves its axis unculled: any leaf may come.)
                    if ray.dir.cmpne(Vec3A::ZERO).all() {
                        let near = brute_force(&grown, ray);
                        assert!(seen.is_subset(&near), "{at}: visits {:?}", seen.difference(&near).collect::<Vec<_>>());
                    }
                }
            }
        }
        let (packet_leaves, single_leaves) = (packet_leaves.get(), single_leaves.get());
        assert!(packet_leaves > 1_000 && single_leaves > 1_000, "{packet_leaves} by packet, {single_leaves} alone");
    }

    /// The leaves of the subtree under node `node` of a wide tree.
    #[cfg(target_arch = "x86_64")]
    fn leaves_under(tree: &Bvh8, node: u32) -> Leaves {
        let n = &tree.nodes[node as usize];
        let mut leaves = Leaves::new();
        for c in 0..8 {
            if n.count[c] > 0 {
                leaves.insert((n.child[c], n.count[c]));
            } else if n.planes[0][c] <= n.planes[3][c] {
                leaves.extend(leaves_under(tree, n.child[c]));
            }
        }
        leaves
    }

    /// Random boxes, from points up to a third of the scene across, near the origin and 3·10⁴
    /// from it: every leaf whose box overlaps one lies under its entry node, and a box with
    /// no entry node overlaps no leaf.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_entry_node_holds_every_leaf_a_box_overlaps() {
        for (offset, size) in [(0.0, 1.0), (3.0e4, 1.0e-2)] {
            let (bvh2, tree) = packet_test_scene(offset, size);
            let Some(tree) = tree else {
                eprintln!("no AVX2 on this CPU: packets are not used and not tested");
                return;
            };
            let mut rng = SplitMix64::new(19);
            let (mut deeper, mut empty) = (0, 0);
            for q in 0..2_000 {
                // Boxes from a point to a thousandth of the scene across, up to a third of it.
                let extent = size * 20.0 * [0.0, 0.001, 0.05, 0.3][q % 4];
                let corner = Vec3A::new(offset, 0.0, 0.0)
                    + (Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 26.0 - 13.0) * size;
                let (lo, hi) = (corner, corner + Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * extent);
                let overlapping: Leaves = bvh2
                    .iter()
                    .filter(|n| n.prim_count > 0)
                    .filter(|n| n.aabb().min.cmple(hi).all() && n.aabb().max.cmpge(lo).all())
                    .map(|n| (n.first_index, n.prim_count))
                    .collect();
                // SAFETY: the eight-wide tree exists, so the CPU has AVX2.
                match unsafe { tree.entry_node(lo, hi) } {
                    None => {
                        assert!(overlapping.is_empty(), "box {q}: no entry, yet it overlaps {overlapping:?}");
                        empty += 1;
                    }
                    Some(node) => {
                        let under = leaves_under(&tree, node);
                        let missed: Vec<_> = overlapping.difference(&under).collect();
                        assert!(missed.is_empty(), "box {q}: node {node} leaves out {missed:?}");
                        deeper += (node != 0) as usize;
                    }
                }
            }
            // The test has teeth: many boxes start below the root, and some overlap nothing.
            assert!(deeper > 300 && empty > 50, "offset {offset}: {deeper} below the root, {empty} empty");
        }
    }

    /// Sum of the surface areas of a wide tree's nodes (each the union of its children's boxes).
    fn node_area<const W: usize>(tree: &WideBvh<W>) -> f32 {
        tree.nodes
            .iter()
            .map(|n| {
                let used = (0..W).take_while(|&c| c == 0 || n.count[c] > 0 || n.child[c] > 0);
                let boxes = used.map(|c| {
                    Aabb::new(
                        Vec3A::new(n.planes[0][c], n.planes[1][c], n.planes[2][c]),
                        Vec3A::new(n.planes[3][c], n.planes[4][c], n.planes[5][c]),
                    )
                });
                boxes.fold(Aabb::empty(), |a, b| a.union(&b)).half_area()
            })
            .sum()
    }

    /// The least node area of any collapse of `bvh2` into nodes of at most `width` children,
    /// by trying every choice of which inner nodes (besides the root) stay nodes.
    fn least_node_area(bvh2: &[Bvh2Node], width: usize) -> f32 {
        let inner: Vec<usize> = (1..bvh2.len()).filter(|&n| bvh2[n].prim_count == 0).collect();
        let mut best = f32::INFINITY;
        for kept in 0u32..1 << inner.len() {
            let stays = |n: usize| n == 0 || inner.iter().position(|&m| m == n).is_some_and(|i| kept >> i & 1 == 1);
            // Children of a kept node: its descendants down to the first leaf or kept node.
            let children = |n: usize| {
                let (mut count, mut todo) = (0, vec![bvh2[n].first_index as usize, bvh2[n].first_index as usize + 1]);
                while let Some(m) = todo.pop() {
                    if bvh2[m].prim_count > 0 || stays(m) {
                        count += 1;
                    } else {
                        todo.extend([bvh2[m].first_index as usize, bvh2[m].first_index as usize + 1]);
                    }
                }
                count
            };
            let nodes: Vec<usize> = std::iter::once(0).chain(inner.iter().copied().filter(|&n| stays(n))).collect();
            if nodes.iter().all(|&n| children(n) <= width) {
                best = best.min(nodes.iter().map(|&n| bvh2[n].aabb().half_area()).sum());
            }
        }
        best
    }

    #[test]
    fn the_slot_plan_does_not_depend_on_the_visiting_order() {
        let mut rng = SplitMix64::new(5);
        let boxes: Vec<Aabb> = (0..5000)
            .map(|_| {
                let min = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 100.0;
                Aabb::new(min, min + Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()))
            })
            .collect();
        let binned = super::super::binned_sah::build(boxes.len(), |i| boxes[i]).0.nodes;
        let ploc = build_bvh2(&boxes, BvhBuildParams::medium_build(), &mut Duration::default()).nodes;
        // The binned layout takes the sequential pass.
        assert!(children_after_parents(&binned));
        for bvh2 in [&binned, &ploc] {
            for width in [4, 8] {
                let (fast, reference) =
                    (SlotPlan::new(bvh2, width), SlotPlan::filled(bvh2, width, breadth_first(bvh2).into_iter().rev()));
                assert_eq!(fast.left, reference.left, "width {width}");
                let bits = |p: &SlotPlan| p.cost.iter().flatten().map(|c| c.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&fast), bits(&reference), "width {width}");
            }
        }
    }

    #[test]
    fn collapsing_keeps_the_inner_nodes_of_least_total_area() {
        let mut rng = SplitMix64::new(23);
        for round in 0..40 {
            let mut point = |scale: f32| Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * scale;
            let boxes: Vec<Aabb> = (0..10 + round % 5)
                .map(|_| {
                    let min = point(10.0);
                    Aabb::new(min, min + point(2.0))
                })
                .collect();
            let params = BvhBuildParams { max_prims_per_leaf: 1, ..BvhBuildParams::medium_build() };
            let bvh2 = build_bvh2(&boxes, params, &mut Duration::default()).nodes;
            let four = Bvh4::from_bvh2(&bvh2);
            let least = least_node_area(&bvh2, 4);
            assert!((node_area(&four) - least).abs() <= 1e-4 * least, "round {round}: {} vs {least}", node_area(&four));
            if let Some(eight) = Bvh8::from_bvh2(&bvh2) {
                let least = least_node_area(&bvh2, 8);
                assert!(
                    (node_area(&eight) - least).abs() <= 1e-4 * least,
                    "round {round}: {} vs {least}",
                    node_area(&eight)
                );
            }
        }
    }

    #[test]
    fn both_widths_visit_exactly_the_leaves_the_ray_enters() {
        let mut rng = SplitMix64::new(7);
        let mut point = |scale: f32| Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * scale;
        let boxes: Vec<Aabb> = (0..3_000)
            .map(|_| {
                let min = point(20.0) - 10.0;
                Aabb::new(min.into(), (min + point(1.5)).into())
            })
            .collect();
        let bvh2 = build_bvh2(&boxes, BvhBuildParams::medium_build(), &mut Duration::default()).nodes;
        let four = Bvh4::from_bvh2(&bvh2);
        let eight = Bvh8::from_bvh2(&bvh2);
        if eight.is_none() {
            eprintln!("no AVX on this CPU: the eight-wide tree is not built and not tested");
        }
        let mut rng = SplitMix64::new(8);
        let mut entered = 0;
        for i in 0..2_000 {
            let origin = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 24.0 - 12.0;
            let mut dir = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            // Every fourth ray runs parallel to one or two axes.
            if i % 4 == 0 {
                dir[i % 3] = 0.0;
                dir[(i / 4) % 3] = 0.0;
            }
            let tmax = if i % 2 == 0 { f32::INFINITY } else { rng.next_f32() * 20.0 };
            let ray = Ray::new(origin, dir.normalize_or(Vec3A::X), tmax);
            let expected = brute_force(&bvh2, &ray);
            entered += expected.len();
            assert_eq!(visited(&four, &ray), (expected.clone(), expected.clone()), "4-wide, ray {i}");
            if let Some(eight) = &eight {
                assert_eq!(visited(eight, &ray), (expected.clone(), expected), "8-wide, ray {i}");
            }
        }
        assert!(entered > 4_000, "rays should enter many leaves ({entered})");
    }
}
