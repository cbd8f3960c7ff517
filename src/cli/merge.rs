//! `hemi merge` (partials of a split-sample still into its image) and `hemi status` (the
//! progress of a frame sequence on disk).

use std::path::PathBuf;

use super::{frames::parse_closed_frames, parse_size};
use crate::{
    error::HemiError,
    film::OutputFile,
    partial::{self, Partial},
    sequence,
};

/// Options of `hemi merge`.
#[derive(clap::Args, Debug)]
pub(super) struct MergeArgs {
    /// Partials written by `hemi render --sample-range K/N` (any order); together they must
    /// hold every sample of the render exactly once.
    #[arg(required = true)]
    parts: Vec<PathBuf>,
    /// Output image: .png (8-bit sRGB) or .exr (linear f32).
    #[arg(long)]
    out: PathBuf,
}

pub(super) fn merge(args: MergeArgs) -> Result<(), HemiError> {
    let file = OutputFile::create(&args.out)?;
    let parts = args
        .parts
        .iter()
        .map(|path| Ok((path.clone(), Partial::load(path)?)))
        .collect::<Result<Vec<_>, HemiError>>()?;
    let image = partial::merge(&parts)?;
    file.write(&image)?;
    let info = &parts[0].1.info;
    super::console::note(&format!(
        "hemi: merged {} partials ({}x{}, {} spp in frames of {}) -> {}",
        parts.len(),
        info.width,
        info.height,
        info.spp,
        info.spf,
        args.out.display()
    ));
    Ok(())
}

/// Options of `hemi status`.
#[derive(clap::Args, Debug)]
pub(super) struct StatusArgs {
    /// The output pattern the sequence was rendered with, e.g. `out/f_{:04}.png`.
    pattern: PathBuf,
    /// The frames to check: A..B (B excluded) or one frame N.
    #[arg(long, value_parser = parse_closed_frames)]
    frames: (u32, u32),
    /// Count a frame as done only at this size, WIDTHxHEIGHT (default: any size).
    #[arg(long, value_parser = parse_size)]
    size: Option<(u32, u32)>,
}

pub(super) fn status(args: StatusArgs) -> Result<(), HemiError> {
    let states = sequence::frame_states(&args.pattern, args.frames, args.size).ok_or_else(|| {
        HemiError::Usage(format!("{} needs a frame-number placeholder such as {{:04}} or ####", args.pattern.display()))
    })?;
    let (report, all_done) = sequence::status_report(&states);
    super::console::out(&report)?;
    if all_done {
        Ok(())
    } else {
        let left = states.iter().filter(|s| s.state != sequence::FrameState::Done).count();
        Err(HemiError::Incomplete(format!("{left} of {} frames not done", states.len())))
    }
}
