//! `mediareg sweep` at a tiny size: the cube at 32×32 against the committed reference
//! (reference/table_small, made with -D res=32), two budgets, two seeds. Checks that
//! sweep.json says what its seed rows say: each summary row's mean corrected MSE, spp
//! and seconds are the means of its seeds' rows at its budget, every ratio interval
//! holds its mean and is the row's MSE over the best's, the best is a baseline of least
//! mean MSE, OIDN's share is its seconds over the budget, and a plot exists per
//! accounting. Seen failing with the shares computed over a budget floored at 0.15 s,
//! and (deliberately) with the spp summarized as the first seed's and the ratio taken
//! to plain volpath instead of the best. Needs OIDN (`common::oidn_present`).

mod common;

use std::path::PathBuf;
use std::process::Command;

use mediareg::report::{Accounting, Method, Row};
use serde_json::Value;

fn temp_dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("mediareg_sweep_{name}_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// `mediareg sweep` of the 32×32 cube (3 frames, no Mitsuba 3) with `args` besides, into
/// a fresh folder: the folder, sweep.json, and its seed rows.
fn sweep_cube(name: &str, args: &[&str]) -> (PathBuf, Value, Vec<(f64, Row)>) {
    let out = temp_dir(name);
    let o = Command::new(env!("CARGO_BIN_EXE_mediareg"))
        .current_dir(common::root())
        .args(["sweep", "--scenes", "cube", "--res", "32", "--frames", "3"])
        .args(["--figure-reference-dir", "reference/table_small"])
        .args(args)
        .args(["-t", "2", "--no-mitsuba", "--out"])
        .arg(&out)
        .output()
        .expect("mediareg runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let data: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("sweep.json")).unwrap()).unwrap();
    let seed_rows = serde_json::from_value(data["seed_rows"].clone()).expect("seed rows");
    (out, data, seed_rows)
}

#[test]
fn sweep_rows_summarize_their_seeds_at_each_budget() {
    let (out, data, seed_rows) = sweep_cube("rows", &["--budgets", "0.1,0.2", "--seeds", "2"]);
    let rows = data["rows"].as_array().expect("rows");
    let oidn = common::oidn_present();
    for budget in [0.1, 0.2] {
        let at: Vec<&Value> = rows.iter().filter(|r| r["budget"] == budget).collect();
        // Frame: volpath, the paper's, the default, the control (and volpath_oidn);
        // still: the same but volpath_oidn's and the default's as one image each.
        assert_eq!(
            at.len(),
            if oidn { 10 } else { 7 },
            "rows at {budget} s: {at:?}"
        );
        for r in &at {
            let method: Method = serde_json::from_value(r["method"].clone()).unwrap();
            let accounting: Accounting = serde_json::from_value(r["accounting"].clone()).unwrap();
            let own: Vec<&Row> = seed_rows
                .iter()
                .filter(|(b, s)| *b == budget && s.method == method && s.accounting == accounting)
                .map(|(_, s)| s)
                .collect();
            assert_eq!(
                own.len(),
                2,
                "{method:?} {accounting:?} at {budget} s: two seeds"
            );
            let corrected: Vec<f64> = own.iter().map(|s| s.mse_corrected).collect();
            let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * b.abs().max(1e-30);
            assert!(
                close(r["mse_corrected"].as_f64().unwrap(), mean(&corrected)),
                "{r}"
            );
            let seconds: Vec<f64> = own.iter().map(|s| s.seconds).collect();
            assert!(close(r["seconds"].as_f64().unwrap(), mean(&seconds)), "{r}");
            let spp: Vec<f64> = own.iter().map(|s| s.spp as f64).collect();
            assert!(
                spp.iter().all(|&n| n >= 1.0),
                "{method:?} at {budget} s: {spp:?}"
            );
            assert!(close(r["spp"].as_f64().unwrap(), mean(&spp)), "{r}");
            let ratio = r["ratio_to_best"].as_array().expect("a ratio with 2 seeds");
            let [m, lo, hi] = [0, 1, 2].map(|i| ratio[i].as_f64().unwrap());
            assert!(lo <= m && m <= hi, "{r}");
            let best: Method = serde_json::from_value(r["best"].clone()).unwrap();
            assert!(best.is_baseline(), "{r}");
            // The best has the least mean MSE of the baselines in its accounting.
            let of = |m: Method| {
                at.iter()
                    .find(|x| {
                        x["method"] == serde_json::to_value(m).unwrap()
                            && x["accounting"] == r["accounting"]
                    })
                    .map(|x| x["mse_corrected"].as_f64().unwrap())
            };
            let least = [
                Method::Volpath,
                Method::VolpathOidn,
                Method::VolpathFiltered,
            ]
            .into_iter()
            .filter_map(of)
            .fold(f64::INFINITY, f64::min);
            assert_eq!(of(best), Some(least), "{r}");
            // The ratio is to that best's MSE (1 exactly for the best itself).
            let want = r["mse_corrected"].as_f64().unwrap() / least;
            assert!(close(m, want), "ratio {m} against {want}: {r}");
        }
    }
    if oidn {
        let share = &data["oidn"][0];
        let t = share["oidn_seconds"].as_f64().unwrap();
        assert!(t > 0.0, "{share}");
        for pair in share["shares"].as_array().unwrap() {
            let (b, s) = (pair[0].as_f64().unwrap(), pair[1].as_f64().unwrap());
            assert!((s - t / b).abs() < 1e-12, "{share}");
        }
    }
    for accounting in ["frame", "still"] {
        let png = out.join(format!("sweep_cube_{accounting}.png"));
        assert!(
            std::fs::metadata(&png)
                .map(|m| m.len() > 1000)
                .unwrap_or(false),
            "{}",
            png.display()
        );
    }
}

/// `--methods` and `--no-still` narrow the sweep as they narrow `table`: only the named
/// methods, only the frame accounting. Seen failing before the sweep honoured them (it
/// ran all five methods and both accountings whatever was asked).
#[test]
fn sweep_renders_only_the_methods_and_accounting_asked_for() {
    let (out, _, seed_rows) = sweep_cube(
        "narrow",
        &[
            "--budgets",
            "0.1",
            "--seeds",
            "1",
            "--no-still",
            "--methods",
            "volpath,volpath_filtered",
        ],
    );
    let mut seen: Vec<(Method, Accounting)> = seed_rows
        .iter()
        .map(|(_, r)| (r.method, r.accounting))
        .collect();
    seen.sort_by_key(|(m, a)| (m.as_str(), a.as_str()));
    seen.dedup();
    assert_eq!(
        seen,
        [
            (Method::Volpath, Accounting::Frame),
            (Method::VolpathFiltered, Accounting::Frame)
        ],
        "{seen:?}"
    );
    assert!(!out.join("sweep_cube_still.png").exists());
}
