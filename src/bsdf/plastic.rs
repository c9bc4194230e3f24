//! Mitsuba 3's smooth `plastic` (`src/bsdfs/plastic.cpp`): a diffuse base under a smooth
//! dielectric coating (relative index η = int_ior / ext_ior), front side only.
//!
//! * Specular (Dirac) reflection off the coating, weight F(θ_i) · specular_reflectance.
//! * Diffuse light that enters, bounces inside and leaves:
//!   f · cos θ_o = ρ' · (cos θ_o / π) · (1 − F(θ_i)) (1 − F(θ_o)) / η²,
//!   with ρ' = ρ / (1 − F_dr) (ρ / (1 − ρ F_dr) with `nonlinear`), F_dr the diffuse
//!   Fresnel reflectance of the inside of the coating (`fresnel_diffuse_reflectance(1/η)`).
//!
//! The specular lobe is picked with probability ∝ F(θ_i) · w_s against
//! (1 − F(θ_i)) · (1 − w_s), w_s = mean(specular) / (mean(diffuse) + mean(specular));
//! the diffuse direction is cosine-sampled.

use std::f32::consts::FRAC_1_PI;

use glam::{Vec2, Vec3, Vec3A};

use super::dielectric::fresnel;
use super::{square_to_cosine_hemisphere, BsdfSample, Texture};

#[derive(Clone, Debug)]
pub struct Plastic {
    /// int_ior / ext_ior
    pub eta: f32,
    pub diffuse_reflectance: Texture,
    /// `None`: not given (1, and the sampling weight uses 1).
    pub specular_reflectance: Option<Vec3>,
    pub nonlinear: bool,
    /// F_dr of the coating's inside, `fresnel_diffuse_reflectance(1/η)`.
    fdr_int: f32,
    /// w_s, the specular lobe's share of the sampling weight.
    specular_weight: f32,
}

/// Diffuse Fresnel reflectance: the fraction of light arriving uniformly from a
/// hemisphere that a smooth interface of relative index `eta` reflects. Mitsuba's fits:
/// Egan and Hilgeman (1973) for η < 1, d'Eon and Irving (2011) otherwise.
pub fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    let inv = 1.0 / eta;
    if eta < 1.0 {
        0.0636 * inv + eta * (eta * -1.4399 + 0.7099) + 0.6681
    } else {
        // Horner in 1/η.
        let c = [0.919317, -3.4793, 6.75335, -7.80989, 4.98554, -1.36881];
        c.iter().rev().fold(0.0f32, |acc, &k| acc * inv + k)
    }
}

impl Plastic {
    /// The constants of the model (F_dr and w_s) computed once, as Mitsuba does in
    /// `parameters_changed`, not per sample.
    pub fn new(
        eta: f32,
        diffuse_reflectance: Texture,
        specular_reflectance: Option<Vec3>,
        nonlinear: bool,
    ) -> Self {
        let s_mean = specular_reflectance.map_or(1.0, |s| s.element_sum() / 3.0);
        Plastic {
            eta,
            fdr_int: fresnel_diffuse_reflectance(1.0 / eta),
            specular_weight: s_mean / (diffuse_reflectance.mean() + s_mean),
            diffuse_reflectance,
            specular_reflectance,
            nonlinear,
        }
    }

    /// Probability of picking the specular lobe at incident cosine `cos_i`, and F(θ_i).
    fn specular_probability(&self, cos_i: f32) -> (f32, f32) {
        let w_s = self.specular_weight;
        let f_i = fresnel(cos_i, self.eta).0;
        let (ps, pd) = (f_i * w_s, (1.0 - f_i) * (1.0 - w_s));
        (ps / (ps + pd), f_i)
    }

    /// ρ' (1 − F_i)(1 − F_o) / η²: the diffuse lobe without its cos θ_o / π.
    fn diffuse(&self, uv: Vec2, f_i: f32, cos_o: f32) -> Vec3 {
        let rho = self.diffuse_reflectance.eval(uv);
        let fdr_int = self.fdr_int;
        let rho = if self.nonlinear {
            rho / (Vec3::ONE - rho * fdr_int)
        } else {
            rho / (1.0 - fdr_int)
        };
        let f_o = fresnel(cos_o, self.eta).0;
        rho * ((1.0 - f_i) * (1.0 - f_o) / (self.eta * self.eta))
    }

    pub fn eval_pdf(&self, wi: Vec3A, wo: Vec3A, uv: Vec2) -> (Vec3, f32) {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let (p_spec, f_i) = self.specular_probability(wi.z);
        let cos_pdf = FRAC_1_PI * wo.z;
        (
            self.diffuse(uv, f_i, wo.z) * cos_pdf,
            cos_pdf * (1.0 - p_spec),
        )
    }

    pub fn sample(&self, wi: Vec3A, s1: f32, s2: Vec2, uv: Vec2) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let (p_spec, f_i) = self.specular_probability(wi.z);
        if s1 < p_spec {
            let spec = self.specular_reflectance.unwrap_or(Vec3::ONE);
            return Some(BsdfSample {
                wo: Vec3A::new(-wi.x, -wi.y, wi.z),
                pdf: p_spec,
                weight: spec * (f_i / p_spec),
                eta: 1.0,
                delta: true,
                null: false,
            });
        }
        let wo = square_to_cosine_hemisphere(s2);
        let p_diff = 1.0 - p_spec;
        if wo.z <= 0.0 || p_diff <= 0.0 {
            return None;
        }
        Some(BsdfSample {
            wo,
            pdf: p_diff * FRAC_1_PI * wo.z,
            // f cos / pdf: the cosine and 1/π cancel.
            weight: self.diffuse(uv, f_i, wo.z) / p_diff,
            eta: 1.0,
            delta: false,
            null: false,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plastic(nonlinear: bool) -> Plastic {
        Plastic::new(
            1.9,
            Texture::Constant(Vec3::new(0.94, 0.271, 0.361)),
            None,
            nonlinear,
        )
    }

    /// The fits against the integral they approximate:
    /// F_dr(η) = ∫ F(cos θ, η) 2 cos θ sin θ dθ over the hemisphere.
    #[test]
    fn diffuse_fresnel_matches_its_integral() {
        for eta in [1.0 / 1.9, 1.0 / 1.5, 1.33, 1.5, 1.9] {
            let n = 20_000;
            let integral: f64 = (0..n)
                .map(|i| {
                    let mu = (i as f64 + 0.5) / n as f64;
                    fresnel(mu as f32, eta).0 as f64 * 2.0 * mu / n as f64
                })
                .sum();
            let fit = fresnel_diffuse_reflectance(eta) as f64;
            assert!(
                (fit - integral).abs() < 0.01,
                "eta {eta}: fit {fit}, integral {integral}"
            );
        }
    }

    /// Sampling agrees with evaluation: weight = f cos / pdf for the diffuse lobe, and the
    /// lobe probabilities add to one.
    #[test]
    fn sample_matches_eval() {
        for nonlinear in [false, true] {
            let b = plastic(nonlinear);
            let wi = Vec3A::new(0.4, -0.2, 0.7).normalize();
            let (p_spec, f_i) = b.specular_probability(wi.z);
            assert!(p_spec > 0.0 && p_spec < 1.0);
            let spec = b
                .sample(wi, 0.5 * p_spec, Vec2::splat(0.3), Vec2::ZERO)
                .unwrap();
            assert!(
                spec.delta
                    && (spec.weight - Vec3::splat(f_i / p_spec))
                        .abs()
                        .max_element()
                        < 1e-6
            );
            for i in 0..40 {
                let s2 = Vec2::new(
                    (i as f32 + 0.5) / 40.0,
                    ((i * 13) % 40) as f32 / 40.0 + 0.01,
                );
                let bs = b.sample(wi, 0.999, s2, Vec2::ZERO).unwrap();
                let (f, pdf) = b.eval_pdf(wi, bs.wo, Vec2::ZERO);
                assert!(!bs.delta && (pdf - bs.pdf).abs() < 1e-5);
                assert!(((f / pdf) - bs.weight).abs().max_element() < 1e-4);
            }
        }
    }

    /// Energy: with a white base the model reflects everything that arrives (the diffuse
    /// part is (1 − F_i)(1 − F_dr,ext) / (η² (1 − F_dr,int)) = 1 − F_i, up to the fits):
    /// the directional albedo by Monte Carlo is 1. The back side reflects nothing.
    #[test]
    fn white_plastic_does_not_create_energy() {
        let b = Plastic::new(1.9, Texture::Constant(Vec3::ONE), None, false);
        let mut rng = crate::integrator::sampler::Pcg32::for_pixel(1, 2);
        for cos in [0.2f32, 0.6, 1.0] {
            let wi = Vec3A::new((1.0 - cos * cos).sqrt(), 0.0, cos);
            let n = 50_000;
            let albedo: f32 = (0..n)
                .filter_map(|_| b.sample(wi, rng.next_1d(), rng.next_2d(), Vec2::ZERO))
                .map(|s| s.weight.x)
                .sum::<f32>()
                / n as f32;
            assert!((albedo - 1.0).abs() < 0.02, "cos {cos}: albedo {albedo}");
        }
        let back = Vec3A::new(0.0, 0.0, -1.0);
        assert!(b.sample(back, 0.5, Vec2::splat(0.5), Vec2::ZERO).is_none());
        assert_eq!(b.eval_pdf(back, Vec3A::Z, Vec2::ZERO), (Vec3::ZERO, 0.0));
    }
}
