//! Adam (Kingma and Ba, "Adam: A Method for Stochastic Optimization", ICLR 2015) over an array of
//! 3D vectors, with the "uniform" variant of Nicolet et al. 2021 ("Large Steps in Inverse Rendering
//! of Geometry", §5): the second-moment estimate is replaced by its maximum over all entries, so
//! that the step is the (reparameterized) gradient direction scaled by one number and the
//! smoothness that `(I + λL)⁻¹` gives the step is kept.

use glam::Vec3;

/// Adam state; [`Adam::step`] writes the update (to be added to the variable).
#[derive(Debug, Clone)]
pub struct Adam {
    m: Vec<Vec3>,
    v: Vec<Vec3>,
    t: i32,
    pub beta1: f32,
    pub beta2: f32,
    pub eps: f32,
    pub uniform: bool,
    /// Uniform variant only: the quantile of the points' second moments (each point's largest
    /// coordinate) that scales the step; 1 is the maximum of Nicolet et al. Below 1, a point whose
    /// step would be longer than the learning rate is shortened to it.
    pub quantile: f32,
    scratch: Vec<f32>,
}

impl Adam {
    pub fn new(n: usize, uniform: bool) -> Self {
        Self {
            m: vec![Vec3::ZERO; n],
            v: vec![Vec3::ZERO; n],
            t: 0,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-12,
            uniform,
            quantile: 1.0,
            scratch: Vec::new(),
        }
    }

    /// One step: `delta = −lr · m̂ / (√v̂ + ε)` (uniform: `√v̂` replaced by its maximum).
    pub fn step(&mut self, g: &[Vec3], lr: f32, delta: &mut [Vec3]) {
        let (b1, b2) = (self.beta1, self.beta2);
        self.t += 1;
        let c1 = 1.0 - b1.powi(self.t);
        let c2 = 1.0 - b2.powi(self.t);
        let mut vmax = 0.0f32;
        for i in 0..g.len() {
            self.m[i] = self.m[i] * b1 + g[i] * (1.0 - b1);
            self.v[i] = self.v[i] * b2 + g[i] * g[i] * (1.0 - b2);
            vmax = vmax.max(self.v[i].max_element());
        }
        if self.uniform && self.quantile < 1.0 && !g.is_empty() {
            self.scratch.clear();
            self.scratch.extend(self.v.iter().map(|v| v.max_element()));
            let k = ((self.scratch.len() - 1) as f32 * self.quantile.max(0.0)) as usize;
            let (_, vq, _) = self.scratch.select_nth_unstable_by(k, f32::total_cmp);
            let s = -lr / c1 / ((*vq / c2).sqrt() + self.eps);
            for i in 0..g.len() {
                delta[i] = (self.m[i] * s).clamp_length_max(lr);
            }
        } else if self.uniform {
            let s = -lr / c1 / ((vmax / c2).sqrt() + self.eps);
            for i in 0..g.len() {
                delta[i] = self.m[i] * s;
            }
        } else {
            for i in 0..g.len() {
                let vh = (self.v[i] / c2).map(f32::sqrt) + Vec3::splat(self.eps);
                delta[i] = -(self.m[i] / c1) * lr / vh;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_step_has_the_learning_rate_as_its_size() {
        let g = [Vec3::new(2.0, -1.0, 0.0), Vec3::new(0.5, 0.0, 4.0)];
        let mut d = [Vec3::ZERO; 2];
        let mut a = Adam::new(2, false);
        a.step(&g, 0.1, &mut d);
        assert!((d[0] - Vec3::new(-0.1, 0.1, 0.0)).length() < 1e-5, "{d:?}");
        let mut u = Adam::new(2, true);
        u.step(&g, 0.1, &mut d);
        // Uniform: the largest entry moves by lr, the others in proportion to their gradient.
        assert!((d[1].z + 0.1).abs() < 1e-5 && (d[0].x + 0.05).abs() < 1e-5, "{d:?}");
    }

    #[test]
    fn a_quantile_scales_the_typical_point_and_clamps_the_outlier() {
        // Nine points with gradient 1 along x and one outlier with 100: the maximum makes the nine
        // move by lr/100, the median (0.5 quantile) by lr, and the outlier is clamped to lr.
        let mut g = vec![Vec3::X; 10];
        g[9] = Vec3::X * 100.0;
        let mut d = vec![Vec3::ZERO; 10];
        let mut a = Adam::new(10, true);
        a.step(&g, 0.1, &mut d);
        assert!((d[0].x + 0.001).abs() < 1e-6 && (d[9].x + 0.1).abs() < 1e-5, "{d:?}");
        let mut q = Adam::new(10, true);
        q.quantile = 0.5;
        q.step(&g, 0.1, &mut d);
        assert!((d[0].x + 0.1).abs() < 1e-5, "{d:?}");
        assert!((d[9].length() - 0.1).abs() < 1e-5, "{d:?}");
    }
}
