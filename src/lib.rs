//! mediareg: a renderer for participating media that reads Mitsuba 3 scene files.
//!
//! Data flows one way: `xml` (file → `SceneDescription`) → `load::build_scene`
//! (plugins → the plain objects of a `scene::SceneParts`) → `Scene::new` (BVH,
//! clearance, emitter selection: the render state) → `integrator::render`
//! (→ `image::Image`) → `image` (EXR/PNG); `regularize` and `report` drive renders.
//!
//! Modules import only from those below them, lowest first: `error`, `simd`, `sampling`,
//! `image`, `denoise`, `xml`, `geometry`, `texture`, `medium`, `bsdf`, `emitter`, `scene`, `load`,
//! `integrator`, `fit`, `optimize`, `regularize`, `report` (`tests/layering.rs` holds the list and checks
//! it, with no import circle inside a module and no file over 800 lines).

pub mod bsdf;
pub mod denoise;
pub mod emitter;
pub mod error;
pub mod fit;
pub mod geometry;
pub mod image;
pub mod integrator;
pub mod load;
pub mod medium;
pub mod optimize;
pub mod regularize;
pub mod report;
pub mod sampling;
pub mod scene;
pub mod simd;
pub mod texture;
pub mod xml;

pub use error::{Loc, SceneError};
pub use load::{load_scene, BuildOverrides};
