//! Packet traversal: rays in SIMD lanes sharing one walk of an eight-wide tree.

use super::{NEAR_START, Node, NodeTest, RayBox, WideBvh, far_scale, plane_rows};
use crate::geometry::{
    counters::{Event, count},
    ray::Ray,
};
use crate::simd::prefetch;
#[cfg(target_arch = "x86_64")]
use crate::{
    geometry::lanes::RayLanes,
    simd::{FusedLanes, Lanes},
};

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
    #[inline(always)]
    pub(crate) fn new(rays: &RayLanes<L>) -> Self {
        let zero = L::splat(rays.tmax.isa(), 0.0);
        let inv = rays.inv_dir;
        RayPacket {
            origin: rays.origin,
            inv_dir: inv,
            negative: [inv[0].lt(zero), inv[1].lt(zero), inv[2].lt(zero)],
            tmax: rays.tmax,
        }
    }
}

/// The node test of a packet traversal: which of the packet's lanes enter each of a node's
/// eight children (bit i for lane i).
#[cfg(target_arch = "x86_64")]
pub(crate) trait PacketNodeTest {
    /// Writes to `entered` the lanes of `within` that enter each child of `n`, and returns the
    /// children some of them enter (bit c for child c), so that a traversal visits those
    /// without a branch on each of the eight. (An out-parameter: a returned array was copied to
    /// the caller's with one wide load of the eight narrow stores just made, which the CPU
    /// cannot forward from its store buffer and so waits for.)
    fn enter(&self, n: &Node<8>, within: u32, entered: &mut [u32; 8]) -> u32;
}

#[cfg(target_arch = "x86_64")]
impl<L: Lanes> PacketNodeTest for RayPacket<L> {
    #[inline(always)]
    fn enter(&self, n: &Node<8>, within: u32, entered: &mut [u32; 8]) -> u32 {
        // Every child's test first, with no branch between them: each is a chain of dependent
        // operations ending in a lane mask, and eight independent chains overlap where a branch
        // on each mask would stall on it (an empty slot is an inverted box, which no ray enters).
        // (Loops, not closures: a closure is compiled without the caller's instruction set.)
        let mut children = 0;
        for (c, e) in entered.iter_mut().enumerate() {
            *e = n.test_packet(c, self, self.tmax) & within;
            children |= u32::from(*e != 0) << c;
        }
        children
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
    #[inline(always)]
    pub(crate) fn new(rays: &RayLanes<L>, live: u32) -> Self {
        let isa = rays.tmax.isa();
        let zero = L::splat(isa, 0.0);
        // 4u = 2⁻²²: scaling by a power of two is exact (short of underflow, where the
        // offsets' roundings are exact too).
        let margin = L::splat(isa, f32::EPSILON * 2.0);
        let mut near_offset = [zero; 3];
        let mut far_offset = [zero; 3];
        let mut negative = [L::mask(isa, 0); 3];
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

    /// The lanes that enter a child whose (near, far) planes on each axis are `planes`, in each
    /// lane's own choice of rows.
    #[inline(always)]
    fn lanes_entering(&self, planes: [(L, L); 3]) -> u32 {
        let isa = self.tmax.isa();
        let mut near = L::splat(isa, NEAR_START);
        let mut far = L::splat(isa, f32::INFINITY);
        for (a, (near_plane, far_plane)) in planes.into_iter().enumerate() {
            // maxps / minps return their second operand when either is NaN.
            near = near_plane.mul_add(self.inv_dir[a], self.near_offset[a]).max_keep(near);
            far = far_plane.mul_add(self.inv_dir[a], self.far_offset[a]).min_keep(far);
        }
        let far = far.mul(L::splat(isa, far_scale())).min_keep(self.tmax);
        L::bits(near.le(far))
    }
}

#[cfg(target_arch = "x86_64")]
impl<L: FusedLanes> PacketNodeTest for FusedPacket<L> {
    #[inline(always)]
    fn enter(&self, n: &Node<8>, within: u32, entered: &mut [u32; 8]) -> u32 {
        // (Loops, not closures: a closure is compiled without the caller's instruction set.)
        let isa = self.tmax.isa();
        let mut planes = [(L::splat(isa, 0.0), L::splat(isa, 0.0)); 3];
        let mut children = 0;
        if let Some((near_row, far_row)) = self.octant {
            for (c, e) in entered.iter_mut().enumerate() {
                for (a, plane) in planes.iter_mut().enumerate() {
                    *plane = (L::splat(isa, n.planes[near_row[a]][c]), L::splat(isa, n.planes[far_row[a]][c]));
                }
                *e = self.lanes_entering(planes) & within;
                children |= u32::from(*e != 0) << c;
            }
        } else {
            for (c, e) in entered.iter_mut().enumerate() {
                for (a, plane) in planes.iter_mut().enumerate() {
                    *plane = n.lane_planes::<L>(isa, c, a, self.negative[a]);
                }
                *e = self.lanes_entering(planes) & within;
                children |= u32::from(*e != 0) << c;
            }
        }
        children
    }
}

/// Entries of the packet traversal's stack, which lives on the call stack; a subtree that
/// would overflow it is traversed ray by ray instead. The unit tests use four, so that the
/// overflow path is taken all the time there and checked like the others.
#[cfg(target_arch = "x86_64")]
const PACKET_STACK: usize = if cfg!(test) { 4 } else { 128 };

/// Fewest live rays for which a node is tested with the packet; fewer go on ray by ray. A
/// packet test costs about as much per child as a single ray's test of all eight children, so
/// the break-even is a few rays; 3 to 7 measured the same within noise.
#[cfg(target_arch = "x86_64")]
pub(crate) const PACKET_MIN_LANES: u32 = 4;

#[cfg(target_arch = "x86_64")]
impl Node<8> {
    /// Child `c`'s near and far planes on axis `a` in each lane: its maximum and minimum in the
    /// lanes of `negative` (directions negative on the axis), its minimum and maximum elsewhere.
    #[inline(always)]
    fn lane_planes<L: Lanes>(&self, isa: L::Isa, c: usize, a: usize, negative: L::Mask) -> (L, L) {
        let (lo, hi) = (L::splat(isa, self.planes[a][c]), L::splat(isa, self.planes[a + 3][c]));
        (lo.select(negative, hi), hi.select(negative, lo))
    }

    /// The lanes of `p` that enter child `c`: the eight-child test's operations per ray, each
    /// ray's near and far planes picked by its own direction's signs, so every lane decides
    /// exactly as [`NodeTest::test`] does for that ray.
    #[inline(always)]
    fn test_packet<L: Lanes>(&self, c: usize, p: &RayPacket<L>, tmax: L) -> u32 {
        let isa = tmax.isa();
        let mut near = L::splat(isa, NEAR_START);
        let mut far = L::splat(isa, f32::INFINITY);
        for a in 0..3 {
            let (near_plane, far_plane) = self.lane_planes::<L>(isa, c, a, p.negative[a]);
            // maxps / minps return their second operand when either is NaN.
            near = near_plane.sub(p.origin[a]).mul(p.inv_dir[a]).max_keep(near);
            far = far_plane.sub(p.origin[a]).mul(p.inv_dir[a]).min_keep(far);
        }
        let far = far.mul(L::splat(isa, far_scale())).min_keep(tmax);
        L::bits(near.le(far))
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
    #[inline(always)]
    pub(crate) fn occluded_packet(
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
            let mut children = p.enter(n, lanes, &mut tested);
            while children != 0 {
                let c = children.trailing_zeros() as usize;
                children &= children - 1;
                // Only rays that entered this node, and are not yet blocked, go on to its children.
                let entered = tested[c] & open;
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
    #[inline(always)]
    pub(crate) fn entry_node_of<L: Lanes>(&self, test: impl NodeTest<8>, rays: &RayLanes<L>, live: u32) -> Option<u32> {
        match rays.segments_box(live, &self.bounds) {
            Some((lo, hi)) => self.entry_node(test, lo, hi),
            None => (!self.nodes.is_empty()).then_some(0),
        }
    }

    /// The deepest node under which lie all leaves whose boxes overlap `lo..hi` (going down
    /// while exactly one child overlaps it and is not a leaf), or `None` where no child of a
    /// node on that way does; the children tested in the eight lanes of `test`.
    #[inline(always)]
    pub(crate) fn entry_node<T: NodeTest<8>>(&self, test: T, lo: glam::Vec3A, hi: glam::Vec3A) -> Option<u32> {
        if self.nodes.is_empty() {
            return None;
        }
        let mut node = 0u32;
        loop {
            let n = &self.nodes[node as usize];
            // An empty slot's inverted box overlaps nothing.
            let overlap = {
                type N<T> = <T as NodeTest<8>>::Lanes;
                let mut overlaps = N::<T>::mask(test, u32::MAX);
                for a in 0..3 {
                    let below = N::<T>::load(test, &n.planes[a]).le(N::<T>::splat(test, hi[a]));
                    let above = N::<T>::splat(test, lo[a]).le(N::<T>::load(test, &n.planes[a + 3]));
                    overlaps = N::<T>::and(overlaps, N::<T>::and(below, above));
                }
                N::<T>::bits(overlaps)
            };
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
    #[inline(always)]
    pub(crate) fn closest_packet<L: Lanes, T>(
        &self,
        test: impl NodeTest<8>,
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
        let isa = p.tmax.isa();
        let widened = |tmax: &[f32; 16]| L::load(isa, &tmax[..]).mul(L::splat(isa, far_scale()));
        let mut tmax_lanes = widened(&hits.tmax);
        while len > 0 {
            len -= 1;
            // SAFETY: every entry below `len` was written before `len` passed it.
            let (node, lanes) = unsafe { todo[len].assume_init() };
            count(Event::PacketNodeTest);
            let n = &self.nodes[node as usize];
            let mut tested = [0u32; 8];
            let mut children = 0u32;
            for (c, t) in tested.iter_mut().enumerate() {
                *t = n.test_packet(c, p, tmax_lanes) & lanes;
                children |= u32::from(*t != 0) << c;
            }
            // Leaves now; inner children pushed farthest first (for the first ray), so that the
            // nearest is popped next.
            let (_, entry) = test.test(n, &order, f32::INFINITY);
            let mut inner = [(0usize, 0f32); 8];
            let mut k = 0;
            while children != 0 {
                let c = children.trailing_zeros() as usize;
                children &= children - 1;
                let entered = tested[c];
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
    /// Lanes offered a second hit at exactly their closest distance so far (or within
    /// rounding of it, where either distance is [`LaneHits::offer_inexact`]'s): which one a
    /// single-ray traversal keeps depends on its order, so the caller traces them alone.
    pub tied: u32,
    /// Lanes whose closest hit so far came through [`LaneHits::offer_inexact`].
    inexact: u32,
}

/// How far apart, relative to the larger, two distances may lie and still count as tied when
/// one of them is rounded ([`LaneHits::offer_inexact`]): twice the few ulps its rounding and the
/// single-ray traversal's comparison with it can each move it.
#[cfg(target_arch = "x86_64")]
const ROUNDED_TIE: f32 = 8.0 * f32::EPSILON;

#[cfg(target_arch = "x86_64")]
impl<T: Copy + PartialEq> LaneHits<T> {
    /// No hits yet for `rays` (up to sixteen), each lane's closest distance its ray's `tmax`.
    pub fn new(rays: &[Ray]) -> Self {
        let mut tmax = [0.0; 16];
        for (t, ray) in tmax.iter_mut().zip(rays) {
            *t = ray.tmax;
        }
        LaneHits { tmax, best: [None; 16], tied: 0, inexact: 0 }
    }

    /// Lane `k`'s ray from `rays`, reaching one step past its closest distance so far, so that
    /// a hit at exactly that distance is seen too (and offered as a tie).
    #[inline(always)]
    pub fn probe(&self, rays: &[Ray], k: usize) -> Ray {
        rays[k].with_tmax(self.tmax[k].next_up())
    }

    /// Offers lane `k` a hit at `t` found by its [`LaneHits::probe`]: kept if closer than its
    /// closest so far (clearing a tie there), else (exactly as close) a tie, unless it is the
    /// closest hit itself offered again (a triangle that spatial splits put in several leaves).
    #[inline(always)]
    pub fn offer(&mut self, k: usize, t: f32, hit: T) {
        self.offer_rounded(k, t, hit, false);
    }

    /// [`LaneHits::offer`] of a hit whose distance is rounded: a hit in an instance's own
    /// frame, at its local distance plus the origin's shift (`Instance::local_ray`). A ray
    /// traced alone compares it with its closest hit so far in the instance's frame, so where
    /// two hits lie within rounding of each other, which one it keeps depends on the order it
    /// meets them in: such lanes are tied.
    #[inline(always)]
    pub fn offer_inexact(&mut self, k: usize, t: f32, hit: T) {
        self.offer_rounded(k, t, hit, true);
    }

    #[inline(always)]
    fn offer_rounded(&mut self, k: usize, t: f32, hit: T, inexact: bool) {
        let bit = 1 << k;
        let rounded = (inexact || self.inexact & bit != 0)
            && self.best[k].is_some_and(|best| best != hit)
            && (t - self.tmax[k]).abs() <= ROUNDED_TIE * t.max(self.tmax[k]);
        if t < self.tmax[k] {
            self.tmax[k] = t;
            self.best[k] = Some(hit);
            self.tied &= !bit;
            self.inexact = (self.inexact & !bit) | if inexact { bit } else { 0 };
        } else if self.best[k] != Some(hit) {
            self.tied |= bit;
        }
        if rounded {
            self.tied |= bit;
        }
    }
}
