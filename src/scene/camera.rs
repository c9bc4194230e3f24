//! Mitsuba 3's `perspective` sensor (`src/sensors/perspective.cpp`,
//! `perspective_projection` in `include/mitsuba/render/sensor.h`).
//!
//! Camera space looks down +z with +x to the image's *left* and +y up (Mitsuba's
//! `look_at` puts `left` in the first column). For a film position `s` ∈ \[0,1\]² relative
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

    /// The film position (pixels, relative to the full film's top-left) that sees the
    /// camera-space direction `d`: the inverse of `sample_ray`. `None` behind the camera.
    #[inline]
    fn film_position_of_local(&self, d: Vec3A) -> Option<Vec2> {
        if d.z <= 0.0 {
            return None;
        }
        let (x, y) = (d.x / d.z, d.y / d.z);
        let s = Vec2::new(
            0.5 * (1.0 - x / self.tan_half_fov_x),
            0.5 * (1.0 - y * self.aspect / self.tan_half_fov_x),
        );
        Some((s - self.principal_point_offset) * self.film_size)
    }

    /// Where the world point `p` appears on the film (pixels from the full film's
    /// top-left; may lie outside the film). `None` when `p` is behind the camera.
    pub fn project_point(&self, p: Vec3A) -> Option<Vec2> {
        let local = self.to_world.inverse().transform_point3a(p);
        self.film_position_of_local(local)
    }

    /// Where a point at infinity in world direction `d` appears on the film.
    pub fn project_direction(&self, d: Vec3A) -> Option<Vec2> {
        let local = self.to_world.inverse().transform_vector3a(d);
        self.film_position_of_local(local)
    }

    /// The camera's centre of projection in world space.
    pub fn origin(&self) -> Vec3A {
        self.to_world.transform_point3a(Vec3A::ZERO)
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

    /// `project_point` inverts `sample_ray`, with a rotated, translated, scaled camera and
    /// a principal point offset.
    #[test]
    fn projection_inverts_sample_ray() {
        let cam = PerspectiveCamera {
            to_world: Mat4::from_translation(glam::Vec3::new(1.0, -2.0, 0.5))
                * Mat4::from_rotation_y(0.7)
                * Mat4::from_rotation_x(-0.3),
            tan_half_fov_x: 0.6,
            aspect: 1.5,
            near_clip: 0.01,
            far_clip: 100.0,
            principal_point_offset: Vec2::new(0.05, -0.02),
            film_size: Vec2::new(96.0, 64.0),
        };
        for pos in [
            Vec2::new(0.5, 0.5),
            Vec2::new(47.3, 12.9),
            Vec2::new(95.5, 63.5),
        ] {
            let r = cam.sample_ray(pos);
            let p = r.o + r.d * 3.7;
            let back = cam.project_point(p).unwrap();
            assert!((back - pos).length() < 1e-3, "{pos} → {back}");
            let back = cam.project_direction(r.d).unwrap();
            assert!((back - pos).length() < 1e-3, "{pos} → {back}");
        }
        assert!(cam
            .project_point(cam.origin() - cam.sample_ray(Vec2::new(9.0, 9.0)).d)
            .is_none());
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
