//! Mitsuba 3's `principled`, `blendbsdf` and `mask` (the Blender exporter's materials).
//!
//! 1. Renders of mitsuba_scenes/principled.xml against Mitsuba 3 references of the same
//!    file, with `path` and with `volpath` (shadow rays through the mask), compared as
//!    tests/mitsuba_equivalence.rs does (per-pixel and block z-tests, false-alarm
//!    probability 1e-6); beside each match a power test: the same comparison must fail
//!    when one lobe is switched off or one parameter is a few percent off.
//! 2. Sampling against evaluation, lobe by lobe: each sample's pdf and weight are
//!    `eval_pdf`'s at its direction, the share of valid samples is ∫ pdf dω, and the
//!    mean weight (the directional albedo by sampling) is ∫ f |cos θ_o| dω by quadrature.

mod common;

use std::f64::consts::PI;

use common::scene_text::{self, build_desc, load_or_build_error, SENSOR};
use common::{check_against_reference, check_window_against_reference};
use glam::{Vec2, Vec3, Vec3A};
use mediareg::bsdf::microfacet::{Microfacet, MicrofacetType};
use mediareg::bsdf::{Blend, Bsdf, Mask, Principled, RoughConductor};
use mediareg::image::stats::Comparison;
use mediareg::sampling::independent::Pcg32;
use mediareg::texture::Texture;

const CHUNKS: usize = 8;
const SPP: u32 = 512;

/// mitsuba_scenes/principled.xml with `path` (reference `principled`, 65,536 spp, as
/// are `principled_volpath` and `principled_set2`).
fn check_path(params: &[(&str, &str)], seed: u64) -> Comparison {
    check_against_reference("principled", "principled", params, CHUNKS, SPP, seed)
}

/// The same scene with `volpath` (reference `principled_volpath`).
fn check_volpath(extra: &[(&str, &str)], seed: u64) -> Comparison {
    let mut params = vec![("integrator", "volpath")];
    params.extend_from_slice(extra);
    check_against_reference(
        "principled_volpath",
        "principled",
        &params,
        CHUNKS,
        SPP,
        seed,
    )
}

/// A second parameter set (reference `principled_set2`): sphere C half transmissive
/// (where Mitsuba's lobe choice depends on the sampled normal), B nearly fully
/// anisotropic, A smoother with clearcoat 1 and sheen 1.5, panel and floor at 0.5.
const SET2: [(&str, &str); 7] = [
    ("c_spec_trans", "0.5"),
    ("b_anisotropic", "0.95"),
    ("a_clearcoat", "1"),
    ("a_roughness", "0.15"),
    ("a_sheen", "1.5"),
    ("mask_opacity", "0.5"),
    ("floor_weight", "0.5"),
];

#[test]
fn second_parameter_set_matches_mitsuba() {
    let c = check_against_reference("principled_set2", "principled", &SET2, CHUNKS, SPP, 111);
    assert!(c.passed, "{c}");
}

/// In the second set, sphere C's spec_trans 5% lower (on sphere C's window).
#[test]
fn second_set_spec_trans_off_by_five_percent_is_detected() {
    let run = |changed: &[(&str, &str)], seed| {
        let mut params: Vec<(&str, &str)> = SET2
            .iter()
            .filter(|(k, _)| !changed.iter().any(|(c, _)| c == k))
            .copied()
            .collect();
        params.extend_from_slice(changed);
        let (name, w) = ("principled_set2", WIN_C);
        check_window_against_reference(name, "principled", &params, w, CHUNKS, SPP_WINDOW, seed)
    };
    let same = run(&[], 112);
    assert!(same.passed, "the window itself: {same}");
    let off = run(&[("c_spec_trans", "0.475")], 113);
    assert!(
        !off.passed,
        "spec_trans 0.475 for 0.5 went undetected: {off}"
    );
}

/// Windows of the 64 × 48 film around what a power test changes: spheres A, B, C,
/// the masked panel, the floor in front.
const WIN_A: [usize; 4] = [2, 13, 18, 20];
const WIN_B: [usize; 4] = [23, 11, 18, 20];
const WIN_C: [usize; 4] = [44, 13, 19, 20];
const WIN_PANEL: [usize; 4] = [0, 4, 64, 11];
/// A window's share of the film is small: more samples per pixel for the same time.
const SPP_WINDOW: u32 = 2048;

/// A power test on a window of reference `name` rendered with `base`: the window must
/// match the reference (the same comparison), and must not with `changed` added.
fn window_power_of(
    name: &str,
    base: &[(&str, &str)],
    window: [usize; 4],
    changed: &[(&str, &str)],
    seed: u64,
) -> (Comparison, Comparison) {
    let run = |params: &[(&str, &str)], seed| {
        check_window_against_reference(name, "principled", params, window, CHUNKS, SPP_WINDOW, seed)
    };
    let mut off = base.to_vec();
    off.extend_from_slice(changed);
    (run(base, seed), run(&off, seed + 1000))
}

/// [`window_power_of`] on the `path` reference.
fn window_power(
    window: [usize; 4],
    changed: &[(&str, &str)],
    seed: u64,
) -> (Comparison, Comparison) {
    window_power_of("principled", &[], window, changed, seed)
}

#[test]
fn principled_blend_mask_match_mitsuba_path() {
    let c = check_path(&[], 101);
    assert!(c.passed, "{c}");
}

#[test]
fn principled_blend_mask_match_mitsuba_volpath() {
    let c = check_volpath(&[], 102);
    assert!(c.passed, "{c}");
}

/// Sphere A without its clearcoat lobe.
#[test]
fn clearcoat_switched_off_is_detected() {
    let (same, off) = window_power(WIN_A, &[("a_clearcoat", "0")], 103);
    assert!(same.passed, "the window itself: {same}");
    assert!(!off.passed, "clearcoat 0 for 0.7 went undetected: {off}");
}

/// Sphere A without its sheen lobe.
#[test]
fn sheen_switched_off_is_detected() {
    let (same, off) = window_power(WIN_A, &[("a_sheen", "0")], 104);
    assert!(same.passed, "the window itself: {same}");
    assert!(!off.passed, "sheen 0 for 0.8 went undetected: {off}");
}

/// Sphere B isotropic instead of anisotropic 0.6.
#[test]
fn anisotropy_switched_off_is_detected() {
    let (same, off) = window_power(WIN_B, &[("b_anisotropic", "0")], 105);
    assert!(same.passed, "the window itself: {same}");
    assert!(!off.passed, "anisotropic 0 for 0.6 went undetected: {off}");
}

/// Sphere B's metallic 5% lower.
#[test]
fn metallic_off_by_five_percent_is_detected() {
    let (same, off) = window_power(WIN_B, &[("b_metallic", "0.855")], 106);
    assert!(same.passed, "the window itself: {same}");
    assert!(!off.passed, "metallic 0.855 for 0.9 went undetected: {off}");
}

/// Sphere C's spec_trans 5% lower (more of its light in the diffuse lobe).
#[test]
fn spec_trans_off_by_five_percent_is_detected() {
    let (same, off) = window_power(WIN_C, &[("c_spec_trans", "0.855")], 107);
    assert!(same.passed, "the window itself: {same}");
    assert!(
        !off.passed,
        "spec_trans 0.855 for 0.9 went undetected: {off}"
    );
}

/// The floor's blend weight (the checkerboard's color1) 5% lower.
#[test]
fn blend_weight_off_by_five_percent_is_detected() {
    let c = check_path(&[("floor_weight", "0.76")], 108);
    assert!(!c.passed, "blend weight 0.76 for 0.8 went undetected: {c}");
}

/// The panel's opacity (the checkerboard's color0) 5% lower, under path and volpath.
#[test]
fn mask_opacity_off_by_five_percent_is_detected() {
    let changed = [("mask_opacity", "0.76")];
    let (same, off) = window_power(WIN_PANEL, &changed, 109);
    assert!(same.passed, "path, the window itself: {same}");
    assert!(
        !off.passed,
        "path: opacity 0.76 for 0.8 went undetected: {off}"
    );
    let volpath = [("integrator", "volpath")];
    let (same, off) = window_power_of("principled_volpath", &volpath, WIN_PANEL, &changed, 110);
    assert!(same.passed, "volpath, the window itself: {same}");
    assert!(
        !off.passed,
        "volpath: opacity 0.76 for 0.8 went undetected: {off}"
    );
}

// ---- Sampling against evaluation ----

fn c(v: f32) -> Texture {
    Texture::Constant(Vec3::splat(v))
}

fn some(v: f32) -> Option<Texture> {
    Some(c(v))
}

/// A principled BSDF with every optional lobe off, η 1.5, roughness 0.5.
fn base() -> Principled {
    Principled {
        base_color: Texture::Constant(Vec3::new(0.8, 0.5, 0.2)),
        roughness: c(0.5),
        anisotropic: None,
        spec_trans: None,
        sheen: None,
        sheen_tint: None,
        flatness: None,
        spec_tint: None,
        metallic: None,
        clearcoat: None,
        clearcoat_gloss: c(0.0),
        eta: 1.5,
        spec_srate: 1.0,
        clearcoat_srate: 1.0,
        diff_refl_srate: 1.0,
    }
}

/// ∫ f(ω) dω over the sphere, midpoint rule in (θ, φ) on a 3000 × 600 grid.
fn integrate_sphere(f: impl Fn(Vec3A) -> f64) -> f64 {
    let (nt, np) = (3000, 600);
    let mut sum = 0.0;
    for i in 0..nt {
        let t = (i as f64 + 0.5) / nt as f64 * PI;
        let (st, ct) = t.sin_cos();
        for j in 0..np {
            let p = (j as f64 + 0.5) / np as f64 * 2.0 * PI;
            let w = Vec3A::new((st * p.cos()) as f32, (st * p.sin()) as f32, ct as f32);
            sum += f(w) * st;
        }
    }
    sum * (PI / nt as f64) * (2.0 * PI / np as f64)
}

/// Checks `b` at `wi` (see the module's note 2), with N = 400² samples: s2 jittered
/// on a grid, s1 independent. The sampled share and albedo are means of N independent
/// values, so they must agree with the quadrature within 5 standard errors (plus 0.1%
/// for the quadrature itself).
fn check_sampling(name: &str, b: &Bsdf, wi: Vec3A) {
    let uv = Vec2::new(0.3, 0.6);
    let n = 400;
    let total = (n * n) as f64;
    let mut rng = Pcg32::new(7, 1);
    let (mut sum, mut sum2) = ([0.0f64; 3], [0.0f64; 3]);
    let mut valid = 0usize;
    for i in 0..n {
        for j in 0..n {
            let jitter = rng.next_2d();
            let s2 = (Vec2::new(i as f32, j as f32) + jitter) / n as f32;
            let s1 = rng.next_1d();
            let Some(bs) = b.sample(wi, s1, s2, uv) else {
                continue;
            };
            assert!(bs.weight.is_finite() && bs.pdf > 0.0, "{name}: {bs:?}");
            if bs.null {
                // The pass-through lobe: a Dirac mass outside eval_pdf.
                assert_eq!(bs.wo, -wi);
                assert_eq!(bs.weight, Vec3::ONE);
                continue;
            }
            valid += 1;
            let (f, pdf) = b.eval_pdf(wi, bs.wo, uv);
            let rel = |a: f32, b: f32| (a - b).abs() / b.abs().max(1e-3);
            assert!(
                rel(bs.pdf, pdf) < 2e-3,
                "{name}: pdf {pdf} vs sampled {}",
                bs.pdf
            );
            let w = f / pdf;
            assert!(
                (w - bs.weight).abs().max_element() <= 2e-3 * w.max_element().max(1.0),
                "{name}: f/pdf {w} vs weight {}",
                bs.weight
            );
            for k in 0..3 {
                sum[k] += bs.weight[k] as f64;
                sum2[k] += (bs.weight[k] as f64).powi(2);
            }
        }
    }
    let share = valid as f64 / total;
    let se_share = (share * (1.0 - share) / total).sqrt();
    let pdf_mass = integrate_sphere(|wo| b.eval_pdf(wi, wo, uv).1 as f64);
    assert!(
        (share - pdf_mass).abs() < 5.0 * se_share + 1e-3,
        "{name} wi {wi}: {share} of the samples are valid, but ∫ pdf = {pdf_mass}"
    );
    for k in 0..3 {
        let mean = sum[k] / total;
        let se = ((sum2[k] / total - mean * mean) / total).sqrt();
        let quad = integrate_sphere(|wo| b.eval_pdf(wi, wo, uv).0[k] as f64);
        println!("{name} wi {wi} channel {k}: albedo by sampling {mean:.5} ± {se:.5}, by quadrature {quad:.5}");
        assert!(
            (mean - quad).abs() < 5.0 * se + 1e-3 * quad,
            "{name} wi {wi} channel {k}: albedo by sampling {mean} ± {se}, by quadrature {quad}"
        );
    }
}

fn wis() -> [Vec3A; 2] {
    [
        Vec3A::new(0.3, 0.1, 0.9).normalize(),
        Vec3A::new(-0.6, 0.4, 0.35).normalize(),
    ]
}

#[test]
fn principled_lobes_sample_what_they_evaluate() {
    let configs: Vec<(&str, Principled)> = vec![
        ("diffuse + specular", base()),
        (
            "clearcoat",
            Principled {
                clearcoat: some(0.9),
                clearcoat_gloss: c(0.3),
                clearcoat_srate: 2.0,
                ..base()
            },
        ),
        (
            "sheen, tinted, flatness, spec_tint",
            Principled {
                sheen: some(0.8),
                sheen_tint: some(0.5),
                flatness: some(0.6),
                spec_tint: some(0.4),
                diff_refl_srate: 0.7,
                ..base()
            },
        ),
        (
            "metallic anisotropic",
            Principled {
                metallic: some(0.8),
                anisotropic: some(0.7),
                roughness: c(0.6),
                ..base()
            },
        ),
        (
            "spec_trans 1",
            Principled {
                spec_trans: some(1.0),
                roughness: c(0.4),
                eta: 1.45,
                ..base()
            },
        ),
    ];
    for (name, p) in configs {
        let b = Bsdf::Principled(Box::new(p));
        for wi in wis() {
            check_sampling(name, &b, wi);
        }
    }
    // spec_trans 1 from inside (reflection and refraction out, total internal reflection).
    let glass = Bsdf::Principled(Box::new(Principled {
        spec_trans: some(1.0),
        roughness: c(0.4),
        ..base()
    }));
    check_sampling(
        "spec_trans 1 inside",
        &glass,
        Vec3A::new(0.2, -0.3, -0.8).normalize(),
    );
}

/// blendbsdf and mask sample their mixtures consistently with their eval_pdf; the
/// mask's pass-through lobe has probability 1 − opacity.
#[test]
fn blend_and_mask_sample_what_they_evaluate() {
    let metal = Bsdf::RoughConductor(RoughConductor {
        distr: Microfacet::new(MicrofacetType::Ggx, 0.3, 0.3),
        eta: Vec3::new(0.2, 0.9, 1.1),
        k: Vec3::new(3.6, 2.6, 2.4),
        specular_reflectance: Vec3::ONE,
    });
    let diffuse = Bsdf::Diffuse {
        reflectance: Texture::Constant(Vec3::new(0.6, 0.5, 0.4)),
    };
    let blend = Bsdf::Blend(Box::new(Blend {
        weight: c(0.35),
        bsdfs: [diffuse.clone(), metal.clone()],
    }));
    let mask = Bsdf::Mask(Box::new(Mask {
        opacity: c(0.7),
        nested: Bsdf::Principled(Box::new(Principled {
            clearcoat: some(0.5),
            ..base()
        })),
    }));
    for wi in wis() {
        check_sampling("blendbsdf", &blend, wi);
        check_sampling("mask", &mask, wi);
    }
    assert_eq!(mask.null_transmission(-0.5, Vec2::ZERO), Vec3::splat(0.3));
    // f of the blend is the weighted sum of its parts.
    let (wi, wo) = (wis()[0], Vec3A::new(-0.2, 0.3, 0.9).normalize());
    let (fb, _) = blend.eval_pdf(wi, wo, Vec2::ZERO);
    let (fd, _) = diffuse.eval_pdf(wi, wo, Vec2::ZERO);
    let (fm, _) = metal.eval_pdf(wi, wo, Vec2::ZERO);
    assert!((fb - (fd * 0.65 + fm * 0.35)).abs().max_element() < 1e-6);
}

// ---- Loading ----

fn build_err(tag: &str, bsdf: &str) -> String {
    let text = format!(
        "<scene version=\"3.0.0\">{SENSOR}<shape type=\"rectangle\">{bsdf}</shape></scene>"
    );
    load_or_build_error(tag, scene_text::load_text("principled", tag, &text, &[]))
}

/// Mistakes are refused with the file, line and what to do, never rendered otherwise.
#[test]
fn bad_principled_blend_and_mask_are_refused_clearly() {
    let cases = [
        (
            "both",
            r#"<bsdf type="principled"><float name="eta" value="1.4"/><float name="specular" value="0.5"/></bsdf>"#,
            "either eta or specular",
        ),
        (
            "unknown",
            r#"<bsdf type="principled"><float name="subsurface" value="0.5"/></bsdf>"#,
            "unreferenced property \"subsurface\"",
        ),
        (
            "aniso",
            r#"<bsdf type="principled"><float name="anisotropic" value="1.5"/></bsdf>"#,
            "anisotropic",
        ),
        (
            "noweight",
            r#"<bsdf type="blendbsdf"><bsdf type="diffuse"/><bsdf type="conductor"/></bsdf>"#,
            "needs a \"weight\"",
        ),
        (
            "onechild",
            r#"<bsdf type="blendbsdf"><float name="weight" value="0.3"/><bsdf type="diffuse"/></bsdf>"#,
            "exactly two nested",
        ),
        (
            "twomasked",
            r#"<bsdf type="mask"><bsdf type="diffuse"/><bsdf type="diffuse"/></bsdf>"#,
            "exactly one nested",
        ),
    ];
    for (tag, bsdf, want) in cases {
        let e = build_err(tag, bsdf);
        assert!(e.contains(want), "{tag}: {e}");
        assert!(e.contains("scene.xml:"), "{tag}: no file:line in {e}");
    }
}

/// Mitsuba's defaults and `get_flag`: `specular` 0.5 is η 1.5; a lobe given as the float
/// 0 is off, given otherwise it is on; mask's opacity defaults to 0.5.
#[test]
fn principled_defaults_and_flags_are_mitsubas() {
    let text = format!(
        r#"<scene version="3.0.0">{SENSOR}<shape type="rectangle"><bsdf type="principled"><float name="sheen" value="0"/><rgb name="clearcoat" value="0, 0, 0"/></bsdf></shape>
        <shape type="sphere"><bsdf type="mask"><bsdf type="principled"/></bsdf></shape></scene>"#
    );
    let desc = scene_text::load_text("principled", "defaults", &text, &[]).unwrap();
    let scene = build_desc("defaults", &desc);
    let principled = scene.bsdfs.iter().find_map(|b| match b {
        Bsdf::Principled(p) => Some(p),
        _ => None,
    });
    let p = principled.expect("a principled bsdf");
    assert!((p.eta - 1.5).abs() < 1e-6, "eta {}", p.eta);
    assert!(p.sheen.is_none() && p.clearcoat.is_some() && p.metallic.is_none());
    assert_eq!(p.roughness, Vec3::splat(0.5));
    assert_eq!(p.base_color, Vec3::splat(0.5));
    let mask = scene.bsdfs.iter().find_map(|b| match b {
        Bsdf::Mask(m) => Some(m),
        _ => None,
    });
    assert_eq!(mask.expect("a mask").opacity, Vec3::splat(0.5));
}

/// eval_pdf against Mitsuba 3.9.1 (`scalar_rgb`, `BSDF::eval_pdf` of `principled`
/// plugins made by `mi.load_dict` with the same parameters, at the same local
/// directions): front reflection, transmission, from inside out and inside reflection.
/// `scripts/mitsuba_fixtures.py principled` prints the table below.
#[test]
fn principled_matches_mitsuba_values() {
    use mediareg::bsdf::principled::eta_from_specular;
    let n = |x: f32, y: f32, z: f32| Vec3A::new(x, y, z).normalize();
    let rgb = |r, g, b| Texture::Constant(Vec3::new(r, g, b));
    let plastic = Principled {
        base_color: rgb(0.8, 0.5, 0.2),
        roughness: c(0.4),
        sheen: some(0.8),
        sheen_tint: some(0.5),
        clearcoat: some(0.7),
        clearcoat_gloss: c(0.6),
        spec_tint: some(0.3),
        flatness: some(0.4),
        eta: eta_from_specular(0.6),
        spec_srate: 0.8,
        clearcoat_srate: 2.0,
        ..base()
    };
    let metal = Principled {
        base_color: rgb(0.9, 0.75, 0.4),
        metallic: some(0.9),
        roughness: c(0.5),
        anisotropic: some(0.6),
        ..base()
    };
    let glass = Principled {
        base_color: rgb(0.85, 0.95, 0.9),
        spec_trans: some(0.5),
        eta: 1.45,
        roughness: c(0.3),
        ..base()
    };
    let dirs = [
        (n(0.5, 0.2, 0.8), n(-0.3, 0.4, 0.7)),
        (n(0.5, 0.2, 0.8), n(-0.2, -0.1, -0.9)),
        (n(0.3, -0.2, -0.7), n(-0.5, 0.3, 0.6)),
        (n(0.3, -0.2, -0.7), n(-0.4, 0.3, -0.7)),
    ];
    // Mitsuba's (f · |cos θ_o|, pdf) per BSDF and direction pair, in `dirs`' order
    // (scripts/mitsuba_fixtures.py principled).
    type Want = [([f32; 3], f32); 4];
    let wants: [(&str, Principled, Want); 3] = [
        (
            "plastic",
            plastic,
            [
                ([0.193_755_03, 0.122_833_73, 0.051_912_397], 0.164_620_76),
                ([0.0; 3], 0.0),
                ([0.0; 3], 0.0),
                ([0.0; 3], 2.386_979),
            ],
        ),
        (
            "metal",
            metal,
            [
                ([0.058_931_112, 0.049_139_213, 0.026_291_443], 0.063_658_72),
                ([0.0; 3], 0.0),
                ([0.0; 3], 0.0),
                ([0.0; 3], 1.135_270_5),
            ],
        ),
        (
            "glass",
            glass,
            [
                ([0.111_156_754, 0.124_107_62, 0.117_632_18], 0.097_058_55),
                ([0.109_665_83, 0.115_937_43, 0.112_845_2], 0.166_748_12),
                ([22.2983, 23.5735, 22.944_76], 23.050_71),
                ([0.095_987_8; 3], 0.192_173_78),
            ],
        ),
    ];
    let rel = |a: f32, b: f32| (a - b).abs() / b.abs().max(1e-6);
    for (name, p, want) in wants {
        let b = Bsdf::Principled(Box::new(p));
        for ((wi, wo), (f_want, pdf_want)) in dirs.iter().zip(want) {
            let (f, pdf) = b.eval_pdf(*wi, *wo, Vec2::ZERO);
            assert!(
                rel(pdf, pdf_want) < 2e-3 || (pdf_want == 0.0 && pdf == 0.0),
                "{name} {wi} → {wo}: pdf {pdf}, Mitsuba {pdf_want}"
            );
            for k in 0..3 {
                assert!(
                    rel(f[k], f_want[k]) < 2e-3 || (f_want[k] == 0.0 && f[k] == 0.0),
                    "{name} {wi} → {wo}: f {f}, Mitsuba {f_want:?}"
                );
            }
        }
    }
}
