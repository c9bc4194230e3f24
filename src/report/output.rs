//! The table's files: `table1.json` (the rows, as `Row`), `table1.csv` (the same
//! columns), `table1.md` (the rows, ratios to plain volpath, the paper's numbers side by
//! side, the references and notes) and `run.json` (how the run was made).

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};

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

    let threads = rayon::current_num_threads();
    let meta = serde_json::json!({
        "budget": budget_text(opts.budget),
        "threads": threads,
        "params": opts.params.iter().cloned().collect::<std::collections::BTreeMap<_, _>>(),
        "frames": opts.frames,
        "w_a": opts.w_a,
        "orbit_degrees_per_frame": opts.orbit_degrees,
        "c_beta": opts.c_beta,
        "seed": opts.seed,
        "references": run.references.iter().map(|(name, m, var)| serde_json::json!({
            "scene": name, "mitsuba_version": m.mitsuba_version, "variant": m.variant,
            "spp": m.spp, "chunks": m.chunks, "seconds": m.seconds, "mean_variance": var,
        })).collect::<Vec<_>>(),
        "notes": run.notes,
        "mediareg_version": env!("CARGO_PKG_VERSION"),
    });
    write(
        &opts.out.join("run.json"),
        &(serde_json::to_string_pretty(&meta)? + "\n"),
    )?;
    write(&opts.out.join("table1.md"), &markdown(opts, run)?)
}

fn markdown(opts: &TableOptions, run: &TableRun) -> Result<String> {
    let mut md = String::new();
    writeln!(md, "# Table 1 of the paper, reproduced\n")?;
    writeln!(
        md,
        "{}; {} render threads; regularized: {} frames (w_a {}), an orbit of {}° per frame, exact reprojection, c_β {}.",
        budget_text(opts.budget),
        rayon::current_num_threads(),
        opts.frames,
        opts.w_a,
        opts.orbit_degrees,
        opts.c_beta
    )?;
    if !opts.params.is_empty() {
        let d: Vec<String> = opts
            .params
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        writeln!(md, "Scene parameters: `-D {}`.", d.join(" -D "))?;
    }
    writeln!(
        md,
        "\nMSE over pixels and channels against the Mitsuba 3 reference; *corrected* subtracts the reference's own variance (an unbiased estimate of the MSE against the true image). *÷ volpath* is the corrected MSE over plain volpath's at the same budget. `regularized` counts one frame of its sequence: the target frame's render plus reprojection, blending and prediction (the paper's accounting).\n"
    )?;
    writeln!(
        md,
        "| scene | method | spp | seconds | MSE | MSE corrected | ÷ volpath |"
    )?;
    writeln!(md, "|---|---|---:|---:|---:|---:|---:|")?;
    for r in &run.rows {
        let ratio = ratio_to_volpath(&run.rows, &r.scene, r.method)
            .map_or("–".into(), |x| format!("{x:.2}"));
        writeln!(
            md,
            "| {} | {} | {} | {:.2} | {:.3e} | {:.3e} | {} |",
            r.scene,
            r.method.as_str(),
            r.spp,
            r.seconds,
            r.mse,
            r.mse_corrected,
            ratio
        )?;
    }

    writeln!(md, "\n## Against the paper\n")?;
    writeln!(
        md,
        "The paper's ratio is its method's MSE over path tracing's at about equal time (16 cores, Mitsuba 0.5); ours are corrected MSE ratios at equal time on this machine. Absolute MSEs depend on the scene's lighting and exposure, which the paper does not publish, so only ratios compare.\n"
    )?;
    writeln!(
        md,
        "| scene | paper: ours / PT | here: regularized / volpath | regularized_spatial / volpath | mitsuba_volpath / volpath |"
    )?;
    writeln!(md, "|---|---:|---:|---:|---:|")?;
    let mut scenes: Vec<&str> = run.rows.iter().map(|r| r.scene.as_str()).collect();
    scenes.dedup();
    for s in scenes {
        let f = |m| ratio_to_volpath(&run.rows, s, m).map_or("–".into(), |x| format!("{x:.2}"));
        let paper = table1_row(s).map_or("–".into(), |p| {
            format!(
                "{:.2} ({:.1e} / {:.1e})",
                p.mse_ratio(),
                p.ours_mse,
                p.pt_mse
            )
        });
        writeln!(
            md,
            "| {s} | {paper} | {} | {} | {} |",
            f(Method::Regularized),
            f(Method::RegularizedSpatial),
            f(Method::MitsubaVolpath)
        )?;
    }

    writeln!(md, "\n## References\n")?;
    writeln!(
        md,
        "| scene | Mitsuba | variant | spp | chunks | seconds | mean variance of the reference |"
    )?;
    writeln!(md, "|---|---|---|---:|---:|---:|---:|")?;
    for (name, m, var) in &run.references {
        writeln!(
            md,
            "| {name} | {} | {} | {} | {} | {:.0} | {var:.3e} |",
            m.mitsuba_version, m.variant, m.spp, m.chunks, m.seconds
        )?;
    }
    if !run.notes.is_empty() {
        writeln!(md, "\n## Notes\n")?;
        for n in &run.notes {
            writeln!(md, "- {n}")?;
        }
    }
    Ok(md)
}
