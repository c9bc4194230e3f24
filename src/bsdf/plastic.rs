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

use std::sync::Mutex;

use rayon::prelude::*;

use super::fresnel::{fresnel, fresnel_diffuse_reflectance, reflect};
use super::microfacet::{eval_reflectance, eval_transmittance, Microfacet};
use super::BsdfSample;
use crate::sampling::warp::square_to_cosine_hemisphere;
use crate::texture::Texture;

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

/// Resolution of `roughplastic`'s table of the coating's transmittance over cos θ.
const TRANSMITTANCE_RES: usize = 64;

/// Mitsuba 3's `roughplastic` (`src/bsdfs/roughplastic.cpp`): a diffuse base under a
/// rough dielectric coating (isotropic Beckmann or GGX), front side only.
///
/// * Glossy reflection off the coating: F(wi·h) D(h) G(wi, wo, h) / (4 cos θ_i).
/// * Diffuse light through the coating and back:
///   ρ' · (cos θ_o / π) · T(θ_i) T(θ_o) / η², with T the rough coating's transmittance
///   (`eval_transmittance`, tabulated over cos θ when the BSDF loads) and ρ' = ρ / (1 − R_int)
///   (ρ / (1 − ρ R_int) with `nonlinear`), R_int the coating's inner reflectance for
///   cosine-weighted light, 2 ∫ R(μ) μ dμ (`eval_reflectance` at 1/η, averaged as
///   Mitsuba does over the table's 64 cosines).
///
/// The glossy lobe is picked with probability ∝ (1 − T(θ_i)) w_s against
/// T(θ_i) (1 − w_s), w_s as in `plastic`; both lobes' pdfs are mixed (one-sample MIS).
#[derive(Clone, Debug)]
pub struct RoughPlastic {
    /// int_ior / ext_ior
    pub eta: f32,
    pub distr: Microfacet,
    pub diffuse_reflectance: Texture,
    pub specular_reflectance: Option<Vec3>,
    pub nonlinear: bool,
    specular_weight: f32,
    /// T(μ) at μ = max(k / 63, 10⁻⁶), k = 0 … 63.
    external_transmittance: Box<[f32; TRANSMITTANCE_RES]>,
    internal_reflectance: f32,
}

/// The rough coating's transmittance table T(μ_k) and its inner reflectance R_int, for
/// relative index `eta`. They cost about 0.4 s (a million visible-normal samples), so
/// they are computed once per (distribution, α, η) and process: every render of a test
/// loads its scene anew.
fn coating_tables(eta: f32, distr: Microfacet) -> (Box<[f32; TRANSMITTANCE_RES]>, f32) {
    /// (distribution, α bits, η bits) → (T table, R_int).
    type Entry = ((u32, u32, u32), Box<[f32; TRANSMITTANCE_RES]>, f32);
    static CACHE: Mutex<Vec<Entry>> = Mutex::new(Vec::new());
    let key = (distr.kind as u32, distr.alpha_u.to_bits(), eta.to_bits());
    if let Some((_, t, r)) = CACHE.lock().unwrap().iter().find(|(k, ..)| *k == key) {
        return (t.clone(), *r);
    }
    let wi = |k: usize| {
        let mu = (k as f32 / (TRANSMITTANCE_RES - 1) as f32).max(1e-6);
        Vec3A::new((1.0 - mu * mu).sqrt(), 0.0, mu)
    };
    let tables: Vec<(f32, f32)> = (0..TRANSMITTANCE_RES)
        .into_par_iter()
        .map(|k| {
            let w = wi(k);
            (
                eval_transmittance(&distr, w, eta),
                eval_reflectance(&distr, w, 1.0 / eta) * w.z,
            )
        })
        .collect();
    let mut transmittance = Box::new([0.0; TRANSMITTANCE_RES]);
    for (t, &(tr, _)) in transmittance.iter_mut().zip(&tables) {
        *t = tr;
    }
    let reflectance = 2.0 * tables.iter().map(|t| t.1).sum::<f32>() / TRANSMITTANCE_RES as f32;
    CACHE
        .lock()
        .unwrap()
        .push((key, transmittance.clone(), reflectance));
    (transmittance, reflectance)
}

impl RoughPlastic {
    /// Tabulates the coating's transmittance and inner reflectance (Mitsuba's
    /// `parameters_changed`).
    pub fn new(
        eta: f32,
        distr: Microfacet,
        diffuse_reflectance: Texture,
        specular_reflectance: Option<Vec3>,
        nonlinear: bool,
    ) -> Self {
        let s_mean = specular_reflectance.map_or(1.0, |s| s.element_sum() / 3.0);
        let (external_transmittance, internal_reflectance) = coating_tables(eta, distr);
        RoughPlastic {
            eta,
            distr,
            specular_weight: s_mean / (diffuse_reflectance.mean() + s_mean),
            diffuse_reflectance,
            specular_reflectance,
            nonlinear,
            external_transmittance,
            internal_reflectance,
        }
    }

    /// T(θ) by linear interpolation in the table (Mitsuba's `lerp_gather`).
    fn transmittance(&self, cos_theta: f32) -> f32 {
        let x = cos_theta * (TRANSMITTANCE_RES - 1) as f32;
        let i = (x as usize).min(TRANSMITTANCE_RES - 2);
        let t = &self.external_transmittance;
        t[i] + (t[i + 1] - t[i]) * (x - i as f32)
    }

    /// Probability of picking the glossy lobe, given T(θ_i).
    fn specular_probability(&self, t_i: f32) -> f32 {
        let w_s = self.specular_weight;
        let (ps, pd) = ((1.0 - t_i) * w_s, t_i * (1.0 - w_s));
        ps / (ps + pd)
    }

    pub fn eval_pdf(&self, wi: Vec3A, wo: Vec3A, uv: Vec2) -> (Vec3, f32) {
        let (cos_i, cos_o) = (wi.z, wo.z);
        if cos_i <= 0.0 || cos_o <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let t_i = self.transmittance(cos_i);
        let p_spec = self.specular_probability(t_i);
        let h = (wo + wi).normalize();
        let d = self.distr.eval(h);
        let g1_wi = self.distr.smith_g1(wi, h);
        let pdf = p_spec * d * g1_wi / (4.0 * cos_i) + (1.0 - p_spec) * FRAC_1_PI * cos_o;
        let f = fresnel(wi.dot(h), self.eta).0;
        let g = self.distr.smith_g1(wo, h) * g1_wi;
        let specular = self.specular_reflectance.unwrap_or(Vec3::ONE) * (f * d * g / (4.0 * cos_i));
        let rho = self.diffuse_reflectance.eval(uv);
        let rho = if self.nonlinear {
            rho / (Vec3::ONE - rho * self.internal_reflectance)
        } else {
            rho / (1.0 - self.internal_reflectance)
        };
        let t_o = self.transmittance(cos_o);
        let diffuse = rho * (FRAC_1_PI / (self.eta * self.eta) * cos_o * t_i * t_o);
        (specular + diffuse, pdf)
    }

    pub fn sample(&self, wi: Vec3A, s1: f32, s2: Vec2, uv: Vec2) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let p_spec = self.specular_probability(self.transmittance(wi.z));
        let wo = if s1 < p_spec {
            reflect(wi, self.distr.sample(wi, s2).0)
        } else {
            square_to_cosine_hemisphere(s2)
        };
        let (value, pdf) = self.eval_pdf(wi, wo, uv);
        (pdf > 0.0 && pdf.is_finite()).then(|| BsdfSample {
            wo,
            pdf,
            weight: value / pdf,
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
        let mut rng = crate::sampling::Pcg32::for_pixel(1, 2);
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
