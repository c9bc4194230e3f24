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
use glam::Vec3;

use super::decompose::{self, Decomposition};
use super::metrics::mse_against;
use super::mitsuba::{MitsubaRunner, Unavailable};
use super::paper::table1_row;
pub use super::reference::{Reference, ReferenceMeta};
pub use super::row::{Accounting, Method, Row};
use crate::denoise::AuxUse;
use crate::image::Image;
use crate::integrator::volpath::Gradient;
use crate::integrator::{render, RenderOptions, Rendered};
use crate::load::build_scene;
use crate::regularize::pilot::{self, Pilot};
use crate::regularize::pipeline::PilotSize;
use crate::regularize::sequence::{image_centre_point, CameraPath};
use crate::regularize::spatial::BilateralParams;
use crate::regularize::{self, CBeta, Reproject};
use crate::scene::shot::Shot;
use crate::scene::{IntegratorKind, Scene};
use crate::{image, xml, BuildOverrides};

/// How much each method may spend.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Budget {
    /// Equal time: seconds per method (per frame for the regularized sequence).
    Seconds(f64),
    /// Equal samples per pixel (per frame for the regularized sequence).
    Spp(u32),
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

/// Renders one scene with every method and appends its rows to `run`.
pub fn run_scene(job: &SceneJob, opts: &TableOptions, run: &mut TableRun) -> Result<()> {
    let name = job.scene.as_str();
    let tag = job.tag.as_str();
    let log = |msg: String| {
        if opts.verbose {
            eprintln!("[{tag}] {msg}");
        }
    };
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
    log(format!(
        "reference: Mitsuba {} {}, {} spp; mean variance {:.3e}",
        reference.meta.mitsuba_version, reference.meta.variant, reference.meta.spp, ref_var_mean
    ));
    if opts.write_png && first_seed {
        image::write_png(
            &opts.out.join(format!("{tag}_reference.png")),
            &reference.mean,
        )?;
    }

    let seed = opts.seed;
    // The first seed's images keep the plain names (the report shows them).
    let suffix = match first_seed {
        true => String::new(),
        false => format!("_seed{seed}"),
    };
    let calibrate = |options: &RenderOptions| -> Option<f64> {
        match opts.budget {
            Budget::Seconds(b) => Some(seconds_per_spp(
                &scene,
                options,
                (b / 10.0).min(1.0),
                seed.wrapping_add(1_000_000),
            )),
            Budget::Spp(_) => None,
        }
    };
    let mut push = |method: Method,
                    accounting: Accounting,
                    factor: Option<[f32; 3]>,
                    img: &Image,
                    spp: u32,
                    seconds: f64,
                    sequence: Option<(usize, f64)>,
                    still_seconds: Option<f64>|
     -> Result<f64> {
        let mut name_of = match (method, factor) {
            (Method::RegularizedDifference, Some(f)) => {
                format!("{}_factor{}", method.as_str(), f[0])
            }
            _ => method.as_str().to_string(),
        };
        if accounting == Accounting::Still {
            name_of += "_still";
        }
        let file = opts.out.join(format!("{tag}_{name_of}{suffix}.exr"));
        image::write_exr(&file, img)?;
        if opts.write_png {
            image::write_png(&file.with_extension("png"), img)?;
        }
        let (mse, mse_corrected) = mse_against(img, &reference.mean, &reference.var);
        log(format!(
            "{name_of}: {spp} spp, {seconds:.2} s, MSE {mse:.4e} (corrected {mse_corrected:.4e})"
        ));
        run.rows.push(Row {
            scene: name.to_string(),
            method,
            accounting,
            seed,
            spp,
            seconds,
            mse,
            mse_corrected,
            image: relative_to(&file, &opts.out),
            reference: ref_rel.clone(),
            factor,
            sequence_frames: sequence.map(|s| s.0),
            sequence_seconds: sequence.map(|s| s.1),
        });
        if let Some(seconds) = still_seconds {
            // The same image, every frame and the whole pilot charged.
            let mut row = run.rows.last().expect("just pushed").clone();
            row.accounting = Accounting::Still;
            row.seconds = seconds;
            run.rows.push(row);
        }
        Ok(mse_corrected)
    };

    let skip = |m: Method| opts.skip.contains(&m);
    let with_seen = RenderOptions {
        seen_emission: true,
        ..Default::default()
    };
    let volpath_per_spp = calibrate(&RenderOptions::default());
    // Plain volpath at the target albedo, then through OIDN (its time, measured on a
    // 1-spp render, comes out of the budget).
    if !skip(Method::Volpath) {
        let spp = match volpath_per_spp {
            Some(per_spp) => spp_for(budget_seconds(opts.budget), per_spp),
            None => budget_spp(opts.budget),
        };
        let r = render(&scene, &scene.shot.with(spp, seed), &with_seen);
        push(
            Method::Volpath,
            Accounting::Frame,
            None,
            &r.image,
            spp,
            r.stats.seconds,
            None,
            None,
        )?;
    }
    let oidn_seconds = match opts.oidn && !skip(Method::VolpathOidn) {
        true => {
            let shot = scene.shot.with(1, seed.wrapping_add(3_000_000));
            let probe = render(&scene, &shot, &with_seen);
            Some(volpath_oidn(&scene, &shot, &probe)?.1)
        }
        false => None,
    };
    if let Some(t_oidn) = oidn_seconds {
        let spp = match volpath_per_spp {
            Some(per_spp) => spp_for(budget_seconds(opts.budget) - t_oidn, per_spp),
            None => budget_spp(opts.budget),
        };
        let shot = scene.shot.with(spp, seed.wrapping_add(10));
        let r = render(&scene, &shot, &with_seen);
        let (img, t) = volpath_oidn(&scene, &shot, &r)?;
        push(
            Method::VolpathOidn,
            Accounting::Frame,
            None,
            &img,
            spp,
            r.stats.seconds + t,
            None,
            None,
        )?;
    }

    // The sequences: the paper's predictor, the default, the control.
    let path = orbit_about_centre(opts, &scene).unwrap_or_else(|| {
        run.notes.push(format!(
            "{name}: the image centre sees no surface, so the regularized sequence keeps the camera still (frames differ only in noise)"
        ));
        CameraPath::Static
    });
    let temporal = sequence_options(opts, medium, factor, path);
    let spatial = regularize::Options {
        frames: 1,
        path: CameraPath::Static,
        spatial: Some(BilateralParams::default()),
        ..temporal.clone()
    };
    let auto = default_options(opts, &temporal);
    let control = regularize::Options {
        method: regularize::Method::Radiance,
        auto_factor: None,
        ..auto.clone()
    };
    // Its frames render at the source albedo (shorter paths): calibrate there.
    let target_albedo = scene.media[medium as usize].albedo;
    let at_source = |factor: f32| {
        RenderOptions {
            gradient: Gradient::Albedo(medium),
            ..Default::default()
        }
        .with_albedo(&scene, medium, target_albedo * factor)
    };
    let per_spp_gradient = calibrate(&at_source(factor));
    let per_spp_default = match auto.auto_factor {
        Some(_) => per_spp_gradient,
        None => calibrate(&at_source(auto.factor)),
    };
    let fixed: Vec<regularize::Options> = opts
        .difference_factors
        .iter()
        .map(|&f| regularize::Options {
            factor: f,
            auto_factor: None,
            ..auto.clone()
        })
        .collect();
    let runs = [
        (
            Method::RegularizedPaper,
            &temporal,
            100u64,
            per_spp_gradient,
        ),
        (
            Method::RegularizedSpatial,
            &spatial,
            200u64,
            per_spp_gradient,
        ),
        (Method::Regularized, &auto, 300u64, per_spp_default),
        (Method::VolpathFiltered, &control, 500u64, volpath_per_spp),
    ]
    .into_iter()
    .chain(fixed.iter().enumerate().map(|(i, o)| {
        (
            Method::RegularizedDifference,
            o,
            400 + i as u64,
            per_spp_gradient,
        )
    }))
    .filter(|(method, ..)| !skip(*method));
    let mut still_seconds = None;
    for (method, ropts, seed_offset, per_spp) in runs {
        let spp = match per_spp {
            Some(per_spp) => {
                // The denoising and prediction cost comes out of the frame's budget:
                // measured on a 1-spp run of the same pipeline.
                let known = run
                    .overheads
                    .iter()
                    .find(|(n, m, _)| n == name && *m == method)
                    .map(|o| o.2);
                let overhead = match known {
                    Some(o) => o,
                    None => {
                        let probe_shot = scene.shot.with(1, seed.wrapping_add(2_000_000));
                        let probe = regularize::regularize(&scene, &probe_shot, ropts)
                            .map_err(|e| anyhow!("{e}"))?;
                        let o = probe.timings.denoise_and_predict
                            + probe.timings.frame_denoise
                            + probe.timings.pilot / probe.frames_rendered as f64;
                        run.overheads.push((name.to_string(), method, o));
                        o
                    }
                };
                spp_for(budget_seconds(opts.budget) - overhead, per_spp)
            }
            None => budget_spp(opts.budget),
        };
        let shot = scene.shot.with(spp, seed.wrapping_add(seed_offset));
        let started = Instant::now();
        let r = regularize::regularize(&scene, &shot, ropts).map_err(|e| anyhow!("{e}"))?;
        let sequence_seconds = started.elapsed().as_secs_f64();
        if let Some(p) = &r.pilot {
            run.notes.push(format!(
                "{name} seed {seed} {}: the pilot chose the factors {:?} (R, G, B) in {:.1} s",
                method.as_str(),
                p.factor,
                p.seconds
            ));
        }
        if r.fallbacks > 0 {
            run.notes.push(format!(
                "{name} seed {seed} {}: {} channel values could not be predicted and keep the source radiance",
                method.as_str(),
                r.fallbacks
            ));
        }
        // One frame of the sequence, and the pilot's share of it (a pilot serves the
        // whole sequence).
        let seconds = r.timings.target_frame
            + r.timings.frame_denoise
            + r.timings.denoise_and_predict
            + r.timings.pilot / r.frames_rendered as f64;
        let is_sequence = method != Method::RegularizedSpatial;
        let sequence = is_sequence.then_some((r.frames_rendered, sequence_seconds));
        let factor = (method != Method::VolpathFiltered).then(|| {
            let (source, target) = (r.albedos.source.to_array(), r.albedos.target.to_array());
            [0, 1, 2].map(|c| match target[c] > 0.0 {
                true => source[c] / target[c],
                false => 1.0,
            })
        });
        let mse_corrected = push(
            method,
            Accounting::Frame,
            factor,
            &r.predicted,
            spp,
            seconds,
            sequence,
            (opts.still && is_sequence).then_some(sequence_seconds),
        )?;
        if method == Method::Regularized {
            still_seconds = Some(sequence_seconds);
        }
        if let (Method::Regularized, Some(pilot), true) = (method, &r.pilot, first_seed) {
            let decomposition =
                decompose_scene(&scene, name, medium, ropts, pilot, spp, mse_corrected);
            run.decomposition.push(decomposition);
        }
    }

    // The baselines at the time of the whole default sequence: one render serves plain
    // volpath and, with OIDN's time charged on top (a few percent of it), volpath_oidn.
    if let (true, Some(total), Some(per_spp)) = (opts.still, still_seconds, volpath_per_spp) {
        let spp = spp_for(total - oidn_seconds.unwrap_or(0.0), per_spp);
        let shot = scene.shot.with(spp, seed.wrapping_add(20));
        let r = render(&scene, &shot, &with_seen);
        if !skip(Method::Volpath) {
            push(
                Method::Volpath,
                Accounting::Still,
                None,
                &r.image,
                spp,
                r.stats.seconds,
                None,
                None,
            )?;
        }
        if oidn_seconds.is_some() {
            let (img, t) = volpath_oidn(&scene, &shot, &r)?;
            push(
                Method::VolpathOidn,
                Accounting::Still,
                None,
                &img,
                spp,
                r.stats.seconds + t,
                None,
                None,
            )?;
        }
    }

    // Mitsuba 3 on the same file.
    match &opts.mitsuba {
        None => run
            .notes
            .push(format!("{name}: Mitsuba 3 not run (--no-mitsuba)")),
        Some(runner) => {
            let file = opts.out.join(format!("{tag}_mitsuba_volpath{suffix}.exr"));
            let (spp, budget) = match opts.budget {
                Budget::Seconds(b) => (None, Some(b)),
                Budget::Spp(n) => (Some(n), None),
            };
            log("mitsuba_volpath: rendering".into());
            match runner.render(
                &scene_file(opts, name),
                &file,
                &opts.params,
                &opts.search,
                spp,
                budget,
                seed.wrapping_add(300),
            ) {
                Ok(m) => {
                    let img = image::read_exr(&file)?;
                    if opts.write_png {
                        image::write_png(&file.with_extension("png"), &img)?;
                    }
                    let (mse, mse_corrected) = mse_against(&img, &reference.mean, &reference.var);
                    log(format!(
                        "mitsuba_volpath ({}): {} spp, {:.2} s, MSE {mse:.4e} (corrected {mse_corrected:.4e})",
                        m.variant, m.spp, m.seconds
                    ));
                    run.rows.push(Row {
                        scene: name.to_string(),
                        method: Method::MitsubaVolpath,
                        accounting: Accounting::Frame,
                        seed,
                        spp: m.spp,
                        seconds: m.seconds,
                        mse,
                        mse_corrected,
                        image: relative_to(&file, &opts.out),
                        reference: ref_rel.clone(),
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
        }
    }
    Ok(())
}

/// Where the automatic row's gain goes (`decompose`): the pilot's terms, and the time
/// per spp and mean path vertices measured at the target and the chosen albedo.
fn decompose_scene(
    scene: &Scene,
    name: &str,
    medium: u32,
    ropts: &regularize::Options,
    pilot: &Pilot,
    spp: u32,
    mse_corrected: f64,
) -> Decomposition {
    let target = scene.media[medium as usize].albedo;
    let source = target * Vec3::from(pilot.factor);
    let shot = &scene.shot;
    let (w, h) = shot.film.crop_size;
    let n_eff = pilot::effective_frames(ropts.frames, ropts.w_a);
    let terms = decompose::pilot_terms(pilot, w * h, n_eff);
    let seed = shot.seed.wrapping_add(6_000_000);
    let difference = RenderOptions {
        gradient: Gradient::Difference { medium, target },
        ..Default::default()
    }
    .with_albedo(scene, medium, source);
    let predicted_variance = (terms.var_source + terms.var_difference_denoised) / spp as f64;
    Decomposition {
        scene: name.to_string(),
        factor: pilot.factor,
        seconds_per_spp_target: seconds_per_spp(scene, &RenderOptions::default(), 1.0, seed),
        seconds_per_spp_source: seconds_per_spp(scene, &difference, 1.0, seed),
        vertices_target: decompose::mean_vertices(scene, shot, medium, target, 4),
        vertices_source: decompose::mean_vertices(scene, shot, medium, source, 4),
        var_target: terms.var_target,
        var_source: terms.var_source,
        var_difference: terms.var_difference,
        var_difference_denoised: terms.var_difference_denoised,
        spp,
        predicted_variance,
        mse_corrected,
        bias2: mse_corrected - predicted_variance,
    }
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
        ..sequence.clone()
    }
}

fn budget_seconds(b: Budget) -> f64 {
    match b {
        Budget::Seconds(s) => s,
        Budget::Spp(_) => unreachable!("only called with a time budget"),
    }
}

fn budget_spp(b: Budget) -> u32 {
    match b {
        Budget::Spp(n) => n,
        Budget::Seconds(_) => unreachable!("only called with an spp budget"),
    }
}
