//! The `mediareg` command line: argument parsing and reporting only.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, Parser, Subcommand};
use glam::Vec3;

use mediareg::image::Image;
use mediareg::integrator::volpath::Gradient;
use mediareg::regularize::pipeline::PilotSize;
use mediareg::regularize::sequence::{image_centre_point, CameraPath};
use mediareg::regularize::spatial::BilateralParams;
use mediareg::regularize::{self, CBeta, Method, Reproject};
use mediareg::report::mitsuba::MitsubaRunner;
use mediareg::report::{self, Budget, TableOptions};
use mediareg::scene::ray_log::{self, RayLog};
use mediareg::scene::{IntegratorKind, Scene};
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

/// What every command needs to load a scene.
#[derive(Args)]
struct SceneArgs {
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
    /// Render only this window of the film: X,Y,W,H in pixels (overrides the film's
    /// crop_offset_x/y, crop_width/height)
    #[arg(long, value_name = "X,Y,W,H", value_parser = parse_crop)]
    crop: Option<[usize; 4]>,
    /// Read files older than 2.0 exactly as Mitsuba 3 does: refuse the Mitsuba 0.6
    /// readings mediareg otherwise makes (sigmaS/sigmaA media, density, index-matched
    /// medium boundaries without a bsdf)
    #[arg(long)]
    strict_v3: bool,
    /// Number of render threads (default: all cores).
    #[arg(short = 't', long = "threads")]
    threads: Option<usize>,
    /// Do not write PNG previews.
    #[arg(long)]
    no_png: bool,
}

/// `mediareg table`'s arguments.
#[derive(Args)]
struct TableArgs {
    /// Scene names: SCENE_DIR/NAME.xml, with REFERENCE_DIR/NAME.exr.
    #[arg(long, value_delimiter = ',', default_value = "bunny,candle,lucy")]
    scenes: Vec<String>,
    /// Seconds per method (per frame for the regularized sequence).
    #[arg(long, conflicts_with = "spp", default_value_t = 30.0)]
    budget: f64,
    /// Equal spp instead of equal time.
    #[arg(long)]
    spp: Option<u32>,
    /// Output folder (default: out/table, or out/figures for `figures`).
    #[arg(long)]
    out: Option<PathBuf>,
    #[arg(long, default_value = "mitsuba_scenes")]
    scene_dir: PathBuf,
    #[arg(long, default_value = "reference")]
    reference_dir: PathBuf,
    /// Set a scene parameter in every scene: -D name=value (the references must have
    /// been made with the same).
    #[arg(short = 'D', value_name = "NAME=VALUE")]
    define: Vec<String>,
    /// Add a folder to the search path (default: .cache/meshes, where
    /// scripts/fetch_meshes puts the meshes).
    #[arg(short = 'a', value_name = "DIR")]
    search: Vec<PathBuf>,
    /// Frames of the regularized sequence (N of Eq. 10).
    #[arg(long, default_value_t = 11)]
    frames: usize,
    /// w_a of Eq. 10.
    #[arg(long, default_value_t = 0.1)]
    wa: f64,
    /// Degrees the camera orbits per frame of the sequence.
    #[arg(long, default_value_t = 0.5)]
    orbit: f32,
    /// c_β of the paper's predictor.
    #[arg(long = "c-beta", default_value_t = 0.5)]
    c_beta: f32,
    /// Source albedo factor (default: the paper's for the scene, else 0.95).
    #[arg(long)]
    factor: Option<f32>,
    /// The Python that has Mitsuba 3 (default: .venv/bin/python if present, else python3).
    #[arg(long)]
    python: Option<PathBuf>,
    /// Do not render with Mitsuba 3.
    #[arg(long)]
    no_mitsuba: bool,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Number of render threads (default: all cores).
    #[arg(short = 't', long = "threads")]
    threads: Option<usize>,
    /// Do not write PNG previews.
    #[arg(long)]
    no_png: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Render a Mitsuba 3 scene file to OUT.exr (linear RGB) and OUT.png (sRGB preview).
    Render {
        #[command(flatten)]
        args: SceneArgs,
        /// Also render a derivative in the same paths: `albedo` writes OUT_dalbedo.exr,
        /// d(radiance_c)/d(albedo_c) of one medium (volpath only).
        #[arg(long, value_enum)]
        gradient: Option<GradientArg>,
        /// The medium (its XML id) whose albedo --gradient differentiates; needed when the
        /// scene has several.
        #[arg(long, value_name = "ID", requires = "gradient")]
        medium: Option<String>,
        /// Record every ray the render casts into the scene to FILE (for
        /// scripts/cast_bound), then cast them again one by one on one thread and write
        /// how long each kind took to FILE.json. Slows the render down. Needs a build
        /// with the ray-log feature.
        #[arg(long, value_name = "FILE")]
        ray_log: Option<PathBuf>,
    },
    /// The paper's method: render at source albedo factor × the scene's, denoise the
    /// albedo gradient over a camera sequence, predict the image at the scene's albedo.
    /// Writes OUT.exr (the prediction), OUT_source.exr, OUT_dalbedo_raw.exr and
    /// OUT_dalbedo.exr (denoised), each with a PNG preview.
    Regularize {
        #[command(flatten)]
        args: SceneArgs,
        /// The medium (its XML id) to extrapolate; needed when the scene has several.
        #[arg(long, value_name = "ID")]
        medium: Option<String>,
        /// Source albedo = factor × the scene's albedo (per channel), or `auto` (the
        /// difference predictor: chosen by a pilot). Default: auto with `--predict
        /// difference`, 0.95 with the others.
        #[arg(long, value_name = "F|auto")]
        factor: Option<String>,
        /// The pilot of `--factor auto`: renders per candidate factor, and their spp.
        #[arg(long, default_value_t = 8)]
        pilot_renders: usize,
        #[arg(long, default_value_t = 1)]
        pilot_spp: u32,
        /// c_β of the paper's predictor (0 < c_β ≤ σ_t α_s), or `fit` to fit it to a
        /// cheap render (--fit-spp, --fit-at).
        #[arg(long = "c-beta", default_value = "0.5", value_name = "C|fit")]
        c_beta: String,
        /// Samples per pixel of the render c_β is fitted to.
        #[arg(long, default_value_t = 4)]
        fit_spp: u32,
        /// The fit's albedo: source + at × (target − source).
        #[arg(long, default_value_t = 1.0)]
        fit_at: f32,
        /// N: the target frame and N − 1 earlier frames.
        #[arg(long, default_value_t = 11)]
        frames: usize,
        /// The blending weight w_a of Eq. 10.
        #[arg(long, default_value_t = 0.1)]
        wa: f64,
        /// How earlier frames are reprojected into the target frame.
        #[arg(long, value_enum, default_value = "exact")]
        reproject: ReprojectArg,
        /// The camera moved this many degrees per frame about the --target point, around
        /// its up vector.
        #[arg(long, value_name = "DEGREES", conflicts_with_all = ["dolly", "camera_path"])]
        orbit: Option<f32>,
        /// The camera moved this far per frame along its view direction.
        #[arg(long, value_name = "DISTANCE", conflicts_with = "camera_path")]
        dolly: Option<f32>,
        /// A file of sensor transforms, one per line in time order, the last the target
        /// frame: 16 numbers (4x4 row-major) or 9 (origin target up).
        #[arg(long, value_name = "FILE")]
        camera_path: Option<PathBuf>,
        /// The orbit's centre "x,y,z" (default: the first visible point at the image centre).
        #[arg(long, value_name = "X,Y,Z")]
        target: Option<String>,
        /// Also filter the gradient spatially (joint bilateral, guided by the first hit);
        /// the default with `--predict difference`.
        #[arg(long, conflicts_with = "no_spatial")]
        spatial: bool,
        /// Filter the gradient over frames only (the default with the paper's predictors).
        #[arg(long)]
        no_spatial: bool,
        /// The prediction function.
        #[arg(long, value_enum, default_value = "difference")]
        predict: PredictArg,
    },
    /// The paper's Table 1 on this machine: for each scene, at equal time (or spp), the
    /// regularized method (temporal and single-frame spatial), plain volpath and Mitsuba 3's
    /// volpath, each image's MSE against the scene's Mitsuba 3 reference. Writes
    /// OUT/table1.md, table1.csv, table1.json, run.json and every image.
    Table(TableArgs),
    /// An HTML page (reports/index.html) from a table run and the figures: per scene the
    /// reference, each method's image and error map, the table, the plots. Also remakes
    /// the table's table1.md from its JSON files.
    Report {
        #[arg(long, default_value = "reports/table")]
        table: PathBuf,
        #[arg(long, default_value = "reports/figures")]
        figures: PathBuf,
        #[arg(short = 'o', long = "output", default_value = "reports/index.html")]
        output: PathBuf,
    },
    /// The paper's figures (Fig. 6, 7, 9, 11, 12 and speed against error) as PNG plots
    /// with their numbers (figN.json), from reduced-size sweeps against the references
    /// in reference/figures/ (Fig. 7: the full-size cube).
    Figures {
        #[command(flatten)]
        table: TableArgs,
        /// Make only these (fig7, fig11, fig12, fig6, fig9, speed).
        #[arg(long, value_delimiter = ',')]
        only: Vec<String>,
        #[arg(long, default_value = "reference/figures")]
        figure_reference_dir: PathBuf,
        /// Resolution of the sweeps.
        #[arg(long, default_value_t = 128)]
        res: u32,
        /// Seconds per method of the sweeps over time (Fig. 11, 12, speed).
        #[arg(long, value_delimiter = ',', default_value = "0.5,1,2,4,8")]
        budgets: Vec<f64>,
        /// Seconds per method of the sweeps over a parameter (Fig. 6, 9).
        #[arg(long, default_value_t = 2.0)]
        sweep_budget: f64,
        /// Samples per pixel per frame of Fig. 7.
        #[arg(long, default_value_t = 64)]
        fig7_spp: u32,
    },
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum GradientArg {
    Albedo,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum ReprojectArg {
    Exact,
    Shift,
    None,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum PredictArg {
    Paper,
    Linear,
    Loglinear,
    /// R_s + the denoised difference R(α_t) − R(α_s) rendered in the same paths
    Difference,
}

/// Set by the first Ctrl-C during `render`: the render stops after dropping the pass
/// under way, and the image of the passes completed is written.
static INTERRUPT: AtomicBool = AtomicBool::new(false);

/// The conventional exit status of a process ended by SIGINT (128 + 2).
const EXIT_INTERRUPTED: u8 = 130;

/// The first Ctrl-C asks the render to stop and write what it has; a second one quits
/// at once (atomic writes leave no partial file either way).
fn install_interrupt_handler() -> Result<()> {
    ctrlc::set_handler(|| {
        if INTERRUPT.swap(true, Ordering::SeqCst) {
            eprintln!("\ninterrupted again: quitting without writing");
            std::process::exit(EXIT_INTERRUPTED as i32);
        }
        eprintln!(
            "\ninterrupted: writing the image rendered so far (Ctrl-C again to quit at once)"
        );
    })
    .context("cannot install the Ctrl-C handler")
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) if INTERRUPT.load(Ordering::SeqCst) => ExitCode::from(EXIT_INTERRUPTED),
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            if INTERRUPT.load(Ordering::SeqCst) {
                ExitCode::from(EXIT_INTERRUPTED)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}

/// `-D name=value` arguments as pairs.
fn parse_defines(defines: &[String]) -> Result<Vec<(String, String)>> {
    defines
        .iter()
        .map(|d| {
            let (k, v) = d
                .split_once('=')
                .ok_or_else(|| anyhow!("-D {d}: expected NAME=VALUE"))?;
            Ok((k.trim().to_string(), v.to_string()))
        })
        .collect()
}

fn set_threads(threads: Option<usize>) -> Result<()> {
    if let Some(t) = threads {
        if t == 0 {
            bail!("-t must be at least 1");
        }
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build_global()
            .context("cannot set up the thread pool")?;
    }
    Ok(())
}

/// `--crop X,Y,W,H`: four non-negative integers.
fn parse_crop(s: &str) -> std::result::Result<[usize; 4], String> {
    let v: Vec<usize> = s
        .split(',')
        .map(|t| t.trim().parse::<usize>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|e| format!("\"{s}\": {e}; expected X,Y,W,H (pixels)"))?;
    <[usize; 4]>::try_from(v).map_err(|v| {
        format!(
            "\"{s}\" has {} numbers; expected four: X,Y,W,H (pixels)",
            v.len()
        )
    })
}

/// Loads the scene and checks where the output goes; returns the scene and OUT.exr.
fn prepare(args: &SceneArgs) -> Result<(Scene, PathBuf)> {
    let params = parse_defines(&args.define)?;
    if args.spp == Some(0) {
        bail!("--spp must be at least 1");
    }
    set_threads(args.threads)?;
    let opts = xml::LoadOptions {
        params,
        search_dirs: args.search.clone(),
        strict_v3: args.strict_v3,
    };
    let overrides = BuildOverrides {
        spp: args.spp,
        seed: args.seed,
        crop: args.crop,
    };
    let scene = load_scene(&args.scene, &opts, &overrides).map_err(|e| anyhow!("{e}"))?;

    let out_exr = args
        .output
        .clone()
        .unwrap_or_else(|| args.scene.with_extension("exr"));
    if out_exr.extension().and_then(|e| e.to_str()) != Some("exr") {
        bail!("output {} must end in .exr", out_exr.display());
    }
    if let Some(dir) = out_exr.parent().filter(|d| !d.as_os_str().is_empty()) {
        if !dir.is_dir() {
            bail!("output folder {} does not exist", dir.display());
        }
    }
    image::check_writable(&out_exr)?;
    for w in &scene.warnings {
        eprintln!("warning: {w}");
    }
    if let Some(w) = mediareg::scene::cost::long_render_warning(
        &scene,
        &scene.shot,
        rayon::current_num_threads(),
    ) {
        eprintln!("warning: {w}");
    }
    Ok((scene, out_exr))
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

/// OUT.exr with `_suffix` added to its stem.
fn sibling(out_exr: &Path, suffix: &str) -> PathBuf {
    let stem = out_exr.file_stem().unwrap_or_default().to_string_lossy();
    out_exr.with_file_name(format!("{stem}{suffix}.exr"))
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render {
            args,
            gradient,
            medium,
            ray_log,
        } => {
            let (mut scene_data, out_exr) = prepare(&args)?;
            if ray_log.is_some() {
                if !cfg!(feature = "ray-log") {
                    bail!("--ray-log needs a build with the ray-log feature: cargo build --release --features ray-log");
                }
                scene_data.ray_log = Some(RayLog::default());
            }
            let gradient = match gradient {
                None => Gradient::None,
                Some(GradientArg::Albedo) => {
                    if scene_data.integrator.kind != IntegratorKind::Volpath {
                        bail!("--gradient albedo needs the volpath integrator (the scene's integrator ignores media)");
                    }
                    Gradient::Albedo(
                        scene_data
                            .medium_index(medium.as_deref())
                            .map_err(|e| anyhow!("--gradient albedo: {e}"))?,
                    )
                }
            };

            let show = std::io::stderr().is_terminal();
            install_interrupt_handler()?;
            let rendered = integrator::render(
                &scene_data,
                &scene_data.shot,
                &integrator::RenderOptions {
                    show_progress: show,
                    gradient,
                    cancel: Some(&INTERRUPT),
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
            // One attribute only: exr keeps them in a HashMap, whose order (and so the
            // file's bytes) would change from run to run.
            let attributes = [("spp", stats.spp as i32)];
            image::write_exr_with(&out_exr, img, &attributes)?;
            let mut written = vec![out_exr.display().to_string()];
            if let Some(g) = &rendered.gradient {
                let out_grad = sibling(&out_exr, "_dalbedo");
                image::write_exr_with(&out_grad, g, &attributes)?;
                written.push(out_grad.display().to_string());
            }
            if !args.no_png {
                let out_png = out_exr.with_extension("png");
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
        Command::Regularize {
            args,
            medium,
            factor,
            c_beta,
            fit_spp,
            fit_at,
            frames,
            wa,
            reproject,
            orbit,
            dolly,
            camera_path,
            target,
            spatial,
            no_spatial,
            predict,
            pilot_renders,
            pilot_spp,
        } => {
            let (scene_data, out_exr) = prepare(&args)?;
            let medium = scene_data
                .medium_index(medium.as_deref())
                .map_err(|e| anyhow!("regularize: {e}"))?;
            let c_beta = if c_beta == "fit" {
                CBeta::Fit {
                    spp: fit_spp,
                    at: fit_at,
                }
            } else {
                CBeta::Fixed(
                    c_beta
                        .parse::<f32>()
                        .ok()
                        .filter(|c| c.is_finite())
                        .ok_or_else(|| anyhow!("--c-beta {c_beta}: expected a number or `fit`"))?,
                )
            };
            let method = match predict {
                PredictArg::Paper => Method::Paper(c_beta),
                PredictArg::Linear => Method::Linear,
                PredictArg::Loglinear => Method::LogLinear,
                PredictArg::Difference => Method::Difference,
            };
            // The target frame: the file's shot, or the camera path's last transform.
            let mut shot = scene_data.shot.clone();
            let path = match (orbit, dolly, camera_path) {
                (Some(degrees), _, _) => {
                    let target = match target {
                        Some(t) => parse_point(&t)?,
                        None => image_centre_point(&scene_data, &scene_data.shot).ok_or_else(|| anyhow!("--orbit: the image centre sees no surface; give the orbit's centre with --target x,y,z"))?,
                    };
                    CameraPath::Orbit {
                        degrees_per_frame: degrees,
                        target,
                    }
                }
                (_, Some(distance), _) => CameraPath::Dolly {
                    distance_per_frame: distance,
                },
                (_, _, Some(file)) => {
                    let p = CameraPath::read(&file).map_err(|e| anyhow!("{e}"))?;
                    // The file's last transform is the target frame.
                    if let CameraPath::Transforms(list) = &p {
                        shot.camera.to_world = *list.last().expect("not empty");
                    }
                    p
                }
                _ => CameraPath::Static,
            };
            if frames > 1 && path == CameraPath::Static {
                eprintln!(
                    "note: no --orbit, --dolly or --camera-path: the {frames} frames share the sensor and differ only in their noise"
                );
            }
            // `auto` (the default with the difference predictor) leaves the factor to the
            // pilot; the factor given is then unused.
            let pilot = PilotSize {
                chunks: pilot_renders,
                spp: pilot_spp,
            };
            let (factor, auto_factor) = match factor.as_deref() {
                Some("auto") => (0.95, Some(pilot)),
                Some(f) => (
                    f.parse::<f32>()
                        .ok()
                        .filter(|f| f.is_finite())
                        .ok_or_else(|| anyhow!("--factor {f}: expected a number or `auto`"))?,
                    None,
                ),
                None => (0.95, (method == Method::Difference).then_some(pilot)),
            };
            let opts = regularize::Options {
                medium,
                factor,
                frames,
                w_a: wa,
                path,
                reproject: match reproject {
                    ReprojectArg::Exact => Reproject::Exact,
                    ReprojectArg::Shift => Reproject::Shift,
                    ReprojectArg::None => Reproject::None,
                },
                spatial: (spatial || (method == Method::Difference && !no_spatial))
                    .then(BilateralParams::default),
                auto_factor,
                method,
                show_progress: std::io::stderr().is_terminal(),
            };
            let r =
                regularize::regularize(&scene_data, &shot, &opts).map_err(|e| anyhow!("{e}"))?;

            let outputs: [(PathBuf, &Image, bool); 4] = [
                (out_exr.clone(), &r.predicted, false),
                (sibling(&out_exr, "_source"), &r.source, false),
                (sibling(&out_exr, "_dalbedo_raw"), &r.raw_gradient, true),
                (sibling(&out_exr, "_dalbedo"), &r.gradient, true),
            ];
            // Both gradient previews on the raw gradient's scale, so they compare.
            let scale = image::signed_scale(&r.raw_gradient);
            let mut written = Vec::new();
            for (path, img, signed) in &outputs {
                image::write_exr(path, img)?;
                written.push(path.display().to_string());
                if !args.no_png {
                    let png = path.with_extension("png");
                    if *signed {
                        image::write_png_signed(&png, img, scale)?;
                    } else {
                        image::write_png(&png, img)?;
                    }
                    written.push(png.display().to_string());
                }
            }
            if r.invalid_samples > 0 {
                eprintln!(
                    "warning: {} samples were NaN or Inf and were dropped",
                    r.invalid_samples
                );
            }
            if r.fallbacks > 0 {
                eprintln!(
                    "warning: {} channel values could not be predicted (negative or not finite) and keep the source radiance",
                    r.fallbacks
                );
            }
            if let Some(p) = &r.pilot {
                let costs: Vec<String> = p
                    .candidates
                    .iter()
                    .map(|c| format!("{}: {:.3e}", c.factor, c.error.iter().sum::<f64>()))
                    .collect();
                println!(
                    "factor {:?} (R, G, B) chosen by the pilot in {:.2} s (predicted squared error at equal time, summed over pixels and channels: {})",
                    p.factor,
                    p.seconds,
                    costs.join(", ")
                );
            }
            let a = &r.albedos;
            let t = &r.timings;
            println!(
                "albedo {} -> {}; {} frames ({:.2} blended per pixel), {} spp each; c_beta {}",
                fmt3(a.source),
                fmt3(a.target),
                r.frames_rendered,
                r.mean_frames,
                shot.spp,
                r.c_beta.map_or("-".into(), |c| format!("{c:.4}")),
            );
            println!(
                "seconds: target frame {:.2}, all frames {:.2}, c_beta fit {:.2}, denoise+predict {:.2}",
                t.target_frame, t.frames, t.fit, t.denoise_and_predict
            );
            println!("wrote {}", written.join(", "));
            Ok(())
        }
        Command::Table(args) => {
            let opts = table_options(args, "out/table")?;
            let run = report::run_table(&opts)?;
            report::output::write_outputs(&opts, &run)?;
            for n in &run.notes {
                eprintln!("note: {n}");
            }
            println!(
                "wrote {} rows to {}/table1.md, table1.csv, table1.json",
                run.rows.len(),
                opts.out.display()
            );
            Ok(())
        }
        Command::Report {
            table,
            figures,
            output,
        } => {
            report::output::rewrite_markdown(&table)?;
            let page = report::html::write_report(&output, &table, &figures)?;
            println!("wrote {}", page.display());
            Ok(())
        }
        Command::Figures {
            table,
            only,
            figure_reference_dir,
            res,
            budgets,
            sweep_budget,
            fig7_spp,
        } => {
            let base = table_options(table, "out/figures")?;
            let opts = report::figures::FigureOptions {
                base,
                figure_reference_dir,
                res,
                budgets,
                budget: sweep_budget,
                fig7_spp,
                only,
            };
            let written = report::figures::make_figures(&opts)?;
            let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
            println!("wrote {}", names.join(", "));
            Ok(())
        }
    }
}

/// The table's options from its arguments (also the base of `figures`).
fn table_options(args: TableArgs, default_out: &str) -> Result<TableOptions> {
    let TableArgs {
        scenes,
        budget,
        spp,
        out,
        scene_dir,
        reference_dir,
        define,
        search,
        frames,
        wa,
        orbit,
        c_beta,
        factor,
        python,
        no_mitsuba,
        seed,
        threads,
        no_png,
    } = args;
    set_threads(threads)?;
    let search = if search.is_empty() {
        vec![PathBuf::from(".cache/meshes")]
    } else {
        search
    };
    let mitsuba = (!no_mitsuba).then(|| {
        let mut r = MitsubaRunner::default_in(Path::new("."));
        if let Some(p) = python {
            r.python = p;
        }
        r
    });
    Ok(TableOptions {
        scenes,
        scene_dir,
        reference_dir,
        search,
        params: parse_defines(&define)?,
        budget: match spp {
            Some(n) => Budget::Spp(n),
            None => Budget::Seconds(budget),
        },
        out: out.unwrap_or_else(|| PathBuf::from(default_out)),
        frames,
        w_a: wa,
        orbit_degrees: orbit,
        c_beta,
        factor,
        mitsuba,
        difference_factors: Vec::new(),
        skip: Vec::new(),
        seed,
        write_png: !no_png,
        verbose: true,
    })
}

fn fmt3(v: Vec3) -> String {
    format!("[{:.4}, {:.4}, {:.4}]", v.x, v.y, v.z)
}

fn parse_point(s: &str) -> Result<Vec3> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>().ok().filter(|v| v.is_finite()))
        .collect::<Option<_>>()
        .ok_or_else(|| anyhow!("--target {s}: expected three numbers x,y,z"))?;
    match v[..] {
        [x, y, z] => Ok(Vec3::new(x, y, z)),
        _ => bail!("--target {s}: expected three numbers x,y,z"),
    }
}
