//! `mediareg fit`: a medium's parameters from target images (`mediareg::fit`).

use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use serde_json::{json, Map, Value};

use mediareg::fit::{self, FitError, FitSettings, FitTarget};
use mediareg::integrator::{GradientError, MediumParam};
use mediareg::{image, load_scene, xml, BuildOverrides};

use crate::common::{medium_error, parse_defines, set_threads};
use crate::interrupt::{install_handler, INTERRUPT};

/// Fit a medium's parameters (sigma_t, albedo, g, scale) to one or more target images,
/// starting from the scene's values: damped Gauss–Newton on the squared error, with the
/// derivatives rendered in the same paths as the image. Writes OUT.json: the values,
/// their 95% intervals, the loss and values of each iteration, the seconds taken.
#[derive(Args)]
pub struct FitArgs {
    /// The scene file (Mitsuba 3 XML) whose medium is fitted.
    pub scene: PathBuf,
    /// A target image (EXR, the scene's film size). Repeat for several views or
    /// lights; a target rendered with other scene parameters names them after an @:
    /// `--target lit_left.exr@light_x=-2,light_y=1`.
    #[arg(long, value_name = "IMAGE.exr[@NAME=VALUE,...]", required = true)]
    pub target: Vec<String>,
    /// The medium: its XML id, its slot (interior, exterior) or its mi.traverse key
    /// (SHAPE_ID.interior_medium); needed when the scene has several.
    #[arg(long, value_name = "NAME")]
    pub medium: Option<String>,
    /// The parameters to fit, comma-separated: sigma_t, albedo, g, scale.
    #[arg(long, value_name = "PARAMS", default_value = "sigma_t,albedo,g")]
    pub params: String,
    /// Set a scene parameter for every target: -D name=value.
    #[arg(short = 'D', value_name = "NAME=VALUE")]
    pub define: Vec<String>,
    /// Add a folder to the search path for meshes and includes.
    #[arg(short = 'a', value_name = "DIR")]
    pub search: Vec<PathBuf>,
    /// Samples per pixel of each iteration's render.
    #[arg(long, default_value_t = 32)]
    pub spp: u32,
    /// Iterations (renders of every target). Default: 100, growing by half at a time
    /// up to 400 while the estimate is still moving.
    #[arg(long)]
    pub iterations: Option<u32>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Number of render threads (default: all cores).
    #[arg(short = 't', long = "threads")]
    pub threads: Option<usize>,
    /// Where the result goes (JSON).
    #[arg(short = 'o', long = "output", value_name = "OUT.json")]
    pub output: PathBuf,
}

/// `name=value,name=value` into its defines; a value may hold commas itself (a
/// point: `light=1,2,3`): a piece without `=` belongs to the value before it.
fn split_defines(list: &str) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for piece in list.split(',') {
        match out.last_mut() {
            Some(last) if !piece.contains('=') => {
                last.push(',');
                last.push_str(piece);
            }
            _ => out.push(piece.to_string()),
        }
    }
    out
}

pub fn run(args: FitArgs) -> Result<()> {
    if args.spp == 0 || args.iterations == Some(0) {
        bail!("--spp and --iterations must be at least 1");
    }
    set_threads(args.threads)?;
    let params = MediumParam::parse_list(&args.params).map_err(|e| anyhow!("--params: {e}"))?;
    let global = parse_defines(&args.define)?;
    let mut targets = Vec::new();
    for spec in &args.target {
        let (path, defines) = match spec.split_once('@') {
            Some((p, d)) => (p, split_defines(d)),
            None => (spec.as_str(), Vec::new()),
        };
        let mut all = global.clone();
        all.extend(parse_defines(&defines).with_context(|| format!("--target {spec}"))?);
        let opts = xml::LoadOptions {
            params: all,
            search_dirs: args.search.clone(),
            strict_v3: false,
        };
        let scene = load_scene(&args.scene, &opts, &BuildOverrides::default())
            .map_err(|e| anyhow!("{e}"))?;
        let image =
            image::read_exr(&PathBuf::from(path)).map_err(|e| anyhow!("--target {path}: {e}"))?;
        targets.push(FitTarget { scene, image });
    }
    install_handler()?;
    let settings = FitSettings {
        medium: args.medium.clone(),
        params,
        spp: args.spp,
        iterations: args.iterations.unwrap_or(fit::DEFAULT_ITERATIONS),
        max_iterations: args.iterations.unwrap_or(fit::MAX_ITERATIONS),
        seed: args.seed,
        cancel: Some(Arc::clone(&INTERRUPT)),
    };
    let start = std::time::Instant::now();
    let mut trace = Vec::new();
    let result = fit::fit(&mut targets, &settings, |p| {
        let mut at = Map::new();
        for (u, v) in p.unknowns.iter().zip(p.values) {
            at.insert(u.label(), json!(v));
        }
        trace.push(json!({"seconds": start.elapsed().as_secs_f64(), "params": at}));
        let values: Vec<String> = p
            .unknowns
            .iter()
            .zip(p.values)
            .map(|(u, v)| format!("{}={v:.4}", u.label()))
            .collect();
        eprintln!(
            "[{:>3}/{}] loss {:.4e}  {}",
            p.iteration,
            p.planned,
            p.loss,
            values.join(" ")
        );
    })
    .map_err(|e| match e {
        FitError::Gradient(GradientError::Medium(m)) => medium_error(m),
        e => anyhow!("{e}"),
    })?;
    let mut values = Map::new();
    let mut ci = Map::new();
    let mut defines = Vec::new();
    for ((u, v), c) in result.unknowns.iter().zip(&result.values).zip(&result.ci) {
        let bound = |x: f32| {
            if x.is_finite() {
                json!(x)
            } else {
                json!(if x > 0.0 { "inf" } else { "-inf" })
            }
        };
        values.insert(u.label(), json!(v));
        ci.insert(u.label(), json!([bound(c[0]), bound(c[1])]));
        if u.channel.is_none() {
            defines.push(format!("-D {}={v}", u.param.name()));
        }
    }
    let out = json!({
        "params": Value::Object(values),
        "ci": Value::Object(ci),
        "loss": result.loss,
        "iterations": result.iterations,
        "converged": result.converged,
        "trace": trace,
        "seconds": result.seconds,
        "spp": args.spp,
    });
    std::fs::write(&args.output, serde_json::to_string_pretty(&out)? + "\n")
        .with_context(|| format!("writing {}", args.output.display()))?;
    for ((u, v), c) in result.unknowns.iter().zip(&result.values).zip(&result.ci) {
        eprintln!(
            "{:>12} = {v:.5}   95% interval [{:.5}, {:.5}]",
            u.label(),
            c[0],
            c[1]
        );
    }
    if !result.converged {
        eprintln!(
            "warning: the parameters were still moving over the last iterations; the intervals understate the error: run more --iterations (or --spp)"
        );
    }
    if !defines.is_empty() {
        eprintln!(
            "reproduce (where the scene file's defaults carry these names): {}",
            defines.join(" ")
        );
    }
    eprintln!(
        "{} iterations in {:.1} s; wrote {}",
        result.iterations,
        result.seconds,
        args.output.display()
    );
    Ok(())
}
