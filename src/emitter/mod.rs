//! Light sources: Mitsuba 3's `area`, `point`, `spot`, `constant`, `envmap` and
//! `directional`.
//!
//! `sample_direction` returns, for a reference point, a direction toward the light, the
//! distance to travel, the solid-angle pdf (1 for Dirac lights) and `Le / pdf`.

pub mod direction;
pub mod envmap;
pub mod selection;

use std::f32::consts::PI;

use glam::{Mat3A, Vec2, Vec3, Vec3A};

use crate::geometry::shape::Geometry;
use crate::sampling::warp::square_to_uniform_sphere;
use crate::simd::Vector3;

#[derive(Clone, Debug)]
pub enum Emitter {
    /// Emits `radiance` from the front side (where the shading normal points) of `shape`.
    Area { shape: u32, radiance: Vec3 },
    /// `intensity / r²` from `position`.
    Point { position: Vec3A, intensity: Vec3 },
    /// Mitsuba's `spot`: `intensity · falloff / r²` from `position`, the falloff 1 inside
    /// the beam, dropping linearly in angle to 0 at the cutoff.
    Spot(Spot),
    /// Uniform environment `radiance` from every direction.
    Constant { radiance: Vec3 },
    /// An environment image (latitude-longitude).
    EnvMap(Box<envmap::EnvMap>),
    /// Parallel light travelling along `direction`, `irradiance` on a surface facing it.
    Directional { direction: Vec3A, irradiance: Vec3 },
}

/// Mitsuba 3's `spot` (`src/emitters/spot.cpp`): a point light shining along its local
/// +z. With θ the angle from that axis, the falloff is 1 for θ ≤ beam_width,
/// (cutoff − θ) / (cutoff − beam_width) up to the cutoff, and 0 beyond.
#[derive(Clone, Debug)]
pub struct Spot {
    pub position: Vec3A,
    /// The linear part of to_world⁻¹: world directions into the light's frame.
    pub to_local: Mat3A,
    pub intensity: Vec3,
    /// Radians.
    pub cutoff_angle: f32,
    pub beam_width: f32,
    cos_cutoff: f32,
    cos_beam: f32,
}

impl Spot {
    /// Angles in radians; their cosines are kept for the falloff test.
    pub fn new(
        position: Vec3A,
        to_local: Mat3A,
        intensity: Vec3,
        cutoff_angle: f32,
        beam_width: f32,
    ) -> Self {
        Spot {
            position,
            to_local,
            intensity,
            cutoff_angle,
            beam_width,
            cos_cutoff: cutoff_angle.cos(),
            cos_beam: beam_width.cos(),
        }
    }

    /// The falloff toward world direction `d` leaving the light.
    pub fn falloff(&self, d: Vec3A) -> f32 {
        let cos_theta = (self.to_local * d).normalize_or_zero().z;
        if cos_theta <= self.cos_cutoff {
            0.0
        } else if cos_theta >= self.cos_beam {
            1.0
        } else {
            (self.cutoff_angle - cos_theta.clamp(-1.0, 1.0).acos())
                / (self.cutoff_angle - self.beam_width)
        }
    }
}

/// A sampled direction toward an emitter.
#[derive(Clone, Copy, Debug)]
pub struct EmitterSample {
    /// Unit direction from the reference point toward the light.
    pub d: Vec3A,
    /// Point on the light (or far along `d` for infinite lights).
    pub p: Vec3A,
    /// Solid-angle pdf (selection pmf not included); 1 for Dirac lights.
    pub pdf: f32,
    /// `Le · G / pdf` — for Dirac lights the incident radiance scale.
    pub weight: Vec3,
    pub delta: bool,
}

/// The scene's bounding sphere, for infinite lights.
#[derive(Clone, Copy, Debug)]
pub struct BSphere {
    pub center: Vec3A,
    pub radius: f32,
}

impl Emitter {
    pub fn is_delta(&self) -> bool {
        matches!(
            self,
            Emitter::Point { .. } | Emitter::Spot(_) | Emitter::Directional { .. }
        )
    }

    pub fn sample_direction(
        &self,
        p_ref: Vec3A,
        s: Vec2,
        shapes: &[Geometry],
        bsphere: &BSphere,
    ) -> Option<EmitterSample> {
        match self {
            Emitter::Area { shape, radiance } => {
                let g = &shapes[*shape as usize];
                let p_ref3 = Vector3::from(p_ref);
                // Spheres seen from outside: sample the cone of the visible cap.
                if let Geometry::Sphere(sp) = g {
                    let sphere = (Vec3::from(sp.center), sp.radius, sp.flip_normals);
                    let (c, inside) =
                        direction::toward_sphere(sphere, *radiance, p_ref3, (s.x, s.y));
                    if !inside {
                        let d = Vec3A::from(c.d);
                        return c.valid.then(|| EmitterSample {
                            d,
                            p: p_ref + d * c.dist,
                            pdf: c.pdf,
                            weight: c.weight.into(),
                            delta: false,
                        });
                    }
                }
                let (p, n) = g.sample_position(s);
                let a =
                    direction::toward_area_point((p.into(), n.into()), g.area(), *radiance, p_ref3);
                a.valid.then(|| EmitterSample {
                    d: a.d.into(),
                    p,
                    pdf: a.pdf,
                    weight: a.weight.into(),
                    delta: false,
                })
            }
            Emitter::Point {
                position,
                intensity,
            } => {
                let a = direction::toward_point((*position).into(), *intensity, p_ref.into());
                a.valid.then(|| EmitterSample {
                    d: a.d.into(),
                    p: *position,
                    pdf: a.pdf,
                    weight: a.weight.into(),
                    delta: true,
                })
            }
            Emitter::Spot(spot) => {
                let v = spot.position - p_ref;
                let dist2 = v.length_squared();
                let falloff = spot.falloff(-v);
                if dist2 == 0.0 || falloff <= 0.0 {
                    return None;
                }
                Some(EmitterSample {
                    d: v / dist2.sqrt(),
                    p: spot.position,
                    pdf: 1.0,
                    weight: spot.intensity * (falloff / dist2),
                    delta: true,
                })
            }
            Emitter::Constant { radiance } => {
                let d = square_to_uniform_sphere(s);
                let r = bsphere.radius.max((p_ref - bsphere.center).length());
                let pdf = 1.0 / (4.0 * PI);
                Some(EmitterSample {
                    d,
                    p: p_ref + d * (2.0 * r),
                    pdf,
                    weight: *radiance / pdf,
                    delta: false,
                })
            }
            Emitter::EnvMap(m) => {
                let (d, pdf, radiance) = m.sample(s)?;
                let r = bsphere.radius.max((p_ref - bsphere.center).length());
                Some(EmitterSample {
                    d,
                    p: p_ref + d * (2.0 * r),
                    pdf,
                    weight: radiance / pdf,
                    delta: false,
                })
            }
            Emitter::Directional {
                direction,
                irradiance,
            } => {
                let bounds = (Vec3::from(bsphere.center), bsphere.radius);
                let toward = -Vec3::from(*direction);
                let a = direction::along_direction(toward, *irradiance, bounds, p_ref.into());
                let d = Vec3A::from(a.d);
                Some(EmitterSample {
                    d,
                    p: p_ref + d * a.dist,
                    pdf: a.pdf,
                    weight: a.weight.into(),
                    delta: true,
                })
            }
        }
    }

    /// Radiance reaching a ray travelling along `d` that ends on this emitter: on an area
    /// light with (shading) normal `n`, only from its front side; for the environment,
    /// from every direction (`n` unused). Dirac lights are never hit.
    pub fn eval(&self, n: Vec3A, d: Vec3A) -> Vec3 {
        match self {
            Emitter::Area { radiance, .. } if n.dot(-d) > 0.0 => *radiance,
            Emitter::Constant { radiance } => *radiance,
            Emitter::EnvMap(m) => m.eval(d),
            _ => Vec3::ZERO,
        }
    }

    /// [`Emitter::eval`] and [`Emitter::pdf_direction`] of one ray's end, what the MIS
    /// weight of an emitter hit needs: the same values, an environment map's texel found
    /// once.
    pub fn eval_and_pdf(
        &self,
        p_ref: Vec3A,
        p: Vec3A,
        n: Vec3A,
        d: Vec3A,
        shapes: &[Geometry],
    ) -> (Vec3, f32) {
        match self {
            Emitter::EnvMap(m) => m.eval_and_pdf(d),
            _ => (self.eval(n, d), self.pdf_direction(p_ref, p, n, d, shapes)),
        }
    }

    /// Solid-angle pdf that `sample_direction` from `p_ref` produces the point `p` with
    /// (shading) normal `n` on this emitter (area lights), or direction `d` (environment).
    pub fn pdf_direction(
        &self,
        p_ref: Vec3A,
        p: Vec3A,
        n: Vec3A,
        d: Vec3A,
        shapes: &[Geometry],
    ) -> f32 {
        match self {
            Emitter::Area { shape, .. } => {
                let cos = n.dot(d);
                if cos >= 0.0 {
                    return 0.0;
                }
                if let Geometry::Sphere(sp) = &shapes[*shape as usize] {
                    if let Some(pdf) = sp.cone_pdf(p_ref) {
                        return pdf;
                    }
                }
                let dist2 = (p - p_ref).length_squared();
                let pdf = dist2 / (shapes[*shape as usize].area() * -cos);
                if pdf.is_finite() {
                    pdf
                } else {
                    0.0
                }
            }
            Emitter::Constant { .. } => 1.0 / (4.0 * PI),
            Emitter::EnvMap(m) => m.pdf(d),
            Emitter::Point { .. } | Emitter::Spot(_) | Emitter::Directional { .. } => 0.0,
        }
    }
}

#[cfg(test)]
mod spot_tests {
    use super::*;

    /// Full inside the beam, linear in angle to 0 at the cutoff, 0 outside and behind.
    #[test]
    fn spot_falloff_profile() {
        let spot = Spot::new(
            Vec3A::ZERO,
            Mat3A::IDENTITY,
            Vec3::ONE,
            30f32.to_radians(),
            20f32.to_radians(),
        );
        let at = |deg: f32| {
            let t = deg.to_radians();
            spot.falloff(Vec3A::new(t.sin(), 0.0, t.cos()))
        };
        assert_eq!(at(0.0), 1.0);
        assert_eq!(at(19.9), 1.0);
        assert!((at(25.0) - 0.5).abs() < 1e-3, "{}", at(25.0));
        assert!((at(27.5) - 0.25).abs() < 1e-3, "{}", at(27.5));
        assert_eq!(at(30.1), 0.0);
        assert_eq!(at(180.0), 0.0);
        // The light's frame: a spot turned to shine along +x.
        let turned = Spot::new(
            Vec3A::ZERO,
            Mat3A::from_rotation_y(-std::f32::consts::FRAC_PI_2),
            Vec3::ONE,
            30f32.to_radians(),
            20f32.to_radians(),
        );
        assert!((turned.falloff(Vec3A::X) - 1.0).abs() < 1e-6);
        assert_eq!(turned.falloff(Vec3A::Z), 0.0);
    }
}
