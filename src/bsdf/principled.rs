//! Mitsuba 3's `principled` (`src/bsdfs/principled.cpp`, `principledhelpers.h`): the
//! Disney BSDF of Burley, "Physically Based Shading at Disney" (2012) and "Extending
//! the Disney BRDF to a BSDF with Integrated Subsurface Scattering" (2015), as Mitsuba
//! 3.9.1 computes it, both sides. With brdf = (1 − metallic)(1 − spec_trans) and
//! bsdf = (1 − metallic) spec_trans, `f · |cos θ_o|` is the sum of
//!
//! * main specular reflection (GGX, α from roughness² and `anisotropic`):
//!   F_p D G / (4 |cos θ_i|), F_p the dielectric Fresnel blended with Schlick terms for
//!   `metallic` and `spec_tint` ([`principled_fresnel`]); only bsdf · F from inside;
//! * specular transmission: √base_color · bsdf · (1 − F) D G |wi·h| |wo·h| /
//!   (|cos θ_i| (wi·h + η wo·h)²) (Walter et al. 2007; radiance's 1/η² cancels η²);
//! * clearcoat (front): 0.25 · clearcoat · F_schlick(0.04) · D_GTR1 · G_GGX(0.25) ·
//!   |cos θ_o| (Mitsuba's expression, without the 1/(4 cos θ_i cos θ_o));
//! * diffuse with retro-reflection (and `flatness`'s fake subsurface) and sheen (front).
//!
//! Sampling picks a lobe with probabilities from the sampling rates and the Fresnel
//! term at the GGX visible normal drawn first from `s2` (the diffuse and clearcoat
//! directions reuse `s2`, as in Mitsuba), then weighs by eval / pdf over all lobes.
//! Replicating this exactly matters: with spec_trans the lobe choice depends on `s2`,
//! so `pdf` is not quite the sampling density, and the image depends on it.

use std::f32::consts::FRAC_1_PI;

use glam::{Vec2, Vec3, Vec3A};

use super::fresnel::{fresnel, reflect, refract};
use super::microfacet::{Microfacet, MicrofacetType};
use super::principled_lobes::{
    clearcoat_g, mac_mic_compatible, principled_fresnel, schlick_angle_weight, schlick_weight, Gtr1,
};
use super::BsdfSample;
use crate::sampling::warp::square_to_cosine_hemisphere;
use crate::texture::{luminance, Texture};

/// The parameters, each a texture read by `eval_1` (a scalar) except `base_color`.
/// `None` is Mitsuba's "not given, or given as the float 0": that lobe's code is off.
#[derive(Clone, Debug)]
pub struct Principled {
    pub base_color: Texture,
    pub roughness: Texture,
    pub anisotropic: Option<Texture>,
    pub spec_trans: Option<Texture>,
    pub sheen: Option<Texture>,
    pub sheen_tint: Option<Texture>,
    pub flatness: Option<Texture>,
    pub spec_tint: Option<Texture>,
    pub metallic: Option<Texture>,
    pub clearcoat: Option<Texture>,
    pub clearcoat_gloss: Texture,
    /// Relative index of refraction (from `eta`, or from `specular`).
    pub eta: f32,
    pub spec_srate: f32,
    pub clearcoat_srate: f32,
    pub diff_refl_srate: f32,
}

/// The parameters at one point.
struct At {
    base_color: Vec3,
    roughness: f32,
    spec_trans: f32,
    metallic: f32,
    clearcoat: f32,
    distr: Microfacet,
}

impl At {
    /// The weights of the reflective and transmissive major lobes.
    fn brdf_bsdf(&self) -> (f32, f32) {
        let m = 1.0 - self.metallic;
        (m * (1.0 - self.spec_trans), m * self.spec_trans)
    }
}

fn opt(t: &Option<Texture>, uv: Vec2) -> f32 {
    t.as_ref().map_or(0.0, |t| t.eval_1(uv))
}

/// Mitsuba's `calc_dist_params`: α = roughness², stretched by √(1 − 0.9 anisotropic)
/// along u and squeezed along v, at least 0.001.
fn dist_params(anisotropic: Option<f32>, roughness: f32) -> (f32, f32) {
    let r2 = roughness * roughness;
    match anisotropic {
        None => (r2.max(0.001), r2.max(0.001)),
        Some(a) => {
            let aspect = (1.0 - 0.9 * a).sqrt();
            ((r2 / aspect).max(0.001), (r2 * aspect).max(0.001))
        }
    }
}

impl Principled {
    /// Whether α_u may differ from α_v (the frame must then follow ∂p/∂u).
    pub fn is_anisotropic(&self) -> bool {
        self.anisotropic
            .as_ref()
            .is_some_and(|a| a.constant() != Some(Vec3::ZERO))
    }

    pub fn is_textured(&self) -> bool {
        let textured = |t: &Texture| t.constant().is_none();
        [&self.base_color, &self.roughness, &self.clearcoat_gloss]
            .into_iter()
            .any(textured)
            || [
                &self.anisotropic,
                &self.spec_trans,
                &self.sheen,
                &self.sheen_tint,
                &self.flatness,
                &self.spec_tint,
                &self.metallic,
                &self.clearcoat,
            ]
            .into_iter()
            .any(|t| t.as_ref().is_some_and(textured))
    }

    fn at(&self, uv: Vec2) -> At {
        let roughness = self.roughness.eval_1(uv);
        let anisotropic = self.anisotropic.as_ref().map(|t| t.eval_1(uv));
        let (ax, ay) = dist_params(anisotropic, roughness);
        At {
            base_color: self.base_color.eval(uv),
            roughness,
            spec_trans: opt(&self.spec_trans, uv),
            metallic: opt(&self.metallic, uv),
            clearcoat: opt(&self.clearcoat, uv),
            distr: Microfacet::new(MicrofacetType::Ggx, ax, ay),
        }
    }

    /// The lobe probabilities (diffuse, clearcoat, transmission, reflection), normalized,
    /// given the dielectric Fresnel term `f` at the microfacet normal.
    fn lobe_probs(&self, p: &At, front: bool, f: f32) -> [f32; 4] {
        let (brdf, bsdf) = p.brdf_bsdf();
        let (mut reflect, mut trans) = if front {
            (
                self.spec_srate * (1.0 - bsdf * (1.0 - f)),
                self.spec_srate * bsdf * (1.0 - f),
            )
        } else {
            (f, 1.0 - f)
        };
        if self.spec_trans.is_none() {
            trans = 0.0;
        }
        let clearcoat = if self.clearcoat.is_some() && front {
            0.25 * p.clearcoat * self.clearcoat_srate
        } else {
            0.0
        };
        let diffuse = if front {
            brdf * self.diff_refl_srate
        } else {
            0.0
        };
        let norm = 1.0 / (reflect + trans + clearcoat + diffuse);
        reflect *= norm;
        [diffuse * norm, clearcoat * norm, trans * norm, reflect]
    }

    pub fn eval_pdf(&self, wi: Vec3A, wo: Vec3A, uv: Vec2) -> (Vec3, f32) {
        if wi.z == 0.0 {
            return (Vec3::ZERO, 0.0);
        }
        let p = self.at(uv);
        (self.eval_at(&p, wi, wo, uv), self.pdf_at(&p, wi, wo, uv))
    }

    /// The half vector, turned to the outside: wi + wo for reflection,
    /// wi + η_path wo for refraction.
    fn half_vector(wi: Vec3A, wo: Vec3A, reflect: bool, eta_path: f32) -> Vec3A {
        let wh = (wi + wo * if reflect { 1.0 } else { eta_path }).normalize();
        if wh.z < 0.0 {
            -wh
        } else {
            wh
        }
    }

    fn eval_at(&self, p: &At, wi: Vec3A, wo: Vec3A, uv: Vec2) -> Vec3 {
        let (cos_i, cos_o) = (wi.z, wo.z);
        let (reflect, refract) = (cos_i * cos_o > 0.0, cos_i * cos_o < 0.0);
        if !(reflect || refract) {
            return Vec3::ZERO;
        }
        let (brdf, bsdf) = p.brdf_bsdf();
        let front = cos_i > 0.0;
        let eta_path = if front { self.eta } else { 1.0 / self.eta };
        let wh = Self::half_vector(wi, wo, reflect, eta_path);
        let (f_diel, ..) = fresnel(wi.dot(wh), self.eta);
        let reflect_ok = reflect && mac_mic_compatible(wh, wi, wo, cos_i, true);
        let refract_ok = refract && mac_mic_compatible(wh, wi, wo, cos_i, false);

        let mut value = Vec3::ZERO;
        let spec_reflect = reflect_ok && f_diel > 0.0;
        let spec_trans = self.spec_trans.is_some() && bsdf > 0.0 && refract_ok && f_diel < 1.0;
        if spec_reflect || spec_trans {
            let d = p.distr.eval(wh);
            let g = p.distr.g(wi, wo, wh);
            if spec_reflect {
                // From inside: no tint or metallic, the dielectric F weighted by bsdf.
                let f = if front {
                    principled_fresnel(
                        f_diel,
                        wi.dot(wh),
                        self.eta,
                        p.base_color,
                        self.metallic.as_ref().map(|_| p.metallic),
                        self.spec_tint.as_ref().map(|t| t.eval_1(uv)),
                    )
                } else {
                    Vec3::splat(bsdf * f_diel)
                };
                value += f * (d * g / (4.0 * cos_i.abs()));
            }
            if spec_trans {
                let (dih, doh) = (wi.dot(wh), wo.dot(wh));
                // (1/η_path)² (radiance) × η_path² cancel.
                let t = ((1.0 - f_diel) * d * g * dih * doh
                    / (cos_i * (dih + eta_path * doh).powi(2)))
                .abs();
                value += p.base_color.map(f32::sqrt) * (bsdf * t);
            }
        }
        if self.clearcoat.is_some() {
            let clearcoat = p.clearcoat;
            if clearcoat > 0.0 && reflect_ok && front {
                let gloss = self.clearcoat_gloss.eval_1(uv);
                let fcc = 0.04 + 0.96 * schlick_angle_weight(wi.dot(wh), self.eta);
                let dcc = Gtr1::new(gloss).eval(wh);
                let gcc = clearcoat_g(wi, wo, wh, 0.25);
                value += Vec3::splat(clearcoat * 0.25 * fcc * dcc * gcc * cos_o.abs());
            }
        }
        if reflect && front {
            let (fo, fi) = (schlick_weight(cos_o.abs()), schlick_weight(cos_i.abs()));
            let cos_d = wh.dot(wo);
            if brdf > 0.0 {
                let f_diff = (1.0 - 0.5 * fi) * (1.0 - 0.5 * fo);
                let rr = 2.0 * p.roughness * cos_d * cos_d;
                let f_retro = rr * (fo + fi + fo * fi * (rr - 1.0));
                let shape = match &self.flatness {
                    None => f_diff + f_retro,
                    Some(flatness) => {
                        // Hanrahan–Krueger's fake subsurface, Fss90 from the retro term.
                        let fss90 = rr / 2.0;
                        let fss = (1.0 + (fss90 - 1.0) * fo) * (1.0 + (fss90 - 1.0) * fi);
                        let f_ss = 1.25 * (fss * (1.0 / (cos_o.abs() + cos_i.abs()) - 0.5) + 0.5);
                        let t = flatness.eval_1(uv);
                        f_diff + f_retro + t * (f_ss - (f_diff + f_retro))
                    }
                };
                value += p.base_color * (brdf * cos_o.abs() * FRAC_1_PI * shape);
            }
            // Sheen, also where brdf = 0 (spec_trans 1): Mitsuba's vectorized variants
            // evaluate it whenever its own mask holds.
            let sheen = opt(&self.sheen, uv);
            if self.sheen.is_some() && sheen > 0.0 && 1.0 - p.metallic > 0.0 {
                let fd = schlick_weight(cos_d.abs());
                let tint = if self.sheen_tint.is_some() {
                    let st = opt(&self.sheen_tint, uv);
                    let lum = luminance(p.base_color);
                    let c_tint = if lum > 0.0 {
                        p.base_color / lum
                    } else {
                        Vec3::ONE
                    };
                    Vec3::ONE + (c_tint - Vec3::ONE) * st
                } else {
                    Vec3::ONE
                };
                value += tint * (sheen * (1.0 - p.metallic) * fd * cos_o.abs());
            }
        }
        if value.is_finite() {
            value
        } else {
            Vec3::ZERO
        }
    }

    fn pdf_at(&self, p: &At, wi: Vec3A, wo: Vec3A, uv: Vec2) -> f32 {
        let (cos_i, cos_o) = (wi.z, wo.z);
        let (reflect, refract) = (cos_i * cos_o > 0.0, cos_i * cos_o < 0.0);
        if !(reflect || refract) {
            return 0.0;
        }
        let front = cos_i > 0.0;
        let eta_path = if front { self.eta } else { 1.0 / self.eta };
        let wh = Self::half_vector(wi, wo, reflect, eta_path);
        let (f_diel, ..) = fresnel(wi.dot(wh), self.eta);
        let [p_diffuse, p_clearcoat, p_trans, p_reflect] = self.lobe_probs(p, front, f_diel);
        // |dwh/dwo|: 1/(4 wo·h) for reflection, η² |wo·h| / (wi·h + η wo·h)² for
        // refraction.
        let (dih, doh) = (wi.dot(wh), wo.dot(wh));
        let dwh_dwo = if reflect || self.spec_trans.is_none() {
            (1.0 / (4.0 * doh)).abs()
        } else {
            (eta_path * eta_path * doh / (dih + eta_path * doh).powi(2)).abs()
        };
        let wi_up = wi * cos_i.signum();
        let mut pdf = 0.0;
        let reflect_ok = reflect && mac_mic_compatible(wh, wi, wo, cos_i, true);
        if reflect_ok {
            pdf += p_reflect * p.distr.pdf(wi_up, wh) * dwh_dwo;
        }
        if reflect {
            pdf += p_diffuse * FRAC_1_PI * cos_o;
        }
        if self.spec_trans.is_some() && refract && mac_mic_compatible(wh, wi, wo, cos_i, false) {
            pdf += p_trans * p.distr.pdf(wi_up, wh) * dwh_dwo;
        }
        if self.clearcoat.is_some() && reflect_ok {
            let gloss = self.clearcoat_gloss.eval_1(uv);
            pdf += p_clearcoat * Gtr1::new(gloss).pdf(wh) * dwh_dwo;
        }
        if pdf.is_finite() {
            pdf
        } else {
            0.0
        }
    }

    pub fn sample(&self, wi: Vec3A, s1: f32, s2: Vec2, uv: Vec2) -> Option<BsdfSample> {
        let cos_i = wi.z;
        if cos_i == 0.0 {
            return None;
        }
        let p = self.at(uv);
        let (_, bsdf) = p.brdf_bsdf();
        let front = cos_i > 0.0;
        if !(front || bsdf > 0.0) {
            return None;
        }
        let (m_spec, _) = p.distr.sample(wi * cos_i.signum(), s2);
        let (f_diel, cos_t, eta_it, eta_ti) = fresnel(wi.dot(m_spec), self.eta);
        let [p_diffuse, p_clearcoat, p_trans, _] = self.lobe_probs(&p, front, f_diel);
        let mut eta = 1.0;
        let wo = if s1 < p_diffuse {
            let wo = square_to_cosine_hemisphere(s2);
            if cos_i * wo.z <= 0.0 {
                return None;
            }
            wo
        } else if s1 < p_diffuse + p_clearcoat {
            let gloss = self.clearcoat_gloss.eval_1(uv);
            let m = Gtr1::new(gloss).sample(s2);
            let wo = reflect(wi, m);
            if !(mac_mic_compatible(m, wi, wo, cos_i, true) && cos_i * wo.z > 0.0) {
                return None;
            }
            wo
        } else if s1 < p_diffuse + p_clearcoat + p_trans {
            let wo = refract(wi, m_spec, cos_t, eta_ti);
            if !(mac_mic_compatible(m_spec, wi, wo, cos_i, false) && cos_i * wo.z < 0.0) {
                return None;
            }
            eta = eta_it;
            wo
        } else {
            let wo = reflect(wi, m_spec);
            if !(mac_mic_compatible(m_spec, wi, wo, cos_i, true) && cos_i * wo.z > 0.0) {
                return None;
            }
            wo
        };
        let pdf = self.pdf_at(&p, wi, wo, uv);
        if pdf.is_nan() || pdf <= 0.0 {
            return None;
        }
        let weight = self.eval_at(&p, wi, wo, uv) / pdf;
        weight.is_finite().then_some(BsdfSample {
            wo,
            pdf,
            weight,
            eta,
            delta: false,
            null: false,
        })
    }
}

/// Mitsuba's `specular` → η: the η whose normal-incidence reflectance
/// ((η − 1)/(η + 1))² is 0.08 · specular.
pub fn eta_from_specular(specular: f32) -> f32 {
    2.0 / (1.0 - (0.08 * specular).sqrt()) - 1.0
}
