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
//! ([`crate::screen`]), so no internal diagonal can be chosen. The distance is to the edge as a
//! segment (to its nearer end beyond its ends), so that pixels near a tip see the tip itself.
//!
//! Our addition for the other weak spot of that reading (a primitive that covers no pixel centre makes
//! no id boundary, so gets no gradient): a pixel `s` within 1 px of a primitive `P` that covers
//! neither `s`'s centre nor any of its 8 neighbours' (and is in front of what `s` shows) treats `P` as
//! a virtual ninth neighbour: `ĉ(s) += (1/9)(1 − r)(c_P − c(s))` with `r` the distance from the centre
//! of `s` to `P` (its nearest edge), and the same gradient through `r`. Only the nearest such `P`
//! counts. The thin tip of a triangle, which covers no pixel centre, thus still pulls on its apex.

use glam::Vec2;
use rayon::prelude::*;

use crate::aa_output::{scatter_corners, AaOutput, N8, NONE};
use crate::image::Image;
use crate::rasterize::channel;
use crate::rasterize::{orient_grad, pixel_range_margin, Buffers, BAND};
use crate::screen::{crossing, segment_distance as edge_distance, Prim, Screen, SegmentGrads};

const INV9: f32 = 1.0 / 9.0;

/// The separating edge between pixel centres `cs` (id `ids`) and `cn` (id `idn`), as
/// `(prim, edge)`.
#[inline]
fn separating_edge(prims: &[Prim], cs: Vec2, cn: Vec2, ids: u32, idn: u32) -> Option<(u32, u32)> {
    if idn != 0 {
        let p = &prims[idn as usize - 1];
        let mut best: Option<(f32, u32)> = None;
        let edges = p.edges();
        for k in 0..4 {
            if let Some((e0, e1)) = edges[k] {
                if let Some(t) = crossing(cs, cn, e0, e1) {
                    if !matches!(best, Some((bt, _)) if t <= bt) {
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
        let edges = p.edges();
        for k in 0..4 {
            if let Some((e0, e1)) = edges[k] {
                if let Some(t) = crossing(cs, cn, e0, e1) {
                    if !matches!(best, Some((bt, _)) if t >= bt) {
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

/// Slots per pixel: the 8 neighbours, then the nearest uncovered primitive.
const SLOTS: usize = 9;

/// Columns per block of [`near_pass`]'s depth culling.
const TILE: usize = 4;

/// The attributes a primitive writes, in the channel layout of [`crate::rasterize`].
#[inline]
fn prim_attrs(screen: &Screen, prim: usize, nch: usize) -> [f32; 6] {
    let mut c = [0.0; 6];
    let orient = screen.prims[prim].orient();
    c[channel::COVERAGE] = 1.0;
    c[channel::COS2] = orient.x;
    c[channel::SIN2] = orient.y;
    if nch >= 6 {
        let d = screen.dir3[prim];
        c[channel::DIR3] = d.x;
        c[channel::DIR3 + 1] = d.y;
        c[channel::DIR3 + 2] = d.z;
    }
    c
}

/// Distance from `c` to the boundary of `p` (nearest edge), with that edge.
#[inline]
fn polygon_distance(p: &Prim, c: Vec2) -> (f32, u32) {
    let mut best = (f32::INFINITY, 0u32);
    for k in 0..4 {
        if let Some((e0, e1)) = p.edge(k) {
            let (r, _, _) = edge_distance(c, e0, e1);
            if r < best.0 {
                best = (r, k as u32);
            }
        }
    }
    best
}

/// Fills slot 8 of every pixel: the nearest primitive within 1 px that covers neither the pixel's
/// centre nor any neighbour's.
fn near_pass(screen: &Screen, buf: &Buffers, edges: &mut [u32], vals: &mut [f32]) {
    let (w, h) = (buf.width() as usize, buf.height() as usize);
    let prims = &screen.prims;
    let (ids, depth, bins) = (&buf.ids, &buf.depth, &buf.bins);
    edges.par_chunks_mut(w * BAND * SLOTS).zip(vals.par_chunks_mut(w * BAND * SLOTS)).enumerate().for_each(
        |(band, (edges, vals))| {
            let row0 = band * BAND;
            let row1 = row0 + edges.len() / (w * SLOTS);
            // The deepest visible depth of each block of TILE columns of the band: a primitive
            // behind it over all the blocks it touches fails the depth test at each of its pixels
            // (its depth there is at least its nearer end's), so it is skipped whole.
            let far: Vec<f32> = (0..w.div_ceil(TILE))
                .map(|bx| {
                    let (x0, x1) = (bx * TILE, ((bx + 1) * TILE).min(w));
                    (row0..row1).flat_map(|y| &depth[y * w + x0..y * w + x1]).fold(0.0f32, |m, &d| m.max(d))
                })
                .collect();
            for chunk in bins {
                let Some(list) = chunk.get(band) else { continue };
                for &si in list {
                    let p = &prims[si as usize];
                    let Some(r) = pixel_range_margin(p, w as u32, h as u32, 1.0) else { continue };
                    // 1e-5: the interpolated depth may round below the nearer end by an ulp.
                    let near = p.z0.min(p.z1) * (1.0 - 1e-5);
                    if near > 0.0 && far[r[0] / TILE..=r[2] / TILE].iter().all(|&f| near >= f) {
                        continue;
                    }
                    for y in r[1].max(row0)..=r[3].min(row1 - 1) {
                        for x in r[0]..=r[2] {
                            let i = y * w + x;
                            let c = Vec2::new(x as f32, y as f32);
                            // Cheap tests first: own pixel, occluded, covered.
                            if ids[i] == si + 1 || p.depth_at(c) >= depth[i] || p.contains(c) {
                                continue;
                            }
                            let (dist, edge) = polygon_distance(p, c);
                            let slot = (i - row0 * w) * SLOTS + 8;
                            if dist >= 1.0 || dist >= vals[slot] {
                                continue;
                            }
                            let touches = N8.iter().any(|&(dx, dy)| {
                                let (nx, ny) = (x as i32 + dx, y as i32 + dy);
                                nx >= 0
                                    && ny >= 0
                                    && nx < w as i32
                                    && ny < h as i32
                                    && ids[ny as usize * w + nx as usize] == si + 1
                            });
                            if touches {
                                continue;
                            }
                            edges[slot] = si * 4 + edge;
                            vals[slot] = dist;
                        }
                    }
                }
            }
        },
    );
}

pub(crate) fn forward(screen: &Screen, buf: &Buffers, out: &mut AaOutput) {
    let a = &buf.attrs;
    let (w, h, nch) = (a.width as usize, a.height as usize, a.channels);
    out.image.reset(a.width, a.height, nch);
    out.edges.clear();
    out.edges.resize(w * h * SLOTS, NONE);
    out.vals.clear();
    out.vals.resize(w * h * SLOTS, 1.0);
    near_pass(screen, buf, &mut out.edges, &mut out.vals);
    let prims = &screen.prims;
    let ids = &buf.ids;
    out.image
        .data
        .par_chunks_mut(w * nch)
        .zip(out.edges.par_chunks_mut(w * SLOTS))
        .zip(out.vals.par_chunks_mut(w * SLOTS))
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
                    let (r, _, _) = edge_distance(centre, e0, e1);
                    if r >= 1.0 {
                        continue;
                    }
                    let wgt = (1.0 - r) * INV9;
                    let cnv = &a.data[j * nch..(j + 1) * nch];
                    for c in 0..nch {
                        px[c] += wgt * (cnv[c] - cs[c]);
                    }
                    edges[x * SLOTS + k] = prim * 4 + edge;
                    vals[x * SLOTS + k] = r;
                }
                let code = edges[x * SLOTS + 8];
                if code != NONE {
                    let cp = prim_attrs(screen, (code >> 2) as usize, nch);
                    let wgt = (1.0 - vals[x * SLOTS + 8]) * INV9;
                    for c in 0..nch {
                        px[c] += wgt * (cp[c] - cs[c]);
                    }
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
    type Parts = (Vec<(u32, Vec2)>, Vec<(u32, Vec2)>);
    let parts: Vec<Parts> = d_attrs
        .data
        .par_chunks_mut(w * nch)
        .enumerate()
        .map(|(y, drow)| {
            let mut out = Vec::new();
            let mut dirs = Vec::new();
            for x in 0..w {
                let i = y * w + x;
                let gs = &g[i * nch..(i + 1) * nch];
                let cs = &a.data[i * nch..(i + 1) * nch];
                let d = &mut drow[x * nch..(x + 1) * nch];
                let mut wsum = 0.0;
                let centre = Vec2::new(x as f32, y as f32);
                for k in 0..SLOTS {
                    let code = saved.edges[i * SLOTS + k];
                    if code != NONE {
                        let r = saved.vals[i * SLOTS + k];
                        let wk = (1.0 - r) * INV9;
                        wsum += wk;
                        let (prim, edge) = (code >> 2, code & 3);
                        let p = &prims[prim as usize];
                        // Geometry: ∂L/∂r = −(1/9) ⟨g(s), c(n) − c(s)⟩.
                        let pc;
                        let cn: &[f32] = if k < 8 {
                            let (dx, dy) = N8[k];
                            let j = (y as i32 + dy) as usize * w + (x as i32 + dx) as usize;
                            &a.data[j * nch..(j + 1) * nch]
                        } else {
                            pc = prim_attrs(screen, prim as usize, nch);
                            // The virtual neighbour's colour is the primitive's: orientation gradient.
                            dirs.push((prim, orient_grad(p, wk * gs[channel::COS2], wk * gs[channel::SIN2])));
                            &pc[..nch]
                        };
                        let mut dot = 0.0;
                        for c in 0..nch {
                            dot += gs[c] * (cn[c] - cs[c]);
                        }
                        if dot != 0.0 {
                            let (e0, e1) = p.edge(edge as usize).unwrap_or_default();
                            let (_, g0, g1) = edge_distance(centre, e0, e1);
                            let dl_dr = -INV9 * dot;
                            out.push((prim * 4 + edge, g0 * dl_dr));
                            out.push((prim * 4 + ((edge + 1) & 3), g1 * dl_dr));
                        }
                    }
                    if k == 8 {
                        continue;
                    }
                    // Colour: the neighbour n = s + o_k blends s's colour in with its slot 7 − k.
                    let (dx, dy) = N8[k];
                    let (nx, ny) = (x as i32 + dx, y as i32 + dy);
                    if nx < 0 || ny < 0 || nx >= w as i32 || ny >= h as i32 {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if saved.edges[j * SLOTS + 7 - k] != NONE {
                        let wn = (1.0 - saved.vals[j * SLOTS + 7 - k]) * INV9;
                        for c in 0..nch {
                            d[c] += wn * g[j * nch + c];
                        }
                    }
                }
                for c in 0..nch {
                    d[c] += (1.0 - wsum) * gs[c];
                }
            }
            (out, dirs)
        })
        .collect();
    let mut corners = Vec::with_capacity(parts.len());
    for (c, dirs) in parts {
        for (s, g) in dirs {
            grads.add_dir(s, g);
        }
        corners.push(c);
    }
    scatter_corners(corners, grads);
}
