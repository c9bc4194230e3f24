//! The auxiliary images a denoiser takes (`render --aovs`, `--denoise oidn`): per pixel,
//! the albedo and the normal of what the camera sees first, averaged over `AOV_SAMPLES`
//! rays through the pixel so that they are free of noise (OIDN's `cleanAux`).
//!
//! What a ray sees first, and what it contributes:
//! - a surface: its BSDF's directional albedo toward the camera, ρ(ω_o) = E[f cos / p]
//!   (one BSDF sample per ray, as pbrt-v4's `rho`; exact for `diffuse`), clamped to
//!   [0, 1], and its shading normal facing the camera;
//! - a null boundary into a medium (or a camera inside one): the medium's single-
//!   scattering albedo σ_s/σ_t, which is the colour of the light it scatters, and the
//!   boundary's normal (none for a camera inside). A null boundary that changes no
//!   medium is passed through;
//! - nothing (the environment) or an emitter's surface: albedo 0 and normal 0: the
//!   light there is directly seen emission, which `denoise` keeps out of the filter.

use glam::{Vec2, Vec3, Vec3A};
use rayon::prelude::*;

use crate::denoise::AuxImages;
use crate::geometry::offset_point;
use crate::image::Image;
use crate::sampling::{Pcg32, PixelSamples};
use crate::scene::shot::Shot;
use crate::scene::Scene;

/// Rays per pixel: the aliasing of an edge left in a 16-ray average is far below what a
/// denoiser resolves.
pub const AOV_SAMPLES: u32 = 16;
/// Null crossings followed before a ray counts as seeing nothing.
const MAX_CROSSINGS: u32 = 16;

/// One pixel's albedo and normal.
type AlbedoNormal = ([f32; 3], [f32; 3]);

/// The albedo and normal images of the shot's crop window.
pub fn first_hit_aovs(scene: &Scene, shot: &Shot) -> AuxImages {
    let film = &shot.film;
    let (cw, ch) = film.crop_size;
    let (ox, oy) = film.crop_offset;
    let rows: Vec<Vec<AlbedoNormal>> = (0..ch)
        .into_par_iter()
        .map(|y| {
            (0..cw)
                .map(|x| {
                    let (fx, fy) = (x + ox, y + oy);
                    let pixel = (fy * film.width + fx) as u64;
                    pixel_aovs(scene, shot, pixel, Vec2::new(fx as f32, fy as f32))
                })
                .collect()
        })
        .collect();
    let image = |pick: fn(&AlbedoNormal) -> [f32; 3]| Image {
        width: cw,
        height: ch,
        pixels: rows.iter().flatten().map(pick).collect(),
    };
    AuxImages {
        albedo: image(|p| p.0),
        normal: image(|p| p.1),
    }
}

/// The mean albedo and normal over the pixel's rays (at its first `AOV_SAMPLES`
/// sample positions, the render's own).
fn pixel_aovs(scene: &Scene, shot: &Shot, pixel: u64, corner: Vec2) -> AlbedoNormal {
    let positions = PixelSamples::new(shot.seed, pixel);
    // A stream no render sample uses (render samples count up from 0).
    let mut rng = Pcg32::for_sample(shot.seed, pixel, u64::MAX - 2);
    let (mut albedo, mut normal) = (Vec3::ZERO, Vec3::ZERO);
    for i in 0..AOV_SAMPLES {
        let ray = shot.camera.sample_ray(corner + positions.get(i));
        let (a, n) = first_seen(scene, ray.o, ray.d, ray.tmax, &mut rng);
        albedo += a;
        normal += n;
    }
    let k = 1.0 / AOV_SAMPLES as f32;
    ((albedo * k).to_array(), (normal * k).to_array())
}

/// What one camera ray sees first (see the module comment): its albedo and normal.
fn first_seen(scene: &Scene, o: Vec3A, d: Vec3A, tmax: f32, rng: &mut Pcg32) -> (Vec3, Vec3) {
    if let Some(m) = scene.camera_medium {
        return (scene.media[m as usize].albedo, Vec3::ZERO);
    }
    let mut o = o;
    let mut tmax = tmax;
    for _ in 0..MAX_CROSSINGS {
        let Some(h) = scene.intersect(o, d, tmax) else {
            break;
        };
        let info = &scene.shapes[h.shape as usize];
        let facing = if h.sh_frame.n.dot(d) > 0.0 {
            -h.sh_frame.n
        } else {
            h.sh_frame.n
        };
        if info.emitter.is_some() {
            break;
        }
        let bsdf = &scene.bsdfs[info.bsdf as usize];
        let entering = if h.n.dot(d) < 0.0 {
            info.interior
        } else {
            info.exterior
        };
        if let (Some(m), true) = (entering, bsdf.has_null_component()) {
            return (scene.media[m as usize].albedo, Vec3::from(facing));
        }
        let wi = h.sh_frame.to_local(-d);
        let s1 = rng.next_1d();
        let s2 = rng.next_2d();
        match bsdf.sample(wi, s1, s2, h.uv) {
            Some(bs) if bs.null => {
                o = offset_point(h.p, h.n, d, scene.offset_scale);
                tmax = f32::INFINITY;
            }
            Some(bs) => {
                let a = bs.weight.clamp(Vec3::ZERO, Vec3::ONE);
                let a = if a.is_finite() { a } else { Vec3::ZERO };
                return (a, Vec3::from(facing));
            }
            None => return (Vec3::ZERO, Vec3::from(facing)),
        }
    }
    (Vec3::ZERO, Vec3::ZERO)
}

/// Probe rays per pixel that decide whether it lies on the edge of a seen emitter.
const EDGE_PROBES: u32 = 16;
/// Rays per edge pixel of the seen emission's estimate.
pub const EDGE_RAYS: u32 = 1024;

/// What the camera ray's first intersection shows of an emitter, as the integrators
/// count it in `PathSample::seen_emission`: which emitter and its emitted radiance; None
/// where no emitting surface is seen (the environment is left to the denoiser), or where
/// the `path` integrator could drop the sample (an emitter with a null BSDF, whose
/// sample counts only if the path later scatters), which this pass cannot tell.
fn seen_at_first(scene: &Scene, o: Vec3A, d: Vec3A, tmax: f32) -> Option<(u32, Vec3)> {
    if scene.integrator.hide_emitters || scene.camera_medium.is_some() {
        return None;
    }
    match scene.intersect(o, d, tmax) {
        Some(h) => {
            let info = &scene.shapes[h.shape as usize];
            let ei = info.emitter?;
            if scene.bsdfs[info.bsdf as usize].has_null_component() {
                return Some((u32::MAX - 1, Vec3::NAN));
            }
            Some((ei, scene.emitters[ei as usize].eval(h.sh_frame.n, d)))
        }
        None => None,
    }
}

/// Replaces, in `seen` (a render's `seen_emission`, same shot), the pixels on the edge of
/// a directly seen emitter by an estimate of `EDGE_RAYS` rays. There a render's few
/// samples per pixel give the edge's coverage with a noise of the emitter's own
/// magnitude, which the denoiser keeps as it is; elsewhere what the pixel sees emits
/// the same everywhere in it, and the render's value stands.
///
/// A pixel is an edge where `EDGE_PROBES` rays spread over its filter's support do not
/// all see the same emitter (or all none). Its estimate is the render's estimand,
///
///   E_p = ∫ w(x − c_p) E(x) dx / ∫ w(x − c_p) dx,                            (A1)
///
/// x over the filter's support around the pixel centre c_p, within the crop window
/// (where the render's samples lie), by the same ratio of sums over stratified points.
/// Which pixels are edges depends on the probes alone, not on the render's samples, so
/// the result stays an unbiased estimate of the seen emission. Returns how many pixels
/// were replaced.
pub fn sharpen_seen_emission(scene: &Scene, shot: &Shot, seen: &mut Image) -> usize {
    let film = &shot.film;
    let (cw, ch) = film.crop_size;
    let (ox, oy) = film.crop_offset;
    assert_eq!((seen.width, seen.height), (cw, ch), "one image of the shot");
    let r = film.rfilter.radius();
    let window = (
        Vec2::new(ox as f32, oy as f32),
        Vec2::new((ox + cw) as f32, (oy + ch) as f32),
    );
    // The weighted mean of the emission over `n` points of the pixel's support, and
    // whether the first `n` points all saw the same emitter.
    let estimate = |pixel: u64, centre: Vec2, n: u32, stream: u64| -> (Vec3, bool) {
        let points = PixelSamples::new(shot.seed ^ stream, pixel);
        let (mut sum, mut weights) = (Vec3::ZERO, 0.0f32);
        let mut first: Option<Option<u32>> = None;
        let mut uniform = true;
        for i in 0..n {
            let x = centre + (points.get(i) * 2.0 - Vec2::ONE) * r;
            if x.cmplt(window.0).any() || x.cmpge(window.1).any() {
                continue;
            }
            let off = x - centre;
            let w = film.rfilter.eval(off.x) * film.rfilter.eval(off.y);
            let ray = shot.camera.sample_ray(x);
            let seen = seen_at_first(scene, ray.o, ray.d, ray.tmax);
            let id = seen.map(|s| s.0);
            uniform &= *first.get_or_insert(id) == id;
            if w > 0.0 {
                sum += w * seen.map_or(Vec3::ZERO, |s| s.1);
                weights += w;
            }
        }
        (sum / weights.max(f32::MIN_POSITIVE), uniform)
    };
    let replaced: Vec<Option<[f32; 3]>> = (0..cw * ch)
        .into_par_iter()
        .map(|i| {
            let (fx, fy) = (i % cw + ox, i / cw + oy);
            let pixel = (fy * film.width + fx) as u64;
            let centre = Vec2::new(fx as f32 + 0.5, fy as f32 + 0.5);
            let (_, uniform) = estimate(pixel, centre, EDGE_PROBES, 0x9e37_79b9);
            if uniform {
                return None;
            }
            let (e, _) = estimate(pixel, centre, EDGE_RAYS, 0x7f4a_7c15);
            // An emitter this pass cannot follow (see `seen_at_first`): keep the render's.
            e.is_finite().then(|| e.to_array())
        })
        .collect();
    let mut count = 0;
    for (p, r) in seen.pixels.iter_mut().zip(replaced) {
        if let Some(v) = r {
            *p = v;
            count += 1;
        }
    }
    count
}
