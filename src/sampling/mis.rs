//! Multiple importance sampling: how two strategies' estimates of one integral are weighted.

use crate::simd::Float;

/// Power heuristic with β = 2 (Veach 1997, Eq. 9.13): `a² / (a² + b²)`, 0 where not
/// finite. One definition for a path and for lanes of paths.
#[inline(always)]
pub fn mis_weight<F: Float>(a: F, b: F) -> F {
    let (a2, b2) = (a * a, b * b);
    let w = a2 / (a2 + b2);
    F::select(w.is_finite(), w, F::zero())
}
