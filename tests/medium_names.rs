//! `--medium` names a medium as Mitsuba 3 does: by XML id, by slot (`interior`,
//! `exterior`) where that is unambiguous, or by its `mi.traverse` key
//! (`<shape id>.interior_medium`); errors list the media by those names. The keys
//! follow what Mitsuba 3.9's `mi.traverse` printed for the same files: a medium nested
//! in shape `cube` is `cube.interior_medium` (with or without an id of its own), one
//! declared at the top level is keyed by its id.

use std::path::PathBuf;

use mediareg::scene::{MediumChoiceError, Scene};
use mediareg::xml::LoadOptions;
use mediareg::{load_scene, BuildOverrides};

const HEAD: &str = r#"<scene version="3.0.0"><integrator type="volpath"/>
<sensor type="perspective"><float name="fov" value="40"/>
<transform name="to_world"><lookat origin="0,0,6" target="0,0,0" up="0,1,0"/></transform>
<film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/></film></sensor>
<emitter type="constant"/>"#;

fn write(tag: &str, body: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "mediareg_medium_names_{}_{tag}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("scene.xml");
    std::fs::write(&path, format!("{HEAD}\n{body}\n</scene>\n")).unwrap();
    path
}

fn scene(tag: &str, body: &str) -> Scene {
    load_scene(
        &write(tag, body),
        &LoadOptions::default(),
        &BuildOverrides::default(),
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

fn medium(sigma_t: f32) -> String {
    format!(r#"<float name="sigma_t" value="{sigma_t}"/><rgb name="albedo" value="0.5"/>"#)
}

/// The medium a shape's slot holds, for comparing with what a name resolves to.
fn interior(s: &Scene, shape: usize) -> u32 {
    s.shapes[shape].interior.unwrap()
}

#[test]
fn slot_and_traverse_key_name_a_nested_medium() {
    let s = scene(
        "nested",
        &format!(
            r#"<shape type="cube" id="cube"><bsdf type="null"/><medium type="homogeneous" name="interior">{}</medium></shape>"#,
            medium(1.0)
        ),
    );
    let m = interior(&s, 0);
    assert_eq!(s.medium_index(Some("interior")), Ok(m));
    assert_eq!(s.medium_index(Some("cube.interior_medium")), Ok(m));
    assert_eq!(s.medium_index(None), Ok(m));
    for wrong in [
        "exterior",
        "cube.exterior_medium",
        "sphere.interior_medium",
        "cube",
    ] {
        match s.medium_index(Some(wrong)) {
            Err(MediumChoiceError::NoSuch { media, .. }) => {
                assert_eq!(media, vec!["cube.interior_medium".to_string()], "{wrong}")
            }
            other => panic!("{wrong}: {other:?}"),
        }
    }
}

#[test]
fn a_top_level_medium_is_named_by_id_and_by_the_slot_that_holds_it() {
    let s = scene(
        "top_level",
        &format!(
            r#"<medium type="homogeneous" id="smoke">{}</medium>
<medium type="homogeneous" id="fog">{}</medium>
<shape type="cube" id="cube"><bsdf type="null"/><ref name="interior" id="smoke"/><ref name="exterior" id="fog"/></shape>
<shape type="sphere" id="ball"><point name="center" x="3" y="0" z="0"/><bsdf type="null"/><ref name="interior" id="smoke"/><ref name="exterior" id="fog"/></shape>"#,
            medium(1.0),
            medium(0.1)
        ),
    );
    let (smoke, fog) = (interior(&s, 0), s.shapes[0].exterior.unwrap());
    assert_ne!(smoke, fog);
    assert_eq!(s.medium_index(Some("smoke")), Ok(smoke));
    assert_eq!(s.medium_index(Some("fog")), Ok(fog));
    // Two shapes share each slot's medium: the slot is still one medium.
    assert_eq!(s.medium_index(Some("interior")), Ok(smoke));
    assert_eq!(s.medium_index(Some("exterior")), Ok(fog));
    assert_eq!(s.medium_index(Some("ball.interior_medium")), Ok(smoke));
    assert_eq!(s.medium_index(Some("cube.exterior_medium")), Ok(fog));
    match s.medium_index(None) {
        Err(MediumChoiceError::Several { media }) => {
            assert_eq!(media, vec!["smoke".to_string(), "fog".to_string()])
        }
        other => panic!("{other:?}"),
    }
}

/// Two shapes with media in their interior slot: a cube with the id `box`, a sphere
/// without an id.
fn box_and_unnamed_sphere() -> String {
    format!(
        r#"<shape type="cube" id="box"><bsdf type="null"/><medium type="homogeneous" name="interior">{}</medium></shape>
<shape type="sphere"><point name="center" x="3" y="0" z="0"/><bsdf type="null"/><medium type="homogeneous" name="interior">{}</medium></shape>"#,
        medium(1.0),
        medium(2.0)
    )
}

#[test]
fn a_slot_with_several_media_is_ambiguous_and_lists_them() {
    let s = scene("ambiguous", &box_and_unnamed_sphere());
    assert_eq!(
        s.medium_index(Some("box.interior_medium")),
        Ok(interior(&s, 0))
    );
    match s.medium_index(Some("interior")) {
        Err(MediumChoiceError::Ambiguous { candidates, .. }) => {
            assert_eq!(candidates.len(), 2, "{candidates:?}");
            assert_eq!(candidates[0], "box.interior_medium");
            // A shape without an id has no key a user can type: its line is given.
            assert!(
                candidates[1].starts_with("interior of shape \"sphere\" at ")
                    && candidates[1].contains("scene.xml:"),
                "{}",
                candidates[1]
            );
        }
        other => panic!("{other:?}"),
    }
}

/// The command line takes the same names, and words the error with its flag.
#[test]
fn render_takes_mitsuba_names_for_its_medium() {
    let path = write("cli", &box_and_unnamed_sphere());
    let run = |name: &str| {
        let out = path.with_file_name(format!("out_{}.exr", name.replace('.', "_")));
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_mediareg"))
            .arg("render")
            .arg(&path)
            .args([
                "--gradient",
                "albedo",
                "--medium",
                name,
                "--spp",
                "1",
                "--no-png",
                "-o",
            ])
            .arg(&out)
            .output()
            .expect("run mediareg");
        (
            o.status.success(),
            out.exists(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let (ok, written, err) = run("box.interior_medium");
    assert!(ok && written, "{err}");
    let (ok, written, err) = run("interior");
    assert!(!ok && !written, "an ambiguous slot must be refused");
    assert!(
        err.contains("--medium interior")
            && err.contains("box.interior_medium")
            && err.contains("interior of shape \"sphere\""),
        "{err}"
    );
}
