//! Mitsuba's texture `to_uv`: the 2D affine map a texture applies to a surface's uv.

use glam::Vec2;

/// Mitsuba's `to_uv` (a 2D affine map, rows (a, b, tx) and (c, d, ty)) applied to `uv`.
#[inline]
pub fn apply_to_uv(to_uv: &[[f32; 3]; 2], uv: Vec2) -> Vec2 {
    let [r0, r1] = to_uv;
    Vec2::new(
        r0[0] * uv.x + r0[1] * uv.y + r0[2],
        r1[0] * uv.x + r1[1] * uv.y + r1[2],
    )
}
