//! mediareg: a renderer for participating media that reads Mitsuba 3 scene files.
//!
//! Data flows one way: `xml` (file → `SceneDescription`) → `scene::build_scene`
//! (description → `Scene`) → `integrator::render` (→ `Image`) → `image` (EXR/PNG).

pub mod bsdf;
pub mod emitter;
pub mod error;
pub mod geometry;
pub mod image;
pub mod integrator;
pub mod medium;
pub mod scene;
pub mod xml;

use std::path::Path;

pub use error::{Loc, SceneError};
pub use scene::build::BuildOverrides;

/// Loads and builds a scene, refusing what cannot be rendered yet.
pub fn load_scene(
    path: &Path,
    opts: &xml::LoadOptions,
    overrides: &BuildOverrides,
) -> Result<scene::Scene, SceneError> {
    let desc = xml::load_file(path, opts)?;
    let scene = scene::build_scene(&desc, overrides)?;
    check_renderable(&desc, &scene)?;
    Ok(scene)
}

/// Participating media and `volpath` are parsed and validated, but rendered only from
/// the next milestone on: refuse them clearly rather than render a different image.
fn check_renderable(desc: &xml::SceneDescription, scene: &scene::Scene) -> Result<(), SceneError> {
    use xml::description::ObjectKind;
    if let Some(o) = desc.objects.iter().find(|o| o.kind == ObjectKind::Medium) {
        return Err(SceneError::at(
            &o.loc,
            format!("participating media are not yet supported for rendering ({} parsed and validated)", o.label()),
        )
        .with_hint("volpath and homogeneous media are the next milestone; remove the medium to render the surfaces"));
    }
    if scene.integrator.kind == scene::IntegratorKind::Volpath {
        let o = desc
            .objects
            .iter()
            .find(|o| o.kind == ObjectKind::Integrator)
            .expect("volpath came from an integrator");
        return Err(SceneError::at(
            &o.loc,
            "the volpath integrator is not yet supported for rendering",
        )
        .with_hint("use <integrator type=\"path\"> for surface scenes"));
    }
    Ok(())
}
