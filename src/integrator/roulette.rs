//! Russian roulette (Mitsuba 3's `volpath` and `path`): past `rr_depth` a path goes on
//! with probability q and, if it does, weighs 1/q, so the estimate stays unbiased.

use crate::simd::{Float, Vector3};

/// q = min(max_c(w) · η², 0.95), where w is the path's weight (its throughput β, or what
/// the estimator rouletted by) and η the product of the relative indices of the
/// refractions it took (the radiance a refraction compresses is not energy lost).
/// Where w is 0 in every channel but the derivative's weight `d` is not (albedo 0), q
/// comes from |d| instead: a detached derivative must keep q > 0. A NaN q ends the path
/// (u < q fails). One definition for a path and for lanes of paths.
#[inline(always)]
pub fn continue_probability<F: Float>(w: Vector3<F>, d: Vector3<F>, eta: F) -> F {
    let w_max = w.max_element();
    let w_max = F::select(w_max.gt(F::zero()), w_max, d.abs().max_element());
    (w_max * eta * eta).min(F::of(0.95))
}

/// The roulette at a vertex past `rr_depth`, from its draw `u`: whether the path goes on
/// (u < q, [`continue_probability`]; a NaN q ends it) and the q its weights are then
/// divided by. One definition for a path and for lanes of paths.
#[inline(always)]
pub fn roulette<F: Float>(w: Vector3<F>, d: Vector3<F>, eta: F, u: F) -> (F::Mask, F) {
    let q = continue_probability(w, d, eta);
    (u.lt(q), q)
}
