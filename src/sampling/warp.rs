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
    let (r, phi) = if x.abs() > y.abs() {
        (x, FRAC_PI_4 * (y / x))
    } else {
        (y, 2.0 * FRAC_PI_4 - FRAC_PI_4 * (x / y))
    };
    let (s, c) = phi.sin_cos();
    (r * c, r * s)
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
