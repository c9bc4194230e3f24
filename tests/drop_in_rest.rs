//! The rest of the drop-in readings real scene files need (issue 42): Mitsuba 3's named
//! conductor materials, a constant `<spectrum>` where a rough BSDF's `alpha` goes, its
//! other samplers (`sample_count` rounded as Mitsuba rounds it), `hdrfilm`'s luminance
//! and alpha pixel formats, and instances that read each mesh file once.
//!
//! Renders against Mitsuba 3 follow tests/volpath_equivalence.rs (independent chunks,
//! per-pixel z-scores, a false-alarm probability of 1e-6), each with a power test that
//! the same comparison fails on a small change.

mod common;

use common::scene_text::{load_or_build_error, load_text, SENSOR};
use common::{check_against_reference, check_edited_against_reference, root};
use glam::Vec3;
use mediareg::bsdf::Bsdf;

const CHUNKS: usize = 16;
const SPP: u32 = 128;

// ---------------------------------------------------------------------------------
// named conductors
// ---------------------------------------------------------------------------------

/// Mitsuba 3's RGB η and κ for each material it ships (tests/fixtures, written by
/// scripts/conductor_ior.py from scalar_rgb's `mi.traverse`).
fn mitsuba_conductors() -> Vec<(String, Vec3, Vec3)> {
    let text = std::fs::read_to_string(root().join("tests/fixtures/conductor_ior_mitsuba.json"))
        .expect("fixture");
    let json: serde_json::Value = serde_json::from_str(&text).expect("json");
    let v3 = |v: &serde_json::Value| {
        Vec3::from_slice(
            &v.as_array()
                .unwrap()
                .iter()
                .map(|c| c.as_f64().unwrap() as f32)
                .collect::<Vec<_>>(),
        )
    };
    json["materials"]
        .as_object()
        .unwrap()
        .iter()
        .map(|(name, m)| (name.clone(), v3(&m["eta"]), v3(&m["k"])))
        .collect()
}

/// The conductor a one-sphere scene with `bsdf` builds.
fn conductor_of(tag: &str, bsdf: &str) -> (Vec3, Vec3) {
    let text = format!(
        r#"<scene version="3.0.0">{SENSOR}
    <shape type="sphere">{bsdf}</shape>
</scene>"#
    );
    let desc = load_text("drop_in_rest", tag, &text, &[]).unwrap_or_else(|e| panic!("{e}"));
    let s = common::scene_text::build_desc(tag, &desc);
    match &s.bsdfs[..] {
        [Bsdf::Conductor(c)] => (c.eta, c.k),
        [Bsdf::RoughConductor(c)] => (c.eta, c.k),
        other => panic!("{tag}: {other:?}"),
    }
}

/// Every material Mitsuba 3 ships gives, in `conductor` and `roughconductor`, the η and
/// κ Mitsuba 3's RGB variant computes from the same spectral tables (to float
/// rounding: 2e-6 relative).
#[test]
fn named_conductors_match_mitsuba_values() {
    let all = mitsuba_conductors();
    assert!(all.len() >= 70, "{} materials", all.len());
    assert_eq!(
        all.len(),
        mediareg::load::conductor_ior::names().len(),
        "mediareg and the fixture list different materials"
    );
    let mut worst = 0f32;
    for (name, eta, k) in &all {
        for plugin in ["conductor", "roughconductor"] {
            let bsdf =
                format!(r#"<bsdf type="{plugin}"><string name="material" value="{name}"/></bsdf>"#);
            let (e, kk) = conductor_of(&format!("{plugin}_{name}"), &bsdf);
            for (ours, theirs, what) in [(e, *eta, "eta"), (kk, *k, "k")] {
                let rel =
                    ((ours - theirs).abs() / theirs.abs().max(Vec3::splat(1e-3))).max_element();
                worst = worst.max(rel);
                assert!(
                    rel <= 2e-6,
                    "{plugin} {name} {what}: mediareg {ours}, Mitsuba 3 {theirs}"
                );
            }
        }
    }
    println!(
        "{} materials, worst relative difference {worst:e}",
        all.len()
    );
}

/// An unknown name (names are case-sensitive, as Mitsuba's file lookup) is refused at
/// its line with the list; a material together with eta or k is refused, as by Mitsuba.
#[test]
fn named_conductor_refusals() {
    let scene = |bsdf: &str| {
        format!(
            r#"<scene version="3.0.0">{SENSOR}
    <shape type="sphere"><bsdf type="conductor">
        {bsdf}
    </bsdf></shape>
</scene>"#
        )
    };
    let e = load_or_build_error(
        "gold",
        load_text(
            "drop_in_rest",
            "gold",
            &scene(r#"<string name="material" value="gold"/>"#),
            &[],
        ),
    );
    assert!(e.contains("scene.xml:4:") && e.contains("\"gold\""), "{e}");
    assert!(e.contains("Au,") && e.contains("Cu_palik"), "{e}");
    for (tag, extra) in [
        ("eta", r#"<float name="eta" value="0.2"/>"#),
        ("k", r#"<float name="k" value="3"/>"#),
    ] {
        let text = scene(&format!(r#"<string name="material" value="Au"/>{extra}"#));
        let e = load_or_build_error(tag, load_text("drop_in_rest", tag, &text, &[]));
        assert!(e.contains("scene.xml:3:") && e.contains("not both"), "{e}");
    }
}

/// named_conductor.xml (a smooth `Au` and a rough `Cu` sphere whose alpha is a constant
/// `<spectrum>`) against Mitsuba 3.
#[test]
fn named_conductor_matches_mitsuba() {
    let c = check_against_reference("named_conductor", "named_conductor", &[], CHUNKS, SPP, 51);
    assert!(c.passed, "{c}");
}

/// The same comparison fails when gold's κ is 3% off (the material replaced by its RGB
/// values, k scaled).
#[test]
fn named_conductor_comparison_detects_k_3_percent_off() {
    let all = mitsuba_conductors();
    let (_, eta, k) = all.iter().find(|(n, _, _)| n == "Au").unwrap();
    let k = *k * 0.97;
    let rgb = |v: Vec3| format!("{}, {}, {}", v.x, v.y, v.z);
    let explicit = format!(
        r#"<rgb name="eta" value="{}"/><rgb name="k" value="{}"/>"#,
        rgb(*eta),
        rgb(k)
    );
    let scene = root().join("mitsuba_scenes/named_conductor.xml");
    let c = check_edited_against_reference(
        "named_conductor",
        &scene,
        &root().join("mitsuba_scenes"),
        &[],
        &[(r#"<string name="material" value="Au"/>"#, &explicit)],
        None,
        CHUNKS,
        SPP,
        52,
    );
    assert!(!c.passed, "gold's k 3% off went unnoticed: {c}");
}

// ---------------------------------------------------------------------------------
// a constant spectrum where a float goes
// ---------------------------------------------------------------------------------

/// The same comparison fails when the copper's alpha (the constant spectrum) is 0.17
/// for 0.2.
#[test]
fn named_conductor_comparison_detects_alpha_off() {
    let c = check_against_reference(
        "named_conductor",
        "named_conductor",
        &[("alpha", "0.17")],
        CHUNKS,
        SPP,
        53,
    );
    assert!(!c.passed, "alpha 0.17 for 0.2 went unnoticed: {c}");
}

/// The roughness `roughconductor` and `roughdielectric` build from `alpha` (or
/// `alpha_u`, `alpha_v`) given as `value`.
fn alphas(tag: &str, plugin: &str, props: &str) -> Result<(f32, f32), String> {
    let text = format!(
        r#"<scene version="3.0.0">{SENSOR}
    <shape type="rectangle"><bsdf type="{plugin}">{props}</bsdf></shape>
</scene>"#
    );
    let desc = load_text("drop_in_rest", tag, &text, &[])?;
    let s = mediareg::load::build_scene(&desc, &Default::default()).map_err(|e| e.to_string())?;
    Ok(match &s.bsdfs[..] {
        [Bsdf::RoughConductor(c)] => (c.distr.alpha_u, c.distr.alpha_v),
        [Bsdf::RoughDielectric(c)] => (c.distr.alpha_u, c.distr.alpha_v),
        other => panic!("{tag}: {other:?}"),
    })
}

/// As in Mitsuba 3 (an unbounded texture's `eval_1`), a rough conductor's or
/// dielectric's roughness may be a constant `<spectrum>` (the same value as the float),
/// an `<rgb>` (its channel mean) or a sampled spectrum (its colour's mean);
/// `roughplastic`'s stays a float, which Mitsuba 3 reads with `get<float>`.
#[test]
fn roughness_takes_a_spectrum_as_mitsuba() {
    for plugin in ["roughconductor", "roughdielectric"] {
        let a = |tag: &str, props: &str| {
            alphas(&format!("{plugin}_{tag}"), plugin, props).unwrap_or_else(|e| panic!("{e}"))
        };
        let float = a("float", r#"<float name="alpha" value="0.3"/>"#);
        assert_eq!(float, (0.3, 0.3));
        assert_eq!(
            a("spectrum", r#"<spectrum name="alpha" value="0.3"/>"#),
            float
        );
        assert_eq!(
            a("rgb", r#"<rgb name="alpha" value="0.2, 0.3, 0.4"/>"#).0,
            (0.2f32 + 0.3 + 0.4) / 3.0
        );
        let uv = a(
            "uv",
            r#"<spectrum name="alpha_u" value="0.1"/><spectrum name="alpha_v" value="0.4"/>"#,
        );
        assert_eq!(uv, (0.1, 0.4));
        // A flat sampled spectrum of 0.3 is (almost) grey 0.3 after the D65 weighting.
        let sampled = a(
            "sampled",
            r#"<spectrum name="alpha" value="360:0.3, 830:0.3"/>"#,
        );
        assert!((sampled.0 - 0.3).abs() < 2e-3, "{sampled:?}");
        let e = alphas(
            &format!("{plugin}_neg"),
            plugin,
            r#"<spectrum name="alpha" value="-0.1"/>"#,
        )
        .unwrap_err();
        assert!(
            e.contains("scene.xml:3:") && e.contains("out of range"),
            "{e}"
        );
    }
    let text = format!(
        r#"<scene version="3.0.0">{SENSOR}
    <shape type="rectangle"><bsdf type="roughplastic"><spectrum name="alpha" value="0.3"/></bsdf></shape>
</scene>"#
    );
    let e = load_or_build_error("plastic", load_text("drop_in_rest", "plastic", &text, &[]));
    assert!(e.contains("scene.xml:3:") && e.contains("<float>"), "{e}");
}

// ---------------------------------------------------------------------------------
// samplers
// ---------------------------------------------------------------------------------

/// Mitsuba 3's sample counts (tests/fixtures, written by scripts/sampler_counts.py):
/// for each sampler, (asked, rendered) pairs.
fn mitsuba_sample_counts() -> Vec<(String, Vec<(u32, u32)>)> {
    let text = std::fs::read_to_string(root().join("tests/fixtures/sampler_counts_mitsuba.json"))
        .expect("fixture");
    let json: serde_json::Value = serde_json::from_str(&text).expect("json");
    json["counts"]
        .as_object()
        .unwrap()
        .iter()
        .map(|(name, pairs)| {
            let pairs = pairs
                .as_array()
                .unwrap()
                .iter()
                .map(|p| (p[0].as_u64().unwrap() as u32, p[1].as_u64().unwrap() as u32))
                .collect();
            (name.clone(), pairs)
        })
        .collect()
}

/// A scene whose sensor holds `sampler`, built with `spp` as `--spp`: its shot's spp,
/// seed and warnings.
fn sampler_shot(
    tag: &str,
    sampler: &str,
    spp: Option<u32>,
) -> Result<(u32, u64, Vec<String>), String> {
    let text = format!(
        r#"<scene version="3.0.0"><sensor type="perspective">
    {sampler}
    <film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/></film></sensor>
</scene>"#
    );
    let desc = load_text("drop_in_rest", tag, &text, &[])?;
    let overrides = mediareg::BuildOverrides {
        spp,
        ..Default::default()
    };
    let s = mediareg::load::build_scene(&desc, &overrides).map_err(|e| e.to_string())?;
    Ok((s.shot.spp, s.shot.seed, s.warnings.clone()))
}

/// Each sampler renders the sample count Mitsuba 3 renders for every count in the
/// fixture (1 to 129 and larger ones): as the file's `sample_count`, and as `--spp`.
#[test]
fn sample_counts_round_as_mitsuba() {
    use mediareg::load::sampler::SamplerKind;
    let all = mitsuba_sample_counts();
    assert_eq!(all.len(), SamplerKind::ALL.len());
    let mut rounded = 0;
    for (name, pairs) in &all {
        let kind = SamplerKind::ALL
            .into_iter()
            .find(|k| k.name() == name)
            .unwrap_or_else(|| panic!("mediareg lacks {name}"));
        for &(asked, want) in pairs {
            assert_eq!(
                kind.sample_count(asked),
                want,
                "{name} sample_count {asked}"
            );
            rounded += usize::from(asked != want);
        }
        // Through the loader, in the file and on the command line.
        for &(asked, want) in pairs.iter().step_by(9) {
            let xml = format!(
                r#"<sampler type="{name}"><integer name="sample_count" value="{asked}"/></sampler>"#
            );
            let (spp, _, notes) = sampler_shot(&format!("{name}_{asked}"), &xml, None).unwrap();
            assert_eq!(spp, want, "{name}: file sample_count {asked}");
            let rounding_noted = notes.iter().any(|n| n.contains("rounded to"));
            assert_eq!(rounding_noted, asked != want, "{name} {asked}: {notes:?}");
            let plain = format!(r#"<sampler type="{name}"/>"#);
            let (spp, _, _) =
                sampler_shot(&format!("{name}_spp{asked}"), &plain, Some(asked)).unwrap();
            assert_eq!(spp, want, "{name}: --spp {asked}");
        }
    }
    println!("{rounded} of the fixture's counts are rounded by Mitsuba 3");
    assert!(rounded > 100);
}

/// The samplers' own parameters are read (`seed`; `jitter`; `strength`), each
/// structured sampler says in one line that mediareg's sampler renders it, and what a
/// sampler does not take is refused as by Mitsuba 3, naming the file and line.
#[test]
fn sampler_parameters() {
    let (spp, seed, notes) = sampler_shot(
        "orthogonal",
        r#"<sampler type="orthogonal"><integer name="sample_count" value="49"/><integer name="seed" value="7"/><boolean name="jitter" value="false"/><integer name="strength" value="3"/></sampler>"#,
        None,
    )
    .unwrap();
    assert_eq!((spp, seed), (49, 7));
    let note: Vec<&String> = notes.iter().filter(|n| n.contains("sampler")).collect();
    assert_eq!(note.len(), 1, "{notes:?}");
    assert!(
        note[0].contains("scene.xml:2:")
            && note[0].contains("\"orthogonal\" (jitter false, strength 3)")
            && note[0].contains("mediareg's sampler"),
        "{}",
        note[0]
    );
    let (_, _, notes) =
        sampler_shot("independent", r#"<sampler type="independent"/>"#, None).unwrap();
    assert!(!notes.iter().any(|n| n.contains("sampler")), "{notes:?}");
    for (tag, xml, needle) in [
        (
            "ld_jitter",
            r#"<sampler type="ldsampler"><boolean name="jitter" value="true"/></sampler>"#,
            "unreferenced property \"jitter\"",
        ),
        (
            "strat_strength",
            r#"<sampler type="stratified"><integer name="strength" value="2"/></sampler>"#,
            "unreferenced property \"strength\"",
        ),
        (
            "sobol",
            r#"<sampler type="sobol"/>"#,
            "independent, stratified, multijitter, orthogonal, ldsampler",
        ),
    ] {
        let e = sampler_shot(tag, xml, None).unwrap_err();
        assert!(
            e.contains("scene.xml:2:") && e.contains(needle),
            "{tag}: {e}"
        );
    }
}

/// samplers.xml, rendered with each of Mitsuba 3's five samplers, against Mitsuba 3's
/// render of the file (with `stratified`).
#[test]
fn every_sampler_matches_mitsuba() {
    for (i, sampler) in [
        "independent",
        "stratified",
        "multijitter",
        "orthogonal",
        "ldsampler",
    ]
    .into_iter()
    .enumerate()
    {
        let c = check_against_reference(
            "samplers",
            "samplers",
            &[("sampler", sampler)],
            CHUNKS,
            144,
            61 + 100 * i as u64,
        );
        assert!(c.passed, "{sampler}: {c}");
    }
}

/// The same comparison fails when a sphere's reflectance is 2% off (with `ldsampler`).
#[test]
fn sampler_comparison_detects_reflectance_2_percent_off() {
    let c = check_against_reference(
        "samplers",
        "samplers",
        &[
            ("sampler", "ldsampler"),
            ("reflectance", "0.714, 0.51, 0.306"),
        ],
        CHUNKS,
        144,
        62,
    );
    assert!(!c.passed, "a 2% reflectance change went unnoticed: {c}");
}

// ---------------------------------------------------------------------------------
// instances read each mesh file once
// ---------------------------------------------------------------------------------

/// The triangles' positions of every mesh a scene builds, in order.
fn mesh_positions(s: &mediareg::scene::Scene) -> Vec<Vec<glam::Vec3A>> {
    s.geometries
        .iter()
        .filter_map(|g| match g {
            mediareg::geometry::shape::Geometry::Mesh(m) => Some(m.positions.to_vec()),
            _ => None,
        })
        .collect()
}

/// instances_mesh.xml (three instances of a group holding an OBJ, and the same OBJ as
/// a shape of its own) reads the file once; each placed copy is bit for bit the copy
/// a scene with that one instance alone builds from its own read of the file.
#[test]
fn instances_read_each_mesh_file_once() {
    let scene = root().join("mitsuba_scenes/instances_mesh.xml");
    let opts = common::options(&[]);
    let desc = mediareg::xml::load_file(&scene, &opts).unwrap_or_else(|e| panic!("{e}"));
    let before = mediareg::load::mesh_files_read();
    let all = common::scene_text::build_desc("instances_mesh", &desc);
    assert_eq!(
        mediareg::load::mesh_files_read() - before,
        1,
        "box.obj read more than once"
    );
    let copies = mesh_positions(&all);
    assert_eq!(copies.len(), 4, "three instances and the block");
    // One instance at a time: the other two and the block removed from the text.
    let text = std::fs::read_to_string(&scene).unwrap();
    let starts: Vec<usize> = text
        .match_indices(r#"<shape type="instance">"#)
        .map(|(i, _)| i)
        .collect();
    let end_of = |i: usize| i + text[i..].find("</shape>").unwrap() + "</shape>".len();
    let block = text.rfind(r#"<shape type="obj">"#).unwrap();
    for (k, &keep) in starts.iter().enumerate() {
        let mut cut = text.clone();
        let mut spans: Vec<(usize, usize)> = starts
            .iter()
            .filter(|&&i| i != keep)
            .map(|&i| (i, end_of(i)))
            .collect();
        spans.push((block, end_of(block)));
        spans.sort();
        for &(a, b) in spans.iter().rev() {
            cut.replace_range(a..b, "");
        }
        // The meshes' folder on the search path, so meshes/box.obj resolves.
        let dir = common::scene_text::tmp_dir("drop_in_rest", &format!("instance_{k}"));
        let path = common::scene_text::write(&dir, "scene.xml", &cut);
        let d = mediareg::xml::load_file(
            &path,
            &common::options_in(&[], vec![root().join("mitsuba_scenes")]),
        );
        let one = mesh_positions(&common::scene_text::build_desc(
            "one",
            &d.unwrap_or_else(|e| panic!("{e}")),
        ));
        assert_eq!(one.len(), 1);
        assert!(
            copies[k] == one[0],
            "instance {k}: the shared read built another mesh"
        );
    }
}

/// instances_mesh.xml against Mitsuba 3.
#[test]
fn instances_mesh_matches_mitsuba() {
    let c = check_against_reference("instances_mesh", "instances_mesh", &[], CHUNKS, SPP, 71);
    assert!(c.passed, "{c}");
}

/// The same comparison fails when the second instance moves by 0.02.
#[test]
fn instances_mesh_comparison_detects_an_instance_moved() {
    let c = check_against_reference(
        "instances_mesh",
        "instances_mesh",
        &[("tree2_x", "0.12")],
        CHUNKS,
        SPP,
        72,
    );
    assert!(!c.passed, "an instance moved by 0.02 went unnoticed: {c}");
}

// ---------------------------------------------------------------------------------
// films: luminance and alpha
// ---------------------------------------------------------------------------------

/// films.xml at `pixel_format` (and `params`), one render at `seed`: the image and the
/// alpha, if the film has one.
fn film_render(
    params: &[(&str, &str)],
    spp: u32,
    seed: u64,
) -> (Vec<[f32; 3]>, Option<Vec<[f32; 3]>>) {
    let scene = root().join("mitsuba_scenes/films.xml");
    let s = common::load_seeded(&scene, params, spp, seed);
    let r = mediareg::integrator::render(&s, &s.shot, &Default::default());
    (r.image.pixels, r.alpha.map(|a| a.pixels))
}

/// The films scene's alpha (luminance_alpha, rendered in `CHUNKS` chunks from `seed`
/// with `params`) against Mitsuba 3's (`reference/NAME`, made with --alpha).
fn check_alpha(
    name: &str,
    params: &[(&str, &str)],
    seed: u64,
) -> mediareg::image::stats::Comparison {
    use mediareg::image::stats::{compare, Estimate};
    let scene = root().join("mitsuba_scenes/films.xml");
    let r = common::reference(name, &scene);
    let chunks: Vec<Vec<[f32; 3]>> = (0..CHUNKS as u64)
        .map(|i| film_render(params, SPP, seed + i).1.expect("an alpha film"))
        .collect();
    let layout = common::layout(&scene, params);
    let ours = Estimate::from_chunks(&chunks, layout);
    let c = compare(
        &ours,
        &r.estimate,
        layout,
        common::ALPHA,
        common::FALSE_ALARM,
    );
    println!("{name} {params:?}: {c}");
    c
}

/// At one seed the formats hold the same render: luminance is Mitsuba's Y of the RGB
/// (0.212671 R + 0.715160 G + 0.072169 B), rgba's colour is rgb's, the alpha the same
/// with either colour; rgb and luminance have no alpha. The alpha is 0 where the rays
/// meet nothing, 1 on the sphere, and strictly between in some fog pixels.
#[test]
fn pixel_formats_hold_the_same_render() {
    let at = |f: &str| film_render(&[("pixel_format", f)], 16, 5);
    let (rgb, none) = at("rgb");
    assert!(none.is_none());
    let (rgba, alpha) = at("rgba");
    assert_eq!(rgb, rgba, "rgba's colour differs from rgb's");
    let (y, none) = at("luminance");
    assert!(none.is_none());
    let (ya, alpha2) = at("luminance_alpha");
    assert_eq!(y, ya);
    for (c, l) in rgb.iter().zip(&y) {
        let want = c[0] * 0.212671 + c[1] * 0.715160 + c[2] * 0.072169;
        assert_eq!(*l, [want; 3]);
    }
    let alpha = alpha.unwrap();
    assert_eq!(Some(&alpha), alpha2.as_ref());
    let a: Vec<f32> = alpha.iter().map(|p| p[0]).collect();
    assert!(a.iter().all(|&v| (0.0..=1.0).contains(&v)));
    assert!(a.contains(&0.0) && a.contains(&1.0), "{a:?}");
    assert!(
        a.iter().any(|&v| v > 0.05 && v < 0.95),
        "no partial alpha in the fog"
    );
}

/// A luminance_alpha film written by `mediareg render` has the channels Y and A, and
/// the comparison tools read it (Y as grey; `read_exr_alpha` the alpha); rgba writes
/// R, G, B, A.
#[test]
fn luminance_alpha_exr_is_written_and_read() {
    let dir = common::scene_text::tmp_dir("drop_in_rest", "films_cli");
    let scene = root().join("mitsuba_scenes/films.xml");
    for (format, rgb) in [("luminance_alpha", false), ("rgba", true)] {
        let out = dir.join(format!("{format}.exr"));
        let status = std::process::Command::new(env!("CARGO_BIN_EXE_mediareg"))
            .args([
                "render",
                scene.to_str().unwrap(),
                "--spp",
                "4",
                "--no-png",
                "-t",
                "1",
            ])
            .args([
                "-D",
                &format!("pixel_format={format}"),
                "-o",
                out.to_str().unwrap(),
            ])
            .output()
            .unwrap();
        assert!(
            status.status.success(),
            "{}",
            String::from_utf8_lossy(&status.stderr)
        );
        let img = mediareg::image::read_exr(&out).unwrap();
        let alpha = mediareg::image::read_exr_alpha(&out)
            .unwrap()
            .expect("an A channel");
        let (want, want_alpha) = film_render(&[("pixel_format", format)], 4, 0);
        assert_eq!(img.pixels, want, "{format}");
        let want_alpha: Vec<f32> = want_alpha.unwrap().iter().map(|p| p[0]).collect();
        assert_eq!(alpha, want_alpha, "{format}");
        assert_eq!(rgb, img.pixels.iter().any(|p| p[0] != p[1]), "{format}");
    }
}

/// films.xml as a Mitsuba 2 file (version 2.0.0) whose film asks `component_format`
/// `value`, its light moved into view (seen directly, above 1), in a fresh folder.
fn films_v2_with_component_format(value: &str) -> std::path::PathBuf {
    let text = std::fs::read_to_string(root().join("mitsuba_scenes/films.xml")).unwrap();
    let pixel_format = r#"<string name="pixel_format" value="$pixel_format"/>"#;
    let light = r#"<point name="center" x="0" y="2" z="1"/>"#;
    for part in [pixel_format, light, r#"version="3.0.0""#] {
        assert!(text.contains(part), "films.xml has no {part}");
    }
    let text = text
        .replace(r#"version="3.0.0""#, r#"version="2.0.0""#)
        .replace(light, r#"<point name="center" x="0" y="1.2" z="1"/>"#)
        .replace(
            pixel_format,
            &format!(r#"{pixel_format}<string name="component_format" value="{value}"/>"#),
        );
    let dir = common::scene_text::tmp_dir("drop_in_rest", &format!("component_{value}"));
    common::scene_text::write(&dir, "films_v2.xml", &text)
}

/// The R, G, B channels of a uint32 EXR (written B, G, R, as Mitsuba and mediareg
/// write them), each its samples; fails where a channel is missing or not uint32.
fn uint32_channels(path: &std::path::Path) -> [Vec<u32>; 3] {
    use exr::prelude::*;
    let file = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .unwrap();
    let channels = &file.layer_data.channel_data.list;
    let names: Vec<String> = channels.iter().map(|c| c.name.to_string()).collect();
    assert_eq!(names, ["B", "G", "R"], "{}", path.display());
    let samples = |i: usize| match &channels[i].sample_data {
        FlatSamples::U32(v) => v.clone(),
        other => panic!("channel {} is not uint32: {other:?}", channels[i].name),
    };
    [samples(2), samples(1), samples(0)]
}

/// A Mitsuba 2 file whose `hdrfilm` asks `component_format` uint32 loads and renders as
/// in Mitsuba 3: `mediareg render` writes R, G, B as uint32 samples (Mitsuba's
/// `Imf::UINT` channels), each the render's value quantized as Mitsuba quantizes it
/// (clamped to [0, 1]: the light seen directly saturates), and `read_exr` reads them
/// back normalized, as Mitsuba reads them. An unknown component format is still an
/// error naming it and the formats there are.
#[test]
fn uint32_film_is_written_as_mitsuba_writes_it() {
    use mediareg::scene::film::quantize_uint32;
    let scene = films_v2_with_component_format("uint32");
    let out = scene.with_file_name("out.exr");
    let run = std::process::Command::new(env!("CARGO_BIN_EXE_mediareg"))
        .args(["render", scene.to_str().unwrap(), "--spp", "4", "--no-png"])
        .args([
            "-t",
            "1",
            "-D",
            "pixel_format=rgb",
            "-o",
            out.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );

    let rgb = [("pixel_format", "rgb")];
    let s = common::load_seeded(&scene, &rgb, 4, 0);
    let want = mediareg::integrator::render(&s, &s.shot, &Default::default())
        .image
        .pixels;
    for (c, samples) in uint32_channels(&out).iter().enumerate() {
        let quantized: Vec<u32> = want.iter().map(|p| quantize_uint32(p[c])).collect();
        assert_eq!(samples, &quantized, "channel {c}");
    }
    let values = || want.iter().flatten();
    assert!(values().any(|&v| v > 1.0), "no pixel saturates");
    assert!(values().any(|&v| v > 0.0 && v < 1.0), "no pixel in (0, 1)");

    let read = mediareg::image::read_exr(&out).unwrap();
    for (got, v) in read.pixels.iter().flatten().zip(values()) {
        assert!((got - v.clamp(0.0, 1.0)).abs() < 1e-7, "{got} read for {v}");
    }

    let scene = films_v2_with_component_format("uint16");
    let loaded = mediareg::xml::load_file(&scene, &common::options(&[])).map_err(|e| e.to_string());
    let loaded = load_or_build_error("uint16", loaded);
    assert!(
        loaded.contains("component_format \"uint16\"") && loaded.contains("uint32"),
        "{loaded}"
    );
}

/// The luminance (luminance_alpha film) against Mitsuba 3's Y.
#[test]
fn luminance_matches_mitsuba() {
    let c = check_against_reference("films", "films", &[], CHUNKS, SPP, 81);
    assert!(c.passed, "{c}");
}

/// The same comparison fails when the fog's albedo is 0.78 for 0.8.
#[test]
fn luminance_comparison_detects_albedo_off() {
    let c = check_against_reference("films", "films", &[("albedo", "0.78")], CHUNKS, SPP, 82);
    assert!(!c.passed, "albedo 0.78 for 0.8 went unnoticed: {c}");
}

/// The alpha (luminance_alpha, and rgba) against Mitsuba 3's, with volpath and with
/// path (`films_path_alpha`: the fog ignored).
#[test]
fn alpha_matches_mitsuba() {
    let c = check_alpha("films_alpha", &[], 83);
    assert!(c.passed, "{c}");
    let c = check_alpha("films_alpha", &[("pixel_format", "rgba")], 183);
    assert!(c.passed, "rgba: {c}");
    let c = check_alpha("films_path_alpha", &[("integrator", "path")], 283);
    assert!(c.passed, "path: {c}");
}

/// The same comparisons fail when the fog's sigma_t is 5% off (volpath) or the
/// sphere's radius 2% off (path).
#[test]
fn alpha_comparison_detects_sigma_t_and_radius_off() {
    let c = check_alpha("films_alpha", &[("sigma_t", "1.575")], 84);
    assert!(!c.passed, "sigma_t 5% off went unnoticed in the alpha: {c}");
    let c = check_alpha(
        "films_path_alpha",
        &[("integrator", "path"), ("radius", "0.49")],
        284,
    );
    assert!(
        !c.passed,
        "the radius 2% off went unnoticed in path's alpha: {c}"
    );
}

/// The uint32 quantizer against a file Mitsuba 3 wrote (tests/fixtures/film, made by
/// scripts/make_uint32_fixture.py: chosen float values, negative, tiny, near and above
/// 1, through Mitsuba's `Bitmap::convert` to uint32): `quantize_uint32` gives Mitsuba's
/// samples exactly where Mitsuba's ordered dither cannot move them (values of 2^-8 and
/// more, and those it clamps) and within one step below; `read_exr` reads Mitsuba's
/// file as Mitsuba reads it. Seen failing with the clamp at 2^32 − 1 (Mitsuba's top is
/// 4294967040, the largest f32 below 2^32). (Rounding by truncation would pass: v · 2^32
/// in f32 is an integer from 2^-9 up, so the rounding mode shows only under the dither.)
#[test]
fn uint32_quantizer_matches_a_file_mitsuba_wrote() {
    use mediareg::scene::film::{dequantize_uint32, quantize_uint32};
    let dir = root().join("tests/fixtures/film");
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("uint32_mitsuba.json")).unwrap())
            .unwrap();
    for name in ["uint32_input.exr", "uint32_mitsuba.exr"] {
        let digest = common::sha256_hex(&dir.join(name));
        assert_eq!(
            meta["sha256"][name].as_str(),
            Some(digest.as_str()),
            "{name} is not the file scripts/make_uint32_fixture.py recorded"
        );
    }
    let input = mediareg::image::read_exr(&dir.join("uint32_input.exr")).unwrap();
    let theirs = uint32_channels(&dir.join("uint32_mitsuba.exr"));
    let mut checked = 0;
    for (c, theirs) in theirs.iter().enumerate() {
        for (p, &q) in input.pixels.iter().zip(theirs) {
            let v = p[c];
            let ours = quantize_uint32(v);
            let dithered = v > 0.0 && v < 2f32.powi(-8);
            let step = ours.abs_diff(q);
            assert!(
                step == 0 || (dithered && step <= 1),
                "{v}: ours {ours}, Mitsuba's {q}"
            );
            checked += (!dithered) as usize;
        }
    }
    assert!(checked > 300, "only {checked} values away from the dither");
    let read_back = mediareg::image::read_exr(&dir.join("uint32_mitsuba.exr")).unwrap();
    for (c, theirs) in theirs.iter().enumerate() {
        for (p, &q) in read_back.pixels.iter().zip(theirs) {
            assert_eq!(p[c], dequantize_uint32(q));
        }
    }
}
