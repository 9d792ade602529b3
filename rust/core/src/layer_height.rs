//! How far hair stands off the scalp over the crown: the hair layer's height, patch by patch.
//!
//! The strand metric ([`crate::metric`]) matches points at a distance; it does not say whether
//! reconstructed hair stands as high above the scalp as the real hair does (hair with volume stands
//! 1–3 cm off the skin at the crown, and a reconstruction that hugs the scalp misses all of it).
//! Here every strand point (strands resampled by arc length) finds its closest point on the scalp
//! within [`MAX_HEIGHT`]; a point whose foot lies on the crown (the scalp's outward normal within 45°
//! of up, +Z of the canonical frame) falls into the [`CELL`]-wide square of the foot's x, y. A cell's
//! height is the median distance of its points. Two strand sets compare cell by cell where both have
//! at least [`MIN_POINTS`] points: the median over cells of the absolute difference.

use std::collections::HashMap;

use glam::Vec3;
use serde::Serialize;

use crate::mesh::Bvh;
use crate::strands::{StrandError, StrandSet};

/// Points farther than this from the scalp are not on the crown's layer (metres).
pub const MAX_HEIGHT: f32 = 0.05;
/// Width of a cell of the crown (metres).
pub const CELL: f32 = 0.01;
/// Points a cell needs in each strand set to be compared.
pub const MIN_POINTS: usize = 20;
/// The crown: where the scalp's outward normal is within 45° of +Z.
const CROWN_COS: f32 = std::f32::consts::FRAC_1_SQRT_2;

/// Per crown cell, the median height of the hair points above it (metres).
#[derive(Debug, Clone, Default)]
pub struct LayerHeights {
    cells: HashMap<(i32, i32), (f32, usize)>,
}

impl LayerHeights {
    /// The heights of `strands` above `scalp` (a mesh in the canonical frame, Z up), the strands
    /// resampled every `step` metres.
    pub fn measure(strands: &StrandSet, scalp: &Bvh, step: f32) -> Result<Self, StrandError> {
        let dense = strands.resample_by_arclength(step)?;
        let mesh = scalp.mesh();
        let centre = mesh.vertices.iter().copied().sum::<Vec3>() / mesh.vertices.len().max(1) as f32;
        let mut per_cell: HashMap<(i32, i32), Vec<f32>> = HashMap::new();
        for &p in dense.points() {
            let Some(cp) = scalp.closest_point(p, MAX_HEIGHT) else { continue };
            let n = mesh.face_normal(cp.triangle as usize);
            // Outward: away from the middle of the scalp's vertices (inside the head).
            let n = if n.dot(cp.point - centre) < 0.0 { -n } else { n };
            if n.z < CROWN_COS {
                continue;
            }
            let key = ((cp.point.x / CELL).floor() as i32, (cp.point.y / CELL).floor() as i32);
            per_cell.entry(key).or_default().push(cp.distance);
        }
        let cells = per_cell
            .into_iter()
            .filter_map(|(k, d)| {
                let n = d.len();
                median(d).map(|m| (k, (m, n)))
            })
            .collect();
        Ok(Self { cells })
    }

    /// The median over cells with at least [`MIN_POINTS`] points of their median height (metres).
    pub fn median(&self) -> Option<f32> {
        median(self.cells.values().filter(|c| c.1 >= MIN_POINTS).map(|c| c.0).collect())
    }
}

/// A prediction's layer heights against the ground truth's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct HeightComparison {
    /// Cells where both have at least [`MIN_POINTS`] points.
    pub cells: usize,
    /// Over those cells: the median height of the ground truth and of the prediction (mm).
    pub gt_median_mm: f32,
    pub pred_median_mm: f32,
    /// Over those cells: the median and the 90th percentile of |prediction − ground truth| (mm).
    pub median_abs_error_mm: f32,
    pub p90_abs_error_mm: f32,
}

/// Compares cell by cell; `None` when no cell has enough points in both.
pub fn compare(pred: &LayerHeights, gt: &LayerHeights) -> Option<HeightComparison> {
    let both: Vec<(f32, f32)> = gt
        .cells
        .iter()
        .filter(|(_, g)| g.1 >= MIN_POINTS)
        .filter_map(|(k, g)| pred.cells.get(k).filter(|p| p.1 >= MIN_POINTS).map(|p| (p.0, g.0)))
        .collect();
    if both.is_empty() {
        return None;
    }
    let mut err: Vec<f32> = both.iter().map(|(p, g)| (p - g).abs()).collect();
    err.sort_by(f32::total_cmp);
    Some(HeightComparison {
        cells: both.len(),
        gt_median_mm: 1e3 * median(both.iter().map(|b| b.1).collect())?,
        pred_median_mm: 1e3 * median(both.iter().map(|b| b.0).collect())?,
        median_abs_error_mm: 1e3 * err[err.len() / 2],
        p90_abs_error_mm: 1e3 * err[(err.len() * 9 / 10).min(err.len() - 1)],
    })
}

fn median(mut v: Vec<f32>) -> Option<f32> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f32::total_cmp);
    Some(v[v.len() / 2])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::TriMesh;

    /// A flat square scalp at z = 0 (normal +Z), 10 cm wide.
    fn flat_scalp() -> Bvh {
        let v = vec![
            Vec3::new(-0.05, -0.05, 0.0),
            Vec3::new(0.05, -0.05, 0.0),
            Vec3::new(0.05, 0.05, 0.0),
            Vec3::new(-0.05, 0.05, 0.0),
        ];
        Bvh::new(TriMesh::new(v, vec![[0, 1, 2], [0, 2, 3]], None, None).unwrap())
    }

    /// Straight strands lying flat at height `h` over the square, along x.
    fn layer(h: f32) -> StrandSet {
        let mut pts = Vec::new();
        let mut counts = Vec::new();
        for j in 0..20 {
            let y = -0.045 + 0.09 * j as f32 / 19.0;
            pts.push(Vec3::new(-0.045, y, h));
            pts.push(Vec3::new(0.045, y, h));
            counts.push(2);
        }
        StrandSet::new(pts, counts).unwrap()
    }

    #[test]
    fn a_layer_two_centimetres_up_against_one_hugging_the_scalp() {
        let scalp = flat_scalp();
        let gt = LayerHeights::measure(&layer(0.02), &scalp, 0.001).unwrap();
        let flat = LayerHeights::measure(&layer(0.002), &scalp, 0.001).unwrap();
        assert!((gt.median().unwrap() - 0.02).abs() < 1e-5);
        let c = compare(&flat, &gt).unwrap();
        // 9 × 9 cells inside the square hold points of both (the strands span x in ±4.5 cm).
        assert!(c.cells >= 64, "{c:?}");
        assert!((c.median_abs_error_mm - 18.0).abs() < 0.01 && (c.gt_median_mm - 20.0).abs() < 0.01, "{c:?}");
        let same = compare(&gt, &gt).unwrap();
        assert_eq!(same.median_abs_error_mm, 0.0);
        // Hair more than MAX_HEIGHT off the scalp is not on the crown's layer.
        assert!(LayerHeights::measure(&layer(0.06), &scalp, 0.001).unwrap().median().is_none());
    }

    #[test]
    fn hair_over_a_wall_of_the_scalp_is_not_on_the_crown() {
        // The square stood on its edge (normal along x): no crown.
        let v = vec![
            Vec3::new(0.0, -0.05, -0.05),
            Vec3::new(0.0, 0.05, -0.05),
            Vec3::new(0.0, 0.05, 0.05),
            Vec3::new(0.0, -0.05, 0.05),
        ];
        let wall = Bvh::new(TriMesh::new(v, vec![[0, 1, 2], [0, 2, 3]], None, None).unwrap());
        let s = StrandSet::new(vec![Vec3::new(0.01, 0.0, -0.04), Vec3::new(0.01, 0.0, 0.04)], vec![2]).unwrap();
        assert!(LayerHeights::measure(&s, &wall, 0.001).unwrap().median().is_none());
    }
}
