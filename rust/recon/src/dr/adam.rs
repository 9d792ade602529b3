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
}

impl Adam {
    pub fn new(n: usize, uniform: bool) -> Self {
        Self { m: vec![Vec3::ZERO; n], v: vec![Vec3::ZERO; n], t: 0, beta1: 0.9, beta2: 0.999, eps: 1e-12, uniform }
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
        if self.uniform {
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
}
