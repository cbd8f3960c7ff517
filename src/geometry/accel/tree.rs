//! The wide tree a BLAS or the top level is traversed through, and the traversals written once for
//! either node width.

use obvhs::bvh2::node::Bvh2Node;

use crate::geometry::{
    ray::Ray,
    wide_bvh::{Bvh4, NodeTest, SahCost, WideBvh},
};
use crate::simd::Plain;
#[cfg(target_arch = "x86_64")]
use crate::simd::{Avx, Eight, Kernel, Lanes, Portable};

/// The wide tree traversal uses: eight children per node (with the token of the eight lanes
/// that test them, AVX2's or the portable ones'), or four ([`bvh_width`]).
#[derive(Clone, Debug)]
pub(super) enum Tree {
    Four(Bvh4),
    #[cfg(target_arch = "x86_64")]
    Eight(crate::geometry::wide_bvh::Bvh8, Eight),
}

impl Default for Tree {
    fn default() -> Self {
        Tree::Four(Bvh4::default())
    }
}

impl Tree {
    /// Collapses `bvh2` to eight children per node where [`bvh_width`] is 8, else to four.
    pub(super) fn from_bvh2(bvh2: &[Bvh2Node]) -> Self {
        #[cfg(target_arch = "x86_64")]
        if bvh_width() == 8
            && let Some(tree) = crate::geometry::wide_bvh::Bvh8::from_bvh2(bvh2)
        {
            return Tree::Eight(tree, Eight::allowed());
        }
        Tree::Four(Bvh4::from_bvh2(bvh2))
    }

    pub(super) fn map_leaves(&mut self, f: impl FnMut(u32, u32) -> (u32, u32)) {
        match self {
            Tree::Four(t) => t.map_leaves(f),
            #[cfg(target_arch = "x86_64")]
            Tree::Eight(t, _) => t.map_leaves(f),
        }
    }

    pub(super) fn memory_bytes(&self) -> usize {
        match self {
            Tree::Four(t) => t.memory_bytes(),
            #[cfg(target_arch = "x86_64")]
            Tree::Eight(t, _) => t.memory_bytes(),
        }
    }

    pub(super) fn sah_cost(&self, tests: impl Fn(u32) -> f64) -> Option<SahCost> {
        match self {
            Tree::Four(t) => t.sah_cost(tests),
            #[cfg(target_arch = "x86_64")]
            Tree::Eight(t, _) => t.sah_cost(tests),
        }
    }

    pub(super) fn len(&self) -> usize {
        match self {
            Tree::Four(t) => t.len(),
            #[cfg(target_arch = "x86_64")]
            Tree::Eight(t, _) => t.len(),
        }
    }

    pub(super) fn width(&self) -> usize {
        match self {
            Tree::Four(_) => 4,
            #[cfg(target_arch = "x86_64")]
            Tree::Eight(..) => 8,
        }
    }

    /// Runs `query` over this tree; an eight-wide tree is traversed by code compiled for its
    /// eight lanes.
    #[inline(always)]
    pub(super) fn query<Q: TreeQuery>(&self, query: Q) -> Q::Output {
        match self {
            Tree::Four(tree) => query.run(tree, Plain),
            #[cfg(target_arch = "x86_64")]
            Tree::Eight(tree, Eight::Avx(isa)) => Avx::compiled(*isa, OnTree { tree, query }),
            #[cfg(target_arch = "x86_64")]
            Tree::Eight(tree, Eight::Portable(isa)) => Portable::compiled(*isa, OnTree { tree, query }),
        }
    }
}

/// A traversal written once for either node width, given the token of its node test.
pub(super) trait TreeQuery {
    type Output;
    fn run<const W: usize>(self, tree: &WideBvh<W>, test: impl NodeTest<W>) -> Self::Output;
}

/// A [`TreeQuery`] over an eight-wide tree as a kernel, so that it is compiled for the
/// eight-lane instruction set and the node test inlines.
#[cfg(target_arch = "x86_64")]
struct OnTree<'a, Q> {
    tree: &'a crate::geometry::wide_bvh::Bvh8,
    query: Q,
}

#[cfg(target_arch = "x86_64")]
impl<L: Lanes<Isa: NodeTest<8>>, Q: TreeQuery> Kernel<L> for OnTree<'_, Q> {
    type Output = Q::Output;
    #[inline(always)]
    fn run(self, isa: L::Isa) -> Q::Output {
        self.query.run(self.tree, isa)
    }
}

/// Occlusion of each of `rays` not yet known to be blocked (`blocked`, same length), by
/// `target`'s traversal of the tree: one call, one dispatch to the tree's width.
pub(super) struct OccludedEach<'a, T> {
    pub(super) target: &'a T,
    pub(super) rays: &'a [Ray],
    pub(super) stack: &'a mut Vec<(u32, f32)>,
    pub(super) blocked: &'a mut [bool],
}

/// What an [`OccludedEach`] query traverses: a BLAS, or the scene through its top level.
pub(super) trait Occluder {
    /// Whether anything reached through `tree` (nodes tested by `test`) blocks `ray`. Uses
    /// `stack` above its length.
    fn occluded_in<const W: usize>(
        &self,
        tree: &WideBvh<W>,
        test: impl NodeTest<W>,
        ray: &Ray,
        stack: &mut Vec<(u32, f32)>,
    ) -> bool;
}

impl<T: Occluder> TreeQuery for OccludedEach<'_, T> {
    type Output = ();
    #[inline(always)]
    fn run<const W: usize>(self, tree: &WideBvh<W>, test: impl NodeTest<W>) {
        for (ray, b) in self.rays.iter().zip(self.blocked.iter_mut()) {
            *b = *b || self.target.occluded_in(tree, test, ray, self.stack);
        }
    }
}

/// The node width: what the environment variable `HEMI_BVH_WIDTH` asks for (4 or 8), else 8
/// where the vector lanes run ([`crate::simd::isa`] at least AVX2) and 4 where they do not:
/// without vector instructions one ray at a time through four-wide nodes is quicker than
/// eight-ray packets in plain arrays (which `HEMI_BVH_WIDTH=8` still runs, with the same
/// images). Read once per process.
#[cfg(target_arch = "x86_64")]
pub(super) fn bvh_width() -> usize {
    static WIDTH: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *WIDTH.get_or_init(|| match std::env::var("HEMI_BVH_WIDTH").as_deref().map(str::trim) {
        Ok("4") => 4,
        Ok("8") => 8,
        _ if crate::simd::isa() >= crate::simd::Isa::Avx2 => 8,
        _ => 4,
    })
}

/// A closest hit in a scene: (instance, primitive slot, b1, b2).
pub(super) type ClosestHit = (u32, u32, f32, f32);
