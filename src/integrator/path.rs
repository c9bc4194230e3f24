//! Mitsuba 3's `path` integrator (`src/integrators/path.cpp`): unidirectional path
//! tracing with emitter sampling and BSDF sampling combined by the power heuristic.
//!
//! Depth: an emitter hit after `d` scattering events counts iff `d + 1 ≤ max_depth`;
//! emitter sampling at depth `d` happens iff `d + 2 ≤ max_depth`. `null` surfaces count
//! as a bounce, as in Mitsuba. Russian roulette from `depth ≥ rr_depth` continues with
//! probability `min(max_c(throughput) · η², 0.95)`.

use glam::{Vec3, Vec3A};

use super::emitters::{sample_light_at_surface, skip_emitters};
use super::roulette::roulette;
use super::sample::PathSample;
use crate::sampling::{mis_weight, Pcg32};
use crate::scene::Scene;
use crate::simd::Vector3;

/// Where the previous bounce happened, for MIS of emitter hits.
#[derive(Clone, Copy)]
struct PrevVertex {
    p: Vec3A,
    bsdf_pdf: f32,
    delta: bool,
}

/// One radiance sample along the camera ray (o, d).
pub fn sample(scene: &Scene, o: Vec3A, d: Vec3A, tmax: f32, rng: &mut Pcg32) -> PathSample {
    let s = &scene.integrator;
    if s.max_depth == 0 {
        return PathSample::default();
    }
    let mut result = Vec3::ZERO;
    let mut seen_emission = Vec3::ZERO;
    let mut throughput = Vec3::ONE;
    let mut eta = 1.0f32;
    let mut depth: u32 = 0;
    // With hide_emitters, the environment counts only once the path has scattered off a
    // non-null surface (Mitsuba's `valid_ray`).
    let mut valid_ray = !s.hide_emitters && scene.environment.is_some();
    let mut prev = PrevVertex {
        p: o,
        bsdf_pdf: 1.0,
        delta: true,
    };
    let mut ray_d = d;
    let mut si = if s.hide_emitters {
        skip_emitters(scene, o, d, tmax)
    } else {
        scene.intersect(o, d, tmax)
    };
    loop {
        // ---- Emission seen by this ray (area light hit, or the environment) ----
        let emitter = match &si {
            Some(h) => scene.shapes[h.shape as usize].emitter,
            None => scene.environment,
        };
        if let Some(ei) = emitter {
            let e = &scene.emitters[ei as usize];
            // Where the ray ended: a surface point and its normal, or (environment) none.
            let (p_end, n_end) = si.map_or((prev.p, Vec3A::ZERO), |h| (h.p, h.sh_frame.n));
            // After a Dirac bounce emitter sampling could not have produced this path.
            let (le, em_pdf) = if prev.delta {
                (e.eval(n_end, ray_d), 0.0)
            } else {
                let (le, pdf) = e.eval_and_pdf(prev.p, p_end, n_end, ray_d, &scene.geometries);
                (le, pdf * scene.emitter_selection.pdf(prev.p, ei as usize))
            };
            let l = throughput * le * mis_weight(prev.bsdf_pdf, em_pdf);
            result += l;
            if depth == 0 && si.is_some() {
                seen_emission = l;
            }
        }

        let h = match si {
            Some(h) if depth.saturating_add(1) < s.max_depth => h,
            _ => {
                // The path ends here; what it saw counts unless emitters are hidden.
                if emitter.is_some() && !s.hide_emitters {
                    valid_ray = true;
                }
                break;
            }
        };
        let info = &scene.shapes[h.shape as usize];
        let bsdf = &scene.bsdfs[info.bsdf as usize];
        let wi = h.sh_frame.to_local(-ray_d);

        // ---- Emitter sampling ----
        if bsdf.is_smooth() && !scene.emitters.is_empty() {
            let visible = |o, d, dist| Vec3::splat(!scene.occluded(o, d, dist) as u8 as f32);
            if let Some(ls) = sample_light_at_surface(scene, &h, wi, bsdf, rng.next_2d(), visible) {
                let w = if ls.delta {
                    1.0
                } else {
                    mis_weight(ls.emitter_pdf, ls.bsdf_pdf)
                };
                result += throughput * ls.value * w;
            }
        }

        // ---- BSDF sampling ----
        let s1 = rng.next_1d();
        let s2 = rng.next_2d();
        let sampled = bsdf.sample(wi, s1, s2, h.uv);
        // Any scattering but a pass-through (null) sample makes the environment count, as
        // Mitsuba 3.9.1 tests the sampled lobe (a failed sample is not a null one there).
        if !sampled.is_some_and(|b| b.null) {
            valid_ray = true;
        }
        let Some(bs) = sampled else { break };
        let wo_world = h.sh_frame.to_world(bs.wo);
        throughput *= bs.weight;
        eta *= bs.eta;
        prev = PrevVertex {
            p: h.p,
            bsdf_pdf: bs.pdf,
            delta: bs.delta,
        };
        depth += 1;

        // ---- Russian roulette ----
        let tmax_c = throughput.max_element();
        if depth >= s.rr_depth {
            // Drawn only where played, as in volpath (the first draws are stratified).
            let u = rng.next_1d();
            let (goes_on, q) = roulette(throughput.into(), Vector3::all(0.0), eta, u);
            if !goes_on {
                break;
            }
            throughput /= q;
        }
        if tmax_c == 0.0 {
            break;
        }
        let o2 = h.offset_p(wo_world, scene.offset_scale);
        ray_d = wo_world;
        si = scene.intersect(o2, ray_d, f32::MAX);
    }
    if valid_ray {
        PathSample {
            radiance: result,
            seen_emission,
            valid: true,
            ..Default::default()
        }
    } else {
        PathSample::default()
    }
}
