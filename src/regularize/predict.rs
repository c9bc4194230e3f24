//! Prediction of the target-albedo image from the source radiance R_s and gradient G_s
//! (the paper, Sec. 4.3, Eq. 11–12), and the two baselines of Fan et al. 2023.
//!
//!   R_t = R_s + G_s · β (e^{Δ/β} − 1) · e^{−γ R_s Δ²},   Δ = α_t − α_s
//!   β = c_β / (σ_t α_s),  0 < c_β ≤ σ_t α_s (so β ≤ 1)
//!   γ = ln((σ_t + 1)^5) / (1 − α_s)
//!
//! Linear: R_t = R_s + G_s Δ.  Log-linear: R_t = R_s e^{(G_s / R_s) Δ}.
//! Every channel has its own α_s, α_t and σ_t.
//!
//! Policy for values that cannot be predicted: a prediction that is negative, NaN or
//! infinite is replaced by R_s itself (the un-extrapolated source value, always a valid
//! image value), and counted, so the caller can report how many there were.

use glam::Vec3;

use crate::error::SceneError;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Predictor {
    /// The paper's function with its constant c_β.
    Paper {
        c_beta: f32,
    },
    Linear,
    LogLinear,
    /// R_t = R_s + D, D the (denoised) difference R(α_t) − R(α_s) rendered in the same
    /// paths (`Estimand::AlbedoDifference`): no model of R(α) and so no bias of one; only the
    /// denoising of D can bias it.
    Difference,
}

/// Per-channel albedos and extinction of the medium being extrapolated.
#[derive(Clone, Copy, Debug)]
pub struct Albedos {
    pub source: Vec3,
    pub target: Vec3,
    pub sigma_t: Vec3,
}

impl Predictor {
    /// Checks the parameters once: c_β in (0, σ_t α_s] per channel, albedos in [0, 1],
    /// σ_t finite and ≥ 0.
    pub fn validate(&self, a: &Albedos) -> Result<(), SceneError> {
        let bad = |msg: String| Err(SceneError::new(None, msg));
        for c in 0..3 {
            let (s, t, st) = (a.source[c], a.target[c], a.sigma_t[c]);
            if !(0.0..=1.0).contains(&s) || !(0.0..=1.0).contains(&t) {
                return bad(format!(
                    "albedos must lie in [0, 1]: source {s}, target {t} (channel {c})"
                ));
            }
            if !st.is_finite() || st < 0.0 {
                return bad(format!(
                    "sigma_t = {st} must be finite and nonnegative (channel {c})"
                ));
            }
            if let Predictor::Paper { c_beta } = *self {
                let limit = st * s;
                if !(c_beta > 0.0 && c_beta <= limit) {
                    return bad(format!(
                        "c_beta = {c_beta} is outside (0, sigma_t * alpha_s] = (0, {limit}] for channel {c} (the paper needs beta = c_beta / (sigma_t alpha_s) <= 1); choose c_beta in that range"
                    ));
                }
            }
        }
        Ok(())
    }

    /// R_t for one channel. `None` when the value is negative or not finite.
    #[inline]
    fn channel(&self, r_s: f32, g_s: f32, alpha_s: f32, alpha_t: f32, sigma_t: f32) -> Option<f32> {
        let (r_s, g_s) = (r_s as f64, g_s as f64);
        let delta = alpha_t as f64 - alpha_s as f64;
        if delta == 0.0 {
            // No extrapolation (and no 0/0 in the log-linear form where R_s = 0).
            return Some(r_s as f32).filter(|r| r.is_finite() && *r >= 0.0);
        }
        let r_t = match *self {
            Predictor::Linear => r_s + g_s * delta,
            // Here g_s is the difference itself.
            Predictor::Difference => r_s + g_s,
            Predictor::LogLinear => r_s * (g_s / r_s * delta).exp(),
            Predictor::Paper { c_beta } => {
                let beta = c_beta as f64 / (sigma_t as f64 * alpha_s as f64);
                // β (e^{Δ/β} − 1), accurate for small Δ/β.
                let growth = beta * (delta / beta).exp_m1();
                // e^{−γ R_s Δ²}; γ is ∞ at α_s = 1, and the factor is 1 when R_s Δ² = 0.
                let x = r_s * delta * delta;
                let damping = if x == 0.0 {
                    1.0
                } else {
                    let gamma = 5.0 * (sigma_t as f64 + 1.0).ln() / (1.0 - alpha_s as f64);
                    (-gamma * x).exp()
                };
                r_s + g_s * growth * damping
            }
        };
        // Checked after the cast: a value beyond f32's range is not finite either.
        let r_t = r_t as f32;
        (r_t.is_finite() && r_t >= 0.0).then_some(r_t)
    }

    /// Predicts every pixel; returns the image and how many values fell back to R_s.
    pub fn predict(
        &self,
        a: &Albedos,
        radiance: &[[f32; 3]],
        gradient: &[[f32; 3]],
    ) -> (Vec<[f32; 3]>, usize) {
        let mut fallbacks = 0;
        let out = radiance
            .iter()
            .zip(gradient)
            .map(|(r, g)| {
                [0, 1, 2].map(|c| {
                    self.channel(r[c], g[c], a.source[c], a.target[c], a.sigma_t[c])
                        .unwrap_or_else(|| {
                            fallbacks += 1;
                            if r[c].is_finite() {
                                r[c].max(0.0)
                            } else {
                                0.0
                            }
                        })
                })
            })
            .collect();
        (out, fallbacks)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grey(s: f32, t: f32, st: f32) -> Albedos {
        Albedos {
            source: Vec3::splat(s),
            target: Vec3::splat(t),
            sigma_t: Vec3::splat(st),
        }
    }

    /// Values computed by hand from Eq. 11–12 (in double precision):
    /// R_s 0.2, G_s 1.5, α_s 0.9025, α_t 0.95, σ_t 10, c_β 0.5:
    /// β = 0.0554016620, γ = 122.968988, R_t = 0.306680238;
    /// linear 0.27125; log-linear 0.2 e^{7.5 · 0.0475} = 0.285592899.
    #[test]
    fn pinned_values() {
        let a = grey(0.9025, 0.95, 10.0);
        let cases = [
            (Predictor::Paper { c_beta: 0.5 }, 0.306_680_24f32),
            (Predictor::Linear, 0.271_25),
            (Predictor::LogLinear, 0.285_592_9),
        ];
        for (p, want) in cases {
            p.validate(&a).unwrap();
            let (img, fb) = p.predict(&a, &[[0.2; 3]], &[[1.5; 3]]);
            assert_eq!(fb, 0);
            assert!(
                (img[0][0] - want).abs() < 1e-6,
                "{p:?}: {} vs {want}",
                img[0][0]
            );
        }
    }

    /// Equal albedos predict R_s; each channel uses its own albedos.
    #[test]
    fn per_channel_and_identity() {
        let a = Albedos {
            source: Vec3::new(0.9, 0.95, 0.5),
            target: Vec3::new(0.9, 0.97, 0.6),
            sigma_t: Vec3::new(10.0, 10.0, 2.0),
        };
        let p = Predictor::Paper { c_beta: 0.5 };
        p.validate(&a).unwrap();
        let (img, _) = p.predict(&a, &[[0.3, 0.3, 0.3]], &[[2.0, 2.0, 2.0]]);
        assert_eq!(img[0][0], 0.3, "Δ = 0 keeps R_s");
        assert!(img[0][1] > 0.3 && img[0][2] > 0.3);
        assert_ne!(img[0][1], img[0][2]);
    }

    /// The edges: R_s = 0, huge G_s/R_s, α_s = 1, σ_t tiny or 1e4, and the fallback.
    #[test]
    fn numerically_safe_at_the_edges() {
        // α_s = 1: γ = ∞, the damping kills the extrapolation → R_s (and Δ ≤ 0 anyway).
        let p = Predictor::Paper { c_beta: 0.5 };
        let a = grey(1.0, 1.0, 10.0);
        let (img, fb) = p.predict(&a, &[[0.4; 3]], &[[3.0; 3]]);
        assert_eq!((img[0][0], fb), (0.4, 0));
        // R_s = 0: damping factor 1, R_t = G_s β (e^{Δ/β} − 1) ≥ 0.
        let a = grey(0.9, 0.95, 10.0);
        let (img, fb) = p.predict(&a, &[[0.0; 3]], &[[1.0; 3]]);
        assert!(img[0][0] > 0.0 && fb == 0);
        // σ_t = 1e4: β tiny, e^{Δ/β} overflows → not finite → falls back to R_s.
        let a = grey(0.9, 0.95, 1e4);
        let (img, fb) = p.predict(&a, &[[0.3; 3]], &[[1.0; 3]]);
        assert_eq!((img[0][0], fb), (0.3, 3));
        // Log-linear at R_s = 0 (G/R = ∞) and huge G/R: fall back, never NaN or Inf.
        let a = grey(0.5, 0.99, 1.0);
        let (img, fb) =
            Predictor::LogLinear.predict(&a, &[[0.0; 3], [1e-30; 3]], &[[1.0; 3], [1e3; 3]]);
        assert!(img.iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
        assert_eq!(fb, 6);
        // Finite in f64 but beyond f32's range (e^{200}): falls back too.
        let (img, fb) = Predictor::LogLinear.predict(&a, &[[1e-3; 3]], &[[200.0 * 1e-3 / 0.49; 3]]);
        assert_eq!((img[0][0], fb), (1e-3, 3));
        // A negative linear prediction falls back to R_s.
        let (img, fb) = Predictor::Linear.predict(&a, &[[0.1; 3]], &[[-1.0; 3]]);
        assert_eq!((img[0][0], fb), (0.1, 3));
    }

    #[test]
    fn c_beta_outside_its_range_is_an_error() {
        let a = grey(0.9, 0.95, 10.0);
        for c_beta in [0.0, -0.1, 9.5, f32::NAN] {
            let e = Predictor::Paper { c_beta }
                .validate(&a)
                .unwrap_err()
                .to_string();
            assert!(e.contains("c_beta"), "{e}");
        }
        assert!(Predictor::Paper { c_beta: 9.0 }.validate(&a).is_ok());
        // σ_t → 0: no c_β > 0 is valid.
        assert!(Predictor::Paper { c_beta: 0.5 }
            .validate(&grey(0.9, 0.95, 0.0))
            .is_err());
        assert!(Predictor::Linear.validate(&grey(1.2, 0.95, 1.0)).is_err());
    }
}
