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
    let s = RenderSettings {
        width: W,
        height: H,
        samples_per_frame: spf,
        samples_per_set: 8,
        target_error,
        aovs,
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
    assert!(acc.counts.is_empty() && acc.sq_sums.is_empty());
    assert!(matches!(acc.sums, Sums::Frames(ref v) if v.len() == PIXELS));
    assert!((0..PIXELS).all(|i| acc.count(i) == 8));

    let mut r = renderer(16, Some(0.05), false);
    r.render(32).unwrap();
    let acc = r.world().resource::<Accumulation>();
    assert_eq!((acc.counts.len(), acc.sq_sums.len()), (PIXELS, PIXELS));
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
