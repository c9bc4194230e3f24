//! Mitsuba 3's smooth `dielectric`: Fresnel-weighted choice between mirror reflection and
//! refraction (`src/bsdfs/dielectric.cpp`, `include/mitsuba/render/fresnel.h`).

use glam::{Vec3, Vec3A};

use super::fresnel::{fresnel, reflect, refract};
use super::microfacet::Microfacet;
use super::BsdfSample;
use crate::simd::{Float, Vector3};

#[derive(Clone, Copy, Debug)]
pub struct Dielectric {
    /// int_ior / ext_ior
    pub eta: f32,
    pub specular_reflectance: Vec3,
    pub specular_transmittance: Vec3,
}

/// Named indices of refraction accepted for `int_ior` / `ext_ior`
/// (`include/mitsuba/render/ior.h`).
pub const NAMED_IOR: &[(&str, f32)] = &[
    ("vacuum", 1.0),
    ("helium", 1.000036),
    ("hydrogen", 1.000132),
    ("air", 1.000277),
    ("carbon dioxide", 1.00045),
    ("water", 1.3330),
    ("acetone", 1.36),
    ("ethanol", 1.361),
    ("carbon tetrachloride", 1.461),
    ("glycerol", 1.4729),
    ("benzene", 1.501),
    ("silicone oil", 1.52045),
    ("bromine", 1.661),
    ("water ice", 1.31),
    ("fused quartz", 1.458),
    ("pyrex", 1.470),
    ("acrylic glass", 1.49),
    ("polypropylene", 1.49),
    ("bk7", 1.5046),
    ("sodium chloride", 1.544),
    ("amber", 1.55),
    ("pet", 1.5750),
    ("diamond", 2.419),
];

pub fn named_ior(name: &str) -> Option<f32> {
    let lower = name.to_ascii_lowercase();
    NAMED_IOR.iter().find(|(n, _)| *n == lower).map(|&(_, v)| v)
}

impl Dielectric {
    pub fn sample(&self, wi: Vec3A, s1: f32) -> Option<BsdfSample> {
        let sides = (
            self.specular_reflectance.into(),
            self.specular_transmittance.into(),
        );
        let s = sample_smooth(self.eta, sides, wi.into(), s1);
        (s.pdf > 0.0).then(|| BsdfSample {
            wo: s.wo.into(),
            pdf: s.pdf,
            weight: s.weight.into(),
            eta: s.eta,
            delta: true,
            null: false,
        })
    }
}

/// A smooth dielectric's sample in its local frame (z the normal), for a path or lanes.
pub struct SmoothSample<F: Float> {
    pub wo: Vector3<F>,
    /// The lobe's probability (0: none).
    pub pdf: F,
    /// `f · |cos θ_o| / pdf`.
    pub weight: Vector3<F>,
    /// The relative index crossed (1 for reflection).
    pub eta: F,
}

/// Mitsuba's smooth `dielectric` sample of relative index `eta` (int_ior / ext_ior)
/// with its specular (reflectance, transmittance), light leaving along `wi`, lobe draw
/// `s1`: mirror reflection with Fresnel's probability R (`fresnel`), weight ρ_s; else
/// refraction, weight τ_s η_ti², the solid angle's compression in radiance transport.
/// One definition for a path and for lanes of paths.
#[inline(always)]
pub fn sample_smooth<F: Float>(
    eta: F,
    (reflectance, transmittance): (Vector3<F>, Vector3<F>),
    wi: Vector3<F>,
    s1: F,
) -> SmoothSample<F> {
    let (r, cos_theta_t, eta_it, eta_ti) = fresnel(wi.z, eta);
    let reflect = s1.le(r);
    let mirrored = Vector3::new(wi.x.negate(), wi.y.negate(), wi.z);
    let refracted = Vector3::new(eta_ti.negate() * wi.x, eta_ti.negate() * wi.y, cos_theta_t);
    SmoothSample {
        wo: refracted.select(reflect, mirrored),
        pdf: F::select(reflect, r, F::one() - r),
        weight: transmittance
            .scale(eta_ti * eta_ti)
            .select(reflect, reflectance),
        eta: F::select(reflect, F::one(), eta_it),
    }
}

/// Mitsuba 3's `thindielectric` (`src/bsdfs/thindielectric.cpp`): a thin pane of
/// relative index η, seen the same from both sides. With F the Fresnel reflectance at
/// |cos θ_i|, the light bouncing inside the pane sums to r = F + (1−F)² F / (1 − F²)
/// = 2F / (1 + F) reflected and t = 1 − r passed straight through. The transmission is a
/// *null* lobe (no refraction, no change of direction): the path does not count it as a
/// scattering vertex, and shadow rays pass through weighted by t.
#[derive(Clone, Debug)]
pub struct ThinDielectric {
    /// int_ior / ext_ior
    pub eta: f32,
    pub specular_reflectance: Vec3,
    pub specular_transmittance: Vec3,
}

impl ThinDielectric {
    /// r = 2F / (1 + F): the reflectance with all internal reflections.
    fn reflectance(&self, cos_theta_i: f32) -> f32 {
        let f = fresnel(cos_theta_i.abs(), self.eta).0;
        f * 2.0 / (1.0 + f)
    }

    /// What passes straight through (Mitsuba's `eval_null_transmission`).
    pub fn null_transmission(&self, cos_theta_i: f32) -> Vec3 {
        self.specular_transmittance * (1.0 - self.reflectance(cos_theta_i))
    }

    pub fn sample(&self, wi: Vec3A, s1: f32) -> Option<BsdfSample> {
        let r = self.reflectance(wi.z);
        let reflect = s1 <= r;
        let (wo, pdf, weight) = if reflect {
            (Vec3A::new(-wi.x, -wi.y, wi.z), r, self.specular_reflectance)
        } else {
            (-wi, 1.0 - r, self.specular_transmittance)
        };
        (pdf > 0.0).then_some(BsdfSample {
            wo,
            pdf,
            weight,
            eta: 1.0,
            delta: true,
            null: !reflect,
        })
    }
}

/// Mitsuba 3's `roughdielectric` (`src/bsdfs/roughdielectric.cpp`; Walter et al. 2007):
/// a rough interface of relative index η seen from both sides. With m the half vector
/// (m ∝ wi + wo for reflection, wi + η wo for transmission, η the index ratio of the
/// side wi is on), D, G and F as in `microfacet` and `fresnel`:
///
///   reflection:   f · |cos θ_o| = F D G / (4 |cos θ_i|)
///   transmission: f · |cos θ_o| = (1 − F) D G |wi·m| |wo·m| / (|cos θ_i| (wi·m + η wo·m)²)
///
/// (the η² of the transmission and the 1/η² of radiance's solid-angle compression
/// cancel). Sampling: a visible normal, then reflection with probability F, with the
/// Jacobians dm/dwo = 1/(4 wo·m) and η² |wo·m| / (wi·m + η wo·m)².
#[derive(Clone, Debug)]
pub struct RoughDielectric {
    /// int_ior / ext_ior
    pub eta: f32,
    pub distr: Microfacet,
    pub specular_reflectance: Vec3,
    pub specular_transmittance: Vec3,
}

impl RoughDielectric {
    pub fn sample(&self, wi: Vec3A, s1: f32, s2: glam::Vec2) -> Option<BsdfSample> {
        if wi.z == 0.0 {
            return None;
        }
        // Sample the normals visible from wi's side, mirrored to the upper hemisphere.
        let (m, pdf_m) = self.distr.sample(wi * wi.z.signum(), s2);
        if pdf_m.is_nan() || pdf_m <= 0.0 {
            return None;
        }
        let (f, cos_theta_t, eta_it, eta_ti) = fresnel(wi.dot(m), self.eta);
        let (wo, pdf, weight, eta, dwh_dwo) = if s1 <= f {
            let wo = reflect(wi, m);
            (
                wo,
                pdf_m * f,
                self.specular_reflectance,
                1.0,
                1.0 / (4.0 * wo.dot(m)),
            )
        } else {
            let wo = refract(wi, m, cos_theta_t, eta_ti);
            let denom = wi.dot(m) + eta_it * wo.dot(m);
            (
                wo,
                pdf_m * (1.0 - f),
                // Radiance is scaled by η_ti² for the solid-angle compression.
                self.specular_transmittance * (eta_ti * eta_ti),
                eta_it,
                eta_it * eta_it * wo.dot(m) / (denom * denom),
            )
        };
        let weight = weight * self.distr.smith_g1(wo, m);
        let pdf = pdf * dwh_dwo.abs();
        if !(pdf > 0.0 && pdf.is_finite()) || weight == Vec3::ZERO {
            return None;
        }
        Some(BsdfSample {
            wo,
            pdf,
            weight,
            eta,
            delta: false,
            null: false,
        })
    }

    pub fn eval_pdf(&self, wi: Vec3A, wo: Vec3A) -> (Vec3, f32) {
        let (cos_i, cos_o) = (wi.z, wo.z);
        if cos_i == 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let reflect = cos_i * cos_o > 0.0;
        let eta = if cos_i > 0.0 {
            self.eta
        } else {
            1.0 / self.eta
        };
        let m = (wi + wo * if reflect { 1.0 } else { eta }).normalize();
        let m = m * m.z.signum();
        let (dot_wi_m, dot_wo_m) = (wi.dot(m), wo.dot(m));
        // The micro- and macro-surface must agree on each direction's side.
        if !(dot_wi_m * cos_i > 0.0 && dot_wo_m * cos_o > 0.0) {
            return (Vec3::ZERO, 0.0);
        }
        let d = self.distr.eval(m);
        let f = fresnel(dot_wi_m, self.eta).0;
        let g = self.distr.g(wi, wo, m);
        let pdf_m = self.distr.pdf(wi * cos_i.signum(), m);
        let (value, pdf) = if reflect {
            (
                self.specular_reflectance * (f * d * g / (4.0 * cos_i.abs())),
                pdf_m * f / (4.0 * dot_wo_m).abs(),
            )
        } else {
            let denom = dot_wi_m + eta * dot_wo_m;
            let denom2 = denom * denom;
            let v = ((1.0 - f) * d * g * dot_wi_m * dot_wo_m / (cos_i * denom2)).abs();
            (
                self.specular_transmittance * v,
                pdf_m * (1.0 - f) * (eta * eta * dot_wo_m / denom2).abs(),
            )
        };
        if !(pdf.is_finite() && value.is_finite()) {
            return (Vec3::ZERO, 0.0);
        }
        (value, pdf)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refraction_obeys_snell() {
        let d = Dielectric {
            eta: 1.5,
            specular_reflectance: Vec3::ONE,
            specular_transmittance: Vec3::ONE,
        };
        let wi = Vec3A::new(0.6, 0.0, 0.8);
        let bs = d.sample(wi, 0.99).unwrap();
        let sin_t = (bs.wo.x * bs.wo.x + bs.wo.y * bs.wo.y).sqrt();
        assert!((0.6 - 1.5 * sin_t).abs() < 1e-5, "{sin_t}");
        assert!(bs.wo.z < 0.0 && (bs.wo.length() - 1.0).abs() < 1e-5);
    }

    /// The pane's reflectance sums the internal bounces: r = 2F/(1+F) ≥ F, and the
    /// transmission is what is left; both lobes are picked in proportion.
    #[test]
    fn thin_dielectric_sums_internal_reflections() {
        let t = ThinDielectric {
            eta: 1.5,
            specular_reflectance: Vec3::ONE,
            specular_transmittance: Vec3::splat(0.9),
        };
        let f = fresnel(1.0, 1.5).0;
        let r = t.reflectance(-1.0);
        assert!((r - 2.0 * f / (1.0 + f)).abs() < 1e-7 && r > f);
        assert!((t.null_transmission(1.0).x - 0.9 * (1.0 - r)).abs() < 1e-6);
        let wi = Vec3A::new(0.6, 0.0, -0.8);
        let refl = t.sample(wi, 0.0).unwrap();
        assert!(!refl.null && refl.wo == Vec3A::new(-0.6, 0.0, -0.8) && refl.weight == Vec3::ONE);
        let pass = t.sample(wi, 0.99).unwrap();
        assert!(pass.null && pass.wo == -wi && pass.weight == Vec3::splat(0.9));
        assert!((refl.pdf + pass.pdf - 1.0).abs() < 1e-6);
    }
}
