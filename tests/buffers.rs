//! The per-pixel buffers a render keeps: their sizes against the bytes each layout needs, and
//! the images of the layouts against each other (one frame's f32 sums against f64 sums).

use hemi::{
    prelude::*,
    resources::{Accumulation, Sums},
    sampling::SampleSets,
};

const W: u32 = 48;
const H: u32 = 20;
const PIXELS: usize = (W * H) as usize;

fn renderer(spf: u32, target_error: Option<f32>, aovs: bool) -> Renderer {
    renderer_releasing(spf, target_error, aovs, false)
}

fn renderer_releasing(spf: u32, target_error: Option<f32>, aovs: bool, release_sums: bool) -> Renderer {
    let s = RenderSettings {
        width: W,
        height: H,
        samples_per_frame: spf,
        samples_per_set: 8,
        target_error,
        aovs,
        release_sums,
        ..Default::default()
    };
    Renderer::with_default_scene(s)
}

/// Image buffer bytes `--stats` reports for `r` after rendering `spp` (sample sets left out).
fn pixel_bytes(r: &mut Renderer, spp: u32) -> usize {
    r.render(spp).unwrap();
    r.stats().buffer_bytes - r.world().resource::<SampleSets>().memory_bytes()
}

#[test]
fn each_render_keeps_the_bytes_per_pixel_its_layout_needs() {
    // f32 sums of the one frame (12) and the linear image (12).
    assert_eq!(pixel_bytes(&mut renderer(8, None, false), 8), PIXELS * 24);
    // f64 sums over frames (24) and the linear image.
    assert_eq!(pixel_bytes(&mut renderer(4, None, false), 8), PIXELS * 36);
    // Adaptive sampling adds counts (4) and squared sums (8).
    assert_eq!(pixel_bytes(&mut renderer(16, Some(0.05), false), 32), PIXELS * 48);
    // AOVs: sums of 12 floats, f32 (48) for one frame, f64 (96) over frames, and their means (48).
    assert_eq!(pixel_bytes(&mut renderer(8, None, true), 8), PIXELS * (24 + 48 + 48));
    assert_eq!(pixel_bytes(&mut renderer(4, None, true), 8), PIXELS * (36 + 96 + 48));
}

#[test]
fn a_render_without_a_target_error_keeps_no_counts_or_squared_sums() {
    let mut r = renderer(4, None, false);
    r.render(8).unwrap();
    let acc = r.world().resource::<Accumulation>();
    assert!(acc.counts.is_empty() && acc.deviations.is_empty());
    assert!(matches!(acc.sums, Sums::Frames(ref v) if v.len() == PIXELS));
    assert!((0..PIXELS).all(|i| acc.count(i) == 8));

    let mut r = renderer(16, Some(0.05), false);
    r.render(32).unwrap();
    let acc = r.world().resource::<Accumulation>();
    assert_eq!((acc.counts.len(), acc.deviations.len()), (PIXELS, PIXELS));
    assert!(acc.counts.contains(&16) && acc.counts.contains(&32), "some pixels retire early");
}

/// One frame's sums in f32 give the image f64 sums of that frame give, bit for bit, and a
/// render continued past its one frame (the sums widened to f64) the image of a render that
/// kept f64 sums from the start.
#[test]
fn one_frames_f32_sums_give_the_image_of_f64_sums() {
    for aovs in [false, true] {
        let mut one_frame = renderer(8, None, aovs);
        one_frame.render(8).unwrap();
        let acc = one_frame.world().resource::<Accumulation>();
        assert!(matches!(acc.sums, Sums::OneFrame(_)) && matches!(acc.aovs, Sums::OneFrame(_)));
        assert_eq!(acc.aovs.len(), if aovs { PIXELS } else { 0 });
        // No sample target: the accumulation keeps f64 sums from its first frame.
        let mut frames = renderer(8, None, aovs);
        frames.run_frame().unwrap();
        assert!(matches!(frames.world().resource::<Accumulation>().sums, Sums::Frames(_)));
        assert!(one_frame.image() == frames.image(), "aovs {aovs}: one frame's images differ");

        one_frame.render(16).unwrap();
        let acc = one_frame.world().resource::<Accumulation>();
        assert!(matches!(acc.sums, Sums::Frames(_)) && matches!(acc.aovs, Sums::Frames(_)));
        frames.run_frame().unwrap();
        assert_eq!(frames.spp(), 16);
        assert!(one_frame.image() == frames.image(), "aovs {aovs}: two frames' images differ");
    }
}

/// A finished one-frame render whose image takes the sums' memory has the image of one that
/// keeps them, bit for bit, and holds one per-pixel buffer; its spent accumulation starts anew,
/// so that raising the target gives the image of a fresh render to it.
#[test]
fn an_image_that_takes_the_sums_is_the_image_of_one_that_keeps_them() {
    for aovs in [false, true] {
        let mut kept = renderer(8, None, aovs);
        kept.render(8).unwrap();
        let mut released = renderer_releasing(8, None, aovs, true);
        let bytes = pixel_bytes(&mut released, 8);
        assert!(released.image() == kept.image(), "aovs {aovs}: images differ");
        assert_eq!(released.image().linear.len(), PIXELS);
        assert_eq!(released.image().aovs.len(), if aovs { PIXELS } else { 0 });
        // The means alone: 12 bytes, and 48 for the AOVs.
        assert_eq!(bytes, PIXELS * if aovs { 12 + 48 } else { 12 });
        let acc = released.world().resource::<Accumulation>();
        assert!(acc.spent() && acc.sums.is_empty() && acc.aovs.is_empty());
        assert!(released.converged(), "the render reached its target");

        // Nothing changed: the next frame traces nothing and the image stays.
        let image = released.image().clone();
        released.run_frame().unwrap();
        assert_eq!(released.stats().reset, None);
        assert_eq!(released.spp(), 8);
        assert!(released.image() == &image, "the image stays");
        released.settings_mut().max_spp = Some(16);
        released.run_frame().unwrap();
        assert!(released.stats().reset.as_deref().is_some_and(|r| r.contains("took the sums")));
        assert_eq!(released.spp(), 8, "the first frame after release starts anew");
        released.render(16).unwrap();
        let mut fresh = renderer(8, None, aovs);
        fresh.render(16).unwrap();
        assert!(released.image() == fresh.image(), "aovs {aovs}: the render after release differs");
    }
}

/// Sums the image may not take stay where they are: several frames (f64), adaptive counts,
/// and a one-frame render that has not reached its target.
#[test]
fn sums_of_frames_or_of_adaptive_renders_stay_with_the_accumulation() {
    let mut frames = renderer_releasing(4, None, false, true);
    frames.render(8).unwrap();
    let acc = frames.world().resource::<Accumulation>();
    assert!(!acc.spent() && matches!(acc.sums, Sums::Frames(ref v) if v.len() == PIXELS));

    let mut adaptive = renderer_releasing(32, Some(0.05), false, true);
    adaptive.render(32).unwrap();
    assert!(!adaptive.world().resource::<Accumulation>().spent());

    let mut untargeted = renderer_releasing(8, None, false, true);
    untargeted.run_frame().unwrap();
    assert!(!untargeted.world().resource::<Accumulation>().spent());
}
