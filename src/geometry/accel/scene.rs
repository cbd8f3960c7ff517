//! Everything rays can hit: the instances, their top level, and the planes beside them.

use std::{
    sync::Arc,
    time::{Duration, Instant},
};

use bevy_ecs::prelude::Resource;
use glam::{Affine3A, Vec3A};
use obvhs::{
    BvhBuildParams,
    aabb::Aabb,
    bvh2::{builder::build_bvh2, node::Bvh2Node},
};

use super::{
    Object, Prim, Shape,
    alpha::AlphaLayer,
    blas::{Blas, SMALL_SET, subtree_depth},
    tlas::Instance,
    tree::{ClosestHit, Occluder, Tree, TreeQuery},
};
use crate::geometry::{
    hit::SurfaceHit,
    ray::Ray,
    shapes::{PlanePrim, SpherePrim, Triangle},
    wide_bvh::{NodeTest, SahCost, WideBvh},
};
use crate::material::PlacedSurface;

/// What the last BVH update did, for statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BvhWork {
    /// Bottom-level BVHs built from scratch.
    pub blas_built: usize,
    /// Bottom-level BVHs refit to moved vertices.
    pub blas_refit: usize,
    /// Whether the top-level BVH over the instances was rebuilt.
    pub tlas_built: bool,
}

impl BvhWork {
    /// Whether any BVH work was done.
    pub fn any(&self) -> bool {
        self.blas_built + self.blas_refit > 0 || self.tlas_built
    }
}

/// Everything rays can hit.
#[derive(Resource, Clone, Debug, Default)]
pub struct SceneGeometry {
    pub(super) blases: Vec<Arc<Blas>>,
    pub(super) instances: Vec<Instance>,
    tlas: Vec<Bvh2Node>,
    /// The top-level BVH2 collapsed to a wide tree, which traversal uses.
    pub(super) top: Tree,
    /// Whether runs of camera rays go through the top level in packets: some BLAS holds
    /// triangle packets.
    pub(super) top_packets: bool,
    /// The BLAS of a scene that is one world-space instance (a baked static scene), which
    /// queries take directly, with no top level: held here so that a query reaches it in one
    /// load rather than through the instance list.
    pub(super) world_blas: Option<Arc<Blas>>,
    pub(super) planes: Vec<PlanePrim>,
    /// Alpha-tested meshes, kept out of the trees above and traversed apart with a test at
    /// every candidate hit; `None` (no query looks for them) when the scene has none.
    pub(super) alpha: Option<Arc<AlphaLayer>>,
    /// Objects, indexed by `SurfaceHit::object`.
    pub objects: Vec<Object>,
    /// The surfaces of textured or alpha-tested objects, indexed like `objects` (empty when no
    /// object has one): read once per camera hit, never during traversal.
    pub surfaces: Vec<Option<Arc<PlacedSurface>>>,
    /// Triangles stored (each shared mesh once).
    pub triangle_count: usize,
    /// Triangles placed in the scene (each instance counted).
    pub instanced_triangle_count: usize,
    /// Zero-area triangles dropped from the input (they can never be hit).
    pub degenerate_triangles: usize,
    /// Bounds of the bounded primitives (empty when there are none).
    pub bounds: Option<(Vec3A, Vec3A)>,
    /// Depth of the top-level BVH plus the deepest BLAS.
    pub depth: usize,
    /// Time the last update took.
    pub build_time: Duration,
}

impl SceneGeometry {
    /// A scene whose bounded primitives (given in world space, any order) form one BLAS,
    /// with `planes` beside it.
    pub fn build(prims: Vec<Prim>, planes: Vec<PlanePrim>, objects: Vec<Object>) -> Self {
        let start = Instant::now();
        let blas = Arc::new(Blas::build(prims));
        let instances = blas.bounds().and_then(|b| Instance::new(0, b, Affine3A::IDENTITY, None));
        let mut g = SceneGeometry::from_instances(vec![blas], instances.into_iter().collect(), planes, objects);
        g.build_time = start.elapsed();
        g
    }

    /// A scene of BLAS instances plus `planes`; builds the top-level BVH over the instances.
    pub fn from_instances(
        blases: Vec<Arc<Blas>>,
        instances: Vec<Instance>,
        planes: Vec<PlanePrim>,
        objects: Vec<Object>,
    ) -> Self {
        let start = Instant::now();
        let (tlas, instances) = if instances.is_empty() {
            (Vec::new(), instances)
        } else {
            // PLOC merges equal Morton codes pair by pair, so thousands of instances at one
            // position would build in quadratic time; the binned builder halves such sets.
            let bvh = if instances.len() < SMALL_SET {
                let aabbs: Vec<Aabb> = instances.iter().map(|i| i.bounds).collect();
                let params = BvhBuildParams { max_prims_per_leaf: 1, ..BvhBuildParams::fast_build() };
                build_bvh2(&aabbs, params, &mut Duration::default())
            } else {
                crate::geometry::binned_sah::build(instances.len(), |i| instances[i].bounds).0
            };
            let ordered = bvh.primitive_indices.iter().map(|&i| instances[i as usize].clone()).collect();
            (bvh.nodes, ordered)
        };
        let triangle_count = blases.iter().map(|b| b.triangle_count).sum();
        let instanced_triangle_count = instances.iter().map(|i| blases[i.blas as usize].triangle_count).sum();
        let degenerate_triangles = blases.iter().map(|b| b.degenerate_triangles).sum();
        let bounds = tlas.first().map(|n| (n.aabb().min, n.aabb().max));
        let depth = subtree_depth(&tlas) + blases.iter().map(|b| b.depth).max().unwrap_or(0);
        let world_blas = match &instances[..] {
            [inst] if inst.identity => Some(blases[inst.blas as usize].clone()),
            _ => None,
        };
        SceneGeometry {
            top_packets: blases.iter().any(|b| !b.packets.is_empty()),
            world_blas,
            blases,
            instances,
            top: Tree::from_bvh2(&tlas),
            tlas,
            planes,
            alpha: None,
            objects,
            surfaces: Vec::new(),
            triangle_count,
            instanced_triangle_count,
            degenerate_triangles,
            bounds,
            depth,
            build_time: start.elapsed(),
        }
    }

    /// This scene with alpha-tested meshes (`alpha`) and the surfaces of textured objects
    /// (indexed like `objects`; empty when there are none).
    pub fn with_surfaces(mut self, alpha: Option<AlphaLayer>, surfaces: Vec<Option<Arc<PlacedSurface>>>) -> Self {
        if let Some(layer) = &alpha {
            self.triangle_count += layer.triangle_count();
            self.instanced_triangle_count += layer.triangle_count();
        }
        self.alpha = alpha.map(Arc::new);
        self.surfaces = surfaces;
        self
    }

    /// Number of alpha-tested meshes, traversed apart from the rest.
    pub fn alpha_mesh_count(&self) -> usize {
        self.alpha.as_ref().map_or(0, |a| a.len())
    }

    /// The surface of the object `hit` lies on, if it has one (a textured or alpha-tested mesh).
    #[inline]
    pub fn surface_of(&self, hit: &SurfaceHit) -> Option<&PlacedSurface> {
        self.surfaces.get(hit.object as usize).and_then(|s| s.as_deref())
    }

    /// Children per node of the trees traversal uses (8 with AVX, else 4).
    pub fn node_width(&self) -> usize {
        self.blases.iter().map(|b| b.node_width()).max().unwrap_or(self.top.width())
    }

    /// Rays per packet in occlusion runs: 16 with AVX-512, 8 with AVX, 0 where trees are
    /// four-wide and every ray is traced alone.
    pub fn packet_lanes(&self) -> usize {
        #[cfg(target_arch = "x86_64")]
        if self.node_width() == 8 {
            return crate::simd::packet_lanes();
        }
        0
    }

    /// Number of binary BVH nodes as built (top level plus every BLAS once).
    pub fn node_count(&self) -> usize {
        self.tlas.len() + self.blases.iter().map(|b| b.node_count()).sum::<usize>()
    }

    /// Number of nodes of the wide trees traversal uses ([`SceneGeometry::node_width`]
    /// children each; top level plus every BLAS once).
    pub fn wide_node_count(&self) -> usize {
        self.top.len() + self.blases.iter().map(|b| b.wide_node_count()).sum::<usize>()
    }

    /// Number of primitives stored in the leaves (shared meshes once; a triangle that spatial
    /// splits put in several leaves once per leaf).
    pub fn prim_count(&self) -> usize {
        self.blases.iter().map(|b| b.slot_count()).sum()
    }

    /// The BLAS with the most primitive slots, by those slots, and its [`SahCost`] (`None`
    /// without one that has area).
    pub fn largest_blas_sah(&self) -> Option<(usize, SahCost)> {
        let largest = self.blases.iter().max_by_key(|b| b.slot_count())?;
        largest.sah_cost().map(|cost| (largest.slot_count(), cost))
    }

    /// The bottom-level BVHs.
    pub fn blases(&self) -> &[Arc<Blas>] {
        &self.blases
    }

    /// The instances, in top-level leaf order.
    pub fn instances(&self) -> &[Instance] {
        &self.instances
    }

    /// The alpha-tested meshes' instances (none without such meshes), which
    /// [`SceneGeometry::instances`] leaves out.
    pub fn alpha_instances(&self) -> impl Iterator<Item = &Instance> {
        self.alpha.iter().flat_map(|layer| layer.instances())
    }

    /// Every bounded primitive placed in world space (instances expanded), for comparisons.
    pub fn world_prims(&self) -> Vec<Prim> {
        let mut out = Vec::new();
        for inst in &self.instances {
            let m = inst.to_world;
            for prim in self.blases[inst.blas as usize].prims() {
                let object = inst.object.unwrap_or(prim.object);
                let shape = match prim.shape {
                    Shape::Triangle(t) => Shape::Triangle(Triangle { p: t.p.map(|p| m.transform_point3a(p)) }),
                    Shape::Sphere(s) => {
                        let scale = m.matrix3.x_axis.length();
                        Shape::Sphere(SpherePrim { center: m.transform_point3a(s.center), radius: s.radius * scale })
                    }
                };
                out.push(Prim { shape, object });
            }
        }
        out
    }

    /// Number of infinite planes.
    pub fn plane_count(&self) -> usize {
        self.planes.len()
    }

    /// Bytes held by nodes, instances and primitives.
    pub fn memory_bytes(&self) -> usize {
        self.tlas.len() * size_of::<Bvh2Node>()
            + self.instances.len() * size_of::<Instance>()
            + self.blases.iter().map(|b| b.memory_bytes()).sum::<usize>()
            + self.planes.len() * size_of::<PlanePrim>()
            + self.alpha.as_ref().map_or(0, |a| a.memory_bytes())
    }

    /// Diagonal length of the bounded geometry's box (0 when there is none).
    pub fn extent(&self) -> f32 {
        self.bounds.map_or(0.0, |(min, max)| (max - min).length())
    }

    /// Closest hit along `ray`, if any. `stack` is reusable scratch space.
    #[inline]
    pub fn intersect(&self, ray: &Ray, stack: &mut Vec<(u32, f32)>) -> Option<SurfaceHit> {
        let mut ray = *ray;
        let best = self.closest_instance(&mut ray, stack);
        if let Some(alpha) = &self.alpha
            && let Some(hit) = alpha.closest(&mut ray, stack)
        {
            // Nearer than any opaque hit: the plane test below decides between the two.
            return self.planes_before(ray, |ray| Some(alpha.surface(hit, ray)));
        }
        self.hit_with_planes(ray, best)
    }

    /// The hit [`SceneGeometry::intersect`] finds along `ray` where it ends at `end` (found by
    /// [`SceneGeometry::ray_ends`] for this ray), bit for bit: the surface at the closest
    /// primitive, unless a plane is hit before it; made into `make(hit)` and written to `out`.
    /// The surface is worked out here and stored from registers, not returned through memory
    /// that a copy would read back while its narrow stores are still in flight.
    #[inline(never)]
    pub fn hit_at_into<T>(&self, ray: &Ray, end: RayEnd, out: &mut Option<T>, make: impl FnOnce(SurfaceHit) -> T) {
        let best = end.closest();
        *out = self
            .planes_before(ray.with_tmax(end.tmax), |ray| {
                best.map(|(i, slot, b1, b2)| self.surface_inlined(i, slot, ray, b1, b2))
            })
            .map(make);
    }

    /// Where `ray` ends among the opaque primitives, traced alone.
    #[inline(always)]
    pub(super) fn ray_end(&self, ray: &Ray, stack: &mut Vec<(u32, f32)>) -> RayEnd {
        let mut ray = *ray;
        let best = self.closest_instance(&mut ray, stack);
        RayEnd::new(best, ray.tmax)
    }

    /// The closest hit along `ray` given the closest primitive hit `best` (instance, slot,
    /// barycentrics) at `ray.tmax`: a plane hit before it wins.
    #[inline]
    fn hit_with_planes(&self, ray: Ray, best: Option<ClosestHit>) -> Option<SurfaceHit> {
        self.planes_before(ray, |ray| best.map(|(i, slot, b1, b2)| self.surface(i, slot, ray, b1, b2)))
    }

    /// Whether a plane lies before `tmax` along `ray`: where one does, the hit there is the
    /// plane's ([`SceneGeometry::hit_at_into`]).
    #[inline(always)]
    pub(super) fn plane_before(&self, ray: &Ray, tmax: f32) -> bool {
        let ray = ray.with_tmax(tmax);
        self.planes.iter().any(|plane| plane.intersect(&ray).is_some())
    }

    /// The hit of a plane before `ray.tmax` if there is one, else `surface(ray)`: the hit
    /// found at `ray.tmax`.
    #[inline(always)]
    fn planes_before(&self, mut ray: Ray, surface: impl FnOnce(&Ray) -> Option<SurfaceHit>) -> Option<SurfaceHit> {
        let mut plane_hit = None;
        for plane in &self.planes {
            if let Some(t) = plane.intersect(&ray) {
                ray.tmax = t;
                plane_hit = Some(plane);
            }
        }
        if let Some(plane) = plane_hit {
            return Some(plane.surface(&ray, ray.tmax));
        }
        surface(&ray)
    }

    /// The surface at a hit of instance `i`'s primitive `slot`; `ray.tmax` is the world t.
    pub(super) fn surface(&self, i: u32, slot: u32, ray: &Ray, b1: f32, b2: f32) -> SurfaceHit {
        self.surface_inlined(i, slot, ray, b1, b2)
    }

    /// [`SceneGeometry::surface`], inlined where it is called.
    #[inline(always)]
    fn surface_inlined(&self, i: u32, slot: u32, ray: &Ray, b1: f32, b2: f32) -> SurfaceHit {
        let inst = &self.instances[i as usize];
        let blas = &self.blases[inst.blas as usize];
        let (object, prim) = hit_ids(inst, blas, slot);
        if inst.identity {
            return SurfaceHit { prim, ..blas.surface(slot, ray, b1, b2, object) };
        }
        // The same local ray as during traversal (a pure function of the world ray's origin and
        // direction), so the local hit is the one that was found.
        let Some((local, dt)) = inst.local_ray(&ray.with_tmax(f32::INFINITY)) else {
            return SurfaceHit { prim, ..blas.surface(slot, ray, b1, b2, object) };
        };
        let local = local.with_tmax(ray.tmax - dt);
        SurfaceHit { prim, ..inst.to_world_hit(blas.surface(slot, &local, b1, b2, object), dt) }
    }

    /// Front-to-back top-level traversal; shrinks `ray.tmax` (world t) to the closest hit and
    /// returns (instance, primitive slot, b1, b2).
    #[inline]
    fn closest_instance(&self, ray: &mut Ray, stack: &mut Vec<(u32, f32)>) -> Option<ClosestHit> {
        stack.clear();
        if let Some(blas) = &self.world_blas {
            // One world-space BLAS (a static scene): no top level to traverse.
            return blas.closest(ray, stack).map(|(slot, b1, b2)| (0, slot, b1, b2));
        }
        self.top.query(TopClosest { scene: self, ray, stack })
    }

    /// Closest hit through the top-level tree `top`.
    #[inline(always)]
    pub(super) fn closest_through<const W: usize>(
        &self,
        top: &WideBvh<W>,
        node_test: impl NodeTest<W>,
        ray: &mut Ray,
        stack: &mut Vec<(u32, f32)>,
    ) -> Option<ClosestHit> {
        let mut best = None;
        top.closest(node_test, ray, stack, |first, count, ray, stack| {
            for k in first..first + count {
                let inst = &self.instances[k as usize];
                let blas = &self.blases[inst.blas as usize];
                if inst.identity {
                    if let Some((slot, b1, b2)) = blas.closest(ray, stack) {
                        best = Some((k, slot, b1, b2));
                    }
                } else if let Some((mut local, dt)) = inst.local_ray(ray)
                    && let Some((slot, b1, b2)) = blas.closest(&mut local, stack)
                {
                    ray.tmax = ray.tmax.min(local.tmax + dt);
                    best = Some((k, slot, b1, b2));
                }
            }
        });
        best
    }

    /// Whether the scene has alpha-tested meshes, which queries test apart.
    #[inline(always)]
    pub fn has_alpha(&self) -> bool {
        self.alpha.is_some()
    }

    /// Whether anything in instances `first..first + count` (a top-level leaf) blocks `ray`.
    #[inline(always)]
    pub(super) fn instances_block(&self, first: u32, count: u32, ray: &Ray, stack: &mut Vec<(u32, f32)>) -> bool {
        let instances = &self.instances[first as usize..(first + count) as usize];
        instances.iter().any(|inst| self.instance_blocks(inst, ray, stack))
    }

    /// Whether anything in instance `inst` blocks `ray` (world space).
    #[inline(always)]
    pub(super) fn instance_blocks(&self, inst: &Instance, ray: &Ray, stack: &mut Vec<(u32, f32)>) -> bool {
        let blas = &self.blases[inst.blas as usize];
        if inst.identity {
            blas.occluded(ray, stack)
        } else {
            inst.local_ray(ray).is_some_and(|(local, _)| blas.occluded(&local, stack))
        }
    }
}

/// Occlusion through the top-level tree.
impl Occluder for SceneGeometry {
    #[inline(always)]
    fn occluded_in<const W: usize>(
        &self,
        top: &WideBvh<W>,
        node_test: impl NodeTest<W>,
        ray: &Ray,
        stack: &mut Vec<(u32, f32)>,
    ) -> bool {
        top.occluded(node_test, ray, stack, |first, count, stack| self.instances_block(first, count, ray, stack))
    }
}

/// Closest hit through the top level: (instance, primitive slot, b1, b2).
pub(super) struct TopClosest<'a> {
    pub(super) scene: &'a SceneGeometry,
    pub(super) ray: &'a mut Ray,
    pub(super) stack: &'a mut Vec<(u32, f32)>,
}

impl TreeQuery for TopClosest<'_> {
    type Output = Option<ClosestHit>;
    #[inline(always)]
    fn run<const W: usize>(self, tree: &WideBvh<W>, node_test: impl NodeTest<W>) -> Self::Output {
        self.scene.closest_through(tree, node_test, self.ray, self.stack)
    }
}

/// The object and mesh triangle of a hit of primitive `slot` of `blas` placed by `inst`: a mesh
/// instance's primitives hold their triangle's index in the mesh; a world-space BLAS's hold
/// their object's, and a bake of textured meshes keeps the triangles apart.
#[inline(always)]
pub(super) fn hit_ids(inst: &Instance, blas: &Blas, slot: u32) -> (u32, u32) {
    let prim = blas.object(slot);
    match inst.object {
        Some(object) => (object, prim),
        None => (prim, blas.source_triangles.as_ref().map_or(u32::MAX, |t| t[slot as usize])),
    }
}

/// Where a ray ends, in 20 bytes: the closest opaque primitive it meets (instance, slot and
/// barycentrics) and its distance, or only the ray's own end where it meets none. Planes are
/// not in it: [`SceneGeometry::hit_at_into`] tests them again (a scene has a few).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayEnd {
    /// The instance hit; [`RayEnd::NO_PRIMITIVE`] where none is, [`RayEnd::UNKNOWN`]'s where
    /// the end is not known.
    instance: u32,
    slot: u32,
    bary: [f32; 2],
    tmax: f32,
}

impl RayEnd {
    /// An end not yet found (what a cache of ends holds before it is filled).
    pub const UNKNOWN: RayEnd = RayEnd { instance: u32::MAX - 1, slot: 0, bary: [0.0; 2], tmax: 0.0 };

    const NO_PRIMITIVE: u32 = u32::MAX;

    #[inline(always)]
    pub(super) fn new(best: Option<ClosestHit>, tmax: f32) -> Self {
        match best {
            Some((instance, slot, b1, b2)) => RayEnd { instance, slot, bary: [b1, b2], tmax },
            None => RayEnd { instance: Self::NO_PRIMITIVE, slot: 0, bary: [0.0; 2], tmax },
        }
    }

    /// Whether the end was found (not [`RayEnd::UNKNOWN`]).
    #[inline(always)]
    pub fn is_known(&self) -> bool {
        self.instance != Self::UNKNOWN.instance
    }

    #[inline(always)]
    fn closest(&self) -> Option<ClosestHit> {
        (self.instance != Self::NO_PRIMITIVE).then_some((self.instance, self.slot, self.bary[0], self.bary[1]))
    }
}

impl Default for RayEnd {
    fn default() -> Self {
        Self::UNKNOWN
    }
}
