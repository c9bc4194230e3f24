//! Surface scattering: Mitsuba 3's `null`, `diffuse`, `dielectric`, `thindielectric`,
//! `conductor`, `plastic` and `twosided`.
//!
//! All directions are in the local shading frame (z = shading normal), `wi` points away
//! from the surface toward where the path came from, as in Mitsuba.

pub mod conductor;
pub mod dielectric;
pub mod plastic;
pub mod texture;

use std::f32::consts::FRAC_1_PI;

use glam::{Vec2, Vec3, Vec3A};

pub use conductor::Conductor;
pub use dielectric::{Dielectric, ThinDielectric};
pub use plastic::Plastic;
pub use texture::Texture;

#[derive(Clone, Debug)]
pub enum Bsdf {
    /// Index-matched boundary: light passes straight through (medium interfaces).
    Null,
    /// Lambertian reflection, `reflectance / π · cos θ_o`, front side only.
    Diffuse {
        reflectance: Texture,
    },
    Dielectric(Dielectric),
    /// A thin pane: specular reflection, and straight (null) transmission.
    ThinDielectric(ThinDielectric),
    /// A smooth conductor: Fresnel-weighted mirror reflection.
    Conductor(Conductor),
    /// A diffuse base under a smooth dielectric coating.
    Plastic(Plastic),
    /// Mitsuba's `twosided`: the back side uses `back` (or the same BSDF mirrored).
    TwoSided(Box<[Bsdf; 2]>),
}

/// The outcome of sampling a BSDF.
#[derive(Clone, Copy, Debug)]
pub struct BsdfSample {
    pub wo: Vec3A,
    pub pdf: f32,
    /// `f · |cos θ_o| / pdf`
    pub weight: Vec3,
    /// Relative index of refraction crossed (1 for reflection).
    pub eta: f32,
    /// A Dirac lobe (specular or null): no MIS with emitter sampling.
    pub delta: bool,
    /// Passed through a `null` BSDF.
    pub null: bool,
}

impl Bsdf {
    /// Whether the BSDF has a non-Dirac component (emitter sampling is worthwhile).
    pub fn is_smooth(&self) -> bool {
        match self {
            Bsdf::Null | Bsdf::Dielectric(_) | Bsdf::ThinDielectric(_) | Bsdf::Conductor(_) => {
                false
            }
            Bsdf::Diffuse { .. } | Bsdf::Plastic(_) => true,
            Bsdf::TwoSided(b) => b[0].is_smooth() || b[1].is_smooth(),
        }
    }

    /// Whether a parameter varies with the texture coordinates.
    pub fn is_textured(&self) -> bool {
        match self {
            Bsdf::Diffuse { reflectance } => reflectance.constant().is_none(),
            Bsdf::Plastic(p) => p.diffuse_reflectance.constant().is_none(),
            Bsdf::TwoSided(b) => b[0].is_textured() || b[1].is_textured(),
            _ => false,
        }
    }

    /// Whether some light passes straight through (Mitsuba's `BSDFFlags::Null` among the
    /// BSDF's flags): `null`, `thindielectric`.
    pub fn has_null_component(&self) -> bool {
        match self {
            Bsdf::Null | Bsdf::ThinDielectric(_) => true,
            Bsdf::TwoSided(b) => b[0].has_null_component() || b[1].has_null_component(),
            _ => false,
        }
    }

    /// What passes straight through toward a direction whose cosine with the shading
    /// normal is `cos_o` (Mitsuba's `eval_null_transmission` at wi = −wo, so
    /// cos θ_i = −cos_o): 1 for `null`, the pane's transmission for `thindielectric`,
    /// 0 (blocked) for the others.
    pub fn null_transmission(&self, cos_o: f32) -> Vec3 {
        match self {
            Bsdf::Null => Vec3::ONE,
            Bsdf::ThinDielectric(t) => t.null_transmission(-cos_o),
            Bsdf::TwoSided(b) => {
                if -cos_o > 0.0 {
                    b[0].null_transmission(cos_o)
                } else {
                    b[1].null_transmission(-cos_o)
                }
            }
            _ => Vec3::ZERO,
        }
    }

    /// `f(wi, wo) · |cos θ_o|` and the pdf of sampling `wo` (0 for Dirac lobes), at
    /// texture coordinates `uv`.
    pub fn eval_pdf(&self, wi: Vec3A, wo: Vec3A, uv: Vec2) -> (Vec3, f32) {
        match self {
            Bsdf::Null | Bsdf::Dielectric(_) | Bsdf::ThinDielectric(_) | Bsdf::Conductor(_) => {
                (Vec3::ZERO, 0.0)
            }
            Bsdf::Diffuse { reflectance } => {
                if wi.z > 0.0 && wo.z > 0.0 {
                    (reflectance.eval(uv) * (FRAC_1_PI * wo.z), FRAC_1_PI * wo.z)
                } else {
                    (Vec3::ZERO, 0.0)
                }
            }
            Bsdf::Plastic(p) => p.eval_pdf(wi, wo, uv),
            Bsdf::TwoSided(b) => {
                let (front, back) = (&b[0], &b[1]);
                if wi.z > 0.0 {
                    front.eval_pdf(wi, wo, uv)
                } else {
                    back.eval_pdf(flip(wi), flip(wo), uv)
                }
            }
        }
    }

    /// Samples an outgoing direction at texture coordinates `uv`. `None` when the
    /// sample carries no energy.
    pub fn sample(&self, wi: Vec3A, s1: f32, s2: Vec2, uv: Vec2) -> Option<BsdfSample> {
        match self {
            Bsdf::Null => Some(BsdfSample {
                wo: -wi,
                pdf: 1.0,
                weight: Vec3::ONE,
                eta: 1.0,
                delta: true,
                null: true,
            }),
            Bsdf::Diffuse { reflectance } => {
                if wi.z <= 0.0 {
                    return None;
                }
                let wo = square_to_cosine_hemisphere(s2);
                if wo.z <= 0.0 {
                    return None;
                }
                Some(BsdfSample {
                    wo,
                    pdf: FRAC_1_PI * wo.z,
                    weight: reflectance.eval(uv),
                    eta: 1.0,
                    delta: false,
                    null: false,
                })
            }
            Bsdf::Dielectric(d) => d.sample(wi, s1),
            Bsdf::ThinDielectric(t) => t.sample(wi, s1),
            Bsdf::Conductor(c) => c.sample(wi),
            Bsdf::Plastic(p) => p.sample(wi, s1, s2, uv),
            Bsdf::TwoSided(b) => {
                if wi.z > 0.0 {
                    b[0].sample(wi, s1, s2, uv)
                } else {
                    let mut bs = b[1].sample(flip(wi), s1, s2, uv)?;
                    bs.wo = flip(bs.wo);
                    Some(bs)
                }
            }
        }
    }
}

fn flip(v: Vec3A) -> Vec3A {
    Vec3A::new(v.x, v.y, -v.z)
}

/// Malley's method on the concentric disk; pdf = cos θ / π.
pub fn square_to_cosine_hemisphere(s: Vec2) -> Vec3A {
    let (x, y) = crate::geometry::shape::square_to_uniform_disk_concentric(s);
    let z = (1.0 - x * x - y * y).max(0.0).sqrt();
    Vec3A::new(x, y, z)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The sampled weight equals eval / pdf: a check that sampling and evaluation agree.
    #[test]
    fn diffuse_sample_matches_eval() {
        let b = Bsdf::Diffuse {
            reflectance: Texture::Constant(Vec3::new(0.2, 0.5, 0.8)),
        };
        let wi = Vec3A::new(0.3, 0.1, 0.9).normalize();
        for i in 0..50 {
            let s = Vec2::new((i as f32 + 0.5) / 50.0, ((i * 7) % 50) as f32 / 50.0 + 0.01);
            let bs = b.sample(wi, 0.5, s, Vec2::ZERO).unwrap();
            let (f, pdf) = b.eval_pdf(wi, bs.wo, Vec2::ZERO);
            assert!((pdf - bs.pdf).abs() < 1e-5);
            assert!(((f / pdf) - bs.weight).abs().max_element() < 1e-4);
        }
    }

    #[test]
    fn twosided_mirrors_the_back() {
        let b = Bsdf::TwoSided(Box::new([
            Bsdf::Diffuse {
                reflectance: Texture::Constant(Vec3::splat(0.5)),
            },
            Bsdf::Diffuse {
                reflectance: Texture::Constant(Vec3::splat(0.5)),
            },
        ]));
        let wi = Vec3A::new(0.0, 0.0, -1.0);
        let wo = Vec3A::new(0.0, 0.6, -0.8);
        let (f, pdf) = b.eval_pdf(wi, wo, Vec2::ZERO);
        assert!((f.x - 0.5 * FRAC_1_PI * 0.8).abs() < 1e-6 && pdf > 0.0);
    }
}
