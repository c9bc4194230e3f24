//! Scenes written as text in a test: a fresh folder per test, the file, loading it, and
//! reading what the loader made of it.

use std::path::{Path, PathBuf};

use mediareg::load::build_scene;
use mediareg::scene::Scene;
use mediareg::xml::description::{ObjectKind, SceneDescription, Value};
use mediareg::xml::load_file;
use mediareg::BuildOverrides;

/// A small sensor, for scenes whose sensor is not under test (build needs one).
pub const SENSOR: &str = r#"<sensor type="perspective"><float name="fov" value="40"/>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="4"/></film></sensor>"#;

/// A fresh, empty folder for one test's files: `$TMP/mediareg_{suite}_{pid}/{tag}`.
pub fn tmp_dir(suite: &str, tag: &str) -> PathBuf {
    let d = std::env::temp_dir()
        .join(format!("mediareg_{suite}_{}", std::process::id()))
        .join(tag);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Writes `text` to `dir/name` (creating folders on the way).
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    if let Some(parent) = p.parent() {
        std::fs::create_dir_all(parent).unwrap();
    }
    std::fs::write(&p, text).unwrap();
    p
}

/// Writes `text` as `scene.xml` in a fresh folder and loads it; the error as text.
pub fn load_text(
    suite: &str,
    tag: &str,
    text: &str,
    params: &[(&str, &str)],
) -> Result<SceneDescription, String> {
    let path = write(&tmp_dir(suite, tag), "scene.xml", text);
    load_file(&path, &super::options_in(params, vec![])).map_err(|e| e.to_string())
}

/// Builds a loaded scene, or panics naming the test.
pub fn build_desc(tag: &str, desc: &SceneDescription) -> Scene {
    build_scene(desc, &BuildOverrides::default())
        .unwrap_or_else(|e| panic!("{tag}: build failed:\n{e}"))
}

/// The error of loading or else of building; panics if both succeed.
pub fn load_or_build_error(tag: &str, loaded: Result<SceneDescription, String>) -> String {
    match loaded {
        Err(e) => e,
        Ok(desc) => match build_scene(&desc, &BuildOverrides::default()) {
            Err(e) => e.to_string(),
            Ok(_) => panic!("{tag}: expected an error (Mitsuba 3 refuses this scene)"),
        },
    }
}

/// The value of property `name` on the first object of `kind` that has it.
pub fn prop<'a>(desc: &'a SceneDescription, kind: ObjectKind, name: &str) -> &'a Value {
    desc.objects
        .iter()
        .filter(|o| o.kind == kind)
        .flat_map(|o| o.props.iter())
        .find(|p| p.name == name)
        .map(|p| &p.value)
        .unwrap_or_else(|| panic!("no property \"{name}\" on any <{}>", kind.tag()))
}
