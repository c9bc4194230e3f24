//! A direction toward a light from a reference point, written once over the number type
//! (`simd::Float`): [`super::Emitter::sample_direction`] runs these on one path, the
//! packet in lanes where a vertex's one emitter has one of these forms. Each rounds as
//! the one-path code always did.

use glam::Vec3;

use crate::geometry::shape::sample_sphere_cone;
use crate::simd::{Float, Vector3};

/// An emitter sample before its shadow ray, for a path or lanes of paths.
pub struct DirectionSample<F: Float> {
    /// Unit direction toward the light.
    pub d: Vector3<F>,
    /// How far along `d` the light's point lies (a directional light's: twice the
    /// scene's bounding radius, or the distance to its centre, whichever is more).
    pub dist: F,
    /// Solid-angle pdf; 1 for a Dirac light.
    pub pdf: F,
    /// `L_e G / pdf`: for a Dirac light the incident radiance.
    pub weight: Vector3<F>,
    /// Where this is a sample (the light faces the point, the pdf is finite and
    /// positive); the fields mean nothing elsewhere.
    pub valid: F::Mask,
}

/// Toward a point light at `position` of `intensity`: `intensity / r²`.
#[inline(always)]
pub fn toward_point<F: Float>(
    position: Vector3<F>,
    intensity: Vec3,
    p_ref: Vector3<F>,
) -> DirectionSample<F> {
    let v = position.sub(p_ref);
    let dist2 = v.dot(v);
    let dist = dist2.sqrt();
    DirectionSample {
        d: v.div(dist),
        dist,
        pdf: F::one(),
        weight: Vector3::splat(intensity).div(dist2),
        valid: dist2.gt(F::zero()),
    }
}

/// Toward a directional light arriving along −`toward` (`irradiance` on a surface
/// facing it), from inside or outside the scene's bounding sphere `(center, radius)`:
/// the light's point lies 2r along `toward`, r the larger of the radius and the
/// point's distance from the centre (beyond every shape).
#[inline(always)]
pub fn along_direction<F: Float>(
    toward: Vec3,
    irradiance: Vec3,
    (center, radius): (Vec3, f32),
    p_ref: Vector3<F>,
) -> DirectionSample<F> {
    let c = p_ref.sub(Vector3::splat(center));
    let r = F::of(radius as f64).max(c.dot(c).sqrt());
    DirectionSample {
        d: Vector3::splat(toward),
        dist: F::of(2.0) * r,
        pdf: F::one(),
        weight: Vector3::splat(irradiance),
        valid: F::mask(true),
    }
}

/// Toward the point `p_light` (normal `n_light`) drawn uniformly on an area light of
/// `area` and `radiance`, lit on its front side only: the solid-angle pdf is
/// pdf_A r² / |cos θ_light| = r² / (area |cos θ_light|).
#[inline(always)]
pub fn toward_area_point<F: Float>(
    (p_light, n_light): (Vector3<F>, Vector3<F>),
    area: F,
    radiance: Vec3,
    p_ref: Vector3<F>,
) -> DirectionSample<F> {
    let v = p_light.sub(p_ref);
    let dist2 = v.dot(v);
    let dist = dist2.sqrt();
    let d = v.div(dist);
    let cos = n_light.dot(d);
    let pdf = dist2 / (area * cos.negate());
    // (A point on the light gives d = NaN, and no sample.)
    let valid = cos.lt(F::zero()) & pdf.is_finite() & pdf.gt(F::zero());
    DirectionSample {
        d,
        dist,
        pdf,
        weight: Vector3::splat(radiance).div(pdf),
        valid,
    }
}

/// Toward a spherical area light (`center`, `radius`; its normals inward where
/// `flip_normals`) of `radiance`, a direction uniform in the cone it fills
/// ([`sample_sphere_cone`]), from the draws `u`; with the paths inside the sphere,
/// which have no cone (the caller samples its area there).
#[inline(always)]
pub fn toward_sphere<F: Float>(
    (center, radius, flip_normals): (Vec3, f32, bool),
    radiance: Vec3,
    p_ref: Vector3<F>,
    (u1, u2): (F, F),
) -> (DirectionSample<F>, F::Mask) {
    let center = Vector3::splat(center);
    let c = sample_sphere_cone(center, radius, p_ref, u1, u2);
    // The light's outward normal where d meets it must face back along d (inward:
    // along it). Normalized before the test, as the one path always did, so that the
    // sign of a near-tangent dot product rounds the same.
    let out = p_ref.add(c.d.scale(c.dist)).sub(center);
    let n = out.div(out.dot(out).sqrt());
    let facing = n.dot(c.d);
    let faces = match flip_normals {
        false => facing.lt(F::zero()),
        true => facing.gt(F::zero()),
    };
    let valid = !c.inside & c.dist.gt(F::zero()) & faces & c.pdf.is_finite();
    let sample = DirectionSample {
        d: c.d,
        dist: c.dist,
        pdf: c.pdf,
        weight: Vector3::splat(radiance).div(c.pdf),
        valid,
    };
    (sample, c.inside)
}
