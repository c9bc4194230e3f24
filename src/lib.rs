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
pub mod load;
pub mod medium;
pub mod regularize;
pub mod report;
pub mod sampling;
pub mod scene;
pub mod texture;
pub mod xml;

pub use error::{Loc, SceneError};
pub use load::{load_scene, BuildOverrides};
