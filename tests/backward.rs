//! Reverse mode in a grid medium's voxels (`integrator::backward`, `mediareg backward`)
//! on `mitsuba_scenes/grid_adjoint.xml` (8³ sigma_t and albedo grids, L = Σ A · I with
//! A = grid_adjoint_A.exr):
//! * against forward mode, which matches Mitsuba 3 (tests/derivatives.rs): for σ_t =
//!   scale · data, Σ_v data_v ∂L/∂data_v = scale ∂L/∂scale, and for α = factor · data,
//!   Σ_v data_v ∂L/∂data_v = ∂L/∂factor (summed over channels);
//! * against Mitsuba 3: the directional derivatives ⟨∇L, V⟩ along three fields V
//!   (smooth, a box, white noise) against Richardson finite differences of Mitsuba 3's
//!   renders (reference/derivatives/grid_adjoint.json, scripts/grid_adjoint_references);
//! * where σ_t = 0 (empty voxels), against one-sided Richardson finite differences of
//!   mediareg's own renders: delta tracking never samples there, the ghost paths do.
//!
//! Every comparison is a Welch t-test over seeds at a per-comparison level that keeps the
//! file's false-alarm probability below FALSE_ALARM (Bonferroni over COMPARISONS). Power:
//! a gradient 5% too large, one with its sign flipped, and the estimators without the
//! transmittance's terms, without the scattering weight's, and without ghosts must fail.

mod common;

use std::path::{Path, PathBuf};

use common::{load_seeded, root};
use mediareg::image::Image;
use mediareg::integrator::backward::{backward, BackwardOptions, Gradients};
use mediareg::integrator::volpath::AdjointDefect;
use mediareg::integrator::{derivative_images, medium_gradient, MediumParam, RenderOptions};
use mediareg::medium::grid::{parse_vol, write_vol, GridData};
use mediareg::scene::Scene;
use statrs::distribution::{ContinuousCDF, StudentsT};

const FALSE_ALARM: f64 = 1e-3;
const COMPARISONS: f64 = 24.0;

fn scene_path() -> PathBuf {
    root().join("mitsuba_scenes/grid_adjoint.xml")
}

fn adjoint_image() -> Image {
    mediareg::image::read_exr(&root().join("mitsuba_scenes/grid_adjoint_A.exr")).unwrap()
}

fn grid(name: &str) -> GridData {
    let path = root().join("mitsuba_scenes/volumes").join(name);
    parse_vol(&std::fs::read(&path).unwrap()).unwrap()
}

fn dot(a: &[f32], b: &[f32]) -> f64 {
    a.iter().zip(b).map(|(x, y)| *x as f64 * *y as f64).sum()
}

/// Mean and standard error of per-seed values.
fn mean_se(x: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let m = x.iter().sum::<f64>() / n;
    let var = x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

/// Welch's t of two estimates (mean, se, dof) and whether it lies within the critical
/// value of the file's per-comparison level.
fn agree(a: (f64, f64, f64), b: (f64, f64, f64)) -> (f64, bool) {
    let (va, vb) = (a.1 * a.1, b.1 * b.1);
    let t = (a.0 - b.0) / (va + vb).sqrt();
    let dof = (va + vb).powi(2) / (va * va / a.2 + vb * vb / b.2);
    let crit = StudentsT::new(0.0, 1.0, dof)
        .unwrap()
        .inverse_cdf(1.0 - FALSE_ALARM / COMPARISONS / 2.0);
    (t, t.abs() <= crit)
}

fn with_dof(x: &[f64]) -> (f64, f64, f64) {
    let (m, s) = mean_se(x);
    (m, s, x.len() as f64 - 1.0)
}

/// The scene at `seed` and `spp`, its sigma_t grid replaced by `sigma_t_file` if given.
fn scene(spp: u32, seed: u64, sigma_t_file: Option<&Path>) -> Scene {
    let file = sigma_t_file.map(|p| p.display().to_string());
    let params: Vec<(&str, &str)> = file.iter().map(|f| ("sigma_t_file", f.as_str())).collect();
    load_seeded(&scene_path(), &params, spp, seed)
}

fn gradients(s: &Scene, defect: Option<AdjointDefect>) -> Gradients {
    let opts = BackwardOptions {
        medium: 0,
        sigma_t: true,
        albedo: true,
        defect,
        ..Default::default()
    };
    backward(s, &s.shot, &adjoint_image(), &opts).unwrap()
}

/// Σ A · I of one render.
fn loss(s: &Scene) -> f64 {
    let img = mediareg::integrator::render(s, &s.shot, &RenderOptions::default()).image;
    let a = adjoint_image();
    img.pixels
        .iter()
        .zip(&a.pixels)
        .map(|(i, a)| (0..3).map(|c| i[c] as f64 * a[c] as f64).sum::<f64>())
        .sum()
}

/// Per seed: Σ data · ∂L/∂data of sigma_t / scale and of the albedo, by reverse mode.
fn adjoint_identities(seeds: u64, spp: u32, defect: Option<AdjointDefect>) -> [Vec<f64>; 2] {
    let (sig, alb) = (
        grid("grid_adjoint_sigma_t.vol"),
        grid("grid_adjoint_albedo.vol"),
    );
    let mut out = [Vec::new(), Vec::new()];
    for seed in 0..seeds {
        let s = scene(spp, seed, None);
        let scale = s.media[0].heterogeneous.as_ref().unwrap().scale as f64;
        let g = gradients(&s, defect);
        out[0].push(dot(&sig.data, g.sigma_t.as_ref().unwrap()) / scale);
        out[1].push(dot(&alb.data, g.albedo.as_ref().unwrap()));
    }
    out
}

/// Per seed: ∂L/∂scale and ∂L/∂(albedo factor) summed over channels, by forward mode.
fn forward_derivatives(seeds: u64, spp: u32) -> [Vec<f64>; 2] {
    let a = adjoint_image();
    let params = [MediumParam::Scale, MediumParam::Albedo];
    let mut out = [Vec::new(), Vec::new()];
    for seed in 0..seeds {
        let s = scene(spp, 1000 + seed, None);
        let (gradient, mi) = medium_gradient(&s, Some("fog"), &params).unwrap();
        let opts = RenderOptions {
            estimand: gradient,
            ..Default::default()
        };
        let r = mediareg::integrator::render(&s, &s.shot, &opts);
        for (k, (_, img)) in derivative_images(&s, mi, &params, &r)
            .into_iter()
            .enumerate()
        {
            let img = img.unwrap();
            let v = img
                .pixels
                .iter()
                .zip(&a.pixels)
                .map(|(d, a)| (0..3).map(|c| d[c] as f64 * a[c] as f64).sum::<f64>())
                .sum();
            out[k].push(v);
        }
    }
    out
}

/// The adjoint's Σ data ∂L/∂data equals forward mode's scale ∂L/∂scale (sigma_t) and
/// ∂L/∂factor (albedo). Power: 1.05× and negated adjoints, and the estimators without
/// the transmittance's or the scattering weight's terms, are rejected.
#[test]
fn adjoint_agrees_with_forward_mode() {
    let (seeds, spp) = (16, 256);
    let adj = adjoint_identities(seeds, spp, None);
    let fwd = forward_derivatives(seeds, spp);
    for (k, name) in ["sigma_t", "albedo"].iter().enumerate() {
        let (a, f) = (with_dof(&adj[k]), with_dof(&fwd[k]));
        let (t, ok) = agree(a, f);
        eprintln!(
            "{name}: adjoint {:.5e} ± {:.1e}, forward {:.5e} ± {:.1e}, t {t:.2}",
            a.0, a.1, f.0, f.1
        );
        assert!(ok, "{name}: adjoint {a:?} vs forward {f:?}: t = {t}");
        for (what, factor) in [("5% too large", 1.05), ("negated", -1.0)] {
            let (t, ok) = agree((a.0 * factor, a.1 * factor.abs(), a.2), f);
            assert!(!ok, "{name} {what} undetected: t = {t}");
        }
    }
    for (defect, k) in [
        (AdjointDefect::Transmittance, 0),
        (AdjointDefect::Scattering, 0),
        (AdjointDefect::Scattering, 1),
    ] {
        let wrong = adjoint_identities(seeds / 2, spp, Some(defect));
        let (t, ok) = agree(with_dof(&wrong[k]), with_dof(&fwd[k]));
        assert!(!ok, "{defect:?} (quantity {k}) undetected: t = {t}");
    }
}

/// Every gradient value finite on hard grids: all voxels empty, a 1000:1 density range,
/// and optical depth about 50 across the box.
#[test]
fn hard_grids_stay_finite() {
    let dir = std::env::temp_dir().join(format!("mediareg_backward_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let n = 512;
    let cases: [(&str, Vec<f32>, f32); 3] = [
        ("empty", vec![0.0; n], 1.25),
        (
            "range",
            (0..n)
                .map(|i| if i % 3 == 0 { 1.0 } else { 1e-3 })
                .collect(),
            1.25,
        ),
        (
            "thick",
            (0..n).map(|i| 6.0 + (i % 5) as f32).collect(),
            12.5,
        ),
    ];
    for (name, data, max) in cases {
        let path = dir.join(format!("{name}.vol"));
        std::fs::write(&path, write_vol([8, 8, 8], 1, &data)).unwrap();
        let file = path.display().to_string();
        let max = max.to_string();
        let params = [
            ("sigma_t_file", file.as_str()),
            ("sigma_t_max", max.as_str()),
        ];
        let s = load_seeded(&scene_path(), &params, 16, 3);
        let g = gradients(&s, None);
        for (what, v) in [("sigma_t", &g.sigma_t), ("albedo", &g.albedo)] {
            let v = v.as_ref().unwrap();
            assert!(v.iter().all(|x| x.is_finite()), "{name}: {what} not finite");
            // With no density there is no scattering, so the albedo has no gradient.
            let expect_some = !(name == "empty" && what == "albedo");
            assert_eq!(v.iter().any(|x| *x != 0.0), expect_some, "{name}: {what}");
        }
    }
}

/// Mitsuba 3's derivatives of the grid scene (reference/derivatives/grid_adjoint.json,
/// scripts/grid_adjoint_references).
fn mitsuba_derivatives() -> serde_json::Value {
    let text =
        std::fs::read_to_string(root().join("reference/derivatives/grid_adjoint.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// One of its estimates as (mean, standard error, degrees of freedom): over its own
/// seeds where it names them (finite differences), else over reverse mode's.
fn mitsuba_estimate(m: &serde_json::Value, reference: &serde_json::Value) -> (f64, f64, f64) {
    let seeds = m["seeds"]
        .as_f64()
        .unwrap_or_else(|| reference["ad"]["seeds"].as_f64().unwrap());
    (
        m["mean"].as_f64().unwrap(),
        m["se"].as_f64().unwrap(),
        seeds - 1.0,
    )
}

/// Where the density is 0 (a box of empty voxels, V its indicator), the adjoint's
/// ⟨∇L, V⟩ agrees with the one-sided Richardson difference 2 D(h/2) − D(h),
/// D(h) = (L(x + hV) − L(x)) / h, of mediareg's renders (the same seed at each point)
/// and of Mitsuba 3's (reference/derivatives/grid_adjoint.json, `one_sided.zero`).
/// Power: without ghost paths the in-scattering a density would bring there is missed.
#[test]
fn empty_voxels_get_their_in_scattering_gradient() {
    let base = grid("grid_adjoint_sigma_t.vol");
    let v: Vec<f32> = base.data.iter().map(|&x| (x == 0.0) as u8 as f32).collect();
    assert!(v.iter().sum::<f32>() >= 8.0, "the grid has empty voxels");
    let dir = std::env::temp_dir().join(format!("mediareg_backward_fd_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let h = 0.02f32;
    let files: Vec<PathBuf> = [0.0, h / 2.0, h]
        .iter()
        .map(|&step| {
            let data: Vec<f32> = base
                .data
                .iter()
                .zip(&v)
                .map(|(x, v)| x + step * v)
                .collect();
            let path = dir.join(format!("step_{step}.vol"));
            std::fs::write(&path, write_vol(base.res, 1, &data)).unwrap();
            path
        })
        .collect();
    let (seeds, spp) = (16u64, 256u32);
    let mut fd = Vec::new();
    for seed in 0..seeds {
        let l: Vec<f64> = files
            .iter()
            .map(|f| loss(&scene(spp, 500 + seed, Some(f))))
            .collect();
        let d = |l1: f64, step: f32| (l1 - l[0]) / step as f64;
        fd.push(2.0 * d(l[1], h / 2.0) - d(l[2], h));
    }
    let along = |defect| -> Vec<f64> {
        (0..seeds)
            .map(|seed| {
                dot(
                    &v,
                    gradients(&scene(spp, seed, None), defect)
                        .sigma_t
                        .as_ref()
                        .unwrap(),
                )
            })
            .collect()
    };
    let (ad, fdv) = (with_dof(&along(None)), with_dof(&fd));
    let (t, ok) = agree(ad, fdv);
    eprintln!(
        "empty voxels: adjoint {:.5e} ± {:.1e}, FD {:.5e} ± {:.1e}, t {t:.2}",
        ad.0, ad.1, fdv.0, fdv.1
    );
    assert!(ok, "adjoint {ad:?} vs FD {fdv:?}: t = {t}");
    // Mitsuba 3's one-sided difference along the same voxels agrees; its prbvolpath
    // gradient, which has delta tracking's support, does not (the file's notes).
    let reference = mitsuba_derivatives();
    let zero = &reference["params"]["sigma_t"]["one_sided"]["zero"];
    let mitsuba_fd = mitsuba_estimate(&zero["fd"], &reference);
    let mitsuba_ad = mitsuba_estimate(&zero["ad"], &reference);
    let (t, ok) = agree(ad, mitsuba_fd);
    eprintln!(
        "empty voxels: Mitsuba FD {:.5e} ± {:.1e}, t {t:.2}",
        mitsuba_fd.0, mitsuba_fd.1
    );
    assert!(
        ok,
        "adjoint {ad:?} vs Mitsuba's one-sided FD {mitsuba_fd:?}: t = {t}"
    );
    assert!(
        !agree(mitsuba_ad, mitsuba_fd).1,
        "prbvolpath's bias there not seen"
    );
    let without = with_dof(&along(Some(AdjointDefect::Ghosts)));
    let (t, ok) = agree(without, fdv);
    eprintln!(
        "without ghosts: {:.5e} ± {:.1e}, t {t:.2}",
        without.0, without.1
    );
    assert!(!ok, "without ghosts undetected: t = {t}");
}

/// ⟨∇L, V⟩ along the three fields of reference/derivatives/grid_adjoint.json, for
/// sigma_t's and the albedo's values, against Mitsuba 3's Richardson finite differences
/// and its prbvolpath gradient (which agree with each other on this grid). Power: each
/// value 5% too large, or negated, is rejected wherever the comparison resolves 5%
/// (at least four of the twelve).
#[test]
fn directional_derivatives_agree_with_mitsuba() {
    let reference = mitsuba_derivatives();
    let fields = ["smooth", "box", "noise"];
    // The fields are signed, which a volume may not be: their data read as it lies.
    let v: Vec<Vec<f32>> = fields
        .iter()
        .map(|f| {
            let path = root().join(format!("mitsuba_scenes/volumes/grid_adjoint_v_{f}.vol"));
            let bytes = std::fs::read(path).unwrap();
            let data = &bytes[mediareg::medium::grid::VOL_HEADER_BYTES..];
            data.chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect()
        })
        .collect();
    let (seeds, spp) = (16u64, 256u32);
    let mut ours = vec![vec![Vec::new(); fields.len()]; 2];
    for seed in 0..seeds {
        let g = gradients(&scene(spp, 2000 + seed, None), None);
        for (k, grad) in [&g.sigma_t, &g.albedo].iter().enumerate() {
            for (i, field) in v.iter().enumerate() {
                ours[k][i].push(dot(field, grad.as_ref().unwrap()));
            }
        }
    }
    let mut resolved = 0;
    for (k, param) in ["sigma_t", "albedo"].iter().enumerate() {
        for (i, field) in fields.iter().enumerate() {
            let r = &reference["params"][param]["fields"][field];
            let ours = with_dof(&ours[k][i]);
            for method in ["fd", "ad"] {
                let theirs = mitsuba_estimate(&r[method], &reference);
                let (t, ok) = agree(ours, theirs);
                eprintln!("{param} {field}: mediareg {:.5e} ± {:.1e}, Mitsuba {method} {:.5e} ± {:.1e}, t {t:.2}", ours.0, ours.1, theirs.0, theirs.1);
                assert!(ok, "{param} along {field}: mediareg {ours:?} vs Mitsuba {method} {theirs:?}: t = {t}");
                let se = (ours.1.powi(2) + theirs.1.powi(2)).sqrt();
                if 0.05 * theirs.0.abs() > 6.0 * se {
                    let (t, ok) = agree((ours.0 * 1.05, ours.1 * 1.05, ours.2), theirs);
                    assert!(
                        !ok,
                        "{param} {field} 5% too large undetected against {method}: t {t}"
                    );
                    resolved += 1;
                }
                if theirs.0.abs() > 6.0 * se {
                    let (t, ok) = agree((-ours.0, ours.1, ours.2), theirs);
                    assert!(
                        !ok,
                        "{param} {field} negated undetected against {method}: t {t}"
                    );
                }
            }
        }
    }
    assert!(
        resolved >= 4,
        "only {resolved} of 12 comparisons resolve 5%"
    );
}
