//! `hemi compare`: hemi's AO against the peer renderers' references, one line per scene.

use std::path::PathBuf;

use super::{console, parse_sampler, peer_compare, peer_scene::PeerScene};
use crate::{error::HemiError, sampling::SamplerKind};

/// Options of `hemi compare`.
#[derive(clap::Args, Debug)]
pub(super) struct CompareArgs {
    /// Peer scene files (`../shared/peers/scenes/*.json`); references are read from `../refs`.
    #[arg(required = true)]
    scenes: Vec<PathBuf>,
    /// Samples per pixel.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=65_536))]
    spp: u32,
    /// Sample pattern.
    #[arg(long, default_value = "cmj", value_parser = parse_sampler)]
    sampler: SamplerKind,
    /// Worker threads (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
}

pub(super) fn compare(args: CompareArgs) -> Result<(), HemiError> {
    console::out(&format!(
        "{:<14} {:>6} {:>9} {:>10} {:>10} {:>10} {:>12} {:>8} {:>9}\n",
        "scene", "spp", "hit px", "bias", "rmse", "predicted", "hit mismatch", "seconds", "Mrays/s"
    ))?;
    for path in &args.scenes {
        let scene = PeerScene::load(path)?;
        let c = peer_compare::compare(&scene, args.spp, args.sampler, args.threads.map(|t| t as usize))?;
        console::out(&format!(
            "{:<14} {:>6} {:>9} {:>+10.2e} {:>10.3e} {:>10.3e} {:>12} {:>8.2} {:>9.2}\n",
            c.scene,
            c.spp,
            c.hit_pixels,
            c.bias,
            c.rmse,
            c.predicted_rmse,
            c.hit_mismatches,
            c.seconds,
            c.rays as f64 / c.seconds / 1e6
        ))?;
    }
    Ok(())
}
