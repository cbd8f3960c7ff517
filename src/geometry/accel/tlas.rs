//! Instances: a BLAS placed in the world, which the top level is built over.

use glam::{Affine3A, Mat3A, Vec3A};
use obvhs::aabb::Aabb;

#[cfg(target_arch = "x86_64")]
use crate::geometry::lanes::RayLanes;
use crate::geometry::{hit::SurfaceHit, ray::Ray};
use crate::math::gamma;
#[cfg(target_arch = "x86_64")]
use crate::simd::{Lanes, dot3};

/// One placement of a BLAS in the world.
#[derive(Clone, Debug)]
pub struct Instance {
    /// Index into the scene's BLAS list.
    pub blas: u32,
    /// The object every primitive of this instance belongs to (`None`: each prim names its own).
    pub object: Option<u32>,
    pub(super) to_world: Affine3A,
    to_local: Affine3A,
    pub(super) identity: bool,
    translation_only: bool,
    pub(super) bounds: Aabb,
}

impl Instance {
    /// An instance of `blas` (whose bounds are `local`) placed by `to_world`, or `None` when
    /// the transform is singular or the placed bounds overflow.
    pub fn new(blas: u32, local: Aabb, to_world: Affine3A, object: Option<u32>) -> Option<Self> {
        let to_local = to_world.inverse();
        if !to_local.is_finite() {
            return None;
        }
        let mut bounds = Aabb::empty();
        for i in 0..8 {
            let corner = Vec3A::new(
                if i & 1 == 0 { local.min.x } else { local.max.x },
                if i & 2 == 0 { local.min.y } else { local.max.y },
                if i & 4 == 0 { local.min.z } else { local.max.z },
            );
            bounds.extend(to_world.transform_point3a(corner));
        }
        // Pad by the rounding of the corner transform so no true hit is culled.
        let pad = bounds.min.abs().max(bounds.max.abs()) * gamma(4);
        let bounds = Aabb::new(bounds.min - pad, bounds.max + pad);
        if !(bounds.min.is_finite() && bounds.max.is_finite()) {
            return None;
        }
        Some(Instance {
            blas,
            object,
            to_world,
            to_local,
            identity: to_world == Affine3A::IDENTITY,
            translation_only: to_world.matrix3 == Mat3A::IDENTITY,
            bounds,
        })
    }

    /// Placed bounds in world space.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The transform from the BLAS frame to world space.
    pub fn to_world(&self) -> Affine3A {
        self.to_world
    }

    /// The ray in the instance's frame and the parameter shift `dt` (world t = local t + dt):
    /// the origin is moved along the direction past its transform's rounding error (pbrt-v4).
    #[inline]
    pub(super) fn local_ray(&self, ray: &Ray) -> Option<(Ray, f32)> {
        let m = &self.to_local;
        if self.translation_only {
            // Same direction: only the origin moves, by one rounded subtraction.
            let o = ray.origin + m.translation;
            let o_err = (ray.origin.abs() + m.translation.abs()) * gamma(1);
            let len2 = ray.dir.length_squared();
            let dt = if len2 > 0.0 { ray.dir.abs().dot(o_err) / len2 } else { 0.0 };
            let tmax = ray.tmax - dt;
            return (tmax > 0.0).then(|| (Ray { origin: o + ray.dir * dt, tmax, ..*ray }, dt));
        }
        let o = m.transform_point3a(ray.origin);
        let d = m.matrix3 * ray.dir;
        let o_err = (abs_mat(&m.matrix3) * ray.origin.abs() + m.translation.abs()) * gamma(3);
        let len2 = d.length_squared();
        let dt = if len2 > 0.0 { d.abs().dot(o_err) / len2 } else { 0.0 };
        let tmax = ray.tmax - dt;
        (tmax > 0.0).then(|| (Ray::new(o + d * dt, d, tmax), dt))
    }

    /// [`Instance::local_ray`] of every lane of `world` at once, each lane's floats those of
    /// its ray's `local_ray` (the same operations in the same order), and the lanes of
    /// `entered` it gives a ray for: a packet enters the instance with one transform of its
    /// lanes, not one per ray followed by a gather of the moved rays into lanes.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub(super) fn local_lanes<L: Lanes>(&self, world: &RayLanes<L>, entered: u32) -> (RayLanes<L>, u32) {
        // (Loops, not closures: a closure is compiled without the caller's instruction set.)
        let isa = world.tmax.isa();
        let m = &self.to_local;
        let zero = L::splat(isa, 0.0);
        let mut local = *world;
        let mut o_err = [zero; 3];
        if self.translation_only {
            let moves = world.origin.iter().zip(m.translation.to_array());
            for ((origin, err), (&o, t)) in local.origin.iter_mut().zip(&mut o_err).zip(moves) {
                *origin = o.add(L::splat(isa, t));
                *err = o.abs().add(L::splat(isa, t.abs())).mul(L::splat(isa, gamma(1)));
            }
        } else {
            let cols = [m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis];
            let mut abs_o = world.origin;
            for x in &mut abs_o {
                *x = x.abs();
            }
            for a in 0..3 {
                let (mut row, mut abs_row) = ([zero; 3], [zero; 3]);
                for (c, col) in cols.iter().enumerate() {
                    row[c] = L::splat(isa, col[a]);
                    abs_row[c] = L::splat(isa, col[a].abs());
                }
                let t = m.translation[a];
                local.origin[a] = dot3(&row, &world.origin).add(L::splat(isa, t));
                local.dir[a] = dot3(&row, &world.dir);
                o_err[a] = dot3(&abs_row, &abs_o).add(L::splat(isa, t.abs())).mul(L::splat(isa, gamma(3)));
                local.inv_dir[a] = L::splat(isa, 1.0).div(local.dir[a]);
            }
        }
        let d = local.dir;
        let len2 = dot3(&d, &d);
        let dt = zero.select(len2.gt(zero), dot3(&[d[0].abs(), d[1].abs(), d[2].abs()], &o_err).div(len2));
        local.tmax = world.tmax.sub(dt);
        for (origin, d) in local.origin.iter_mut().zip(d) {
            *origin = origin.add(d.mul(dt));
        }
        let live = L::bits(local.tmax.gt(zero)) & entered;
        (local, live)
    }

    /// A hit found in the instance's frame, moved to world space with its error bound grown by
    /// the transform's rounding (pbrt-v4's `Transform::operator()(Point3fi)`).
    #[inline]
    pub(super) fn to_world_hit(&self, hit: SurfaceHit, dt: f32) -> SurfaceHit {
        let m = &self.to_world;
        let abs = abs_mat(&m.matrix3);
        let p = m.transform_point3a(hit.p);
        let p_error = (abs * hit.p_error) * (1.0 + gamma(3)) + (abs * hit.p.abs() + m.translation.abs()) * gamma(3);
        // Normals go by the inverse transpose; it keeps the side the ray came from.
        let normal = (self.to_local.matrix3.transpose() * hit.normal).normalize();
        SurfaceHit { t: hit.t + dt, p, p_error, normal, ..hit }
    }
}

#[inline(always)]
fn abs_mat(m: &Mat3A) -> Mat3A {
    Mat3A::from_cols(m.x_axis.abs(), m.y_axis.abs(), m.z_axis.abs())
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use glam::{Quat, Vec3};

    use super::*;
    use crate::geometry::lanes::PacketLanes;
    use crate::random::SplitMix64;
    use crate::simd::{Avx, Avx512, both_widths};

    /// A packet's lanes moved into an instance's frame are, lane for lane, the floats of each
    /// ray's own [`Instance::local_ray`] (and the lanes it gives no ray for are not live):
    /// for a translation, a translation with a uniform scale, and a rotation with an uneven
    /// scale; directions with zero and negative-zero components and segments too short to
    /// survive the origin's shift included.
    #[test]
    fn lanes_enter_an_instance_as_each_ray_does() {
        both_widths(local_lanes_are_local_rays::<Avx>, local_lanes_are_local_rays::<Avx512>);
    }

    fn local_lanes_are_local_rays<L: PacketLanes>(isa: L::Isa) {
        let mut rng = SplitMix64::new(42);
        let mut f = move |scale: f32| (rng.next_f32() * 2.0 - 1.0) * scale;
        let placements = [
            Affine3A::from_translation(Vec3::new(3.5, -1.25, 7.0)),
            Affine3A::from_scale_rotation_translation(Vec3::splat(0.17), Quat::IDENTITY, Vec3::new(-5.2, 0.18, 6.0)),
            Affine3A::from_scale_rotation_translation(
                Vec3::new(0.5, 2.0, 1.3),
                Quat::from_euler(glam::EulerRot::XYZ, 0.3, -1.1, 2.0),
                Vec3::new(100.0, -20.0, 0.5),
            ),
        ];
        let bounds = Aabb::new(Vec3A::splat(-1.0), Vec3A::splat(1.0));
        let bits = |v: Vec3A| v.to_array().map(f32::to_bits);
        for (p, &to_world) in placements.iter().enumerate() {
            let inst = Instance::new(0, bounds, to_world, None).expect("an invertible placement");
            for round in 0..20 {
                let rays: Vec<Ray> = (0..L::WIDTH)
                    .map(|k| {
                        let mut dir = Vec3A::new(f(1.0), f(1.0), f(1.0));
                        // Zero components of either sign, on some axis of some lanes.
                        if k % 5 == 1 {
                            dir[k % 3] = if k % 2 == 0 { 0.0 } else { -0.0 };
                        }
                        // Some segments end before the origin's shift: no local ray.
                        let tmax = if k % 7 == 3 { 1e-9 } else { f(10.0).abs() + 0.1 };
                        Ray::new(Vec3A::new(f(50.0), f(50.0), f(50.0)), dir, tmax)
                    })
                    .collect();
                let entered = if round % 2 == 0 { u32::MAX >> (32 - L::WIDTH) } else { 0b1011_0110_1101 };
                let (local, live) = inst.local_lanes(&L::rays(isa, &rays), entered);
                for (k, ray) in rays.iter().enumerate() {
                    let want = inst.local_ray(ray).filter(|_| entered & (1 << k) != 0);
                    assert_eq!(live & (1 << k) != 0, want.is_some(), "placement {p}, lane {k}");
                    if let Some((want, _)) = want {
                        let got = local.ray(k);
                        assert_eq!(bits(got.origin), bits(want.origin), "placement {p}, lane {k}: origin");
                        assert_eq!(bits(got.dir), bits(want.dir), "placement {p}, lane {k}: dir");
                        assert_eq!(bits(got.inv_dir), bits(want.inv_dir), "placement {p}, lane {k}: inv_dir");
                        assert_eq!(got.tmax.to_bits(), want.tmax.to_bits(), "placement {p}, lane {k}: tmax");
                    }
                }
            }
        }
    }
}
