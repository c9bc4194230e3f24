//! Camera sequences for temporal denoising (the paper, Sec. 4.2): the target frame
//! (k = 0, the scene's own sensor for an orbit or a dolly) and the frames before it
//! (k = 1..N−1), as sensor `to_world` transforms.
//!
//! * Orbit: the whole sensor rotates about the axis through `target` along its own up
//!   vector, `step` degrees per frame: frame k = T(c) R(up, −k·step) T(−c) · to_world.
//! * Dolly: the sensor moves along its view direction, `step` scene units per frame
//!   towards what it looks at, so frame k sits k·step further back.
//! * A file of transforms in time order, one per line, the last line being the target
//!   frame: either 16 numbers (a 4×4 matrix, row-major, as Mitsuba's `<matrix>`) or 9
//!   (`origin target up` of a `<lookat>`). `#` starts a comment.

use std::path::Path;

use glam::{DVec3, Mat4, Vec3};

use crate::error::{Loc, SceneError};
use crate::scene::shot::Shot;
use crate::scene::Scene;
use crate::xml::transform;

#[derive(Clone, Debug, PartialEq)]
pub enum CameraPath {
    /// Every frame at the scene's sensor (only the noise differs).
    Static,
    Orbit {
        degrees_per_frame: f32,
        target: Vec3,
    },
    Dolly {
        distance_per_frame: f32,
    },
    /// Sensor transforms in time order (the last is the target frame).
    Transforms(Vec<Mat4>),
}

impl CameraPath {
    /// `to_world` of frames k = 0..n (k = 0 the target frame), from the scene's sensor
    /// transform. A file gives at most as many frames as it has lines.
    pub fn frames(&self, to_world: Mat4, n: usize) -> Vec<Mat4> {
        match self {
            CameraPath::Static => vec![to_world; n],
            CameraPath::Orbit {
                degrees_per_frame,
                target,
            } => {
                let up = to_world.y_axis.truncate().normalize();
                (0..n)
                    .map(|k| {
                        let angle = -(k as f32) * degrees_per_frame.to_radians();
                        Mat4::from_translation(*target)
                            * Mat4::from_axis_angle(up, angle)
                            * Mat4::from_translation(-*target)
                            * to_world
                    })
                    .collect()
            }
            CameraPath::Dolly { distance_per_frame } => {
                let forward = to_world.z_axis.truncate().normalize();
                (0..n)
                    .map(|k| {
                        Mat4::from_translation(-forward * (k as f32 * distance_per_frame))
                            * to_world
                    })
                    .collect()
            }
            CameraPath::Transforms(list) => list.iter().rev().take(n).copied().collect(),
        }
    }

    /// Reads a file of transforms (module comment).
    pub fn read(path: &Path) -> Result<CameraPath, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| {
            SceneError::new(
                Some(Loc::file_only(path)),
                format!("cannot read the camera path: {e}"),
            )
        })?;
        let mut list = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let file = std::sync::Arc::new(path.to_path_buf());
            let here = || Some(Loc::new(&file, i as u32 + 1, 1));
            let body = line.split('#').next().unwrap_or("").trim();
            if body.is_empty() {
                continue;
            }
            let nums: Vec<f64> = body
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter(|s| !s.is_empty())
                .map(|s| {
                    s.parse::<f64>()
                        .ok()
                        .filter(|v| v.is_finite())
                        .ok_or_else(|| {
                            SceneError::new(here(), format!("'{s}' is not a finite number"))
                        })
                })
                .collect::<Result<_, _>>()?;
            let m = match nums.len() {
                16 => transform::matrix_row_major(&nums.clone().try_into().unwrap()),
                9 => {
                    let v = |j: usize| DVec3::new(nums[j], nums[j + 1], nums[j + 2]);
                    transform::look_at(v(0), v(3), v(6)).ok_or_else(|| {
                        SceneError::new(
                            here(),
                            "degenerate lookat: origin equals target, or up is parallel to the view direction",
                        )
                    })?
                }
                k => {
                    return Err(SceneError::new(
                        here(),
                        format!("{k} numbers: expected 16 (a 4x4 matrix, row-major) or 9 (origin target up)"),
                    ))
                }
            };
            if m.determinant().abs() < 1e-12 {
                return Err(SceneError::new(here(), "the matrix is singular"));
            }
            list.push(m.as_mat4());
        }
        if list.is_empty() {
            return Err(SceneError::new(
                Some(Loc::file_only(path)),
                "the camera path has no transforms",
            ));
        }
        Ok(CameraPath::Transforms(list))
    }
}

/// The first visible point through the film's centre: the default orbit centre.
pub fn image_centre_point(scene: &Scene, shot: &Shot) -> Option<Vec3> {
    let centre = glam::Vec2::new(shot.film.width as f32, shot.film.height as f32) * 0.5;
    let ray = shot.camera.sample_ray(centre);
    scene
        .intersect(ray.o, ray.d, ray.tmax)
        .map(|h| Vec3::from(h.p))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Mat4 {
        transform::look_at(
            DVec3::new(2.2, 1.6, 3.0),
            DVec3::new(0.0, -0.1, 0.0),
            DVec3::Y,
        )
        .unwrap()
        .as_mat4()
    }

    #[test]
    fn orbit_keeps_the_distance_to_the_target_and_looks_at_it() {
        let c = camera();
        let target = Vec3::new(0.0, -0.1, 0.0);
        let frames = CameraPath::Orbit {
            degrees_per_frame: 2.0,
            target,
        }
        .frames(c, 4);
        assert_eq!(frames[0], c);
        let r0 = (c.w_axis.truncate() - target).length();
        for (k, f) in frames.iter().enumerate() {
            let o = f.w_axis.truncate();
            assert!(((o - target).length() - r0).abs() < 1e-5);
            // Still looking at the target.
            let fwd = f.z_axis.truncate().normalize();
            assert!(fwd.dot((target - o).normalize()) > 1.0 - 1e-6);
            // k · 2 degrees from the target frame's position.
            let (a, b) = (
                (o - target).normalize(),
                (c.w_axis.truncate() - target).normalize(),
            );
            let angle = a.cross(b).length().atan2(a.dot(b)).to_degrees();
            assert!((angle - 2.0 * k as f32).abs() < 1e-2, "frame {k}: {angle}");
        }
    }

    #[test]
    fn dolly_moves_back_along_the_view_direction() {
        let c = camera();
        let frames = CameraPath::Dolly {
            distance_per_frame: 0.1,
        }
        .frames(c, 3);
        let fwd = c.z_axis.truncate().normalize();
        let d = frames[2].w_axis.truncate() - c.w_axis.truncate();
        assert!((d + 0.2 * fwd).length() < 1e-5);
        assert_eq!(frames[2].z_axis, c.z_axis);
    }

    #[test]
    fn transform_files_read_and_bad_lines_are_named() {
        let dir = std::env::temp_dir().join(format!("mediareg-seq-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let good = dir.join("good.txt");
        std::fs::write(
            &good,
            "# first\n1 0 0 0  0 1 0 0  0 0 1 5  0 0 0 1\n\n0,0,4, 0,0,0, 0,1,0  # last = target\n",
        )
        .unwrap();
        let path = CameraPath::read(&good).unwrap();
        let frames = path.frames(Mat4::IDENTITY, 11);
        assert_eq!(frames.len(), 2);
        assert!((frames[0].w_axis.truncate() - Vec3::new(0.0, 0.0, 4.0)).length() < 1e-6);
        assert!((frames[1].w_axis.truncate() - Vec3::new(0.0, 0.0, 5.0)).length() < 1e-6);

        for (text, want) in [
            ("1 2 3\n", "good.txt:1"),
            ("\n0 0 0 0 0 0 0 1 0\n", "degenerate"),
            ("1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 nan\n", "not a finite number"),
            ("0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 1\n", "singular"),
            ("# nothing\n", "no transforms"),
        ] {
            std::fs::write(&good, text).unwrap();
            let e = CameraPath::read(&good).unwrap_err().to_string();
            assert!(e.contains(want) && e.contains("good.txt"), "{text:?}: {e}");
        }
        let e = CameraPath::read(&dir.join("missing.txt"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing.txt"), "{e}");
    }
}
