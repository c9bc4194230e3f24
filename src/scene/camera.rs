//! Mitsuba 3's `perspective` sensor (`src/sensors/perspective.cpp`,
//! `perspective_projection` in `include/mitsuba/render/sensor.h`).
//!
//! Camera space looks down +z with +x to the image's *left* and +y up (Mitsuba's
//! `look_at` puts `left` in the first column). For a film position `s` ∈ [0,1]² relative
//! to the full film (plus the principal point offset), the camera-space direction on the
//! z = 1 plane is
//!
//! ```text
//! x = (1 − 2 s_x) · tan(fov_x / 2),   y = (1 − 2 s_y) · tan(fov_x / 2) / aspect
//! ```

use glam::{Mat4, Vec2, Vec3A};

use crate::geometry::Ray;

#[derive(Clone, Debug)]
pub struct PerspectiveCamera {
    pub to_world: Mat4,
    /// tan(fov_x / 2)
    pub tan_half_fov_x: f32,
    /// film width / film height
    pub aspect: f32,
    pub near_clip: f32,
    pub far_clip: f32,
    pub principal_point_offset: Vec2,
    /// Full film size in pixels.
    pub film_size: Vec2,
}

/// Converts Mitsuba's `fov` along `fov_axis` to the horizontal field of view, in degrees
/// (`parse_fov` in `src/render/sensor.cpp`).
pub fn fov_x_degrees(fov: f64, axis: &str, aspect: f64) -> Option<f64> {
    let axis = match axis {
        "smaller" => {
            if aspect > 1.0 {
                "y"
            } else {
                "x"
            }
        }
        "larger" => {
            if aspect > 1.0 {
                "x"
            } else {
                "y"
            }
        }
        a => a,
    };
    let half = (0.5 * fov).to_radians().tan();
    Some(match axis {
        "x" => fov,
        "y" => (2.0 * (half * aspect).atan()).to_degrees(),
        "diagonal" => {
            let width = 2.0 * half / (1.0 + 1.0 / (aspect * aspect)).sqrt();
            (2.0 * (0.5 * width).atan()).to_degrees()
        }
        _ => return None,
    })
}

impl PerspectiveCamera {
    /// The ray through film position `pos` (pixels, relative to the full film's top-left).
    #[inline]
    pub fn sample_ray(&self, pos: Vec2) -> Ray {
        let s = pos / self.film_size + self.principal_point_offset;
        let d = Vec3A::new(
            (1.0 - 2.0 * s.x) * self.tan_half_fov_x,
            (1.0 - 2.0 * s.y) * self.tan_half_fov_x / self.aspect,
            1.0,
        )
        .normalize();
        // Mitsuba starts the ray on the near plane and ends it on the far plane.
        let inv_z = 1.0 / d.z;
        let near_t = self.near_clip * inv_z;
        let far_t = self.far_clip * inv_z;
        let o = self.to_world.transform_point3a(d * near_t);
        let dw = self.to_world.transform_vector3a(d);
        let len = dw.length();
        Ray::new(o, dw / len, (far_t - near_t) * len)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fov_axis_conversions() {
        assert_eq!(fov_x_degrees(40.0, "x", 2.0), Some(40.0));
        let fx = fov_x_degrees(40.0, "y", 2.0).unwrap();
        assert!(((0.5 * fx).to_radians().tan() - 2.0 * 20f64.to_radians().tan()).abs() < 1e-12);
        assert_eq!(
            fov_x_degrees(40.0, "smaller", 2.0),
            fov_x_degrees(40.0, "y", 2.0)
        );
        assert!(fov_x_degrees(40.0, "z", 2.0).is_none());
    }

    #[test]
    fn center_ray_looks_down_z_and_left_is_plus_x() {
        let cam = PerspectiveCamera {
            to_world: Mat4::IDENTITY,
            tan_half_fov_x: 1.0,
            aspect: 1.0,
            near_clip: 0.01,
            far_clip: 100.0,
            principal_point_offset: Vec2::ZERO,
            film_size: Vec2::new(10.0, 10.0),
        };
        let r = cam.sample_ray(Vec2::new(5.0, 5.0));
        assert!((r.d - Vec3A::Z).length() < 1e-6);
        let left = cam.sample_ray(Vec2::new(0.0, 5.0));
        assert!(left.d.x > 0.0);
        let top = cam.sample_ray(Vec2::new(5.0, 0.0));
        assert!(top.d.y > 0.0);
    }
}
