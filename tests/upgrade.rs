//! Files older than 2.0 (Mitsuba 0.5/0.6): Mitsuba 3's own upgrades, the 0.6 readings
//! mediareg adds (one line of output each), and `--strict-v3`, which refuses them.

mod common;

use std::process::Command;

use common::scene_text::{load_text, tmp_dir, write, SENSOR};
use common::{options, root};
use mediareg::xml::description::{ObjectKind, Value};
use mediareg::BuildOverrides;

/// The 0.6 form of chromatic_sphere.xml (sigmaS/sigmaA, a boundary without a bsdf,
/// camelCase names, lookAt, diffuseReflectance) renders bit for bit the same image.
#[test]
fn v06_scene_renders_as_its_mitsuba3_form() {
    let render = |name: &str| {
        let s = mediareg::load_scene(
            &root().join(format!("mitsuba_scenes/{name}.xml")),
            &options(&[]),
            &BuildOverrides {
                spp: Some(8),
                seed: Some(4),
                ..Default::default()
            },
        )
        .unwrap_or_else(|e| panic!("{name}: {e}"));
        let notes = s.warnings.iter().filter(|w| w.contains("0.6 file")).count();
        (
            mediareg::integrator::render(&s, &s.shot, &Default::default())
                .image
                .pixels,
            notes,
        )
    };
    let (old, notes) = render("v06_chromatic_sphere");
    let (new, _) = render("chromatic_sphere");
    assert_eq!(
        notes, 2,
        "one line per 0.6 reading (the medium, the boundary)"
    );
    assert!(
        old.iter()
            .zip(&new)
            .all(|(a, b)| a.map(f32::to_bits) == b.map(f32::to_bits)),
        "the 0.6 file renders another image"
    );
}

/// Through the command line: a line per 0.6 reading on stderr, and `--strict-v3`
/// refuses the first one with the file and line.
#[test]
fn strict_v3_refuses_the_06_readings() {
    let scene = root().join("mitsuba_scenes/v06_chromatic_sphere.xml");
    let out = tmp_dir("upgrade", "cli").join("out.exr");
    let run = |strict: bool| {
        let mut c = Command::new(env!("CARGO_BIN_EXE_mediareg"));
        c.arg("render")
            .arg(&scene)
            .args(["--spp", "1", "--no-png", "-o"])
            .arg(&out);
        if strict {
            c.arg("--strict-v3");
        }
        c.output().expect("run mediareg")
    };
    let ok = run(false);
    let stderr = String::from_utf8_lossy(&ok.stderr);
    assert!(ok.status.success(), "{stderr}");
    assert_eq!(stderr.matches("0.6 file").count(), 2, "{stderr}");
    assert!(stderr.contains("v06_chromatic_sphere.xml:29:"), "{stderr}");
    std::fs::remove_file(&out).unwrap();
    let strict = run(true);
    let stderr = String::from_utf8_lossy(&strict.stderr);
    assert!(!strict.status.success() && !out.exists());
    assert!(
        stderr.contains("v06_chromatic_sphere.xml:29:")
            && stderr.contains("--strict-v3")
            && stderr.contains("sigmaS"),
        "{stderr}"
    );
}

fn v06(body: &str) -> String {
    format!(r#"<scene version="0.6.0">{SENSOR}{body}</scene>"#)
}

/// Mitsuba 3's own: uoffset/voffset/uscale/vscale become to_uv = scale · translate;
/// 0.5's density becomes scale.
#[test]
fn uv_offsets_and_density() {
    let d = load_text(
        "upgrade",
        "uv",
        &v06(r#"<texture type="checkerboard" id="t"><float name="uoffset" value="0.5"/><float name="vscale" value="4"/></texture>
            <medium type="homogeneous" id="m"><float name="density" value="3"/></medium>"#),
        &[],
    )
    .unwrap();
    let Value::Transform(m) = common::scene_text::prop(&d, ObjectKind::Texture, "to_uv") else {
        panic!("to_uv is not a transform")
    };
    let p = m.transform_point3(glam::DVec3::new(1.0, 1.0, 0.0));
    assert!(
        (p - glam::DVec3::new(1.5, 4.0, 0.0)).length() < 1e-12,
        "{p}"
    );
    assert_eq!(
        common::scene_text::prop(&d, ObjectKind::Medium, "scale"),
        &Value::Float(3.0)
    );
    assert_eq!(d.notes.len(), 1, "{:?}", d.notes);
}

/// What cannot be read: an unknown 0.6 material preset (the known ones:
/// tests/drop_in_plugins.rs), sigmaS without sigmaA, both forms.
#[test]
fn unreadable_06_media_are_refused_clearly() {
    for (tag, body, needle) in [
        (
            "preset",
            r#"<medium type="homogeneous"><string name="material" value="Gravy"/></medium>"#,
            "unknown Mitsuba 0.6 medium material",
        ),
        (
            "half",
            r#"<medium type="homogeneous"><float name="sigmaS" value="1"/></medium>"#,
            "needs both sigmaS and sigmaA",
        ),
        (
            "both",
            r#"<medium type="homogeneous"><float name="sigmaS" value="1"/><float name="sigmaA" value="1"/><float name="sigmaT" value="2"/></medium>"#,
            "not both",
        ),
    ] {
        let e = load_text("upgrade", tag, &v06(body), &[]).unwrap_err();
        assert!(e.contains(needle) && e.contains("scene.xml:"), "{tag}: {e}");
    }
}

/// A grey medium stays a float; a 3.0 file is never touched by the 0.6 readings.
#[test]
fn grey_media_and_new_files() {
    let body = r#"<medium type="homogeneous" id="m"><float name="sigmaS" value="3"/><float name="sigmaA" value="1"/></medium>"#;
    let d = load_text("upgrade", "grey", &v06(body), &[]).unwrap();
    assert_eq!(
        common::scene_text::prop(&d, ObjectKind::Medium, "sigma_t"),
        &Value::Float(4.0)
    );
    assert_eq!(
        common::scene_text::prop(&d, ObjectKind::Medium, "albedo"),
        &Value::Float(0.75)
    );
    let dir = tmp_dir("upgrade", "v3");
    let path = write(
        &dir,
        "scene.xml",
        &format!(
            r#"<scene version="3.0.0">{SENSOR}{}</scene>"#,
            body.replace("sigmaS", "sigma_s")
                .replace("sigmaA", "sigma_a")
        ),
    );
    let d = mediareg::xml::load_file(&path, &options(&[])).unwrap();
    assert!(d.notes.is_empty());
    let e = common::scene_text::load_or_build_error("v3", Ok(d));
    assert!(
        e.contains("sigma_s"),
        "Mitsuba 3 refuses sigma_s in a 3.0 file: {e}"
    );
}
