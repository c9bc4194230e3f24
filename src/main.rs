//! The `mediareg` command line: argument parsing and reporting only.

use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{anyhow, bail, Context, Result};
use clap::{Parser, Subcommand};

use mediareg::integrator::volpath::Gradient;
use mediareg::scene::IntegratorKind;
use mediareg::{image, integrator, load_scene, xml, BuildOverrides};

#[derive(Parser)]
#[command(
    name = "mediareg",
    version,
    about = "A renderer for participating media that reads Mitsuba 3 scene files"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a Mitsuba 3 scene file to OUT.exr (linear RGB) and OUT.png (sRGB preview).
    Render {
        /// The scene file (Mitsuba 3 XML).
        scene: PathBuf,
        /// Output EXR (default: the scene's name with .exr, beside the scene, as Mitsuba does).
        #[arg(short = 'o', long = "output")]
        output: Option<PathBuf>,
        /// Set a scene parameter: -D name=value (overrides <default>).
        #[arg(short = 'D', value_name = "NAME=VALUE")]
        define: Vec<String>,
        /// Add a folder to the search path for meshes and includes.
        #[arg(short = 'a', value_name = "DIR")]
        search: Vec<PathBuf>,
        /// Samples per pixel (overrides the sampler's sample_count).
        #[arg(long)]
        spp: Option<u32>,
        /// Random seed (overrides the sampler's seed).
        #[arg(long)]
        seed: Option<u64>,
        /// Number of render threads (default: all cores).
        #[arg(short = 't', long = "threads")]
        threads: Option<usize>,
        /// Do not write the PNG preview.
        #[arg(long)]
        no_png: bool,
        /// Also render a derivative in the same paths: `albedo` writes OUT_dalbedo.exr,
        /// d(radiance_c)/d(albedo_c) of one medium (volpath only).
        #[arg(long, value_enum)]
        gradient: Option<GradientArg>,
        /// The medium (its XML id) whose albedo --gradient differentiates; needed when the
        /// scene has several.
        #[arg(long, value_name = "ID", requires = "gradient")]
        medium: Option<String>,
    },
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum GradientArg {
    Albedo,
}

/// The medium `--gradient` refers to: the one named, or the only one.
fn gradient_medium(scene: &mediareg::scene::Scene, name: Option<&str>) -> Result<u32> {
    let ids: Vec<String> = scene
        .media
        .iter()
        .enumerate()
        .map(|(i, m)| m.id.clone().unwrap_or_else(|| format!("(unnamed #{i})")))
        .collect();
    match name {
        Some(n) => scene
            .media
            .iter()
            .position(|m| m.id.as_deref() == Some(n))
            .map(|i| i as u32)
            .ok_or_else(|| {
                anyhow!(
                    "--medium {n}: no medium has that id; the scene's media: {}",
                    ids.join(", ")
                )
            }),
        None => match scene.media.len() {
            0 => bail!("--gradient albedo: the scene has no medium"),
            1 => Ok(0),
            _ => bail!(
                "--gradient albedo: the scene has {} media, name one with --medium ID: {}",
                ids.len(),
                ids.join(", ")
            ),
        },
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render {
            scene,
            output,
            define,
            search,
            spp,
            seed,
            threads,
            no_png,
            gradient,
            medium,
        } => {
            let mut params = Vec::new();
            for d in &define {
                let (k, v) = d
                    .split_once('=')
                    .ok_or_else(|| anyhow!("-D {d}: expected NAME=VALUE"))?;
                params.push((k.trim().to_string(), v.to_string()));
            }
            if spp == Some(0) {
                bail!("--spp must be at least 1");
            }
            if let Some(t) = threads {
                if t == 0 {
                    bail!("-t must be at least 1");
                }
                rayon::ThreadPoolBuilder::new()
                    .num_threads(t)
                    .build_global()
                    .context("cannot set up the thread pool")?;
            }
            let opts = xml::LoadOptions {
                params,
                search_dirs: search,
            };
            let scene_data = load_scene(&scene, &opts, &BuildOverrides { spp, seed })
                .map_err(|e| anyhow!("{e}"))?;

            let out_exr = output.unwrap_or_else(|| scene.with_extension("exr"));
            if out_exr.extension().and_then(|e| e.to_str()) != Some("exr") {
                bail!("output {} must end in .exr", out_exr.display());
            }
            let out_png = out_exr.with_extension("png");
            if let Some(dir) = out_exr.parent().filter(|d| !d.as_os_str().is_empty()) {
                if !dir.is_dir() {
                    bail!("output folder {} does not exist", dir.display());
                }
            }

            let gradient = match gradient {
                None => Gradient::None,
                Some(GradientArg::Albedo) => {
                    if scene_data.integrator.kind != IntegratorKind::Volpath {
                        bail!("--gradient albedo needs the volpath integrator (the scene uses path, which ignores media)");
                    }
                    Gradient::Albedo(gradient_medium(&scene_data, medium.as_deref())?)
                }
            };
            let out_grad = {
                let stem = out_exr.file_stem().unwrap_or_default().to_string_lossy();
                out_exr.with_file_name(format!("{stem}_dalbedo.exr"))
            };

            let show = std::io::stderr().is_terminal();
            let rendered = integrator::render_with(
                &scene_data,
                &integrator::RenderOptions {
                    show_progress: show,
                    gradient,
                },
            );
            let (img, stats) = (&rendered.image, &rendered.stats);
            image::write_exr(&out_exr, img)?;
            let mut written = vec![out_exr.display().to_string()];
            if let Some(g) = &rendered.gradient {
                image::write_exr(&out_grad, g)?;
                written.push(out_grad.display().to_string());
            }
            if !no_png {
                image::write_png(&out_png, img)?;
                written.push(out_png.display().to_string());
            }
            if stats.invalid_samples > 0 {
                eprintln!(
                    "warning: {} samples were NaN or Inf and were dropped",
                    stats.invalid_samples
                );
            }
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
    }
}
