//! The paper's figures on this machine, each a PNG plot with its numbers beside it
//! (`figN.json`: every row with its image, as `table1.json`):
//!
//! * Fig. 6: σ_t ∈ {5, 10, 15, 20, 50} on the Bunny, regularized against equal-time
//!   volpath (corrected MSE against σ_t);
//! * Fig. 7: the three prediction functions (Eq. 11–12, linear, log-linear) from one
//!   source render and denoised gradient of the Cube, along a row of pixels, against the
//!   reference;
//! * Fig. 9: MSE against the source factor (0.1–0.97) on Lucy;
//! * Fig. 11: MSE against seconds on the Cube (where the biased method stops winning);
//! * Fig. 12: the same at albedo 0.5, the paper's failure case;
//! * speed: MSE against seconds, log-log, for every scene and method.
//!
//! The sweeps render at reduced size (`-D res=…`) against references made for exactly
//! that size (`reference/figures/`); every point is a `table::run_scene`.

use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use serde::Serialize;

use super::metrics::mse_against;
use super::plot::{line_plot, Axes, Series};
use super::table::{
    load_with_reference, orbit_about_centre, run_scene, sequence_options, Budget, Method, Row,
    SceneJob, TableOptions, TableRun,
};
use crate::image;
use crate::image::Image;
use crate::regularize;
use crate::regularize::predict::Predictor;

/// The figures that exist, in the order they are made.
pub const FIGURES: [&str; 6] = ["fig7", "fig11", "fig12", "fig6", "fig9", "speed"];

#[derive(Clone, Debug)]
pub struct FigureOptions {
    /// Scene folder, search path, sequence settings, Mitsuba, seed, output folder;
    /// `budget`, `params` and `scenes` are set per figure.
    pub base: TableOptions,
    /// References of the reduced-size sweeps.
    pub figure_reference_dir: PathBuf,
    /// Resolution of the sweeps (`-D res=`).
    pub res: u32,
    /// Seconds per method for the sweeps over time (Fig. 11, 12, speed).
    pub budgets: Vec<f64>,
    /// Seconds per method for the sweeps over a parameter (Fig. 6, 9).
    pub budget: f64,
    /// Samples per pixel per frame of Fig. 7's sequence.
    pub fig7_spp: u32,
    pub only: Vec<String>,
}

#[derive(Serialize)]
struct Point {
    x: f64,
    rows: Vec<Row>,
}

#[derive(Serialize)]
struct FigureData {
    figure: String,
    x: String,
    points: Vec<Point>,
    notes: Vec<String>,
}

fn write_json(path: &Path, data: &impl Serialize) -> Result<()> {
    let text = serde_json::to_string_pretty(data)? + "\n";
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}

pub fn make_figures(opts: &FigureOptions) -> Result<Vec<PathBuf>> {
    for f in &opts.only {
        if !FIGURES.contains(&f.as_str()) {
            bail!(
                "--only {f}: no such figure (there are {})",
                FIGURES.join(", ")
            );
        }
    }
    std::fs::create_dir_all(&opts.base.out)
        .with_context(|| format!("cannot create {}", opts.base.out.display()))?;
    let wanted = |f: &str| opts.only.is_empty() || opts.only.iter().any(|o| o == f);
    let mut written = Vec::new();
    if wanted("fig7") {
        written.push(fig7(opts)?);
    }
    if wanted("fig11") {
        written.push(time_sweep(
            opts,
            "fig11",
            "cube",
            "cube",
            &[],
            "Fig. 11: Cube, albedo 0.95",
        )?);
    }
    if wanted("fig12") {
        written.push(time_sweep(
            opts,
            "fig12",
            "cube",
            "cube_albedo0.5",
            &[("albedo", "0.5")],
            "Fig. 12: Cube, albedo 0.5 (the failure case)",
        )?);
    }
    if wanted("fig6") {
        written.push(fig6(opts)?);
    }
    if wanted("fig9") {
        written.push(fig9(opts)?);
    }
    if wanted("speed") {
        for scene in ["bunny", "candle", "lucy"] {
            let title = format!("Speed against error: {scene}");
            written.push(time_sweep(
                opts,
                &format!("speed_{scene}"),
                scene,
                scene,
                &[],
                &title,
            )?);
        }
    }
    Ok(written)
}

/// The reference name of a reduced-size sweep: `SCENE_resN` plus the parameters.
fn reference_name(reference: &str, res: u32) -> String {
    match reference.split_once('_') {
        Some((scene, rest)) => format!("{scene}_res{res}_{rest}"),
        None => format!("{reference}_res{res}"),
    }
}

/// One run of `scene` against a figure reference, with extra `-D` parameters.
/// What a sweep point renders besides the table's rows.
#[derive(Default)]
struct Extra {
    /// `regularized_difference` rows at these fixed factors.
    difference_factors: Vec<f32>,
    skip: Vec<Method>,
}

fn sweep_point(
    opts: &FigureOptions,
    job: SceneJob,
    params: &[(&str, &str)],
    budget: f64,
    factor: Option<f32>,
    mitsuba: bool,
    extra: Extra,
) -> Result<TableRun> {
    let mut params: Vec<(String, String)> = params
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    params.push(("res".into(), opts.res.to_string()));
    params.sort();
    let table = TableOptions {
        scenes: vec![job.scene.clone()],
        reference_dir: opts.figure_reference_dir.clone(),
        params,
        budget: Budget::Seconds(budget),
        factor: factor.or(opts.base.factor),
        mitsuba: if mitsuba {
            opts.base.mitsuba.clone()
        } else {
            None
        },
        out: opts.base.out.join("images"),
        difference_factors: extra.difference_factors,
        // The figures plot the paper's comparisons: one seed, one accounting, without
        // the table's denoised baselines and control.
        skip: extra
            .skip
            .into_iter()
            .chain([Method::VolpathOidn, Method::VolpathFiltered])
            .collect(),
        seeds: 1,
        still: false,
        ..opts.base.clone()
    };
    std::fs::create_dir_all(&table.out)?;
    let mut run = TableRun::default();
    run_scene(&job, &table, &mut run)?;
    // Image paths relative to the figure's JSON, one folder up.
    for r in &mut run.rows {
        r.image = format!("images/{}", r.image);
        r.reference = format!("images/{}", r.reference);
    }
    Ok(run)
}

fn mse_series(points: &[Point], method: Method) -> Vec<(f64, f64)> {
    points
        .iter()
        .filter_map(|p| {
            p.rows
                .iter()
                .find(|r| r.method == method)
                .map(|r| (p.x, r.mse_corrected))
        })
        .collect()
}

const METHODS: [(Method, &str); 5] = [
    (Method::Regularized, "regularized (difference, auto factor)"),
    (Method::RegularizedPaper, "regularized (paper, temporal)"),
    (Method::RegularizedSpatial, "regularized (paper, spatial)"),
    (Method::Volpath, "volpath (mediareg)"),
    (Method::MitsubaVolpath, "volpath (Mitsuba 3)"),
];

/// Draws a figure's plot and writes its numbers: `figure`.png and `figure`.json.
fn finish(
    opts: &FigureOptions,
    figure: &str,
    x: &str,
    axes: Axes,
    series: &[Series],
    points: Vec<Point>,
    notes: Vec<String>,
) -> Result<PathBuf> {
    let png = opts.base.out.join(format!("{figure}.png"));
    line_plot(&png, &axes, series)?;
    write_json(
        &opts.base.out.join(format!("{figure}.json")),
        &FigureData {
            figure: figure.into(),
            x: x.into(),
            points,
            notes,
        },
    )?;
    Ok(png)
}

const MSE_LABEL: &str = "MSE (reference variance subtracted)";

/// MSE against seconds, log-log: every method at each budget (Fig. 11, 12, speed).
fn time_sweep(
    opts: &FigureOptions,
    figure: &str,
    scene: &str,
    reference: &str,
    params: &[(&str, &str)],
    title: &str,
) -> Result<PathBuf> {
    let mut points = Vec::new();
    let mut notes = Vec::new();
    for &b in &opts.budgets {
        let job = SceneJob {
            scene: scene.into(),
            reference: reference_name(reference, opts.res),
            tag: format!("{figure}_{b}s"),
        };
        let run = sweep_point(opts, job, params, b, None, true, Extra::default())?;
        notes.extend(run.notes);
        points.push(Point {
            x: b,
            rows: run.rows,
        });
    }
    // x: the seconds each method really took.
    let series: Vec<Series> = METHODS
        .iter()
        .map(|(m, name)| {
            let pts = points
                .iter()
                .filter_map(|p| p.rows.iter().find(|r| r.method == *m))
                .map(|r| (r.seconds, r.mse_corrected))
                .collect();
            Series::new(name, pts)
        })
        .filter(|s| !s.points.is_empty())
        .collect();
    finish(
        opts,
        figure,
        "budget_seconds",
        Axes {
            title: format!("{title} ({0}x{0})", opts.res),
            x_label: "seconds (one frame for the sequence)".into(),
            y_label: MSE_LABEL.into(),
            log_x: true,
            log_y: true,
        },
        &series,
        points,
        notes,
    )
}

/// The fixed factors the σ_t and factor sweeps render the difference predictor at, to
/// compare the pilot's choice with the best one the reference picks.
const FACTOR_GRID: [f32; 4] = [0.7, 0.5, 0.3, 0.2];

/// The lowest corrected MSE of the fixed-factor difference rows of `rows`, with its factor.
fn best_fixed<'a>(rows: impl IntoIterator<Item = &'a Row>) -> Option<(f32, f64)> {
    rows.into_iter()
        .filter(|r| r.method == Method::RegularizedDifference)
        .map(|r| (r.factor.map_or(f32::NAN, |f| f[0]), r.mse_corrected))
        .min_by(|a, b| a.1.total_cmp(&b.1))
}

/// The note comparing the automatic row with the best fixed factor `(factor, MSE)`.
fn auto_against_best(auto: &Row, (factor, mse): (f32, f64)) -> String {
    format!(
        "auto factor {:?} MSE {:.3e}; best fixed factor {factor} MSE {mse:.3e}; auto / best {:.2}",
        auto.factor.unwrap_or([f32::NAN; 3]),
        auto.mse_corrected,
        auto.mse_corrected / mse
    )
}

/// Fig. 6: σ_t sweep on the Bunny at one budget, with the pilot's factor against the
/// best of a grid of fixed factors chosen with the reference.
fn fig6(opts: &FigureOptions) -> Result<PathBuf> {
    let mut points = Vec::new();
    let mut notes = Vec::new();
    let mut best = Vec::new();
    for sigma_t in [5.0, 10.0, 15.0, 20.0, 50.0] {
        let s = format!("{sigma_t}");
        let job = SceneJob {
            scene: "bunny".into(),
            reference: reference_name(&format!("bunny_sigma_t{s}"), opts.res),
            tag: format!("fig6_sigma_t{s}"),
        };
        let extra = Extra {
            difference_factors: FACTOR_GRID.to_vec(),
            skip: Vec::new(),
        };
        let run = sweep_point(
            opts,
            job,
            &[("sigma_t", &s)],
            opts.budget,
            None,
            false,
            extra,
        )?;
        notes.extend(run.notes);
        if let (Some(best_row), Some(auto)) = (
            best_fixed(&run.rows),
            run.rows.iter().find(|r| r.method == Method::Regularized),
        ) {
            notes.push(format!(
                "sigma_t {s}: {}",
                auto_against_best(auto, best_row)
            ));
            best.push((sigma_t, best_row.1));
        }
        points.push(Point {
            x: sigma_t,
            rows: run.rows,
        });
    }
    let series = vec![
        Series::new(
            "regularized (difference, auto factor)",
            mse_series(&points, Method::Regularized),
        ),
        Series::dashed(
            "regularized (difference, best fixed factor: chosen with the reference)",
            best,
        ),
        Series::new(
            "regularized (paper, temporal)",
            mse_series(&points, Method::RegularizedPaper),
        ),
        Series::new(
            "regularized (paper, spatial)",
            mse_series(&points, Method::RegularizedSpatial),
        ),
        Series::new("volpath, equal time", mse_series(&points, Method::Volpath)),
    ];
    finish(
        opts,
        "fig6",
        "sigma_t",
        Axes {
            title: format!(
                "Fig. 6: Bunny, sigma_t sweep, {} s per method ({1}x{1})",
                opts.budget, opts.res
            ),
            x_label: "sigma_t".into(),
            y_label: MSE_LABEL.into(),
            log_x: true,
            log_y: true,
        },
        &series,
        points,
        notes,
    )
}

/// Fig. 9: source-factor sweep on Lucy at one budget: the paper's predictor and the
/// difference at each factor; plain volpath (the mean of its runs) and the pilot's
/// choice (one run) as lines.
fn fig9(opts: &FigureOptions) -> Result<PathBuf> {
    let mut points = Vec::new();
    let mut notes = Vec::new();
    let job = |tag: String| SceneJob {
        scene: "lucy".into(),
        reference: reference_name("lucy", opts.res),
        tag,
    };
    for factor in [0.1f64, 0.2, 0.3, 0.5, 0.7, 0.8, 0.9, 0.93, 0.95, 0.97] {
        let extra = Extra {
            difference_factors: vec![factor as f32],
            skip: vec![Method::Regularized],
        };
        let tag = format!("fig9_factor{factor}");
        let run = sweep_point(
            opts,
            job(tag),
            &[],
            opts.budget,
            Some(factor as f32),
            false,
            extra,
        )?;
        notes.extend(run.notes);
        points.push(Point {
            x: factor,
            rows: run.rows,
        });
    }
    let only_auto = Extra {
        difference_factors: Vec::new(),
        skip: vec![
            Method::Volpath,
            Method::RegularizedPaper,
            Method::RegularizedSpatial,
        ],
    };
    let auto_run = sweep_point(
        opts,
        job("fig9_auto".into()),
        &[],
        opts.budget,
        None,
        false,
        only_auto,
    )?;
    notes.extend(auto_run.notes);
    let auto = auto_run
        .rows
        .iter()
        .find(|r| r.method == Method::Regularized)
        .ok_or_else(|| anyhow!("fig9: the automatic row did not run"))?;
    if let Some(best_row) = best_fixed(points.iter().flat_map(|p| &p.rows)) {
        notes.push(auto_against_best(auto, best_row));
    }
    let volpath = mse_series(&points, Method::Volpath);
    let mean_volpath = volpath.iter().map(|p| p.1).sum::<f64>() / volpath.len().max(1) as f64;
    let (x0, x1) = (points[0].x, points[points.len() - 1].x);
    let series = vec![
        Series::new(
            "regularized (difference)",
            mse_series(&points, Method::RegularizedDifference),
        ),
        Series::dashed(
            "regularized (difference, auto factor: one run)",
            vec![(x0, auto.mse_corrected), (x1, auto.mse_corrected)],
        ),
        Series::new(
            "regularized (paper, temporal)",
            mse_series(&points, Method::RegularizedPaper),
        ),
        Series::new(
            "regularized (paper, spatial)",
            mse_series(&points, Method::RegularizedSpatial),
        ),
        Series::dashed(
            "volpath, equal time (mean of the runs)",
            vec![(x0, mean_volpath), (x1, mean_volpath)],
        ),
    ];
    points.push(Point {
        x: f64::NAN,
        rows: auto_run.rows,
    });
    finish(
        opts,
        "fig9",
        "factor",
        Axes {
            title: format!(
                "Fig. 9: Lucy, source factor sweep, {} s per method ({1}x{1})",
                opts.budget, opts.res
            ),
            x_label: "source factor (alpha_s / alpha_t)".into(),
            y_label: MSE_LABEL.into(),
            log_x: false,
            log_y: true,
        },
        &series,
        points,
        notes,
    )
}

#[derive(Serialize)]
struct Fig7Data {
    figure: &'static str,
    row: usize,
    spp_per_frame: u32,
    frames: usize,
    c_beta: f32,
    /// Whole-image MSE (reference variance subtracted) of each prediction.
    mse_corrected: Vec<(String, f64)>,
    /// Per pixel of the row: x, then the channel mean of each curve, in `curves` order.
    curves: Vec<String>,
    values: Vec<Vec<f64>>,
}

/// Fig. 7: one source render and denoised gradient of the Cube (full size, its
/// table reference), predicted three ways.
fn fig7(opts: &FigureOptions) -> Result<PathBuf> {
    let base = &opts.base;
    let (scene, reference) = load_with_reference(base, "cube", "cube", &[])?;
    let medium = scene.medium_index(None).map_err(|e| anyhow!("{e}"))?;
    let shot = scene.shot.with(opts.fig7_spp, base.seed.wrapping_add(700));
    let path = orbit_about_centre(base, &scene).context("Fig. 7: the image centre sees nothing")?;
    let ropts = sequence_options(base, medium, base.factor.unwrap_or(0.95), path);
    let r = regularize::regularize(&scene, &shot, &ropts).map_err(|e| anyhow!("{e}"))?;
    let (w, h) = (r.source.width, r.source.height);
    let predictors = [
        (
            "paper (Eq. 11-12)",
            Predictor::Paper {
                c_beta: base.c_beta,
            },
        ),
        ("linear", Predictor::Linear),
        ("log-linear", Predictor::LogLinear),
    ];
    let mut images: Vec<(String, Image)> = vec![
        ("reference".into(), reference.mean.clone()),
        ("source R_s".into(), r.source.clone()),
    ];
    for (name, p) in &predictors {
        let (pixels, _) = p.predict(&r.albedos, &r.source.pixels, &r.gradient.pixels);
        images.push((
            name.to_string(),
            Image {
                width: w,
                height: h,
                pixels,
            },
        ));
    }
    let row = h / 2;
    let channel_mean = |img: &Image, x: usize| {
        let p = img.pixels[row * w + x];
        (p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0
    };
    // Log-linear explodes where R_s is near 0 (README): clip the curves at 3× the
    // reference's largest value on the row, so the others stay readable.
    let clip = 3.0
        * (0..w)
            .map(|x| channel_mean(&reference.mean, x))
            .fold(0.0, f64::max);
    let series: Vec<Series> = images
        .iter()
        .map(|(name, img)| {
            let pts = (0..w)
                .map(|x| (x as f64, channel_mean(img, x).min(clip)))
                .collect();
            if name == "reference" {
                Series::dashed(name, pts)
            } else {
                Series::new(name, pts)
            }
        })
        .collect();
    let png = base.out.join("fig7.png");
    line_plot(
        &png,
        &Axes {
            title: format!(
                "Fig. 7: Cube, row {row}: predictions from alpha_s = {} alpha_t, {} spp x {} frames",
                ropts.factor, opts.fig7_spp, base.frames
            ),
            x_label: "pixel x".into(),
            y_label: "radiance (channel mean; clipped at 3x the reference's max)".into(),
            log_x: false,
            log_y: false,
        },
        &series,
    )?;
    for (name, img) in &images[1..] {
        let file = base.out.join(format!(
            "fig7_{}.exr",
            name.split([' ', '('])
                .next()
                .unwrap_or(name)
                .replace('-', "")
        ));
        image::write_exr(&file, img)?;
    }
    let data = Fig7Data {
        figure: "fig7",
        row,
        spp_per_frame: opts.fig7_spp,
        frames: base.frames,
        c_beta: base.c_beta,
        mse_corrected: images[1..]
            .iter()
            .map(|(name, img)| {
                (
                    name.clone(),
                    mse_against(img, &reference.mean, &reference.var).1,
                )
            })
            .collect(),
        curves: images.iter().map(|(n, _)| n.clone()).collect(),
        values: (0..w)
            .map(|x| {
                std::iter::once(x as f64)
                    .chain(images.iter().map(|(_, img)| channel_mean(img, x)))
                    .collect()
            })
            .collect(),
    };
    write_json(&base.out.join("fig7.json"), &data)?;
    Ok(png)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sweep_references_are_named_by_scene_size_and_parameters() {
        assert_eq!(reference_name("cube", 128), "cube_res128");
        assert_eq!(
            reference_name("cube_albedo0.5", 128),
            "cube_res128_albedo0.5"
        );
        assert_eq!(
            reference_name("bunny_sigma_t50", 64),
            "bunny_res64_sigma_t50"
        );
    }
}
