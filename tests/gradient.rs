//! The albedo gradient (`--gradient albedo`): d(radiance_c)/d(albedo_c) estimated in the
//! same paths as the radiance (the paper, Sec. 4.1), checked three ways.
//!
//! * Against finite differences of mediareg's own renders with common random numbers:
//!   with Russian roulette off (rr_depth ≥ max_depth) the renders at α ± h follow the same
//!   paths, each path's weight is c·α^k, and the central difference differs from the
//!   derivative k α^{k−1} c only by its truncation error, at most
//!   (K−1)(K−2)/6 · h²/α² relative for k < K = max_depth, plus float rounding.
//! * Against Mitsuba 3's own derivative of the same XML: reference/medium_cube_dalbedo,
//!   Richardson central differences of Mitsuba 3 renders with common random numbers
//!   (scripts/mitsuba_reference.py --derivative albedo), compared statistically like the
//!   radiance (tests/volpath_equivalence.rs).
//! * Power: a gradient 5% too large, and one that leaves out the vertex each NEE
//!   contribution is made from, must fail that comparison.

mod common;

use common::{
    layout, load_seeded, reference, render_gradient_chunks, render_pixels, root, ALPHA, FALSE_ALARM,
};
use mediareg::image::stats::{compare, Comparison, Estimate};
use mediareg::integrator::volpath::Estimand;
use mediareg::integrator::RenderOptions;

const CHUNKS: usize = 16;
const SPP: u32 = 128;
/// The parameters reference/medium_cube_dalbedo.json was made with.
const PARAMS: [(&str, &str); 3] = [("albedo", "0.95"), ("max_depth", "12"), ("rr_depth", "100")];

fn cube() -> std::path::PathBuf {
    root().join("mitsuba_scenes/medium_cube.xml")
}

fn render(
    params: &[(&str, &str)],
    spp: u32,
    seed: u64,
    gradient: Estimand,
) -> (Vec<[f32; 3]>, Option<Vec<[f32; 3]>>) {
    render_scene(&cube(), params, spp, seed, gradient)
}

fn render_scene(
    scene: &std::path::Path,
    params: &[(&str, &str)],
    spp: u32,
    seed: u64,
    gradient: Estimand,
) -> (Vec<[f32; 3]>, Option<Vec<[f32; 3]>>) {
    let s = load_seeded(scene, params, spp, seed);
    render_pixels(
        &s,
        RenderOptions {
            estimand: gradient,
            ..Default::default()
        },
    )
}

/// Central differences at albedo α ± h (every channel moved by h) against the gradient
/// at α, with common random numbers: `scene` must turn Russian roulette off and set its
/// albedo through `$albedo`; `alpha` per channel, `k_max` its max_depth.
fn check_finite_differences(
    scene: &std::path::Path,
    extra: &[(&str, &str)],
    alpha: [f64; 3],
    k_max: f64,
) {
    let h = 0.01f64;
    let render_at = |shift: f64, gradient| {
        // One number for a grey albedo (a <float> in the scene), three for an <rgb>.
        let a = if alpha.iter().all(|&a| a == alpha[0]) {
            (alpha[0] + shift).to_string()
        } else {
            alpha.map(|a| (a + shift).to_string()).join(", ")
        };
        let mut params = vec![("albedo", a.as_str())];
        params.extend(extra);
        render_scene(scene, &params, 16, 3, gradient)
    };
    let (plus, _) = render_at(h, Estimand::RadianceOnly);
    let (minus, _) = render_at(-h, Estimand::RadianceOnly);
    let (_, grad) = render_at(0.0, Estimand::AlbedoDerivative(0));
    let grad = grad.unwrap();
    let mut worst = 0.0f64;
    let mut nonzero = 0;
    for i in 0..grad.len() {
        for c in 0..3 {
            // Truncation: Σ c_k [C(k,3) α^{k−3} h² + …] ≤ G (K−1)(K−2)/6 · h²/α² (1 + 1%).
            let trunc = (k_max - 1.0) * (k_max - 2.0) / 6.0 * h * h / (alpha[c] * alpha[c]) * 1.01;
            // Rounding: each render's pixel is exact to ~1e-5 relative (f32 path arithmetic
            // and accumulation), and the difference is divided by 2h.
            let round = 1e-5 / (2.0 * h);
            let fd = (plus[i][c] as f64 - minus[i][c] as f64) / (2.0 * h);
            let g = grad[i][c] as f64;
            let tol = g.abs() * trunc + round * (plus[i][c].abs() + minus[i][c].abs()) as f64;
            let excess = (fd - g).abs() / tol.max(1e-12);
            worst = worst.max(excess);
            assert!(
                (fd - g).abs() <= tol,
                "pixel {i} channel {c}: finite difference {fd} vs gradient {g} (tolerance {tol})"
            );
            if g > 0.0 {
                nonzero += 1;
            }
        }
    }
    assert!(nonzero > grad.len(), "the gradient image is (nearly) empty");
    println!("largest |FD − G| / tolerance: {worst:.3}");
}

#[test]
fn gradient_matches_finite_differences_with_common_random_numbers() {
    check_finite_differences(
        &cube(),
        &[("max_depth", "12"), ("rr_depth", "100")],
        [0.95; 3],
        12.0,
    );
}

/// The same for a chromatic medium around the camera (spectral MIS over channels, RGB
/// albedo) with emitters inside it and a surface in it.
#[test]
fn gradient_matches_finite_differences_in_a_chromatic_medium_with_emitters_inside() {
    check_finite_differences(
        &root().join("tests/fixtures/gradient_chromatic.xml"),
        &[],
        [0.9, 0.7, 0.95],
        12.0,
    );
}

fn check(gradient: Estimand, scale: f32, seed: u64) -> Comparison {
    let r = reference("medium_cube_dalbedo", &cube());
    let mut chunks = render_gradient_chunks(&cube(), &PARAMS, CHUNKS, SPP, seed, gradient);
    for img in &mut chunks {
        for p in img.iter_mut() {
            *p = p.map(|v| v * scale);
        }
    }
    let layout = layout(&cube(), &PARAMS);
    let ours = Estimate::from_chunks(&chunks, layout);
    let c = compare(&ours, &r.estimate, layout, ALPHA, FALSE_ALARM);
    println!("gradient {gradient:?} x{scale}: {c}");
    c
}

#[test]
fn gradient_matches_mitsuba_derivative() {
    let c = check(Estimand::AlbedoDerivative(0), 1.0, 31);
    assert!(c.passed, "{c}");
}

#[test]
fn comparison_detects_gradient_five_percent_too_large() {
    let c = check(Estimand::AlbedoDerivative(0), 1.05, 32);
    assert!(!c.passed, "a gradient scaled by 1.05 went undetected: {c}");
}

#[test]
fn comparison_detects_gradient_ignoring_nee_vertices() {
    let c = check(Estimand::AlbedoDerivativeIgnoringNeeVertex(0), 1.0, 33);
    assert!(
        !c.passed,
        "a gradient that ignores NEE vertices went undetected: {c}"
    );
}

/// Same paths: asking for the gradient leaves the radiance image bit for bit the same
/// where Russian roulette does not run.
#[test]
fn gradient_does_not_change_the_radiance() {
    let p = [("max_depth", "12"), ("rr_depth", "100")];
    let (plain, _) = render(&p, 8, 5, Estimand::RadianceOnly);
    let (with, _) = render(&p, 8, 5, Estimand::AlbedoDerivative(0));
    assert!(plain
        .iter()
        .zip(&with)
        .all(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits)));
}

/// The command line: several media need --medium (the error lists them), an unknown id
/// is named, and the path integrator (which ignores media) is refused.
#[test]
fn gradient_command_line_errors() {
    let run = |scene: &std::path::Path, extra: &[&str]| {
        let out = std::env::temp_dir().join(format!("mediareg_grad_{}.exr", std::process::id()));
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_mediareg"))
            .arg("render")
            .arg(scene)
            .args(["--gradient", "albedo", "--spp", "1", "--no-png", "-o"])
            .arg(&out)
            .args(extra)
            .output()
            .expect("run mediareg");
        assert!(!o.status.success(), "expected failure");
        assert!(!out.exists(), "no output on error");
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let two = root().join("tests/bad_input/two_media.xml");
    let e = run(&two, &[]);
    assert!(
        e.contains("--medium") && e.contains("milk") && e.contains("wax"),
        "{e}"
    );
    let e = run(&two, &["--medium", "honey"]);
    assert!(e.contains("honey") && e.contains("milk"), "{e}");
    let e = run(&root().join("mitsuba_scenes/cbox.xml"), &[]);
    assert!(e.contains("volpath"), "{e}");
}

/// The spatial denoiser on a real gradient: guided by the first hit's depth and normal
/// and the radiance, it lowers the gradient's error against Mitsuba 3's derivative (the
/// reference's own variance is subtracted from both MSEs).
#[test]
fn spatial_denoising_lowers_the_gradient_error() {
    use mediareg::regularize::spatial::{denoise, first_hit_features, BilateralParams};
    let r = reference("medium_cube_dalbedo", &cube());
    let s = load_seeded(&cube(), &PARAMS, 32, 41);
    let out = mediareg::integrator::render(
        &s,
        &s.shot,
        &RenderOptions {
            show_progress: false,
            estimand: Estimand::AlbedoDerivative(0),
            ..Default::default()
        },
    );
    let grad = out.gradient.unwrap().pixels;
    let features = first_hit_features(&s, &s.shot);
    assert!(
        features.depth.iter().any(|d| d.is_infinite()),
        "the sky is visible"
    );
    assert!(features
        .normal
        .iter()
        .zip(&features.depth)
        .all(|(n, d)| !d.is_finite() || (n.length() - 1.0).abs() < 1e-3));
    let width = s.shot.film.crop_size.0;
    let denoised = denoise(
        &grad,
        &out.image.pixels,
        &features,
        width,
        &BilateralParams::default(),
    );
    let mse = |img: &[[f32; 3]]| r.mse(img);
    let (raw, filtered) = (mse(&grad), mse(&denoised));
    println!("gradient MSE vs Mitsuba (reference variance subtracted): raw {raw:.3e}, denoised {filtered:.3e}");
    assert!(
        filtered < raw / 2.0,
        "raw {raw:.3e}, denoised {filtered:.3e}"
    );
}

/// R(α_t) from paths rendered at α_s: each render's R_s + D (`Estimand::AlbedoDifference`,
/// D = f ((α_t / α_s)^k − 1) per path) at α_s = 0.9 α_t.
fn reweighted_chunks(target: f32, seed: u64) -> Vec<Vec<[f32; 3]>> {
    let scene = root().join("mitsuba_scenes/medium_cube.xml");
    (0..16u64)
        .map(|i| {
            let s = load_seeded(&scene, &[("albedo", "0.855")], 128, seed + i);
            let opts = RenderOptions {
                estimand: Estimand::AlbedoDifference {
                    medium: 0,
                    target: glam::Vec3::splat(target),
                },
                ..Default::default()
            };
            let r = mediareg::integrator::render(&s, &s.shot, &opts);
            let d = r.gradient.expect("a difference was asked for").pixels;
            r.image
                .pixels
                .iter()
                .zip(&d)
                .map(|(a, b)| [0, 1, 2].map(|c| a[c] + b[c]))
                .collect()
        })
        .collect()
}

fn check_reweighted(target: f32, seed: u64) -> Comparison {
    let scene = root().join("mitsuba_scenes/medium_cube.xml");
    let r = reference("medium_cube", &scene);
    let layout = layout(&scene, &[]);
    let ours = Estimate::from_chunks(&reweighted_chunks(target, seed), layout);
    let c = compare(&ours, &r.estimate, layout, ALPHA, FALSE_ALARM);
    println!("R_s + D at 0.855 -> {target}: {c}");
    c
}

/// The difference is unbiased: R_s + D rendered at α_s = 0.855 matches Mitsuba 3's
/// image at α_t = 0.95.
#[test]
fn difference_from_a_lower_albedo_matches_mitsuba_at_the_target() {
    let c = check_reweighted(0.95, 51);
    assert!(c.passed, "{c}");
}

/// Power: extrapolating to 0.94 instead must fail against the image at 0.95.
#[test]
fn difference_to_the_wrong_target_is_detected() {
    let c = check_reweighted(0.94, 52);
    assert!(!c.passed, "a 1% wrong target went undetected: {c}");
}
