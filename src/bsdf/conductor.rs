//! Mitsuba 3's smooth `conductor` (`src/bsdfs/conductor.cpp`): a perfect mirror whose
//! reflectance is the Fresnel reflectance of a complex index of refraction η + iκ,
//! times `specular_reflectance`; front side only.

use glam::{Vec3, Vec3A};

use super::fresnel::{fresnel_conductor, reflect};
use super::microfacet::Microfacet;
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

#[cfg(test)]
mod tests {
    use super::*;

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
