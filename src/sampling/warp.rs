//! Mitsuba's `warp`: maps from the unit square to the shapes samples are drawn on.

use glam::{Vec2, Vec3A};

use crate::simd::{Float, Vector3};

/// Shirley–Chiu concentric map from the unit square to the unit disk.
pub fn square_to_uniform_disk_concentric(s: Vec2) -> (f32, f32) {
    concentric_disk(s.x, s.y)
}

/// The concentric map for a path or for lanes of paths (each wedge's branch a select).
#[inline(always)]
pub fn concentric_disk<F: Float>(u1: F, u2: F) -> (F, F) {
    let (zero, one, two) = (F::zero(), F::one(), F::of(2.0));
    let x = two * u1 - one;
    let y = two * u2 - one;
    // φ = θ in the wedges around the x axis and π/2 − θ in those around y, with
    // θ = π/4 · (minor / major) in [−π/4, π/4]: cos φ and sin φ are cos θ and sin θ,
    // swapped in the second case.
    let around_x = x.abs().gt(y.abs());
    let r = F::select(around_x, x, y);
    let ratio = F::select(around_x, y, x) / r;
    let (s, c) = sin_cos_quarter(F::of(std::f32::consts::FRAC_PI_4 as f64) * ratio);
    let (dx, dy) = (r * F::select(around_x, c, s), r * F::select(around_x, s, c));
    // The centre (0/0 above) maps to itself.
    let centre = x.eq(zero) & y.eq(zero);
    (F::select(centre, zero, dx), F::select(centre, zero, dy))
}

/// sin θ and cos θ for |θ| ≤ π/4 by their Taylor series (to θ⁹ and θ¹⁰: the next
/// terms are below 2e-9 there), without libm's range reduction: within a few units
/// in the last place of f32, the same in lanes as in one path.
#[inline(always)]
fn sin_cos_quarter<F: Float>(t: F) -> (F, F) {
    let k = |x: f32| F::of(x as f64);
    let t2 = t * t;
    let s = t
        * (k(1.0)
            + t2 * (k(-1.0 / 6.0)
                + t2 * (k(1.0 / 120.0) + t2 * (k(-1.0 / 5040.0) + t2 * k(1.0 / 362_880.0)))));
    let c = k(1.0)
        + t2 * (k(-0.5)
            + t2 * (k(1.0 / 24.0)
                + t2 * (k(-1.0 / 720.0) + t2 * (k(1.0 / 40_320.0) + t2 * k(-1.0 / 3_628_800.0)))));
    (s, c)
}

pub fn square_to_uniform_sphere(s: Vec2) -> Vec3A {
    let z = 1.0 - 2.0 * s.y;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (sp, cp) = (2.0 * std::f32::consts::PI * s.x).sin_cos();
    Vec3A::new(r * cp, r * sp, z)
}

/// Malley's method on the concentric disk; pdf = cos θ / π.
pub fn square_to_cosine_hemisphere(s: Vec2) -> Vec3A {
    cosine_hemisphere(s.x, s.y).into()
}

/// Malley's method for a path or for lanes of paths: the disk's point lifted to the
/// hemisphere, z = √(1 − x² − y²).
#[inline(always)]
pub fn cosine_hemisphere<F: Float>(u1: F, u2: F) -> Vector3<F> {
    let (x, y) = concentric_disk(u1, u2);
    let z = (F::one() - x * x - y * y).max(F::zero()).sqrt();
    Vector3::new(x, y, z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_4;

    /// The series against f64's sin and cos across [−π/4, π/4].
    #[test]
    fn quarter_sin_cos_is_f32_accurate() {
        let n = 100_000;
        for i in 0..=n {
            let t = -FRAC_PI_4 + 2.0 * FRAC_PI_4 * i as f64 / n as f64;
            let (s, c) = sin_cos_quarter(t as f32);
            let t = t as f32 as f64;
            assert!((s as f64 - t.sin()).abs() < 2.5e-7, "sin {t}: {s}");
            assert!((c as f64 - t.cos()).abs() < 2.5e-7, "cos {t}: {c}");
        }
    }

    /// The concentric map is Shirley and Chiu's (computed in f64) on a grid over the
    /// square, the wedges' borders and the centre included.
    #[test]
    fn concentric_map_is_shirley_chius() {
        let n = 300;
        for i in 0..=n {
            for j in 0..=n {
                let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                let (x, y) = (2.0 * u - 1.0, 2.0 * v - 1.0);
                let want = if x == 0.0 && y == 0.0 {
                    (0.0, 0.0)
                } else if x.abs() > y.abs() {
                    let phi = FRAC_PI_4 * (y / x);
                    (x * phi.cos(), x * phi.sin())
                } else {
                    let phi = 2.0 * FRAC_PI_4 - FRAC_PI_4 * (x / y);
                    (y * phi.cos(), y * phi.sin())
                };
                let got = square_to_uniform_disk_concentric(Vec2::new(u as f32, v as f32));
                assert!(
                    (got.0 as f64 - want.0).abs() < 5e-7 && (got.1 as f64 - want.1).abs() < 5e-7,
                    "({u}, {v}): {got:?} vs {want:?}"
                );
            }
        }
    }
}
