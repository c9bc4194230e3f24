//! Mitsuba's built-in analytic shapes (`sphere`, `rectangle`, `disk`) and the shape enum
//! the renderer works with. `cube` is a triangle mesh, as in Mitsuba 3.

use glam::{Mat3A, Mat4, Vec2, Vec3A, Vec4};

use super::mesh::TriangleMesh;
use super::Bounds;
use crate::sampling::warp::{square_to_uniform_disk_concentric, square_to_uniform_sphere};
use crate::simd::{Float, Vector3};

/// Mitsuba's `sphere`: center + radius (after `to_world`, which must be a similarity).
#[derive(Clone, Debug)]
pub struct Sphere {
    pub center: Vec3A,
    pub radius: f32,
    pub flip_normals: bool,
    /// The rotation (or reflection) part of `to_world`: the sphere's own axes, which
    /// orient its parameterisation (∂p/∂u).
    pub axes: Mat3A,
}

/// Mitsuba's `rectangle` ([-1, 1]² in the z = 0 plane, normal +z) and `disk` (unit disk in
/// z = 0, normal +z), each placed by an affine `to_world`.
#[derive(Clone, Debug)]
pub struct Planar {
    pub to_world: Mat4,
    pub to_local: Mat4,
    /// `to_world`'s first three rows, for sampling ([`Planar::rectangle_point`]).
    to_world_rows: [Vec4; 3],
    pub normal: Vec3A,
    pub area: f32,
    pub is_disk: bool,
}

#[derive(Clone, Debug)]
pub enum Geometry {
    Mesh(TriangleMesh),
    Sphere(Sphere),
    Planar(Planar),
}

impl Planar {
    pub fn new(to_world: Mat4, flip_normals: bool, is_disk: bool) -> Self {
        let dx = to_world.transform_vector3a(Vec3A::X);
        let dy = to_world.transform_vector3a(Vec3A::Y);
        let mut normal = to_world
            .inverse()
            .transpose()
            .transform_vector3a(Vec3A::Z)
            .normalize_or_zero();
        if flip_normals {
            normal = -normal;
        }
        // Area of the image of the local unit square is |dx × dy|.
        let jac = dx.cross(dy).length();
        let area = if is_disk {
            std::f32::consts::PI * jac
        } else {
            4.0 * jac
        };
        let to_local = to_world.inverse();
        Planar {
            to_world,
            to_local,
            to_world_rows: [to_world.row(0), to_world.row(1), to_world.row(2)],
            normal,
            area,
            is_disk,
        }
    }

    #[inline]
    pub fn intersect(&self, o: Vec3A, d: Vec3A, tmax: f32) -> Option<f32> {
        let ol = self.to_local.transform_point3a(o);
        let dl = self.to_local.transform_vector3a(d);
        let (hit, t) = plane_hit(ol.into(), dl.into(), self.is_disk, tmax);
        hit.then_some(t)
    }

    pub fn sample_position(&self, s: Vec2) -> Vec3A {
        if !self.is_disk {
            return self.rectangle_point(s.x, s.y).into();
        }
        let (x, y) = square_to_uniform_disk_concentric(s);
        self.to_world.transform_point3a(Vec3A::new(x, y, 0.0))
    }

    /// A rectangle's point at (2u₁ − 1, 2u₂ − 1) of its [-1, 1]² (uniform by area for
    /// uniform draws), for a path or lanes: `to_world` applied as glam applies it.
    #[inline(always)]
    pub fn rectangle_point<F: Float>(&self, u1: F, u2: F) -> Vector3<F> {
        let (two, one) = (F::of(2.0), F::one());
        let (x, y) = (two * u1 - one, two * u2 - one);
        // The local z = 0 drops the third column (its product is a signed zero).
        let [px, py, pz] = self
            .to_world_rows
            .map(|r| F::of(r.x as f64) * x + F::of(r.y as f64) * y + F::of(r.w as f64));
        Vector3::new(px, py, pz)
    }

    pub fn bounds(&self) -> Bounds {
        let mut b = Bounds::EMPTY;
        for (x, y) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            b.expand(self.to_world.transform_point3a(Vec3A::new(x, y, 0.0)));
        }
        b
    }
}

/// Where a ray meets a rectangle or disk with t in (0, tmax), given in the shape's own
/// space (`ol + t dl`; the shape in its z = 0 plane, within [-1, 1]² or the unit disk):
/// (whether it does, t), for a path or lanes. A ray parallel to the plane gives t = ±∞
/// or NaN, which is no hit. (One path maps the ray with glam, lanes with
/// `geometry::affine_point`/`affine_vector`: the same bits.)
#[inline(always)]
pub fn plane_hit<F: Float>(ol: Vector3<F>, dl: Vector3<F>, disk: bool, tmax: F) -> (F::Mask, F) {
    let t = ol.z.negate() / dl.z;
    let ahead = t.gt(F::zero()) & t.lt(tmax);
    if !F::any(ahead) {
        return (ahead, t);
    }
    let (x, y) = (ol.x + dl.x * t, ol.y + dl.y * t);
    let one = F::one();
    let inside = match disk {
        true => (x * x + y * y).le(one),
        false => x.abs().le(one) & y.abs().le(one),
    };
    (inside & ahead, t)
}

/// Uniform pdf over a cone of half-angle θ_max.
#[inline(always)]
fn cone_pdf<F: Float>(cos_max: F) -> F {
    F::one() / (F::of((2.0 * std::f32::consts::PI) as f64) * (F::one() - cos_max))
}

/// A direction toward a sphere from [`sample_sphere_cone`], for a path or lanes of paths.
pub struct ConeDirection<F: Float> {
    /// Unit direction from the reference point.
    pub d: Vector3<F>,
    /// Distance to where it meets the sphere.
    pub dist: F,
    /// Solid-angle pdf.
    pub pdf: F,
    /// Where the reference point is inside the sphere (deeper than the ray epsilon):
    /// no cone, the rest is meaningless there.
    pub inside: F::Mask,
}

/// The cone a sphere of `radius` fills, seen from a point `c` away from its centre.
struct VisibleCone<F: Float> {
    /// |c|².
    dc2: F,
    /// sin² θ_max = r² / |c|², and cos θ_max.
    sin2_max: F,
    cos_max: F,
    /// Where the point is inside the sphere (deeper than the ray epsilon): no cone.
    inside: F::Mask,
}

#[inline(always)]
fn visible_cone<F: Float>(c: Vector3<F>, radius: f32) -> VisibleCone<F> {
    let dc2 = c.dot(c);
    // Mitsuba shrinks the radius by RayEpsilon: points on the surface count as outside
    // (a vertex on the light sees the hemisphere it fills).
    let r_adj = radius * (1.0 - super::RAY_EPSILON);
    let sin2_max = F::of((radius * radius) as f64) / dc2;
    VisibleCone {
        dc2,
        sin2_max,
        cos_max: (F::one() - sin2_max).max(F::zero()).sqrt(),
        inside: dc2.le(F::of((r_adj * r_adj) as f64)),
    }
}

/// A direction uniform in the cone of the cap of the sphere (`center`, `radius`) visible
/// from `p`, pdf 1 / (2π (1 − cos θ_max)), and the distance to the nearer root,
///   t = (|c|² − r²) / (|c| cos θ + √(r² − |c|² sin² θ)),   c = center − p,
/// the product of the roots over the larger one, so that nothing cancels. Small cones
/// (sin² θ_max below Mitsuba's 1.5° threshold) take sin² θ = sin² θ_max u1 instead of
/// 1 − cos² θ (the Taylor expansion, as Mitsuba).
///
/// Mitsuba draws the point on the sphere (by its angle at the centre) and the
/// direction toward it after; here the direction comes first and the point is where
/// it meets the sphere: the same distribution, with fewer square roots and
/// divisions one after the other (this was 15% of the render time of a fog lit by a
/// sphere).
#[inline(always)]
pub fn sample_sphere_cone<F: Float>(
    center: Vector3<F>,
    radius: f32,
    p: Vector3<F>,
    u1: F,
    u2: F,
) -> ConeDirection<F> {
    let (zero, one) = (F::zero(), F::one());
    let c = center.sub(p);
    let VisibleCone {
        dc2,
        sin2_max,
        cos_max,
        inside,
    } = visible_cone(c, radius);
    let r2 = F::of((radius * radius) as f64);
    let wide_cone = sin2_max.gt(F::of(0.000_685_23f32 as f64));
    let cos_wide = (cos_max - one) * u1 + one;
    let sin2_small = sin2_max * u1;
    let cos_t = F::select(wide_cone, cos_wide, (one - sin2_small).sqrt());
    let sin2 = F::select(wide_cone, (one - cos_wide * cos_wide).max(zero), sin2_small);
    let dc_len = dc2.sqrt();
    let d = super::around(c.div(dc_len), cos_t, sin2.sqrt(), u2);
    let half_chord = (r2 - dc2 * sin2).max(zero).sqrt();
    let dist = (dc2 - r2) / (dc_len * cos_t + half_chord);
    ConeDirection {
        d,
        dist,
        pdf: cone_pdf(cos_max),
        inside,
    }
}

impl Sphere {
    /// Mitsuba's ∂p/∂u at `p` (up to its 2π length): the azimuthal direction
    /// (−y, x, 0) in the sphere's own frame; zero at the poles.
    pub fn dp_du(&self, p: Vec3A) -> Vec3A {
        let local = self.axes.transpose() * (p - self.center);
        self.axes * Vec3A::new(-local.y, local.x, 0.0)
    }

    /// Where the line `o + t d` meets the sphere, t0 ≤ t1, in double precision (as
    /// Mitsuba does); None if it misses.
    #[inline]
    fn roots(&self, o: Vec3A, d: Vec3A) -> Option<(f64, f64)> {
        let oc = (o - self.center).as_dvec3();
        let d = d.as_dvec3();
        let a = d.length_squared();
        let b = 2.0 * oc.dot(d);
        let r = self.radius as f64;
        let c = oc.length_squared() - r * r;
        let disc = b * b - 4.0 * a * c;
        if disc < 0.0 {
            return None;
        }
        let sq = disc.sqrt();
        // Numerically stable roots.
        let q = -0.5 * (b + sq.copysign(b));
        let (t0, t1) = (q / a, c / q);
        Some(if t0 > t1 { (t1, t0) } else { (t0, t1) })
    }

    /// Ray–sphere intersection, nearest t in (0, tmax).
    #[inline]
    pub fn intersect(&self, o: Vec3A, d: Vec3A, tmax: f32) -> Option<f32> {
        let [first, second] = self.hits_within(o, d, tmax);
        first.or(second)
    }

    /// Both hits of the ray with t in (0, tmax), nearest first (a ray meets a sphere at
    /// most twice): what a shadow ray through a `null` sphere crosses.
    #[inline]
    pub fn hits_within(&self, o: Vec3A, d: Vec3A, tmax: f32) -> [Option<f32>; 2] {
        let Some((t0, t1)) = self.roots(o, d) else {
            return [None, None];
        };
        let tmax = tmax as f64;
        let within = |t: f64| (t > 0.0 && t < tmax).then_some(t as f32);
        [within(t0), within(t1)]
    }

    pub fn normal_at(&self, p: Vec3A) -> Vec3A {
        let n = (p - self.center).normalize_or_zero();
        if self.flip_normals {
            -n
        } else {
            n
        }
    }

    pub fn area(&self) -> f32 {
        4.0 * std::f32::consts::PI * self.radius * self.radius
    }

    /// The pdf [`sample_sphere_cone`] gives any direction toward the sphere from `p_ref`,
    /// or `None` from inside.
    pub fn cone_pdf(&self, p_ref: Vec3A) -> Option<f32> {
        let cone = visible_cone(Vector3::from(self.center - p_ref), self.radius);
        (!cone.inside).then(|| cone_pdf(cone.cos_max))
    }

    pub fn bounds(&self) -> Bounds {
        Bounds {
            min: self.center - Vec3A::splat(self.radius),
            max: self.center + Vec3A::splat(self.radius),
        }
    }
}

impl Geometry {
    /// World-space bounding box.
    pub fn bounds(&self) -> Bounds {
        match self {
            Geometry::Mesh(m) => {
                let mut b = Bounds::EMPTY;
                for p in m.positions.iter() {
                    b.expand(*p);
                }
                b
            }
            Geometry::Sphere(s) => s.bounds(),
            Geometry::Planar(p) => p.bounds(),
        }
    }

    pub fn area(&self) -> f32 {
        match self {
            Geometry::Mesh(m) => m.total_area,
            Geometry::Sphere(s) => s.area(),
            Geometry::Planar(p) => p.area,
        }
    }

    /// A point uniformly distributed by area and its (shading) normal; pdf = 1 / area.
    pub fn sample_position(&self, s: Vec2) -> (Vec3A, Vec3A) {
        match self {
            Geometry::Mesh(m) => m.sample_position(s),
            Geometry::Sphere(sp) => {
                let p = sp.center + square_to_uniform_sphere(s) * sp.radius;
                (p, sp.normal_at(p))
            }
            Geometry::Planar(pl) => (pl.sample_position(s), pl.normal),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Cone samples hit the sphere where they say, and are uniform in the cone:
    /// the mean of cos(angle to the axis) is (1 + cos θ_max) / 2.
    #[test]
    fn sphere_cone_sampling_is_uniform_in_the_visible_cone() {
        let sp = Sphere {
            center: Vec3A::new(0.3, -0.2, 0.5),
            radius: 0.7,
            flip_normals: false,
            axes: Mat3A::IDENTITY,
        };
        for p_ref in [
            Vec3A::new(0.0, 0.0, 4.0),
            Vec3A::new(1.2, 0.1, 0.4),
            Vec3A::new(40.0, 3.0, -9.0),
        ] {
            let axis = (sp.center - p_ref).normalize();
            let cos_max =
                (1.0 - sp.radius * sp.radius / (sp.center - p_ref).length_squared()).sqrt();
            let n = 200;
            let mut mean = 0.0f64;
            for i in 0..n {
                for j in 0..n {
                    let s = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                    let c = sample_sphere_cone::<f32>(
                        sp.center.into(),
                        sp.radius,
                        p_ref.into(),
                        s.x,
                        s.y,
                    );
                    assert!(!c.inside);
                    let (pdf, d) = (c.pdf, Vec3A::from(c.d));
                    let p = p_ref + d * c.dist;
                    let nrm = (p - sp.center).normalize();
                    assert!((d.length() - 1.0).abs() < 1e-5, "a unit direction");
                    assert!(((p - sp.center).length() - sp.radius).abs() < 1e-5);
                    let t = sp
                        .intersect(p_ref, d, f32::MAX)
                        .expect("the sample must hit");
                    assert!((t - c.dist).abs() < 1e-4 * t, "hit at {t}, not {}", c.dist);
                    assert!(nrm.dot(d) < 1e-3, "a visible point faces the reference");
                    assert!((pdf - sp.cone_pdf(p_ref).unwrap()).abs() < 1e-3 * pdf);
                    mean += d.dot(axis) as f64;
                }
            }
            mean /= (n * n) as f64;
            let want = (1.0 + cos_max as f64) / 2.0;
            assert!((mean - want).abs() < 1e-4, "{mean} vs {want}");
        }
        assert!(sp.cone_pdf(sp.center).is_none(), "inside: no cone");
    }
}
