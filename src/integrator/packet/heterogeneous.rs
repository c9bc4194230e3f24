//! A heterogeneous medium's lanes beyond its trackings (which `medium::heterogeneous`
//! writes once over the number type, the lanes tracking at the global majorant):
//! the depth estimate for the derivative in its scale, lane by lane.

use glam::Vec3;

use super::lanes::{lanes_of, L, V3, WIDTH};
use crate::medium::heterogeneous::HeterogeneousMedium;

/// `HeterogeneousMedium::depth_estimate` (an unbiased estimate of ∫σ, σ_t before the
/// scale) over the stretches [tmin, tmax] of the rays from `o` along unit `d`, for the
/// lanes of `mask` (0 elsewhere), lane by lane: one lookup a segment, for the
/// derivative in the scale.
pub fn depth_estimate(h: &HeterogeneousMedium, o: V3, d: V3, (tmin, tmax): (L, L), mask: L) -> V3 {
    let (t0, t1) = (tmin.to_array(), tmax.to_array());
    let mut out = [Vec3::ZERO; WIDTH];
    for k in lanes_of(mask.move_mask()) {
        let dk = d.lane_a(k);
        out[k] = h.depth_estimate(o.lane_a(k) + dk * t0[k], dk, t1[k] - t0[k]);
    }
    V3::from_fn(|k| out[k])
}
