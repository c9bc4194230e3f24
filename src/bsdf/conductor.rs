//! Mitsuba 3's smooth `conductor` (`src/bsdfs/conductor.cpp`): a perfect mirror whose
//! reflectance is the Fresnel reflectance of a complex index of refraction η + iκ,
//! times `specular_reflectance`; front side only.

use glam::{Vec3, Vec3A};

use super::microfacet::{reflect, Microfacet};
use super::BsdfSample;

#[derive(Clone, Debug, PartialEq)]
pub struct Conductor {
    /// Real part of the relative index of refraction, per channel.
    pub eta: Vec3,
    /// Imaginary part (extinction coefficient κ), per channel.
    pub k: Vec3,
    pub specular_reflectance: Vec3,
}

impl Conductor {
    /// Mitsuba's `material = "none"`: η = 0, κ = 1, which is a 100% reflecting mirror.
    pub fn ideal_mirror(specular_reflectance: Vec3) -> Self {
        Conductor {
            eta: Vec3::ZERO,
            k: Vec3::ONE,
            specular_reflectance,
        }
    }

    pub fn sample(&self, wi: Vec3A) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let f = Vec3::new(
            fresnel_conductor(wi.z, self.eta.x, self.k.x),
            fresnel_conductor(wi.z, self.eta.y, self.k.y),
            fresnel_conductor(wi.z, self.eta.z, self.k.z),
        );
        Some(BsdfSample {
            wo: Vec3A::new(-wi.x, -wi.y, wi.z),
            pdf: 1.0,
            weight: self.specular_reflectance * f,
            eta: 1.0,
            delta: true,
            null: false,
        })
    }
}

/// Mitsuba 3's `roughconductor` (`src/bsdfs/roughconductor.cpp`): microfacet reflection
/// off a conductor, front side only. With h = (wi + wo)/|wi + wo|:
///   f · cos θ_o = F(wi·h) D(h) G(wi, wo, h) / (4 cos θ_i) · specular_reflectance,
/// sampled by a visible normal (pdf D G1(wi, h) / (4 cos θ_i) per solid angle of wo).
#[derive(Clone, Debug, PartialEq)]
pub struct RoughConductor {
    pub distr: Microfacet,
    pub eta: Vec3,
    pub k: Vec3,
    pub specular_reflectance: Vec3,
}

impl RoughConductor {
    fn fresnel(&self, cos_theta_i: f32) -> Vec3 {
        Vec3::new(
            fresnel_conductor(cos_theta_i, self.eta.x, self.k.x),
            fresnel_conductor(cos_theta_i, self.eta.y, self.k.y),
            fresnel_conductor(cos_theta_i, self.eta.z, self.k.z),
        )
    }

    pub fn sample(&self, wi: Vec3A, s2: glam::Vec2) -> Option<BsdfSample> {
        if wi.z <= 0.0 {
            return None;
        }
        let (m, pdf_m) = self.distr.sample(wi, s2);
        let wo = reflect(wi, m);
        if pdf_m.is_nan() || pdf_m <= 0.0 || wo.z <= 0.0 {
            return None;
        }
        let pdf = pdf_m / (4.0 * wo.dot(m));
        let weight =
            self.fresnel(wi.dot(m)) * self.specular_reflectance * self.distr.smith_g1(wo, m);
        (pdf > 0.0 && pdf.is_finite()).then_some(BsdfSample {
            wo,
            pdf,
            weight,
            eta: 1.0,
            delta: false,
            null: false,
        })
    }

    pub fn eval_pdf(&self, wi: Vec3A, wo: Vec3A) -> (Vec3, f32) {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let h = (wi + wo).normalize();
        let d = self.distr.eval(h);
        if d == 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let value = self.fresnel(wi.dot(h))
            * self.specular_reflectance
            * (d * self.distr.g(wi, wo, h) / (4.0 * wi.z));
        let pdf = d * self.distr.smith_g1(wi, h) / (4.0 * wi.z);
        (value, pdf)
    }
}

/// Unpolarized Fresnel reflectance at a conductor with index η + iκ, for cos θ_i > 0
/// (the exact formula, e.g. pbrt 3rd ed. §8.2.1, as Mitsuba's `fresnel_conductor`):
///   a² + b² = √((η² − κ² − sin²θ)² + 4η²κ²),  a = √((a² + b² + η² − κ² − sin²θ) / 2)
///   R_s = (a² + b² + cos²θ − 2a cosθ) / (a² + b² + cos²θ + 2a cosθ)
///   R_p = R_s (cos²θ (a² + b²) + sin⁴θ − 2a cosθ sin²θ) / (… + 2a cosθ sin²θ)
pub fn fresnel_conductor(cos_theta_i: f32, eta: f32, k: f32) -> f32 {
    let (c, eta, k) = (cos_theta_i.clamp(0.0, 1.0) as f64, eta as f64, k as f64);
    let c2 = c * c;
    let s2 = 1.0 - c2;
    let t1 = eta * eta - k * k - s2;
    let a2pb2 = (t1 * t1 + 4.0 * eta * eta * k * k).max(0.0).sqrt();
    let a = (0.5 * (a2pb2 + t1)).max(0.0).sqrt();
    let term1 = a2pb2 + c2;
    let term2 = 2.0 * c * a;
    let r_s = (term1 - term2) / (term1 + term2);
    let term3 = a2pb2 * c2 + s2 * s2;
    let term4 = term2 * s2;
    let r_p = r_s * (term3 - term4) / (term3 + term4);
    (0.5 * (r_s + r_p)) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// η = 0, κ = 1 reflects everything at every angle; a dielectric-like conductor
    /// (κ = 0) at normal incidence gives ((η − 1)/(η + 1))²; at grazing incidence 1.
    #[test]
    fn fresnel_conductor_known_values() {
        for c in [1.0, 0.7, 0.3, 0.05] {
            assert!(
                (fresnel_conductor(c, 0.0, 1.0) - 1.0).abs() < 1e-6,
                "cos {c}"
            );
        }
        let r0 = ((1.5f32 - 1.0) / 2.5).powi(2);
        assert!((fresnel_conductor(1.0, 1.5, 0.0) - r0).abs() < 1e-6);
        assert!((fresnel_conductor(1e-6, 0.2, 3.0) - 1.0).abs() < 1e-4);
        // Gold-like (η 0.2, κ 3.6) at normal incidence: ((η−1)² + κ²)/((η+1)² + κ²).
        let want = ((0.2f32 - 1.0).powi(2) + 3.6 * 3.6) / ((1.2f32).powi(2) + 3.6 * 3.6);
        assert!((fresnel_conductor(1.0, 0.2, 3.6) - want).abs() < 1e-6);
    }

    #[test]
    fn mirror_reflects_about_the_normal_front_side_only() {
        let m = Conductor::ideal_mirror(Vec3::new(0.9, 0.8, 0.7));
        let wi = Vec3A::new(0.3, -0.2, 0.9).normalize();
        let bs = m.sample(wi).unwrap();
        assert!((bs.wo - Vec3A::new(-wi.x, -wi.y, wi.z)).length() < 1e-6);
        assert!((bs.weight - Vec3::new(0.9, 0.8, 0.7)).abs().max_element() < 1e-6);
        assert!(bs.delta && !bs.null);
        assert!(m.sample(Vec3A::new(0.0, 0.0, -1.0)).is_none());
    }
}
