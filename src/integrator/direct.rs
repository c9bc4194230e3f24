//! Mitsuba 3's `direct` integrator (`src/integrators/direct.cpp`): direct illumination
//! only, at the first surface the camera ray meets, with `emitter_samples` emitter
//! samples and `bsdf_samples` BSDF samples combined by the power heuristic over the
//! sample fractions:
//!
//!   emitter sample: f · L / p_e · w(p_e f_e, p_b f_b) / n_e,
//!   BSDF sample:    f · L / p_b · w(p_b f_b, p_e f_e) / n_b,
//!
//! with f_e = n_e / (n_e + n_b), f_b = n_b / (n_e + n_b) and w the power heuristic.
//! Media are ignored, as in Mitsuba.
//!
//! Kept from Mitsuba 3.9.1 as it is: a delta emitter's (point, directional) sample gets
//! weight 1, **not 1 / n_e**, so with `emitter_samples` = n such lights count n times.
//! (Rendering `emitter_samples` 4 against 1 in Mitsuba gives 3.7× the image of a point-lit
//! plane.) A file written for Mitsuba expects that image.

use glam::{Vec3, Vec3A};

use super::emitters::sample_light_at_surface;
use super::sample::PathSample;
use crate::sampling::mis_weight;
use crate::sampling::Pcg32;
use crate::scene::Scene;

/// One radiance sample along the camera ray (o, d).
pub fn sample(
    scene: &Scene,
    o: Vec3A,
    d: Vec3A,
    tmax: f32,
    rng: &mut Pcg32,
    emitter_samples: u32,
    bsdf_samples: u32,
) -> PathSample {
    let total = (emitter_samples + bsdf_samples) as f32;
    let (frac_lum, frac_bsdf) = (emitter_samples as f32 / total, bsdf_samples as f32 / total);
    let si = scene.intersect(o, d, tmax);
    let mut result = Vec3::ZERO;

    // ---- Visible emitters ----
    let emitter = match &si {
        Some(h) => scene.shapes[h.shape as usize].emitter,
        None => scene.environment,
    };
    if let Some(ei) = emitter {
        let n_end = si.map_or(Vec3A::ZERO, |h| h.sh_frame.n);
        result += scene.emitters[ei as usize].eval(n_end, d);
    }
    let seen_emission = if si.is_some() { result } else { Vec3::ZERO };
    // `valid`: the ray hit a surface (Mitsuba's `valid_ray`: the film's alpha).
    let done = |radiance, valid| PathSample {
        radiance,
        seen_emission,
        valid,
        ..Default::default()
    };
    let Some(h) = si else {
        return done(result, false);
    };
    let bsdf = &scene.bsdfs[scene.shapes[h.shape as usize].bsdf as usize];
    let wi = h.sh_frame.to_local(-d);

    // ---- Emitter sampling ----
    if bsdf.is_smooth() && !scene.emitters.is_empty() {
        for _ in 0..emitter_samples {
            let visible = |o, d, dist| Vec3::splat(!scene.occluded(o, d, dist) as u8 as f32);
            let Some(ls) = sample_light_at_surface(scene, &h, wi, bsdf, rng.next_2d(), visible)
            else {
                continue;
            };
            let w = if ls.delta {
                1.0
            } else {
                mis_weight(ls.emitter_pdf * frac_lum, ls.bsdf_pdf * frac_bsdf)
                    / emitter_samples as f32
            };
            result += ls.value * w;
        }
    }

    // ---- BSDF sampling ----
    for _ in 0..bsdf_samples {
        let s1 = rng.next_1d();
        let s2 = rng.next_2d();
        let Some(bs) = bsdf.sample(wi, s1, s2, h.uv) else {
            continue;
        };
        if bs.weight == Vec3::ZERO {
            continue;
        }
        let wo = h.sh_frame.to_world(bs.wo);
        let hit = scene.intersect(h.offset_p(wo, scene.offset_scale), wo, f32::MAX);
        let emitter = match &hit {
            Some(g) => scene.shapes[g.shape as usize].emitter,
            None => scene.environment,
        };
        let Some(ei) = emitter else { continue };
        let e = &scene.emitters[ei as usize];
        let (p_end, n_end) = hit.map_or((h.p, Vec3A::ZERO), |g| (g.p, g.sh_frame.n));
        let (le, em_pdf) = if bs.delta {
            (e.eval(n_end, wo), 0.0)
        } else {
            let (le, pdf) = e.eval_and_pdf(h.p, p_end, n_end, wo, &scene.geometries);
            (le, pdf * scene.emitter_selection.pdf(h.p, ei as usize))
        };
        let w = mis_weight(bs.pdf * frac_bsdf, em_pdf * frac_lum) / bsdf_samples as f32;
        result += bs.weight * le * w;
    }
    done(result, true)
}
