//! Drop-in structure of published scenes (issue 30, part C): geometry instancing
//! (`shapegroup` + `instance`), objects referenced before they are declared, several or
//! no sensors, integrators rendered by one of mediareg's, media nested without a name,
//! and unread properties in files older than 2.0.

mod common;

use common::check_against_reference;

const CHUNKS: usize = 8;
const SPP: u32 = 64;

/// Three instances of a two-shape group (a cube and a sphere), referred to before the
/// group is declared, against Mitsuba 3 (`reference/instances`, 16384 spp).
#[test]
fn instances_match_mitsuba() {
    let c = check_against_reference("instances", "instances", &[], CHUNKS, SPP, 11);
    assert!(c.passed, "{c}");
}

/// Power: the second instance moved by 0.02 (of a 8-unit floor; about a third of a pixel)
/// is detected.
#[test]
fn instances_comparison_detects_an_instance_moved() {
    let c = check_against_reference(
        "instances",
        "instances",
        &[("tree2_x", "0.12")],
        CHUNKS,
        SPP,
        12,
    );
    assert!(!c.passed, "an instance moved by 0.02 went undetected: {c}");
}

/// The same instances scene with `prb` and `ptracer`, which mediareg renders with its
/// `path` (a warning says so), against Mitsuba 3's own prb and ptracer renders of it
/// (`reference/instances_prb`, `instances_ptracer`, 16384 spp each).
#[test]
fn prb_and_ptracer_render_as_path_and_match_mitsuba() {
    for name in ["prb", "ptracer"] {
        let reference = format!("instances_{name}");
        let c = check_against_reference(
            &reference,
            "instances",
            &[("integrator", name)],
            CHUNKS,
            SPP,
            13,
        );
        assert!(c.passed, "{name}: {c}");
    }
}

/// Power on the ptracer reference: the same 0.02 move of an instance is detected.
#[test]
fn ptracer_comparison_detects_an_instance_moved() {
    let c = check_against_reference(
        "instances_ptracer",
        "instances",
        &[("integrator", "ptracer"), ("tree2_x", "0.12")],
        CHUNKS,
        SPP,
        14,
    );
    assert!(!c.passed, "an instance moved by 0.02 went undetected: {c}");
}

// ---------------------------------------------------------------------------------
// Loading and building scenes written in the test.

use common::scene_text::{tmp_dir, write, SENSOR};
use mediareg::scene::{IntegratorKind, Scene};
use mediareg::xml::LoadOptions;
use mediareg::BuildOverrides;
use std::path::{Path, PathBuf};

fn fixture(name: &str) -> PathBuf {
    common::root().join("tests/fixtures/drop_in").join(name)
}

/// Writes `text` as `tag/scene.xml` and loads and builds it; the error as text.
fn build_text(
    tag: &str,
    text: &str,
    strict_v3: bool,
    overrides: &BuildOverrides,
) -> Result<Scene, String> {
    let path = write(&tmp_dir("drop_in_structure", tag), "scene.xml", text);
    build_file(&path, strict_v3, overrides)
}

fn build_file(path: &Path, strict_v3: bool, overrides: &BuildOverrides) -> Result<Scene, String> {
    let opts = LoadOptions {
        strict_v3,
        ..Default::default()
    };
    mediareg::load_scene(path, &opts, overrides).map_err(|e| e.to_string())
}

fn scene3(body: &str) -> String {
    format!("<scene version=\"3.0.0\">{SENSOR}\n{body}\n</scene>")
}

fn render(s: &Scene) -> Vec<[f32; 3]> {
    mediareg::integrator::render(s, &s.shot, &Default::default())
        .image
        .pixels
}

fn seeded(spp: u32, seed: u64) -> BuildOverrides {
    BuildOverrides {
        spp: Some(spp),
        seed: Some(seed),
        ..Default::default()
    }
}

/// Every object referred to before it is declared (a sampler, a textured bsdf, a
/// dielectric, a medium and its top-level hg phase): the image is bit for bit that of
/// the same file in declaration order.
#[test]
fn forward_references_render_as_the_file_in_declaration_order() {
    let o = seeded(4, 5);
    let fwd = build_file(&fixture("forward_refs.xml"), false, &o).unwrap();
    let ordered = build_file(&fixture("forward_refs_ordered.xml"), false, &o).unwrap();
    assert_eq!(fwd.media.len(), 1);
    assert!(matches!(
        fwd.media[0].phase,
        mediareg::medium::Phase::HenyeyGreenstein { g } if g == 0.6
    ));
    let (a, b) = (render(&fwd), render(&ordered));
    assert!(a.iter().any(|p| p[0] > 0.0), "the image is not black");
    assert!(a == b, "forward references changed the image");
}

/// An id no object declares is an error at the <ref>'s line; so is a reference cycle.
#[test]
fn undeclared_and_circular_references_are_errors_at_the_ref() {
    let e = build_text(
        "undeclared",
        &scene3("<shape type=\"sphere\">\n<ref id=\"nowhere\"/></shape>"),
        false,
        &Default::default(),
    )
    .err()
    .expect("an error");
    assert!(
        e.contains("scene.xml:4:") && e.contains("\"nowhere\""),
        "{e}"
    );
    let e = build_text(
        "cycle",
        &scene3(
            "<bsdf type=\"twosided\" id=\"a\">\n<ref id=\"b\"/></bsdf>\n<bsdf type=\"twosided\" id=\"b\">\n<ref id=\"a\"/></bsdf>",
        ),
        false,
        &Default::default(),
    )
    .err().expect("an error");
    assert!(
        e.contains("circular reference")
            && (e.contains("scene.xml:4:") || e.contains("scene.xml:6:")),
        "{e}"
    );
}

const GROUP: &str = r#"<shape type="shapegroup" id="g"><shape type="sphere"><float name="radius" value="0.5"/></shape><shape type="cube"/></shape>"#;

/// Each instance adds the group's shapes, placed; the group itself adds none.
#[test]
fn each_instance_places_a_copy_of_the_group() {
    let inst = |t: &str| {
        format!("<shape type=\"instance\"><ref id=\"g\"/><transform name=\"to_world\">{t}</transform></shape>")
    };
    let s = build_text(
        "two_instances",
        &scene3(&format!(
            "{GROUP}{}{}",
            inst("<translate x=\"3\"/>"),
            inst("<scale value=\"2\"/><translate y=\"-4\"/>")
        )),
        false,
        &Default::default(),
    )
    .unwrap();
    assert_eq!(s.shapes.len(), 4, "two instances of a two-shape group");
    let s = build_text("no_instance", &scene3(GROUP), false, &Default::default()).unwrap();
    assert_eq!(s.shapes.len(), 0, "a shapegroup alone renders nothing");
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("no instance refers to it")),
        "{:?}",
        s.warnings
    );
}

/// What Mitsuba 3 refuses in instancing (an emitter in a group, nested groups, an
/// instance of a plain shape), and what a baked copy cannot be (a mirrored instance, a
/// sphere scaled non-uniformly): each an error naming the line.
#[test]
fn instancing_mitsuba_refuses_or_we_cannot_bake_is_refused_with_the_line() {
    let cases = [
        ("emitter", "<shape type=\"shapegroup\" id=\"g\"><shape type=\"sphere\">\n<emitter type=\"area\"/></shape></shape><shape type=\"instance\"><ref id=\"g\"/></shape>", "Instancing of emitters", 4),
        ("nested", "<shape type=\"shapegroup\" id=\"g\">\n<shape type=\"shapegroup\"/></shape>", "inside a shapegroup", 4),
        ("plain", "<shape type=\"sphere\" id=\"s\"/><shape type=\"instance\">\n<ref id=\"s\"/></shape>", "only a shapegroup", 4),
        ("mirror", &format!("{GROUP}\n<shape type=\"instance\"><ref id=\"g\"/><transform name=\"to_world\"><scale x=\"-1\"/></transform></shape>"), "mirrors", 4),
        ("ellipsoid", &format!("{GROUP}\n<shape type=\"instance\"><ref id=\"g\"/><transform name=\"to_world\"><scale x=\"2\"/></transform></shape>"), "non-uniformly", 3),
    ];
    for (tag, body, what, line) in cases {
        let e = build_text(tag, &scene3(body), false, &Default::default())
            .err()
            .expect("an error");
        assert!(
            e.contains(what) && e.contains(&format!("scene.xml:{line}:")),
            "{tag}: {e}"
        );
    }
}

/// Several sensors: sensor 0 by default, with a line saying so; `--sensor N` picks one,
/// without that line (it was asked for); a number past the last is an error.
#[test]
fn sensor_option_picks_one_of_several_sensors() {
    let film = |w: u32| {
        format!("<sensor type=\"perspective\"><film type=\"hdrfilm\"><integer name=\"width\" value=\"{w}\"/><integer name=\"height\" value=\"4\"/></film></sensor>")
    };
    let text = format!(
        "<scene version=\"3.0.0\">\n{}\n{}\n</scene>",
        film(8),
        film(12)
    );
    let pick = |n: usize| BuildOverrides {
        sensor: Some(n),
        ..Default::default()
    };
    let said =
        |s: &mediareg::scene::Scene| s.warnings.iter().any(|w| w.contains("rendering sensor"));
    let unasked = build_text("sensor", &text, false, &Default::default()).unwrap();
    let s0 = build_text("sensor0", &text, false, &pick(0)).unwrap();
    let s1 = build_text("sensor1", &text, false, &pick(1)).unwrap();
    assert_eq!(
        (
            unasked.shot.film.width,
            s0.shot.film.width,
            s1.shot.film.width
        ),
        (8, 8, 12)
    );
    assert!(
        unasked.warnings.iter().any(
            |w| w.contains("scene.xml:2:") && w.contains("rendering sensor 0 of the scene's 2")
        ),
        "{:?}",
        unasked.warnings
    );
    assert!(
        !said(&s0) && !said(&s1),
        "{:?} {:?}",
        s0.warnings,
        s1.warnings
    );
    let e = build_text("sensor2", &text, false, &pick(2))
        .err()
        .expect("an error");
    assert!(e.contains("--sensor 2") && e.contains("2 <sensor>s"), "{e}");
}

/// No sensor: the camera Mitsuba 2 (and Mitsuba 3 before 3.0) added. Mitsuba 3.9.1's
/// bounding box of tests/fixtures/drop_in/no_sensor.xml is (-1.6, -1.2, -0.75) to (1.6,
/// 1.2, 1.3) (`mi.load_file(...).bbox()`); Mitsuba 2's formula in float32 gives distance
/// 3.86274171, near_clip 0.0386274159, far_clip 19.8627415 and the camera at (0, 0,
/// -4.61274147), looking along +z with a 45° fov, the default 768 × 576 film and 4 spp.
/// no_sensor_explicit.xml writes that camera out: both render bit for bit alike.
#[test]
fn no_sensor_gets_mitsuba_2s_default_camera() {
    let s = build_file(&fixture("no_sensor.xml"), false, &Default::default()).unwrap();
    let c = &s.shot.camera;
    let close = |a: f32, b: f64| (a as f64 - b).abs() <= 1e-6 * b.abs().max(1.0);
    assert!(
        close(c.near_clip, 0.0386274159) && close(c.far_clip, 19.8627415),
        "{c:?}"
    );
    assert!(close(c.tan_half_fov_x, 22.5f64.to_radians().tan()), "{c:?}");
    let origin = c.to_world.transform_point3(glam::Vec3::ZERO);
    assert!(
        close(origin.x, 0.0) && close(origin.y, 0.0) && close(origin.z, -4.61274147),
        "{origin}"
    );
    assert_eq!(
        (s.shot.film.width, s.shot.film.height, s.shot.spp),
        (768, 576, 4)
    );
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("no <sensor>") && w.contains("Mitsuba 3 refuses")),
        "{:?}",
        s.warnings
    );
    let o = seeded(1, 3);
    let a = render(&build_file(&fixture("no_sensor.xml"), false, &o).unwrap());
    let b = render(&build_file(&fixture("no_sensor_explicit.xml"), false, &o).unwrap());
    assert!(
        a == b,
        "the default camera differs from Mitsuba's numbers written out"
    );
}

/// Integrators that estimate the image of one of mediareg's are rendered by it with one
/// warning line; prb's depth defaults to 6 (Mitsuba's ADIntegrator); `aov` renders its
/// nested integrator; an unknown one is refused with a hint naming --integrator.
#[test]
fn integrator_aliases_render_with_ours_and_unknown_ones_name_the_option() {
    let with = |tag: &str, integrator: &str| {
        build_text(tag, &scene3(integrator), false, &Default::default())
    };
    let s = with("prb", "<integrator type=\"prb\"/>").unwrap();
    assert_eq!(
        (s.integrator.kind, s.integrator.max_depth),
        (IntegratorKind::Path, 6)
    );
    assert_eq!(
        s.warnings
            .iter()
            .filter(|w| w.contains("\"prb\" is rendered by mediareg's path"))
            .count(),
        1,
        "{:?}",
        s.warnings
    );
    let s = with(
        "prbvolpath",
        "<integrator type=\"prbvolpath\"><integer name=\"max_depth\" value=\"9\"/></integrator>",
    )
    .unwrap();
    assert_eq!(
        (s.integrator.kind, s.integrator.max_depth),
        (IntegratorKind::Volpath, 9)
    );
    let s = with("ptracer", "<integrator type=\"ptracer\"><boolean name=\"hide_emitters\" value=\"true\"/><integer name=\"samples_per_pass\" value=\"4\"/></integrator>").unwrap();
    assert!(s.integrator.kind == IntegratorKind::Path && s.integrator.hide_emitters);
    let s = with("aov", "<integrator type=\"aov\"><string name=\"aovs\" value=\"dd.y:depth\"/><integrator type=\"volpath\"/></integrator>").unwrap();
    assert_eq!(s.integrator.kind, IntegratorKind::Volpath);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("AOVs \"dd.y:depth\" are not written")),
        "{:?}",
        s.warnings
    );
    let e = with("bdpt_v3", "\n<integrator type=\"bdpt\"/>")
        .err()
        .expect("an error");
    assert!(
        e.contains("scene.xml:4:") && e.contains("--integrator"),
        "{e}"
    );
}

/// `--integrator NAME` replaces the file's integrator, keeping its depth settings; an
/// unknown NAME is an error listing ours.
#[test]
fn integrator_option_overrides_the_file() {
    let text = scene3("<integrator type=\"path\"><integer name=\"max_depth\" value=\"3\"/><integer name=\"rr_depth\" value=\"2\"/></integrator>");
    let o = |name: &str| BuildOverrides {
        integrator: Some(name.into()),
        ..Default::default()
    };
    let s = build_text("override", &text, false, &o("volpath")).unwrap();
    assert_eq!(
        (
            s.integrator.kind,
            s.integrator.max_depth,
            s.integrator.rr_depth
        ),
        (IntegratorKind::Volpath, 3, 2)
    );
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("--integrator volpath")),
        "{:?}",
        s.warnings
    );
    let e = build_text("override_bad", &text, false, &o("bdpt"))
        .err()
        .expect("an error");
    assert!(
        e.contains("--integrator bdpt") && e.contains("path, volpath, direct"),
        "{e}"
    );
}

/// A medium nested in a shape without name="interior"/"exterior" is bound to nothing
/// (as Mitsuba 3's Shape does), with a warning line naming where it is.
#[test]
fn unnamed_nested_medium_is_bound_to_nothing_with_a_warning() {
    let s = build_text(
        "unnamed_medium",
        &scene3("<shape type=\"sphere\">\n<medium type=\"homogeneous\"/></shape>"),
        false,
        &Default::default(),
    )
    .unwrap();
    assert_eq!((s.shapes[0].interior, s.shapes[0].exterior), (None, None));
    assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
    assert!(
        s.warnings[0].contains("scene.xml:4:") && s.warnings[0].contains("bound to nothing"),
        "{:?}",
        s.warnings
    );
}

/// A property no plugin reads: in a 0.6 file one warning line each and the scene
/// renders (Mitsuba 0.6 logged it); with --strict-v3, and in any 3.0 file, an error at
/// its line.
#[test]
fn unread_properties_of_old_files_are_warnings_unless_strict() {
    let body = |version: &str| {
        format!(
            "<scene version=\"{version}\"><sensor type=\"perspective\"><film type=\"hdrfilm\"><integer name=\"width\" value=\"8\"/><integer name=\"height\" value=\"4\"/></film></sensor>\n<integrator type=\"volpath\">\n<integer name=\"version\" value=\"2\"/>\n<boolean name=\"strictNormals\" value=\"true\"/></integrator></scene>"
        )
    };
    let s = build_text("v06", &body("0.6.0"), false, &Default::default()).unwrap();
    let unread: Vec<_> = s
        .warnings
        .iter()
        .filter(|w| w.contains("ignored, as Mitsuba 0.6 ignored it"))
        .collect();
    assert_eq!(unread.len(), 2, "{:?}", s.warnings);
    assert!(
        unread[0].contains("scene.xml:3:") && unread[0].contains("\"version\""),
        "{unread:?}"
    );
    assert!(
        unread[1].contains("scene.xml:4:") && unread[1].contains("\"strict_normals\""),
        "{unread:?}"
    );
    let e = build_text("v06_strict", &body("0.6.0"), true, &Default::default())
        .err()
        .expect("an error");
    assert!(
        e.contains("scene.xml:3:") && e.contains("unreferenced property \"version\""),
        "{e}"
    );
    let e = build_text("v3", &body("3.0.0"), false, &Default::default())
        .err()
        .expect("an error");
    assert!(
        e.contains("scene.xml:3:") && e.contains("unreferenced property \"version\""),
        "{e}"
    );
}

/// Mitsuba 0.6's `volpath_simple` and `bdpt` in a 0.6 file: rendered by volpath (bdpt by
/// path when the file has no medium), with the warning line.
#[test]
fn old_integrators_render_with_ours_in_old_files() {
    let old = |tag: &str, integrator: &str, extra: &str| {
        build_text(
            tag,
            &format!("<scene version=\"0.6.0\">{SENSOR}<integrator type=\"{integrator}\"><integer name=\"maxDepth\" value=\"5\"/></integrator>{extra}</scene>"),
            false,
            &Default::default(),
        )
        .unwrap()
    };
    let s = old("simple", "volpath_simple", "");
    assert_eq!(
        (s.integrator.kind, s.integrator.max_depth),
        (IntegratorKind::Volpath, 5)
    );
    assert_eq!(
        old("bdpt", "bdpt", "").integrator.kind,
        IntegratorKind::Path
    );
    let fog = "<shape type=\"sphere\"><medium type=\"homogeneous\" name=\"interior\"/></shape>";
    let s = old("bdpt_media", "bdpt", fog);
    assert_eq!(s.integrator.kind, IntegratorKind::Volpath);
    assert!(
        s.warnings
            .iter()
            .any(|w| w.contains("\"bdpt\" is rendered by mediareg's volpath")),
        "{:?}",
        s.warnings
    );
}
