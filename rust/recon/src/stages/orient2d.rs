//! Stage `orient2d`: a 2D orientation map per view ([`crate::orient2d`], Gabor filter bank).
//!
//! Saves `orient2d/<view>.exr` (cos 2θ, sin 2θ, confidence: the layout of a capture's
//! `gt/orientation`, for other tools), `orient2d/<view>.png` pictures when asked, and
//! `orient2d/maps.bin`, the maps exactly as computed (θ and confidence as `f32`), which is what
//! [`Orient2dOut::load`] reads: θ through cos 2θ and sin 2θ would not come back bit for bit.

use std::io::{Read, Write};

use crate::config::{ReconstructConfig, Stage};
use crate::error::ReconError;
use crate::orient2d::{load_mask, GaborBank, GrayImage, OrientationMap};
use crate::stages::{mkdir, need, Context};

/// The maps, one per view in the capture's order.
#[derive(Debug, Clone, PartialEq)]
pub struct Orient2dOut {
    pub maps: Vec<OrientationMap>,
}

const MAGIC: &[u8; 8] = b"HRMAPS01";

/// Computes the maps of every view.
pub fn run(ctx: &Context<'_>, cfg: &ReconstructConfig) -> Result<Orient2dOut, ReconError> {
    let bank = GaborBank::new(cfg.gabor);
    let views = &ctx.capture.views;
    let mut maps = Vec::with_capacity(views.len());
    for (i, v) in views.iter().enumerate() {
        ctx.progress.check()?;
        ctx.progress.update("orient2d", i as f32 / views.len() as f32, &v.name);
        let img = GrayImage::load(&v.image)?;
        let mask = match &v.mask {
            Some(m) => Some(load_mask(m, img.width, img.height, cfg.mask_threshold)?),
            None => None,
        };
        maps.push(bank.compute(&img, mask.as_deref()));
    }
    ctx.progress.update("orient2d", 1.0, "");
    Ok(Orient2dOut { maps })
}

impl Orient2dOut {
    /// Writes the maps (see the module doc); `pictures` adds the PNGs.
    pub fn save(&self, ctx: &Context<'_>, pictures: bool) -> Result<(), ReconError> {
        mkdir(&ctx.path("orient2d"))?;
        for (v, map) in ctx.capture.views.iter().zip(&self.maps) {
            map.save_exr(&ctx.output(&format!("orient2d/{}.exr", v.name)))?;
            if pictures {
                map.save_png(&ctx.output(&format!("orient2d/{}.png", v.name)))?;
            }
        }
        let path = ctx.output("orient2d/maps.bin");
        hairrecon_core::formats::atomic_write(&path, |w| {
            w.write_all(MAGIC)?;
            w.write_all(&(self.maps.len() as u32).to_le_bytes())?;
            for m in &self.maps {
                w.write_all(&m.width.to_le_bytes())?;
                w.write_all(&m.height.to_le_bytes())?;
                for x in m.theta.iter().chain(&m.confidence) {
                    w.write_all(&x.to_le_bytes())?;
                }
            }
            Ok(())
        })?;
        Ok(())
    }

    /// Reads the maps an earlier run saved; `from` names the stage that asks (for the error).
    pub fn load(ctx: &Context<'_>, from: Stage) -> Result<Self, ReconError> {
        let path = need(ctx, from, Stage::Orient2d, "orient2d/maps.bin")?;
        let bad = |msg: String| ReconError::StageFile { stage: Stage::Orient2d, path: path.clone(), msg };
        let bytes = std::fs::read(&path).map_err(|e| bad(e.to_string()))?;
        let mut r = &bytes[..];
        let u32_at = |r: &mut &[u8]| -> Result<u32, ReconError> {
            let mut b = [0u8; 4];
            r.read_exact(&mut b).map_err(|_| bad("the file is truncated".into()))?;
            Ok(u32::from_le_bytes(b))
        };
        let mut magic = [0u8; 8];
        r.read_exact(&mut magic).map_err(|_| bad("the file is truncated".into()))?;
        if &magic != MAGIC {
            return Err(bad("not a hairrecon orientation-map file".into()));
        }
        let n = u32_at(&mut r)? as usize;
        if n != ctx.capture.views.len() {
            return Err(bad(format!("it holds {n} maps, the capture has {} views", ctx.capture.views.len())));
        }
        let mut maps = Vec::with_capacity(n);
        for v in &ctx.capture.views {
            let (width, height) = (u32_at(&mut r)?, u32_at(&mut r)?);
            if (width, height) != (v.camera.width(), v.camera.height()) {
                return Err(bad(format!("view {}'s map is {width}×{height}, its camera is not", v.name)));
            }
            let px = width as usize * height as usize;
            if r.len() < 8 * px {
                return Err(bad("the file is truncated".into()));
            }
            let floats = |b: &[u8]| -> Vec<f32> {
                b.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
            };
            let theta = floats(&r[..4 * px]);
            let confidence = floats(&r[4 * px..8 * px]);
            r = &r[8 * px..];
            maps.push(OrientationMap { width, height, theta, confidence });
        }
        Ok(Self { maps })
    }
}
