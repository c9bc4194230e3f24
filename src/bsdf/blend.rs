//! Mitsuba 3's `blendbsdf` (`src/bsdfs/blendbsdf.cpp`) and `mask` (`src/bsdfs/mask.cpp`):
//! BSDFs made of other BSDFs, weighted by a scalar texture read with `eval_1` and
//! clipped to [0, 1].
//!
//! * blendbsdf: f = (1 − w) f₀ + w f₁, pdf likewise. Sampling picks f₁ when s1 ≤ w
//!   (s1 rescaled for the nested sample), and weighs the sampled direction by the
//!   mixture: (w f₁ + (1 − w) f₀) / (w pdf₁ + (1 − w) pdf₀), in Mitsuba's exact form,
//!   so a Dirac sample mixed with the other BSDF's density comes out as Mitsuba's does.
//! * mask: f = α f_nested; with probability 1 − α the ray passes straight through (a
//!   null lobe, weight 1); shadow rays are let through by 1 − α (1 − the nested BSDF's
//!   own null transmission).

use glam::{Vec2, Vec3, Vec3A};

use super::{Bsdf, BsdfSample};
use crate::texture::Texture;

#[derive(Clone, Debug)]
pub struct Blend {
    pub weight: Texture,
    pub bsdfs: [Bsdf; 2],
}

impl Blend {
    #[inline]
    pub fn weight(&self, uv: Vec2) -> f32 {
        self.weight.eval_1(uv).clamp(0.0, 1.0)
    }

    pub fn eval_pdf(&self, wi: Vec3A, wo: Vec3A, uv: Vec2) -> (Vec3, f32) {
        let w = self.weight(uv);
        let (f0, p0) = self.bsdfs[0].eval_pdf(wi, wo, uv);
        let (f1, p1) = self.bsdfs[1].eval_pdf(wi, wo, uv);
        (f0 * (1.0 - w) + f1 * w, p0 * (1.0 - w) + p1 * w)
    }

    pub fn sample(&self, wi: Vec3A, s1: f32, s2: Vec2, uv: Vec2) -> Option<BsdfSample> {
        let w = self.weight(uv);
        // Which is sampled, with what probability, and the other one.
        let (first, s1, p_pick) = if s1 > w || w == 0.0 {
            (0, (s1 - w) / (1.0 - w), 1.0 - w)
        } else {
            (1, s1 / w, w)
        };
        let mut bs = self.bsdfs[first].sample(wi, s1, s2, uv)?;
        let (f_other, pdf_other) = self.bsdfs[1 - first].eval_pdf(wi, bs.wo, uv);
        let pdf = (1.0 - p_pick) * pdf_other + p_pick * bs.pdf;
        if pdf.is_nan() || pdf <= 0.0 {
            return None;
        }
        // (f_other (1 − p) + (weight · pdf) p) / pdf_mixed, weight · pdf being the
        // sampled BSDF's f · |cos| (or its Dirac mass).
        bs.weight = (f_other * (1.0 - p_pick) + bs.weight * (bs.pdf * p_pick)) / pdf;
        bs.pdf = pdf;
        Some(bs)
    }

    pub fn null_transmission(&self, cos_o: f32, uv: Vec2) -> Vec3 {
        if !self.bsdfs.iter().any(Bsdf::has_null_component) {
            return Vec3::ZERO;
        }
        let w = self.weight(uv);
        self.bsdfs[0].null_transmission(cos_o, uv) * (1.0 - w)
            + self.bsdfs[1].null_transmission(cos_o, uv) * w
    }
}

#[derive(Clone, Debug)]
pub struct Mask {
    pub opacity: Texture,
    pub nested: Bsdf,
}

impl Mask {
    #[inline]
    pub fn opacity(&self, uv: Vec2) -> f32 {
        self.opacity.eval_1(uv).clamp(0.0, 1.0)
    }

    pub fn eval_pdf(&self, wi: Vec3A, wo: Vec3A, uv: Vec2) -> (Vec3, f32) {
        let a = self.opacity(uv);
        let (f, pdf) = self.nested.eval_pdf(wi, wo, uv);
        (f * a, pdf * a)
    }

    pub fn sample(&self, wi: Vec3A, s1: f32, s2: Vec2, uv: Vec2) -> Option<BsdfSample> {
        let a = self.opacity(uv);
        if s1 < a {
            let mut bs = self.nested.sample(wi, s1 / a, s2, uv)?;
            bs.pdf *= a;
            Some(bs)
        } else {
            Some(BsdfSample {
                wo: -wi,
                pdf: 1.0 - a,
                weight: Vec3::ONE,
                eta: 1.0,
                delta: true,
                null: true,
            })
        }
    }

    pub fn null_transmission(&self, cos_o: f32, uv: Vec2) -> Vec3 {
        let a = self.opacity(uv);
        Vec3::ONE - (Vec3::ONE - self.nested.null_transmission(cos_o, uv)) * a
    }
}
