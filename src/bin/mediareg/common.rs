//! What several commands share: loading a scene and checking where its output goes,
//! the table's arguments (also the base of `figures`), and small parsers.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use glam::Vec3;

pub use mediareg::image::sibling;
use mediareg::regularize::RegularizeError;
use mediareg::report::mitsuba::MitsubaRunner;
use mediareg::report::{Budget, Method, TableOptions};
use mediareg::scene::{MediumChoiceError, Scene};
use mediareg::{image, load_scene, xml, BuildOverrides};

/// What every command needs to load a scene.
#[derive(Args)]
pub struct SceneArgs {
    /// The scene file (Mitsuba 3 XML).
    pub scene: PathBuf,
    /// Output EXR (default: the scene's name with .exr, beside the scene, as Mitsuba does).
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
    /// Set a scene parameter: -D name=value (overrides <default>).
    #[arg(short = 'D', value_name = "NAME=VALUE")]
    pub define: Vec<String>,
    /// Add a folder to the search path for meshes and includes.
    #[arg(short = 'a', value_name = "DIR")]
    pub search: Vec<PathBuf>,
    /// Samples per pixel (overrides the sampler's sample_count).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Random seed (overrides the sampler's seed).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Render only this window of the film: X,Y,W,H in pixels (overrides the film's
    /// crop_offset_x/y, crop_width/height)
    #[arg(long, value_name = "X,Y,W,H", value_parser = parse_crop)]
    pub crop: Option<[usize; 4]>,
    /// Read files older than 2.0 exactly as Mitsuba 3 does: refuse the Mitsuba 0.6
    /// readings mediareg otherwise makes (sigmaS/sigmaA media, density, index-matched
    /// medium boundaries without a bsdf)
    #[arg(long)]
    pub strict_v3: bool,
    /// Which <sensor> to render when the scene has several: 0 is the first in the file
    /// (as Mitsuba's `mitsuba` renders; unasked, with a warning where there are several).
    #[arg(long, value_name = "N")]
    pub sensor: Option<usize>,
    /// Render with one of mediareg's integrators (path, volpath, direct) instead of the
    /// file's; the file's max_depth, rr_depth and hide_emitters are kept.
    #[arg(long, value_name = "NAME")]
    pub integrator: Option<String>,
    /// Number of render threads (default: all cores).
    #[arg(short = 't', long = "threads")]
    pub threads: Option<usize>,
    /// Do not write PNG previews.
    #[arg(long)]
    pub no_png: bool,
}

/// `mediareg table`'s arguments.
#[derive(Args)]
pub struct TableArgs {
    /// Scene names: SCENE_DIR/NAME.xml, with REFERENCE_DIR/NAME.exr.
    #[arg(long, value_delimiter = ',', default_value = "bunny,candle,lucy")]
    pub scenes: Vec<String>,
    /// Seconds per method (per frame for the regularized sequence).
    #[arg(long, conflicts_with = "spp", default_value_t = 30.0)]
    pub budget: f64,
    /// Equal spp instead of equal time.
    #[arg(long)]
    pub spp: Option<u32>,
    /// The paper's spp instead of equal time: path tracing 200 / 1300 / 350 spp, the
    /// method 256 / 2048 / 512 per frame (Bunny / Candle / Lucy, its Table 1).
    #[arg(long, conflicts_with_all = ["spp", "budget"])]
    pub paper_spp: bool,
    /// Only these methods (volpath, volpath_oidn, volpath_filtered, regularized_paper,
    /// regularized_spatial, regularized; default: all).
    #[arg(long, value_delimiter = ',')]
    pub methods: Vec<String>,
    /// Output folder (default: out/table, or out/figures for `figures`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    #[arg(long, default_value = "mitsuba_scenes")]
    pub scene_dir: PathBuf,
    #[arg(long, default_value = "reference")]
    pub reference_dir: PathBuf,
    /// Set a scene parameter in every scene: -D name=value (the references must have
    /// been made with the same).
    #[arg(short = 'D', value_name = "NAME=VALUE")]
    pub define: Vec<String>,
    /// Add a folder to the search path (default: .cache/meshes, where
    /// scripts/fetch_meshes puts the meshes).
    #[arg(short = 'a', value_name = "DIR")]
    pub search: Vec<PathBuf>,
    /// Frames of the regularized sequence (N of Eq. 10).
    #[arg(long, default_value_t = 11)]
    pub frames: usize,
    /// w_a of Eq. 10.
    #[arg(long, default_value_t = 0.1)]
    pub wa: f64,
    /// Degrees the camera orbits per frame of the sequence.
    #[arg(long, default_value_t = 0.5)]
    pub orbit: f32,
    /// c_β of the paper's predictor.
    #[arg(long = "c-beta", default_value_t = 0.5)]
    pub c_beta: f32,
    /// Source albedo factor (default: the paper's for the scene, else 0.95).
    #[arg(long)]
    pub factor: Option<f32>,
    /// The Python that has Mitsuba 3 (default: .venv/bin/python if present, else python3).
    #[arg(long)]
    pub python: Option<PathBuf>,
    /// Do not render with Mitsuba 3.
    #[arg(long)]
    pub no_mitsuba: bool,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Seeds per scene (each ratio gets its confidence interval over them).
    #[arg(long, default_value_t = 4)]
    pub seeds: usize,
    /// Only the `frame` accounting (no baselines at the whole sequence's time).
    #[arg(long)]
    pub no_still: bool,
    /// No Open Image Denoise: no volpath_oidn rows, the bilateral filter in the
    /// regularized rows (default: used when the library loads).
    #[arg(long)]
    pub no_oidn: bool,
    /// Number of render threads (default: all cores).
    #[arg(short = 't', long = "threads")]
    pub threads: Option<usize>,
    /// Do not write PNG previews.
    #[arg(long)]
    pub no_png: bool,
}

/// `-D name=value` arguments as pairs.
pub fn parse_defines(defines: &[String]) -> Result<Vec<(String, String)>> {
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

pub fn set_threads(threads: Option<usize>) -> Result<()> {
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
pub fn parse_crop(s: &str) -> std::result::Result<[usize; 4], String> {
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
pub fn prepare(args: &SceneArgs) -> Result<(Scene, PathBuf)> {
    let params = parse_defines(&args.define)?;
    if args.spp == Some(0) {
        bail!("--spp must be at least 1");
    }
    set_threads(args.threads)?;
    // A ray caster asked for and missing is an error before a long load.
    mediareg::geometry::accel::Backend::requested().map_err(|e| anyhow!(e))?;
    let opts = xml::LoadOptions {
        params,
        search_dirs: args.search.clone(),
        strict_v3: args.strict_v3,
    };
    let overrides = BuildOverrides {
        spp: args.spp,
        seed: args.seed,
        crop: args.crop,
        sensor: args.sensor,
        integrator: args.integrator.clone(),
    };
    // The output is checked before the load, which may take seconds on a large scene.
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
    let scene = load_scene(&args.scene, &opts, &overrides).map_err(|e| anyhow!("{e}"))?;

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

/// The table's options from its arguments (also the base of `figures`).
pub fn table_options(args: TableArgs, default_out: &str) -> Result<TableOptions> {
    let TableArgs {
        scenes,
        budget,
        spp,
        paper_spp,
        methods,
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
        seeds,
        no_still,
        no_oidn,
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
        budget: match (spp, paper_spp) {
            (_, true) => Budget::PaperSpp,
            (Some(n), _) => Budget::Spp(n),
            (None, _) => Budget::Seconds(budget),
        },
        out: out.unwrap_or_else(|| PathBuf::from(default_out)),
        frames,
        w_a: wa,
        orbit_degrees: orbit,
        c_beta,
        factor,
        mitsuba,
        difference_factors: Vec::new(),
        skip: skipped(&methods)?,
        seed,
        seeds,
        still: !no_still,
        oidn: !no_oidn && mediareg::denoise::oidn::load().is_ok(),
        write_png: !no_png,
        verbose: true,
    })
}

/// The methods a table run skips: all but `only` where it names some, else the
/// single-frame spatial variant (the figures' business).
fn skipped(only: &[String]) -> Result<Vec<Method>> {
    let all = [
        Method::Volpath,
        Method::VolpathOidn,
        Method::VolpathFiltered,
        Method::RegularizedPaper,
        Method::RegularizedSpatial,
        Method::Regularized,
    ];
    if only.is_empty() {
        return Ok(vec![Method::RegularizedSpatial]);
    }
    for name in only {
        if !all.iter().any(|m| m.as_str() == name) {
            let names: Vec<&str> = all.iter().map(|m| m.as_str()).collect();
            bail!(
                "--methods {name}: not a table method (one of {})",
                names.join(", ")
            );
        }
    }
    Ok(all
        .into_iter()
        .filter(|m| !only.iter().any(|n| n == m.as_str()))
        .chain([Method::RegularizedDifference])
        .collect())
}

pub fn fmt3(v: Vec3) -> String {
    format!("[{:.4}, {:.4}, {:.4}]", v.x, v.y, v.z)
}

pub fn parse_point(s: &str) -> Result<Vec3> {
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

/// A medium that could not be chosen, worded with the `--medium` flag.
pub fn medium_error(e: MediumChoiceError) -> anyhow::Error {
    match &e {
        MediumChoiceError::NoSuch { name, .. } | MediumChoiceError::Ambiguous { name, .. } => {
            anyhow!("--medium {name}: {e}")
        }
        MediumChoiceError::Several { .. } => anyhow!("{e} (--medium NAME)"),
        MediumChoiceError::NoMedium => anyhow!("{e}"),
    }
}

/// The method's refusal, worded with the flags of `regularize` that set what it refuses.
pub fn regularize_error(e: RegularizeError) -> anyhow::Error {
    let flag = match &e {
        RegularizeError::AutoFactorNeedsDifference => "--factor auto (--predict difference)".into(),
        RegularizeError::PilotTooSmall { .. } => "--pilot-renders, --pilot-spp".into(),
        RegularizeError::Factor(f) => format!("--factor {f}"),
        RegularizeError::Frames { frames, w_a } => format!("--frames {frames}, --wa {w_a}"),
        RegularizeError::Fit { .. } => "--fit-spp, --fit-at".into(),
        RegularizeError::NothingToFit => "--c-beta fit".into(),
        _ => return anyhow!("{e}"),
    };
    anyhow!("{flag}: {e}")
}

/// The warning for samples the render dropped as NaN or Inf (none: nothing said).
pub fn warn_invalid_samples(count: u64) {
    if count > 0 {
        eprintln!("warning: {count} samples were NaN or Inf and were dropped");
    }
}
