//! `mediareg render`: one image (and a derivative in the same paths) of a scene file.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{anyhow, bail, Context, Result};
use clap::Args;

use mediareg::image;
use mediareg::integrator::{self, volpath::Gradient, GradientError};
use mediareg::scene::ray_log::{self, RayLog};
use mediareg::scene::Scene;

use crate::common::{medium_error, prepare, sibling, warn_invalid_samples, SceneArgs};
use crate::interrupt::{install_handler, INTERRUPT};

/// Render a Mitsuba 3 scene file to OUT.exr (linear RGB) and OUT.png (sRGB preview).
#[derive(Args)]
pub struct RenderArgs {
    #[command(flatten)]
    pub args: SceneArgs,
    /// Also render a derivative in the same paths: `albedo` writes OUT_dalbedo.exr,
    /// d(radiance_c)/d(albedo_c) of one medium (volpath only).
    #[arg(long, value_enum)]
    pub gradient: Option<GradientArg>,
    /// The medium (its XML id) whose albedo --gradient differentiates; needed when the
    /// scene has several.
    #[arg(long, value_name = "ID", requires = "gradient")]
    pub medium: Option<String>,
    /// Record every ray the render casts into the scene to FILE (for
    /// scripts/cast_bound), then cast them again one by one on one thread and write
    /// how long each kind took to FILE.json. Slows the render down. Needs a build
    /// with the ray-log feature.
    #[arg(long, value_name = "FILE")]
    pub ray_log: Option<PathBuf>,
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum GradientArg {
    Albedo,
}

pub fn run(cmd: RenderArgs) -> Result<()> {
    let RenderArgs {
        args,
        gradient,
        medium,
        ray_log,
    } = cmd;
    let (mut scene_data, out_exr) = prepare(&args)?;
    if ray_log.is_some() {
        if !cfg!(feature = "ray-log") {
            bail!("--ray-log needs a build with the ray-log feature: cargo build --release --features ray-log");
        }
        scene_data.ray_log = Some(RayLog::default());
    }
    let gradient = match gradient {
        None => Gradient::None,
        Some(GradientArg::Albedo) => integrator::albedo_gradient(&scene_data, medium.as_deref())
            .map_err(|e| match e {
                GradientError::NeedsVolpath => anyhow!("--gradient albedo: {e}"),
                GradientError::Medium(m) => anyhow!("--gradient albedo: {:#}", medium_error(m)),
            })?,
    };

    let show = std::io::stderr().is_terminal();
    install_handler()?;
    let rendered = integrator::render(
        &scene_data,
        &scene_data.shot,
        &integrator::RenderOptions {
            show_progress: show,
            gradient,
            cancel: Some(Arc::clone(&INTERRUPT)),
            ..Default::default()
        },
    );
    let (img, stats) = (&rendered.image, &rendered.stats);
    if let (Some(path), Some(log)) = (&ray_log, scene_data.ray_log.take()) {
        write_ray_log(path, &scene_data, log, stats)?;
    }
    if stats.interrupted {
        if stats.spp == 0 {
            bail!("interrupted before the first pass completed: nothing written");
        }
        eprintln!(
            "warning: interrupted at {} of {} spp; the EXR header's \"spp\" says so",
            stats.spp, scene_data.shot.spp
        );
    }
    // The spp reached (less than asked for when interrupted), in the EXR header.
    let spp = Some(u64::from(stats.spp));
    write_film_exr(&out_exr, &rendered, scene_data.shot.film.pixel_format, spp)?;
    let mut written = vec![out_exr.display().to_string()];
    if let Some(g) = &rendered.gradient {
        let out_grad = sibling(&out_exr, "_dalbedo");
        image::write_render_exr(&out_grad, g, spp)?;
        written.push(out_grad.display().to_string());
    }
    if !args.no_png {
        let out_png = out_exr.with_extension("png");
        image::write_png(&out_png, img)?;
        written.push(out_png.display().to_string());
    }
    warn_invalid_samples(stats.invalid_samples);
    println!(
        "rendered {}x{} at {} spp in {:.2} s ({:.2} M samples/s); wrote {}",
        img.width,
        img.height,
        stats.spp,
        stats.seconds,
        stats.samples as f64 / stats.seconds.max(1e-9) / 1e6,
        written.join(", ")
    );
    Ok(())
}

/// `render --ray-log`: the rays to `path`, and to `path`.json how many of each kind a
/// sample cast and how long each takes cast again here (see `scene::ray_log`).
fn write_ray_log(
    path: &Path,
    scene: &Scene,
    log: RayLog,
    stats: &integrator::RenderStats,
) -> Result<()> {
    let rays = log.into_rays();
    ray_log::write(path, &rays).with_context(|| format!("writing {}", path.display()))?;
    let timings = ray_log::time_casts(scene, &rays, 5);
    let samples = stats.samples.max(1) as f64;
    let kinds: Vec<serde_json::Value> = timings
        .iter()
        .map(|t| {
            eprintln!(
                "ray log: {} casts of kind \"{}\", {:.3} a sample, {:.1} ns each cast again on one thread",
                t.count,
                t.kind.name(),
                t.count as f64 / samples,
                t.ns_per_ray
            );
            serde_json::json!({
                "kind": t.kind as u8,
                "name": t.kind.name(),
                "count": t.count,
                "per_sample": t.count as f64 / samples,
                "ns_per_ray": t.ns_per_ray,
            })
        })
        .collect();
    let summary = serde_json::json!({
        "rays": path.file_name().map(|n| n.to_string_lossy().into_owned()),
        "samples": stats.samples,
        "render_seconds": stats.seconds,
        "threads": rayon::current_num_threads(),
        "casts": kinds,
    });
    let json = path.with_extension("json");
    std::fs::write(&json, serde_json::to_string_pretty(&summary)?)
        .with_context(|| format!("writing {}", json.display()))?;
    Ok(())
}

/// Writes the render as the film's `pixel_format` asks: R, G, B; Y (Mitsuba's
/// luminance, which the render already holds in every channel); and alpha A where asked.
fn write_film_exr(
    out: &std::path::Path,
    rendered: &integrator::Rendered,
    format: mediareg::scene::film::PixelFormat,
    spp: Option<u64>,
) -> anyhow::Result<()> {
    let img = &rendered.image;
    if format == mediareg::scene::film::PixelFormat::Rgb {
        return image::write_render_exr(out, img, spp);
    }
    let channel = |c: usize, of: &image::Image| of.pixels.iter().map(|p| p[c]).collect();
    let mut channels: Vec<(&str, Vec<f32>)> = if format.is_luminance() {
        vec![("Y", channel(0, img))]
    } else {
        vec![
            ("R", channel(0, img)),
            ("G", channel(1, img)),
            ("B", channel(2, img)),
        ]
    };
    if let Some(a) = &rendered.alpha {
        channels.push(("A", channel(0, a)));
    }
    image::write_channels_exr(out, (img.width, img.height), channels, spp)
}
