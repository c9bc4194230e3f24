//! Issue 41, item 5: `regularize` with `--frames 1` (the default choices, the whole run
//! charged) against plain volpath and plain volpath through OIDN at equal time, in
//! MSE × seconds. The three run at the same seeds (a shot's samples depend on their
//! index alone, so `regularize`'s main render is the first samples of the others'):
//! their errors move together, and the ratio's interval is the paired one (S2 in
//! `report::summary`). Measurement (ignored, minutes):
//! `cargo test --release --test never_lose -- --ignored --nocapture`
//! ($NEVER_LOSE_BUDGET seconds per method, default 2; $NEVER_LOSE_SEEDS, default 4).

mod common;

use std::time::Instant;

use mediareg::denoise::AuxUse;
use mediareg::image;
use mediareg::integrator::{self, denoised, RenderOptions};
use mediareg::regularize::{self, choices, Choices};
use mediareg::report::metrics::mse_against;
use mediareg::report::summary::paired_ratio_interval;

use common::{load_seeded, root};

/// (name, scene file, parameters, reference).
type Case = (
    &'static str,
    &'static str,
    &'static [(&'static str, &'static str)],
    &'static str,
);

/// scripts/bench's scenes, the cloud, Fig. 12's cube at albedo 0.5 and the Table 1 scenes.
const SCENES: &[Case] = &[
    ("cube", "medium_cube", &[], "medium_cube"),
    (
        "chromatic_sphere",
        "chromatic_sphere",
        &[],
        "chromatic_sphere",
    ),
    ("bunny_medium", "bunny_medium", &[], "bunny_medium"),
    (
        "bunny_two_lights",
        "bunny_two_lights",
        &[],
        "bunny_two_lights",
    ),
    ("lucy_res64", "lucy", &[("res", "64")], "bench/lucy_res64"),
    (
        "thin_cube",
        "medium_cube",
        &[("sigma_t", "1")],
        "bench/medium_cube_sigma_t1",
    ),
    (
        "dense_cube",
        "medium_cube",
        &[("sigma_t", "50")],
        "bench/medium_cube_sigma_t50",
    ),
    (
        "medium_in_dielectric",
        "medium_in_dielectric",
        &[],
        "medium_in_dielectric",
    ),
    (
        "camera_in_medium",
        "camera_in_medium",
        &[],
        "camera_in_medium",
    ),
    (
        "max_depth_directional",
        "max_depth_directional",
        &[],
        "max_depth_directional",
    ),
    ("furnace", "furnace", &[], "furnace"),
    ("cloud", "cloud", &[], "cloud"),
    (
        "fig12_cube_albedo0.5",
        "cube",
        &[("res", "128"), ("albedo", "0.5")],
        "figures/cube_res128_albedo0.5",
    ),
    ("bunny", "bunny", &[], "bunny"),
    ("candle", "candle", &[], "candle"),
    ("lucy", "lucy", &[], "lucy"),
];

#[test]
#[ignore]
fn measure_never_lose() {
    let budget: f64 = common::env_or("NEVER_LOSE_BUDGET", 2.0);
    let seeds: u64 = common::env_or("NEVER_LOSE_SEEDS", 4);
    let only = std::env::var("NEVER_LOSE_SCENES").unwrap_or_default();
    println!("| scene | spp plain | MSE×s plain | MSE×s plain+OIDN | MSE×s regularize --frames 1 | ÷ better [95% CI] | MSE ÷ | s ÷ | OIDN kept (seeds) |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (name, file, params, reference) in SCENES {
        if !only.is_empty() && !only.split(',').any(|s| s == *name) {
            continue;
        }
        let path = root().join(format!("mitsuba_scenes/{file}.xml"));
        let (reference_mean, reference_var) = common::reference_images(reference);
        let err = |img: &image::Image| mse_against(img, &reference_mean, &reference_var).1;
        let with_seen = RenderOptions {
            seen_emission: true,
            ..Default::default()
        };
        // Seconds per spp, and OIDN's seconds (both once per scene).
        let probe = load_seeded(&path, params, 1, 99);
        let mut spp = 1u32;
        let per_spp = loop {
            let r = integrator::render(&probe, &probe.shot.with(spp, 99), &with_seen);
            if r.stats.seconds >= budget / 8.0 || spp >= 1 << 16 {
                break r.stats.seconds / spp as f64;
            }
            spp *= 2;
        };
        let r = integrator::render(&probe, &probe.shot.with(1, 98), &with_seen);
        let t = Instant::now();
        denoised::oidn(&probe, &probe.shot, &r, AuxUse::None, None).unwrap();
        let t_oidn = t.elapsed().as_secs_f64();
        let spp_plain = ((budget / per_spp) as u32).max(1);
        let spp_oidn = (((budget - t_oidn) / per_spp) as u32).max(1);
        // (MSE, seconds) per seed.
        let (mut plain, mut oidn, mut reg) = (vec![], vec![], vec![]);
        let mut kept = 0;
        for seed in 0..seeds {
            let scene = load_seeded(&path, params, spp_plain, seed * 7919 + 1);
            let r = integrator::render(&scene, &scene.shot, &RenderOptions::default());
            plain.push((err(&r.image), r.stats.seconds));
            let shot = scene.shot.with(spp_oidn, seed * 7919 + 1);
            let r = integrator::render(&scene, &shot, &with_seen);
            let t = Instant::now();
            let img = denoised::oidn(&scene, &shot, &r, AuxUse::None, None).unwrap();
            oidn.push((err(&img), r.stats.seconds + t.elapsed().as_secs_f64()));
            // The default choices with one frame, the whole run charged.
            let shot = scene.shot.with(spp_oidn, seed * 7919 + 1);
            let c = Choices {
                frames: 1,
                ..Default::default()
            };
            let (opts, shot) = choices::options(&scene, &shot, &c).unwrap();
            let t = Instant::now();
            let out = regularize::regularize(&scene, &shot, &opts).unwrap();
            reg.push((err(&out.predicted), t.elapsed().as_secs_f64()));
            kept += out.oidn_check.as_ref().is_none_or(|c| c.chose_oidn) as usize;
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        let product = |v: &[(f64, f64)]| v.iter().map(|(e, s)| e * s).collect::<Vec<_>>();
        let part =
            |v: &[(f64, f64)], i: usize| mean(&v.iter().map(|p| [p.0, p.1][i]).collect::<Vec<_>>());
        let better = match mean(&product(&plain)) <= mean(&product(&oidn)) {
            true => &plain,
            false => &oidn,
        };
        let ratio = paired_ratio_interval(&product(&reg), &product(better))
            .map_or("–".into(), |[m, lo, hi]| {
                format!("{m:.3} [{lo:.3}, {hi:.3}]")
            });
        println!(
            "| {name} | {spp_plain} | {:.3e} | {:.3e} | {:.3e} | {ratio} | {:.3} | {:.3} | {kept}/{seeds} |",
            mean(&product(&plain)),
            mean(&product(&oidn)),
            mean(&product(&reg)),
            part(&reg, 0) / part(better, 0),
            part(&reg, 1) / part(better, 1),
        );
    }
}
