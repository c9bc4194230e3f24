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

use crate::denoise::AuxImages;
use glam::{Vec2, Vec3, Vec3A};
use rayon::prelude::*;

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
                o = h.offset_p(d, scene.offset_scale);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::{render, scene_from_xml, RenderOptions};

    /// A pinhole at the origin looking along +z (fov 90 across x: the plane z = 2 spans
    /// x ∈ [−2, 2] over the film's 8 columns, half a unit each), a box filter, and `body`.
    fn scene(name: &str, body: &str) -> Scene {
        let xml = format!(
            r#"<scene version="3.0.0">
            <integrator type="path"/>
            <sensor type="perspective"><float name="fov" value="90"/>
                <transform name="to_world"><lookat origin="0,0,0" target="0,0,1" up="0,1,0"/></transform>
                <sampler type="independent"><integer name="sample_count" value="1"/></sampler>
                <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/>
                    <rfilter type="box"/></film></sensor>
            {body}
            </scene>"#
        );
        scene_from_xml("aovs", name, &xml)
    }

    /// A rectangle light facing the camera at z = 2 whose left edge is at x = 0.125, a
    /// quarter of a column right of the film's centre line (x = 0.5 a column there): each
    /// row's edge pixel is covered 0.75 or 0.25 (by the film's orientation), the row's
    /// light sums to 3.75 columns. The sharpened seen emission must give exactly those,
    /// within the error of 1024 stratified rays on a straight edge, and change only the
    /// 8 edge pixels. Power: the render's own sample a pixel misses it.
    #[test]
    fn the_seen_emission_of_an_edge_is_its_coverage() {
        let s = scene(
            "edge",
            r#"<shape type="rectangle"><transform name="to_world">
                <rotate y="1" angle="180"/><scale value="5"/><translate x="5.125" z="2"/></transform>
                <emitter type="area"><rgb name="radiance" value="2, 2, 2"/></emitter></shape>"#,
        );
        let opts = RenderOptions {
            show_progress: false,
            seen_emission: true,
            ..Default::default()
        };
        let mut seen = render(&s, &s.shot, &opts).seen_emission.unwrap();
        let before = seen.clone();
        let replaced = sharpen_seen_emission(&s, &s.shot, &mut seen);
        assert_eq!(replaced, 8, "one edge pixel a row");
        let mut rough = 0f32;
        for y in 0..8 {
            let row = &seen.pixels[y * 8..(y + 1) * 8];
            let sum: f32 = row.iter().map(|p| p[0]).sum();
            assert!((sum - 2.0 * 3.75).abs() < 0.02, "row {y}: {sum}");
            let edge: Vec<f32> = row
                .iter()
                .map(|p| p[0] / 2.0)
                .filter(|&c| c > 0.0 && c < 1.0)
                .collect();
            assert_eq!(edge.len(), 1, "row {y}: {row:?}");
            assert!(
                (edge[0] - 0.25).abs() < 0.01 || (edge[0] - 0.75).abs() < 0.01,
                "row {y}: coverage {}",
                edge[0]
            );
            let raw: f32 = before.pixels[y * 8..(y + 1) * 8].iter().map(|p| p[0]).sum();
            rough = rough.max((raw - 2.0 * 3.75).abs());
        }
        assert!(
            rough > 0.02,
            "the render's own estimate was already exact ({rough})"
        );
    }

    /// The first-hit albedo and normal against what they must be: a diffuse wall filling
    /// the view gives its reflectance and the normal facing the camera; a null sphere of
    /// medium around the camera's view gives the medium's single-scattering albedo; the
    /// sky gives 0.
    #[test]
    fn first_hit_aovs_are_the_reflectance_the_medium_albedo_and_zero() {
        let wall = scene(
            "wall",
            r#"<shape type="rectangle"><transform name="to_world">
                <rotate y="1" angle="180"/><scale value="50"/><translate z="3"/></transform>
                <bsdf type="diffuse"><rgb name="reflectance" value="0.3, 0.5, 0.7"/></bsdf></shape>"#,
        );
        let aux = first_hit_aovs(&wall, &wall.shot);
        for (a, n) in aux.albedo.pixels.iter().zip(&aux.normal.pixels) {
            for (got, want) in a.iter().zip([0.3, 0.5, 0.7]) {
                assert!((got - want).abs() < 1e-6, "albedo {a:?}");
            }
            assert!(
                (n[2] + 1.0).abs() < 1e-5 && n[0].abs() < 1e-5,
                "normal {n:?}"
            );
        }
        let fog = scene(
            "fog",
            r#"<shape type="sphere"><float name="radius" value="1"/><point name="center" x="0" y="0" z="10"/>
                <bsdf type="null"/><medium type="homogeneous" name="interior">
                <rgb name="sigma_t" value="0.25, 0.5, 1"/><float name="scale" value="4"/>
                <rgb name="albedo" value="0.9, 0.6, 0.3"/></medium></shape>
               <emitter type="constant"><rgb name="radiance" value="1, 1, 1"/></emitter>"#,
        );
        let aux = first_hit_aovs(&fog, &fog.shot);
        // The centre pixels see the sphere (it spans about a third of a column at z = 10
        // on each side of the axis: the four centre pixels partly), the corners the sky.
        let corner = aux.albedo.pixels[0];
        assert_eq!(corner, [0.0; 3], "the sky's albedo");
        assert_eq!(aux.normal.pixels[0], [0.0; 3], "the sky's normal");
        let centre = aux.albedo.pixels[3 * 8 + 3];
        let covered = centre[0] / 0.9;
        assert!(covered > 0.05, "the sphere is seen: {centre:?}");
        for (c, want) in centre.iter().zip([0.9, 0.6, 0.3]) {
            assert!((c / covered - want).abs() < 1e-5, "{centre:?}");
        }
    }
}
