//! A warning, before rendering, when paths in a medium will be very long.
//!
//! In a medium of albedo α and optical radius τ = σ_t R (R: the scene's half-size), a
//! path scatters until it is absorbed (~1/(1 − α) vertices) or diffuses out (~τ²
//! vertices), whichever comes first. Russian roulette (Mitsuba's q = min(max β · η²,
//! 0.95) past rr_depth) ends a path after ~20 more vertices in expectation, and
//! max_depth caps it. At albedo 1 and σ_t 1e4 over a unit scene, with rr_depth beyond
//! reach and no max_depth, a path takes ~1e8 vertices: days for an image.

use super::shot::Shot;
use super::{IntegratorKind, Scene};

/// Medium vertices per second a render thread manages, for the estimate (order of
/// magnitude; measured ~1e7 on this project's machines).
const VERTICES_PER_SECOND: f64 = 1e7;
/// Warn above this estimated render time.
const WARN_SECONDS: f64 = 3600.0;

/// Expected scattering vertices of one path in the worst medium, and the medium's name.
pub fn expected_path_vertices(scene: &Scene) -> Option<(f64, String)> {
    if scene.integrator.kind != IntegratorKind::Volpath {
        return None;
    }
    let s = &scene.integrator;
    scene
        .media
        .iter()
        .enumerate()
        .map(|(i, m)| {
            // A heterogeneous medium's albedo: the factor on its volume times its largest value.
            let volume_max = m.heterogeneous.as_ref().map_or(1.0, |h| h.albedo.max);
            let albedo = (m.albedo.max_element() * volume_max) as f64;
            let tau = m.sigma_t.max_element() as f64 * scene.offset_scale as f64;
            let absorbed = if albedo < 1.0 {
                1.0 / (1.0 - albedo)
            } else {
                f64::INFINITY
            };
            let physical = absorbed.min(1.0 + tau * tau);
            // Russian roulette from rr_depth on: ~1/(1 − 0.95) more vertices.
            let with_rr = physical.min(s.rr_depth as f64 + 20.0);
            let n = with_rr.min(s.max_depth as f64);
            let name = m.id.clone().unwrap_or_else(|| format!("#{i}"));
            (n, name)
        })
        .max_by(|a, b| a.0.total_cmp(&b.0))
}

/// The warning to print before rendering `shot`, if the estimate exceeds an hour.
pub fn long_render_warning(scene: &Scene, shot: &Shot, threads: usize) -> Option<String> {
    let (vertices, name) = expected_path_vertices(scene)?;
    let (w, h) = shot.film.crop_size;
    let paths = (w * h) as f64 * shot.spp as f64;
    let seconds = paths * vertices / (VERTICES_PER_SECOND * threads.max(1) as f64);
    (seconds > WARN_SECONDS).then(|| {
        format!(
            "paths in medium {name} may scatter ~{vertices:.0e} times each (albedo near 1, optically thick, \
             Russian roulette from depth {} and max_depth {}): this render may take ~{:.0e} hours. \
             Set the integrator's max_depth or a lower rr_depth to bound it",
            scene.integrator.rr_depth,
            if scene.integrator.max_depth == u32::MAX {
                "-1".to_string()
            } else {
                scene.integrator.max_depth.to_string()
            },
            seconds / 3600.0
        )
    })
}
