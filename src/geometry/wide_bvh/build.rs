//! Collapsing a BVH2 into a wide BVH, keeping the inner nodes of least total surface area.

use obvhs::bvh2::node::Bvh2Node;

use super::{Bvh4, Bvh8, Node, WideBvh};

/// Most children a wide node may have, plus one (slot counts index arrays directly).
const SLOTS: usize = 9;

/// For each node of a BVH2, the least total surface area of the wide nodes its subtree needs
/// when it may take up to `i` slots of its parent's wide node, and how it spends them.
pub(super) struct SlotPlan {
    /// `cost[n][i]`, for `i` in 1..=W: with one slot, the node is a leaf (cost 0) or a wide
    /// node of its own; with more, its two children may share them instead.
    pub(super) cost: Vec<[f32; SLOTS]>,
    /// `left[n][i]`: slots the first child gets when node `n` hands its `i` slots to its
    /// children; 0 when it does better with fewer slots.
    pub(super) left: Vec<[u8; SLOTS]>,
}

impl SlotPlan {
    /// The plan for `bvh2` (root at 0, an inner node's children at `first_index` and the next)
    /// and nodes of `width` children. Costs are filled children first: where every inner
    /// node's children come after it (the binned builder's layout), in reverse array order, one
    /// sequential pass (the dragon's plan 60–64 → 13–19 ms against the order below); else in
    /// reverse breadth-first order.
    pub(super) fn new(bvh2: &[Bvh2Node], width: usize) -> Self {
        if children_after_parents(bvh2) {
            Self::filled(bvh2, width, (0..bvh2.len()).rev())
        } else {
            Self::filled(bvh2, width, breadth_first(bvh2).into_iter().rev())
        }
    }

    /// [`SlotPlan::new`], visiting the nodes in the order `children_first` gives (every
    /// node after its children).
    pub(super) fn filled(bvh2: &[Bvh2Node], width: usize, children_first: impl Iterator<Item = usize>) -> Self {
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
pub(super) fn children_after_parents(bvh2: &[Bvh2Node]) -> bool {
    bvh2.iter()
        .enumerate()
        .all(|(i, n)| n.prim_count > 0 || (n.first_index as usize > i && n.first_index as usize + 1 < bvh2.len()))
}

/// The nodes of `bvh2` reachable from the root, parents before children.
pub(super) fn breadth_first(bvh2: &[Bvh2Node]) -> Vec<usize> {
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

impl Bvh4 {
    /// Collapses a BVH2 (root at 0, children of an inner node at `first_index` and the next).
    pub fn from_bvh2(bvh2: &[Bvh2Node]) -> Self {
        Self::collapse(bvh2)
    }
}

impl Bvh8 {
    /// Collapses a BVH2 as [`Bvh4::from_bvh2`] does, or `None` on architectures whose
    /// traversal has no eight-lane kernels.
    pub fn from_bvh2(bvh2: &[Bvh2Node]) -> Option<Self> {
        #[cfg(target_arch = "x86_64")]
        return Some(Self::collapse(bvh2));
        #[cfg(not(target_arch = "x86_64"))]
        {
            let _ = bvh2;
            None
        }
    }
}

impl<const W: usize> WideBvh<W> {
    /// Collapses `bvh2` into nodes of up to `W` children. Every BVH2 leaf stays a leaf, so the
    /// surface area heuristic's cost of the wide tree varies only with the inner nodes kept:
    /// they are chosen by dynamic programming to make the sum of their surface areas least
    /// (Ylitie et al. 2017, §4.1), where filling each node with the children of largest area
    /// (what this did before) can keep more than it needs, and costs traversal time on deep
    /// meshes such as the dragon and Sponza; the images are the same.
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
        let mut nodes = crate::geometry::huge_pages::vec_on_huge_pages(bvh2.len() / 2 + 1);
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
        // The bound above is loose (the dragon's wide tree uses a fifth of it): the rest goes back
        // (glibc shrinks a block in place, so the huge-page advice stays with it).
        nodes.shrink_to_fit();
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
}
