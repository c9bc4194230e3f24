//! Draws for the paths of a number type (Mitsuba's `Sampler::next_1d(active)`): one
//! path draws from its `Pcg32`; lanes draw from a stream each, only in the lanes that
//! are on, so that every path's stream sees the draws of its own path in order, as on
//! one path, whatever the other lanes do.

use glam::Vec2;
use wide::f32x8;

use super::Pcg32;
use crate::simd::Float;

/// Uniform draws in [0, 1) for the paths of `F`, in the paths of a mask.
pub trait Sampler<F: Float> {
    /// One draw per path of `active` (0 in the others).
    fn draw_1d(&mut self, active: F::Mask) -> F;
    /// Two draws (one `next_2d`) per path of `active`.
    fn draw_2d(&mut self, active: F::Mask) -> (F, F);
}

impl Sampler<f32> for Pcg32 {
    #[inline(always)]
    fn draw_1d(&mut self, _: bool) -> f32 {
        self.next_1d()
    }
    #[inline(always)]
    fn draw_2d(&mut self, _: bool) -> (f32, f32) {
        let Vec2 { x, y } = self.next_2d();
        (x, y)
    }
}

/// Lanes draw from the streams of their paths, lane k from stream k.
impl Sampler<f32x8> for [Pcg32] {
    #[inline(always)]
    fn draw_1d(&mut self, active: f32x8) -> f32x8 {
        let mut u = [0f32; 8];
        for k in lanes_of(active) {
            u[k] = self[k].next_1d();
        }
        f32x8::from(u)
    }
    #[inline(always)]
    fn draw_2d(&mut self, active: f32x8) -> (f32x8, f32x8) {
        let (mut u, mut v) = ([0f32; 8], [0f32; 8]);
        for k in lanes_of(active) {
            let s = self[k].next_2d();
            (u[k], v[k]) = (s.x, s.y);
        }
        (f32x8::from(u), f32x8::from(v))
    }
}

/// The lanes that are on in `mask`.
#[inline(always)]
fn lanes_of(mask: f32x8) -> impl Iterator<Item = usize> {
    let bits = mask.move_mask();
    (0..8).filter(move |k| bits >> k & 1 == 1)
}
