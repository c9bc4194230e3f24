//! Rendering: the film is cut into blocks (32×32, smaller for small images) rendered in
//! parallel (rayon), in passes of samples per pixel (1, 1, 2, 4, … up to an eighth of
//! the total), so that a render can be cut short between passes with an image of
//! uniform spp. Each sample has its own random stream (seed, pixel, sample index) and
//! its position in the pixel from the pixel's shifted (0,2)-sequence (`sampling::pixel`),
//! and blocks are merged in a fixed order whose pass schedule depends on spp only, so a
//! seed gives the bit-identical image at any thread count.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use glam::{Vec2, Vec3};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use super::packet::{self, PacketScene};
use super::sample::PathSample;
use super::volpath::PathSettings;
use super::{direct, path, volpath};
use crate::image::Image;
use crate::sampling::{PaddedScrambles, Pcg32, PixelSamples};
use crate::scene::film::{ImageBlock, Rfilter};
use crate::scene::shot::Shot;
use crate::scene::{IntegratorKind, Scene};

/// The block side: 32, or smaller for a small image so that there are at least
/// `MIN_BLOCKS` blocks to share between threads (a 64×64 film in four 32×32 blocks
/// of unequal cost kept one of two threads idle a third of the time). It depends on the
/// image size only, never on the thread count, so the image stays bit-identical at any
/// thread count.
fn block_size(width: usize, height: usize) -> usize {
    const MIN_BLOCKS: usize = 64;
    [32, 16, 8]
        .into_iter()
        .find(|&b| width.div_ceil(b) * height.div_ceil(b) >= MIN_BLOCKS)
        .unwrap_or(8)
}

#[derive(Clone, Debug)]
pub struct RenderStats {
    pub spp: u32,
    pub samples: u64,
    pub seconds: f64,
    /// Samples whose value was NaN or infinite (dropped, never written).
    pub invalid_samples: u64,
    /// Whether `RenderOptions::cancel` cut the render short (`spp` is what it reached).
    pub interrupted: bool,
}

/// What to render besides the radiance, what to change in the scene for this render
/// alone, and how to report progress.
#[derive(Clone, Debug, Default)]
pub struct RenderOptions {
    pub show_progress: bool,
    /// What to estimate beside the radiance in the same paths (volpath only).
    pub estimand: volpath::Estimand,
    /// Per medium, the albedo to render with instead of the scene's (the paper's method
    /// renders at a lower albedo); None renders the scene's.
    pub albedo: Option<Vec<Vec3>>,
    /// Also accumulate the emission the camera sees directly (`PathSample::seen_emission`)
    /// into `Rendered::seen_emission`, for a denoiser to keep out.
    pub seen_emission: bool,
    /// Set (e.g. by a Ctrl-C handler, or the Python module's signal check) to stop:
    /// the pass under way is dropped and the image of the passes completed is returned.
    /// Shared, so each caller (one Python thread's render) can have its own.
    pub cancel: Option<Arc<AtomicBool>>,
    /// Run every path through the scalar integrator, also where the packet one
    /// (`integrator::packet`) takes the scene: its reference, for tests and A/B timings.
    /// The environment variable `MEDIAREG_PATHS=scalar` does the same.
    pub scalar_paths: bool,
    /// The index of the first sample of each pixel's stream this render takes: it
    /// renders samples `first_sample .. first_sample + spp`. Renders of consecutive
    /// ranges of one seed are together the render of all their samples, stratified as
    /// one (each sample's draws depend on its index alone, `sampling::padded`).
    pub first_sample: u32,
}

impl RenderOptions {
    /// The same options with `medium`'s albedo replaced (the others as `scene` has them
    /// or as already replaced).
    pub fn with_albedo(mut self, scene: &Scene, medium: u32, albedo: Vec3) -> RenderOptions {
        let mut all = self
            .albedo
            .take()
            .unwrap_or_else(|| scene.media.iter().map(|m| m.albedo).collect());
        all[medium as usize] = albedo;
        self.albedo = Some(all);
        self
    }
}

/// The packet form of `scene` where its paths run in lanes (`integrator::packet`) and
/// the options allow it; else why they run in the scalar integrator.
pub fn packet_scene(
    scene: &Scene,
    shot: &Shot,
    opts: &RenderOptions,
) -> Result<PacketScene, String> {
    if opts.scalar_paths || std::env::var("MEDIAREG_PATHS").is_ok_and(|v| v == "scalar") {
        return Err("scalar paths asked for".into());
    }
    let ps = PacketScene::new(scene)?;
    // The camera rays start on the near plane, a rectangle: its corners inside the
    // (convex) shape of the camera's medium put every ray's origin there.
    let (w, h) = (shot.film.width as f32, shot.film.height as f32);
    let corners = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)];
    let rays = corners.map(|(x, y)| shot.camera.sample_ray(Vec2::new(x, y)));
    if !rays
        .iter()
        .all(|r| ps.takes_camera_ray(Vec3::from(r.o), r.tmax))
    {
        return Err("the camera is not inside its medium's shape, or clips within it".into());
    }
    Ok(ps)
}

/// Camera samples waiting for a packet: their film positions, rays and streams.
#[derive(Default)]
struct PacketQueue {
    positions: Vec<Vec2>,
    rays: Vec<(glam::Vec3A, glam::Vec3A, f32)>,
    rngs: Vec<Pcg32>,
}

impl PacketQueue {
    fn push(&mut self, pos: Vec2, ray: (glam::Vec3A, glam::Vec3A, f32), rng: Pcg32) {
        self.positions.push(pos);
        self.rays.push(ray);
        self.rngs.push(rng);
    }

    fn is_full(&self) -> bool {
        self.rays.len() == packet::WIDTH
    }

    /// Traces the queued samples as one packet, splats them in the order queued, and
    /// empties the queue.
    fn run(
        &mut self,
        scene: &Scene,
        ps: &PacketScene,
        settings: &PathSettings,
        splat: &mut impl FnMut(Vec2, PathSample),
    ) {
        let n = self.rays.len();
        if n == 0 {
            return;
        }
        let mut out = [PathSample::default(); packet::WIDTH];
        packet::sample_packet(
            scene,
            ps,
            settings,
            &self.rays,
            &mut self.rngs,
            &mut out[..n],
        );
        for (pos, s) in self.positions.iter().zip(&out[..n]) {
            splat(*pos, *s);
        }
        self.positions.clear();
        self.rays.clear();
        self.rngs.clear();
    }
}

/// Sample ranges of the passes: 1, 1, 2, 4, … doubling up to max(1, spp / 8).
fn pass_schedule(spp: u32) -> Vec<(u32, u32)> {
    let cap = (spp / 8).max(1);
    let mut passes = Vec::new();
    let (mut start, mut size) = (0u32, 1u32);
    while start < spp {
        let end = start.saturating_add(size).min(spp);
        passes.push((start, end));
        if start > 0 {
            size = (size * 2).min(cap);
        }
        start = end;
    }
    passes
}

/// The radiance image and, when asked for, the derivative image (same layout, signed)
/// and the directly seen emission (a part of the radiance). With a luminance film the
/// image holds Y in all three channels; with an alpha film `alpha` holds it (in all
/// three channels too).
pub struct Rendered {
    pub image: Image,
    pub gradient: Option<Image>,
    /// d/dσ_t (d/d scale in a heterogeneous medium) and d/dg of the medium asked for
    /// (`volpath::Differentiated`), unscaled: `integrator::derivatives` names them.
    pub d_sigma: Option<Image>,
    pub d_g: Option<Image>,
    pub seen_emission: Option<Image>,
    pub alpha: Option<Image>,
    /// Per pixel, the sum of the filter weights of the samples it received: renders of
    /// consecutive sample ranges (`RenderOptions::first_sample`) join by these into the
    /// render of all their samples (`image::merge::mean_by_weights`).
    pub weights: Vec<f32>,
    pub stats: RenderStats,
}

/// One tile's films: the radiance, and the optional images splatted with the same
/// filter weights.
struct Blocks {
    radiance: ImageBlock,
    d_albedo: Option<ImageBlock>,
    d_sigma: Option<ImageBlock>,
    d_g: Option<ImageBlock>,
    seen: Option<ImageBlock>,
    alpha: Option<ImageBlock>,
}

/// Which optional images a render accumulates.
#[derive(Clone, Copy)]
struct Wanted {
    d_albedo: bool,
    d_sigma: bool,
    d_g: bool,
    seen: bool,
    alpha: bool,
}

impl Blocks {
    fn new(offset: (i64, i64), size: (usize, usize), border: usize, wanted: Wanted) -> Self {
        let b = || ImageBlock::new(offset, size, border);
        Blocks {
            radiance: b(),
            d_albedo: wanted.d_albedo.then(b),
            d_sigma: wanted.d_sigma.then(b),
            d_g: wanted.d_g.then(b),
            seen: wanted.seen.then(b),
            alpha: wanted.alpha.then(b),
        }
    }

    /// Splats a sample into every image. The optional images are developed with the
    /// radiance's weight sums (`develop_by`), which are theirs too (the same positions
    /// and filter), so a zero value, which adds nothing to a weighted sum, is not
    /// splatted: most samples see no emitter and many never meet the medium.
    fn put(&mut self, p: (f32, f32), s: &PathSample, filter: &Rfilter) {
        self.radiance.put(p, s.radiance, filter);
        let alpha = Vec3::splat(s.valid as u8 as f32);
        for (b, v) in [
            (&mut self.d_albedo, s.d_albedo),
            (&mut self.d_sigma, s.d_sigma),
            (&mut self.d_g, s.d_g),
            (&mut self.seen, s.seen_emission),
            (&mut self.alpha, alpha),
        ] {
            if let Some(b) = b {
                if v != Vec3::ZERO {
                    b.put(p, v, filter);
                }
            }
        }
    }

    fn accumulate_into(&self, target: &mut Blocks) {
        self.radiance.accumulate_into(&mut target.radiance);
        for (from, to) in [
            (&self.d_albedo, &mut target.d_albedo),
            (&self.d_sigma, &mut target.d_sigma),
            (&self.d_g, &mut target.d_g),
            (&self.seen, &mut target.seen),
            (&self.alpha, &mut target.alpha),
        ] {
            if let (Some(f), Some(t)) = (from, to) {
                f.accumulate_into(t);
            }
        }
    }
}

/// Renders `scene` through `shot` (Mitsuba's `render(scene, sensor, seed, spp)`):
/// radiance and, with `opts.estimand`, its derivative, each sample splatted into both
/// images with the same filter weight.
pub fn render(scene: &Scene, shot: &Shot, opts: &RenderOptions) -> Rendered {
    let show_progress = opts.show_progress;
    let estimand = opts.estimand;
    let wanted = Wanted {
        d_albedo: estimand.has_d_albedo(),
        d_sigma: estimand.extinction_medium().is_some(),
        d_g: estimand.g_medium().is_some(),
        seen: opts.seen_emission,
        alpha: shot.film.pixel_format.has_alpha(),
    };
    let albedo: Vec<Vec3> = match &opts.albedo {
        Some(a) => {
            assert_eq!(a.len(), scene.media.len(), "one albedo per medium");
            a.clone()
        }
        None => scene.media.iter().map(|m| m.albedo).collect(),
    };
    let settings = PathSettings {
        albedo: &albedo,
        estimand,
    };
    let packets = packet_scene(scene, shot, opts).ok();
    let film = &shot.film;
    let (cw, ch) = film.crop_size;
    let (ox, oy) = film.crop_offset;
    let border = film.rfilter.border();
    let spp = shot.spp;
    let sample = |o, d, tmax, rng: &mut Pcg32| match scene.integrator.kind {
        IntegratorKind::Path => path::sample(scene, o, d, tmax, rng),
        IntegratorKind::Direct {
            emitter_samples,
            bsdf_samples,
        } => direct::sample(scene, o, d, tmax, rng, emitter_samples, bsdf_samples),
        IntegratorKind::Volpath => volpath::sample(scene, &settings, o, d, tmax, rng),
    };

    let mut tiles = Vec::new();
    let block = block_size(cw, ch);
    for ty in (0..ch).step_by(block) {
        for tx in (0..cw).step_by(block) {
            tiles.push((tx, ty, block.min(cw - tx), block.min(ch - ty)));
        }
    }
    let total = (cw * ch) as u64 * spp as u64;
    let bar = if show_progress {
        let b = ProgressBar::new(total);
        b.set_style(
            ProgressStyle::with_template(
                "{bar:40} {percent:>3}%  {human_pos}/{human_len} samples  {per_sec}  ETA {eta}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        b
    } else {
        ProgressBar::hidden()
    };

    let cancelled = || {
        opts.cancel
            .as_ref()
            .is_some_and(|c| c.load(Ordering::Relaxed))
    };
    let new_blocks = || -> Vec<Blocks> {
        tiles
            .iter()
            .map(|&(tx, ty, tw, th)| {
                let (o, size) = ((tx as i64, ty as i64), (tw, th));
                Blocks::new(o, size, border, wanted)
            })
            .collect()
    };

    let start = std::time::Instant::now();
    let mut acc = new_blocks();
    let mut invalid_samples = 0;
    let mut spp_done = 0;
    let first = opts.first_sample;
    for (s0, s1) in pass_schedule(spp) {
        let (s0, s1) = (first.saturating_add(s0), first.saturating_add(s1));
        // Each tile renders samples s0..s1 of its pixels into fresh blocks; None if
        // cancelled on the way (the whole pass is then dropped).
        let mut pass = new_blocks();
        let invalid: Vec<Option<u64>> = tiles
            .par_iter()
            .zip(pass.par_iter_mut())
            .map(|(&(tx, ty, tw, th), blocks)| {
                let mut invalid = 0u64;
                let mut splat = |pos: Vec2, mut s: PathSample| {
                    if !(s.radiance.is_finite()
                        && s.d_albedo.is_finite()
                        && s.d_sigma.is_finite()
                        && s.d_g.is_finite()
                        && s.seen_emission.is_finite())
                    {
                        invalid += 1;
                        s = PathSample::default();
                    }
                    let p = (pos.x - ox as f32, pos.y - oy as f32);
                    blocks.put(p, &s, &film.rfilter);
                };
                let mut queue = PacketQueue::default();
                for y in ty..ty + th {
                    if cancelled() {
                        return None;
                    }
                    for x in tx..tx + tw {
                        let (fx, fy) = (x + ox, y + oy);
                        let pixel = (fy * film.width + fx) as u64;
                        let positions = PixelSamples::new(shot.seed, pixel);
                        let mut words = Pcg32::for_sample(shot.seed, pixel, u64::MAX - 1);
                        let scrambles = PaddedScrambles::new(|| words.next_u32());
                        for si in s0..s1 {
                            let mut rng = Pcg32::for_path(shot.seed, pixel, si, &scrambles);
                            let u = positions.get(si);
                            let pos = Vec2::new(fx as f32 + u.x, fy as f32 + u.y);
                            let ray = shot.camera.sample_ray(pos);
                            match &packets {
                                Some(ps) => {
                                    queue.push(pos, (ray.o, ray.d, ray.tmax), rng);
                                    if queue.is_full() {
                                        queue.run(scene, ps, &settings, &mut splat);
                                    }
                                }
                                None => splat(pos, sample(ray.o, ray.d, ray.tmax, &mut rng)),
                            }
                        }
                    }
                }
                if let Some(ps) = &packets {
                    queue.run(scene, ps, &settings, &mut splat);
                }
                bar.inc((tw * th) as u64 * (s1 - s0) as u64);
                Some(invalid)
            })
            .collect();
        let Some(invalid) = invalid.into_iter().sum::<Option<u64>>() else {
            break;
        };
        invalid_samples += invalid;
        for (b, pb) in acc.iter_mut().zip(&pass) {
            pb.accumulate_into(b);
        }
        spp_done = s1 - first;
        if cancelled() {
            break;
        }
    }
    bar.finish_and_clear();

    let mut full = Blocks::new((0, 0), (cw, ch), border, wanted);
    for b in &acc {
        b.accumulate_into(&mut full);
    }
    let seconds = start.elapsed().as_secs_f64();
    let as_image = |b: &ImageBlock| Image {
        width: cw,
        height: ch,
        pixels: b.develop_by(&full.radiance),
    };
    let mut image = as_image(&full.radiance);
    let mut seen_emission = full.seen.as_ref().map(as_image);
    if film.pixel_format.is_luminance() {
        // Mitsuba's develop: Y of the developed RGB (the seen emission's likewise, so
        // that it stays a part of the image).
        for img in std::iter::once(&mut image).chain(seen_emission.as_mut()) {
            for p in &mut img.pixels {
                *p = [crate::scene::film::luminance(*p); 3];
            }
        }
    }
    Rendered {
        image,
        gradient: full.d_albedo.as_ref().map(as_image),
        d_sigma: full.d_sigma.as_ref().map(as_image),
        d_g: full.d_g.as_ref().map(as_image),
        seen_emission,
        alpha: full.alpha.as_ref().map(as_image),
        weights: full.radiance.weight_sums(),
        stats: RenderStats {
            spp: spp_done,
            samples: (cw * ch) as u64 * spp_done as u64,
            seconds,
            invalid_samples,
            interrupted: spp_done < spp,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_shrink_for_small_images_only() {
        assert_eq!(block_size(1024, 1024), 32);
        assert_eq!(block_size(256, 256), 32);
        assert_eq!(block_size(128, 128), 16);
        assert_eq!(block_size(64, 64), 8);
        assert_eq!(block_size(3, 5), 8);
        for (w, h) in [(64, 64), (100, 37), (128, 128), (512, 300)] {
            let b = block_size(w, h);
            assert!(w.div_ceil(b) * h.div_ceil(b) >= 64, "{w}x{h}: block {b}");
        }
    }
}
