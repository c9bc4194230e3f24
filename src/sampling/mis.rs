//! Multiple importance sampling: how two strategies' estimates of one integral are weighted.

/// Power heuristic with β = 2: `a² / (a² + b²)`, 0 when not finite.
#[inline]
pub fn mis_weight(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    let w = a2 / (a2 + b2);
    if w.is_finite() {
        w
    } else {
        0.0
    }
}
