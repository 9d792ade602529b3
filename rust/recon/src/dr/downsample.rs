//! The targets at a coarser image scale, for the guide stage: each view `f` times smaller in both
//! directions, every block of `f × f` pixels one pixel (a remainder at the right or bottom edge is
//! dropped).
//!
//! The guide stage moves 2,000 guides and with them the 50,000 children that follow them: broad
//! moves that a coarser image resolves. A step's time grows with the pixels the strands cover (a
//! strand of sub-pixel width covers pixels along its length, so about in proportion to the image
//! height), and the losses are sums over pixels whose mean over a block a coarser pixel keeps:
//! - the camera: `fx`, `fy` and the skew over `f`; the principal point where the block's centre
//!   falls (pixel centres are at integer coordinates, so a block's centre is `(f − 1)/2` from its
//!   first pixel);
//! - the mask: the block's mean coverage;
//! - the orientation `(cos 2θ, sin 2θ)` with confidence `κ`: the direction of `Σ κ t` over the
//!   block, with confidence `|Σ κ t| / f²` (a block whose pixels disagree is less sure);
//! - the head's depth: the farthest of the block (a strand is hidden only where the head hides it
//!   in the whole block, so that a block the head's outline cuts stays visible).

use glam::Vec3;
use hairrecon_core::Camera;
use rayon::prelude::*;

use super::{DrError, DrTargets, DrView};

/// `camera` for an image `f` times smaller (see the module docs).
pub fn camera(camera: &Camera, f: u32) -> Result<Camera, DrError> {
    let (w, h) = (camera.width() / f, camera.height() / f);
    let mut k = camera.k_rows();
    let s = 1.0 / f as f32;
    let shift = 0.5 * (f as f32 - 1.0);
    k[0][0] *= s;
    k[0][1] *= s;
    k[1][1] *= s;
    k[0][2] = (k[0][2] - shift) * s;
    k[1][2] = (k[1][2] - shift) * s;
    let t = camera.t();
    Camera::new(k, camera.r_rows(), [t.x, t.y, t.z], w, h).map_err(|e| DrError::Downsample(format!("camera: {e}")))
}

/// One view's targets `f` times smaller (see the module docs).
pub fn view(v: &DrView, index: usize, f: u32) -> Result<DrView, DrError> {
    if v.camera.width() < f || v.camera.height() < f {
        return Err(DrError::Downsample(format!(
            "view {index} is {}x{} pixels, smaller than the factor {f}",
            v.camera.width(),
            v.camera.height()
        )));
    }
    let cam = camera(&v.camera, f)?;
    let w0 = v.camera.width() as usize;
    let (w, h) = (cam.width() as usize, cam.height() as usize);
    let f = f as usize;
    let n = (f * f) as f32;
    let block = |x: usize, y: usize| (0..f).flat_map(move |dy| (0..f).map(move |dx| (y * f + dy) * w0 + x * f + dx));
    let mut mask = vec![0.0f32; w * h];
    let mut orientation = vec![[0.0f32; 3]; w * h];
    let mut depth = v.head_depth.as_ref().map(|_| vec![0.0f32; w * h]);
    mask.par_chunks_mut(w).zip(orientation.par_chunks_mut(w)).enumerate().for_each(|(y, (m_row, o_row))| {
        for x in 0..w {
            m_row[x] = block(x, y).map(|p| v.mask[p]).sum::<f32>() / n;
            let sum = block(x, y).fold(Vec3::ZERO, |acc, p| {
                let [c, s, k] = v.orientation[p];
                acc + Vec3::new(k * c, k * s, 0.0)
            });
            let len = sum.length();
            o_row[x] = if len > 0.0 { [sum.x / len, sum.y / len, len / n] } else { [0.0; 3] };
        }
    });
    if let (Some(d), Some(src)) = (depth.as_mut(), v.head_depth.as_ref()) {
        d.par_chunks_mut(w).enumerate().for_each(|(y, row)| {
            for (x, out) in row.iter_mut().enumerate() {
                *out = block(x, y).map(|p| src[p]).fold(f32::NEG_INFINITY, f32::max);
            }
        });
    }
    DrView::new(index, cam, mask, orientation, depth)
}

/// Every view of `targets` `f` times smaller; `f = 1` gives a copy.
pub fn targets(targets: &DrTargets, f: u32) -> Result<DrTargets, DrError> {
    if f <= 1 {
        return Ok(targets.clone());
    }
    let views = targets.views.iter().enumerate().map(|(i, v)| view(v, i, f)).collect::<Result<_, _>>()?;
    Ok(DrTargets { views })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam(w: u32, h: u32) -> Camera {
        Camera::new(
            [[300.0, 0.0, (w as f32 - 1.0) / 2.0], [0.0, 300.0, (h as f32 - 1.0) / 2.0], [0.0, 0.0, 1.0]],
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            [0.0, 0.0, 0.5],
            w,
            h,
        )
        .unwrap()
    }

    #[test]
    fn a_point_lands_in_the_block_that_held_it() {
        let c = cam(40, 30);
        let d = camera(&c, 2).unwrap();
        assert_eq!((d.width(), d.height()), (20, 15));
        for p in [Vec3::new(0.01, -0.02, 0.1), Vec3::new(-0.03, 0.015, 0.2), Vec3::ZERO] {
            let fine = c.project(p).unwrap().pixel;
            let coarse = d.project(p).unwrap().pixel;
            // Fine pixel u lies in block floor((u + 0.5) / 2), whose centre is at coarse integer
            // coordinates: coarse = (u - 0.5) / 2.
            assert!((coarse.x - (fine.x - 0.5) / 2.0).abs() < 1e-4, "{fine} {coarse}");
            assert!((coarse.y - (fine.y - 0.5) / 2.0).abs() < 1e-4, "{fine} {coarse}");
        }
    }

    #[test]
    fn blocks_average_the_mask_and_weigh_orientations_by_confidence() {
        let c = cam(4, 2);
        let n = 8;
        let mut mask = vec![0.0; n];
        mask[0] = 1.0;
        mask[1] = 1.0;
        mask[4] = 0.5;
        // Left block: two pixels at 0° (confident), one at 90° (weak), one without confidence.
        // Right block: two pixels at +45° and two at -45° of equal confidence: no direction.
        let dir = |deg: f32, k: f32| {
            let a = 2.0 * deg.to_radians();
            [a.cos(), a.sin(), k]
        };
        let orientation = vec![
            dir(0.0, 1.0),
            dir(0.0, 1.0),
            dir(45.0, 0.5),
            dir(-45.0, 0.5),
            dir(90.0, 0.5),
            dir(0.0, 0.0),
            dir(45.0, 0.5),
            dir(-45.0, 0.5),
        ];
        let depth = vec![1.0, 2.0, 1.0, f32::INFINITY, 3.0, 0.5, 1.0, 1.0];
        let v = DrView::new(0, c, mask, orientation, Some(depth)).unwrap();
        let d = view(&v, 0, 2).unwrap();
        assert_eq!(d.mask, vec![2.5 / 4.0, 0.0]);
        // Σ κ t on the left: 2·(1, 0) + 0.5·(−1, 0) = (1.5, 0), confidence 1.5 / 4.
        let [c0, s0, k0] = d.orientation[0];
        assert!((c0 - 1.0).abs() < 1e-6 && s0.abs() < 1e-6 && (k0 - 0.375).abs() < 1e-6, "{:?}", d.orientation[0]);
        assert!(d.orientation[1][2] < 1e-6, "{:?}", d.orientation[1]);
        assert_eq!(d.head_depth.unwrap(), vec![3.0, f32::INFINITY]);
    }

    #[test]
    fn a_factor_of_one_is_a_copy() {
        let c = cam(3, 3);
        let v = DrView::new(0, c, vec![0.5; 9], vec![[1.0, 0.0, 1.0]; 9], None).unwrap();
        let t = DrTargets { views: vec![v] };
        let d = targets(&t, 1).unwrap();
        assert_eq!(d.views[0].mask, t.views[0].mask);
        assert_eq!(d.views[0].camera.width(), 3);
    }
}
