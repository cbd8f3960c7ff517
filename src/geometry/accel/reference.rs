//! The brute-force reference queries tests check traversal against.

use super::{Prim, hit_prim, scene::SceneGeometry};
use crate::geometry::{
    hit::SurfaceHit,
    ray::{Ray, Shear},
};

impl SceneGeometry {
    /// Intersects one world-space primitive: (t, b1, b2).
    #[inline(always)]
    pub fn hit_prim(prim: &Prim, ray: &Ray) -> Option<(f32, f32, f32)> {
        hit_prim(prim, ray, &Shear::new(ray.dir))
    }

    /// Closest hit by testing every primitive of every instance (for tests and validation).
    pub fn intersect_brute_force(&self, ray: &Ray) -> Option<SurfaceHit> {
        let mut ray = *ray;
        let mut best = None;
        for (i, inst) in self.instances.iter().enumerate() {
            let blas = &self.blases[inst.blas as usize];
            let (mut local, dt) = if inst.identity {
                (ray, 0.0)
            } else {
                match inst.local_ray(&ray) {
                    Some(local) => local,
                    None => continue,
                }
            };
            let shear = Shear::new(local.dir);
            for (slot, prim) in blas.slotted() {
                if let Some((t, b1, b2)) = hit_prim(&prim, &local, &shear) {
                    local.tmax = t;
                    ray.tmax = t + dt;
                    best = Some((i as u32, slot, b1, b2));
                }
            }
        }
        let mut plane_hit = None;
        for plane in &self.planes {
            if let Some(t) = plane.intersect(&ray) {
                ray.tmax = t;
                plane_hit = Some(plane.surface(&ray, t));
            }
        }
        plane_hit.or_else(|| best.map(|(i, slot, b1, b2)| self.surface(i, slot, &ray, b1, b2)))
    }
}
