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
pub mod regularize;
pub mod report;
pub mod sampling;
pub mod scene;
pub mod texture;
pub mod xml;

use std::path::Path;

pub use error::{Loc, SceneError};
pub use scene::build::BuildOverrides;

/// Loads and builds a scene.
pub fn load_scene(
    path: &Path,
    opts: &xml::LoadOptions,
    overrides: &BuildOverrides,
) -> Result<scene::Scene, SceneError> {
    let desc = xml::load_file(path, opts)?;
    scene::build_scene(&desc, overrides)
}
