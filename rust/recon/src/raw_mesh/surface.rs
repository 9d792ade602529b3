//! Surface extraction from a TSDF grid and light clean-up of the result.
//!
//! In: a [`TsdfGrid`]. Out: a triangle mesh of its zero level set with outward normals (pointing
//! to positive distances, i.e. toward the cameras).
//!
//! - [`surface_nets`]: naive surface nets (Gibson, "Constrained Elastic Surface Nets", 1998, in the
//!   simple form popularised by M. Lysenko's "Smooth Voxel Terrain" notes): one vertex per cell whose
//!   corners change sign, placed at the mean of the edge zero crossings, and one quad (two
//!   triangles) per grid edge that crosses zero, joining the four cells around that edge. Only cells
//!   whose eight corners were all observed take part, so no surface appears at the border of the
//!   observed space. Far simpler than marching cubes and without its ambiguous cases; the output is
//!   a quad mesh of about the same quality.
//! - [`taubin_smooth`]: Taubin's λ|μ smoothing (Taubin, "A Signal Processing Approach to Fair
//!   Surface Design", SIGGRAPH 1995), which smooths without the shrinkage of plain Laplacian
//!   smoothing.
//! - [`drop_small_components`]: removes connected pieces with fewer triangles than a threshold.

use glam::Vec3;
use hairrecon_core::TriMesh;
use rayon::prelude::*;

use super::tsdf::TsdfGrid;

/// The four cell offsets (in the two axes other than the edge's) around a grid edge, in
/// counter-clockwise order seen from the positive end of the edge's axis.
const RING: [(u32, u32); 4] = [(0, 0), (1, 0), (1, 1), (0, 1)];

/// Extracts the zero level set of `grid` as triangles. Returns (vertices, triangles).
pub fn surface_nets(grid: &TsdfGrid) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (nx, ny, nz) = (grid.dims.x, grid.dims.y, grid.dims.z);
    if nx < 2 || ny < 2 || nz < 2 {
        return (Vec::new(), Vec::new());
    }
    let (cx, cy, cz) = (nx - 1, ny - 1, nz - 1); // cells per axis
    let cell_index = |i: u32, j: u32, k: u32| i as usize + cx as usize * (j as usize + cy as usize * k as usize);
    // 1. One vertex per sign-changing, fully observed cell (parallel over cell slices).
    let per_slice: Vec<Vec<(usize, Vec3)>> = (0..cz)
        .into_par_iter()
        .map(|k| {
            let mut out = Vec::new();
            for j in 0..cy {
                for i in 0..cx {
                    if let Some(p) = cell_vertex(grid, i, j, k) {
                        out.push((cell_index(i, j, k), p));
                    }
                }
            }
            out
        })
        .collect();
    let mut vertex_of_cell = vec![u32::MAX; cx as usize * cy as usize * cz as usize];
    let mut vertices = Vec::with_capacity(per_slice.iter().map(Vec::len).sum());
    for (c, p) in per_slice.into_iter().flatten() {
        vertex_of_cell[c] = vertices.len() as u32;
        vertices.push(p);
    }
    // 2. One quad per sign-changing grid edge whose four surrounding cells all have a vertex.
    let quads: Vec<Vec<[u32; 4]>> = (0..nz)
        .into_par_iter()
        .map(|k| {
            let mut out = Vec::new();
            for j in 0..ny {
                for i in 0..nx {
                    let a = grid.index(i, j, k);
                    if grid.weight[a] <= 0.0 {
                        continue;
                    }
                    for axis in 0..3 {
                        let (ti, tj, tk) = match axis {
                            0 => (i + 1, j, k),
                            1 => (i, j + 1, k),
                            _ => (i, j, k + 1),
                        };
                        if ti >= nx || tj >= ny || tk >= nz {
                            continue;
                        }
                        let b = grid.index(ti, tj, tk);
                        if grid.weight[b] <= 0.0 {
                            continue;
                        }
                        let (sa, sb) = (grid.tsdf[a] < 0.0, grid.tsdf[b] < 0.0);
                        if sa == sb {
                            continue;
                        }
                        // Cells around the edge: the edge's two other axes step by -1 and 0.
                        let mut q = [0u32; 4];
                        let mut ok = true;
                        for (n, &(du, dv)) in RING.iter().enumerate() {
                            let (ci, cj, ck) = match axis {
                                0 => (Some(i), (j + du).checked_sub(1), (k + dv).checked_sub(1)),
                                1 => ((i + dv).checked_sub(1), Some(j), (k + du).checked_sub(1)),
                                _ => ((i + du).checked_sub(1), (j + dv).checked_sub(1), Some(k)),
                            };
                            let v = match (ci, cj, ck) {
                                (Some(ci), Some(cj), Some(ck)) if ci < cx && cj < cy && ck < cz => {
                                    vertex_of_cell[cell_index(ci, cj, ck)]
                                }
                                _ => u32::MAX,
                            };
                            if v == u32::MAX {
                                ok = false;
                                break;
                            }
                            q[n] = v;
                        }
                        if !ok {
                            continue;
                        }
                        // RING winds around +axis; the normal must point from negative to positive.
                        if sb {
                            q.reverse(); // positive at the low end: the normal points to -axis
                        }
                        out.push(q);
                    }
                }
            }
            out
        })
        .collect();
    let mut triangles = Vec::new();
    for q in quads.into_iter().flatten() {
        // Split along the shorter diagonal.
        let d02 = vertices[q[0] as usize].distance_squared(vertices[q[2] as usize]);
        let d13 = vertices[q[1] as usize].distance_squared(vertices[q[3] as usize]);
        if d02 <= d13 {
            triangles.push([q[0], q[1], q[2]]);
            triangles.push([q[0], q[2], q[3]]);
        } else {
            triangles.push([q[0], q[1], q[3]]);
            triangles.push([q[1], q[2], q[3]]);
        }
    }
    (vertices, triangles)
}

/// The surface-nets vertex of cell (i, j, k): the mean of the zero crossings on its 12 edges, or
/// `None` when some corner is unobserved or no edge crosses zero.
fn cell_vertex(grid: &TsdfGrid, i: u32, j: u32, k: u32) -> Option<Vec3> {
    let mut v = [0.0f32; 8];
    for (c, val) in v.iter_mut().enumerate() {
        let (di, dj, dk) = ((c & 1) as u32, ((c >> 1) & 1) as u32, ((c >> 2) & 1) as u32);
        let idx = grid.index(i + di, j + dj, k + dk);
        if grid.weight[idx] <= 0.0 {
            return None;
        }
        *val = grid.tsdf[idx];
    }
    let (mut sum, mut n) = (Vec3::ZERO, 0u32);
    for a in 0..8usize {
        for bit in [1usize, 2, 4] {
            let b = a | bit;
            if b == a {
                continue;
            }
            if (v[a] < 0.0) != (v[b] < 0.0) {
                let t = v[a] / (v[a] - v[b]);
                let pa = Vec3::new((a & 1) as f32, ((a >> 1) & 1) as f32, ((a >> 2) & 1) as f32);
                let pb = Vec3::new((b & 1) as f32, ((b >> 1) & 1) as f32, ((b >> 2) & 1) as f32);
                sum += pa + t * (pb - pa);
                n += 1;
            }
        }
    }
    (n > 0).then(|| grid.position(i, j, k) + grid.voxel * sum / n as f32)
}

/// Vertex neighbours from the triangles (sorted, deduplicated).
fn neighbours(n: usize, triangles: &[[u32; 3]]) -> Vec<Vec<u32>> {
    let mut nb = vec![Vec::new(); n];
    for t in triangles {
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            nb[a as usize].push(b);
            nb[b as usize].push(a);
        }
    }
    nb.par_iter_mut().for_each(|v| {
        v.sort_unstable();
        v.dedup();
    });
    nb
}

/// Taubin λ|μ smoothing with the uniform Laplacian: `iterations` pairs of steps, λ = 0.5, μ = -0.53.
pub fn taubin_smooth(vertices: &mut [Vec3], triangles: &[[u32; 3]], iterations: u32) {
    let nb = neighbours(vertices.len(), triangles);
    let mut next = vertices.to_vec();
    for _ in 0..iterations {
        for factor in [0.5f32, -0.53] {
            next.par_iter_mut().enumerate().for_each(|(i, out)| {
                let p = vertices[i];
                let ns = &nb[i];
                *out = if ns.is_empty() {
                    p
                } else {
                    let mean = ns.iter().map(|&j| vertices[j as usize]).sum::<Vec3>() / ns.len() as f32;
                    p + factor * (mean - p)
                };
            });
            vertices.copy_from_slice(&next);
        }
    }
}

/// A copy of `mesh` Taubin-smoothed by `pairs` pairs of steps ([`taubin_smooth`]), with the
/// vertices at one position moved as one (a mesh split at UV seams does not tear). The triangles,
/// the vertex order and the UVs are kept; vertex normals are dropped.
pub fn smoothed(mesh: &TriMesh, pairs: u32) -> TriMesh {
    let (mut welded, weld) = mesh.weld_positions();
    let triangles: Vec<[u32; 3]> = mesh.triangles.iter().map(|t| t.map(|v| weld[v as usize])).collect();
    taubin_smooth(&mut welded, &triangles, pairs);
    let vertices = weld.iter().map(|&w| welded[w as usize]).collect();
    TriMesh { vertices, triangles: mesh.triangles.clone(), normals: None, uvs: mesh.uvs.clone() }
}

/// Keeps the connected components (by shared vertices) with at least `min_triangles` triangles,
/// and drops vertices that no triangle uses. Returns the new (vertices, triangles).
pub fn drop_small_components(
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    min_triangles: usize,
) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    // Union-find over vertices.
    let mut parent: Vec<u32> = (0..vertices.len() as u32).collect();
    fn find(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            parent[x as usize] = parent[parent[x as usize] as usize];
            x = parent[x as usize];
        }
        x
    }
    for t in triangles {
        let a = find(&mut parent, t[0]);
        for &v in &t[1..] {
            let b = find(&mut parent, v);
            if a != b {
                parent[b as usize] = a;
            }
        }
    }
    let mut size = vec![0usize; vertices.len()];
    let roots: Vec<u32> = triangles.iter().map(|t| find(&mut parent, t[0])).collect();
    for &r in &roots {
        size[r as usize] += 1;
    }
    let mut remap = vec![u32::MAX; vertices.len()];
    let mut out_v = Vec::new();
    let mut out_t = Vec::new();
    for (t, &r) in triangles.iter().zip(&roots) {
        if size[r as usize] < min_triangles {
            continue;
        }
        let mut nt = [0u32; 3];
        for (c, &v) in t.iter().enumerate() {
            if remap[v as usize] == u32::MAX {
                remap[v as usize] = out_v.len() as u32;
                out_v.push(vertices[v as usize]);
            }
            nt[c] = remap[v as usize];
        }
        out_t.push(nt);
    }
    (out_v, out_t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::UVec3;

    /// A grid holding the exact (truncated) signed distance of a sphere: surface nets must give a
    /// closed surface whose vertices lie on the sphere to within a tenth of a voxel and whose
    /// normals point outward.
    #[test]
    fn surface_nets_of_a_sphere_is_closed_accurate_and_outward() {
        let (voxel, trunc, radius) = (0.01f32, 0.03f32, 0.2f32);
        let mut g = TsdfGrid::new(Vec3::splat(-0.3), Vec3::splat(0.3), voxel, trunc);
        assert_eq!(g.dims, UVec3::splat(61));
        for k in 0..g.dims.z {
            for j in 0..g.dims.y {
                for i in 0..g.dims.x {
                    let idx = g.index(i, j, k);
                    let d = g.position(i, j, k).length() - radius;
                    g.tsdf[idx] = (d / trunc).clamp(-1.0, 1.0);
                    g.weight[idx] = 1.0;
                }
            }
        }
        let (v, t) = surface_nets(&g);
        assert!(t.len() > 1000, "{} triangles", t.len());
        let worst = v.iter().map(|p| (p.length() - radius).abs()).fold(0.0f32, f32::max);
        assert!(worst < 0.1 * voxel, "worst radial error {worst}");
        // Closed: every edge is shared by exactly two triangles, in opposite directions.
        let mut edges = std::collections::HashMap::new();
        for tri in &t {
            for e in 0..3 {
                *edges.entry((tri[e], tri[(e + 1) % 3])).or_insert(0) += 1;
            }
        }
        for (&(a, b), &n) in &edges {
            assert_eq!(n, 1, "edge {a}-{b} used {n} times in the same direction");
            assert!(edges.contains_key(&(b, a)), "edge {a}-{b} has no twin: the surface has a hole");
        }
        // Outward: the face normal agrees with the position's direction.
        for tri in &t {
            let [a, b, c] = tri.map(|i| v[i as usize]);
            let n = (b - a).cross(c - a);
            assert!(n.dot(a + b + c) > 0.0, "inward triangle {tri:?}");
        }
        // Taubin smoothing keeps the radius (no shrinkage beyond a fraction of a voxel).
        let mut vs = v.clone();
        taubin_smooth(&mut vs, &t, 5);
        let mean_r = vs.iter().map(|p| p.length()).sum::<f32>() / vs.len() as f32;
        assert!((mean_r - radius).abs() < 0.1 * voxel, "mean radius after smoothing {mean_r}");
    }

    #[test]
    fn small_components_are_dropped() {
        let v = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE, Vec3::new(2.0, 0.0, 0.0), Vec3::splat(5.0)];
        let t = vec![[0, 1, 2], [0, 2, 3], [1, 2, 3], [4, 5, 6]];
        let (nv, nt) = drop_small_components(&v, &t, 2);
        assert_eq!(nt.len(), 3);
        assert_eq!(nv.len(), 4);
    }

    /// A noisy plane cut in two along a seam (its vertices there doubled, as a mesh split at UV
    /// seams has them): [`smoothed`] moves both copies as one, keeps the triangles, and takes the
    /// noise down (Taubin's filter passes the plane and halves this white noise).
    #[test]
    fn smoothing_a_split_mesh_keeps_its_seam_closed_and_takes_the_noise_out() {
        let n = 21usize;
        let mut s = 7u32;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as f32 / u32::MAX as f32 - 0.5
        };
        let heights: Vec<f32> = (0..n * n).map(|_| 0.002 * rnd()).collect();
        let seam = n / 2;
        let mut vertices = Vec::new();
        let mut index = vec![[0u32; 2]; n * n];
        for j in 0..n {
            for i in 0..n {
                let p = Vec3::new(0.01 * i as f32, 0.01 * j as f32, heights[j * n + i]);
                index[j * n + i] = [vertices.len() as u32; 2];
                vertices.push(p);
                if i == seam {
                    index[j * n + i][1] = vertices.len() as u32;
                    vertices.push(p);
                }
            }
        }
        // Left of the seam uses the first copy, right of it the second.
        let at = |i: usize, j: usize, right: bool| index[j * n + i][usize::from(right && i == seam)];
        let mut triangles = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                let right = i >= seam;
                let (a, b, c, d) = (at(i, j, right), at(i + 1, j, right), at(i, j + 1, right), at(i + 1, j + 1, right));
                triangles.push([a, b, d]);
                triangles.push([a, d, c]);
            }
        }
        let mesh = TriMesh::new(vertices, triangles, None, None).unwrap();
        let out = smoothed(&mesh, 5);
        assert_eq!(out.triangles, mesh.triangles);
        for j in 0..n {
            let [l, r] = index[j * n + seam];
            assert_ne!(l, r);
            assert_eq!(out.vertices[l as usize], out.vertices[r as usize], "the seam opened at row {j}");
        }
        // Inner vertices only: the rim has no neighbours beyond it and Taubin's filter pulls it in.
        let rms = |m: &TriMesh| {
            let inner: Vec<f32> = m
                .vertices
                .iter()
                .filter(|p| p.x > 0.025 && p.x < 0.175 && p.y > 0.025 && p.y < 0.175)
                .map(|p| p.z * p.z)
                .collect();
            (inner.iter().sum::<f32>() / inner.len() as f32).sqrt()
        };
        let (before, after) = (rms(&mesh), rms(&out));
        assert!(after < 0.6 * before, "noise {before} -> {after}"); // 0.49 when written
    }
}
