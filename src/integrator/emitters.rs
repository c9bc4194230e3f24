//! What the integrators share about emitters: sampling one from a surface point
//! (Mitsuba's `sample_emitter_direction` with the BSDF's evaluation and the shadow ray)
//! and skipping emitter shapes for `hide_emitters`.

use glam::{Vec2, Vec3, Vec3A};

use crate::geometry::{offset_point, SHADOW_EPSILON};
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
    let so = offset_point(h.p, h.n, es.d, scene.offset_scale);
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
        let o2 = offset_point(si.p, si.n, d, scene.offset_scale);
        tmax -= (o2 - o).length();
        o = o2;
    }
}
