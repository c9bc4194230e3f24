//! `mediareg table` at a reduced size: the cube of the paper's figures at 32×32 against a
//! committed Mitsuba 3 reference (reference/table_small/cube.*, made with -D res=32), the
//! same pipeline as the full-size run in reports/. Checks that the files say what the
//! images are: every MSE recomputed from the EXRs table1_seeds.json names equals the
//! JSON's, and table1.json's summaries are the means, ratios and best baselines of those
//! rows.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use mediareg::report::{Accounting, Method, Row, Summary};

fn table(out: &Path, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mediareg"))
        .current_dir(common::root())
        .args([
            "table", "--scenes", "cube", "-D", "res=32", "--budget", "0.4",
        ])
        .args(["--reference-dir", "reference/table_small", "--frames", "5"])
        .args(["--seeds", "2"])
        .args(["-t", "2", "--out"])
        .arg(out)
        .args(extra)
        .output()
        .expect("mediareg runs")
}

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("mediareg_table_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn table_files_agree_with_the_images_they_name() {
    let out = temp_dir("files");
    // A Python that does not exist: the Mitsuba row is skipped with a note, not an error.
    let o = table(&out, &["--python", "/nonexistent/python3"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "table failed: {stderr}");
    assert!(
        stderr.contains("Mitsuba 3 not run"),
        "the skipped Mitsuba row must be noted: {stderr}"
    );

    let rows: Vec<Row> =
        serde_json::from_str(&std::fs::read_to_string(out.join("table1_seeds.json")).unwrap())
            .expect("table1_seeds.json is a list of rows");
    let oidn = common::oidn_present();
    let mut want = vec![Method::Volpath];
    want.extend(oidn.then_some(Method::VolpathOidn));
    want.extend([
        Method::RegularizedPaper,
        Method::Regularized,
        Method::VolpathFiltered,
    ]);
    let methods: Vec<Method> = rows
        .iter()
        .filter(|r| r.accounting == Accounting::Frame && r.seed == rows[0].seed)
        .map(|r| r.method)
        .collect();
    assert_eq!(methods, want);
    let seeds: Vec<u64> = rows.iter().fold(Vec::new(), |mut v, r| {
        if !v.contains(&r.seed) {
            v.push(r.seed);
        }
        v
    });
    assert_eq!(seeds.len(), 2, "--seeds 2");
    for r in &rows {
        assert_eq!(r.scene, "cube");
        assert!(r.spp >= 1 && r.seconds > 0.0 && r.seconds.is_finite());
        let img = mediareg::image::read_exr(&out.join(&r.image)).expect("the row's image");
        // The row's reference, checked against the sha256 its JSON records.
        let reference = out.join(&r.reference);
        assert!(reference.ends_with("cube.exr"), "{}", reference.display());
        let (mean, var, _) =
            mediareg::report::reference::read_reference_images(reference.parent().unwrap(), "cube")
                .unwrap_or_else(|e| panic!("{e:#}"));
        assert!(img
            .pixels
            .iter()
            .all(|p| p.iter().all(|c| c.is_finite() && *c >= 0.0)));
        // Recompute both MSEs from the files, in f64.
        let n = (img.pixels.len() * 3) as f64;
        let mut raw = 0.0;
        let mut var_sum = 0.0;
        for i in 0..img.pixels.len() {
            for c in 0..3 {
                raw += (img.pixels[i][c] as f64 - mean.pixels[i][c] as f64).powi(2);
                var_sum += var.pixels[i][c] as f64;
            }
        }
        raw /= n;
        let corrected = raw - var_sum / n;
        assert!(
            (raw - r.mse).abs() <= 1e-9 * raw,
            "{:?}: JSON MSE {} vs {raw}",
            r.method,
            r.mse
        );
        assert!((corrected - r.mse_corrected).abs() <= 1e-9 * raw);
        assert!(raw > 0.0, "a Monte Carlo image equal to its reference?");
    }
    let seq = rows
        .iter()
        .find(|r| r.method == Method::Regularized && r.accounting == Accounting::Frame)
        .unwrap();
    assert_eq!(seq.sequence_frames, Some(5));
    assert!(seq.sequence_seconds.unwrap() >= seq.seconds);
    let row_of = |method: Method, accounting: Accounting| {
        rows.iter()
            .find(|r| r.method == method && r.accounting == accounting && r.seed == seq.seed)
    };
    // The still accounting charges the control's image the whole sequence.
    let control = row_of(Method::VolpathFiltered, Accounting::Frame).unwrap();
    let control_still = row_of(Method::VolpathFiltered, Accounting::Still).unwrap();
    assert_eq!(
        (control_still.image.as_str(), control_still.seconds),
        (control.image.as_str(), control.sequence_seconds.unwrap())
    );
    // The default's still row is `regularize --frames 1` at that time (with OIDN): an
    // image of its own, with more samples than a frame of the sequence.
    match (oidn, row_of(Method::Regularized, Accounting::Still)) {
        (true, Some(still)) => {
            assert!(
                still.image.ends_with("regularized_still.exr"),
                "{}",
                still.image
            );
            assert!(still.spp > seq.spp, "{} ≤ {}", still.spp, seq.spp);
        }
        (false, None) => {}
        (oidn, still) => panic!("OIDN {oidn}, the default's still row {still:?}"),
    }

    // The summaries: means over the seeds, ratios and the best baseline.
    let summaries: Vec<Summary> =
        serde_json::from_str(&std::fs::read_to_string(out.join("table1.json")).unwrap())
            .expect("table1.json is a list of summaries");
    for s in &summaries {
        let own: Vec<&Row> = rows
            .iter()
            .filter(|r| r.method == s.method && r.accounting == s.accounting)
            .collect();
        assert_eq!(s.seeds.len(), own.len());
        let mean =
            |f: &dyn Fn(&Row) -> f64| own.iter().map(|r| f(r)).sum::<f64>() / own.len() as f64;
        assert!(
            (s.mse_corrected - mean(&|r| r.mse_corrected)).abs() <= 1e-12 * s.mse.abs().max(1e-30)
        );
        let baseline = |m: Method| {
            summaries
                .iter()
                .find(|b| b.method == m && b.accounting == s.accounting)
                .map(|b| b.mse_corrected)
        };
        let best = [
            Method::Volpath,
            Method::VolpathOidn,
            Method::VolpathFiltered,
        ]
        .into_iter()
        .filter_map(|m| baseline(m).map(|v| (m, v)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap();
        assert_eq!(s.best, Some(best.0), "{:?} {:?}", s.method, s.accounting);
        if let Some([r, lo, hi]) = s.ratio_to_best {
            assert!((r - s.mse_corrected / best.1).abs() <= 1e-9 * r.abs() && lo <= r && r <= hi);
        }
        if s.method == Method::Volpath {
            assert_eq!(s.ratio_to_volpath, Some([1.0; 3]));
        }
    }
    for accounting in [Accounting::Frame, Accounting::Still] {
        assert!(summaries
            .iter()
            .any(|s| s.method == Method::Volpath && s.accounting == accounting));
    }

    let csv = std::fs::read_to_string(out.join("table1.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert!(lines[0].starts_with("scene,method,accounting,seeds,spp,seconds,mse,mse_corrected,"));
    assert_eq!(lines.len(), 1 + summaries.len());
    for (line, s) in lines[1..].iter().zip(&summaries) {
        assert!(line.starts_with(&format!(
            "cube,{},{},2,",
            s.method.as_str(),
            s.accounting.as_str()
        )));
    }
    let md = std::fs::read_to_string(out.join("table1.md")).unwrap();
    for m in [
        "| cube | volpath | frame |",
        "| cube | regularized | still |",
        "## Against the paper",
    ] {
        assert!(md.contains(m), "table1.md lacks {m}");
    }
    let run: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("run.json")).unwrap()).unwrap();
    assert_eq!(run["references"][0]["spp"], 8192);
    let _ = std::fs::remove_dir_all(&out);
}

/// Runs a table that must be refused; returns its stderr.
fn refused(args: &[&str]) -> String {
    let out = temp_dir("refused");
    let o = Command::new(env!("CARGO_BIN_EXE_mediareg"))
        .current_dir(common::root())
        .arg("table")
        .args(args)
        .args([
            "--budget",
            "0.2",
            "--reference-dir",
            "reference/table_small",
        ])
        .args(["--no-mitsuba", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let _ = std::fs::remove_dir_all(&out);
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    stderr
}

#[test]
fn a_reference_made_for_other_parameters_is_refused() {
    let stderr = refused(&["--scenes", "cube", "-D", "res=16"]);
    assert!(
        stderr.contains("was made with -D") && stderr.contains("mitsuba_reference.py"),
        "{stderr}"
    );
    let stderr = refused(&["--scenes", "bunny"]);
    assert!(
        stderr.contains("no Mitsuba 3 reference for bunny"),
        "{stderr}"
    );
}
