//! DR on every k-th point of each strand ([`super::DrOptions::stride`]): the strands are thinned to
//! their root, every `stride`-th point after it and their tip, DR moves those, and each point in
//! between moves by the linear blend of the moves of the two kept points around it. A strand keeps
//! its own point count and its fine shape (a curl between two kept points moves as one piece);
//! DR's time and memory follow the kept points.

use glam::Vec3;
use hairrecon_core::{StrandError, StrandSet};
use rayon::prelude::*;

/// The dense index of coarse point `j` of a strand of `n` points thinned by `k`.
fn kept(j: usize, k: usize, n: usize) -> usize {
    (j * k).min(n - 1)
}

/// How many points a strand of `n` points keeps when thinned by `k`: 0, k, 2k, … below its tip,
/// and the tip.
pub fn kept_count(n: usize, k: usize) -> usize {
    if n <= 1 {
        n
    } else {
        (n - 2) / k + 2
    }
}

/// The strands thinned to every `k`-th point (root first, tip last).
pub fn thin(strands: &StrandSet, k: usize) -> StrandSet {
    let k = k.max(1);
    let mut points = Vec::new();
    let mut counts = Vec::with_capacity(strands.num_strands());
    for i in 0..strands.num_strands() {
        let s = strands.strand(i);
        let m = kept_count(s.len(), k);
        points.extend((0..m).map(|j| s[kept(j, k, s.len())]));
        counts.push(m as u32);
    }
    StrandSet::new(points, counts).expect("a thinned strand keeps at least its root")
}

/// The dense strands moved as their thinned points moved to `after` (laid out as
/// [`thin`]`(dense, k)`): a kept point becomes its coarse point, a point between two kept ones
/// moves by the linear blend of their moves (by index, which is arc length on evenly spaced
/// strands). In place: DR's sets are large (50,000 children of ~250 points: 150 MB). Fails when a
/// moved point is not finite.
pub fn lift(dense: StrandSet, k: usize, after: &[Vec3]) -> Result<StrandSet, StrandError> {
    let k = k.max(1);
    let offsets = dense.offsets().to_vec();
    let mut coarse_offsets = Vec::with_capacity(dense.num_strands() + 1);
    coarse_offsets.push(0usize);
    for w in offsets.windows(2) {
        coarse_offsets.push(coarse_offsets.last().unwrap() + kept_count(w[1] - w[0], k));
    }
    assert_eq!(after.len(), *coarse_offsets.last().unwrap(), "`after` is not thinned from `dense`");
    let (mut points, counts) = dense.into_parts();
    super::strands_mut(&mut points, &offsets).into_par_iter().enumerate().for_each(|(i, s)| {
        let (c0, n) = (coarse_offsets[i], s.len());
        let m = kept_count(n, k);
        // From the tip to the root: each span's far end has moved already, so its move is carried
        // from the span before; its near end is still where it was.
        let mut moved_far = after[c0 + m - 1] - s[n - 1];
        s[n - 1] = after[c0 + m - 1];
        for j in (0..m - 1).rev() {
            let (a, b) = (kept(j, k, n), kept(j + 1, k, n));
            let moved_near = after[c0 + j] - s[a];
            for (d, p) in s.iter_mut().enumerate().take(b).skip(a + 1) {
                let t = (d - a) as f32 / (b - a) as f32;
                *p += moved_near * (1.0 - t) + moved_far * t;
            }
            s[a] = after[c0 + j];
            moved_far = moved_near;
        }
    });
    StrandSet::new(points, counts)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn strands(lens: &[usize]) -> StrandSet {
        let mut p = Vec::new();
        for (s, &n) in lens.iter().enumerate() {
            p.extend((0..n).map(|i| Vec3::new(s as f32, i as f32, (i * i) as f32)));
        }
        StrandSet::new(p, lens.iter().map(|&n| n as u32).collect()).unwrap()
    }

    #[test]
    fn thinning_keeps_the_root_every_kth_point_and_the_tip() {
        let s = strands(&[2, 2, 3, 7, 8]);
        let t = thin(&s, 3);
        assert_eq!(t.counts(), &[2, 2, 2, 3, 4]);
        // the strand of 7 points keeps 0, 3, 6; that of 8 keeps 0, 3, 6, 7
        let ys = |i: usize| t.strand(i).iter().map(|p| p.y as usize).collect::<Vec<_>>();
        assert_eq!(ys(2), vec![0, 2]);
        assert_eq!(ys(3), vec![0, 3, 6]);
        assert_eq!(ys(4), vec![0, 3, 6, 7]);
        assert_eq!(thin(&s, 1).points(), s.points());
        assert_eq!(kept_count(1, 3), 1);
        for (n, k) in [(2, 2), (2, 5), (5, 2), (6, 2), (100, 3), (101, 4)] {
            assert_eq!(kept_count(n, k), thin(&strands(&[n]), k).points().len(), "n {n} k {k}");
        }
    }

    fn after_all(s: &StrandSet) -> Vec<Vec3> {
        s.points().iter().map(|p| *p + Vec3::new(1.0, -2.0, 0.5)).collect()
    }

    #[test]
    fn lifting_moves_kept_points_exactly_and_blends_between() {
        let s = strands(&[8, 2, 5]);
        let before = thin(&s, 3);
        // move the kept points of strand 0 (dense 0, 3, 6, 7) by 0, 3, 6, 9 along x; the others not
        let mut after = before.points().to_vec();
        for (j, p) in after[..4].iter_mut().enumerate() {
            p.x += 3.0 * j as f32;
        }
        let lifted = lift(s.clone(), 3, &after).unwrap();
        let lifted = lifted.points();
        let dx: Vec<f32> = (0..8).map(|d| lifted[d].x - s.points()[d].x).collect();
        assert_eq!(dx, vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 9.0]);
        assert_eq!(&lifted[8..], &s.points()[8..]);
        // a strand of 5 keeps 0, 3, 4: its point 1 moves by 2/3 of point 0's move and 1/3 of point 3's
        let mut after = before.points().to_vec();
        after[7].z += 3.0; // strand 2's coarse point 1 (dense 3)
        let lifted = lift(s.clone(), 3, &after).unwrap();
        let dz: Vec<f32> = (10..15).map(|d| lifted.points()[d].z - s.points()[d].z).collect();
        assert_eq!(dz, vec![0.0, 1.0, 2.0, 3.0, 0.0]);
        // every move of the coarse strands is a move of the dense ones at the kept points
        assert_eq!(thin(&lifted, 3).points(), &after[..]);
        assert_eq!(lifted.counts(), s.counts());
        // at stride 1 every point is kept
        assert_eq!(lift(s.clone(), 1, &after_all(&s)).unwrap().points(), &after_all(&s)[..]);
    }
}
