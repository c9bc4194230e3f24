//! Rays, local frames, shapes and the acceleration structure.

pub mod accel;
pub mod clearance;
pub mod convex;
pub mod cuboid;
pub mod mesh;
pub mod ply;
pub mod serialized;
pub mod shape;

use glam::{Vec3A, Vec4};

use crate::simd::{Float, Vector3};

/// Mitsuba 3's ray epsilon for single precision (`math::RayEpsilon<float>` =
/// `Epsilon * 1500`, `Epsilon` = 2⁻²⁴): spawned rays are offset by this much, scaled by
/// the magnitude of the point, along the normal.
pub const RAY_EPSILON: f32 = 1500.0 / 16_777_216.0;
/// Shadow rays stop this much (relative) short of their target (`math::ShadowEpsilon`).
pub const SHADOW_EPSILON: f32 = RAY_EPSILON * 10.0;

#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub o: Vec3A,
    pub d: Vec3A,
    pub tmax: f32,
}

impl Ray {
    #[inline]
    pub fn new(o: Vec3A, d: Vec3A, tmax: f32) -> Self {
        Ray { o, d, tmax }
    }

    pub fn at(&self, t: f32) -> Vec3A {
        self.o + self.d * t
    }
}

/// Offsets `p` off a surface with normal `n`, to the side `d` points to (Mitsuba's
/// `Interaction::offset_p`): magnitude `(scale + max|p_i|) · RayEpsilon`.
///
/// Mitsuba's floor is `scale` = 1, which assumes a scene about one unit in size: in a
/// scene scaled down by 1e-3 it is 9% of an object's size, and in a dense medium the
/// ray skips that much of it on entering. The scene passes its own size
/// ([`crate::scene::Scene::offset_scale`]), so a scene scaled by s (and σ_t by 1/s)
/// renders the same image; for a unit-sized scene it is Mitsuba's offset.
///
/// One definition for a path and for lanes of paths (the one path's `Vec3A` callers go
/// through [`crate::scene::SurfaceInteraction::offset_p`]; it rounds as glam did).
#[inline(always)]
pub fn offset_point<F: Float>(
    p: Vector3<F>,
    n: Vector3<F>,
    d: Vector3<F>,
    scale: f32,
) -> Vector3<F> {
    let mag = offset_magnitude(p, scale);
    p.add(n.scale(F::select(n.dot(d).ge(F::zero()), mag, mag.negate())))
}

/// How far [`offset_point`] moves `p` off its surface.
#[inline(always)]
pub fn offset_magnitude<F: Float>(p: Vector3<F>, scale: f32) -> F {
    (F::of(scale as f64) + p.abs().max_element()) * F::of(RAY_EPSILON as f64)
}

/// Row `r` of an affine map (its 3×3 part's row, the translation's component in `w`)
/// applied to the point `p`: ((r_x p_x + r_y p_y) + r_z p_z) + r_w, the order glam's
/// transforms add in, for a path or lanes.
#[inline(always)]
pub fn affine_row_point<F: Float>(r: Vec4, p: Vector3<F>) -> F {
    affine_row_vector(r, p) + F::of(r.w as f64)
}

/// Row `r` of an affine map applied to the direction `d`: (r_x d_x + r_y d_y) + r_z d_z.
#[inline(always)]
pub fn affine_row_vector<F: Float>(r: Vec4, d: Vector3<F>) -> F {
    F::of(r.x as f64) * d.x + F::of(r.y as f64) * d.y + F::of(r.z as f64) * d.z
}

/// The affine map of rows `rows` applied to the point `p` (as glam's
/// `transform_point3a`).
#[inline(always)]
pub fn affine_point<F: Float>(rows: &[Vec4; 3], p: Vector3<F>) -> Vector3<F> {
    let [x, y, z] = rows.map(|r| affine_row_point(r, p));
    Vector3::new(x, y, z)
}

/// The affine map of rows `rows` applied to the direction `d` (as glam's
/// `transform_vector3a`).
#[inline(always)]
pub fn affine_vector<F: Float>(rows: &[Vec4; 3], d: Vector3<F>) -> Vector3<F> {
    let [x, y, z] = rows.map(|r| affine_row_vector(r, d));
    Vector3::new(x, y, z)
}

/// An orthonormal frame around `n` (Duff et al. 2017, as Mitsuba's `coordinate_system`).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub s: Vec3A,
    pub t: Vec3A,
    pub n: Vec3A,
}

/// The two tangents (s, t) of Duff et al.'s branchless orthonormal basis around the unit
/// `n` ("Building an Orthonormal Basis, Revisited", 2017, Listing 3), for a path or for
/// lanes of paths.
#[inline(always)]
pub fn coordinate_system<F: Float>(n: Vector3<F>) -> (Vector3<F>, Vector3<F>) {
    let one = F::one();
    let sign = one.copysign(n.z);
    let a = one.negate() / (sign + n.z);
    let b = n.x * n.y * a;
    let s = Vector3::new(one + sign * n.x * n.x * a, sign * b, sign.negate() * n.x);
    let t = Vector3::new(b, sign + n.y * n.y * a, n.y.negate());
    (s, t)
}

/// `local` (in the frame of [`coordinate_system`] around the unit `n`) in world space:
/// s x + t y + n z.
#[inline(always)]
pub fn to_world<F: Float>(n: Vector3<F>, local: Vector3<F>) -> Vector3<F> {
    let (s, t) = coordinate_system(n);
    s.scale(local.x).add(t.scale(local.y)).add(n.scale(local.z))
}

/// The direction at cos θ, sin θ from the unit `n` and azimuth 2π `u`.
#[inline(always)]
pub fn around<F: Float>(n: Vector3<F>, cos_theta: F, sin_theta: F, u: F) -> Vector3<F> {
    let (sin_phi, cos_phi) = (F::of((2.0 * std::f32::consts::PI) as f64) * u).sin_cos();
    to_world(
        n,
        Vector3::new(sin_theta * cos_phi, sin_theta * sin_phi, cos_theta),
    )
}

impl Frame {
    #[inline]
    pub fn new(n: Vec3A) -> Self {
        let (s, t) = coordinate_system(n.into());
        Frame {
            s: s.into(),
            t: t.into(),
            n,
        }
    }

    /// The frame around `n` whose first axis is the tangent `dp_du` made orthogonal to
    /// `n` (Mitsuba's `initialize_sh_frame`); `Frame::new(n)` when that vanishes.
    pub fn with_tangent(n: Vec3A, dp_du: Vec3A) -> Self {
        match (dp_du - n * n.dot(dp_du)).try_normalize() {
            Some(s) => Frame {
                s,
                t: n.cross(s),
                n,
            },
            None => Frame::new(n),
        }
    }

    #[inline]
    pub fn to_local(&self, v: Vec3A) -> Vec3A {
        Vec3A::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }

    #[inline]
    pub fn to_world(&self, v: Vec3A) -> Vec3A {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// Axis-aligned bounding box.
#[derive(Clone, Copy, Debug)]
pub struct Bounds {
    pub min: Vec3A,
    pub max: Vec3A,
}

impl Bounds {
    pub const EMPTY: Bounds = Bounds {
        min: Vec3A::splat(f32::INFINITY),
        max: Vec3A::splat(f32::NEG_INFINITY),
    };

    pub fn expand(&mut self, p: Vec3A) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    pub fn union(&self, o: &Bounds) -> Bounds {
        Bounds {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    /// A sphere around the box: its centre and half its diagonal.
    pub fn bounding_sphere(&self) -> (Vec3A, f32) {
        (
            (self.min + self.max) * 0.5,
            (self.max - self.min).length() * 0.5,
        )
    }

    /// Whether the two boxes share a point (touching counts).
    pub fn overlaps(&self, o: &Bounds) -> bool {
        self.min.cmple(o.max).all() && self.max.cmpge(o.min).all()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_is_orthonormal() {
        for n in [Vec3A::Z, -Vec3A::Z, Vec3A::new(0.3, -0.5, 0.8).normalize()] {
            let f = Frame::new(n);
            assert!(f.s.dot(f.t).abs() < 1e-6 && f.s.dot(n).abs() < 1e-6);
            assert!((f.s.cross(f.t) - n).length() < 1e-5);
            let v = Vec3A::new(0.1, 0.7, -0.2);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-6);
        }
    }
}
