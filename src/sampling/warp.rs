//! Mitsuba's `warp`: maps from the unit square to the shapes samples are drawn on.

use glam::{Vec2, Vec3A};

/// Shirley–Chiu concentric map from the unit square to the unit disk.
pub fn square_to_uniform_disk_concentric(s: Vec2) -> (f32, f32) {
    let x = 2.0 * s.x - 1.0;
    let y = 2.0 * s.y - 1.0;
    if x == 0.0 && y == 0.0 {
        return (0.0, 0.0);
    }
    use std::f32::consts::FRAC_PI_4;
    // φ = θ in the wedges around the x axis and π/2 − θ in those around y, with
    // θ = π/4 · (minor / major) in [−π/4, π/4]: cos φ and sin φ are cos θ and sin θ,
    // swapped in the second case.
    if x.abs() > y.abs() {
        let (s, c) = sin_cos_quarter(FRAC_PI_4 * (y / x));
        (x * c, x * s)
    } else {
        let (s, c) = sin_cos_quarter(FRAC_PI_4 * (x / y));
        (y * s, y * c)
    }
}

/// sin θ and cos θ for |θ| ≤ π/4 by their Taylor series (to θ⁹ and θ¹⁰: the next
/// terms are below 2e-9 there), without libm's range reduction: within a few units
/// in the last place of f32.
#[inline]
fn sin_cos_quarter(t: f32) -> (f32, f32) {
    let t2 = t * t;
    let s = t
        * (1.0
            + t2 * (-1.0 / 6.0
                + t2 * (1.0 / 120.0 + t2 * (-1.0 / 5040.0 + t2 * (1.0 / 362_880.0)))));
    let c = 1.0
        + t2 * (-0.5
            + t2 * (1.0 / 24.0
                + t2 * (-1.0 / 720.0 + t2 * (1.0 / 40_320.0 + t2 * (-1.0 / 3_628_800.0)))));
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
    let (x, y) = square_to_uniform_disk_concentric(s);
    let z = (1.0 - x * x - y * y).max(0.0).sqrt();
    Vec3A::new(x, y, z)
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
