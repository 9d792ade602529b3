//! Similarity transforms (scale, rotation, translation) in f64: the map between a capture's own
//! frame (a photogrammetry tool's, in its units) and the canonical one (metres, Z up, the face
//! toward −Y) that head fitting finds, applied to meshes, strands and cameras.

use glam::{DMat3, DQuat, DVec3, Vec3};

use crate::{Camera, CameraError, StrandSet, TriMesh};

/// `x ↦ scale · rotation · x + translation`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Similarity {
    pub scale: f64,
    pub rotation: DMat3,
    pub translation: DVec3,
}

impl Similarity {
    pub const IDENTITY: Self = Self { scale: 1.0, rotation: DMat3::IDENTITY, translation: DVec3::ZERO };

    /// Maps a point.
    #[inline]
    pub fn apply(&self, p: DVec3) -> DVec3 {
        self.scale * (self.rotation * p) + self.translation
    }

    /// The inverse map.
    pub fn inverse(&self) -> Self {
        let rt = self.rotation.transpose();
        Self { scale: 1.0 / self.scale, rotation: rt, translation: -(rt * self.translation) / self.scale }
    }

    /// `self ∘ other`: `other` first.
    pub fn then_after(&self, other: &Self) -> Self {
        Self {
            scale: self.scale * other.scale,
            rotation: self.rotation * other.rotation,
            translation: self.apply(other.translation),
        }
    }

    /// The rotation as a unit axis and an angle in degrees (axis +Z for no rotation).
    pub fn axis_angle_degrees(&self) -> (DVec3, f64) {
        let (axis, angle) = DQuat::from_mat3(&self.rotation).normalize().to_axis_angle();
        if angle.abs() < 1e-12 {
            (DVec3::Z, 0.0)
        } else {
            (axis, angle.to_degrees())
        }
    }

    /// The angle of the rotation that takes `self`'s rotation to `other`'s, in degrees.
    pub fn rotation_angle_to(&self, other: &Self) -> f64 {
        let m = self.rotation.transpose() * other.rotation;
        ((m.x_axis.x + m.y_axis.y + m.z_axis.z - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
    }
}

/// Maps a mesh's vertices by a similarity (f64 inside), normals rotated; for callers that move a
/// raw mesh into the canonical frame.
pub fn transform_mesh(mesh: &TriMesh, s: &Similarity) -> TriMesh {
    let rot = s.rotation.as_mat3();
    TriMesh {
        vertices: mesh.vertices.iter().map(|v| s.apply(v.as_dvec3()).as_vec3()).collect(),
        triangles: mesh.triangles.clone(),
        normals: mesh.normals.as_ref().map(|n| n.iter().map(|&v: &Vec3| (rot * v).normalize_or_zero()).collect()),
        uvs: mesh.uvs.clone(),
    }
}

/// Maps strands' points by a similarity (f64 inside). An error only when a point becomes
/// non-finite.
pub fn transform_strands(strands: &StrandSet, s: &Similarity) -> Result<StrandSet, crate::StrandError> {
    strands.map_points(|p| s.apply(p.as_dvec3()).as_vec3())
}

/// The camera that sees `s`'s image of the world as `camera` sees the world: for a world point
/// `X`, `camera` projects `X` where the result projects `s(X)`. With `s(X) = c R_s X + T`:
/// `R' = R R_sᵀ`, `t' = c t − R R_sᵀ T` (the projective factor `1/c` drops out).
pub fn transform_camera(camera: &Camera, s: &Similarity) -> Result<Camera, CameraError> {
    let r = camera.r().as_dmat3() * s.rotation.transpose();
    let t = s.scale * camera.t().as_dvec3() - r * s.translation;
    let rows = |m: DMat3| {
        let m = m.transpose();
        [m.x_axis, m.y_axis, m.z_axis].map(|v| v.as_vec3().to_array())
    };
    Camera::new(camera.k_rows(), rows(r), t.as_vec3().to_array(), camera.width(), camera.height())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_moved_camera_projects_moved_points_where_it_projected_the_points() {
        let cam = Camera::look_at(Vec3::new(0.3, -0.9, 0.2), Vec3::ZERO, Vec3::Z, 0.6, 400, 600).unwrap();
        let s = Similarity {
            scale: 37.0,
            rotation: DMat3::from_rotation_x(0.7) * DMat3::from_rotation_z(-2.1),
            translation: DVec3::new(4.0, -9.0, 2.5),
        };
        let moved = transform_camera(&cam, &s).unwrap();
        for p in [Vec3::new(0.05, 0.02, 0.1), Vec3::new(-0.1, 0.08, -0.03), Vec3::ZERO] {
            let a = cam.project(p).unwrap().pixel;
            let b = moved.project(s.apply(p.as_dvec3()).as_vec3()).unwrap().pixel;
            assert!((a - b).length() < 2e-2, "{a} {b}");
        }
        let back = transform_camera(&moved, &s.inverse()).unwrap();
        assert!((back.center() - cam.center()).length() < 1e-5);
    }
}
