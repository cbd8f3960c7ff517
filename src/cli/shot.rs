//! The options `hemi render` and `hemi view` share: which scene, the camera to see it from, a
//! ground under it, the background, and the look of 8-bit output.

use std::path::PathBuf;

use glam::Vec3;

use crate::{
    components::Camera,
    error::HemiError,
    look::{Look, Tonemap},
    sampling::SamplerKind,
    scene::staging,
};

/// The scene and how it is staged.
#[derive(clap::Args, Debug, Clone)]
pub struct SceneArgs {
    /// A .gltf/.glb scene, or a peer scene .json (default: the built-in scene).
    pub scene: Option<PathBuf>,
    /// The glTF camera, by name or index (default: the scene's first camera, or one that
    /// frames the whole scene when it has none).
    #[arg(long, conflicts_with = "look_from")]
    pub camera: Option<String>,
    /// The glTF animations that play together: `all`, or names and indices separated by
    /// commas (default: all when no two animate the same node, else the first).
    #[arg(long)]
    pub animation: Option<String>,
    /// Camera position X,Y,Z: replaces the scene's camera (or supplies one), with --look-at.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, requires = "look_at", allow_hyphen_values = true)]
    pub look_from: Option<Vec3>,
    /// The point the --look-from camera looks at, X,Y,Z.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, requires = "look_from", allow_hyphen_values = true)]
    pub look_at: Option<Vec3>,
    /// Up direction of the --look-from camera.
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_vec3, requires = "look_from", allow_hyphen_values = true, default_value = "0,1,0")]
    pub up: Vec3,
    /// Vertical field of view of the --look-from camera, in degrees.
    #[arg(long, value_name = "DEG", requires = "look_from", default_value_t = 40.0, value_parser = parse_fov)]
    pub fov: f32,
    /// Add a grey ground plane just under the scene's objects (as placed at the first
    /// rendered time), so that an isolated model gets its contact shadows.
    #[arg(long)]
    pub ground: bool,
    /// Radiance of rays that hit nothing: linear R,G,B, #RRGGBB (sRGB) or `transparent`
    /// (PNG with straight alpha, EXR with a premultiplied A channel) [default: black, or the
    /// built-in scene's sky].
    #[arg(long, value_name = "COLOR", value_parser = parse_background)]
    pub background: Option<Background>,
}

/// What rays that hit nothing show.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Background {
    /// This linear radiance.
    Color(Vec3),
    /// Nothing: coverage becomes the image's alpha.
    Transparent,
}

impl SceneArgs {
    /// Whether the background is transparent.
    pub fn transparent(&self) -> bool {
        self.background == Some(Background::Transparent)
    }

    /// The radiance of escaped rays the options ask for (`None`: the scene's own).
    pub fn background_radiance(&self) -> Option<Vec3> {
        self.background.map(|b| match b {
            Background::Color(c) => c,
            Background::Transparent => Vec3::ZERO,
        })
    }

    /// The --look-from camera, if asked for.
    pub fn camera_override(&self) -> Option<Camera> {
        let (eye, target) = (self.look_from?, self.look_at?);
        Some(Camera { eye, target, up: self.up, vfov_degrees: self.fov })
    }

    /// Checks the --look-from camera before anything is loaded.
    pub fn check(&self) -> Result<(), HemiError> {
        match self.camera_override() {
            Some(c) => c.validate().map_err(|e| HemiError::Usage(format!("--look-from/--look-at/--up: {e}"))),
            None => Ok(()),
        }
    }

    /// Applies the camera and the ground to a scene already spawned into `world`.
    pub fn stage(&self, world: &mut bevy_ecs::world::World) -> Result<(), HemiError> {
        if let Some(camera) = self.camera_override() {
            staging::replace_camera(world, camera)
                .map_err(|e| HemiError::Usage(format!("--look-from/--look-at/--up: {e}")))?;
        }
        if self.ground && staging::spawn_ground(world).is_none() {
            super::console::note("hemi: warning: --ground: the scene has no finite object to put a ground under");
        }
        Ok(())
    }
}

/// The image's size, its sampling and the threads that render it.
#[derive(clap::Args, Debug, Clone)]
pub struct RunArgs {
    /// Image size, WIDTHxHEIGHT (for `hemi view`, the window's full-resolution size)
    /// [default: 640x360, or a peer scene's own].
    #[arg(long, value_parser = super::parse_size)]
    pub size: Option<(u32, u32)>,
    /// Seed of every random decision: the same seed gives the same image bit for bit
    /// [default: 0, or a peer scene's seed].
    #[arg(long)]
    pub seed: Option<u64>,
    /// Sample pattern: regular, random, jittered, n-rooks, multi-jittered, hammersley, cmj, zsobol.
    #[arg(long, default_value = "cmj", value_parser = super::parse_sampler)]
    pub sampler: SamplerKind,
    /// Worker threads (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub threads: Option<u32>,
}

/// The look of 8-bit output.
#[derive(clap::Args, Debug, Clone)]
pub struct LookArgs {
    /// Exposure in stops of 8-bit output (PNG, the window): radiance × 2^EV before the tone
    /// curve (EXR stays linear and unscaled).
    #[arg(long, value_name = "EV", default_value_t = 0.0, value_parser = parse_exposure, allow_hyphen_values = true)]
    pub exposure: f32,
    /// Tone curve of 8-bit output: none (clamp), khronos-neutral, aces (Narkowicz's fit).
    #[arg(long, default_value = "none", value_parser = parse_tonemap)]
    pub tonemap: Tonemap,
}

impl LookArgs {
    /// The look these options describe.
    pub fn look(&self) -> Look {
        Look { exposure: self.exposure, tonemap: self.tonemap }
    }
}

/// Three finite numbers `X,Y,Z`.
pub fn parse_vec3(s: &str) -> Result<Vec3, String> {
    let parts: Vec<&str> = s.split(',').collect();
    let [x, y, z] = parts[..] else { return Err(format!("expected X,Y,Z, e.g. 0,1.5,4 (got '{s}')")) };
    let number = |v: &str| match v.trim().parse::<f32>() {
        Ok(f) if f.is_finite() => Ok(f),
        _ => Err(format!("'{}' in '{s}' is not a finite number", v.trim())),
    };
    Ok(Vec3::new(number(x)?, number(y)?, number(z)?))
}

fn parse_fov(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v > 0.0 && v < 180.0 => Ok(v),
        _ => Err(format!("field of view '{s}' must be a number of degrees in (0, 180)")),
    }
}

fn parse_exposure(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.abs() <= 64.0 => Ok(v),
        _ => Err(format!("exposure '{s}' must be a number of stops in [-64, 64]")),
    }
}

fn parse_tonemap(s: &str) -> Result<Tonemap, String> {
    Tonemap::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = Tonemap::ALL.iter().map(|t| t.name()).collect();
        format!("unknown tone curve '{s}' (expected one of: {})", names.join(", "))
    })
}

/// `transparent`, `#RRGGBB` (sRGB, decoded to linear) or linear `R,G,B` (finite, ≥ 0).
pub fn parse_background(s: &str) -> Result<Background, String> {
    if s.eq_ignore_ascii_case("transparent") {
        return Ok(Background::Transparent);
    }
    let color = match s.strip_prefix('#') {
        Some(hex) if hex.len() == 6 && hex.chars().all(|c| c.is_ascii_hexdigit()) => {
            let byte = |k: usize| u8::from_str_radix(&hex[2 * k..2 * k + 2], 16).expect("checked hex digits");
            let decode = |b: u8| {
                let v = b as f32 / 255.0;
                if v <= 0.040_45 { v / 12.92 } else { ((v + 0.055) / 1.055).powf(2.4) }
            };
            Vec3::new(decode(byte(0)), decode(byte(1)), decode(byte(2)))
        }
        Some(_) => return Err(format!("background '{s}': expected #RRGGBB with six hex digits")),
        None => parse_vec3(s).map_err(|e| format!("background: {e}, #RRGGBB or transparent"))?,
    };
    if color.min_element() < 0.0 {
        return Err(format!("background '{s}' must not be negative"));
    }
    Ok(Background::Color(color))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backgrounds_parse_as_linear_colours() {
        assert_eq!(parse_background("transparent"), Ok(Background::Transparent));
        assert_eq!(parse_background("0.5,0,1"), Ok(Background::Color(Vec3::new(0.5, 0.0, 1.0))));
        let Ok(Background::Color(c)) = parse_background("#ff0080") else { panic!() };
        // sRGB 0x80 = 128/255 is linear 0.2158605.
        assert_eq!((c.x, c.y), (1.0, 0.0));
        assert!((c.z - 0.215_860_5).abs() < 1e-6, "{c}");
        for bad in ["#ff00", "#gg0000", "1,2", "-1,0,0", "nan,0,0", "red"] {
            assert!(parse_background(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn vectors_need_three_finite_numbers() {
        assert_eq!(parse_vec3(" 1, -2.5,3 "), Ok(Vec3::new(1.0, -2.5, 3.0)));
        for bad in ["1,2", "1,2,3,4", "1,inf,2", "a,b,c", ""] {
            assert!(parse_vec3(bad).is_err(), "{bad}");
        }
    }
}
