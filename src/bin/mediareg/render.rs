//! `mediareg render`: one image (and a derivative in the same paths) of a scene file.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{anyhow, bail, Context, Result};
use clap::Args;

use mediareg::denoise::{self, AuxUse};
use mediareg::image;
use mediareg::integrator::{self, aovs, volpath::Estimand, GradientError, MediumParam};
use mediareg::scene::ray_log::{self, RayLog};
use mediareg::scene::Scene;

use crate::common::{medium_error, prepare, sibling, warn_invalid_samples, SceneArgs};
use crate::interrupt::{install_handler, INTERRUPT};

/// Render a Mitsuba 3 scene file to OUT.exr (linear RGB) and OUT.png (sRGB preview).
#[derive(Args)]
pub struct RenderArgs {
    #[command(flatten)]
    pub args: SceneArgs,
    /// Also render derivatives in the same paths, of one medium's parameters
    /// (comma-separated: sigma_t, albedo, g, scale): each writes OUT_d<name>.exr
    /// (signed float), e.g. OUT_dalbedo.exr = d(radiance_c)/d(albedo_c), OUT_dg.exr =
    /// d(radiance_c)/dg (volpath only).
    #[arg(long, value_name = "PARAMS")]
    pub gradient: Option<String>,
    /// The medium whose parameters --gradient differentiates: its XML id, its slot
    /// (interior, exterior) or its mi.traverse key (SHAPE_ID.interior_medium); needed
    /// when the scene has several.
    #[arg(long, value_name = "NAME", requires = "gradient")]
    pub medium: Option<String>,
    /// Record every ray the render casts into the scene to FILE (for
    /// scripts/cast_bound), then cast them again one by one on one thread and write
    /// how long each kind took to FILE.json. Slows the render down. Needs a build
    /// with the ray-log feature.
    #[arg(long, value_name = "FILE")]
    pub ray_log: Option<PathBuf>,
    /// Denoise the image: `oidn` writes Intel Open Image Denoise's output to OUT.exr
    /// and the render to OUT_noisy.exr (the directly seen emission is kept out of the
    /// denoiser). Needs the library: scripts/fetch_oidn.
    #[arg(long, value_enum, value_name = "DENOISER")]
    pub denoise: Option<DenoiseArg>,
    /// Which auxiliary images the denoiser takes: none (the default: they did not help
    /// on media, docs/denoise.md), albedo, or albedo and normal.
    #[arg(long, value_enum, default_value = "none", requires = "denoise")]
    pub denoise_aux: AuxArg,
    /// Also write the albedo and normal of what each pixel sees first
    /// (OUT_albedo.exr, OUT_normal.exr), the denoiser's auxiliary images.
    #[arg(long)]
    pub aovs: bool,
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum DenoiseArg {
    Oidn,
}

#[derive(Clone, Copy, clap::ValueEnum)]
pub enum AuxArg {
    AlbedoNormal,
    Albedo,
    None,
}

impl From<AuxArg> for AuxUse {
    fn from(a: AuxArg) -> AuxUse {
        match a {
            AuxArg::AlbedoNormal => AuxUse::AlbedoNormal,
            AuxArg::Albedo => AuxUse::Albedo,
            AuxArg::None => AuxUse::None,
        }
    }
}

pub fn run(cmd: RenderArgs) -> Result<()> {
    let RenderArgs {
        args,
        gradient,
        medium,
        ray_log,
        denoise,
        denoise_aux,
        aovs,
    } = cmd;
    // Before a long render: the denoiser must be there.
    if denoise.is_some() {
        denoise::oidn::load().map_err(|e| anyhow!("--denoise oidn: {e}"))?;
    }
    let (mut scene_data, out_exr) = prepare(&args)?;
    if ray_log.is_some() {
        if !cfg!(feature = "ray-log") {
            bail!("--ray-log needs a build with the ray-log feature: cargo build --release --features ray-log");
        }
        scene_data.ray_log = Some(RayLog::default());
    }
    let params = match &gradient {
        Some(list) => MediumParam::parse_list(list).map_err(|e| anyhow!("--gradient: {e}"))?,
        None => Vec::new(),
    };
    let (estimand, medium_index) = if params.is_empty() {
        (Estimand::RadianceOnly, 0)
    } else {
        let names: Vec<&str> = params.iter().map(|p| p.name()).collect();
        let flag = format!("--gradient {}", names.join(","));
        integrator::medium_gradient(&scene_data, medium.as_deref(), &params).map_err(
            |e| match e {
                GradientError::Medium(m) => anyhow!("{flag}: {:#}", medium_error(m)),
                e => anyhow!("{flag}: {e}"),
            },
        )?
    };

    eprintln!("ray caster: {}", scene_data.accel.describe());
    match integrator::render::packet_scene(&scene_data, &scene_data.shot, &Default::default()) {
        Ok(_) => eprintln!(
            "paths: {} at a time in SIMD lanes",
            integrator::packet::WIDTH
        ),
        Err(why) => eprintln!("paths: one at a time ({why})"),
    }
    let show = std::io::stderr().is_terminal();
    install_handler()?;
    let rendered = integrator::render(
        &scene_data,
        &scene_data.shot,
        &integrator::RenderOptions {
            show_progress: show,
            estimand,
            seen_emission: denoise.is_some(),
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
    let mut written = Vec::new();
    let use_aux = AuxUse::from(denoise_aux);
    let aux = aovs.then(|| aovs::first_hit_aovs(&scene_data, &scene_data.shot));
    let denoised = match denoise {
        None => None,
        Some(DenoiseArg::Oidn) => {
            let start = std::time::Instant::now();
            let shot = &scene_data.shot;
            let out =
                integrator::denoised::oidn(&scene_data, shot, &rendered, use_aux, aux.as_ref())
                    .map_err(|e| anyhow!("--denoise oidn: {e}"))?;
            eprintln!(
                "denoised with Open Image Denoise {} in {:.2} s",
                denoise::oidn::load()
                    .map(|o| o.version_string())
                    .unwrap_or_default(),
                start.elapsed().as_secs_f64()
            );
            Some(out)
        }
    };
    let shown = denoised.as_ref().unwrap_or(img);
    let film = &scene_data.shot.film;
    let format = film.pixel_format;
    let alpha = rendered.alpha.as_ref();
    if let Some(d) = &denoised {
        let mut d = d.clone();
        if format.is_luminance() {
            for p in &mut d.pixels {
                *p = [mediareg::scene::film::luminance(*p); 3];
            }
        }
        write_film_exr(&out_exr, &d, alpha, film, spp)?;
        written.push(out_exr.display().to_string());
        let noisy = sibling(&out_exr, "_noisy");
        write_film_exr(&noisy, img, alpha, film, spp)?;
        written.push(noisy.display().to_string());
    } else {
        write_film_exr(&out_exr, img, alpha, film, spp)?;
        written.push(out_exr.display().to_string());
    }
    if let Some(a) = &aux {
        for (suffix, im) in [("_albedo", &a.albedo), ("_normal", &a.normal)] {
            let path = sibling(&out_exr, suffix);
            image::write_exr(&path, im)?;
            written.push(path.display().to_string());
        }
    }
    let derivatives = integrator::derivative_images(&scene_data, medium_index, &params, &rendered);
    for (param, img) in derivatives {
        if let Some(img) = img {
            let out_grad = sibling(&out_exr, &format!("_d{}", param.name()));
            image::write_render_exr(&out_grad, &img, spp)?;
            written.push(out_grad.display().to_string());
        }
    }
    if !args.no_png {
        let out_png = out_exr.with_extension("png");
        image::write_png(&out_png, shown)?;
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

/// Writes `img` as the film's `pixel_format` asks: R, G, B; Y (Mitsuba's luminance,
/// which the image already holds in every channel); and the alpha A where asked; in
/// float32 samples, or uint32 ones where its `component_format` asks.
fn write_film_exr(
    out: &Path,
    img: &image::Image,
    alpha: Option<&image::Image>,
    film: &mediareg::scene::film::Film,
    spp: Option<u64>,
) -> Result<()> {
    use mediareg::scene::film::{ComponentFormat, PixelFormat};
    let format = film.pixel_format;
    if format == PixelFormat::Rgb && film.component_format != ComponentFormat::Uint32 {
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
    if let Some(a) = alpha {
        channels.push(("A", channel(0, a)));
    }
    image::write_channels_exr_as(
        out,
        (img.width, img.height),
        channels,
        spp,
        film.component_format,
    )
}
