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

mod build;
mod node_test;
#[cfg(target_arch = "x86_64")]
mod packet;
#[cfg(test)]
mod tests;
mod traversal;

#[cfg(target_arch = "x86_64")]
pub(crate) use packet::{FusedPacket, LaneHits, PACKET_MIN_LANES, RayPacket};

use obvhs::aabb::Aabb;

use super::ray::Ray;
use crate::{math::gamma, simd::Lanes};

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
    // Written out rather than through `array::from_fn`, which does not always fold away where
    // this inlines into a large kernel.
    let far_row = |a: u32| 3 * ((negative >> a) & 1) as usize;
    let (x, y, z) = (far_row(0), far_row(1), far_row(2));
    ([x, 1 + y, 2 + z], [3 - x, 4 - y, 5 - z])
}

/// What a tree costs a ray by the surface area heuristic, in the units of Embree's own BVH
/// statistics (printed by its `verbose=3` device): each inner node's box and each leaf's box
/// times its primitive tests, as half areas over the root box's. A line through the root box
/// meets a box inside it with probability the ratio of their areas, so these are the node
/// tests and leaf tests such a line expects, up to where an occlusion query stops.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SahCost {
    /// Inner nodes (the root counts 1).
    pub inner: f64,
    /// Leaves, each weighted by its tests (a triangle leaf's packets of four).
    pub leaves: f64,
}

impl SahCost {
    /// Both parts.
    pub fn total(&self) -> f64 {
        self.inner + self.leaves
    }
}

/// The ray–children test of nodes of width `W`, run by the token of the lanes it is compiled
/// for ([`Lanes::Isa`]): the traversals take it as their proof that the CPU may run the test,
/// and the lone-ray kernels they call run in its lanes.
pub(crate) trait NodeTest<const W: usize>: Copy {
    /// The lanes whose token this is.
    type Lanes: Lanes<Isa = Self>;
    /// Which children of `n` the ray enters before `tmax` (bit i for child i) and their entry
    /// distances.
    fn test(self, n: &Node<W>, r: &RayBox, tmax: f32) -> (u32, [f32; W]);
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

impl<const W: usize> WideBvh<W> {
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

    /// The tree's [`SahCost`], a leaf of `count` primitives taking `tests(count)` tests
    /// (`None` for an empty tree or a root box without a finite area).
    pub fn sah_cost(&self, tests: impl Fn(u32) -> f64) -> Option<SahCost> {
        let half_area = |min: [f32; 3], max: [f32; 3]| {
            let [x, y, z] = std::array::from_fn(|a| f64::from(max[a]) - f64::from(min[a]));
            x * y + y * z + z * x
        };
        let root = half_area(self.bounds.min.to_array(), self.bounds.max.to_array());
        if self.nodes.is_empty() || !(root.is_finite() && root > 0.0) {
            return None;
        }
        let mut cost = SahCost { inner: root, leaves: 0.0 };
        for n in &self.nodes {
            // Empty slots are inverted boxes.
            for i in (0..W).filter(|&i| n.planes[0][i] <= n.planes[3][i]) {
                let area = half_area([0, 1, 2].map(|a| n.planes[a][i]), [3, 4, 5].map(|a| n.planes[a][i]));
                match n.count[i] {
                    0 => cost.inner += area,
                    count => cost.leaves += area * tests(count),
                }
            }
        }
        Some(SahCost { inner: cost.inner / root, leaves: cost.leaves / root })
    }
}
