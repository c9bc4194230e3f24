//! The `<transform>` operations of Mitsuba's XML, in double precision.
//!
//! Each operation inside `<transform>` is applied *after* the ones before it, so the
//! accumulated matrix is left-multiplied: `M ← Op · M` (Mitsuba 3 `parser.cpp`).

use glam::{DMat4, DVec3, DVec4};

/// `<translate value="x,y,z"/>`
pub fn translate(v: DVec3) -> DMat4 {
    DMat4::from_translation(v)
}

/// `<scale value="s"/>` or `<scale value="x,y,z"/>`
pub fn scale(v: DVec3) -> DMat4 {
    DMat4::from_scale(v)
}

/// `<rotate value="ax,ay,az" angle="deg"/>`: drjit's `rotate<Matrix4>(axis, angle)`, the
/// Rodrigues formula applied to the axis *as given* (drjit does not normalise it):
///
/// ```text
/// R = c·I + (1 − c)·a aᵀ + s·[a]×,   c = cos θ, s = sin θ
/// ```
pub fn rotate(axis: DVec3, angle_deg: f64) -> DMat4 {
    let (s, c) = angle_deg.to_radians().sin_cos();
    let a = axis;
    let m = 1.0 - c;
    // Rows of R (glam's from_cols takes columns, so build rows and transpose).
    let r0 = DVec4::new(
        a.x * a.x * m + c,
        a.x * a.y * m - a.z * s,
        a.x * a.z * m + a.y * s,
        0.0,
    );
    let r1 = DVec4::new(
        a.y * a.x * m + a.z * s,
        a.y * a.y * m + c,
        a.y * a.z * m - a.x * s,
        0.0,
    );
    let r2 = DVec4::new(
        a.z * a.x * m - a.y * s,
        a.z * a.y * m + a.x * s,
        a.z * a.z * m + c,
        0.0,
    );
    DMat4::from_cols(r0, r1, r2, DVec4::W).transpose()
}

/// `<matrix value="m00 m01 ... m33"/>`: 16 values, row by row. Mitsuba 3 stores
/// transforms as affine (`AffineTransform4d`), so the bottom row is dropped and taken
/// as (0, 0, 0, 1) — a projective row in a scene file has no effect there either.
pub fn matrix_row_major(v: &[f64; 16]) -> DMat4 {
    let mut m = DMat4::from_cols_array(v).transpose();
    m.x_axis.w = 0.0;
    m.y_axis.w = 0.0;
    m.z_axis.w = 0.0;
    m.w_axis.w = 1.0;
    m
}

/// `<matrix value="..."/>` with 9 values: a 3×3 linear part, row by row.
pub fn matrix3_row_major(v: &[f64; 9]) -> DMat4 {
    DMat4::from_mat3(glam::DMat3::from_cols_array(v).transpose())
}

/// The default `up` of `<lookat>` when none (or zero) is given: the first tangent of
/// Mitsuba's `coordinate_system(dir)` (Duff et al. 2017).
pub fn default_up(dir: DVec3) -> DVec3 {
    let sign = 1f64.copysign(dir.z);
    let a = -1.0 / (sign + dir.z);
    let b = dir.x * dir.y * a;
    DVec3::new(1.0 + sign * dir.x * dir.x * a, sign * b, -sign * dir.x)
}

/// `<lookat origin target up/>`: Mitsuba's `Transform4f::look_at`. Columns are
/// (left, up', dir, origin) with `dir = ‖target − origin‖`, `left = ‖up × dir‖`,
/// `up' = dir × left`. Returns `None` when the frame is degenerate (up ∥ dir or
/// origin = target), where Mitsuba would produce NaNs.
pub fn look_at(origin: DVec3, target: DVec3, up: DVec3) -> Option<DMat4> {
    let dir = (target - origin).try_normalize()?;
    let left = up.cross(dir).try_normalize()?;
    let new_up = dir.cross(left);
    Some(DMat4::from_cols(
        left.extend(0.0),
        new_up.extend(0.0),
        dir.extend(0.0),
        origin.extend(1.0),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotate_z_90_maps_x_to_y() {
        let r = rotate(DVec3::Z, 90.0);
        let p = r.transform_point3(DVec3::X);
        assert!((p - DVec3::Y).length() < 1e-12, "{p}");
    }

    #[test]
    fn look_at_maps_z_to_view_direction() {
        let m = look_at(DVec3::new(0.0, 0.0, 5.0), DVec3::ZERO, DVec3::Y).unwrap();
        let d = m.transform_vector3(DVec3::Z);
        assert!((d - DVec3::NEG_Z).length() < 1e-12);
        assert!(look_at(DVec3::ZERO, DVec3::Y, DVec3::Y).is_none());
    }
}
