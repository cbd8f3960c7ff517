//! Surfaces: alpha cut-outs and blends that rays pass through (camera, AO), textured and
//! vertex-coloured base colours, against equivalent scenes and hand-computed values.

mod common;

use std::sync::Arc;

use common::{occluder, settings, white};
use hemi::{
    glam::Vec4,
    material::{AlphaMode, Filter, Sampler, Surface, SurfaceAttributes, Texture, Wrap},
    prelude::*,
    resources::Aov,
};

/// A camera straight above the origin looking down at the floor.
fn camera_above(height: f32) -> Camera {
    Camera { eye: Vec3::new(0.0, height, 0.0), target: Vec3::ZERO, up: Vec3::Z, vfov_degrees: 60.0 }
}

/// A horizontal quad at height `y` over x, z in [x0, x1] × [z0, z1], texture coordinates
/// running from (0, 0) at (x0, z0) to (1, 1) at (x1, z1).
fn quad(y: f32, (x0, x1): (f32, f32), (z0, z1): (f32, f32)) -> (Arc<Mesh>, Vec<Vec2>) {
    let positions = vec![Vec3::new(x0, y, z0), Vec3::new(x1, y, z0), Vec3::new(x1, y, z1), Vec3::new(x0, y, z1)];
    let mesh = Mesh { positions, indices: vec![[0, 1, 2], [0, 2, 3]] };
    (Arc::new(mesh), vec![Vec2::new(0.0, 0.0), Vec2::new(1.0, 0.0), Vec2::new(1.0, 1.0), Vec2::new(0.0, 1.0)])
}

/// A nearest-filtered, clamped texture of `w` × `h` texels in rows.
fn texture(w: u32, h: u32, texels: Vec<[u8; 4]>) -> Arc<Texture> {
    let sampler = Sampler { wrap_u: Wrap::ClampToEdge, wrap_v: Wrap::ClampToEdge, filter: Filter::Nearest };
    Arc::new(Texture::new(w, h, texels, sampler).unwrap())
}

/// A surface whose base colour reads `texture` through `uvs`, alpha used as `mode`.
fn textured(uvs: Vec<Vec2>, texture: Arc<Texture>, mode: AlphaMode) -> Surface {
    Surface {
        attributes: Arc::new(SurfaceAttributes { tex_coords: vec![uvs], colors: None }),
        base_color: Some(hemi::material::BaseColorTexture { texture, tex_coord: 0, transform: Default::default() }),
        alpha: 1.0,
        alpha_mode: mode,
    }
}

const MASK: AlphaMode = AlphaMode::Mask { cutoff: 0.5 };

/// Renders a white floor (y = 0) under an occluder with floor 0 (pixel = AO) plus what
/// `spawn` adds, seen from `height` above the origin, at `threads` threads.
fn render(height: f32, spp: u32, threads: usize, spawn: impl Fn(&mut World)) -> Renderer {
    let mut s = settings(24, 24, spp, SamplerKind::CorrelatedMultiJittered);
    s.aovs = true;
    let mut r = Renderer::new(s).with_threads(threads).unwrap();
    let world = r.world_mut();
    world.spawn(camera_above(height));
    world.spawn(occluder(0.0));
    world.spawn((Plane::default(), Transform::default(), white()));
    spawn(world);
    r.run_frame().expect("valid scene");
    r
}

fn mean(r: &Renderer) -> f64 {
    let img = &r.image().linear;
    img.iter().map(|p| p.x as f64).sum::<f64>() / img.len() as f64
}

/// Seen from above, a quad with checkerboard alpha over the floor gives what a quad of only
/// its opaque squares gives: the camera sees the floor through the cut-out squares and the
/// floor's AO rays pass through them.
#[test]
fn a_checkerboard_alpha_quad_occludes_like_its_opaque_squares_alone() {
    let (mesh, uvs) = quad(0.2, (-1.0, 1.0), (-1.0, 1.0));
    let (o, c) = ([255, 255, 255, 255], [255, 255, 255, 0]);
    let board = texture(2, 2, vec![o, c, c, o]);
    let checker = render(3.0, 16, 2, |w| {
        w.spawn((TriangleMesh(mesh.clone()), white(), textured(uvs.clone(), board.clone(), MASK)));
    });
    let squares = render(3.0, 16, 2, |w| {
        w.spawn((TriangleMesh(quad(0.2, (-1.0, 0.0), (-1.0, 0.0)).0), white()));
        w.spawn((TriangleMesh(quad(0.2, (0.0, 1.0), (0.0, 1.0)).0), white()));
    });
    // The same rays are blocked; only the order in which a pixel's samples are summed may
    // differ (the alpha scene has no tree for the AO packets), which moves the last bits.
    let (a, b) = (checker.image().aov(Aov::Ao).unwrap(), squares.image().aov(Aov::Ao).unwrap());
    let worst = a.iter().zip(&b).map(|(p, q)| (*p - *q).abs().max_element()).fold(0.0, f32::max);
    assert!(worst < 1e-5, "pixels differ by up to {worst}");
    // Through the clear squares (2 × 8 × 8 pixels) the camera sees the occluded floor where a
    // solid quad shows its own top, AO 1: the comparison can tell.
    let solid = render(3.0, 16, 2, |w| {
        w.spawn((TriangleMesh(mesh.clone()), white()));
    });
    let solid = solid.image().aov(Aov::Ao).unwrap();
    let seen_through = a.iter().zip(&solid).filter(|(p, q)| q.x == 1.0 && p.x < 1.0).count();
    assert!(seen_through >= 64, "{seen_through} pixels");
    // The alpha path was taken and cut hits out; the opaque scene never enters it.
    let a = checker.stats().alpha;
    assert!(a.rays > 0 && a.cut > 0 && a.cut < a.candidates, "{a:?}");
    assert_eq!(squares.stats().alpha.rays, 0);
}

#[test]
fn a_fully_cut_out_occluder_leaves_the_open_planes_ao_of_exactly_one() {
    let (mesh, _) = quad(0.2, (-1.0, 1.0), (-1.0, 1.0));
    let cut = Surface { alpha: 0.0, alpha_mode: MASK, ..Default::default() };
    // The camera below the quad sees only the floor under it.
    let r = render(0.1, 16, 2, |w| {
        w.spawn((TriangleMesh(mesh.clone()), white(), cut.clone()));
    });
    assert!(r.image().linear.iter().all(|p| *p == Vec3::ONE), "every pixel is exactly 1");
    let opaque = render(0.1, 16, 2, |w| {
        w.spawn((TriangleMesh(mesh.clone()), white()));
    });
    assert!(opaque.image().linear.iter().all(|p| p.x < 0.9));
}

/// Camera rays pass through cut-out texels: under a quad whose left half is cut out, the
/// albedo AOV shows the floor's colour there and the texture × `cd` elsewhere.
#[test]
fn camera_rays_pass_through_cut_out_texels_to_the_floor_behind() {
    let mut s = settings(20, 20, 1, SamplerKind::CorrelatedMultiJittered);
    (s.aovs, s.jitter) = (true, false);
    let mut r = Renderer::new(s);
    let world = r.world_mut();
    world.spawn(camera_above(3.0));
    world.spawn(occluder(0.0));
    world.spawn((Plane::default(), Transform::default(), Matte::new(Vec3::new(0.0, 1.0, 0.0))));
    let (mesh, uvs) = quad(0.5, (-10.0, 10.0), (-10.0, 10.0));
    let halves = texture(2, 1, vec![[255, 255, 255, 0], [255, 0, 0, 255]]);
    world.spawn((TriangleMesh(mesh), Matte::new(Vec3::splat(0.5)), textured(uvs, halves, MASK)));
    r.run_frame().unwrap();
    let albedo = r.image().aov(Aov::Albedo).unwrap();
    let (floor, red) = (Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.5, 0.0, 0.0));
    let n_floor = albedo.iter().filter(|&&a| a == floor).count();
    let n_red = albedo.iter().filter(|&&a| a == red).count();
    assert_eq!(n_floor + n_red, albedo.len(), "every pixel is the floor or the texture");
    assert_eq!(n_floor, n_red, "the texel boundary x = 0 splits the view in half");
    // Each row: one half of the floor, the other half of the texture.
    for row in albedo.chunks(20) {
        let left_floor = row[0] == floor;
        assert!(row[..10].iter().all(|&a| (a == floor) == left_floor), "{row:?}");
        assert!(row[10..].iter().all(|&a| (a == floor) != left_floor), "{row:?}");
    }
}

/// BLEND at α = 0.5: each AO ray through the quad passes with probability one half, so the
/// mean AO lies halfway between the open floor's and the opaque quad's (to within the noise),
/// and the decision is a hash of the ray: the same image at 1 and 2 threads.
#[test]
fn a_half_transparent_blend_halves_the_occlusion_and_is_deterministic() {
    let (mesh, _) = quad(0.2, (-3.0, 3.0), (-3.0, 3.0));
    let blend = Surface { alpha: 0.5, alpha_mode: AlphaMode::Blend, ..Default::default() };
    let spawn_blend = |w: &mut World| {
        w.spawn((TriangleMesh(mesh.clone()), white(), blend.clone()));
    };
    // The camera below the quad sees only the floor, whose AO rays meet the quad.
    let one = render(0.1, 64, 1, spawn_blend);
    let two = render(0.1, 64, 2, spawn_blend);
    assert_eq!(one.image().linear, two.image().linear);
    let opaque = mean(&render(0.1, 64, 2, |w| {
        w.spawn((TriangleMesh(mesh.clone()), white()));
    }));
    let expected = 0.5 * (1.0 + opaque);
    // 24 × 24 pixels × 64 samples of a 0/1 visibility: the standard error of the mean is
    // at most 0.5 / √36864 = 0.0026.
    let got = mean(&one);
    assert!(opaque < 0.7, "the quad occludes: {opaque}");
    assert!((got - expected).abs() < 0.013, "blend {got}, expected {expected} (opaque {opaque})");
}

/// The albedo AOV shows the textured colour: `cd` × texture × vertex colour at the hit.
#[test]
fn vertex_colours_and_texture_multiply_the_matte_colour() {
    let mut s = settings(8, 8, 1, SamplerKind::CorrelatedMultiJittered);
    (s.aovs, s.jitter) = (true, false);
    let mut r = Renderer::new(s);
    let world = r.world_mut();
    world.spawn(camera_above(3.0));
    world.spawn(occluder(0.0));
    let (mesh, uvs) = quad(0.5, (-10.0, 10.0), (-10.0, 10.0));
    // sRGB 188 is linear 0.50289; the vertex colours are all (0.5, 1, 0.25).
    let grey = texture(1, 1, vec![[188, 188, 188, 255]]);
    let mut surface = textured(uvs, grey, AlphaMode::Opaque);
    let colors = Some(vec![Vec4::new(0.5, 1.0, 0.25, 1.0); 4]);
    surface.attributes = Arc::new(SurfaceAttributes { colors, ..(*surface.attributes).clone() });
    world.spawn((TriangleMesh(mesh), Matte::new(Vec3::new(1.0, 0.5, 1.0)), surface));
    r.run_frame().unwrap();
    let expected = Vec3::new(0.5, 0.5, 0.25) * 0.502_886;
    for a in r.image().aov(Aov::Albedo).unwrap() {
        assert!((a - expected).abs().max_element() < 1e-4, "{a} vs {expected}");
    }
}
