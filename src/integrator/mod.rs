//! The integrators (Mitsuba's `path`, `volpath`, `direct`) and the render driver
//! that runs one of them over the film (`render`).

pub mod aovs;
pub mod backward;
pub mod denoised;
pub mod direct;
pub mod emitters;
pub mod gradient;
pub mod packet;
pub mod path;
pub mod render;
pub mod roulette;
pub mod sample;
pub mod volpath;

pub use gradient::{
    albedo_gradient, derivative_images, medium_gradient, GradientError, MediumParam,
};
pub use sample::PathSample;

pub use render::{render, RenderOptions, RenderStats, Rendered};

/// A scene from XML text, for the integrators' tests: written to `name`.xml in this
/// process's directory for `group` (tests run in parallel: each group its own), then
/// loaded.
#[cfg(test)]
pub(crate) fn scene_from_xml(group: &str, name: &str, xml: &str) -> crate::scene::Scene {
    let dir = std::env::temp_dir().join(format!("mediareg_{group}_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{name}.xml"));
    std::fs::write(&path, xml).unwrap();
    crate::load_scene(&path, &Default::default(), &Default::default())
        .unwrap_or_else(|e| panic!("{name}: {e}"))
}
