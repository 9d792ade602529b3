//! The anti-aliasing toy of Dr.Hair's supplement (3.1): grow one segment by differentiable rendering.
//!
//! A 128×128 image. One segment from a fixed root to an optimized tip becomes a triangle whose root
//! edge is `width_px` wide and whose apex is the tip. The target is the silhouette of the long strand
//! (the same triangle at full length), by default rendered by the method under test
//! ([`ToyTarget::Rendered`]: the loss is 0 exactly at the target, so the toy tests the gradients and
//! not a method's bias), or as its exact area coverage per pixel ([`ToyTarget::Coverage`], 8×8
//! supersampling, the same image for every method). The segment starts at 20% of the target length; plain SGD without
//! momentum, learning rate 1.0, on the L2 loss `s · Σ_p (ĉ(p) − target(p))²` of the coverage channel, a
//! sum over pixels with `s = 0.4` by default (the paper gives neither the reduction nor a factor;
//! with plain SGD at learning rate 1 the factor sets the step: at `s = 0.5` the 0.8 and 1.0 px runs of
//! `ours` settle into 2-cycles short of the target, at `s = 0.25` the 0.6 px run is still growing after
//! 25,000 iterations; measured with `hairrecon toy-aa --loss-scale`). The
//! optimized length is the distance from the root to the tip.

use glam::Vec2;

use crate::antialias::AaMethod;
use crate::channel;
use crate::error::RasterError;
use crate::image::Image;
use crate::renderer::Renderer;
use crate::screen::{Prim, RasterSettings, Screen, SegmentShape, Width};

/// What the toy is asked to do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToyConfig {
    pub method: AaMethod,
    pub width_px: f32,
    pub iters: usize,
    pub learning_rate: f32,
    pub size: u32,
    pub root: Vec2,
    pub target_tip: Vec2,
    /// Initial length as a fraction of the target length.
    pub start_fraction: f32,
    pub target: ToyTarget,
    /// `L = loss_scale · Σ_p (ĉ(p) − target(p))²`; 0.4 by default (see the crate report: at 0.5 the 0.8 and 1.0 px runs fall into 2-cycles of SGD at learning rate 1, at 0.25 the 0.6 px run grows too slowly).
    pub loss_scale: f32,
}

/// How the target image is made from the full-length triangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ToyTarget {
    /// Rendered by the method under test: the loss is exactly 0 at the target, so the run measures
    /// only whether the gradients lead there.
    #[default]
    Rendered,
    /// Exact area coverage (8×8 supersampling), the same image for every method.
    Coverage,
}

impl ToyConfig {
    /// The supplement's set-up: root at the top left, the target tip below and slightly to the left,
    /// about 104 px away, at an angle that is not aligned with the pixel grid.
    pub fn paper(method: AaMethod, width_px: f32, iters: usize) -> Self {
        Self {
            method,
            width_px,
            iters,
            learning_rate: 1.0,
            size: 128,
            root: Vec2::new(40.3, 10.7),
            target_tip: Vec2::new(21.9, 113.4),
            start_fraction: 0.2,
            target: ToyTarget::Rendered,
            loss_scale: 0.4,
        }
    }
}

/// One point of the loss curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ToyStep {
    pub iter: usize,
    pub loss: f32,
    pub tip_error_px: f32,
    pub length_ratio: f32,
}

/// The outcome of a toy run.
#[derive(Debug, Clone, PartialEq)]
pub struct ToyResult {
    pub initial_loss: f32,
    pub final_loss: f32,
    pub final_tip_error_px: f32,
    pub final_length_ratio: f32,
    pub final_tip: Vec2,
    /// The loss before every update (index = iteration), then the final loss.
    pub curve: Vec<ToyStep>,
}

fn settings(width_px: f32) -> RasterSettings {
    RasterSettings { width: Width::Pixels(width_px), shape: SegmentShape::Triangle, direction_3d: false }
}

/// The exact-coverage image (8×8 samples per pixel) of the triangle from `root` to `tip`.
pub fn coverage_image(size: u32, root: Vec2, tip: Vec2, width_px: f32) -> Result<Image, RasterError> {
    let screen = Screen::from_pixels(size, size, &[root, tip], None, &[[0, 1]], settings(width_px))?;
    let p: &Prim = &screen.prims()[0];
    let mut img = Image::zeros(size, size, 1);
    const S: usize = 8;
    for y in 0..size {
        for x in 0..size {
            let c = Vec2::new(x as f32, y as f32);
            // Only pixels near the bounding box can be covered.
            let bbox = p.bbox();
            if c.x < bbox[0] - 1.0 || c.x > bbox[2] + 1.0 || c.y < bbox[1] - 1.0 || c.y > bbox[3] + 1.0 {
                continue;
            }
            let mut n = 0;
            for j in 0..S {
                for i in 0..S {
                    let o = Vec2::new((i as f32 + 0.5) / S as f32 - 0.5, (j as f32 + 0.5) / S as f32 - 0.5);
                    n += p.contains(c + o) as u32;
                }
            }
            img.data[(y * size + x) as usize] = n as f32 / (S * S) as f32;
        }
    }
    Ok(img)
}

/// The anti-aliased coverage of the segment `root → tip` with `method` (for pictures).
pub fn render_coverage(
    method: AaMethod,
    size: u32,
    root: Vec2,
    tip: Vec2,
    width_px: f32,
) -> Result<Image, RasterError> {
    let mut r = Renderer::new(method);
    let img = r.forward_pixels(size, size, &[root, tip], &[[0, 1]], settings(width_px))?;
    Ok(img.channel(channel::COVERAGE))
}

/// Runs the toy; `on_step` is called after every iteration with the iteration number.
pub fn run_toy(cfg: &ToyConfig, mut on_step: impl FnMut(usize)) -> Result<ToyResult, RasterError> {
    let target = match cfg.target {
        ToyTarget::Rendered => render_coverage(cfg.method, cfg.size, cfg.root, cfg.target_tip, cfg.width_px)?,
        ToyTarget::Coverage => coverage_image(cfg.size, cfg.root, cfg.target_tip, cfg.width_px)?,
    };
    let target_len = (cfg.target_tip - cfg.root).length();
    let mut tip = cfg.root + (cfg.target_tip - cfg.root) * cfg.start_fraction;
    let mut r = Renderer::new(cfg.method);
    let mut d_image = Image::default();
    let mut curve = Vec::with_capacity(cfg.iters + 1);
    let set = settings(cfg.width_px);
    let step_of = |iter: usize, loss: f32, tip: Vec2| ToyStep {
        iter,
        loss,
        tip_error_px: (tip - cfg.target_tip).length(),
        length_ratio: (tip - cfg.root).length() / target_len,
    };
    for iter in 0..=cfg.iters {
        let img = r.forward_pixels(cfg.size, cfg.size, &[cfg.root, tip], &[[0, 1]], set)?;
        let nch = img.channels;
        d_image.reset(img.width, img.height, nch);
        let mut loss = 0.0f64;
        for (k, &t) in target.data.iter().enumerate() {
            let e = img.data[k * nch + channel::COVERAGE] - t;
            loss += (cfg.loss_scale * e * e) as f64;
            d_image.data[k * nch + channel::COVERAGE] = 2.0 * cfg.loss_scale * e;
        }
        curve.push(step_of(iter, loss as f32, tip));
        if iter == cfg.iters {
            break;
        }
        let g = r.backward_screen(&d_image)?;
        tip -= g.pos[1] * cfg.learning_rate;
        on_step(iter);
    }
    let last = *curve.last().unwrap_or(&step_of(0, 0.0, tip));
    Ok(ToyResult {
        initial_loss: curve[0].loss,
        final_loss: last.loss,
        final_tip_error_px: last.tip_error_px,
        final_length_ratio: last.length_ratio,
        final_tip: tip,
        curve,
    })
}
