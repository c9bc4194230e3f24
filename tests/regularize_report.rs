//! On demand (`cargo test --release --test regularize_report -- --ignored --nocapture`):
//! the paper's method on its cube (σ_t 10, albedo 0.95, g 0.7, factor 0.95) against the
//! Mitsuba 3 reference, per variant and seed, with equal-time plain renders; writes
//! reports/regularize_cube.{md,json}.
//!
//! Accounting: a regularized frame of a sequence costs its own render plus denoising,
//! prediction and (with `--c-beta fit`) the cheap render; the other frames of the
//! sequence are paid for by the frames they are (the paper's Table 1). The plain render
//! it is compared with gets the same seconds: its spp is scaled by the measured time.

mod common;

use std::fmt::Write as _;

use common::{load_seeded, reference, root};
use glam::Vec3;
use mediareg::regularize::predict::Predictor;
use mediareg::regularize::sequence::CameraPath;
use mediareg::regularize::spatial::BilateralParams;
use mediareg::regularize::{self, CBeta, Method, Options, Reproject};
use serde_json::json;

const TARGET: Vec3 = Vec3::new(0.0, -0.1, 0.0);
const SEEDS: [u64; 3] = [101, 102, 103];
const C_BETA_GRID: [f32; 12] = [0.2, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.5, 2.0, 3.0, 5.0, 8.5];

struct Row {
    variant: &'static str,
    spp: u32,
    seconds: Vec<f64>,
    mse: Vec<f64>,
    plain_equal_time: Vec<f64>,
    c_beta: Vec<Option<f32>>,
}

/// A ratio for the table: two decimals, or powers of ten when it explodes.
fn ratio(r: f64) -> String {
    if r < 100.0 {
        format!("{r:.2}")
    } else {
        format!("{r:.1e}")
    }
}

fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

#[test]
#[ignore]
fn regularize_cube_report() {
    let cube = root().join("mitsuba_scenes/medium_cube.xml");
    let r = reference("medium_cube", &cube);
    let orbit = CameraPath::Orbit {
        degrees_per_frame: 1.0,
        target: TARGET,
    };
    let fit = Method::Paper(CBeta::Fit { spp: 4, at: 1.0 });
    let variants: Vec<(&'static str, Options)> = vec![
        (
            "temporal (orbit 1°/frame, exact), c_β 0.5",
            Options {
                path: orbit.clone(),
                ..Default::default()
            },
        ),
        (
            "temporal (orbit, Eq. 9 shift), c_β 0.5",
            Options {
                path: orbit.clone(),
                reproject: Reproject::Shift,
                ..Default::default()
            },
        ),
        (
            "temporal (orbit, exact), c_β fit",
            Options {
                path: orbit.clone(),
                method: fit,
                ..Default::default()
            },
        ),
        (
            "temporal (orbit, exact), linear",
            Options {
                path: orbit.clone(),
                method: Method::Linear,
                ..Default::default()
            },
        ),
        (
            "temporal (orbit, exact), log-linear",
            Options {
                path: orbit.clone(),
                method: Method::LogLinear,
                ..Default::default()
            },
        ),
        (
            "single frame, no denoising, c_β 0.5",
            Options {
                frames: 1,
                ..Default::default()
            },
        ),
        (
            "single frame, spatial, c_β 0.5",
            Options {
                frames: 1,
                spatial: Some(BilateralParams::default()),
                ..Default::default()
            },
        ),
        (
            "single frame, spatial, c_β fit",
            Options {
                frames: 1,
                spatial: Some(BilateralParams::default()),
                method: fit,
                ..Default::default()
            },
        ),
    ];

    let mut rows: Vec<Row> = Vec::new();
    let mut plain_rows: Vec<Row> = Vec::new();
    // For the fitted variants: c_β chosen with the reference (best on a grid) on the same renders.
    let mut sweeps = Vec::new();
    // Warm up (thread pool, caches) so that the first timed render is not slower.
    let warm = load_seeded(&cube, &[], 64, 0);
    mediareg::integrator::render(&warm, &warm.shot, &Default::default());
    for spp in [64u32, 256] {
        // Plain volpath at the target albedo: its MSE and seconds per sample.
        let mut plain = Row {
            variant: "plain volpath",
            spp,
            seconds: vec![],
            mse: vec![],
            plain_equal_time: vec![],
            c_beta: vec![],
        };
        for &seed in &SEEDS {
            let s = load_seeded(&cube, &[], spp, seed);
            let out = mediareg::integrator::render(&s, &s.shot, &Default::default());
            let (img, stats) = (out.image, out.stats);
            plain.seconds.push(stats.seconds);
            plain.mse.push(r.mse(&img.pixels));
        }
        // The median: robust to a stray slow render.
        let plain_seconds = median(&plain.seconds);
        let equal_time = |seconds: f64, seed: u64| {
            let spp_eq = ((spp as f64 * seconds / plain_seconds).round() as u32).max(1);
            let s = load_seeded(&cube, &[], spp_eq, seed + 1000);
            r.mse(
                &mediareg::integrator::render(&s, &s.shot, &Default::default())
                    .image
                    .pixels,
            )
        };
        for (name, opts) in &variants {
            let mut row = Row {
                variant: name,
                spp,
                seconds: vec![],
                mse: vec![],
                plain_equal_time: vec![],
                c_beta: vec![],
            };
            let mut sweep_mse = vec![0.0; C_BETA_GRID.len()];
            for &seed in &SEEDS {
                let s = load_seeded(&cube, &[], spp, seed);
                let out = regularize::regularize(&s, &s.shot, opts).unwrap();
                let t = &out.timings;
                let seconds = t.target_frame + t.fit + t.denoise_and_predict;
                row.seconds.push(seconds);
                row.mse.push(r.mse(&out.predicted.pixels));
                row.c_beta.push(out.c_beta);
                row.plain_equal_time.push(equal_time(seconds, seed));
                if matches!(opts.method, Method::Paper(CBeta::Fit { .. })) {
                    for (j, &c_beta) in C_BETA_GRID.iter().enumerate() {
                        let (img, _) = Predictor::Paper { c_beta }.predict(
                            &out.albedos,
                            &out.source.pixels,
                            &out.gradient.pixels,
                        );
                        sweep_mse[j] += r.mse(&img) / SEEDS.len() as f64;
                    }
                }
            }
            println!(
                "spp {spp} {name}: MSE {:.3e} (plain at equal time {:.3e}), {:.3} s, c_β {:?}",
                mean(&row.mse),
                mean(&row.plain_equal_time),
                mean(&row.seconds),
                row.c_beta
            );
            if matches!(opts.method, Method::Paper(CBeta::Fit { .. })) {
                let best = (0..C_BETA_GRID.len())
                    .min_by(|&a, &b| sweep_mse[a].total_cmp(&sweep_mse[b]))
                    .unwrap();
                let paper_default = C_BETA_GRID.iter().position(|&c| c == 0.5).unwrap();
                sweeps.push(json!({
                    "variant": name, "spp": spp,
                    "grid": C_BETA_GRID, "mse": sweep_mse,
                    "best_c_beta": C_BETA_GRID[best], "best_mse": sweep_mse[best],
                    "c_beta_0.5_mse": sweep_mse[paper_default], "fit_mse": mean(&row.mse),
                }));
            }
            rows.push(row);
        }
        plain_rows.push(plain);
    }

    // The report.
    let mut md = String::new();
    writeln!(
        md,
        "# Regularization on the cube (σ_t 10, albedo 0.95, g 0.7, factor 0.95)\n"
    )
    .unwrap();
    writeln!(md, "Made by `cargo test --release --test regularize_report -- --ignored --nocapture` (tests/regularize_report.rs): 64×64, box filter, {} seeds per cell, 2 threads, after a warm-up render; MSE against reference/medium_cube (Mitsuba 3.9.1, 8192 spp) with the reference's variance subtracted. Seconds per target frame: its render, plus denoising, prediction and the c_β fit's render; the plain render at equal time gets those seconds (its spp scaled by the median seconds of the plain renders at this spp).\n", SEEDS.len()).unwrap();
    writeln!(
        md,
        "| spp | method | seconds | MSE | plain volpath at equal time | ratio | c_β |"
    )
    .unwrap();
    writeln!(md, "|---|---|---|---|---|---|---|").unwrap();
    for p in &plain_rows {
        writeln!(
            md,
            "| {} | plain volpath | {:.3} | {:.3e} | | | |",
            p.spp,
            mean(&p.seconds),
            mean(&p.mse)
        )
        .unwrap();
        for row in rows.iter().filter(|r| r.spp == p.spp) {
            let cb: Vec<String> = row
                .c_beta
                .iter()
                .map(|c| c.map_or("-".into(), |c| format!("{c:.2}")))
                .collect();
            writeln!(
                md,
                "| {} | {} | {:.3} | {:.3e} | {:.3e} | {} | {} |",
                row.spp,
                row.variant,
                mean(&row.seconds),
                mean(&row.mse),
                mean(&row.plain_equal_time),
                ratio(mean(&row.mse) / mean(&row.plain_equal_time)),
                cb.join(", ")
            )
            .unwrap();
        }
    }
    writeln!(md, "\nThe fitted c_β against the c_β chosen with the reference (the best of {:?} on the same renders, mean MSE over seeds):\n", C_BETA_GRID).unwrap();
    writeln!(
        md,
        "| spp | variant | best c_β | its MSE | fitted c_β's MSE | c_β 0.5's MSE |"
    )
    .unwrap();
    writeln!(md, "|---|---|---|---|---|---|").unwrap();
    for s in &sweeps {
        let best = s["best_mse"].as_f64().unwrap();
        let f = |key: &str| {
            let v = s[key].as_f64().unwrap();
            format!("{v:.3e} ({:+.0}%)", 100.0 * (v / best - 1.0))
        };
        writeln!(
            md,
            "| {} | {} | {} | {best:.3e} | {} | {} |",
            s["spp"],
            s["variant"].as_str().unwrap(),
            s["best_c_beta"],
            f("fit_mse"),
            f("c_beta_0.5_mse"),
        )
        .unwrap();
    }
    let rows_json: Vec<_> = plain_rows
        .iter()
        .chain(&rows)
        .map(|r| {
            json!({"variant": r.variant, "spp": r.spp, "seconds": r.seconds, "mse": r.mse,
                   "plain_equal_time_mse": r.plain_equal_time, "c_beta": r.c_beta})
        })
        .collect();
    let dir = root().join("reports");
    std::fs::write(dir.join("regularize_cube.md"), &md).unwrap();
    std::fs::write(
        dir.join("regularize_cube.json"),
        serde_json::to_string_pretty(
            &json!({"seeds": SEEDS, "rows": rows_json, "c_beta_sweeps": sweeps}),
        )
        .unwrap(),
    )
    .unwrap();
    println!("{md}");
}
