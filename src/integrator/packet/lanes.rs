//! The packet's registers: `wide`'s `f32x8` (one lane per path), `simd::Vector3` of
//! them (a position, a direction or an RGB value per path) and masks (all bits
//! set in a lane that is on); the lanes draw by `sampling::Sampler`.

use wide::f32x8;

use crate::simd::Vector3;

/// Paths in a packet.
pub const WIDTH: usize = 8;

/// One f32 per path.
pub type L = f32x8;

/// A vector (or an RGB value) per path: `simd::Vector3` over the lanes (`from_fn`,
/// `lane`: its ways in and out of them).
pub type V3 = Vector3<L>;

/// The lanes where bit k of `bits` is set.
#[inline(always)]
pub fn lanes_of(bits: i32) -> impl Iterator<Item = usize> {
    (0..WIDTH).filter(move |k| bits >> k & 1 == 1)
}

/// All-ones where `cond`, per lane.
#[inline(always)]
pub fn mask_of(cond: impl Fn(usize) -> bool) -> L {
    L::from(std::array::from_fn::<f32, WIDTH, _>(|k| {
        if cond(k) {
            f32::from_bits(u32::MAX)
        } else {
            0.0
        }
    }))
}
