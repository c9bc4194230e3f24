//! The paper's method (Wu et al. 2024, "Efficient participating media rendering with
//! differentiable regularization"): render at a lower source albedo α_s, estimate
//! d(radiance)/d(albedo) in the same paths (`integrator::volpath`, `Gradient::Albedo`),
//! denoise the gradient, and predict the image at the target albedo α_t.

pub mod predict;
pub mod spatial;
pub mod temporal;
