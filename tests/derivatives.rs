//! The derivative images (`render --gradient sigma_t,albedo,g,scale`) against Mitsuba
//! 3's on four scenes (a cube, a mesh boundary, a chromatic medium, a grid's density
//! scale): reference/derivatives/<scene>.json holds Mitsuba 3's reverse-mode
//! derivatives (prbvolpath) and Richardson finite differences of its renders (volpath),
//! each a mean over seeds with its standard error (scripts/derivative_references).
//! mediareg's are means over seeds too; each comparison is a Welch t-test of the image
//! mean's derivative (per channel for a chromatic parameter, summed over channels for a
//! grey one), at a per-comparison level that keeps the whole file's false-alarm
//! probability below FALSE_ALARM (Bonferroni). Power tests: a derivative 5% off (on the
//! cube, the mesh boundary and the chromatic medium; half off on the grid, whose only
//! reference is noisier), one with its sign flipped, and one without the shadow
//! rays' term must each fail, and on the cube the derivative image turned half a turn
//! (its mean unchanged). Besides the image mean, each quadrant's mean is compared
//! against Mitsuba's finite differences.

mod common;

use std::path::Path;

use common::{load_seeded, root};
use mediareg::integrator::volpath::Estimand;
use mediareg::integrator::{derivative_images, medium_gradient, MediumParam, RenderOptions};
use serde_json::Value;
use statrs::distribution::{ContinuousCDF, StudentsT};

/// Whole-file false-alarm probability, and the most comparisons it is shared among.
const FALSE_ALARM: f64 = 1e-3;
/// The values compared over the file: about 60 (each parameter's image mean against
/// AD and FD, its four quadrants against FD, per channel where chromatic).
const COMPARISONS: f64 = 64.0;

/// A mean over seeds and its standard error, per compared value, with its degrees of
/// freedom.
#[derive(Clone, Debug)]
struct Estimate {
    mean: Vec<f64>,
    se: Vec<f64>,
    dof: f64,
}

fn estimate(samples: &[Vec<f64>]) -> Estimate {
    let n = samples.len() as f64;
    let k = samples[0].len();
    let mean: Vec<f64> = (0..k)
        .map(|i| samples.iter().map(|s| s[i]).sum::<f64>() / n)
        .collect();
    let se = (0..k)
        .map(|i| {
            let var = samples
                .iter()
                .map(|s| (s[i] - mean[i]).powi(2))
                .sum::<f64>()
                / (n - 1.0);
            (var / n).sqrt()
        })
        .collect();
    Estimate {
        mean,
        se,
        dof: n - 1.0,
    }
}

fn from_json(v: &Value, seeds: f64) -> Estimate {
    let list = |k: &str| -> Vec<f64> {
        v[k].as_array()
            .unwrap_or_else(|| panic!("{k} in {v}"))
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    Estimate {
        mean: list("mean"),
        se: list("se"),
        dof: seeds - 1.0,
    }
}

/// The largest |t| / critical value over the values compared, ours scaled by `factor`:
/// above 1 is a failure.
fn excess(ours: &Estimate, reference: &Estimate, factor: f64) -> f64 {
    let alpha = FALSE_ALARM / COMPARISONS;
    (0..reference.mean.len())
        .map(|i| {
            let (a, b) = (
                factor * factor * ours.se[i].powi(2),
                reference.se[i].powi(2),
            );
            // Welch–Satterthwaite degrees of freedom.
            let dof = (a + b).powi(2) / (a * a / ours.dof + b * b / reference.dof);
            let t = StudentsT::new(0.0, 1.0, dof).unwrap();
            let critical = t.inverse_cdf(1.0 - alpha / 2.0);
            (factor * ours.mean[i] - reference.mean[i]).abs() / (a + b).sqrt() / critical
        })
        .fold(0.0, f64::max)
}

/// One scene's reference and mediareg's derivatives of it, per parameter: (name,
/// ours, Mitsuba's AD if any, Mitsuba's FD if any, and (ours, Mitsuba's FD) of each
/// quadrant of the image where the reference has them).
type Compared = Vec<(
    String,
    Estimate,
    Option<Estimate>,
    Option<Estimate>,
    Vec<(Estimate, Estimate)>,
)>;

/// The image mean per channel, then each quadrant's (top left, top right, bottom left,
/// bottom right; an odd size's middle row or column in the lower or right half, as
/// scripts/derivative_references splits them): 15 numbers.
fn region_means(img: &mediareg::image::Image) -> Vec<f64> {
    let (w, h) = (img.width, img.height);
    let (hw, hh) = (w / 2, h / 2);
    let regions = [
        (0..w, 0..h),
        (0..hw, 0..hh),
        (hw..w, 0..hh),
        (0..hw, hh..h),
        (hw..w, hh..h),
    ];
    let mut out = Vec::with_capacity(15);
    for (xs, ys) in regions {
        let n = (xs.len() * ys.len()) as f64;
        for c in 0..3 {
            let sum: f64 = ys
                .clone()
                .flat_map(|y| xs.clone().map(move |x| (x, y)))
                .map(|(x, y)| img.pixels[y * w + x][c] as f64)
                .sum();
            out.push(sum / n);
        }
    }
    out
}

/// mediareg's derivatives of scene `name` (its reference's defines), `seeds` renders
/// of `spp` each, with the estimator `tweak` makes of the asked-for one.
fn compare(name: &str, seeds: u64, spp: u32, tweak: impl Fn(Estimand) -> Estimand) -> Compared {
    let text = std::fs::read_to_string(root().join(format!("reference/derivatives/{name}.json")))
        .expect("reference/derivatives: run scripts/derivative_references");
    let r: Value = serde_json::from_str(&text).unwrap();
    let defines: Vec<(String, String)> = r["defines"]
        .as_object()
        .unwrap()
        .iter()
        .map(|(k, v)| (k.clone(), v.as_str().unwrap().to_string()))
        .collect();
    let defines: Vec<(&str, &str)> = defines
        .iter()
        .map(|(k, v)| (k.as_str(), v.as_str()))
        .collect();
    let names: Vec<&String> = r["params"].as_object().unwrap().keys().collect();
    let params: Vec<MediumParam> = names
        .iter()
        .map(|n| MediumParam::parse_list(n).unwrap()[0])
        .collect();
    let path = root().join(r["scene"].as_str().unwrap());
    let mut samples: Vec<Vec<Vec<f64>>> = vec![Vec::new(); params.len()];
    for seed in 0..seeds {
        let scene = load_seeded(Path::new(&path), &defines, spp, 1000 + seed);
        let (gradient, mi) = medium_gradient(&scene, None, &params).unwrap();
        let opts = RenderOptions {
            estimand: tweak(gradient),
            ..Default::default()
        };
        let rendered = mediareg::integrator::render(&scene, &scene.shot, &opts);
        for (i, (_, img)) in derivative_images(&scene, mi, &params, &rendered)
            .into_iter()
            .enumerate()
        {
            let mean = region_means(&img.unwrap());
            assert!(
                mean.iter().all(|m| m.is_finite()),
                "{name}: non-finite derivative"
            );
            samples[i].push(mean);
        }
    }
    let ad_seeds = r["ad"]["seeds"].as_f64().unwrap();
    let fd_seeds = r["fd"]["seeds"].as_f64().unwrap();
    names
        .iter()
        .zip(samples)
        .map(|(n, s)| {
            let entry = &r["params"][n.as_str()];
            let ad = entry.get("ad").map(|v| from_json(v, ad_seeds));
            let chromatic = ad.as_ref().is_some_and(|a| a.mean.len() == 3);
            let fd = entry.get("fd").map(|v| match chromatic {
                true => from_json(v, fd_seeds),
                false => from_json(&v["total"], fd_seeds),
            });
            // A grey parameter: the sum over channels. Part 0 is the whole image,
            // parts 1-4 its quadrants.
            let part = |q: usize| -> Vec<Vec<f64>> {
                s.iter()
                    .map(|m| {
                        let rgb = &m[3 * q..3 * q + 3];
                        match chromatic {
                            true => rgb.to_vec(),
                            false => vec![rgb.iter().sum()],
                        }
                    })
                    .collect()
            };
            let quadrants = match entry["fd"]["quadrants"].as_array() {
                Some(list) => list
                    .iter()
                    .enumerate()
                    .map(|(q, v)| {
                        let theirs = match chromatic {
                            true => from_json(v, fd_seeds),
                            false => from_json(&v["total"], fd_seeds),
                        };
                        (estimate(&part(q + 1)), theirs)
                    })
                    .collect(),
                None => Vec::new(),
            };
            ((*n).clone(), estimate(&part(0)), ad, fd, quadrants)
        })
        .collect()
}

/// The largest excess over a scene's comparisons (AD and FD), ours scaled by `factor`,
/// printed.
fn worst(name: &str, compared: &Compared, factor: f64) -> f64 {
    let mut worst = 0.0f64;
    for (param, ours, ad, fd, quadrants) in compared {
        let mut show = |kind: &str, ours: &Estimate, r: &Estimate| {
            let e = excess(ours, r, factor);
            println!(
                "{name} {param} vs Mitsuba {kind}: ours {:?} ± {:?}, Mitsuba {:?} ± {:?}; excess {e:.2}",
                ours.mean, ours.se, r.mean, r.se
            );
            worst = worst.max(e);
        };
        for (kind, r) in [("AD", ad), ("FD", fd)] {
            if let Some(r) = r {
                show(kind, ours, r);
            }
        }
        for (q, (ours, r)) in quadrants.iter().enumerate() {
            show(&format!("FD, quadrant {}", q + 1), ours, r);
        }
    }
    worst
}

fn same(g: Estimand) -> Estimand {
    g
}

#[test]
fn cube_derivatives_match_mitsuba() {
    let c = compare("medium_cube", 16, 1024, same);
    let w = worst("medium_cube", &c, 1.0);
    assert!(
        w <= 1.0,
        "medium_cube: a derivative differs from Mitsuba 3's ({w:.2})"
    );
    // Power: 5% off, and the sign flipped, fail each parameter.
    for (param, ours, ad, ..) in &c {
        let ad = ad.as_ref().unwrap();
        for factor in [1.05, 0.95, -1.0] {
            let e = excess(ours, ad, factor);
            assert!(e > 1.0, "{param} × {factor} passed ({e:.2})");
        }
    }
    // Power in the image's layout: the derivative image turned half a turn (the same
    // mean, each quadrant the opposite one's) fails each parameter.
    for (param, _, _, _, quadrants) in &c {
        assert_eq!(
            quadrants.len(),
            4,
            "{param}: the reference has no quadrants"
        );
        let e = excess(&quadrants[0].0, &quadrants[3].1, 1.0).max(excess(
            &quadrants[3].0,
            &quadrants[0].1,
            1.0,
        ));
        assert!(e > 1.0, "{param} turned half a turn passed ({e:.2})");
    }
}

#[test]
fn cube_power_without_shadow_term() {
    let wrong = |g: Estimand| match g {
        Estimand::MediumDerivatives { medium, mut params } => {
            params.without_shadow_term = true;
            Estimand::MediumDerivatives { medium, params }
        }
        g => g,
    };
    let c = compare("medium_cube", 16, 1024, wrong);
    let (_, ours, ad, ..) = c.iter().find(|(p, ..)| p == "sigma_t").unwrap();
    let e = excess(ours, ad.as_ref().unwrap(), 1.0);
    assert!(
        e > 1.0,
        "σ_t's derivative without the shadow rays' term passed ({e:.2})"
    );
}

#[test]
fn mesh_boundary_derivatives_match_mitsuba() {
    let c = compare("bunny_medium", 16, 1024, same);
    let w = worst("bunny_medium", &c, 1.0);
    assert!(
        w <= 1.0,
        "bunny_medium: a derivative differs from Mitsuba 3's ({w:.2})"
    );
    // Power: 5% off, and the sign flipped, fail each parameter against Mitsuba's AD
    // (measured excess 1.55-9.7 at 5%, σ_t the least).
    for (param, ours, ad, ..) in &c {
        for factor in [1.05, 0.95, -1.0] {
            let e = excess(ours, ad.as_ref().unwrap(), factor);
            assert!(e > 1.0, "bunny_medium {param} × {factor} passed ({e:.2})");
        }
    }
}

#[test]
fn chromatic_derivatives_match_mitsuba() {
    let c = compare("chromatic_sphere", 16, 1024, same);
    let w = worst("chromatic_sphere", &c, 1.0);
    assert!(
        w <= 1.0,
        "chromatic_sphere: a derivative differs from Mitsuba 3's ({w:.2})"
    );
    // Power on the chromatic parameters (g's is the cube's: here its noise is larger).
    for (param, ours, ad, ..) in c.iter().filter(|(p, ..)| p != "g") {
        let e = excess(ours, ad.as_ref().unwrap(), 1.05);
        assert!(e > 1.0, "chromatic {param} × 1.05 passed ({e:.2})");
    }
}

#[test]
fn grid_scale_derivative_matches_mitsuba() {
    let c = compare("cloud", 16, 128, same);
    let w = worst("cloud", &c, 1.0);
    assert!(
        w <= 1.0,
        "cloud: a derivative differs from Mitsuba 3's ({w:.2})"
    );
    // Power: half off either way, and the sign flipped. Mitsuba's finite difference is
    // the only reference here (its reverse mode disagrees with it on this cloud,
    // docs/gradient.md) and its standard error is 4% of the value, so at this file's
    // false-alarm level 5% off is within its noise (excess 0.12) and so is 25% (0.98):
    // a tighter check needs a longer reference (16 seeds of FD took most of 272 s).
    let (_, ours, _, fd, _) = c.iter().find(|(p, ..)| p == "scale").unwrap();
    for factor in [1.5, 0.5, -1.0] {
        let e = excess(ours, fd.as_ref().unwrap(), factor);
        assert!(
            e > 1.0,
            "the grid scale's derivative × {factor} passed ({e:.2})"
        );
    }
}

/// The command line: a parameter the medium does not have, or that mediareg cannot
/// differentiate there, is refused naming it and what to do instead; nothing is written.
#[test]
fn derivative_command_line_errors() {
    let run = |scene: &str, params: &str| {
        let out = std::env::temp_dir().join(format!("mediareg_deriv_{}.exr", std::process::id()));
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_mediareg"))
            .arg("render")
            .arg(root().join(scene))
            .args(["--gradient", params, "--spp", "1", "--no-png", "-o"])
            .arg(&out)
            .output()
            .expect("run mediareg");
        assert!(
            !o.status.success(),
            "{scene} --gradient {params}: expected failure"
        );
        assert!(!out.exists(), "no output on error");
        String::from_utf8_lossy(&o.stderr).into_owned()
    };
    let e = run("mitsuba_scenes/medium_on_floor.xml", "albedo,g");
    assert!(e.contains("has no g") && e.contains("hg"), "{e}");
    let e = run("mitsuba_scenes/cloud.xml", "sigma_t");
    assert!(e.contains("sigma_t") && e.contains("scale"), "{e}");
    let e = run("mitsuba_scenes/medium_cube.xml", "sigma_t,density");
    assert!(
        e.contains("density") && e.contains("sigma_t, albedo, g or scale"),
        "{e}"
    );
}

/// A hard case: its name, scene and defines.
type HardCase<'a> = (&'a str, &'a str, &'a [(&'a str, &'a str)]);

/// The hard cases: optically thick, g → ±0.95, albedo 1, and a chromatic σ_t whose
/// channels differ by 10× (where Mitsuba 3's volpath has infinite variance). Every
/// derivative pixel finite (never NaN or Inf, no sample dropped as invalid), and the
/// image mean's derivative with its standard error over seeds printed (docs/gradient.md
/// reports them).
#[test]
fn hard_cases_stay_finite() {
    let cube = "mitsuba_scenes/medium_cube.xml";
    let cases: [HardCase; 5] = [
        (
            "thick",
            cube,
            &[("sigma_t", "60"), ("albedo", "0.9"), ("g", "0.5")],
        ),
        (
            "g 0.95",
            cube,
            &[("sigma_t", "4"), ("albedo", "0.8"), ("g", "0.95")],
        ),
        (
            "g -0.95",
            cube,
            &[("sigma_t", "4"), ("albedo", "0.8"), ("g", "-0.95")],
        ),
        (
            "albedo 1",
            cube,
            &[("sigma_t", "10"), ("albedo", "1"), ("g", "0.5")],
        ),
        (
            "chromatic 10x",
            "mitsuba_scenes/chromatic_sphere.xml",
            &[("sigma_t", "1.0, 0.3, 0.1")],
        ),
    ];
    let params = [MediumParam::SigmaT, MediumParam::Albedo, MediumParam::G];
    for (name, scene, defines) in cases {
        let mut defines = defines.to_vec();
        defines.push(("res", "24"));
        let mut samples: Vec<Vec<Vec<f64>>> = vec![Vec::new(); params.len()];
        for seed in 0..8 {
            let s = load_seeded(&root().join(scene), &defines, 64, 500 + seed);
            let (gradient, mi) = medium_gradient(&s, None, &params).unwrap();
            let opts = RenderOptions {
                estimand: gradient,
                ..Default::default()
            };
            let r = mediareg::integrator::render(&s, &s.shot, &opts);
            assert_eq!(
                r.stats.invalid_samples, 0,
                "{name}: samples dropped as not finite"
            );
            for (i, (_, img)) in derivative_images(&s, mi, &params, &r)
                .into_iter()
                .enumerate()
            {
                let img = img.unwrap();
                assert!(
                    img.pixels.iter().flatten().all(|v| v.is_finite()),
                    "{name}: a derivative pixel is not finite"
                );
                let n = img.pixels.len() as f64;
                samples[i].push(vec![
                    img.pixels.iter().flatten().map(|&v| v as f64).sum::<f64>() / n,
                ]);
            }
        }
        for (p, s) in params.iter().zip(&samples) {
            let e = estimate(s);
            println!(
                "hard case {name}: d/d{} of the image mean {:.5e} ± {:.2e} ({:.1}%)",
                p.name(),
                e.mean[0],
                e.se[0],
                100.0 * e.se[0] / e.mean[0].abs()
            );
        }
    }
}
