//! What varies over a mesh's surface: per-vertex texture coordinates and colours, a base-colour
//! texture that modulates the [`Matte`](crate::components::Matte) colour, and alpha (glTF's
//! `alphaMode`) that lets rays pass through cut-out or translucent parts.
//!
//! A [`Surface`] is an optional component beside a `TriangleMesh`: meshes without one carry no
//! attributes and are traced and shaded exactly as before. The renderer reads a surface once
//! per camera hit (the colour) and, for alpha-tested meshes, at each candidate hit of any ray
//! (the alpha).

pub mod texture;

use std::sync::Arc;

use bevy_ecs::prelude::Component;
use glam::{Vec2, Vec4};

pub use texture::{Filter, Sampler, Texture, TextureTransform, Wrap};

use crate::{
    components::Mesh,
    random::{mix64, unit_f32},
};

/// Per-vertex attributes of a mesh, indexed like its `positions`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SurfaceAttributes {
    /// Texture coordinate sets (`TEXCOORD_0`, `TEXCOORD_1`, …).
    pub tex_coords: Vec<Vec<Vec2>>,
    /// Vertex colours (`COLOR_0`): linear RGB and alpha, multiplying the base colour.
    pub colors: Option<Vec<Vec4>>,
}

/// A base-colour texture as a surface uses it.
#[derive(Clone, Debug)]
pub struct BaseColorTexture {
    /// The image and its sampler.
    pub texture: Arc<Texture>,
    /// Which of [`SurfaceAttributes::tex_coords`] it reads.
    pub tex_coord: usize,
    /// Where those coordinates land on the image.
    pub transform: TextureTransform,
}

/// How a surface's alpha affects rays (glTF's `alphaMode`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum AlphaMode {
    /// Alpha is ignored: the surface blocks every ray.
    #[default]
    Opaque,
    /// Rays pass where alpha is below `cutoff` and are blocked elsewhere.
    Mask {
        /// glTF's `alphaCutoff` (0.5 by default).
        cutoff: f32,
    },
    /// Rays pass with probability 1 − alpha, decided per ray and triangle by a hash, so that
    /// images stay the same at any thread count.
    Blend,
}

/// The varying surface of a `TriangleMesh` entity. Its colour is the entity's `Matte::cd` ×
/// the texture's colour × the vertex colour; its alpha is [`Surface::alpha`] × the texture's
/// alpha × the vertex alpha, used as [`Surface::alpha_mode`] says.
#[derive(Component, Clone, Debug)]
pub struct Surface {
    /// Per-vertex attributes (shared by the entities that share the mesh).
    pub attributes: Arc<SurfaceAttributes>,
    /// The base-colour texture, if any.
    pub base_color: Option<BaseColorTexture>,
    /// Alpha factor (glTF's `baseColorFactor` alpha).
    pub alpha: f32,
    /// How alpha affects rays.
    pub alpha_mode: AlphaMode,
}

impl Default for Surface {
    fn default() -> Self {
        Surface { attributes: Arc::default(), base_color: None, alpha: 1.0, alpha_mode: AlphaMode::Opaque }
    }
}

/// Equal when they share the same attributes and image (by pointer: comparing texels every
/// frame would cost more than a rebuild) and the same factors.
impl PartialEq for Surface {
    fn eq(&self, other: &Self) -> bool {
        let same_texture = match (&self.base_color, &other.base_color) {
            (None, None) => true,
            (Some(a), Some(b)) => {
                Arc::ptr_eq(&a.texture, &b.texture) && a.tex_coord == b.tex_coord && a.transform == b.transform
            }
            _ => false,
        };
        Arc::ptr_eq(&self.attributes, &other.attributes)
            && same_texture
            && self.alpha.to_bits() == other.alpha.to_bits()
            && self.alpha_mode == other.alpha_mode
    }
}

impl Surface {
    /// Whether rays may pass through parts of it.
    pub fn alpha_tested(&self) -> bool {
        self.alpha_mode != AlphaMode::Opaque
    }

    /// First problem that makes this surface unusable on `mesh`: attributes whose count is not
    /// the vertex count, a texture reading a coordinate set that is missing, a non-finite
    /// attribute or factor.
    pub fn validate(&self, mesh: &Mesh) -> Result<(), String> {
        let n = mesh.positions.len();
        let a = &self.attributes;
        for (k, set) in a.tex_coords.iter().enumerate() {
            if set.len() != n {
                return Err(format!("texture coordinate set {k} has {} entries for {n} vertices", set.len()));
            }
            if let Some(i) = set.iter().position(|uv| !uv.is_finite()) {
                return Err(format!("texture coordinate set {k}: vertex {i} has a non-finite value {}", set[i]));
            }
        }
        if let Some(colors) = &a.colors {
            if colors.len() != n {
                return Err(format!("{} vertex colours for {n} vertices", colors.len()));
            }
            if let Some(i) = colors.iter().position(|c| !c.is_finite()) {
                return Err(format!("vertex {i} has a non-finite colour {}", colors[i]));
            }
        }
        if let Some(t) = &self.base_color
            && t.tex_coord >= a.tex_coords.len()
        {
            return Err(format!(
                "the base-colour texture reads texture coordinate set {}, which is missing",
                t.tex_coord
            ));
        }
        let cutoff_ok = match self.alpha_mode {
            AlphaMode::Mask { cutoff } => cutoff.is_finite(),
            _ => true,
        };
        if !(self.alpha.is_finite() && cutoff_ok) {
            return Err(format!("alpha {} or its mode {:?} is not finite", self.alpha, self.alpha_mode));
        }
        Ok(())
    }

    /// Colour multiplier (RGB, before `Matte::cd`) and alpha at barycentrics (b1, b2) of
    /// triangle `tri` of `mesh` (b1 weighs its second vertex, b2 its third).
    pub fn at(&self, mesh: &Mesh, tri: u32, b1: f32, b2: f32) -> Vec4 {
        let mut c = Vec4::new(1.0, 1.0, 1.0, self.alpha);
        let Some(&[i0, i1, i2]) = mesh.indices.get(tri as usize) else { return c };
        let (i0, i1, i2) = (i0 as usize, i1 as usize, i2 as usize);
        let b0 = 1.0 - b1 - b2;
        let a = &self.attributes;
        if let Some(colors) = &a.colors
            && let (Some(c0), Some(c1), Some(c2)) = (colors.get(i0), colors.get(i1), colors.get(i2))
        {
            c *= *c0 * b0 + *c1 * b1 + *c2 * b2;
        }
        if let Some(t) = &self.base_color
            && let Some(uvs) = a.tex_coords.get(t.tex_coord)
            && let (Some(u0), Some(u1), Some(u2)) = (uvs.get(i0), uvs.get(i1), uvs.get(i2))
        {
            let uv = *u0 * b0 + *u1 * b1 + *u2 * b2;
            c *= t.texture.sample(t.transform.apply(uv));
        }
        c
    }

    /// Whether a ray identified by `ray_key` passes through triangle `tri` of `mesh` at
    /// barycentrics (b1, b2): never for an opaque surface; where alpha is below the cutoff for
    /// a mask; with probability 1 − alpha for a blended one, by a hash of `ray_key` and `tri`.
    pub fn passes(&self, mesh: &Mesh, tri: u32, b1: f32, b2: f32, ray_key: u64) -> bool {
        match self.alpha_mode {
            AlphaMode::Opaque => false,
            AlphaMode::Mask { cutoff } => self.at(mesh, tri, b1, b2).w < cutoff,
            AlphaMode::Blend => {
                let alpha = self.at(mesh, tri, b1, b2).w;
                let key = ray_key ^ u64::from(tri).wrapping_mul(0x9e37_79b9_7f4a_7c15);
                unit_f32((mix64(key) >> 32) as u32) >= alpha
            }
        }
    }
}

/// A surface with the mesh whose vertices its attributes follow, as the renderer holds it for
/// one scene object.
#[derive(Clone, Debug)]
pub struct PlacedSurface {
    /// The entity's surface.
    pub surface: Surface,
    /// The entity's mesh (its triangles say which vertices a hit interpolates).
    pub mesh: Arc<Mesh>,
}

impl PlacedSurface {
    /// [`Surface::at`] on this mesh.
    #[inline]
    pub fn at(&self, tri: u32, b1: f32, b2: f32) -> Vec4 {
        self.surface.at(&self.mesh, tri, b1, b2)
    }

    /// [`Surface::passes`] on this mesh.
    #[inline]
    pub fn passes(&self, tri: u32, b1: f32, b2: f32, ray_key: u64) -> bool {
        self.surface.passes(&self.mesh, tri, b1, b2, ray_key)
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;

    fn triangle() -> Mesh {
        Mesh { positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y], indices: vec![[0, 1, 2]] }
    }

    #[test]
    fn vertex_colours_interpolate_by_barycentrics_and_multiply_the_factor() {
        let colors = vec![Vec4::new(1.0, 0.0, 0.0, 1.0), Vec4::new(0.0, 1.0, 0.0, 0.5), Vec4::new(0.0, 0.0, 1.0, 0.0)];
        let attributes = Arc::new(SurfaceAttributes { tex_coords: vec![], colors: Some(colors) });
        let s = Surface { attributes, alpha: 0.8, ..Default::default() };
        let c = s.at(&triangle(), 0, 0.25, 0.5);
        // b0 = 0.25: (0.25, 0.25, 0.5) and alpha 0.8 × (0.25 + 0.125 + 0).
        assert!((c - Vec4::new(0.25, 0.25, 0.5, 0.8 * 0.375)).abs().max_element() < 1e-6, "{c}");
    }

    #[test]
    fn blend_passes_about_one_minus_alpha_of_rays_and_mask_by_cutoff() {
        let mesh = triangle();
        let s = Surface { alpha: 0.3, alpha_mode: AlphaMode::Blend, ..Default::default() };
        let n = 20_000;
        let passed = (0..n).filter(|&k| s.passes(&mesh, 0, 0.2, 0.2, k)).count() as f64 / n as f64;
        // 1 − α = 0.7; the binomial standard error is 0.0032.
        assert!((passed - 0.7).abs() < 0.02, "{passed}");
        assert_eq!(s.passes(&mesh, 0, 0.2, 0.2, 5), s.passes(&mesh, 0, 0.2, 0.2, 5));
        let mask = |cutoff| Surface { alpha: 0.3, alpha_mode: AlphaMode::Mask { cutoff }, ..Default::default() };
        assert!(mask(0.5).passes(&mesh, 0, 0.2, 0.2, 1));
        assert!(!mask(0.3).passes(&mesh, 0, 0.2, 0.2, 1));
        let opaque = Surface { alpha: 0.0, ..Default::default() };
        assert!(!opaque.passes(&mesh, 0, 0.2, 0.2, 1));
    }
}
