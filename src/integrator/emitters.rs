//! What the integrators share about emitters: sampling one from a surface point
//! (Mitsuba's `sample_emitter_direction` with the BSDF's evaluation and the shadow ray),
//! the MIS weight of an emitter a path meets, and skipping emitter shapes for
//! `hide_emitters`.

use glam::{Vec2, Vec3, Vec3A};

use crate::geometry::SHADOW_EPSILON;
use crate::sampling::mis_weight;
use crate::scene::{Scene, SurfaceInteraction};

/// Emitter sampling at a surface point, before MIS: the emitter-sampled direction's
/// BSDF-weighted radiance and both pdfs.
pub(crate) struct SurfaceLightSample {
    /// `f · Le · G / p` with the emitter selection included: the estimate with weight 1.
    pub value: Vec3,
    /// Solid-angle pdf of the direction under emitter sampling (selection included).
    pub emitter_pdf: f32,
    /// Pdf of the same direction under BSDF sampling.
    pub bsdf_pdf: f32,
    pub delta: bool,
}

/// Picks an emitter with `u` (`Scene::emitter_selection`; Mitsuba's
/// `sample_emitter_direction` picks uniformly), samples a direction to it from the
/// surface point `h`, and traces the shadow ray: `visibility`
/// (from the offset origin, unit direction, distance already shortened by
/// ShadowEpsilon) returns 1 (path, direct), or the transmittance of the media crossed
/// (volpath). None when nothing arrives (no emitter, back-facing, zero BSDF, blocked).
pub(crate) fn sample_light_at_surface(
    scene: &Scene,
    h: &SurfaceInteraction,
    wi: Vec3A,
    bsdf: &crate::bsdf::Bsdf,
    u: Vec2,
    visibility: impl FnOnce(Vec3A, Vec3A, f32) -> Vec3,
) -> Option<SurfaceLightSample> {
    // None where there is no emitter to pick.
    let (idx, u, p_select) = scene.emitter_selection.select(h.p, u)?;
    let es = scene.emitters[idx].sample_direction(h.p, u, &scene.geometries, &scene.bsphere)?;
    let (f, bsdf_pdf) = bsdf.eval_pdf(wi, h.sh_frame.to_local(es.d), h.uv);
    if f == Vec3::ZERO {
        return None;
    }
    // Shadow ray: spawn_ray_to(p), shortened by ShadowEpsilon.
    let so = h.offset_p(es.d, scene.offset_scale);
    let v = es.p - so;
    let dist = v.length();
    if dist <= 0.0 {
        return None;
    }
    let tr = visibility(so, v / dist, dist * (1.0 - SHADOW_EPSILON));
    if tr == Vec3::ZERO {
        return None;
    }
    Some(SurfaceLightSample {
        value: f * es.weight * tr / p_select,
        emitter_pdf: es.pdf * p_select,
        bsdf_pdf,
        delta: es.delta,
    })
}

/// The emission of emitter `ei` that a path meets at `p_end` (normal `n_end`; the
/// environment: the last vertex and a zero normal) along `d`, MIS-weighted against
/// emitter sampling at the vertex it last scattered at, `from` (whose direction's pdf
/// is `from_pdf`): the power heuristic of `from_pdf` against the emitter's solid-angle
/// pdf times its selection probability (Mitsuba's volpath). In `full` where emitter
/// sampling could not have made the path (the camera ray, after a specular chain).
#[inline]
pub(crate) fn emission_met(
    scene: &Scene,
    ei: u32,
    (p_end, n_end, d): (Vec3A, Vec3A, Vec3A),
    (from, from_pdf): (Vec3A, f32),
    full: bool,
) -> Vec3 {
    let e = &scene.emitters[ei as usize];
    if full {
        return e.eval(n_end, d);
    }
    let (le, pdf) = e.eval_and_pdf(from, p_end, n_end, d, &scene.geometries);
    let em_pdf = pdf * scene.emitter_selection.pdf(from, ei as usize);
    le * mis_weight(from_pdf, em_pdf)
}

/// The first hit along (o, d) that is not an emitter shape (`hide_emitters` on the
/// camera ray: Mitsuba's `skip_area_emitters`).
pub(crate) fn skip_emitters(
    scene: &Scene,
    mut o: Vec3A,
    d: Vec3A,
    mut tmax: f32,
) -> Option<SurfaceInteraction> {
    loop {
        let si = scene.intersect(o, d, tmax)?;
        if scene.shapes[si.shape as usize].emitter.is_none() {
            return Some(si);
        }
        let o2 = si.offset_p(d, scene.offset_scale);
        tmax -= (o2 - o).length();
        o = o2;
    }
}
