//! `mediareg table`: the paper's Table 1 on this machine. For each scene, at equal time
//! (or equal spp), against a Mitsuba 3 reference:
//!
//! * `regularized`: the paper's method as `mediareg regularize` runs it: a camera
//!   sequence (an orbit about the image centre's first visible point) at α_s = factor·α_t,
//!   the gradient blended over N frames (Eq. 10, exact reprojection), Eq. 11–12 with
//!   c_β = 0.5. Its cost is that of one frame of the sequence (the paper's accounting):
//!   the target frame's render plus reprojection, blending and prediction;
//! * `regularized_spatial`: one frame, the gradient filtered spatially instead;
//! * `volpath`: plain volpath at α_t;
//! * `mitsuba_volpath`: Mitsuba 3's volpath on the same XML (`scripts/mitsuba_render.py`),
//!   when the `mitsuba` package is importable; its time excludes kernel compilation.
//!
//! Equal time: each method's seconds per spp is measured first (renders of 1, 2, 4, …
//! spp until one takes a while), and its spp is the budget over that. Each row records
//! the seconds its render really took.
//!
//! The MSE is against the reference, raw and with the reference's own variance
//! subtracted (`metrics`). The reference must have been made from the very files and
//! `-D` parameters of the run: their sha256 and parameters are checked against its JSON.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{anyhow, bail, Context, Result};

use super::decompose::Decomposition;
use super::metrics::mse_against;
use super::mitsuba::{MitsubaRequest, MitsubaRunner, Unavailable};
use super::paper::table1_row;
pub use super::reference::{Reference, ReferenceMeta};
pub use super::row::{Accounting, Method, Row};
use crate::denoise::AuxUse;
use crate::image::Image;
use crate::integrator::{render, RenderOptions, Rendered};
use crate::load::build_scene;
use crate::regularize::pipeline::PilotSize;
use crate::regularize::sequence::{image_centre_point, CameraPath};
use crate::regularize::spatial::BilateralParams;
use crate::regularize::{self, CBeta, Reproject};
use crate::scene::shot::Shot;
use crate::scene::{IntegratorKind, Scene};
use crate::{image, xml, BuildOverrides};

mod sequences;

/// How much each method may spend.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// Equal time: seconds per method (per frame for the regularized sequence).
    Seconds(f64),
    /// Equal samples per pixel (per frame for the regularized sequence).
    Spp(u32),
    /// The paper's sample counts (its Table 1): path tracing's for the baselines, the
    /// method's per frame for the sequences.
    PaperSpp,
}

#[derive(Clone, Debug)]
pub struct TableOptions {
    /// Scene names: `SCENE_DIR/NAME.xml`, reference `REFERENCE_DIR/NAME.exr`.
    pub scenes: Vec<String>,
    pub scene_dir: PathBuf,
    pub reference_dir: PathBuf,
    pub search: Vec<PathBuf>,
    /// `-D` parameters; the reference must have been made with the same.
    pub params: Vec<(String, String)>,
    pub budget: Budget,
    pub out: PathBuf,
    /// N of Eq. 10 (the paper: 11) and w_a (0.1).
    pub frames: usize,
    pub w_a: f64,
    /// The orbit step between frames of the regularized sequence.
    pub orbit_degrees: f32,
    pub c_beta: f32,
    /// α_s = factor · α_t; default: the paper's factor for the scene, else 0.95.
    pub factor: Option<f32>,
    /// `None`: no Mitsuba 3 rows.
    pub mitsuba: Option<MitsubaRunner>,
    /// A `regularized_difference` row at each of these fixed factors (the sweeps' rows
    /// to compare the pilot's choice with).
    pub difference_factors: Vec<f32>,
    /// Methods not to run.
    pub skip: Vec<Method>,
    /// The first seed; `seeds` seeds in all, far apart (each render adds its own offsets).
    pub seed: u64,
    pub seeds: usize,
    /// Also the `still` accounting: the baselines rendered again at the time of the whole
    /// regularized sequence and its pilot.
    pub still: bool,
    /// Open Image Denoise is there: the `volpath_oidn` rows, and the regularized rows'
    /// filter (`regularized_filter`).
    pub oidn: bool,
    pub write_png: bool,
    /// One line per step on stderr.
    pub verbose: bool,
}

/// Everything a run produced.
#[derive(Default)]
pub struct TableRun {
    pub rows: Vec<Row>,
    /// Per scene: the reference's spp, the mean of its variance, and the correction's
    /// standard error (`metrics::correction_se`).
    pub references: Vec<(String, ReferenceMeta, f64, f64)>,
    /// Things the reader must know (a method skipped, and why).
    pub notes: Vec<String>,
    /// Per scene and method: the seconds a 1-spp run of its pipeline spends beside the
    /// frames' rendering (measured at the first seed, reused by the others).
    pub overheads: Vec<(String, Method, f64)>,
    /// Per scene with a `regularized` row: where its gain goes.
    pub decomposition: Vec<Decomposition>,
    /// Per scene and seed: OIDN's seconds on one image (the 1-spp probe of
    /// `volpath_oidn`), for its share of a budget.
    pub oidn_seconds: Vec<(String, f64)>,
}

fn scene_file(opts: &TableOptions, scene: &str) -> PathBuf {
    opts.scene_dir.join(format!("{scene}.xml"))
}

/// Loads `SCENE_DIR/scene.xml` with `params` and builds it, with its reference
/// `REFERENCE_DIR/reference` checked against the files and parameters (read once).
pub fn load_with_reference(
    opts: &TableOptions,
    scene: &str,
    reference: &str,
    params: &[(String, String)],
) -> Result<(Scene, Reference)> {
    let xml_path = scene_file(opts, scene);
    if !xml_path.is_file() {
        bail!(
            "scene {scene}: {} does not exist (--scenes names files in {})",
            xml_path.display(),
            opts.scene_dir.display()
        );
    }
    let load = xml::LoadOptions {
        params: params.to_vec(),
        search_dirs: opts.search.clone(),
        ..Default::default()
    };
    let desc = xml::load_file(&xml_path, &load).map_err(|e| anyhow!("{e}"))?;
    let reference = Reference::load(&opts.reference_dir, reference, &xml_path, &load, &desc)?;
    let built = build_scene(&desc, &BuildOverrides::default()).map_err(|e| anyhow!("{e}"))?;
    if built.integrator.kind != IntegratorKind::Volpath {
        bail!("{}: the table needs a volpath scene", xml_path.display());
    }
    if built.shot.film.crop_size != (reference.meta.width, reference.meta.height) {
        bail!(
            "{}: renders {}x{}, its reference is {}x{}",
            xml_path.display(),
            built.shot.film.crop_size.0,
            built.shot.film.crop_size.1,
            reference.meta.width,
            reference.meta.height
        );
    }
    Ok((built, reference))
}

/// The paper's method as the table runs it: N frames along `path`, exact
/// reprojection, Eq. 10, then Eq. 11–12 with the run's fixed c_β.
pub fn sequence_options(
    opts: &TableOptions,
    medium: u32,
    factor: f32,
    path: CameraPath,
) -> regularize::Options {
    regularize::Options {
        medium,
        factor,
        frames: opts.frames,
        w_a: opts.w_a,
        path,
        reproject: Reproject::Exact,
        spatial: None,
        oidn: regularize::OidnUse::None,
        method: regularize::Method::Paper(CBeta::Fixed(opts.c_beta)),
        auto_factor: None,
        pick: false,
        oidn_check: false,
        show_progress: false,
    }
}

/// An orbit of the run's step about the first point the image centre sees.
pub fn orbit_about_centre(opts: &TableOptions, scene: &Scene) -> Option<CameraPath> {
    image_centre_point(scene, &scene.shot).map(|target| CameraPath::Orbit {
        degrees_per_frame: opts.orbit_degrees,
        target,
    })
}

/// Seconds per spp of `scene` rendered with `options`: renders at 1, 2, 4, … spp until
/// one takes at least `min_seconds` (fixed costs per render are then a small part).
fn seconds_per_spp(scene: &Scene, options: &RenderOptions, min_seconds: f64, seed: u64) -> f64 {
    let mut spp = 1u32;
    loop {
        let r = render(scene, &scene.shot.with(spp, seed), options);
        if r.stats.seconds >= min_seconds || spp >= 1 << 16 {
            break r.stats.seconds / spp as f64;
        }
        spp *= 2;
    }
}

fn spp_for(budget: f64, seconds_per_spp: f64) -> u32 {
    (budget / seconds_per_spp.max(1e-9)).floor().clamp(1.0, 1e7) as u32
}

/// `path` relative to the folder `base` (both made absolute first).
fn relative_to(path: &Path, base: &Path) -> String {
    let abs = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    pathdiff::diff_paths(abs(path), abs(base))
        .unwrap_or_else(|| path.to_path_buf())
        .to_string_lossy()
        .into_owned()
}

/// Runs the table; writes the images into `opts.out` and returns the rows (the caller
/// writes the table files with `write_outputs`).
pub fn run_table(opts: &TableOptions) -> Result<TableRun> {
    if opts.scenes.is_empty() {
        bail!("--scenes: no scene given");
    }
    match opts.budget {
        Budget::Seconds(b) if !(b.is_finite() && b > 0.0) => {
            bail!("--budget {b}: must be a positive number of seconds")
        }
        Budget::Spp(0) => bail!("--spp must be at least 1"),
        Budget::PaperSpp => {
            if let Some(s) = opts.scenes.iter().find(|s| table1_row(s).is_none()) {
                bail!("--paper-spp: the paper's Table 1 has no row for {s} (it has bunny, candle, lucy)")
            }
        }
        _ => {}
    }
    std::fs::create_dir_all(&opts.out)
        .with_context(|| format!("cannot create {}", opts.out.display()))?;
    let mut run = TableRun::default();
    for name in &opts.scenes {
        for i in 0..opts.seeds.max(1) {
            let seeded = TableOptions {
                seed: seed_of(opts.seed, i),
                ..opts.clone()
            };
            run_scene(&SceneJob::named(name), &seeded, &mut run)?;
        }
    }
    Ok(run)
}

/// The i-th seed of a run: far enough apart that no two seeds' renders share a stream
/// (a render adds offsets up to a few million to its seed, a sequence its frame index).
pub fn seed_of(first: u64, i: usize) -> u64 {
    first.wrapping_add(i as u64 * 10_000_019)
}

/// One scene of a run: `SCENE_DIR/scene.xml` against `REFERENCE_DIR/reference.exr`,
/// its files named `tag_METHOD.exr`.
#[derive(Clone, Debug)]
pub struct SceneJob {
    pub scene: String,
    pub reference: String,
    pub tag: String,
}

impl SceneJob {
    /// The table's case: scene, reference and files share the name.
    pub fn named(name: &str) -> SceneJob {
        SceneJob {
            scene: name.into(),
            reference: name.into(),
            tag: name.into(),
        }
    }
}

/// Renders one scene with every method and appends its rows to `run`, step by step:
/// the baselines, the regularized sequences, the baselines again at the sequence's
/// time (`still`), Mitsuba 3.
pub fn run_scene(job: &SceneJob, opts: &TableOptions, run: &mut TableRun) -> Result<()> {
    let ctx = SceneRun::load(job, opts, run)?;
    let baselines = run_baselines(&ctx, run)?;
    let still_seconds = sequences::run_sequences(&ctx, run, baselines.volpath_per_spp)?;
    run_still_baselines(&ctx, run, &baselines, still_seconds)?;
    run_mitsuba(&ctx, run)
}

/// One scene at one seed, as `run_scene` renders it: the scene and its reference, and
/// what each of its steps shares.
struct SceneRun<'a> {
    opts: &'a TableOptions,
    /// The scene's name, as its rows and notes give it.
    name: &'a str,
    /// The prefix of its files' names.
    tag: &'a str,
    scene: Scene,
    reference: Reference,
    /// The medium whose albedo the regularized methods change.
    medium: u32,
    /// α_s = factor · α_t of the fixed-factor sequences.
    factor: f32,
    /// The reference's path relative to `opts.out`, as the rows give it.
    ref_rel: String,
    /// The run's first seed of this scene: its images keep the plain names.
    first_seed: bool,
    seed: u64,
    /// The files' suffix: none at the first seed, else `_seedN`.
    suffix: String,
    /// The baselines' render options (emission seen from the camera counts).
    with_seen: RenderOptions,
}

/// One method's image, as its row records it.
struct MethodImage<'i> {
    method: Method,
    accounting: Accounting,
    /// The regularized rows' factor per channel (source over target albedo).
    factor: Option<[f32; 3]>,
    image: &'i Image,
    spp: u32,
    seconds: f64,
    /// A sequence's frames rendered and its whole time.
    sequence: Option<(usize, f64)>,
    /// Also a `still` row of the same image, charged these seconds.
    still_seconds: Option<f64>,
}

impl<'i> MethodImage<'i> {
    /// A baseline's image: no factor, no sequence, no still row.
    fn baseline(
        method: Method,
        accounting: Accounting,
        image: &'i Image,
        spp: u32,
        seconds: f64,
    ) -> Self {
        MethodImage {
            method,
            accounting,
            factor: None,
            image,
            spp,
            seconds,
            sequence: None,
            still_seconds: None,
        }
    }
}

impl<'a> SceneRun<'a> {
    /// Loads the scene and its reference; at the scene's first seed, records the
    /// reference in `run` (and writes its PNG when asked).
    fn load(job: &'a SceneJob, opts: &'a TableOptions, run: &mut TableRun) -> Result<Self> {
        let name = job.scene.as_str();
        let (scene, reference) = load_with_reference(opts, name, &job.reference, &opts.params)?;
        let medium = scene
            .medium_index(None)
            .map_err(|e| anyhow!("{name}: {e}"))?;
        let factor = opts
            .factor
            .or(table1_row(name).map(|r| r.factor))
            .unwrap_or(0.95);
        let ref_rel = relative_to(&reference.path, &opts.out);
        let ref_var_mean = super::metrics::mean(&reference.var);
        let first_seed = !run.references.iter().any(|(n, ..)| n == name);
        if first_seed {
            let se = super::metrics::correction_se(&reference.var, reference.meta.chunks);
            run.references
                .push((name.to_string(), reference.meta.clone(), ref_var_mean, se));
        }
        let seed = opts.seed;
        let ctx = SceneRun {
            opts,
            name,
            tag: job.tag.as_str(),
            scene,
            reference,
            medium,
            factor,
            ref_rel,
            first_seed,
            seed,
            // The first seed's images keep the plain names (the report shows them).
            suffix: match first_seed {
                true => String::new(),
                false => format!("_seed{seed}"),
            },
            with_seen: RenderOptions {
                seen_emission: true,
                ..Default::default()
            },
        };
        let meta = &ctx.reference.meta;
        ctx.log(format!(
            "reference: Mitsuba {} {}, {} spp; mean variance {:.3e}",
            meta.mitsuba_version, meta.variant, meta.spp, ref_var_mean
        ));
        if opts.write_png && first_seed {
            image::write_png(
                &opts.out.join(format!("{}_reference.png", ctx.tag)),
                &ctx.reference.mean,
            )?;
        }
        Ok(ctx)
    }

    /// One line on stderr when the run is verbose.
    fn log(&self, msg: String) {
        if self.opts.verbose {
            eprintln!("[{}] {msg}", self.tag);
        }
    }

    /// The run skips `method`.
    fn skip(&self, method: Method) -> bool {
        self.opts.skip.contains(&method)
    }

    /// Seconds per spp of the scene rendered with `options` at a time budget (`None`
    /// at an spp budget).
    fn calibrate(&self, options: &RenderOptions) -> Option<f64> {
        match self.opts.budget {
            Budget::Seconds(b) => Some(seconds_per_spp(
                &self.scene,
                options,
                (b / 10.0).min(1.0),
                self.seed.wrapping_add(1_000_000),
            )),
            Budget::Spp(_) | Budget::PaperSpp => None,
        }
    }

    /// Writes `out`'s image (`tag_METHOD[_still][_seedN].exr`, and the PNG when asked),
    /// measures it against the reference and pushes its row (and its still row);
    /// returns the corrected MSE.
    fn push(&self, run: &mut TableRun, out: MethodImage) -> Result<f64> {
        let opts = self.opts;
        let mut name_of = match (out.method, out.factor) {
            (Method::RegularizedDifference, Some(f)) => {
                format!("{}_factor{}", out.method.as_str(), f[0])
            }
            _ => out.method.as_str().to_string(),
        };
        if out.accounting == Accounting::Still {
            name_of += "_still";
        }
        let file = opts
            .out
            .join(format!("{}_{name_of}{}.exr", self.tag, self.suffix));
        image::write_exr(&file, out.image)?;
        if opts.write_png {
            image::write_png(&file.with_extension("png"), out.image)?;
        }
        let (mse, mse_corrected) =
            mse_against(out.image, &self.reference.mean, &self.reference.var);
        let (spp, seconds) = (out.spp, out.seconds);
        self.log(format!(
            "{name_of}: {spp} spp, {seconds:.2} s, MSE {mse:.4e} (corrected {mse_corrected:.4e})"
        ));
        run.rows.push(Row {
            scene: self.name.to_string(),
            method: out.method,
            accounting: out.accounting,
            seed: self.seed,
            spp,
            seconds,
            mse,
            mse_corrected,
            image: relative_to(&file, &opts.out),
            reference: self.ref_rel.clone(),
            factor: out.factor,
            sequence_frames: out.sequence.map(|s| s.0),
            sequence_seconds: out.sequence.map(|s| s.1),
        });
        if let Some(seconds) = out.still_seconds {
            // The same image, every frame and the whole pilot charged.
            let mut row = run.rows.last().expect("just pushed").clone();
            row.accounting = Accounting::Still;
            row.seconds = seconds;
            run.rows.push(row);
        }
        Ok(mse_corrected)
    }
}

/// What the baselines measured that the still baselines reuse.
struct Baselines {
    /// Plain volpath's seconds per spp (`None` at an spp budget).
    volpath_per_spp: Option<f64>,
    /// OIDN's seconds on a 1-spp render (`None` when volpath_oidn does not run).
    oidn_seconds: Option<f64>,
}

/// Plain volpath at the target albedo, then through OIDN (its time, measured on a
/// 1-spp render, comes out of the budget).
fn run_baselines(ctx: &SceneRun, run: &mut TableRun) -> Result<Baselines> {
    let (opts, scene, seed) = (ctx.opts, &ctx.scene, ctx.seed);
    let volpath_per_spp = ctx.calibrate(&RenderOptions::default());
    if !ctx.skip(Method::Volpath) {
        let spp = match volpath_per_spp {
            Some(per_spp) => spp_for(budget_seconds(opts.budget), per_spp),
            None => budget_spp(opts.budget, ctx.name, false),
        };
        let r = render(scene, &scene.shot.with(spp, seed), &ctx.with_seen);
        let out = MethodImage::baseline(
            Method::Volpath,
            Accounting::Frame,
            &r.image,
            spp,
            r.stats.seconds,
        );
        ctx.push(run, out)?;
    }
    let oidn_seconds = match opts.oidn && !ctx.skip(Method::VolpathOidn) {
        true => {
            let shot = scene.shot.with(1, seed.wrapping_add(3_000_000));
            let probe = render(scene, &shot, &ctx.with_seen);
            let t = volpath_oidn(scene, &shot, &probe)?.1;
            run.oidn_seconds.push((ctx.name.to_string(), t));
            Some(t)
        }
        false => None,
    };
    if let Some(t_oidn) = oidn_seconds {
        let spp = match volpath_per_spp {
            Some(per_spp) => spp_for(budget_seconds(opts.budget) - t_oidn, per_spp),
            None => budget_spp(opts.budget, ctx.name, false),
        };
        let shot = scene.shot.with(spp, seed.wrapping_add(10));
        let r = render(scene, &shot, &ctx.with_seen);
        push_volpath_oidn(ctx, run, (&shot, &r), Accounting::Frame, spp)?;
    }
    Ok(Baselines {
        volpath_per_spp,
        oidn_seconds,
    })
}

/// The baselines at the time of the whole default sequence (`still_seconds`), when
/// the run asks for the still accounting: one render serves plain volpath and, with
/// OIDN's time charged on top (a few percent of it), volpath_oidn.
fn run_still_baselines(
    ctx: &SceneRun,
    run: &mut TableRun,
    baselines: &Baselines,
    still_seconds: Option<f64>,
) -> Result<()> {
    let (true, Some(total), Some(per_spp)) =
        (ctx.opts.still, still_seconds, baselines.volpath_per_spp)
    else {
        return Ok(());
    };
    let scene = &ctx.scene;
    let spp = spp_for(total - baselines.oidn_seconds.unwrap_or(0.0), per_spp);
    let shot = scene.shot.with(spp, ctx.seed.wrapping_add(20));
    let r = render(scene, &shot, &ctx.with_seen);
    if !ctx.skip(Method::Volpath) {
        let out = MethodImage::baseline(
            Method::Volpath,
            Accounting::Still,
            &r.image,
            spp,
            r.stats.seconds,
        );
        ctx.push(run, out)?;
    }
    if baselines.oidn_seconds.is_some() {
        push_volpath_oidn(ctx, run, (&shot, &r), Accounting::Still, spp)?;
    }
    run_still_regularized(ctx, run, baselines, total)
}

/// The default row in the still accounting: what `regularize --frames 1` makes of the
/// whole time (one plain frame through OIDN, `render --denoise oidn`'s image), charged
/// all it spends. With OIDN only: without it the one
/// frame is the bilateral pipeline, which no still baseline uses.
fn run_still_regularized(
    ctx: &SceneRun,
    run: &mut TableRun,
    baselines: &Baselines,
    total: f64,
) -> Result<()> {
    let (Some(t_oidn), Some(per_spp)) = (baselines.oidn_seconds, baselines.volpath_per_spp) else {
        return Ok(());
    };
    if ctx.skip(Method::Regularized) {
        return Ok(());
    }
    let options = regularize::Options {
        medium: ctx.medium,
        factor: 1.0,
        frames: 1,
        method: regularize::Method::Difference,
        oidn: regularize::OidnUse::Frames,
        ..Default::default()
    };
    let spp = spp_for(total - t_oidn, per_spp);
    let shot = ctx.scene.shot.with(spp, ctx.seed.wrapping_add(30));
    let r = regularize::regularize(&ctx.scene, &shot, &options).map_err(|e| anyhow!("{e}"))?;
    let t = &r.timings;
    let out = MethodImage::baseline(
        Method::Regularized,
        Accounting::Still,
        &r.predicted,
        spp,
        t.target_frame + t.frame_denoise,
    );
    ctx.push(run, out).map(|_| ())
}

/// The render `r` of `shot` (`spp` samples) through OIDN: volpath_oidn's row, charged
/// the render's time and OIDN's.
fn push_volpath_oidn(
    ctx: &SceneRun,
    run: &mut TableRun,
    (shot, r): (&Shot, &Rendered),
    accounting: Accounting,
    spp: u32,
) -> Result<()> {
    let (img, t) = volpath_oidn(&ctx.scene, shot, r)?;
    let out = MethodImage::baseline(
        Method::VolpathOidn,
        accounting,
        &img,
        spp,
        r.stats.seconds + t,
    );
    ctx.push(run, out).map(|_| ())
}

/// Mitsuba 3 on the same file: its row, or a note saying why it did not run.
fn run_mitsuba(ctx: &SceneRun, run: &mut TableRun) -> Result<()> {
    let (opts, name) = (ctx.opts, ctx.name);
    let Some(runner) = &opts.mitsuba else {
        run.notes
            .push(format!("{name}: Mitsuba 3 not run (--no-mitsuba)"));
        return Ok(());
    };
    let file = opts
        .out
        .join(format!("{}_mitsuba_volpath{}.exr", ctx.tag, ctx.suffix));
    let (spp, budget) = match opts.budget {
        Budget::Seconds(b) => (None, Some(b)),
        Budget::Spp(_) | Budget::PaperSpp => (Some(budget_spp(opts.budget, name, false)), None),
    };
    ctx.log("mitsuba_volpath: rendering".into());
    let request = MitsubaRequest {
        scene: &scene_file(opts, name),
        out: &file,
        defines: &opts.params,
        search: &opts.search,
        spp,
        budget,
        seed: ctx.seed.wrapping_add(300),
    };
    match runner.render(&request) {
        Ok(m) => {
            let img = image::read_exr(&file)?;
            if opts.write_png {
                image::write_png(&file.with_extension("png"), &img)?;
            }
            let reference = &ctx.reference;
            let (mse, mse_corrected) = mse_against(&img, &reference.mean, &reference.var);
            ctx.log(format!(
                "mitsuba_volpath ({}): {} spp, {:.2} s, MSE {mse:.4e} (corrected {mse_corrected:.4e})",
                m.variant, m.spp, m.seconds
            ));
            run.rows.push(Row {
                scene: name.to_string(),
                method: Method::MitsubaVolpath,
                accounting: Accounting::Frame,
                seed: ctx.seed,
                spp: m.spp,
                seconds: m.seconds,
                mse,
                mse_corrected,
                image: relative_to(&file, &opts.out),
                reference: ctx.ref_rel.clone(),
                factor: None,
                sequence_frames: None,
                sequence_seconds: None,
            });
        }
        Err(Unavailable::NotInstalled(why)) => run.notes.push(format!(
            "{name}: Mitsuba 3 not run: {why} (install it: python3 -m venv .venv && .venv/bin/pip install mitsuba numpy)"
        )),
        Err(Unavailable::Failed(e)) => {
            run.notes.push(format!("{name}: Mitsuba 3 failed: {e:#}"))
        }
    }
    Ok(())
}

/// `render --denoise oidn` on a render of `shot`: the image and the seconds it took.
fn volpath_oidn(scene: &Scene, shot: &Shot, r: &Rendered) -> Result<(Image, f64)> {
    let started = Instant::now();
    let img = crate::integrator::denoised::oidn(scene, shot, r, AuxUse::None, None)
        .map_err(|e| anyhow!("--denoise oidn: {e}"))?;
    Ok((img, started.elapsed().as_secs_f64()))
}

/// What `mediareg regularize` does by default for this sequence (`choices::options`):
/// with OIDN, the difference at `DEFAULT_FACTOR` with every frame denoised; without, the
/// factor from the pilot, the bilateral filter.
pub fn default_options(opts: &TableOptions, sequence: &regularize::Options) -> regularize::Options {
    let (auto_factor, factor) = match opts.oidn {
        true => (None, regularize::choices::DEFAULT_FACTOR),
        false => (Some(PilotSize::default()), 0.95),
    };
    regularize::Options {
        method: regularize::Method::Difference,
        auto_factor,
        factor,
        spatial: (!opts.oidn).then(BilateralParams::default),
        oidn: match opts.oidn {
            true => regularize::OidnUse::Frames,
            false => regularize::OidnUse::None,
        },
        pick: opts.oidn,
        ..sequence.clone()
    }
}

fn budget_seconds(b: Budget) -> f64 {
    match b {
        Budget::Seconds(s) => s,
        Budget::Spp(_) | Budget::PaperSpp => unreachable!("only called with a time budget"),
    }
}

/// The spp of `scene`'s baselines, or per frame of its sequences, at an spp budget.
fn budget_spp(b: Budget, scene: &str, sequence: bool) -> u32 {
    match (b, table1_row(scene)) {
        (Budget::Spp(n), _) => n,
        (Budget::PaperSpp, Some(row)) if sequence => row.ours_spp,
        (Budget::PaperSpp, Some(row)) => row.pt_spp,
        (Budget::PaperSpp, None) => unreachable!("run_table checks the scenes"),
        (Budget::Seconds(_), _) => unreachable!("only called with an spp budget"),
    }
}
