//! The pieces of Mitsuba 3's `principledhelpers.h` that `principled` builds on: the GTR1
//! distribution of the clearcoat (Burley 2012, Appendix B), its separable GGX shadowing,
//! Schlick's Fresnel approximation, and the principled Fresnel blend.

use std::f32::consts::PI;

use glam::{Vec2, Vec3, Vec3A};

use crate::texture::luminance;

/// Burley's GTR1 ("generalized Trowbridge–Reitz", γ = 1) distribution of normals, the
/// clearcoat's: D(m) = (α² − 1) / (π ln α² (1 + (α² − 1) cos²θ)), sampled by inverting
/// its CDF in cos²θ (not visible normals, as in Mitsuba).
pub struct Gtr1 {
    alpha: f32,
}

impl Gtr1 {
    /// The clearcoat roughness: α = lerp(0.1, 0.001, clearcoat_gloss).
    pub fn new(clearcoat_gloss: f32) -> Self {
        Gtr1 {
            alpha: 0.1 + (0.001 - 0.1) * clearcoat_gloss,
        }
    }

    pub fn eval(&self, m: Vec3A) -> f32 {
        let (c2, a2) = (m.z * m.z, self.alpha * self.alpha);
        let d = (a2 - 1.0) / (PI * a2.ln() * (1.0 + (a2 - 1.0) * c2));
        if d * m.z > 1e-20 {
            d
        } else {
            0.0
        }
    }

    /// The density of `sample`'s normals: D(m) cos θ_m.
    pub fn pdf(&self, m: Vec3A) -> f32 {
        if m.z < 0.0 {
            0.0
        } else {
            m.z * self.eval(m)
        }
    }

    /// cos²θ = (1 − α^{2(1 − u_y)}) / (1 − α²), φ = 2π u_x.
    pub fn sample(&self, u: Vec2) -> Vec3A {
        let (sin_phi, cos_phi) = (2.0 * PI * u.x).sin_cos();
        let a2 = self.alpha * self.alpha;
        let cos2 = (1.0 - a2.powf(1.0 - u.y)) / (1.0 - a2);
        let sin_t = (1.0 - cos2).max(0.0).sqrt();
        Vec3A::new(cos_phi * sin_t, sin_phi * sin_t, cos2.max(0.0).sqrt())
    }
}

/// Smith's G1 for isotropic GGX of roughness α: 2 / (1 + √(1 + α² tan²θ)); 1 at normal
/// incidence, 0 when `v` sees the microfacet `wh` from behind.
pub fn smith_ggx1(v: Vec3A, wh: Vec3A, alpha: f32) -> f32 {
    if v.dot(wh) * v.z <= 0.0 {
        return 0.0;
    }
    if v.z == 1.0 {
        return 1.0;
    }
    let c2 = v.z * v.z;
    let tan2 = (1.0 - c2) / c2;
    2.0 / (1.0 + (1.0 + alpha * alpha * tan2).sqrt())
}

/// The clearcoat's separable shadowing-masking G1(wi) G1(wo).
pub fn clearcoat_g(wi: Vec3A, wo: Vec3A, wh: Vec3A, alpha: f32) -> f32 {
    smith_ggx1(wi, wh, alpha) * smith_ggx1(wo, wh, alpha)
}

/// (1 − cos)⁵, cos clamped to [0, 1].
#[inline]
pub fn schlick_weight(cos_i: f32) -> f32 {
    let m = (1.0 - cos_i).clamp(0.0, 1.0);
    let m2 = m * m;
    m2 * m2 * m
}

/// The weight w of Schlick's approximation R0 + (1 − R0) w = lerp(w, 1, R0) at the
/// microfacet angle, w = (1 − cos)⁵ taken on the side of the lower index (the refracted
/// angle when light comes from the denser side), as Mitsuba's `calc_schlick`.
pub fn schlick_angle_weight(cos_theta_i: f32, eta: f32) -> f32 {
    let eta_it = if cos_theta_i >= 0.0 { eta } else { 1.0 / eta };
    if eta_it > 1.0 {
        schlick_weight(cos_theta_i.abs())
    } else {
        let eta_ti = 1.0 / eta_it;
        let cos_t2 = 1.0 - (1.0 - cos_theta_i * cos_theta_i) * eta_ti * eta_ti;
        schlick_weight(cos_t2.max(0.0).sqrt())
    }
}

/// Schlick's R0 + (1 − R0) w per channel.
#[inline]
pub fn calc_schlick(r0: Vec3, cos_theta_i: f32, eta: f32) -> Vec3 {
    let w = schlick_angle_weight(cos_theta_i, eta);
    r0 + (Vec3::ONE - r0) * w
}

/// ((η − 1)/(η + 1))², the normal-incidence reflectance.
pub fn schlick_r0_eta(eta: f32) -> f32 {
    ((eta - 1.0) / (eta + 1.0)).powi(2)
}

/// Whether the microfacet `m` agrees with the macro-surface: both wi and wo on m's
/// outer side for reflection; wi outside and wo inside for refraction (m turned to
/// wi's side of the surface by the sign of cos θ_i).
#[inline]
pub fn mac_mic_compatible(
    m: Vec3A,
    wi: Vec3A,
    wo: Vec3A,
    cos_theta_i: f32,
    reflection: bool,
) -> bool {
    let m = if cos_theta_i < 0.0 { -m } else { m };
    if reflection {
        wi.dot(m) > 0.0 && wo.dot(m) > 0.0
    } else {
        wi.dot(m) > 0.0 && wo.dot(m) < 0.0
    }
}

/// The principled Fresnel term of the main specular lobe from outside:
/// (1 − metallic)(1 − spec_tint) F_dielectric + metallic · Schlick(base_color) +
/// (1 − metallic) spec_tint · Schlick(c_tint R0(η)), with c_tint = base_color /
/// luminance. `None` is a lobe turned off (Mitsuba's `has_metallic`, `has_spec_tint`).
pub fn principled_fresnel(
    f_dielectric: f32,
    cos_theta_i: f32,
    eta: f32,
    base_color: Vec3,
    metallic: Option<f32>,
    spec_tint: Option<f32>,
) -> Vec3 {
    let m = metallic.unwrap_or(0.0);
    let mut f_schlick = Vec3::ZERO;
    if metallic.is_some() {
        f_schlick += calc_schlick(base_color, cos_theta_i, eta) * m;
    }
    if let Some(st) = spec_tint {
        let lum = luminance(base_color);
        let c_tint = if lum > 0.0 {
            base_color / lum
        } else {
            Vec3::ONE
        };
        let eta_it = if cos_theta_i >= 0.0 { eta } else { 1.0 / eta };
        f_schlick +=
            calc_schlick(c_tint * schlick_r0_eta(eta_it), cos_theta_i, eta) * ((1.0 - m) * st);
    }
    Vec3::splat((1.0 - m) * (1.0 - spec_tint.unwrap_or(0.0)) * f_dielectric) + f_schlick
}
