//! Adam (Kingma and Ba 2015, Algorithm 1), as Mitsuba 3's `mi.ad.Adam` applies it to
//! a parameter tensor: per value, first and second moment estimates of the gradient,
//! bias-corrected by the step count, and a step of lr · m̂ / (√v̂ + ε).

/// Adam's state for one parameter vector.
#[derive(Clone, Debug)]
pub struct Adam {
    pub lr: f32,
    pub beta_1: f32,
    pub beta_2: f32,
    pub epsilon: f32,
    m: Vec<f32>,
    v: Vec<f32>,
    t: u32,
}

impl Adam {
    /// Mitsuba 3's defaults: β₁ 0.9, β₂ 0.999, ε 1e-8.
    pub fn new(lr: f32, len: usize) -> Adam {
        Adam {
            lr,
            beta_1: 0.9,
            beta_2: 0.999,
            epsilon: 1e-8,
            m: vec![0.0; len],
            v: vec![0.0; len],
            t: 0,
        }
    }

    /// Forgets the moments (a parameter of another size: Mitsuba resets them when a
    /// tensor is replaced by one of another shape).
    pub fn reset(&mut self, len: usize) {
        self.m = vec![0.0; len];
        self.v = vec![0.0; len];
        self.t = 0;
    }

    /// One step on `x` down the gradient `g`, then each value clamped into [lo, hi].
    pub fn step(&mut self, x: &mut [f32], g: &[f32], (lo, hi): (f32, f32)) {
        assert_eq!(
            x.len(),
            self.m.len(),
            "Adam's state and the parameter differ in size"
        );
        self.t += 1;
        let t = self.t as i32;
        // lr_t = lr √(1 − β₂ᵗ) / (1 − β₁ᵗ) (the algorithm's efficient form, Mitsuba's too).
        let lr_t = self.lr * (1.0 - self.beta_2.powi(t)).sqrt() / (1.0 - self.beta_1.powi(t));
        for (((x, &g), m), v) in x.iter_mut().zip(g).zip(&mut self.m).zip(&mut self.v) {
            *m = self.beta_1 * *m + (1.0 - self.beta_1) * g;
            *v = self.beta_2 * *v + (1.0 - self.beta_2) * g * g;
            *x = (*x - lr_t * *m / (v.sqrt() + self.epsilon)).clamp(lo, hi);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On f(x) = Σ (x − c)², Adam's first step moves every value by lr against its
    /// gradient's sign (m̂/√v̂ = ±1), and 2000 steps reach the minimum; the clamp holds.
    #[test]
    fn adam_steps_by_lr_and_converges() {
        let c = [0.3f32, -0.2, 0.7];
        let mut x = vec![0.0f32; 3];
        let mut adam = Adam::new(0.01, 3);
        let grad =
            |x: &[f32]| -> Vec<f32> { x.iter().zip(&c).map(|(x, c)| 2.0 * (x - c)).collect() };
        let g = grad(&x);
        adam.step(&mut x, &g, (-1.0, 1.0));
        for (x, c) in x.iter().zip(&c) {
            assert!((x - 0.01 * c.signum()).abs() < 1e-6, "{x}");
        }
        for _ in 0..2000 {
            let g = grad(&x);
            adam.step(&mut x, &g, (-1.0, 0.5));
        }
        assert!(
            (x[0] - 0.3).abs() < 1e-3 && (x[1] + 0.2).abs() < 1e-3,
            "{x:?}"
        );
        assert_eq!(x[2], 0.5, "clamped");
    }
}
