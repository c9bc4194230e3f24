//! `mediareg fit` (`mediareg::fit`): a thin cube's medium recovered from an image Mitsuba
//! 3 rendered (tests/fixtures/fit/thin_cube_mitsuba.exr: medium_cube.xml at sigma_t 2.5,
//! albedo 0.8, g 0.5, 64×64, max_depth 64, scalar_rgb volpath at 2048 spp, seed 7; made
//! by scripts/fit_against_mitsuba), from sigma_t 1.2, albedo 0.6, g 0; and a parameter
//! pair the images cannot tell apart (sigma_t and scale multiply) reported as
//! undetermined instead of with a confident interval; a grid medium's density scale
//! from Mitsuba 3's image of the cloud, the medium at its new scale rendering as the
//! one loaded at it; a chromatic albedo (one unknown per channel); and the `mediareg
//! fit` command with two targets, one under its own `@light=...`.

mod common;

use common::root;
use mediareg::fit::{fit, FitSettings, FitTarget};
use mediareg::integrator::MediumParam;
use mediareg::{load_scene, xml, BuildOverrides};

fn cube(defines: &[(&str, &str)]) -> mediareg::scene::Scene {
    let mut params: Vec<(String, String)> = [("res", "64"), ("max_depth", "64")]
        .iter()
        .chain(defines)
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    params.dedup_by(|a, b| a.0 == b.0);
    let opts = xml::LoadOptions {
        params,
        ..Default::default()
    };
    load_scene(
        &root().join("mitsuba_scenes/medium_cube.xml"),
        &opts,
        &BuildOverrides::default(),
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

/// The fixture, refused where its bytes are not those its JSON records (as reference/'s
/// images are).
fn target() -> mediareg::image::Image {
    let dir = root().join("tests/fixtures/fit");
    let meta: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("thin_cube_mitsuba.json")).expect("the fixture's JSON"),
    )
    .expect("valid JSON");
    let path = dir.join("thin_cube_mitsuba.exr");
    let digest = common::sha256_hex(&path);
    assert_eq!(
        meta["sha256"].as_str(),
        Some(digest.as_str()),
        "{} is not the image its JSON records (scripts/fit_against_mitsuba made it)",
        path.display()
    );
    mediareg::image::read_exr(&path).unwrap()
}

fn settings(params: &[MediumParam], iterations: u32) -> FitSettings {
    FitSettings {
        medium: None,
        params: params.to_vec(),
        spp: 8,
        iterations,
        max_iterations: iterations,
        seed: 1,
        cancel: None,
    }
}

/// Over seeds 1-3: absorption σ_t(1 − α) and reduced scattering σ_t α (1 − g) within
/// 5%; each parameter within (σ_t 5%, albedo 0.02, g 0.05) of Mitsuba's *and* inside its
/// interval, which must be bounded and no wider than twice that tolerance either side
/// (an unbounded or uninformative interval fails); the fit settled (it may grow to twice its
/// plan); the start outside every σ_t interval (power: the fit moved, and says how far).
/// Measured (2026-12-07): σ_t 2.475-2.525, albedo 0.798-0.803, g 0.494-0.506, the
/// intervals' half-widths 0.12-0.16, 0.011-0.016 and 0.029-0.042 (the seeds' spread well
/// inside them; seed 2 grew to 180 iterations); seen failing with the intervals shrunk
/// 4× (the truth outside on seed 1).
#[test]
fn thin_cube_fit_recovers_mitsuba_medium() {
    let start = [("sigma_t", "1.2"), ("albedo", "0.6"), ("g", "0")];
    let truth = [2.5, 0.8, 0.5];
    let tolerance = [0.125, 0.02, 0.05];
    let params = [MediumParam::SigmaT, MediumParam::Albedo, MediumParam::G];
    for seed in 1..=3 {
        let mut targets = vec![FitTarget {
            scene: cube(&start),
            image: target(),
        }];
        let s = FitSettings {
            seed,
            max_iterations: 240,
            ..settings(&params, 120)
        };
        let r = fit(&mut targets, &s, |_| {}).unwrap();
        let [sg, a, g] = [r.values[0] as f64, r.values[1] as f64, r.values[2] as f64];
        println!(
            "seed {seed}: fit in {:.1} s ({} iterations): sigma_t {sg:.4} albedo {a:.4} g {g:.4}, intervals {:?}, converged {}",
            r.seconds, r.iterations, r.ci, r.converged
        );
        let absorption = sg * (1.0 - a) / (2.5 * 0.2);
        let reduced = sg * a * (1.0 - g) / (2.5 * 0.8 * 0.5);
        assert!(
            (absorption - 1.0).abs() < 0.05,
            "seed {seed}: absorption off by {absorption}"
        );
        assert!(
            (reduced - 1.0).abs() < 0.05,
            "seed {seed}: reduced scattering off by {reduced}"
        );
        for i in 0..3 {
            let [lo, hi] = r.ci[i].map(|c| c as f64);
            let v = r.values[i] as f64;
            let name = r.unknowns[i].label();
            assert!(
                (v - truth[i]).abs() <= tolerance[i],
                "seed {seed}: {name} {v} against {}",
                truth[i]
            );
            assert!(
                lo <= truth[i] && truth[i] <= hi,
                "seed {seed}: {name}'s interval [{lo}, {hi}] misses {}",
                truth[i]
            );
            assert!(
                lo.is_finite() && hi.is_finite() && hi - lo <= 4.0 * tolerance[i],
                "seed {seed}: {name}'s interval [{lo}, {hi}] says little"
            );
        }
        assert!(!(r.ci[0][0] <= 1.2 && 1.2 <= r.ci[0][1]), "{:?}", r.ci[0]);
        assert!(r.converged, "seed {seed}: not settled in {}", r.iterations);
    }
}

/// A fit whose estimate is still moving when its planned iterations end goes on (the
/// plan growing by half) until it settles or reaches `max_iterations`, along the same
/// iterates; with `max_iterations` equal to the plan it stops there and says it had
/// not settled.
#[test]
fn an_unsettled_fit_goes_on_until_it_settles() {
    let start = [("sigma_t", "1.2"), ("albedo", "0.6"), ("g", "0")];
    let params = [MediumParam::SigmaT, MediumParam::Albedo, MediumParam::G];
    let run = |max_iterations: u32| {
        let mut targets = vec![FitTarget {
            scene: cube(&start),
            image: target(),
        }];
        let s = FitSettings {
            max_iterations,
            ..settings(&params, 20)
        };
        fit(&mut targets, &s, |_| {}).unwrap()
    };
    let fixed = run(20);
    let grown = run(120);
    println!(
        "fixed: {} iterations, converged {}, sigma_t {}; grown: {} iterations, converged {}, sigma_t {} {:?}",
        fixed.iterations, fixed.converged, fixed.values[0], grown.iterations, grown.converged,
        grown.values[0], grown.ci
    );
    assert_eq!(fixed.iterations, 20);
    assert!(
        !fixed.converged,
        "20 iterations from the start should not settle"
    );
    // The plans: 20, 30, 45, 68, 102, then the cap.
    assert!(
        [30, 45, 68, 102].contains(&grown.iterations),
        "{}",
        grown.iterations
    );
    assert!(
        grown.converged && grown.iterations < 120,
        "the grown fit must settle before its cap: {} iterations, converged {}",
        grown.iterations,
        grown.converged
    );
    assert_eq!(
        fixed.loss[..],
        grown.loss[..20],
        "the same iterates up to the first plan"
    );
    let off = |r: &mediareg::fit::FitResult| (r.values[0] as f64 / 2.5 - 1.0).abs();
    assert!(
        off(&grown) < off(&fixed),
        "going on brought sigma_t nearer 2.5"
    );
}

/// sigma_t and scale enter only as their product: the fit's intervals for both must be
/// unbounded, and those of a parameter the images do fix (the albedo) bounded.
#[test]
fn a_parameter_the_images_cannot_fix_is_reported_undetermined() {
    let mut targets = vec![FitTarget {
        scene: cube(&[("sigma_t", "2.5"), ("albedo", "0.8"), ("g", "0.5")]),
        image: target(),
    }];
    let params = [MediumParam::SigmaT, MediumParam::Scale, MediumParam::Albedo];
    let r = fit(&mut targets, &settings(&params, 6), |_| {}).unwrap();
    println!("intervals {:?}", r.ci);
    for i in 0..2 {
        assert!(
            r.ci[i][0] == f32::NEG_INFINITY && r.ci[i][1] == f32::INFINITY,
            "{}: {:?}",
            r.unknowns[i].label(),
            r.ci[i]
        );
    }
    assert!(
        r.ci[2][0].is_finite() && r.ci[2][1].is_finite(),
        "albedo {:?}",
        r.ci[2]
    );
}

/// The cloud (a grid medium) at density `scale`, 8 spp a render.
fn cloud(scale: &str) -> mediareg::scene::Scene {
    common::load_seeded(
        &root().join("mitsuba_scenes/cloud.xml"),
        &[("scale", scale)],
        8,
        3,
    )
}

/// A fit moves a grid medium's scale by `Medium::set_scale`, which makes its majorants
/// again: the medium must render as the one loaded at that scale, bit for bit. Power:
/// the scale changed without the majorants renders otherwise.
#[test]
fn a_grid_medium_set_to_a_scale_renders_as_loaded_at_it() {
    let loaded = cloud("8");
    let mut moved = cloud("4");
    let mut stale = cloud("4");
    moved.media[0].set_scale(8.0);
    let h = stale.media[0].heterogeneous.as_mut().unwrap();
    h.scale = 8.0;
    stale.media[0].scale = 8.0;
    let render = |s: &mediareg::scene::Scene| {
        common::render_pixels(s, mediareg::integrator::RenderOptions::default()).0
    };
    let want = render(&loaded);
    assert!(
        render(&moved) == want,
        "set_scale(8) renders otherwise than scale 8 loaded"
    );
    assert!(
        render(&stale) != want,
        "a stale majorant rendered as the loaded scale"
    );
}

/// The cloud's density scale from Mitsuba 3's image of it (reference/cloud.exr: scale
/// 8), from 4: within 5% and inside its bounded interval (measured 7.995 [7.908, 8.084]),
/// the start outside. (At 8 spp an iteration the cloud's fireflies swamp the residual;
/// 64 spp do not.)
#[test]
fn grid_scale_fit_recovers_mitsuba_cloud() {
    let image = mediareg::image::read_exr(&root().join("reference/cloud.exr")).unwrap();
    let mut targets = vec![FitTarget {
        scene: cloud("4"),
        image,
    }];
    let settings = FitSettings {
        spp: 64,
        ..settings(&[MediumParam::Scale], 30)
    };
    let r = fit(&mut targets, &settings, |_| {}).unwrap();
    let scale = r.values[0] as f64;
    println!(
        "fit in {:.1} s: scale {scale:.4}, interval {:?}, converged {}",
        r.seconds, r.ci, r.converged
    );
    let inside = r.ci[0][0] as f64 <= 8.0 && 8.0 <= r.ci[0][1] as f64;
    assert!(
        (scale - 8.0).abs() <= 0.4 && inside && r.ci[0][1].is_finite() && r.ci[0][0].is_finite(),
        "scale {scale}, interval {:?}",
        r.ci[0]
    );
    assert!(!(r.ci[0][0] <= 4.0 && 4.0 <= r.ci[0][1]), "{:?}", r.ci[0]);
}

/// A chromatic albedo is fitted per channel (three unknowns): the chromatic sphere's
/// albedo from Mitsuba 3's image of it (reference/chromatic_sphere.exr: albedo 0.9, 0.7,
/// 0.95), from 0.7, 0.5, 0.8, σ_t and g at the scene's values. Each channel within 0.02
/// and inside its bounded interval; power: every interval excludes its start.
#[test]
fn a_chromatic_albedo_is_fitted_per_channel() {
    let (image, _) = common::reference_images("chromatic_sphere");
    let scene = common::load_seeded(
        &root().join("mitsuba_scenes/chromatic_sphere.xml"),
        &[("albedo", "0.7, 0.5, 0.8")],
        8,
        1,
    );
    let mut targets = vec![FitTarget { scene, image }];
    let r = fit(&mut targets, &settings(&[MediumParam::Albedo], 40), |_| {}).unwrap();
    println!(
        "fit in {:.1} s: {:?} {:?}, intervals {:?}, converged {}",
        r.seconds,
        r.unknowns.iter().map(|u| u.label()).collect::<Vec<_>>(),
        r.values,
        r.ci,
        r.converged
    );
    assert_eq!(r.unknowns.len(), 3, "one unknown per channel");
    for (c, (truth, start)) in [(0.9, 0.7), (0.7, 0.5), (0.95, 0.8)]
        .into_iter()
        .enumerate()
    {
        let v = r.values[c] as f64;
        let [lo, hi] = r.ci[c].map(|x| x as f64);
        assert!((v - truth).abs() <= 0.02, "albedo[{c}] {v} against {truth}");
        assert!(
            lo.is_finite() && hi.is_finite() && lo <= truth && truth <= hi,
            "albedo[{c}]'s interval [{lo}, {hi}] against {truth}"
        );
        assert!(!(lo <= start && start <= hi), "albedo[{c}] did not move");
    }
}

/// `mediareg fit` itself, with two targets, the second rendered under another light
/// (`--target IMAGE@light=...`): the albedo of cube_movable_light.xml (σ_t 4, g 0.5)
/// from 0.6, the targets mediareg's own renders at albedo 0.8 (1024 spp). Recovered: the
/// JSON's value within 0.01 and inside its interval, at most 0.01 wide (measured 0.799
/// [0.7975, 0.8005]). Power: the second target given without its `@light=...` (so
/// fitted under the first light) is not (measured 0.787 [0.755, 0.820]: the mismatch
/// widens the interval, as it should, and moves the value).
#[test]
fn the_fit_command_fits_targets_under_their_own_parameters() {
    use std::process::Command;
    let dir = common::scene_text::tmp_dir("fit", "cli");
    let scene = root().join("tests/fixtures/fit/cube_movable_light.xml");
    let back = "light=1.4,0.2,-1.3";
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_mediareg"))
            .args(args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    let common_defines = ["-D", "sigma_t=4", "-D", "g=0.5"];
    let scene_arg = scene.to_str().unwrap();
    for (name, light) in [("front", None), ("back", Some(back))] {
        let out = dir.join(format!("{name}.exr"));
        let mut args = vec!["render", scene_arg, "--spp", "1024", "--seed", "11"];
        args.extend(common_defines);
        args.extend(["-D", "albedo=0.8"]);
        if let Some(l) = light {
            args.extend(["-D", l]);
        }
        args.extend(["-o", out.to_str().unwrap()]);
        run(&args);
    }
    let fitted = |second: &str| {
        let out = dir.join("fit.json");
        let mut args = vec!["fit", scene_arg];
        args.extend(common_defines);
        args.extend(["-D", "albedo=0.6", "--params", "albedo", "--spp", "8"]);
        args.extend(["--iterations", "30", "--target"]);
        let first = dir.join("front.exr");
        args.push(first.to_str().unwrap());
        args.extend(["--target", second, "-o", out.to_str().unwrap()]);
        run(&args);
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        let value = json["params"]["albedo"].as_f64().unwrap();
        let ci = json["ci"]["albedo"].as_array().unwrap().clone();
        let [lo, hi] = [0, 1].map(|i| ci[i].as_f64().unwrap_or(f64::NAN));
        println!("{second}: albedo {value} [{lo}, {hi}]");
        (value, lo, hi)
    };
    let recovered = |(v, lo, hi): (f64, f64, f64)| {
        (v - 0.8).abs() <= 0.01 && lo <= 0.8 && 0.8 <= hi && hi - lo <= 0.01
    };
    let back_exr = dir.join("back.exr");
    let good = fitted(&format!("{}@{back}", back_exr.display()));
    assert!(recovered(good), "albedo {good:?} (value, interval)");
    let wrong = fitted(back_exr.to_str().unwrap());
    assert!(
        !recovered(wrong),
        "a target fitted under the wrong light passed too: {wrong:?}"
    );
}
