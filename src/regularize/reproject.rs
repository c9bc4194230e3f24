//! Where each pixel of the target frame is found in an earlier frame (Eq. 10's
//! proj_k^{-1}), two ways:
//!
//! * `screen_motion`: the paper's Eq. 9, one motion vector for the whole frame, here the
//!   screen-space motion of the point the camera moves around (the orbit target).
//! * `exact`: through each pixel's first visible point P (a ray through the pixel centre
//!   of the target frame). P is projected into frame k; it reprojects only if frame k's
//!   camera sees P itself there (a ray from frame k's centre of projection to P hits
//!   nothing before it): otherwise it was occluded in frame k (disocclusion), and the
//!   pixel takes fewer frames. Pixels that see no surface reproject by direction, and
//!   only where frame k sees no surface in that direction either.

use glam::{Vec2, Vec3A};

use super::spatial::Features;
use super::temporal::Reprojection;
use crate::scene::camera::PerspectiveCamera;
use crate::scene::shot::Shot;
use crate::scene::Scene;

/// A visibility ray must end within this relative distance of P to see P itself.
const SAME_POINT: f32 = 1e-3;

/// Inside the lattice of pixel centres of a `width` × `height` crop window (with a
/// little slack for rounding: the border pixels project onto themselves).
fn inside(p: Vec2, width: usize, height: usize) -> bool {
    const SLACK: f32 = 1e-3;
    let (lo, hi) = (
        0.5 - SLACK,
        Vec2::new(width as f32, height as f32) - (0.5 - SLACK),
    );
    p.x >= lo && p.y >= lo && p.x <= hi.x && p.y <= hi.y
}

/// The exact reprojection into the frame seen by `frame` (same film and crop window as
/// the target frame, whose first hits are `target`).
pub fn exact(
    scene: &Scene,
    shot: &Shot,
    target: &Features,
    frame: &PerspectiveCamera,
) -> Reprojection {
    let (cw, ch) = shot.film.crop_size;
    let crop = Vec2::new(
        shot.film.crop_offset.0 as f32,
        shot.film.crop_offset.1 as f32,
    );
    let o = frame.origin();
    (0..target.depth.len())
        .map(|i| {
            let film_pos = if target.depth[i].is_finite() {
                let p = Vec3A::from(target.position[i]);
                let to_p = p - o;
                let dist = to_p.length();
                let d = to_p / dist;
                let seen = scene
                    .intersect(o, d, dist * (1.0 + SAME_POINT))
                    .is_some_and(|h| (h.t - dist).abs() <= SAME_POINT * dist);
                if !seen {
                    return None;
                }
                frame.project_point(p)?
            } else {
                let d = Vec3A::from(target.direction[i]);
                if scene.intersect(o, d, f32::INFINITY).is_some() {
                    return None;
                }
                frame.project_direction(d)?
            };
            let pos = film_pos - crop;
            inside(pos, cw, ch).then_some((pos.x, pos.y))
        })
        .collect()
}

/// Eq. 9's motion vector for frame k: how far `point` moves on screen from the target
/// frame to frame k, in pixels (`None` when it is behind either camera).
pub fn screen_motion(
    target_frame: &PerspectiveCamera,
    frame: &PerspectiveCamera,
    point: Vec3A,
) -> Option<(f32, f32)> {
    let d = frame.project_point(point)? - target_frame.project_point(point)?;
    Some((d.x, d.y))
}
