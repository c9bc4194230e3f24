//! `mediareg sweep`: Table 1's methods across budgets (issue 56). Each scene, budget and
//! seed is one `table::run_scene` at the figures' reduced size against that size's
//! reference (`reference/figures/`), both accountings; each (scene, budget) is
//! summarized over its seeds as `table1.json` is (`summary`: the ratio to the best
//! baseline with its 95% interval). The budgets are per frame, and chosen so that OIDN's
//! share of a frame (its seconds on one image over the budget, `oidn_share`) runs from
//! about a quarter down to a few percent: where the method's fixed costs decide and
//! where the samples do.
//!
//! Writes `sweep.json` (rows {scene, method, accounting, budget, seeds, spp, seconds,
//! mse_corrected, ratio_to_best, best}) and per scene and accounting a log–log plot of
//! corrected MSE against seconds with each method's 95% band over seeds. The images go
//! to `OUT/sweep_images/` (not kept in git).

use std::path::{Path, PathBuf};

use anyhow::Result;
use serde::Serialize;

use super::plot::{line_plot, Axes, Series};
use super::row::{Accounting, Method, Row};
use super::summary::summarize;
use super::table::{run_scene, seed_of, Budget, SceneJob, TableOptions, TableRun};

#[derive(Clone, Debug)]
pub struct SweepOptions {
    /// Scenes, seeds, threads, OIDN and the sequence's settings; the budget, the
    /// parameters, the references and the output folder are set per point.
    pub base: TableOptions,
    /// The references of the reduced size (`NAME_resRES.exr`).
    pub reference_dir: PathBuf,
    pub res: u32,
    /// Seconds per method and frame.
    pub budgets: Vec<f64>,
}

/// One method at one budget, over the seeds.
#[derive(Serialize, Clone, Debug)]
pub struct SweepRow {
    pub scene: String,
    pub method: Method,
    pub accounting: Accounting,
    pub budget: f64,
    pub seeds: Vec<u64>,
    pub spp: f64,
    pub seconds: f64,
    pub mse_corrected: f64,
    pub mse_corrected_se: f64,
    /// `[mean, ci_low, ci_high]` over the best baseline's corrected MSE.
    pub ratio_to_best: Option<[f64; 3]>,
    pub best: Option<Method>,
}

/// OIDN's seconds on one image of the scene, and its share of each budget.
#[derive(Serialize, Clone, Debug)]
pub struct OidnShare {
    pub scene: String,
    pub oidn_seconds: f64,
    /// (budget, share).
    pub shares: Vec<(f64, f64)>,
}

#[derive(Serialize)]
pub struct SweepData {
    pub res: u32,
    pub threads: Option<usize>,
    pub budgets: Vec<f64>,
    pub seeds: usize,
    pub oidn: Vec<OidnShare>,
    pub rows: Vec<SweepRow>,
    /// Per seed, as `table1_seeds.json`.
    pub seed_rows: Vec<(f64, Row)>,
    pub notes: Vec<String>,
    pub seconds: f64,
}

/// The methods the sweep never renders (the spatial variant, the fixed factors and
/// Mitsuba 3 are the figures' business); `--methods` and `--no-still` narrow it further.
const SKIP: [Method; 3] = [
    Method::RegularizedSpatial,
    Method::RegularizedDifference,
    Method::MitsubaVolpath,
];

/// Runs the sweep and writes `sweep.json` (after every scene and budget, so that a long
/// run leaves what it measured) and the plots; returns the JSON's path.
pub fn run_sweep(opts: &SweepOptions, threads: Option<usize>) -> Result<PathBuf> {
    let started = std::time::Instant::now();
    let out = &opts.base.out;
    let images = out.join("sweep_images");
    std::fs::create_dir_all(&images)?;
    let mut params = opts.base.params.clone();
    params.push(("res".into(), opts.res.to_string()));
    params.sort();
    let mut data = SweepData {
        res: opts.res,
        threads,
        budgets: opts.budgets.clone(),
        seeds: opts.base.seeds,
        oidn: Vec::new(),
        rows: Vec::new(),
        seed_rows: Vec::new(),
        notes: Vec::new(),
        seconds: 0.0,
    };
    let json = out.join("sweep.json");
    for scene in &opts.base.scenes {
        let mut oidn_seconds = Vec::new();
        for &budget in &opts.budgets {
            let mut run = TableRun::default();
            for i in 0..opts.base.seeds.max(1) {
                let point = TableOptions {
                    scenes: vec![scene.clone()],
                    reference_dir: opts.reference_dir.clone(),
                    params: params.clone(),
                    budget: Budget::Seconds(budget),
                    out: images.clone(),
                    mitsuba: None,
                    skip: SKIP.iter().chain(&opts.base.skip).copied().collect(),
                    seed: seed_of(opts.base.seed, i),
                    seeds: 1,
                    write_png: false,
                    ..opts.base.clone()
                };
                let job = SceneJob {
                    scene: scene.clone(),
                    reference: reference_name(&opts.reference_dir, scene, opts.res),
                    tag: format!("{scene}_{budget}s"),
                };
                run_scene(&job, &point, &mut run)?;
            }
            oidn_seconds.extend(run.oidn_seconds.iter().map(|o| o.1));
            let correction = |s: &str| {
                run.references
                    .iter()
                    .find(|r| r.0 == s)
                    .map_or(f64::NAN, |r| r.3)
            };
            for s in summarize(&run.rows, correction) {
                data.rows.push(SweepRow {
                    scene: s.scene,
                    method: s.method,
                    accounting: s.accounting,
                    budget,
                    seeds: s.seeds,
                    spp: s.spp,
                    seconds: s.seconds,
                    mse_corrected: s.mse_corrected,
                    mse_corrected_se: s.mse_corrected_se,
                    ratio_to_best: s.ratio_to_best,
                    best: s.best,
                });
            }
            data.seed_rows
                .extend(run.rows.into_iter().map(|r| (budget, r)));
            data.notes
                .extend(run.notes.into_iter().map(|n| format!("{budget} s: {n}")));
            data.seconds = started.elapsed().as_secs_f64();
            write_json(&json, &data)?;
        }
        let median = median(&mut oidn_seconds);
        data.oidn.push(OidnShare {
            scene: scene.clone(),
            oidn_seconds: median,
            shares: opts.budgets.iter().map(|&b| (b, median / b)).collect(),
        });
        for accounting in [Accounting::Frame, Accounting::Still] {
            plot(out, &data, scene, accounting)?;
        }
    }
    data.seconds = started.elapsed().as_secs_f64();
    write_json(&json, &data)?;
    Ok(json)
}

/// `NAME_resRES` where the folder has it (the figures' references), else `NAME`: either
/// way the reference's JSON must record `res` = RES (`Reference::load` checks it).
fn reference_name(dir: &Path, scene: &str, res: u32) -> String {
    let sized = format!("{scene}_res{res}");
    match dir.join(format!("{sized}.exr")).exists() {
        true => sized,
        false => scene.to_string(),
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n => v[n / 2],
    }
}

fn write_json(path: &Path, data: &SweepData) -> Result<()> {
    std::fs::write(path, serde_json::to_string_pretty(data)?)?;
    Ok(())
}

/// `sweep_SCENE_ACCOUNTING.png`: each method's mean corrected MSE against its mean
/// seconds, log–log, with the 95% band of the mean over seeds.
fn plot(out: &Path, data: &SweepData, scene: &str, accounting: Accounting) -> Result<()> {
    let methods = [
        Method::Regularized,
        Method::RegularizedPaper,
        Method::Volpath,
        Method::VolpathOidn,
        Method::VolpathFiltered,
    ];
    let series: Vec<Series> = methods
        .iter()
        .filter_map(|&m| {
            let rows: Vec<&SweepRow> = data
                .rows
                .iter()
                .filter(|r| r.scene == scene && r.method == m && r.accounting == accounting)
                .collect();
            if rows.is_empty() {
                return None;
            }
            let points = rows.iter().map(|r| (r.seconds, r.mse_corrected)).collect();
            // A t quantile at n − 1 = 2 degrees of freedom would be 4.3; the band shows
            // the spread, 2 standard errors, not a test.
            let band = rows
                .iter()
                .map(|r| {
                    let half = 2.0 * r.mse_corrected_se;
                    (
                        r.seconds,
                        (r.mse_corrected - half).max(r.mse_corrected * 0.05),
                        r.mse_corrected + half,
                    )
                })
                .collect();
            Some(Series::new(m.as_str(), points).with_band(band))
        })
        .collect();
    if series.is_empty() {
        return Ok(());
    }
    let png = out.join(format!("sweep_{scene}_{}.png", accounting.as_str()));
    let title = match accounting {
        Accounting::Frame => "one frame of an animation",
        Accounting::Still => "one still image",
    };
    line_plot(
        &png,
        &Axes {
            title: format!("{scene}, {title} ({0}x{0})", data.res),
            x_label: "seconds".into(),
            y_label: "MSE (reference variance subtracted)".into(),
            log_x: true,
            log_y: true,
        },
        &series,
    )
}
