//! The Mitsuba 3 XML parser and scene builder, checked against what real Mitsuba 3
//! (3.9.1, `scalar_rgb`) does with the same XML.
//!
//! * Transform matrices come from tests/fixtures/transforms.json, written by
//!   scripts/transform_fixtures.py (Mitsuba's own parser output, double precision).
//! * Every other expected number below was observed with `mi.load_string` +
//!   `mi.traverse` (or a sensor/shape query) on the same XML; the comment next to each
//!   says which.
//!
//! Each test writes its scene into its own folder under `std::env::temp_dir()`.

mod common;

use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3, Vec3};
use mediareg::bsdf::Bsdf;
use mediareg::emitter::Emitter;
use mediareg::geometry::shape::Geometry;
use mediareg::load::build_scene;
use mediareg::load::UNIFORM_SPECTRUM_RGB;
use mediareg::medium::Phase;
use mediareg::scene::film::Rfilter;
use mediareg::scene::Scene;
use mediareg::xml::description::{ObjectKind, SceneDescription, Value};
use mediareg::xml::{load_file, LoadOptions};
use mediareg::BuildOverrides;

use common::scene_text::{self, build_desc, load_or_build_error, prop, write, SENSOR};

// ---------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------

fn tmp_dir(tag: &str) -> PathBuf {
    scene_text::tmp_dir("parser", tag)
}

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/parser")
        .join(name)
}

/// Loads `<scene version="3.0.0">{body}</scene>` (body on its own lines) from a temp file.
fn load_with(tag: &str, body: &str, params: &[(&str, &str)]) -> Result<SceneDescription, String> {
    let text = format!("<scene version=\"3.0.0\">\n{body}\n</scene>\n");
    scene_text::load_text("parser", tag, &text, params)
}

fn load(tag: &str, body: &str) -> SceneDescription {
    load_with(tag, body, &[]).unwrap_or_else(|e| panic!("{tag}: load failed:\n{e}"))
}

/// Loads and builds `body` plus the default sensor.
fn build(tag: &str, body: &str) -> Scene {
    let desc = load(tag, &format!("{SENSOR}\n{body}"));
    build_desc(tag, &desc)
}

/// Loads and builds `body` as is (it brings its own sensor).
fn build_raw(tag: &str, body: &str) -> Scene {
    let desc = load(tag, body);
    build_desc(tag, &desc)
}

/// The error of loading or building `body` (plus the default sensor).
fn build_err(tag: &str, body: &str) -> String {
    load_or_build_error(tag, load_with(tag, &format!("{SENSOR}\n{body}"), &[]))
}

/// |a − b| ≤ tol · max(1, |b|): relative for large values, absolute near zero.
fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * b.abs().max(1.0)
}

#[track_caller]
fn assert_close(got: f64, want: f64, tol: f64, what: &str) {
    assert!(
        close(got, want, tol),
        "{what}: got {got}, expected {want} (tolerance {tol})"
    );
}

#[track_caller]
fn assert_vec3(got: Vec3, want: [f32; 3], tol: f64, what: &str) {
    for i in 0..3 {
        assert!(
            close(got[i] as f64, want[i] as f64, tol),
            "{what}: got {got}, expected {want:?} (component {i}, tolerance {tol})"
        );
    }
}

fn sphere(scene: &Scene, i: usize) -> (Vec3, f32, bool) {
    match &scene.geometries[i] {
        Geometry::Sphere(s) => (Vec3::from(s.center), s.radius, s.flip_normals),
        other => panic!("shape {i} should be a sphere, is {other:?}"),
    }
}

fn planar_area(scene: &Scene, i: usize) -> f32 {
    match &scene.geometries[i] {
        Geometry::Planar(p) => p.area,
        other => panic!("shape {i} should be a rectangle/disk, is {other:?}"),
    }
}

fn dielectric_eta(b: &Bsdf) -> f32 {
    match b {
        Bsdf::Dielectric(d) => d.eta,
        other => panic!("expected a dielectric, got {other:?}"),
    }
}

// ---------------------------------------------------------------------------------------
// (a) <transform> against Mitsuba's parser
// ---------------------------------------------------------------------------------------

fn transform_fixtures() -> serde_json::Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/transforms.json");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| {
        panic!(
            "{}: {e} (run scripts/transform_fixtures.py)",
            path.display()
        )
    });
    serde_json::from_str(&text).expect("transforms.json is valid JSON")
}

fn parse_transform(name: &str, ops: &str) -> Result<DMat4, String> {
    let desc = load_with(
        &format!("transform_{name}"),
        &format!(
            "<shape type=\"rectangle\">\n<transform name=\"to_world\">{ops}</transform>\n</shape>"
        ),
        &[],
    )?;
    match prop(&desc, ObjectKind::Shape, "to_world") {
        Value::Transform(m) => Ok(*m),
        other => Err(format!("to_world parsed as <{}>", other.type_name())),
    }
}

#[test]
fn transform_fixtures_were_made_by_mitsuba_3() {
    let f = transform_fixtures();
    let version = f["mitsuba_version"].as_str().expect("mitsuba_version");
    assert!(version.starts_with("3."), "fixtures from Mitsuba {version}");
    let cases = f["cases"].as_array().expect("cases");
    assert!(cases.len() >= 30, "only {} transform cases", cases.len());
}

/// Fixture cases with a test of their own (a known difference from Mitsuba, kept
/// separate so that the other cases still guard the transform code).
const SEPARATELY_TESTED: &[&str] = &["matrix_16_projective"];

/// Compares mediareg's matrix for fixture case `name` with Mitsuba's; `Err` lists the
/// differing entries.
fn check_transform_case(case: &serde_json::Value) -> Result<(), String> {
    let name = case["name"].as_str().unwrap();
    let ops = case["xml"].as_str().unwrap();
    let want: Vec<Vec<f64>> = case["matrix"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            r.as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect()
        })
        .collect();
    assert_eq!(want.len(), 4, "{name}: 4 rows");
    let m = parse_transform(name, ops)
        .map_err(|e| format!("{name}: {ops}\n  mediareg refuses it: {e}"))?;
    let mut bad = Vec::new();
    for (r, row) in want.iter().enumerate() {
        assert_eq!(row.len(), 4, "{name}: 4 columns");
        for (c, &w) in row.iter().enumerate() {
            let got = m.row(r)[c];
            if !close(got, w, 1e-5) {
                bad.push(format!("({r},{c}) mediareg {got} vs Mitsuba {w}"));
            }
        }
    }
    if bad.is_empty() {
        Ok(())
    } else {
        Err(format!("{name}: {ops}\n  {}", bad.join("\n  ")))
    }
}

fn transform_case(name: &str) -> serde_json::Value {
    transform_fixtures()["cases"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["name"] == name)
        .unwrap_or_else(|| panic!("no fixture case {name}"))
        .clone()
}

/// Every case of transforms.json (but SEPARATELY_TESTED): all 16 entries within 1e-5
/// (relative; absolute near 0) of the matrix Mitsuba's parser builds. All mismatches
/// are listed before failing.
#[test]
fn transforms_match_mitsuba() {
    let f = transform_fixtures();
    let failures: Vec<String> = f["cases"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| !SEPARATELY_TESTED.contains(&c["name"].as_str().unwrap()))
        .filter_map(|c| check_transform_case(c).err())
        .collect();
    assert!(
        failures.is_empty(),
        "{} transform case(s) differ from Mitsuba 3:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Mitsuba 3.9 parses `<transform>` into an *affine* transform (AffineTransform4d): a
/// `<matrix>` with bottom row (0.1, 0.2, 0.3, 1) comes out with bottom row (0, 0, 0, 1).
/// mediareg keeps the projective row.
#[test]
fn matrix_bottom_row_is_dropped_like_mitsuba_3_9() {
    if let Err(e) = check_transform_case(&transform_case("matrix_16_projective")) {
        panic!("differs from Mitsuba 3.9.1:\n{e}");
    }
}

/// Mitsuba 3 uses the rotation axis as given (no normalisation): `rotate(0,0,2, 90°)`
/// has z-z entry |a|² = 4 (checked in the fixtures too; spelled out here).
#[test]
fn rotate_does_not_normalize_the_axis() {
    let m = parse_transform("rot002", r#"<rotate value="0, 0, 2" angle="90"/>"#).unwrap();
    assert_close(m.row(2)[2], 4.0, 1e-12, "m[2][2] of rotate(0,0,2; 90°)");
    assert_close(m.row(0)[1], -2.0, 1e-12, "m[0][1] of rotate(0,0,2; 90°)");
    assert_close(m.row(1)[0], 2.0, 1e-12, "m[1][0] of rotate(0,0,2; 90°)");
}

/// Later operations apply after earlier ones: translate then rotate 90° about z
/// maps the origin to (0, 1, 0).
#[test]
fn transform_ops_compose_left_to_right() {
    let m = parse_transform(
        "compose",
        r#"<translate value="1, 0, 0"/><rotate z="1" angle="90"/>"#,
    )
    .unwrap();
    let p = m.transform_point3(DVec3::ZERO);
    assert!(
        (p - DVec3::Y).length() < 1e-12,
        "origin went to {p}, Mitsuba gives (0, 1, 0)"
    );
}

#[test]
fn rotate_zero_axis_and_missing_angle_are_errors() {
    // Mitsuba: "rotation axis cannot be zero"; "missing required attribute "angle"".
    assert!(parse_transform("rot0", r#"<rotate value="0, 0, 0" angle="30"/>"#).is_err());
    assert!(parse_transform("rotnoangle", r#"<rotate value="0, 0, 1"/>"#).is_err());
}

// ---------------------------------------------------------------------------------------
// (b) parameters, include, references, upgrade
// ---------------------------------------------------------------------------------------

const PARAM_SCENE: &str = r#"
<default name="kind" value="sphere"/>
<default name="r" value="2.5"/>
<default name="prop" value="radius"/>
<default name="cx" value="1"/>
<default name="myid" value="ball"/>
<shape type="$kind" id="$myid">
    <float name="$prop" value="$r"/>
    <point name="center" value="$cx, 2, $cx"/>
</shape>"#;

/// `$name` is substituted in any attribute: type, id, name and (part of) value.
/// Mitsuba: shape id "ball", sphere radius 2.5 at (1, 2, 1).
#[test]
fn default_and_substitution_in_any_attribute() {
    let desc = load("defaults", &format!("{SENSOR}{PARAM_SCENE}"));
    let shape = desc
        .objects
        .iter()
        .find(|o| o.kind == ObjectKind::Shape)
        .expect("a shape");
    assert_eq!(shape.plugin, "sphere", "type=\"$kind\"");
    assert_eq!(shape.id.as_deref(), Some("ball"), "id=\"$myid\"");
    assert_eq!(
        prop(&desc, ObjectKind::Shape, "radius"),
        &Value::Float(2.5),
        "name=\"$prop\" value=\"$r\""
    );
    assert_eq!(
        prop(&desc, ObjectKind::Shape, "center"),
        &Value::Point(DVec3::new(1.0, 2.0, 1.0)),
        "value=\"$cx, 2, $cx\""
    );
    let scene = build_desc("defaults", &desc);
    let (c, r, _) = sphere(&scene, 0);
    assert_eq!((c, r), (Vec3::new(1.0, 2.0, 1.0), 2.5));
}

/// `-D r=0.5` wins over `<default name="r" value="2.5"/>` (Mitsuba: radius 0.5).
#[test]
fn command_line_parameter_overrides_default() {
    let desc = load_with(
        "override",
        &format!("{SENSOR}{PARAM_SCENE}"),
        &[("r", "0.5")],
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let scene = build_desc("override", &desc);
    let (c, r, _) = sphere(&scene, 0);
    assert_eq!(r, 0.5, "-D r=0.5 must override the default 2.5");
    assert_eq!(c, Vec3::new(1.0, 2.0, 1.0), "other defaults unchanged");
}

/// The longest parameter name wins: `$rr` is `rr`, not `$r` followed by "r"
/// (Mitsuba: radius 3).
#[test]
fn substitution_takes_the_whole_parameter_name() {
    let desc = load(
        "longest_name",
        r#"<default name="r" value="2"/><default name="rr" value="3"/>
           <shape type="sphere"><float name="radius" value="$rr"/></shape>"#,
    );
    assert_eq!(prop(&desc, ObjectKind::Shape, "radius"), &Value::Float(3.0));
}

/// Mitsuba: `mi.load_string(xml, unused=1)` fails with "Found unused parameters:
/// - $unused=1", whether or not the scene has defaults.
#[test]
fn unused_command_line_parameter_is_an_error() {
    let e = load_with(
        "unused",
        &format!("{SENSOR}{PARAM_SCENE}"),
        &[("unused", "1")],
    )
    .expect_err("an unused -D parameter must be an error, as in Mitsuba");
    assert!(
        e.contains("unused"),
        "the message should name the parameter: {e}"
    );
    assert!(
        e.contains("scene.xml"),
        "the message should name the file: {e}"
    );

    let e = load_with(
        "unused_plain",
        r#"<shape type="sphere"/>"#,
        &[("unused", "1")],
    )
    .expect_err("an unused -D parameter must be an error");
    assert!(e.contains("unused"), "{e}");
}

/// Mitsuba also counts a -D whose `<default>` exists but whose `$name` is never
/// referenced as unused ("Found unused parameters: - $r=2").
#[test]
fn parameter_with_default_but_never_referenced_is_unused() {
    let e = load_with(
        "unused_default",
        r#"<default name="r" value="0.5"/><shape type="sphere"/>"#,
        &[("r", "2")],
    )
    .expect_err("Mitsuba refuses -D r=2 when $r is never used");
    assert!(e.contains("\"r\"") || e.contains("$r"), "{e}");
    // A <default> that is never used is fine without -D (Mitsuba loads it).
    load(
        "unused_default_ok",
        r#"<default name="r" value="0.5"/><shape type="sphere"/>"#,
    );
}

/// Mitsuba: "undefined parameter: $undefined".
#[test]
fn undefined_parameter_is_an_error() {
    let e = load_with(
        "undefined",
        r#"<shape type="sphere"><float name="radius" value="$undefined"/></shape>"#,
        &[],
    )
    .expect_err("$undefined must be an error");
    assert!(e.contains("undefined"), "{e}");
    assert!(
        e.contains("scene.xml:"),
        "error should carry file:line:col: {e}"
    );
}

/// tests/fixtures/parser/include_main.xml includes "include_part.xml" by a relative
/// name; it must resolve next to the scene file (the test's cwd is the crate root).
#[test]
fn include_is_relative_to_the_scene_folder() {
    let desc = load_file(&fixture("include_main.xml"), &LoadOptions::default())
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        desc.files.len(),
        2,
        "scene + included file: {:?}",
        desc.files
    );
    assert!(
        desc.files[1].ends_with("include_part.xml"),
        "{:?}",
        desc.files
    );
    let scene = build_desc("include", &desc);
    // The included bsdf is shared by <ref id="included_bsdf"/> in the main file.
    assert_eq!(scene.shapes.len(), 1);
    match &scene.bsdfs[scene.shapes[0].bsdf as usize] {
        Bsdf::Diffuse { reflectance } => assert_vec3(
            reflectance.constant().expect("a constant reflectance"),
            [0.25, 0.5, 0.75],
            1e-6,
            "included reflectance",
        ),
        other => panic!("expected the included diffuse bsdf, got {other:?}"),
    }
    // The included constant emitter.
    assert_eq!(scene.emitters.len(), 1);
    match &scene.emitters[0] {
        Emitter::Constant { radiance } => assert_vec3(*radiance, [3.0; 3], 0.0, "radiance"),
        other => panic!("expected the included constant emitter, got {other:?}"),
    }
}

/// The same, from a temp folder, with the include in a subfolder and loaded through a
/// path with a different cwd-relative prefix.
#[test]
fn include_in_subfolder_resolves_against_the_including_scene() {
    let dir = tmp_dir("include_sub");
    write(
        &dir,
        "parts/light.xml",
        r#"<scene version="3.0.0"><emitter type="point"><point name="position" value="1, 2, 3"/><float name="intensity" value="7"/></emitter></scene>"#,
    );
    let path = write(
        &dir,
        "scene.xml",
        &format!(r#"<scene version="3.0.0">{SENSOR}<include filename="parts/light.xml"/></scene>"#),
    );
    let desc = load_file(&path, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    let scene = build_desc("include_sub", &desc);
    match &scene.emitters[..] {
        [Emitter::Point {
            position,
            intensity,
        }] => {
            assert_eq!(Vec3::from(*position), Vec3::new(1.0, 2.0, 3.0));
            assert_eq!(*intensity, Vec3::splat(7.0));
        }
        other => panic!("expected one point emitter from the include, got {other:?}"),
    }
}

/// `id` + `<ref id>`: two shapes share one built bsdf.
#[test]
fn ref_shares_a_bsdf() {
    let scene = build(
        "ref_bsdf",
        r#"<bsdf type="dielectric" id="glass"><float name="int_ior" value="1.7"/></bsdf>
           <shape type="sphere"><ref id="glass"/></shape>
           <shape type="sphere"><point name="center" value="3, 0, 0"/><ref id="glass"/></shape>"#,
    );
    assert_eq!(scene.shapes.len(), 2);
    assert_eq!(
        scene.shapes[0].bsdf, scene.shapes[1].bsdf,
        "both shapes must point at the same bsdf"
    );
    let eta = dielectric_eta(&scene.bsdfs[scene.shapes[0].bsdf as usize]);
    // Mitsuba: eta = 1.7 / 1.000277 (air) = 1.69953.
    assert_close(eta as f64, 1.7 / 1.000277, 1e-6, "shared dielectric eta");
}

/// `<ref name="interior" id="...">` attaches a declared medium; two shapes referring to
/// it share one built medium.
#[test]
fn ref_with_name_attaches_a_medium() {
    let scene = build(
        "ref_medium",
        r#"<medium type="homogeneous" id="fog"><float name="sigma_t" value="0.5"/></medium>
           <shape type="sphere"><ref name="interior" id="fog"/><bsdf type="null"/></shape>
           <shape type="sphere"><point name="center" value="3, 0, 0"/><ref name="exterior" id="fog"/><bsdf type="null"/></shape>"#,
    );
    assert_eq!(scene.media.len(), 1, "one medium, shared");
    assert_eq!(scene.shapes[0].interior, Some(0), "interior of shape 0");
    assert_eq!(scene.shapes[0].exterior, None);
    assert_eq!(scene.shapes[1].exterior, Some(0), "exterior of shape 1");
    assert_vec3(scene.media[0].sigma_t, [0.5; 3], 0.0, "sigma_t");
}

#[test]
fn ref_to_unknown_id_is_an_error() {
    let e = build_err(
        "ref_unknown",
        r#"<shape type="sphere"><ref id="nope"/></shape>"#,
    );
    assert!(e.contains("nope"), "{e}");
}

/// Plugins nested in plugins: a twosided wrapping a diffuse inside a shape with an area
/// emitter; a sensor with film, rfilter and sampler; a medium with a phase function.
#[test]
fn nested_plugins() {
    let scene = build_raw(
        "nested",
        r#"<sensor type="perspective">
             <float name="fov" value="30"/>
             <sampler type="independent"><integer name="sample_count" value="9"/></sampler>
             <film type="hdrfilm">
               <integer name="width" value="6"/><integer name="height" value="3"/>
               <rfilter type="tent"><float name="radius" value="1.5"/></rfilter>
             </film>
           </sensor>
           <shape type="rectangle">
             <bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.1, 0.2, 0.3"/></bsdf></bsdf>
             <emitter type="area"><rgb name="radiance" value="4, 5, 6"/></emitter>
             <medium type="homogeneous" name="interior"><phase type="hg"><float name="g" value="-0.4"/></phase></medium>
           </shape>"#,
    );
    assert_eq!(scene.shot.spp, 9);
    assert_eq!((scene.shot.film.width, scene.shot.film.height), (6, 3));
    assert_eq!(scene.shot.film.rfilter, Rfilter::Tent { radius: 1.5 });
    let info = &scene.shapes[0];
    match &scene.bsdfs[info.bsdf as usize] {
        Bsdf::TwoSided(b) => {
            for side in b.iter() {
                match side {
                    Bsdf::Diffuse { reflectance } => assert_vec3(
                        reflectance.constant().expect("constant"),
                        [0.1, 0.2, 0.3],
                        1e-6,
                        "twosided side",
                    ),
                    other => panic!("twosided side should be diffuse, is {other:?}"),
                }
            }
        }
        other => panic!("expected twosided, got {other:?}"),
    }
    match &scene.emitters[info.emitter.expect("area emitter") as usize] {
        Emitter::Area { shape, radiance } => {
            assert_eq!(*shape, 0);
            assert_vec3(*radiance, [4.0, 5.0, 6.0], 0.0, "area radiance");
        }
        other => panic!("expected an area emitter, got {other:?}"),
    }
    let m = &scene.media[info.interior.expect("nested interior medium") as usize];
    assert_eq!(m.phase, Phase::HenyeyGreenstein { g: -0.4 });
}

/// Version 0.6.0 files: camelCase property names are upgraded (intIOR → int_ior,
/// extIOR → ext_ior, toWorld → to_world, sampleCount → sample_count, nearClip, farClip,
/// fovAxis). Mitsuba 3.9.1 loads tests/fixtures/parser/old_version.xml to: eta 1.6/1.1,
/// near_clip 0.5, sample_count 16, to_world = [[-1,0,0,0],[0,1,0,0],[0,0,-1,5]].
#[test]
fn old_version_camel_case_is_upgraded() {
    let desc = load_file(&fixture("old_version.xml"), &LoadOptions::default())
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(
        matches!(prop(&desc, ObjectKind::Bsdf, "int_ior"), Value::Float(v) if *v == 1.6),
        "intIOR → int_ior"
    );
    assert!(
        matches!(
            prop(&desc, ObjectKind::Sampler, "sample_count"),
            Value::Integer(16)
        ),
        "sampleCount → sample_count"
    );
    assert!(
        matches!(
            prop(&desc, ObjectKind::Sensor, "to_world"),
            Value::Transform(_)
        ),
        "toWorld → to_world"
    );
    let scene = build_desc("old_version", &desc);
    assert_eq!(scene.shot.spp, 16);
    assert_close(scene.shot.camera.near_clip as f64, 0.5, 1e-7, "nearClip");
    assert_close(scene.shot.camera.far_clip as f64, 200.0, 1e-7, "farClip");
    assert_close(
        dielectric_eta(&scene.bsdfs[scene.shapes[0].bsdf as usize]) as f64,
        1.6 / 1.1,
        1e-6,
        "intIOR / extIOR",
    );
    let want = glam::Mat4::from_cols_array_2d(&[
        [-1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, -1.0, 0.0],
        [0.0, 0.0, 5.0, 1.0],
    ]);
    assert!(
        scene.shot.camera.to_world.abs_diff_eq(want, 1e-6),
        "camera to_world {} vs Mitsuba {want}",
        scene.shot.camera.to_world
    );
}

/// Mitsuba 3.9.1 does NOT rename the old `<lookAt>` tag, even in a version 0.6.0 file:
/// loading tests/fixtures/parser/old_version_lookAt.xml fails with
/// `unexpected <lookAt> element inside <transform>`. mediareg deliberately loads a
/// pre-2.0 file's `<lookAt>` as its author meant (0.5/0.6 files are in scope).
#[test]
fn old_lookat_camel_case_tag_in_old_file_is_loaded_as_meant() {
    let r = load_file(&fixture("old_version_lookAt.xml"), &LoadOptions::default());
    assert!(r.is_ok(), "{:?}", r.err().map(|e| e.to_string()));
}

/// A 3.0.0 file keeps its names: camelCase is not rewritten, so `intIOR` is an
/// unreferenced property (Mitsuba: "Unreferenced property "intIOR"").
#[test]
fn new_version_does_not_upgrade_camel_case() {
    let e = build_err(
        "no_upgrade",
        r#"<shape type="sphere"><bsdf type="dielectric"><float name="intIOR" value="1.6"/></bsdf></shape>"#,
    );
    assert!(e.contains("intIOR"), "{e}");
}

// ---------------------------------------------------------------------------------------
// Property types
// ---------------------------------------------------------------------------------------

#[test]
fn every_property_type_parses() {
    let desc = load(
        "prop_types",
        r#"<bsdf type="diffuse" id="x">
             <float name="f" value="-1.5e-1"/>
             <integer name="i" value="-42"/>
             <boolean name="b1" value="true"/>
             <boolean name="b2" value="false"/>
             <string name="s" value="hello world"/>
             <point name="p" value="1, 2, 3"/>
             <point name="pxyz" x="4" z="6"/>
             <vector name="v" value="0.5 -0.5 2"/>
             <vector name="vxyz" y="-1"/>
             <rgb name="c1" value="0.25"/>
             <rgb name="c3" value="0.1, 0.2, 0.3"/>
             <spectrum name="sp" value="0.7"/>
           </bsdf>"#,
    );
    let k = ObjectKind::Bsdf;
    assert_eq!(prop(&desc, k, "f"), &Value::Float(-0.15));
    assert_eq!(prop(&desc, k, "i"), &Value::Integer(-42));
    assert_eq!(prop(&desc, k, "b1"), &Value::Boolean(true));
    assert_eq!(prop(&desc, k, "b2"), &Value::Boolean(false));
    assert_eq!(prop(&desc, k, "s"), &Value::String("hello world".into()));
    assert_eq!(
        prop(&desc, k, "p"),
        &Value::Point(DVec3::new(1.0, 2.0, 3.0))
    );
    assert_eq!(
        prop(&desc, k, "pxyz"),
        &Value::Point(DVec3::new(4.0, 0.0, 6.0)),
        "missing point components default to 0"
    );
    assert_eq!(
        prop(&desc, k, "v"),
        &Value::Vector(DVec3::new(0.5, -0.5, 2.0))
    );
    assert_eq!(
        prop(&desc, k, "vxyz"),
        &Value::Vector(DVec3::new(0.0, -1.0, 0.0))
    );
    assert_eq!(
        prop(&desc, k, "c1"),
        &Value::Rgb(DVec3::splat(0.25)),
        "a single rgb value is broadcast"
    );
    assert_eq!(prop(&desc, k, "c3"), &Value::Rgb(DVec3::new(0.1, 0.2, 0.3)));
    assert_eq!(prop(&desc, k, "sp"), &Value::Spectrum(0.7));
}

#[test]
fn malformed_property_values_are_errors() {
    for (tag, body) in [
        (
            "bad_float",
            r#"<shape type="sphere"><float name="radius" value="abc"/></shape>"#,
        ),
        (
            "bad_int",
            r#"<sensor type="perspective"><sampler type="independent"><integer name="sample_count" value="1.5"/></sampler></sensor>"#,
        ),
        (
            "bad_bool",
            r#"<shape type="sphere"><boolean name="flip_normals" value="yes"/></shape>"#,
        ),
        (
            "bad_rgb",
            r#"<bsdf type="diffuse"><rgb name="reflectance" value="0.1, 0.2"/></bsdf>"#,
        ),
    ] {
        let r = load_with(tag, body, &[]);
        assert!(r.is_err(), "{tag}: {body} should not parse");
        let e = r.unwrap_err();
        assert!(
            e.contains("scene.xml:"),
            "{tag}: error should carry file:line:col: {e}"
        );
    }
}

// ---------------------------------------------------------------------------------------
// Sensor, film, sampler
// ---------------------------------------------------------------------------------------

fn camera_scene(tag: &str, sensor_props: &str, w: u32, h: u32) -> Scene {
    build_raw(
        tag,
        &format!(
            r#"<sensor type="perspective">{sensor_props}
                 <film type="hdrfilm"><integer name="width" value="{w}"/><integer name="height" value="{h}"/></film>
               </sensor>"#
        ),
    )
}

/// tan(fov_x / 2) for `fov` along `axis`, from the definitions (film aspect a = w / h):
/// x: fov; y: tan(fx/2) = a·tan(fov/2); diagonal: tan(fx/2) = tan(fov/2)·a/√(1 + a²);
/// smaller/larger: y or x depending on a.
fn tan_half_fov_x_formula(fov: f64, axis: &str, a: f64) -> f64 {
    let t = (0.5 * fov).to_radians().tan();
    let axis = match axis {
        "smaller" => {
            if a > 1.0 {
                "y"
            } else {
                "x"
            }
        }
        "larger" => {
            if a > 1.0 {
                "x"
            } else {
                "y"
            }
        }
        other => other,
    };
    match axis {
        "x" => t,
        "y" => t * a,
        "diagonal" => t * a / (1.0 + a * a).sqrt(),
        _ => unreachable!(),
    }
}

/// fov = 40 on films 8×4 and 4×8 for each fov_axis, against the formula and against
/// Mitsuba 3.9.1's `x_fov` (mi.traverse).
#[test]
fn perspective_fov_axis() {
    // (axis, w, h, Mitsuba x_fov in degrees)
    let mitsuba = [
        ("x", 8, 4, 40.0),
        ("x", 4, 8, 40.0),
        ("y", 8, 4, 72.10477447509766),
        ("y", 4, 8, 20.628210067749023),
        ("diagonal", 8, 4, 36.064788818359375),
        ("diagonal", 4, 8, 18.49018669128418),
        ("smaller", 8, 4, 72.10477447509766),
        ("smaller", 4, 8, 40.0),
        ("larger", 8, 4, 40.0),
        ("larger", 4, 8, 20.628210067749023),
    ];
    for (axis, w, h, x_fov) in mitsuba {
        let scene = camera_scene(
            &format!("fov_{axis}_{w}x{h}"),
            &format!(r#"<float name="fov" value="40"/><string name="fov_axis" value="{axis}"/>"#),
            w,
            h,
        );
        let got = scene.shot.camera.tan_half_fov_x as f64;
        let what = format!("fov_axis={axis}, film {w}x{h}");
        let a = w as f64 / h as f64;
        assert_close(
            got,
            tan_half_fov_x_formula(40.0, axis, a),
            1e-6,
            &format!("{what} (formula)"),
        );
        assert_close(
            got,
            (0.5_f64 * x_fov).to_radians().tan(),
            1e-6,
            &format!("{what} (Mitsuba x_fov {x_fov})"),
        );
        assert_close(
            scene.shot.camera.aspect as f64,
            a,
            1e-7,
            &format!("{what}: aspect"),
        );
    }
}

/// Without fov, Mitsuba uses focal_length = 50mm on the diagonal; with the default film
/// (768×576) its x_fov is 38.18484°. Default clips: near 0.01, far 10000.
#[test]
fn perspective_defaults() {
    let scene = build_raw("cam_defaults", r#"<sensor type="perspective"/>"#);
    assert_close(
        scene.shot.camera.tan_half_fov_x as f64,
        (0.5 * 38.18484115600586f64).to_radians().tan(),
        1e-6,
        "default (50mm) horizontal fov",
    );
    assert_close(
        scene.shot.camera.near_clip as f64,
        1e-2,
        1e-6,
        "default near_clip",
    );
    assert_close(
        scene.shot.camera.far_clip as f64,
        1e4,
        1e-6,
        "default far_clip",
    );
    assert_eq!(
        (scene.shot.film.width, scene.shot.film.height),
        (768, 576),
        "default film size"
    );
    assert_eq!(
        scene.shot.film.rfilter,
        Rfilter::Gaussian { stddev: 0.5 },
        "default rfilter"
    );
    assert_eq!((scene.shot.spp, scene.shot.seed), (4, 0), "default sampler");
}

#[test]
fn perspective_near_far_clip() {
    let scene = camera_scene(
        "clips",
        r#"<float name="fov" value="50"/><float name="near_clip" value="0.25"/><float name="far_clip" value="75"/>"#,
        8,
        4,
    );
    assert_close(scene.shot.camera.near_clip as f64, 0.25, 1e-7, "near_clip");
    assert_close(scene.shot.camera.far_clip as f64, 75.0, 1e-7, "far_clip");
}

#[test]
fn hdrfilm_size_and_crop() {
    let scene = build_raw(
        "crop",
        r#"<sensor type="perspective"><float name="fov" value="40"/>
             <film type="hdrfilm">
               <integer name="width" value="64"/><integer name="height" value="48"/>
               <integer name="crop_offset_x" value="8"/><integer name="crop_offset_y" value="4"/>
               <integer name="crop_width" value="16"/><integer name="crop_height" value="20"/>
             </film></sensor>"#,
    );
    assert_eq!(
        (scene.shot.film.width, scene.shot.film.height),
        (64, 48),
        "film size"
    );
    assert_eq!(scene.shot.film.crop_offset, (8, 4), "crop offset");
    assert_eq!(scene.shot.film.crop_size, (16, 20), "crop size");
    // Without crop, the crop window is the whole film.
    let scene = camera_scene("nocrop", r#"<float name="fov" value="40"/>"#, 10, 7);
    assert_eq!(scene.shot.film.crop_offset, (0, 0));
    assert_eq!(scene.shot.film.crop_size, (10, 7));
}

#[test]
fn crop_window_outside_the_film_is_an_error() {
    let r = load_with(
        "badcrop",
        r#"<sensor type="perspective"><film type="hdrfilm">
             <integer name="width" value="8"/><integer name="height" value="8"/>
             <integer name="crop_offset_x" value="4"/><integer name="crop_width" value="8"/>
           </film></sensor>"#,
        &[],
    )
    .map(|d| build_scene(&d, &BuildOverrides::default()).map(|_| ()));
    assert!(
        matches!(r, Ok(Err(_)) | Err(_)),
        "a crop window past the film's right edge must be refused"
    );
}

fn rfilter_of(tag: &str, rfilter: &str) -> Rfilter {
    build_raw(
        tag,
        &format!(
            r#"<sensor type="perspective"><float name="fov" value="40"/>
                 <film type="hdrfilm"><integer name="width" value="4"/><integer name="height" value="4"/>{rfilter}</film></sensor>"#
        ),
    )
    .shot
    .film
    .rfilter
}

/// Mitsuba defaults: tent radius 1, gaussian stddev 0.5 (radius 2), and a gaussian when
/// the film has no rfilter ("GaussianFilter[stddev=0.50, radius=2.00]").
#[test]
fn rfilters_and_their_defaults() {
    assert_eq!(rfilter_of("rf_none", ""), Rfilter::Gaussian { stddev: 0.5 });
    assert_eq!(
        rfilter_of("rf_box", r#"<rfilter type="box"/>"#),
        Rfilter::Box
    );
    assert_eq!(
        rfilter_of("rf_tent", r#"<rfilter type="tent"/>"#),
        Rfilter::Tent { radius: 1.0 }
    );
    assert_eq!(
        rfilter_of(
            "rf_tent2",
            r#"<rfilter type="tent"><float name="radius" value="2.5"/></rfilter>"#
        ),
        Rfilter::Tent { radius: 2.5 }
    );
    assert_eq!(
        rfilter_of("rf_gauss", r#"<rfilter type="gaussian"/>"#),
        Rfilter::Gaussian { stddev: 0.5 }
    );
    let g = rfilter_of(
        "rf_gauss2",
        r#"<rfilter type="gaussian"><float name="stddev" value="0.25"/></rfilter>"#,
    );
    assert_eq!(g, Rfilter::Gaussian { stddev: 0.25 });
    assert_eq!(g.radius(), 1.0, "gaussian radius is 4 stddev");
}

#[test]
fn independent_sampler_count_and_seed() {
    let scene = build_raw(
        "sampler",
        r#"<sensor type="perspective"><float name="fov" value="40"/>
             <sampler type="independent"><integer name="sample_count" value="37"/><integer name="seed" value="12345"/></sampler>
           </sensor>"#,
    );
    assert_eq!(scene.shot.spp, 37, "sample_count");
    assert_eq!(scene.shot.seed, 12345, "seed");
}

// ---------------------------------------------------------------------------------------
// Shapes
// ---------------------------------------------------------------------------------------

/// Mitsuba: sphere(center (1,2,3), r 0.5) has bbox [0.5,1.5]×[1.5,2.5]×[2.5,3.5];
/// sphere(center (1,0,0), r 2) with to_world = translate(1,0,0)·scale(3) has bbox
/// [-2,10]×[-6,6]×[-6,6], i.e. center (4,0,0), radius 6.
#[test]
fn sphere_center_and_radius() {
    let scene = build(
        "spheres",
        r#"<shape type="sphere"><point name="center" x="1" y="2" z="3"/><float name="radius" value="0.5"/></shape>
           <shape type="sphere"><point name="center" value="1, 0, 0"/><float name="radius" value="2"/>
             <transform name="to_world"><scale value="3"/><translate x="1"/></transform></shape>
           <shape type="sphere"/>"#,
    );
    let (c, r, flip) = sphere(&scene, 0);
    assert_eq!(
        (c, r, flip),
        (Vec3::new(1.0, 2.0, 3.0), 0.5, false),
        "plain sphere"
    );
    let (c, r, _) = sphere(&scene, 1);
    assert!(
        (c - Vec3::new(4.0, 0.0, 0.0)).length() < 1e-6,
        "transformed center {c}"
    );
    assert!((r - 6.0).abs() < 1e-6, "transformed radius {r}");
    let (c, r, _) = sphere(&scene, 2);
    assert_eq!(
        (c, r),
        (Vec3::ZERO, 1.0),
        "default sphere: unit, at the origin"
    );
}

/// Mitsuba surface_area(): rectangle scaled (2,3) → 24; disk scaled 2 → 4π;
/// cube scaled 0.5 → 6.
#[test]
fn rectangle_disk_and_cube_areas() {
    let scene = build(
        "areas",
        r#"<shape type="rectangle"><transform name="to_world"><scale x="2" y="3"/></transform></shape>
           <shape type="disk"><transform name="to_world"><scale value="2"/></transform></shape>
           <shape type="cube"><transform name="to_world"><scale value="0.5"/></transform></shape>
           <shape type="rectangle"/>
           <shape type="disk"/>"#,
    );
    assert_close(
        planar_area(&scene, 0) as f64,
        24.0,
        1e-6,
        "scaled rectangle area",
    );
    assert_close(
        planar_area(&scene, 1) as f64,
        4.0 * std::f64::consts::PI,
        1e-6,
        "scaled disk area",
    );
    match &scene.geometries[2] {
        Geometry::Mesh(m) => {
            assert_eq!(m.triangles.len(), 12, "cube triangles");
            assert_close(m.total_area as f64, 6.0, 1e-6, "scaled cube area");
            let (lo, hi) = m.positions.iter().fold(
                (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
                |(lo, hi), p| (lo.min(Vec3::from(*p)), hi.max(Vec3::from(*p))),
            );
            assert_eq!(
                (lo, hi),
                (Vec3::splat(-0.5), Vec3::splat(0.5)),
                "cube bounds"
            );
        }
        other => panic!("cube should be a mesh, is {other:?}"),
    }
    assert_close(
        planar_area(&scene, 3) as f64,
        4.0,
        1e-6,
        "unit rectangle [-1,1]²",
    );
    assert_close(
        planar_area(&scene, 4) as f64,
        std::f64::consts::PI,
        1e-6,
        "unit disk",
    );
}

/// flip_normals: a rectangle's normal is +z, flipped −z; spheres and meshes keep the
/// flag for shading.
#[test]
fn flip_normals() {
    let scene = build(
        "flip",
        r#"<shape type="rectangle"/>
           <shape type="rectangle"><boolean name="flip_normals" value="true"/></shape>
           <shape type="sphere"><boolean name="flip_normals" value="true"/></shape>
           <shape type="cube"><boolean name="flip_normals" value="true"/></shape>"#,
    );
    let normal = |i: usize| match &scene.geometries[i] {
        Geometry::Planar(p) => Vec3::from(p.normal),
        other => panic!("{other:?}"),
    };
    assert_eq!(normal(0), Vec3::Z, "rectangle normal");
    assert_eq!(normal(1), -Vec3::Z, "flipped rectangle normal");
    assert!(sphere(&scene, 2).2, "sphere flip_normals flag");
    match &scene.geometries[3] {
        Geometry::Mesh(m) => assert!(m.flip_normals, "cube flip_normals flag"),
        other => panic!("{other:?}"),
    }
}

// ---------------------------------------------------------------------------------------
// BSDFs
// ---------------------------------------------------------------------------------------

/// Mitsuba `eta` (mi.traverse): default bk7/air 1.504183; water/air 1.3326308;
/// 1.7/1.2 = 1.4166666; diamond/water 1.8147037.
#[test]
fn dielectric_iors_numbers_and_names() {
    let scene = build(
        "iors",
        r#"<shape type="sphere"><bsdf type="dielectric"/></shape>
           <shape type="sphere"><bsdf type="dielectric"><string name="int_ior" value="water"/></bsdf></shape>
           <shape type="sphere"><bsdf type="dielectric"><float name="int_ior" value="1.7"/><float name="ext_ior" value="1.2"/></bsdf></shape>
           <shape type="sphere"><bsdf type="dielectric"><string name="int_ior" value="diamond"/><string name="ext_ior" value="water"/></bsdf></shape>
           <shape type="sphere"><bsdf type="dielectric"><string name="int_ior" value="bk7"/><string name="ext_ior" value="air"/></bsdf></shape>"#,
    );
    let eta = |i: usize| dielectric_eta(&scene.bsdfs[scene.shapes[i].bsdf as usize]) as f64;
    assert_close(
        eta(0),
        1.504183292388916,
        1e-6,
        "default int_ior bk7 / ext_ior air",
    );
    assert_close(
        eta(0),
        1.5046 / 1.000277,
        1e-6,
        "bk7 = 1.5046, air = 1.000277",
    );
    assert_close(eta(1), 1.3326307535171509, 1e-6, "water / air");
    assert_close(eta(1), 1.333 / 1.000277, 1e-6, "water = 1.333");
    assert_close(eta(2), 1.4166666269302368, 1e-6, "1.7 / 1.2");
    assert_close(eta(3), 1.8147037029266357, 1e-6, "diamond / water");
    assert_close(eta(4), eta(0), 1e-7, "explicit bk7/air equals the default");
}

#[test]
fn unknown_named_ior_is_an_error() {
    let e = build_err(
        "bad_ior",
        r#"<shape type="sphere"><bsdf type="dielectric"><string name="int_ior" value="unobtainium"/></bsdf></shape>"#,
    );
    assert!(e.contains("unobtainium"), "{e}");
}

/// `twosided` with one nested bsdf uses it on both sides; with two, front then back.
#[test]
fn twosided_one_and_two_nested() {
    let scene = build(
        "twosided",
        r#"<shape type="rectangle"><bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.1, 0.2, 0.3"/></bsdf></bsdf></shape>
           <shape type="rectangle"><bsdf type="twosided">
             <bsdf type="diffuse"><float name="reflectance" value="0.9"/></bsdf>
             <bsdf type="diffuse"><float name="reflectance" value="0.1"/></bsdf>
           </bsdf></shape>"#,
    );
    let sides = |i: usize| -> [Vec3; 2] {
        match &scene.bsdfs[scene.shapes[i].bsdf as usize] {
            Bsdf::TwoSided(b) => [0, 1].map(|k| match &b[k] {
                Bsdf::Diffuse { reflectance } => reflectance.constant().expect("constant"),
                other => panic!("side {k}: {other:?}"),
            }),
            other => panic!("expected twosided, got {other:?}"),
        }
    };
    let [f, b] = sides(0);
    assert_vec3(f, [0.1, 0.2, 0.3], 1e-6, "front (one nested)");
    assert_eq!(f, b, "one nested bsdf serves both sides");
    let [f, b] = sides(1);
    assert_vec3(f, [0.9; 3], 1e-6, "front (two nested)");
    assert_vec3(b, [0.1; 3], 1e-6, "back (two nested)");
}

// ---------------------------------------------------------------------------------------
// Emitters
// ---------------------------------------------------------------------------------------

/// Mitsuba 3.9.1, scalar_rgb: `<spectrum value="2"/>` as point intensity, constant and
/// area radiance and directional irradiance all become (2.40959, 1.89658, 1.81783), i.e.
/// 2 × (1.204794, 0.948291, 0.908916); `<float value="2"/>` and `<rgb value="2"/>` stay
/// (2, 2, 2); `<rgb value="1,2,3"/>` stays (1, 2, 3).
const MITSUBA_UNIFORM_SPECTRUM_RGB: [f32; 3] = [1.204794, 0.948291, 0.908916];

fn emitter_values(tag: &str, value_xml: &str) -> [Vec3; 4] {
    let v = |name: &str| value_xml.replace("NAME", name);
    let scene = build(
        tag,
        &format!(
            r#"<emitter type="point">{}<point name="position" value="0, 5, 0"/></emitter>
               <emitter type="constant">{}</emitter>
               <emitter type="directional">{}<vector name="direction" value="0, -1, 0"/></emitter>
               <shape type="rectangle"><emitter type="area">{}</emitter></shape>"#,
            v("intensity"),
            v("radiance"),
            v("irradiance"),
            v("radiance")
        ),
    );
    let mut out = [Vec3::ZERO; 4];
    for e in &scene.emitters {
        match e {
            Emitter::Point { intensity, .. } => out[0] = *intensity,
            Emitter::Constant { radiance } => out[1] = *radiance,
            Emitter::Directional { irradiance, .. } => out[2] = *irradiance,
            Emitter::Area { radiance, .. } => out[3] = *radiance,
            Emitter::EnvMap(_) | Emitter::Spot(_) => panic!("{tag}: only the four above"),
        }
    }
    assert_eq!(scene.emitters.len(), 4, "{tag}: four emitters");
    out
}

const EMITTERS: [&str; 4] = [
    "point intensity",
    "constant radiance",
    "directional irradiance",
    "area radiance",
];

#[test]
fn uniform_spectrum_rgb_constant_matches_mitsuba() {
    let c = UNIFORM_SPECTRUM_RGB.to_array();
    for i in 0..3 {
        assert!(
            (c[i] - MITSUBA_UNIFORM_SPECTRUM_RGB[i]).abs() < 2e-6,
            "UNIFORM_SPECTRUM_RGB = {c:?}, Mitsuba's uniform spectrum in sRGB is {MITSUBA_UNIFORM_SPECTRUM_RGB:?}"
        );
    }
}

#[test]
fn emitter_constant_spectrum_becomes_mitsuba_rgb() {
    let got = emitter_values("em_spectrum", r#"<spectrum name="NAME" value="2"/>"#);
    let want = MITSUBA_UNIFORM_SPECTRUM_RGB.map(|x| 2.0 * x);
    for (g, what) in got.iter().zip(EMITTERS) {
        // Mitsuba prints (2.40959, 1.89658, 1.81783).
        assert_vec3(*g, want, 2e-6, &format!("{what} <spectrum value=\"2\"/>"));
    }
}

#[test]
fn emitter_float_and_rgb_stay_as_given() {
    for (tag, xml, want) in [
        ("em_float", r#"<float name="NAME" value="2"/>"#, [2.0f32; 3]),
        ("em_rgb1", r#"<rgb name="NAME" value="2"/>"#, [2.0; 3]),
        (
            "em_rgb3",
            r#"<rgb name="NAME" value="1, 2, 3"/>"#,
            [1.0, 2.0, 3.0],
        ),
    ] {
        let got = emitter_values(tag, xml);
        for (g, what) in got.iter().zip(EMITTERS) {
            assert_vec3(*g, want, 0.0, &format!("{what} {xml}"));
        }
    }
}

#[test]
fn emitter_positions_and_directions() {
    let scene = build(
        "em_geom",
        r#"<emitter type="point"><point name="position" value="1, 2, 3"/></emitter>
           <emitter type="point"><transform name="to_world"><translate value="-1, 0, 4"/></transform></emitter>
           <emitter type="directional"><vector name="direction" value="0, 0, -2"/></emitter>
           <emitter type="directional"><transform name="to_world"><lookat origin="0, 0, 0" target="1, 0, 0" up="0, 1, 0"/></transform></emitter>"#,
    );
    let mut points = Vec::new();
    let mut dirs = Vec::new();
    for e in &scene.emitters {
        match e {
            Emitter::Point {
                position,
                intensity,
            } => {
                assert_eq!(*intensity, Vec3::ONE, "default intensity 1");
                points.push(Vec3::from(*position))
            }
            Emitter::Directional {
                direction,
                irradiance,
            } => {
                assert_eq!(*irradiance, Vec3::ONE, "default irradiance 1");
                dirs.push(Vec3::from(*direction))
            }
            other => panic!("{other:?}"),
        }
    }
    assert_eq!(
        points,
        [Vec3::new(1.0, 2.0, 3.0), Vec3::new(-1.0, 0.0, 4.0)]
    );
    assert!(
        (dirs[0] - Vec3::NEG_Z).length() < 1e-6,
        "direction is normalised: {}",
        dirs[0]
    );
    assert!(
        (dirs[1] - Vec3::X).length() < 1e-6,
        "to_world maps +z to the light direction: {}",
        dirs[1]
    );
}

// ---------------------------------------------------------------------------------------
// Media
// ---------------------------------------------------------------------------------------

fn media_of(tag: &str, medium: &str) -> Scene {
    // build_scene directly: load_scene refuses media (not renderable yet).
    build(
        tag,
        &format!(r#"<shape type="sphere"><bsdf type="null"/>{medium}</shape>"#),
    )
}

/// Mitsuba (traverse): albedo (0.2, 0.4, 0.6), sigma_t 2, scale 0.5, hg g 0.3.
/// sigma_t is stored pre-multiplied by scale: 1.0.
#[test]
fn homogeneous_medium_values_and_hg() {
    let scene = media_of(
        "medium_hg",
        r#"<medium type="homogeneous" name="interior">
             <rgb name="albedo" value="0.2, 0.4, 0.6"/>
             <float name="sigma_t" value="2"/>
             <float name="scale" value="0.5"/>
             <phase type="hg"><float name="g" value="0.3"/></phase>
           </medium>"#,
    );
    let m = &scene.media[scene.shapes[0].interior.expect("interior") as usize];
    assert_vec3(m.albedo, [0.2, 0.4, 0.6], 1e-6, "albedo");
    assert_vec3(m.sigma_t, [1.0; 3], 1e-6, "sigma_t × scale");
    assert_eq!(m.phase, Phase::HenyeyGreenstein { g: 0.3 });
}

/// Mitsuba: rgb sigma_t within [0,1] is taken as given (0.5, 0.7, 0.9), times scale.
#[test]
fn homogeneous_medium_rgb_sigma_t_times_scale() {
    let scene = media_of(
        "medium_rgb",
        r#"<medium type="homogeneous" name="interior">
             <rgb name="sigma_t" value="0.5, 0.7, 0.9"/>
             <float name="scale" value="4"/>
             <phase type="isotropic"/>
           </medium>"#,
    );
    let m = &scene.media[0];
    assert_vec3(m.sigma_t, [2.0, 2.8, 3.6], 1e-6, "rgb sigma_t × scale 4");
    assert_vec3(m.albedo, [0.75; 3], 1e-6, "default albedo 0.75");
    assert_eq!(m.phase, Phase::Isotropic);
}

/// Mitsuba: a constant `<spectrum>` in a medium stays uniform (sigma_t value 2.0, albedo
/// 0.5): the sRGB conversion of uniform spectra applies only to emitters.
#[test]
fn homogeneous_medium_spectrum_stays_uniform() {
    let scene = media_of(
        "medium_spectrum",
        r#"<medium type="homogeneous" name="interior">
             <spectrum name="albedo" value="0.5"/>
             <spectrum name="sigma_t" value="2"/>
           </medium>"#,
    );
    let m = &scene.media[0];
    assert_vec3(m.albedo, [0.5; 3], 1e-6, "spectrum albedo");
    assert_vec3(m.sigma_t, [2.0; 3], 1e-6, "spectrum sigma_t");
}

/// Mitsuba defaults: albedo 0.75, sigma_t 1, scale 1, isotropic phase; hg default g 0.8.
#[test]
fn homogeneous_medium_defaults() {
    let scene = media_of(
        "medium_defaults",
        r#"<medium type="homogeneous" name="interior"/>"#,
    );
    let m = &scene.media[0];
    assert_vec3(m.albedo, [0.75; 3], 1e-6, "default albedo");
    assert_vec3(m.sigma_t, [1.0; 3], 1e-6, "default sigma_t");
    assert_eq!(m.phase, Phase::Isotropic, "default phase");
    assert!(m.sample_emitters, "default sample_emitters");

    let scene = media_of(
        "medium_hg_default",
        r#"<medium type="homogeneous" name="interior"><phase type="hg"/></medium>"#,
    );
    assert_eq!(
        scene.media[0].phase,
        Phase::HenyeyGreenstein { g: 0.8 },
        "hg default g"
    );
}

/// Mitsuba 3.9.1 (scalar_rgb) treats an `<rgb>` sigma_t as a reflectance and refuses
/// components above 1: `<rgb name="sigma_t" value="1, 2, 3"/>` fails with
/// "[SRGBReflectanceSpectrum] Invalid RGB reflectance value [1, 2, 3], must be in the
/// range [0, 1]!" (also for value="2"). A float or spectrum sigma_t > 1 is fine.
#[test]
fn homogeneous_medium_rgb_sigma_t_above_one_is_refused_like_mitsuba() {
    let e = build_err(
        "medium_rgb_gt1",
        r#"<shape type="sphere"><bsdf type="null"/>
             <medium type="homogeneous" name="interior"><rgb name="sigma_t" value="1, 2, 3"/></medium>
           </shape>"#,
    );
    assert!(e.contains("sigma_t"), "{e}");
}

#[test]
fn medium_errors() {
    for (tag, medium, needle) in [
        (
            "albedo_gt1",
            r#"<rgb name="albedo" value="1.5"/>"#,
            "albedo",
        ),
        (
            "bad_g",
            r#"<phase type="hg"><float name="g" value="1"/></phase>"#,
            "g",
        ),
        (
            "bad_plugin_prop",
            r#"<float name="density" value="1"/>"#,
            "density",
        ),
    ] {
        let e = build_err(
            tag,
            &format!(
                r#"<shape type="sphere"><bsdf type="null"/><medium type="homogeneous" name="interior">{medium}</medium></shape>"#
            ),
        );
        assert!(e.contains(needle), "{tag}: {e}");
    }
}

/// A sensor takes its medium under any name (Mitsuba's Endpoint looks for any nested
/// medium), and refuses a second one.
#[test]
fn sensor_medium_any_name_at_most_one() {
    let body = |media: &str| {
        format!(
            r#"<sensor type="perspective"><float name="fov" value="40"/>{media}
                <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="4"/></film></sensor>"#
        )
    };
    let s = build_raw(
        "sensor_medium",
        &body(
            r#"<medium type="homogeneous" name="fog"><float name="sigma_t" value="0.5"/></medium>"#,
        ),
    );
    let m = s.camera_medium.expect("the sensor's medium");
    assert_eq!(s.media[m as usize].sigma_t, Vec3::splat(0.5));
    let desc = load(
        "sensor_two_media",
        &body(r#"<medium type="homogeneous"/><medium type="homogeneous"/>"#),
    );
    assert!(build_scene(&desc, &BuildOverrides::default()).is_err());
}
