//! What every estimator draws on: random numbers (Mitsuba's `independent` sampler,
//! PCG32, its first draws per path from padded (0,2)-sequences; `Sampler`, their draws
//! for one path or for lanes), the samples' positions
//! in their pixel (a shifted (0,2)-sequence), warps from
//! the unit square, and the MIS weight.

pub mod independent;
pub mod mis;
pub mod padded;
pub mod pixel;
pub mod sampler;
pub mod warp;

pub use independent::Pcg32;
pub use mis::mis_weight;
pub use padded::PaddedScrambles;
pub use pixel::PixelSamples;
pub use sampler::Sampler;
