//! `mediareg optimize`: a grid medium's voxels from target images of the scene's
//! sensors (`mediareg::optimize`), Mitsuba 3's volume tutorial as one command.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use mediareg::medium::grid::Filter;
use mediareg::optimize::{self, Grids, OptimizeSettings, Stage, View};
use mediareg::scene::Scene;
use mediareg::{image, load, xml, BuildOverrides};

use crate::backward::{parse_volume_params, write_grid};
use crate::common::{medium_error, parse_defines, set_threads};
use crate::interrupt::{install_handler, INTERRUPT};

/// Fit a grid medium's voxels (sigma_t, and albedo) to images of the scene's sensors:
/// L2 loss, reverse-mode gradients, Adam, a coarse-to-fine schedule. Writes OUT.vol
/// (OUT_albedo.vol), and OUT.json with the loss and seconds of every iteration.
#[derive(Args)]
pub struct OptimizeArgs {
    /// The scene file (Mitsuba 3 XML) whose medium is optimized.
    pub scene: PathBuf,
    /// A target image (EXR) of one sensor: the n-th --target is the n-th <sensor> in
    /// file order, unless it names its sensor: `--target view3.exr@sensor=3`.
    #[arg(long, value_name = "IMAGE.exr[@sensor=N]", required = true)]
    pub target: Vec<String>,
    /// The volumes to optimize, comma-separated: sigma_t, albedo.
    #[arg(long, value_name = "PARAMS", default_value = "sigma_t")]
    pub params: String,
    /// The medium: its XML id, its slot (interior, exterior) or its mi.traverse key
    /// (SHAPE_ID.interior_medium); needed when the scene has several.
    #[arg(long, value_name = "NAME")]
    pub medium: Option<String>,
    /// Adam's learning rate (the tutorial's 0.02).
    #[arg(long, default_value_t = 0.02)]
    pub lr: f32,
    /// A stage of the schedule, ITERATIONS:RES:SPP[:LR] (RES a grid side, or `-` to keep
    /// the grid's; LR this stage's learning rate, else --lr); repeat for coarse to fine.
    /// Default: one stage of --iterations at --spp.
    #[arg(long, value_name = "ITERS:RES:SPP[:LR]")]
    pub stage: Vec<String>,
    /// Iterations without --stage (each an Adam step per target).
    #[arg(long, default_value_t = 40)]
    pub iterations: u32,
    /// Samples per pixel without --stage.
    #[arg(long, default_value_t = 8)]
    pub spp: u32,
    /// How the grid is resampled between stages: nearest (the tutorial's dr.upsample)
    /// or trilinear.
    #[arg(long, default_value = "nearest")]
    pub upsample: String,
    /// The range sigma_t's values are kept in, LO,HI (the tutorial's 1e-6,1).
    #[arg(long, value_name = "LO,HI", default_value = "0,inf")]
    pub range: String,
    /// The range of the albedo's values.
    #[arg(long, value_name = "LO,HI", default_value = "0,1")]
    pub albedo_range: String,
    /// Start sigma_t's grid at this value everywhere (at the first stage's resolution)
    /// instead of the scene's.
    #[arg(long)]
    pub init: Option<f32>,
    /// Also write OUT_iterK.vol every K iterations.
    #[arg(long, value_name = "K")]
    pub snapshot_every: Option<u32>,
    /// Set a scene parameter: -D name=value.
    #[arg(short = 'D', value_name = "NAME=VALUE")]
    pub define: Vec<String>,
    /// Add a folder to the search path.
    #[arg(short = 'a', value_name = "DIR")]
    pub search: Vec<PathBuf>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Number of render threads (default: all cores).
    #[arg(short = 't', long = "threads")]
    pub threads: Option<usize>,
    /// The optimized volume (Mitsuba's .vol).
    #[arg(short = 'o', long = "output", value_name = "OUT.vol")]
    pub output: PathBuf,
}

fn parse_range(flag: &str, s: &str) -> Result<(f32, f32)> {
    let parse = |v: &str| -> Result<f32> {
        v.trim()
            .parse::<f32>()
            .map_err(|_| anyhow!("{flag} {s}: '{v}' is not a number"))
    };
    let (lo, hi) = s
        .split_once(',')
        .ok_or_else(|| anyhow!("{flag} {s}: expected LO,HI"))?;
    let (lo, hi) = (parse(lo)?, parse(hi)?);
    if lo.is_nan() || hi.is_nan() || lo > hi {
        bail!("{flag} {s}: LO must not exceed HI");
    }
    Ok((lo, hi))
}

fn parse_stage(s: &str) -> Result<Stage> {
    let parts: Vec<&str> = s.split(':').collect();
    let bad =
        || anyhow!("--stage {s}: expected ITERATIONS:RES:SPP[:LR], e.g. 20:16:8 (RES may be -)");
    let (it, res, spp, lr) = match parts[..] {
        [it, res, spp] => (it, res, spp, None),
        [it, res, spp, lr] => (it, res, spp, Some(lr)),
        _ => return Err(bad()),
    };
    let lr = match lr {
        Some(v) => Some(v.parse::<f32>().ok().filter(|v| *v > 0.0).ok_or_else(bad)?),
        None => None,
    };
    let iterations: u32 = it.parse().map_err(|_| bad())?;
    let spp: u32 = spp.parse().map_err(|_| bad())?;
    let res = match res {
        "-" => None,
        r => {
            let n: usize = r.parse().map_err(|_| bad())?;
            if n == 0 || n > 1024 {
                bail!("--stage {s}: the grid side must be 1 to 1024");
            }
            Some([n; 3])
        }
    };
    if spp == 0 {
        bail!("--stage {s}: spp must be at least 1");
    }
    Ok(Stage {
        iterations,
        res,
        spp,
        lr,
    })
}

/// The target's image path and its sensor (the n-th target's by default).
fn parse_target(spec: &str, n: usize) -> Result<(PathBuf, usize)> {
    match spec.split_once('@') {
        None => Ok((PathBuf::from(spec), n)),
        Some((path, rest)) => {
            let sensor = rest
                .strip_prefix("sensor=")
                .and_then(|v| v.parse().ok())
                .ok_or_else(|| anyhow!("--target {spec}: expected IMAGE.exr@sensor=N"))?;
            Ok((PathBuf::from(path), sensor))
        }
    }
}

/// OUT with `_suffix` before its extension.
fn beside(out: &Path, suffix: &str, ext: &str) -> PathBuf {
    PathBuf::from(format!(
        "{}{suffix}.{ext}",
        out.with_extension("").display()
    ))
}

fn write_grids(scene: &Scene, medium: u32, out: &Path, grids: &Grids) -> Result<Vec<String>> {
    let het = scene.media[medium as usize]
        .heterogeneous
        .as_deref()
        .ok_or_else(|| anyhow!("the medium is not heterogeneous"))?;
    let mut written = Vec::new();
    if let Some(v) = &grids.sigma_t {
        let volume = het
            .sigma_t
            .with_grid(grids.res, v.clone())
            .unwrap_or_else(|| het.sigma_t.clone());
        write_grid(out, &volume, v)?;
        written.push(out.display().to_string());
    }
    if let Some(v) = &grids.albedo {
        let path = beside(out, "_albedo", "vol");
        let volume = het
            .albedo
            .with_grid(grids.res, v.clone())
            .unwrap_or_else(|| het.albedo.clone());
        write_grid(&path, &volume, v)?;
        written.push(path.display().to_string());
    }
    Ok(written)
}

/// The process's peak resident memory in MiB (Linux's VmHWM), if known.
pub fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

pub fn run(args: OptimizeArgs) -> Result<()> {
    set_threads(args.threads)?;
    let (sigma_t, albedo) = parse_volume_params(&args.params)?;
    if args.output.extension().is_none_or(|e| e != "vol") {
        bail!("-o {}: the output is a .vol file", args.output.display());
    }
    let stages = match args.stage.is_empty() {
        true => vec![Stage {
            iterations: args.iterations,
            res: None,
            spp: args.spp.max(1),
            lr: None,
        }],
        false => args
            .stage
            .iter()
            .map(|s| parse_stage(s))
            .collect::<Result<_>>()?,
    };
    let upsampling = match args.upsample.as_str() {
        "nearest" => Filter::Nearest,
        "trilinear" => Filter::Trilinear,
        o => bail!("--upsample {o}: nearest or trilinear"),
    };
    let opts = xml::LoadOptions {
        params: parse_defines(&args.define)?,
        search_dirs: args.search.clone(),
        strict_v3: false,
    };
    let desc = xml::load_file(&args.scene, &opts).map_err(|e| anyhow!("{e}"))?;
    let mut scene: Option<Scene> = None;
    let mut views = Vec::new();
    for (n, spec) in args.target.iter().enumerate() {
        let (path, sensor) = parse_target(spec, n)?;
        let target =
            image::read_exr(&path).map_err(|e| anyhow!("--target {}: {e}", path.display()))?;
        let overrides = BuildOverrides {
            sensor: Some(sensor),
            ..Default::default()
        };
        let built =
            load::build_scene(&desc, &overrides).map_err(|e| anyhow!("--target {spec}: {e}"))?;
        if let Some(first) = &scene {
            if first.camera_medium != built.camera_medium {
                bail!("--target {spec}: its sensor sits in another medium than the first target's");
            }
        }
        views.push(View {
            shot: built.shot.clone(),
            target,
        });
        scene.get_or_insert(built);
    }
    let mut scene = scene.ok_or_else(|| anyhow!("no --target"))?;
    let medium = scene
        .medium_index(args.medium.as_deref())
        .map_err(medium_error)?;
    install_handler()?;
    let settings = OptimizeSettings {
        medium,
        sigma_t,
        albedo,
        lr: args.lr,
        stages: stages.clone(),
        upsampling,
        sigma_t_range: parse_range("--range", &args.range)?,
        albedo_range: parse_range("--albedo-range", &args.albedo_range)?,
        init_sigma_t: args.init,
        seed: args.seed,
        cancel: Some(Arc::clone(&INTERRUPT)),
    };
    let total: u64 = stages.iter().map(|s| s.iterations as u64).sum();
    let bar = match std::io::stderr().is_terminal() {
        true => ProgressBar::new(total),
        false => ProgressBar::hidden(),
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} iterations  loss {msg}  ETA {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    let mut snapshot_error = None;
    let result = optimize::optimize(&mut scene, &views, &settings, |r, scene| {
        bar.set_message(format!("{:.3e}", r.loss));
        bar.inc(1);
        if args
            .snapshot_every
            .is_some_and(|k| k > 0 && (r.iteration + 1) % k == 0)
        {
            let path = beside(&args.output, &format!("_iter{}", r.iteration + 1), "vol");
            let grids = current_grids(scene, medium, sigma_t, albedo);
            if let Err(e) = grids.map(|g| write_grids(scene, medium, &path, &g)) {
                snapshot_error.get_or_insert(e);
            }
        }
    })
    .map_err(|e| anyhow!("{}: {e}", args.scene.display()))?;
    bar.finish_and_clear();
    if let Some(e) = snapshot_error {
        return Err(e.context("writing a snapshot"));
    }
    let grids = match result.interrupted {
        true => {
            eprintln!("interrupted: writing the volume of the lowest loss so far");
            &result.best
        }
        false => &result.last,
    };
    let written = write_grids(&scene, medium, &args.output, grids)?;
    let seconds = result.iterations.last().map_or(0.0, |r| r.seconds);
    let iterations: Vec<_> = result
        .iterations
        .iter()
        .map(|r| json!({"iteration": r.iteration, "loss": r.loss, "seconds": r.seconds, "res": r.res, "spp": r.spp}))
        .collect();
    let report = json!({
        "scene": args.scene.display().to_string(),
        "params": args.params,
        "lr": args.lr,
        "stages": stages.iter().map(|s| json!({"iterations": s.iterations, "res": s.res, "spp": s.spp, "lr": s.lr})).collect::<Vec<_>>(),
        "upsample": args.upsample,
        "iterations": iterations,
        "seconds_total": seconds,
        "peak_rss_mib": peak_rss_mib(),
        "interrupted": result.interrupted,
        "volumes": written,
    });
    let json_path = args.output.with_extension("json");
    std::fs::write(&json_path, serde_json::to_string_pretty(&report)?)
        .with_context(|| format!("writing {}", json_path.display()))?;
    let last_loss = result.iterations.last().map_or(f64::NAN, |r| r.loss);
    eprintln!(
        "{} iterations in {seconds:.1} s, last loss {last_loss:.4e}: wrote {}, {}",
        result.iterations.len(),
        written.join(", "),
        json_path.display()
    );
    if result.interrupted {
        std::process::exit(crate::interrupt::EXIT_INTERRUPTED as i32);
    }
    Ok(())
}

/// The medium's grids as the scene holds them now.
fn current_grids(scene: &Scene, medium: u32, sigma_t: bool, albedo: bool) -> Result<Grids> {
    use mediareg::medium::grid::Source;
    let het = scene.media[medium as usize]
        .heterogeneous
        .as_deref()
        .ok_or_else(|| anyhow!("the medium is not heterogeneous"))?;
    let data = |on: bool, v: &mediareg::medium::grid::Volume| match (&v.source, on) {
        (Source::Grid { grid, .. }, true) => Some((grid.res, grid.data.clone())),
        _ => None,
    };
    let s = data(sigma_t, &het.sigma_t);
    let a = data(albedo, &het.albedo);
    let res = s.as_ref().or(a.as_ref()).map(|x| x.0).unwrap_or([1; 3]);
    Ok(Grids {
        res,
        sigma_t: s.map(|x| x.1),
        albedo: a.map(|x| x.1),
    })
}
