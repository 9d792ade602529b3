//! Selective silhouette anti-aliasing in the manner of nvdiffrast's `antialias` op (Laine et al.,
//! "Modular primitives for high-performance differentiable rendering", SIGGRAPH Asia 2020).
//!
//! Only horizontal and vertical neighbour pairs with different ids are considered. For such a pair,
//! the primitive in front (smaller depth; background is infinitely far) owns the silhouette: with `i`
//! the pixel it covers and `o` the other, the edge of that primitive crossed by the segment `i → o`
//! is found, at parameter `t ∈ [0, 1]` from `i`. If `t > 1/2` the edge lies inside `o`'s half, and
//! `o` is blended towards `i`: `ĉ(o) += (t − 1/2)(c(i) − c(o))`; otherwise `i` is blended towards `o`:
//! `ĉ(i) += (1/2 − t)(c(o) − c(i))`. The gradient reaches only the edge that crosses the pair, through
//! `t`. nvdiffrast also skips edges shared by two triangles of a mesh; segment primitives share no
//! edges, so every edge here is a silhouette edge.

use glam::Vec2;
use rayon::prelude::*;

use crate::aa_output::{scatter_corners, AaOutput, NONE};
use crate::image::Image;
use crate::rasterize::Buffers;
use crate::screen::{crossing, Prim, Screen, SegmentGrads};

/// The 4-neighbourhood; slot `3 − k` is the opposite of slot `k`.
const N4: [(i32, i32); 4] = [(0, -1), (-1, 0), (1, 0), (0, 1)];

/// The edge of `p` crossed by `ci → co` nearest `ci`, as `(edge, t)`.
#[inline]
fn exit_edge(p: &Prim, ci: Vec2, co: Vec2) -> Option<(u32, f32)> {
    let mut best: Option<(u32, f32)> = None;
    for k in 0..4 {
        if let Some((e0, e1)) = p.edge(k) {
            if let Some(t) = crossing(ci, co, e0, e1) {
                if !matches!(best, Some((_, bt)) if t >= bt) {
                    best = Some((k as u32, t));
                }
            }
        }
    }
    best
}

/// ∂t/∂e0 and ∂t/∂e1 for the crossing parameter `t` of `p0 → p1` with the line `e0 → e1`.
#[inline]
fn crossing_grad(p0: Vec2, p1: Vec2, e0: Vec2, e1: Vec2) -> (Vec2, Vec2) {
    let r = p1 - p0;
    let s = e1 - e0;
    let w = e0 - p0;
    let den = r.perp_dot(s);
    let t = w.perp_dot(s) / den;
    // N = w × s, D = r × s; a × b = a.x b.y − a.y b.x.
    let dn_dw = Vec2::new(s.y, -s.x);
    let dn_ds = Vec2::new(-w.y, w.x);
    let dd_ds = Vec2::new(-r.y, r.x);
    let dt_ds = (dn_ds - dd_ds * t) / den;
    let dt_dw = dn_dw / den;
    (dt_dw - dt_ds, dt_ds)
}

pub(crate) fn forward(screen: &Screen, buf: &Buffers, out: &mut AaOutput) {
    let a = &buf.attrs;
    let (w, h, nch) = (a.width as usize, a.height as usize, a.channels);
    out.image.reset(a.width, a.height, nch);
    out.edges.clear();
    out.edges.resize(w * h * 4, NONE);
    out.vals.clear();
    out.vals.resize(w * h * 4, 0.0);
    let prims = &screen.prims;
    let (ids, depth) = (&buf.ids, &buf.depth);
    out.image
        .data
        .par_chunks_mut(w * nch)
        .zip(out.edges.par_chunks_mut(w * 4))
        .zip(out.vals.par_chunks_mut(w * 4))
        .enumerate()
        .for_each(|(y, ((img, edges), vals))| {
            for x in 0..w {
                let i = y * w + x;
                let px = &mut img[x * nch..(x + 1) * nch];
                let cs = &a.data[i * nch..(i + 1) * nch];
                px.copy_from_slice(cs);
                for (k, &(dx, dy)) in N4.iter().enumerate() {
                    let (nx, ny) = (x as i32 + dx, y as i32 + dy);
                    if nx < 0 || ny < 0 || nx >= w as i32 || ny >= h as i32 {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if ids[j] == ids[i] {
                        continue;
                    }
                    let cself = Vec2::new(x as f32, y as f32);
                    let cn = Vec2::new(nx as f32, ny as f32);
                    // The front primitive owns the silhouette.
                    let self_front = depth[i] < depth[j] || (depth[i] == depth[j] && ids[i] < ids[j]);
                    let (front, ci, co) = if self_front { (ids[i], cself, cn) } else { (ids[j], cn, cself) };
                    if front == 0 {
                        continue;
                    }
                    let Some((edge, t)) = exit_edge(&prims[front as usize - 1], ci, co) else { continue };
                    // This pixel is modified if it is `o` and t > 1/2, or `i` and t < 1/2.
                    let alpha = if self_front { 0.5 - t } else { t - 0.5 };
                    if alpha <= 0.0 {
                        continue;
                    }
                    let cnv = &a.data[j * nch..(j + 1) * nch];
                    for c in 0..nch {
                        px[c] += alpha * (cnv[c] - cs[c]);
                    }
                    edges[x * 4 + k] = (((front - 1) * 4 + edge) << 1) | (!self_front) as u32;
                    vals[x * 4 + k] = t;
                }
            }
        });
}

pub(crate) fn backward(
    screen: &Screen,
    buf: &Buffers,
    saved: &AaOutput,
    d_image: &Image,
    d_attrs: &mut Image,
    grads: &mut SegmentGrads,
) {
    let a = &buf.attrs;
    let (w, h, nch) = (a.width as usize, a.height as usize, a.channels);
    let prims = &screen.prims;
    let g = &d_image.data;
    let parts: Vec<Vec<(u32, Vec2)>> = d_attrs
        .data
        .par_chunks_mut(w * nch)
        .enumerate()
        .map(|(y, drow)| {
            let mut out = Vec::new();
            for x in 0..w {
                let i = y * w + x;
                let gs = &g[i * nch..(i + 1) * nch];
                let cs = &a.data[i * nch..(i + 1) * nch];
                let d = &mut drow[x * nch..(x + 1) * nch];
                let mut asum = 0.0;
                let cself = Vec2::new(x as f32, y as f32);
                for (k, &(dx, dy)) in N4.iter().enumerate() {
                    let (nx, ny) = (x as i32 + dx, y as i32 + dy);
                    if nx < 0 || ny < 0 || nx >= w as i32 || ny >= h as i32 {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    let code = saved.edges[i * 4 + k];
                    if code != NONE {
                        let t = saved.vals[i * 4 + k];
                        let outside = code & 1 == 1;
                        let alpha = if outside { t - 0.5 } else { 0.5 - t };
                        asum += alpha;
                        let cn = &a.data[j * nch..(j + 1) * nch];
                        let mut dot = 0.0;
                        for c in 0..nch {
                            dot += gs[c] * (cn[c] - cs[c]);
                        }
                        if dot != 0.0 {
                            let pe = code >> 1;
                            let (prim, edge) = (pe >> 2, pe & 3);
                            let (e0, e1) = prims[prim as usize].edge(edge as usize).unwrap_or_default();
                            let cn_ = Vec2::new(nx as f32, ny as f32);
                            let (ci, co) = if outside { (cn_, cself) } else { (cself, cn_) };
                            let (g0, g1) = crossing_grad(ci, co, e0, e1);
                            let dl_dt = if outside { dot } else { -dot };
                            out.push((prim * 4 + edge, g0 * dl_dt));
                            out.push((prim * 4 + ((edge + 1) & 3), g1 * dl_dt));
                        }
                    }
                    let back = saved.edges[j * 4 + 3 - k];
                    if back != NONE {
                        let t = saved.vals[j * 4 + 3 - k];
                        let alpha = if back & 1 == 1 { t - 0.5 } else { 0.5 - t };
                        for c in 0..nch {
                            d[c] += alpha * g[j * nch + c];
                        }
                    }
                }
                for c in 0..nch {
                    d[c] += (1.0 - asum) * gs[c];
                }
            }
            out
        })
        .collect();
    scatter_corners(parts, grads);
}
