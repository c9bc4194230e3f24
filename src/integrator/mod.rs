//! The integrators (Mitsuba's `path`, `volpath`, `direct`) and the render driver
//! that runs one of them over the film (`render`).

pub mod aovs;
pub mod denoised;
pub mod direct;
pub mod emitters;
pub mod gradient;
pub mod packet;
pub mod path;
pub mod render;
pub mod sample;
pub mod volpath;

pub use gradient::{albedo_gradient, GradientError};
pub use sample::PathSample;

pub use render::{render, RenderOptions, RenderStats, Rendered};
