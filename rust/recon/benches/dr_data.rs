//! DR's targets for the benchmarks, shared by `benches/dr_step.rs` and `examples/dr_scaling.rs`: the
//! coverage and orientation of ground-truth strands rendered in each view.

use glam::Vec2;
use hairrecon_core::{Camera, StrandSet};
use hairrecon_raster::{channel, strand_segments, AaMethod, RasterSettings, Renderer, SegmentShape, Width};
use hairrecon_recon::dr::{DrTargets, DrView};

/// Strand width, metres (the library's default).
pub const WIDTH_M: f32 = 0.0002;

/// The coverage and orientation of `gt` in each view, as DR's targets.
pub fn targets(gt: &StrandSet, cams: &[Camera]) -> DrTargets {
    let segs = strand_segments(gt);
    let settings = RasterSettings { width: Width::World(WIDTH_M), shape: SegmentShape::Quad, direction_3d: false };
    let mut r = Renderer::new(AaMethod::Ours);
    let views = cams
        .iter()
        .enumerate()
        .map(|(i, cam)| {
            let img = r.forward(cam, gt.points(), &segs, settings).expect("render").clone();
            let px = |p: usize| img.pixel((p % cam.width() as usize) as u32, (p / cam.width() as usize) as u32);
            let mask: Vec<f32> = (0..img.num_pixels()).map(|p| px(p)[channel::COVERAGE]).collect();
            let orient: Vec<[f32; 3]> = (0..img.num_pixels())
                .map(|p| {
                    let o = Vec2::new(px(p)[channel::COS2], px(p)[channel::SIN2]).normalize_or_zero();
                    [o.x, o.y, f32::from(u8::from(o != Vec2::ZERO))]
                })
                .collect();
            DrView::new(i, *cam, mask, orient, None).expect("view")
        })
        .collect();
    DrTargets { views }
}
