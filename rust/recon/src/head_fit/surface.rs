//! The raw mesh as the fit queries it: exact closest points (core's [`Bvh`]) with a smoothed
//! normal field. Photogrammetry and fusion meshes are noisy at the scale of their triangles (half a
//! millimetre of noise on 1–2 mm triangles turns face normals by tens of degrees), and the
//! point-to-plane steps follow the normals: each vertex's area-weighted normal, averaged over its
//! neighbours a few times (about the width of a few triangles), interpolated at the closest point.

use glam::{DVec3, Vec3};
use hairrecon_core::{Bvh, TriMesh};

use super::icp::{Match, Target};

/// The raw mesh with its smoothed vertex normals.
#[derive(Debug)]
pub struct RawSurface {
    pub bvh: Bvh,
    normals: Vec<Vec3>,
}

impl RawSurface {
    /// The surface of `mesh`, its vertex normals averaged with their neighbours' `smoothing` times.
    pub fn new(mesh: TriMesh, smoothing: usize) -> Self {
        let mut normals = mesh.compute_vertex_normals();
        if smoothing > 0 {
            let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); mesh.vertices.len()];
            for t in &mesh.triangles {
                for k in 0..3 {
                    neighbours[t[k] as usize].push(t[(k + 1) % 3]);
                }
            }
            for _ in 0..smoothing {
                normals = (0..normals.len())
                    .map(|i| {
                        let sum = neighbours[i].iter().fold(normals[i], |s, &j| s + normals[j as usize]);
                        sum.normalize_or(normals[i])
                    })
                    .collect();
            }
        }
        Self { bvh: Bvh::new(mesh), normals }
    }

    pub fn mesh(&self) -> &TriMesh {
        self.bvh.mesh()
    }
}

impl Target for RawSurface {
    #[inline]
    fn closest(&self, p: DVec3, cap: f64) -> Match {
        match self.bvh.closest_point(p.as_vec3(), cap as f32) {
            Some(c) => {
                let t = self.mesh().triangles[c.triangle as usize];
                let n = c.bary.x * self.normals[t[0] as usize]
                    + c.bary.y * self.normals[t[1] as usize]
                    + c.bary.z * self.normals[t[2] as usize];
                let normal = n.normalize_or(self.mesh().face_normal(c.triangle as usize)).as_dvec3();
                Match { point: c.point.as_dvec3(), normal, distance: (c.point.as_dvec3() - p).length() }
            }
            None => Match { point: p, normal: DVec3::ZERO, distance: cap },
        }
    }

    #[inline]
    fn crosses(&self, p: DVec3, dir: DVec3, reach: f64) -> bool {
        self.bvh.crosses(p, dir, reach)
    }
}
