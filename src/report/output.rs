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
use super::table::{Budget, Method, Row, TableOptions, TableRun};

fn write(path: &Path, text: &str) -> Result<()> {
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}

fn row_of<'a>(rows: &'a [Row], scene: &str, method: Method) -> Option<&'a Row> {
    rows.iter().find(|r| r.scene == scene && r.method == method)
}

/// `method`'s corrected MSE over plain volpath's, in the same scene.
pub fn ratio_to_volpath(rows: &[Row], scene: &str, method: Method) -> Option<f64> {
    let m = row_of(rows, scene, method)?;
    let v = row_of(rows, scene, Method::Volpath)?;
    Some(m.mse_corrected / v.mse_corrected)
}

/// The same ratio with each MSE multiplied by the seconds it took: equal time holds only
/// to the accuracy of the timing (about ±20% here), and for an unbiased estimator
/// MSE × seconds does not depend on the budget (the inverse of the efficiency).
pub fn time_adjusted_ratio(rows: &[Row], scene: &str, method: Method) -> Option<f64> {
    let m = row_of(rows, scene, method)?;
    let v = row_of(rows, scene, Method::Volpath)?;
    Some(m.mse_corrected * m.seconds / (v.mse_corrected * v.seconds))
}

fn cell(x: Option<f64>) -> String {
    x.map_or("–".into(), |x| format!("{x:.2}"))
}

/// A row's ratios to plain volpath as table cells: raw, and time-adjusted.
pub fn ratio_cells(rows: &[Row], r: &Row) -> [String; 2] {
    [
        cell(ratio_to_volpath(rows, &r.scene, r.method)),
        cell(time_adjusted_ratio(rows, &r.scene, r.method)),
    ]
}

/// The paper comparison's cells for a scene: the paper's ours/PT, then regularized,
/// regularized_spatial and mitsuba_volpath over volpath, each "raw (time-adjusted)".
pub fn paper_cells(rows: &[Row], scene: &str) -> [String; 5] {
    let f = |m| match (
        ratio_to_volpath(rows, scene, m),
        time_adjusted_ratio(rows, scene, m),
    ) {
        (Some(a), Some(b)) => format!("{a:.2} ({b:.2})"),
        _ => "–".into(),
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
        f(Method::Regularized),
        f(Method::RegularizedSpatial),
        f(Method::RegularizedAuto),
        f(Method::MitsubaVolpath),
    ]
}

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
    pub references: Vec<ReferenceInfo>,
    pub notes: Vec<String>,
    pub mediareg_version: String,
    /// Where the automatic row's gain goes, per scene (`decompose`).
    #[serde(default)]
    pub decomposition: Vec<Decomposition>,
}

/// Remakes `dir/table1.md` from `dir/table1.json` and `dir/run.json`.
pub fn rewrite_markdown(dir: &Path) -> Result<()> {
    let read = |name: &str| {
        std::fs::read_to_string(dir.join(name))
            .with_context(|| format!("no {name} in {}: run mediareg table", dir.display()))
    };
    let rows: Vec<Row> = serde_json::from_str(&read("table1.json")?).context("table1.json")?;
    let info: RunInfo = serde_json::from_str(&read("run.json")?).context("run.json")?;
    write(&dir.join("table1.md"), &markdown(&info, &rows)?)
}

fn budget_text(b: Budget) -> String {
    match b {
        Budget::Seconds(s) => format!("equal time: {s} s per method (per frame for the sequence)"),
        Budget::Spp(n) => format!("equal spp: {n} per method (per frame for the sequence)"),
    }
}

pub fn write_outputs(opts: &TableOptions, run: &TableRun) -> Result<()> {
    let json = serde_json::to_string_pretty(&run.rows)?;
    write(&opts.out.join("table1.json"), &(json + "\n"))?;

    let mut csv = String::from("scene,method,spp,seconds,mse,mse_corrected,image,reference\n");
    for r in &run.rows {
        writeln!(
            csv,
            "{},{},{},{:.3},{:.6e},{:.6e},{},{}",
            r.scene,
            r.method.as_str(),
            r.spp,
            r.seconds,
            r.mse,
            r.mse_corrected,
            r.image,
            r.reference
        )?;
    }
    write(&opts.out.join("table1.csv"), &csv)?;

    let info = RunInfo {
        budget: budget_text(opts.budget),
        threads: rayon::current_num_threads(),
        params: opts.params.iter().cloned().collect(),
        frames: opts.frames,
        w_a: opts.w_a,
        orbit_degrees_per_frame: opts.orbit_degrees,
        c_beta: opts.c_beta,
        seed: opts.seed,
        references: run
            .references
            .iter()
            .map(|(name, m, var)| ReferenceInfo {
                scene: name.clone(),
                mitsuba_version: m.mitsuba_version.clone(),
                variant: m.variant.clone(),
                spp: m.spp,
                chunks: m.chunks,
                seconds: m.seconds,
                mean_variance: *var,
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
    write(&opts.out.join("table1.md"), &markdown(&info, &run.rows)?)
}

fn markdown(info: &RunInfo, rows: &[Row]) -> Result<String> {
    let mut md = String::new();
    writeln!(md, "# Table 1 of the paper, reproduced\n")?;
    writeln!(
        md,
        "{}; {} render threads; regularized: {} frames (w_a {}), an orbit of {}° per frame, exact reprojection, c_β {}.",
        info.budget,
        info.threads,
        info.frames,
        info.w_a,
        info.orbit_degrees_per_frame,
        info.c_beta
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
        "\nMSE over pixels and channels against the Mitsuba 3 reference; *corrected* subtracts the reference's own variance (an unbiased estimate of the MSE against the true image). *÷ volpath* is the corrected MSE over plain volpath's at the same budget; *× time ÷ volpath* multiplies each MSE by the seconds it really took first (equal time holds to about ±20% here; for an unbiased method MSE × seconds does not depend on the budget). `regularized` counts one frame of its sequence: the target frame's render plus reprojection, blending and prediction (the paper's accounting).\n"
    )?;
    writeln!(
        md,
        "| scene | method | spp | seconds | MSE | MSE corrected | ÷ volpath | × time ÷ volpath |"
    )?;
    writeln!(md, "|---|---|---:|---:|---:|---:|---:|---:|")?;
    for r in rows {
        let [raw, adjusted] = ratio_cells(rows, r);
        writeln!(
            md,
            "| {} | {} | {} | {:.2} | {:.3e} | {:.3e} | {raw} | {adjusted} |",
            r.scene,
            r.method.as_str(),
            r.spp,
            r.seconds,
            r.mse,
            r.mse_corrected,
        )?;
    }

    writeln!(md, "\n## Against the paper\n")?;
    writeln!(
        md,
        "The paper's ratio is its method's MSE over path tracing's at about equal time (16 cores, Mitsuba 0.5); ours are corrected MSE ratios at equal time on this machine. Absolute MSEs depend on the scene's lighting and exposure, which the paper does not publish, so only ratios compare.\n"
    )?;
    writeln!(
        md,
        "| scene | paper: ours / PT | here: regularized / volpath (× time) | regularized_spatial / volpath (× time) | regularized_auto / volpath (× time) | mitsuba_volpath / volpath (× time) |"
    )?;
    writeln!(md, "|---|---:|---:|---:|---:|---:|")?;
    let mut scenes: Vec<&str> = rows.iter().map(|r| r.scene.as_str()).collect();
    scenes.dedup();
    for s in scenes {
        let [paper, reg, spatial, auto, mitsuba] = paper_cells(rows, s);
        writeln!(
            md,
            "| {s} | {paper} | {reg} | {spatial} | {auto} | {mitsuba} |"
        )?;
    }

    writeln!(md, "\n## References\n")?;
    writeln!(
        md,
        "| scene | Mitsuba | variant | spp | chunks | seconds | mean variance of the reference |"
    )?;
    writeln!(md, "|---|---|---|---:|---:|---:|---:|")?;
    for r in &info.references {
        writeln!(
            md,
            "| {} | {} | {} | {} | {} | {:.0} | {:.3e} |",
            r.scene, r.mitsuba_version, r.variant, r.spp, r.chunks, r.seconds, r.mean_variance
        )?;
    }
    if !info.decomposition.is_empty() {
        writeln!(md, "\n## Where the gain goes (regularized_auto)\n")?;
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
