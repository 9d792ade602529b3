//! Hard rasterization of segment primitives with a depth test (forward only).
//!
//! In: a [`Screen`]. Out: [`Buffers`]: per pixel the id of the nearest primitive whose closed area
//! contains the pixel centre (`segment + 1`, 0 for background), its depth, and the attributes
//! coverage, `(cos 2θ, sin 2θ)` of the screen direction (so that orientations blend without the
//! 180° jump), and optionally the 3D direction. Pixel centres are at integer coordinates
//! (`docs/method.md`). The image is cut into horizontal bands of [`BAND`] rows; primitives are binned
//! to bands in parallel chunks, then each band is rasterized by one rayon task (Laine and Karras 2011,
//! "High-performance software rasterization on GPUs", in its simplest bin-then-raster form). Ties in
//! depth keep the lower segment index, so the result does not depend on the thread count. The image
//! is piecewise constant in the vertices: gradients come from the anti-aliasing ops and from
//! [`attributes_backward`].

use glam::Vec2;
use rayon::prelude::*;

use crate::image::Image;
use crate::screen::{Screen, SegmentGrads};

/// Rows per band.
pub const BAND: usize = 8;
/// Primitives per binning chunk.
const CHUNK: usize = 1 << 15;

/// Attribute channels written by [`rasterize`].
pub mod channel {
    /// 1 where a primitive covers the pixel centre, else 0.
    pub const COVERAGE: usize = 0;
    /// cos 2θ of the screen direction.
    pub const COS2: usize = 1;
    /// sin 2θ of the screen direction.
    pub const SIN2: usize = 2;
    /// x of the unit 3D direction; y and z follow (only with `direction_3d`).
    pub const DIR3: usize = 3;
}

/// The output of [`rasterize`], reused between calls.
#[derive(Debug, Clone, Default)]
pub struct Buffers {
    width: u32,
    height: u32,
    /// `segment + 1` of the visible primitive, 0 for background.
    pub ids: Vec<u32>,
    /// Depth of the visible primitive, `f32::INFINITY` for background.
    pub depth: Vec<f32>,
    /// Attributes, see [`channel`].
    pub attrs: Image,
    /// Per binning chunk, per band: the primitives that come within 1 px of a pixel centre of the band.
    pub(crate) bins: Vec<Vec<Vec<u32>>>,
}

impl Buffers {
    pub fn new() -> Self {
        Self::default()
    }
    pub fn width(&self) -> u32 {
        self.width
    }
    pub fn height(&self) -> u32 {
        self.height
    }
    /// Id at pixel `(x, y)`.
    pub fn id(&self, x: u32, y: u32) -> u32 {
        self.ids[y as usize * self.width as usize + x as usize]
    }
}

/// The pixel centres within the bounding box of `p` grown by `margin` pixels (`None` when there
/// are none, or when the box is not finite).
#[inline]
pub(crate) fn pixel_range_margin(p: &crate::screen::Prim, w: u32, h: u32, margin: f32) -> Option<[usize; 4]> {
    let bbox = p.bbox();
    if !bbox.iter().all(|v| v.is_finite()) {
        return None;
    }
    let x0 = ceil_i(bbox[0] - margin).max(0);
    let y0 = ceil_i(bbox[1] - margin).max(0);
    let x1 = floor_i(bbox[2] + margin).min(w as i64 - 1);
    let y1 = floor_i(bbox[3] + margin).min(h as i64 - 1);
    if x0 > x1 || y0 > y1 {
        return None;
    }
    Some([x0 as usize, y0 as usize, x1 as usize, y1 as usize])
}

/// `x.floor()` of a finite `x` as an integer, without a call to libm's `floorf` (which the
/// baseline x86-64 target makes of `f32::floor`); `x` beyond ±2^62 saturates.
#[inline]
fn floor_i(x: f32) -> i64 {
    let t = x as i64;
    t - i64::from(x < t as f32)
}

/// `x.ceil()` of a finite `x` as an integer; see [`floor_i`].
#[inline]
fn ceil_i(x: f32) -> i64 {
    let t = x as i64;
    t + i64::from(x > t as f32)
}

#[inline]
fn pixel_range(p: &crate::screen::Prim, w: u32, h: u32) -> Option<[usize; 4]> {
    pixel_range_margin(p, w, h, 0.0)
}

/// Rasterizes the primitives of `screen` into `buf` (overwritten, allocations reused).
pub fn rasterize(screen: &Screen, buf: &mut Buffers) {
    let (w, h) = (screen.width, screen.height);
    let (wu, hu) = (w as usize, h as usize);
    buf.width = w;
    buf.height = h;
    let nbands = hu.div_ceil(BAND);
    let prims = &screen.prims;
    let nchunks = prims.len().div_ceil(CHUNK).max(1);
    buf.bins.resize_with(nchunks, Vec::new);
    buf.bins.truncate(nchunks);
    buf.bins.par_iter_mut().enumerate().for_each(|(c, bins)| {
        bins.resize_with(nbands, Vec::new);
        bins.truncate(nbands);
        bins.iter_mut().for_each(Vec::clear);
        let start = c * CHUNK;
        let end = (start + CHUNK).min(prims.len());
        for (i, p) in prims[start..end].iter().enumerate() {
            if !p.valid() {
                continue;
            }
            if let Some(r) = pixel_range_margin(p, w, h, 1.0) {
                for band in r[1] / BAND..=r[3] / BAND {
                    bins[band].push((start + i) as u32);
                }
            }
        }
    });
    buf.ids.clear();
    buf.ids.resize(wu * hu, 0);
    buf.depth.clear();
    buf.depth.resize(wu * hu, f32::INFINITY);
    let bins = &buf.bins;
    buf.ids.par_chunks_mut(wu * BAND).zip(buf.depth.par_chunks_mut(wu * BAND)).enumerate().for_each(
        |(band, (ids, depth))| {
            let row0 = band * BAND;
            let row1 = row0 + ids.len() / wu;
            for chunk in bins {
                for &si in &chunk[band] {
                    let p = &prims[si as usize];
                    let Some(r) = pixel_range(p, w, h) else { continue };
                    for y in r[1].max(row0)..=r[3].min(row1 - 1) {
                        let row = (y - row0) * wu;
                        for x in r[0]..=r[2] {
                            let c = Vec2::new(x as f32, y as f32);
                            let v = c - p.a;
                            let t = v.dot(p.u()) / p.len;
                            if !(0.0..=1.0).contains(&t) {
                                continue;
                            }
                            let s = v.dot(p.n);
                            if s.abs() > p.hw0 + (p.hw1 - p.hw0) * t {
                                continue;
                            }
                            let z = p.z0 + (p.z1 - p.z0) * t;
                            if z < depth[row + x] {
                                depth[row + x] = z;
                                ids[row + x] = si + 1;
                            }
                        }
                    }
                }
            }
        },
    );
    let nch = if screen.settings.direction_3d { 6 } else { 3 };
    buf.attrs.reset(w, h, nch);
    let (ids, dir3) = (&buf.ids, &screen.dir3);
    buf.attrs.data.par_chunks_mut(wu * nch * BAND).enumerate().for_each(|(band, a)| {
        let base = band * BAND * wu;
        for (k, px) in a.chunks_exact_mut(nch).enumerate() {
            let id = ids[base + k];
            if id == 0 {
                continue;
            }
            let orient = prims[id as usize - 1].orient();
            px[channel::COVERAGE] = 1.0;
            px[channel::COS2] = orient.x;
            px[channel::SIN2] = orient.y;
            if nch == 6 {
                let d = dir3[id as usize - 1];
                px[channel::DIR3] = d.x;
                px[channel::DIR3 + 1] = d.y;
                px[channel::DIR3 + 2] = d.z;
            }
        }
    });
}

/// ∂L/∂(b − a) of a primitive, given ∂L/∂cos 2θ and ∂L/∂sin 2θ.
#[inline]
pub(crate) fn orient_grad(p: &crate::screen::Prim, gc: f32, gs: f32) -> Vec2 {
    let d = p.u() * p.len;
    let l2 = p.len * p.len;
    let l4 = l2 * l2;
    // f = (dx² − dy²)/L², g = 2 dx dy / L².
    let df = Vec2::new(4.0 * d.x * d.y * d.y, -4.0 * d.y * d.x * d.x) / l4;
    let dg = Vec2::new(2.0 * d.y * (d.y * d.y - d.x * d.x), 2.0 * d.x * (d.x * d.x - d.y * d.y)) / l4;
    df * gc + dg * gs
}

/// Backward of the attributes: adds `∂L/∂(b − a)` of every visible segment, through
/// `(cos 2θ, sin 2θ)`, to `grads.dir`. `d_attrs` has the shape of `buf.attrs`. Coverage and the 3D
/// direction get no gradient here (coverage is constant; the 3D direction is forward only).
pub fn attributes_backward(screen: &Screen, buf: &Buffers, d_attrs: &Image, grads: &mut SegmentGrads) {
    let nch = d_attrs.channels;
    let wu = buf.width as usize;
    let prims = &screen.prims;
    let partial: Vec<Vec<(u32, Vec2)>> = buf
        .ids
        .par_chunks(wu * BAND)
        .zip(d_attrs.data.par_chunks(wu * BAND * nch))
        .map(|(ids, g)| {
            let mut out: Vec<(u32, Vec2)> = Vec::new();
            for (k, &id) in ids.iter().enumerate() {
                if id == 0 {
                    continue;
                }
                let gc = g[k * nch + channel::COS2];
                let gs = g[k * nch + channel::SIN2];
                if gc == 0.0 && gs == 0.0 {
                    continue;
                }
                out.push((id - 1, orient_grad(&prims[id as usize - 1], gc, gs)));
            }
            out
        })
        .collect();
    for part in partial {
        for (s, g) in part {
            grads.add_dir(s, g);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The integer floor and ceiling are `f32::floor` and `f32::ceil` on negative, positive,
    /// whole, tiny and large values.
    #[test]
    fn floor_and_ceil_without_libm_match_the_float_ones() {
        let mut xs =
            vec![0.0f32, -0.0, 0.5, -0.5, 1.0, -1.0, 1e-30, -1e-30, 3.999_999_8, -3.999_999_8, 1e9, -1e9, 16_777_217.0];
        xs.extend((-2000..2000).map(|i| i as f32 * 0.37 + 0.001 * (i % 7) as f32));
        for x in xs {
            assert_eq!(floor_i(x), x.floor() as i64, "floor {x}");
            assert_eq!(ceil_i(x), x.ceil() as i64, "ceil {x}");
        }
    }
}
