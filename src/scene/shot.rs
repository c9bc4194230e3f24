//! What one render takes besides the scene, as Mitsuba's `render(scene, sensor, seed,
//! spp)`: where the camera is, the film it exposes, how many samples per pixel and
//! from which seed. The scene keeps the shot its file describes ([`crate::scene::Scene::shot`]);
//! a caller that wants another camera, seed or sample count renders a changed copy, and
//! the scene itself is never written after it is built.

use super::camera::PerspectiveCamera;
use super::film::Film;

#[derive(Clone, Debug)]
pub struct Shot {
    pub camera: PerspectiveCamera,
    pub film: Film,
    /// Samples per pixel.
    pub spp: u32,
    /// The seed of every sample's random stream (with the pixel and sample index).
    pub seed: u64,
}

impl Shot {
    /// The same shot with another seed and sample count.
    pub fn with(&self, spp: u32, seed: u64) -> Shot {
        Shot {
            spp,
            seed,
            ..self.clone()
        }
    }
}
