//! Dr.Hair's anti-aliasing for line segments (Takimoto et al., CVPR 2024, supplement 3.1), in the
//! reading of `docs/method.md` ("One reading of the paper's anti-aliasing").
//!
//! For a pixel `s` and each of its 8 neighbours `n` with a different id (another primitive or
//! background), find the edge that separates them: the edge of `n`'s primitive crossed by the
//! segment between the pixel centres, the crossing nearest `n`; else an edge of `s`'s own primitive,
//! the crossing nearest `s`. With `r = min(distance from the centre of s to that edge's line, 1)`:
//!
//! `ĉ(s) = c(s) + (1/9) Σ_n (1 − r(s, n)) (c(n) − c(s))`.
//!
//! Backward: linear in `c`; `∂L/∂r = −(1/9) ⟨∂L/∂ĉ(s), c(n) − c(s)⟩` flows to the two corners of the
//! chosen edge through the point-to-line distance. Every id boundary in all 8 directions gives a
//! gradient, not only silhouettes between horizontal or vertical neighbours, which is what lets a
//! sub-pixel segment keep growing (see the toy, [`crate::toy`]). Primitives are whole segments
//! ([`crate::screen`]), so no internal diagonal can be chosen.

use glam::Vec2;
use rayon::prelude::*;

use crate::antialias::{scatter_corners, AaOutput, N8, NONE};
use crate::image::Image;
use crate::rasterize::Buffers;
use crate::screen::{crossing, line_distance, Prim, Screen, SegmentGrads};

const INV9: f32 = 1.0 / 9.0;

/// The separating edge between pixel centres `cs` (id `ids`) and `cn` (id `idn`), as
/// `(prim, edge)`.
#[inline]
fn separating_edge(prims: &[Prim], cs: Vec2, cn: Vec2, ids: u32, idn: u32) -> Option<(u32, u32)> {
    if idn != 0 {
        let p = &prims[idn as usize - 1];
        let mut best: Option<(f32, u32)> = None;
        for k in 0..4 {
            if let Some((e0, e1)) = p.edge(k) {
                if let Some(t) = crossing(cs, cn, e0, e1) {
                    if best.map_or(true, |(bt, _)| t > bt) {
                        best = Some((t, k as u32));
                    }
                }
            }
        }
        if let Some((_, k)) = best {
            return Some((idn - 1, k));
        }
    }
    if ids != 0 {
        let p = &prims[ids as usize - 1];
        let mut best: Option<(f32, u32)> = None;
        for k in 0..4 {
            if let Some((e0, e1)) = p.edge(k) {
                if let Some(t) = crossing(cs, cn, e0, e1) {
                    if best.map_or(true, |(bt, _)| t < bt) {
                        best = Some((t, k as u32));
                    }
                }
            }
        }
        if let Some((_, k)) = best {
            return Some((ids - 1, k));
        }
    }
    None
}

pub(crate) fn forward(screen: &Screen, buf: &Buffers, out: &mut AaOutput) {
    let a = &buf.attrs;
    let (w, h, nch) = (a.width as usize, a.height as usize, a.channels);
    out.image.reset(a.width, a.height, nch);
    out.edges.clear();
    out.edges.resize(w * h * 8, NONE);
    out.vals.clear();
    out.vals.resize(w * h * 8, 1.0);
    let prims = &screen.prims;
    let ids = &buf.ids;
    out.image
        .data
        .par_chunks_mut(w * nch)
        .zip(out.edges.par_chunks_mut(w * 8))
        .zip(out.vals.par_chunks_mut(w * 8))
        .enumerate()
        .for_each(|(y, ((img, edges), vals))| {
            for x in 0..w {
                let i = y * w + x;
                let px = &mut img[x * nch..(x + 1) * nch];
                let cs = &a.data[i * nch..(i + 1) * nch];
                px.copy_from_slice(cs);
                let ids_ = ids[i];
                let centre = Vec2::new(x as f32, y as f32);
                for (k, &(dx, dy)) in N8.iter().enumerate() {
                    let (nx, ny) = (x as i32 + dx, y as i32 + dy);
                    if nx < 0 || ny < 0 || nx >= w as i32 || ny >= h as i32 {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    let idn = ids[j];
                    if idn == ids_ {
                        continue;
                    }
                    let cn = Vec2::new(nx as f32, ny as f32);
                    let Some((prim, edge)) = separating_edge(prims, centre, cn, ids_, idn) else { continue };
                    let (e0, e1) = prims[prim as usize].edge(edge as usize).unwrap_or_default();
                    let (r, _, _) = line_distance(centre, e0, e1);
                    if r >= 1.0 {
                        continue;
                    }
                    let wgt = (1.0 - r) * INV9;
                    let cnv = &a.data[j * nch..(j + 1) * nch];
                    for c in 0..nch {
                        px[c] += wgt * (cnv[c] - cs[c]);
                    }
                    edges[x * 8 + k] = prim * 4 + edge;
                    vals[x * 8 + k] = r;
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
                let mut wsum = 0.0;
                let centre = Vec2::new(x as f32, y as f32);
                for k in 0..8 {
                    let code = saved.edges[i * 8 + k];
                    if code != NONE {
                        let r = saved.vals[i * 8 + k];
                        wsum += (1.0 - r) * INV9;
                        // Geometry: ∂L/∂r = −(1/9) ⟨g(s), c(n) − c(s)⟩.
                        let (dx, dy) = N8[k];
                        let j = (y as i32 + dy) as usize * w + (x as i32 + dx) as usize;
                        let cn = &a.data[j * nch..(j + 1) * nch];
                        let mut dot = 0.0;
                        for c in 0..nch {
                            dot += gs[c] * (cn[c] - cs[c]);
                        }
                        if dot != 0.0 {
                            let (prim, edge) = (code >> 2, code & 3);
                            let (e0, e1) = prims[prim as usize].edge(edge as usize).unwrap_or_default();
                            let (_, g0, g1) = line_distance(centre, e0, e1);
                            let dl_dr = -INV9 * dot;
                            out.push((prim * 4 + edge, g0 * dl_dr));
                            out.push((prim * 4 + ((edge + 1) & 3), g1 * dl_dr));
                        }
                    }
                    // Colour: the neighbour n = s + o_k blends s's colour in with its slot 7 − k.
                    let (dx, dy) = N8[k];
                    let (nx, ny) = (x as i32 + dx, y as i32 + dy);
                    if nx < 0 || ny < 0 || nx >= w as i32 || ny >= h as i32 {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if saved.edges[j * 8 + 7 - k] != NONE {
                        let wn = (1.0 - saved.vals[j * 8 + 7 - k]) * INV9;
                        for c in 0..nch {
                            d[c] += wn * g[j * nch + c];
                        }
                    }
                }
                for c in 0..nch {
                    d[c] += (1.0 - wsum) * gs[c];
                }
            }
            out
        })
        .collect();
    scatter_corners(parts, grads);
}
