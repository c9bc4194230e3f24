//! What every estimator draws on: random numbers (Mitsuba's `independent` sampler,
//! PCG32), warps from the unit square, and the MIS weight.

pub mod independent;
pub mod mis;
pub mod warp;

pub use independent::Pcg32;
pub use mis::mis_weight;
