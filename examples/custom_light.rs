//! A light type defined entirely outside hemi: a sky dome whose radiance fades from a warm
//! horizon to a deep blue zenith. It is registered with one call and lights the built-in
//! scene in place of the ambient occluder.
//!
//! ```sh
//! cargo run --release --example custom_light -- custom_light.png
//! ```

use std::f32::consts::PI;

use hemi::{HemiError, prelude::*, sampling::warp::cosine_power_hemisphere};

/// The component users spawn: a dome of sky light around the whole scene. Its "up" is the
/// entity's local +Y (the identity transform when it has none).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
struct GradientDome {
    /// Radiance at the horizon (linear RGB).
    horizon: Vec3,
    /// Radiance straight up.
    zenith: Vec3,
}

/// The dome resolved for a frame: what the tracer samples at every shading point.
struct PlacedDome {
    horizon: Vec3,
    zenith: Vec3,
    up: Vec3,
}

impl Light for GradientDome {
    type Placed = PlacedDome;
    const NAME: &'static str = "gradient dome";

    /// Refused values stop the frame with this one-line message.
    fn validate(&self, transform: &Transform) -> Result<(), String> {
        let ok = |c: Vec3| c.is_finite() && c.min_element() >= 0.0;
        if !(ok(self.horizon) && ok(self.zenith)) {
            return Err(format!(
                "gradient dome colours {} / {} must be finite, non-negative",
                self.horizon, self.zenith
            ));
        }
        if !(transform.rotation * Vec3::Y).is_finite() {
            return Err("gradient dome rotation is not finite".into());
        }
        Ok(())
    }

    /// Runs once per change, not per sample: precompute here. `None` skips a black dome.
    fn place(&self, transform: &Transform) -> Option<PlacedDome> {
        let up = (transform.rotation * Vec3::Y).normalize_or(Vec3::Y);
        (self.horizon.max(self.zenith).max_element() > 0.0).then_some(PlacedDome {
            horizon: self.horizon,
            zenith: self.zenith,
            up,
        })
    }
}

impl PlacedLight for PlacedDome {
    // One 2-D sample per shading point (the default), feeding the diffuse term kd·cd/π.
    const DIMS: u32 = 1;
    const TERM: Term = Term::Diffuse;

    /// One cosine-distributed direction w: the irradiance estimate is L(w)·cos θ / pdf = π·L(w),
    /// seen only if the shadow ray towards w escapes the scene.
    fn sample(&self, at: &ShadingPoint, u: &LightSamples) -> Option<LightSample> {
        let s = cosine_power_hemisphere(u.get(0), 1.0);
        let dir = at.frame().to_world(s.dir);
        let t = dir.dot(self.up).max(0.0).sqrt();
        let radiance = self.horizon.lerp(self.zenith, t);
        if radiance.max_element() <= 0.0 {
            return None; // nothing to see: no shadow ray
        }
        Some(LightSample {
            unoccluded: radiance * PI,
            occluded: Vec3::ZERO,
            shadow: Some(Shadow::Along { dir: dir.into(), max_distance: f32::INFINITY }),
        })
    }
}

fn main() -> Result<(), HemiError> {
    let out = std::env::args().nth(1).unwrap_or_else(|| "custom_light.png".into());
    let settings =
        RenderSettings { width: 640, height: 360, samples_per_frame: 8, samples_per_set: 64, ..Default::default() };
    let mut renderer = Renderer::with_default_scene(settings);
    renderer.add_light::<GradientDome>(); // the one line that plugs the light in

    // Swap the built-in scene's ambient occluder for the dome.
    let world = renderer.world_mut();
    let occluders: Vec<Entity> = world.query_filtered::<Entity, With<AmbientOccluder>>().iter(world).collect();
    for e in occluders {
        world.despawn(e);
    }
    world.spawn(GradientDome { horizon: Vec3::new(0.75, 0.6, 0.45), zenith: Vec3::new(0.25, 0.4, 0.8) });

    renderer.render(64)?;
    renderer.save(out.as_ref())?;
    let stats = renderer.stats();
    println!("wrote {out}: 64 spp; last frame {} shadow rays; {}", stats.rays.shadow, trace_note(stats));
    Ok(())
}

/// The trace system's note, which lists the lights by name.
fn trace_note(stats: &FrameStats) -> &str {
    stats.systems.iter().find(|s| s.name == "trace").map_or("", |s| s.note.as_str())
}
