//! The table's files: `table1.json` (the rows, as `Row`), `table1.csv` (the same
//! columns), `run.json` (how the run was made, as `RunInfo`) and `table1.md` (the rows,
//! ratios to plain volpath, the paper's numbers side by side, the references and notes),
//! which is made from the two JSON files alone (`mediareg report` remakes it).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};

use super::decompose::Decomposition;
use super::paper::table1_row;
use super::summary::{summarize, Summary};
use super::table::{Accounting, Budget, Method, Row, TableOptions, TableRun};

fn write(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}

/// The paper comparison's cells for a scene, from the summaries (means over seeds): the
/// paper's ours/PT, then regularized_paper and regularized over volpath, regularized over
/// the best baseline in each accounting, and mitsuba_volpath over volpath.
pub fn paper_cells(summaries: &[Summary], scene: &str) -> [String; 6] {
    let find = |m: Method, a: Accounting| {
        summaries
            .iter()
            .find(|s| s.scene == scene && s.method == m && s.accounting == a)
    };
    let mean = |x: Option<[f64; 3]>| x.map_or("–".into(), |x| format!("{:.3}", x[0]));
    let versus_volpath = |m| mean(find(m, Accounting::Frame).and_then(|s| s.ratio_to_volpath));
    let versus_best = |a| {
        find(Method::Regularized, a).map_or("–".into(), |s| {
            format!(
                "{} ({})",
                interval(s.ratio_to_best),
                s.best.map_or("–", |b| b.as_str())
            )
        })
    };
    let paper = table1_row(scene).map_or("–".into(), |p| {
        format!(
            "{:.2} ({:.1e} / {:.1e})",
            p.mse_ratio(),
            p.ours_mse,
            p.pt_mse
        )
    });
    [
        paper,
        versus_volpath(Method::RegularizedPaper),
        versus_volpath(Method::Regularized),
        versus_best(Accounting::Frame),
        versus_best(Accounting::Still),
        versus_volpath(Method::MitsubaVolpath),
    ]
}

/// The header of the paper comparison (`paper_cells`).
pub const PAPER_HEADER: [&str; 7] = [
    "scene",
    "paper: ours / PT",
    "regularized_paper ÷ volpath",
    "regularized ÷ volpath",
    "regularized ÷ best, frame [95% CI] (best)",
    "regularized ÷ best, still [95% CI] (best)",
    "mitsuba_volpath ÷ volpath",
];

/// A reference as `run.json` lists it.
#[derive(Serialize, Deserialize, Clone, Debug)]
pub struct ReferenceInfo {
    pub scene: String,
    pub mitsuba_version: String,
    pub variant: String,
    pub spp: u32,
    pub chunks: u32,
    pub seconds: f64,
    pub mean_variance: f64,
    /// The standard error of the correction (`summary::correction_se`).
    #[serde(default)]
    pub correction_se: f64,
}

/// `run.json`: how a table run was made.
#[derive(Serialize, Deserialize, Clone, Debug)]
pub struct RunInfo {
    pub budget: String,
    pub threads: usize,
    pub params: BTreeMap<String, String>,
    pub frames: usize,
    pub w_a: f64,
    pub orbit_degrees_per_frame: f32,
    pub c_beta: f32,
    pub seed: u64,
    #[serde(default)]
    pub seeds: Vec<u64>,
    /// Whether the regularized rows and volpath_oidn used Open Image Denoise.
    #[serde(default)]
    pub oidn: bool,
    pub references: Vec<ReferenceInfo>,
    pub notes: Vec<String>,
    pub mediareg_version: String,
    /// Where the automatic row's gain goes, per scene (`decompose`).
    #[serde(default)]
    pub decomposition: Vec<Decomposition>,
}

/// Remakes `dir/table1.json` and `table1.md` from `dir/table1_seeds.json` and
/// `dir/run.json`.
pub fn rewrite_markdown(dir: &Path) -> Result<()> {
    let read = |name: &str| {
        std::fs::read_to_string(dir.join(name))
            .with_context(|| format!("no {name} in {}: run mediareg table", dir.display()))
    };
    let rows: Vec<Row> =
        serde_json::from_str(&read("table1_seeds.json")?).context("table1_seeds.json")?;
    let info: RunInfo = serde_json::from_str(&read("run.json")?).context("run.json")?;
    let summaries = summaries_of(&info, &rows);
    write(
        &dir.join("table1.json"),
        &(serde_json::to_string_pretty(&summaries)? + "\n"),
    )?;
    write(&dir.join("table1.md"), &markdown(&info, &summaries)?)
}

pub fn summaries_of(info: &RunInfo, rows: &[Row]) -> Vec<Summary> {
    summarize(rows, |scene| {
        info.references
            .iter()
            .find(|r| r.scene == scene)
            .map_or(f64::NAN, |r| r.correction_se)
    })
}

/// The first seed's rows in the frame accounting: the images a reader is shown.
pub fn first_seed_rows(rows: &[Row]) -> Vec<Row> {
    rows.iter()
        .filter(|r| {
            r.accounting == Accounting::Frame
                && rows.iter().find(|f| f.scene == r.scene).map(|f| f.seed) == Some(r.seed)
        })
        .cloned()
        .collect()
}

fn budget_text(b: Budget) -> String {
    match b {
        Budget::Seconds(s) => format!("equal time: {s} s per method (per frame for the sequence)"),
        Budget::Spp(n) => format!("equal spp: {n} per method (per frame for the sequence)"),
        Budget::PaperSpp => "the paper's spp: path tracing's for the baselines, the method's per frame for the sequences (its Table 1)".into(),
    }
}

pub fn write_outputs(opts: &TableOptions, run: &TableRun) -> Result<()> {
    let json = serde_json::to_string_pretty(&run.rows)?;
    write(&opts.out.join("table1_seeds.json"), &(json + "\n"))?;

    let info = RunInfo {
        budget: budget_text(opts.budget),
        threads: rayon::current_num_threads(),
        params: opts.params.iter().cloned().collect(),
        frames: opts.frames,
        w_a: opts.w_a,
        orbit_degrees_per_frame: opts.orbit_degrees,
        c_beta: opts.c_beta,
        seed: opts.seed,
        seeds: (0..opts.seeds.max(1))
            .map(|i| super::table::seed_of(opts.seed, i))
            .collect(),
        oidn: opts.oidn,
        references: run
            .references
            .iter()
            .map(|(name, m, var, se)| ReferenceInfo {
                scene: name.clone(),
                mitsuba_version: m.mitsuba_version.clone(),
                variant: m.variant.clone(),
                spp: m.spp,
                chunks: m.chunks,
                seconds: m.seconds,
                mean_variance: *var,
                correction_se: *se,
            })
            .collect(),
        notes: run.notes.clone(),
        mediareg_version: env!("CARGO_PKG_VERSION").into(),
        decomposition: run.decomposition.clone(),
    };
    write(
        &opts.out.join("run.json"),
        &(serde_json::to_string_pretty(&info)? + "\n"),
    )?;
    let summaries = summaries_of(&info, &run.rows);
    write(
        &opts.out.join("table1.json"),
        &(serde_json::to_string_pretty(&summaries)? + "\n"),
    )?;
    let mut csv = String::from(
        "scene,method,accounting,seeds,spp,seconds,mse,mse_corrected,mse_corrected_se,ratio_to_volpath,ratio_to_volpath_low,ratio_to_volpath_high,ratio_to_best,ratio_to_best_low,ratio_to_best_high,best\n",
    );
    let triple =
        |x: Option<[f64; 3]>| x.map_or(",,".into(), |[a, b, c]| format!("{a:.5},{b:.5},{c:.5}"));
    for r in &summaries {
        writeln!(
            csv,
            "{},{},{},{},{:.1},{:.3},{:.6e},{:.6e},{:.3e},{},{},{}",
            r.scene,
            r.method.as_str(),
            r.accounting.as_str(),
            r.seeds.len(),
            r.spp,
            r.seconds,
            r.mse,
            r.mse_corrected,
            r.mse_corrected_se,
            triple(r.ratio_to_volpath),
            triple(r.ratio_to_best),
            r.best.map_or("", |b| b.as_str())
        )?;
    }
    write(&opts.out.join("table1.csv"), &csv)?;
    write(&opts.out.join("table1.md"), &markdown(&info, &summaries)?)
}

/// `[mean, low, high]` as a table cell: "mean [low, high]".
pub fn interval(x: Option<[f64; 3]>) -> String {
    x.map_or("–".into(), |[m, lo, hi]| {
        match lo.is_nan() || hi.is_nan() {
            true => format!("{m:.3} [one seed]"),
            false => format!("{m:.3} [{lo:.3}, {hi:.3}]"),
        }
    })
}

fn markdown(info: &RunInfo, summaries: &[Summary]) -> Result<String> {
    let mut md = String::new();
    writeln!(md, "# Table 1 of the paper, reproduced\n")?;
    writeln!(
        md,
        "{}; {} render threads; {} seeds per row; sequences: {} frames (w_a {}), an orbit of {}° per frame, exact reprojection, c_β {}; Open Image Denoise {}.",
        info.budget,
        info.threads,
        info.seeds.len().max(1),
        info.frames,
        info.w_a,
        info.orbit_degrees_per_frame,
        info.c_beta,
        match info.oidn {
            true => "used (volpath_oidn; the regularized default and its control denoise every frame)",
            false => "not used",
        }
    )?;
    if !info.params.is_empty() {
        let d: Vec<String> = info
            .params
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        writeln!(md, "Scene parameters: `-D {}`.", d.join(" -D "))?;
    }
    writeln!(
        md,
        "\nMSE over pixels and channels against the Mitsuba 3 reference, mean over the seeds; *corrected* subtracts the reference's own variance (an unbiased estimate of the MSE against the true image; ± the seeds' standard error). Ratios are of mean corrected MSEs, with their 95% confidence interval over the seeds; *best* is the baseline (volpath, volpath_oidn, volpath_filtered) of least corrected MSE in the same accounting. Accounting `frame` (an animation, the paper's): a sequence is charged its target frame (render, its denoising, the blend and prediction) and its share of the pilot; `still` (one image): every frame and the whole pilot, and volpath and volpath_oidn are rendered again at that time.\n"
    )?;
    writeln!(
        md,
        "| scene | method | accounting | spp | seconds | MSE | MSE corrected | ÷ volpath [95% CI] | ÷ best [95% CI] | best |"
    )?;
    writeln!(md, "|---|---|---|---:|---:|---:|---:|---:|---:|---|")?;
    for r in summaries {
        writeln!(
            md,
            "| {} | {} | {} | {:.0} | {:.2} | {:.3e} | {:.3e}{} | {} | {} | {} |",
            r.scene,
            r.method.as_str(),
            r.accounting.as_str(),
            r.spp,
            r.seconds,
            r.mse,
            r.mse_corrected,
            // One seed has no spread.
            match r.mse_corrected_se.is_nan() {
                true => String::new(),
                false => format!(" ± {:.1e}", r.mse_corrected_se),
            },
            interval(r.ratio_to_volpath),
            interval(r.ratio_to_best),
            r.best.map_or("–", |b| b.as_str()),
        )?;
    }
    writeln!(md, "\n## Against the paper\n")?;
    writeln!(
        md,
        "The paper's ratio is its method's MSE over path tracing's at about equal time (16 cores, Mitsuba 0.5, one frame of an animation); ours are ratios of mean corrected MSEs at equal time on this machine, the frame accounting unless it says still. Absolute MSEs depend on the scene's lighting and exposure, which the paper does not publish, so only ratios compare.\n"
    )?;
    writeln!(md, "| {} |", PAPER_HEADER.join(" | "))?;
    writeln!(md, "|---|---:|---:|---:|---:|---:|---:|")?;
    let mut scenes: Vec<&str> = summaries.iter().map(|r| r.scene.as_str()).collect();
    scenes.dedup();
    for s in scenes {
        writeln!(md, "| {s} | {} |", paper_cells(summaries, s).join(" | "))?;
    }

    writeln!(md, "\n## References\n")?;
    writeln!(
        md,
        "| scene | Mitsuba | variant | spp | chunks | seconds | mean variance of the reference (the correction) | its standard error |"
    )?;
    writeln!(md, "|---|---|---|---:|---:|---:|---:|---:|")?;
    for r in &info.references {
        writeln!(
            md,
            "| {} | {} | {} | {} | {} | {:.0} | {:.3e} | {:.1e} |",
            r.scene,
            r.mitsuba_version,
            r.variant,
            r.spp,
            r.chunks,
            r.seconds,
            r.mean_variance,
            r.correction_se
        )?;
    }
    if !info.decomposition.is_empty() {
        writeln!(md, "\n## Where the gain goes (regularized)\n")?;
        writeln!(
            md,
            "Per pixel and channel, one sample's variance from the factor's pilot at the target albedo α_t (R_t) and at the source albedo α_s it chose (R_s, and the difference D before and after the spatial filter and the blend over frames); seconds per spp measured at both; k̄ the contribution-weighted mean number of scattering vertices in the medium (Σ α ∂R/∂α / Σ R). *predicted* is [Var(R_s) + Var(D) denoised] / spp, the variance the prediction should have; *bias²* is the corrected MSE minus it: the denoising's bias and what the pilot's variances miss; negative where they overstate the noise (the pilot's variances come from 1-spp renders, and the stratified positions in the pixel make an N-spp mean converge faster than 1/N at edges).\n"
        )?;
        writeln!(
            md,
            "| scene | factor | s/spp α_t | s/spp α_s | k̄ α_t | k̄ α_s | Var R_t | Var R_s | Var D | Var D denoised | spp | predicted | MSE corrected | bias² |"
        )?;
        writeln!(
            md,
            "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
        )?;
        for d in &info.decomposition {
            writeln!(
                md,
                "| {} | {:?} | {:.4} | {:.4} | {:.2} | {:.2} | {:.3e} | {:.3e} | {:.3e} | {:.3e} | {} | {:.3e} | {:.3e} | {:.3e} |",
                d.scene,
                d.factor,
                d.seconds_per_spp_target,
                d.seconds_per_spp_source,
                d.vertices_target,
                d.vertices_source,
                d.var_target,
                d.var_source,
                d.var_difference,
                d.var_difference_denoised,
                d.spp,
                d.predicted_variance,
                d.mse_corrected,
                d.bias2
            )?;
        }
    }
    if !info.notes.is_empty() {
        writeln!(md, "\n## Notes\n")?;
        for n in &info.notes {
            writeln!(md, "- {n}")?;
        }
    }
    Ok(md)
}
