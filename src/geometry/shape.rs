//! Mitsuba's built-in analytic shapes (`sphere`, `rectangle`, `disk`) and the shape enum
//! the renderer works with. `cube` is a triangle mesh, as in Mitsuba 3.

use glam::{Mat4, Vec2, Vec3A};

use super::mesh::TriangleMesh;
use super::Bounds;

/// Mitsuba's `sphere`: center + radius (after `to_world`, which must be a similarity).
#[derive(Clone, Debug)]
pub struct Sphere {
    pub center: Vec3A,
    pub radius: f32,
    pub flip_normals: bool,
}

/// Mitsuba's `rectangle` ([-1, 1]² in the z = 0 plane, normal +z) and `disk` (unit disk in
/// z = 0, normal +z), each placed by an affine `to_world`.
#[derive(Clone, Debug)]
pub struct Planar {
    pub to_world: Mat4,
    pub to_local: Mat4,
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
        Planar {
            to_world,
            to_local: to_world.inverse(),
            normal,
            area,
            is_disk,
        }
    }

    #[inline]
    pub fn intersect(&self, o: Vec3A, d: Vec3A, tmax: f32) -> Option<f32> {
        let ol = self.to_local.transform_point3a(o);
        let dl = self.to_local.transform_vector3a(d);
        if dl.z == 0.0 {
            return None;
        }
        let t = -ol.z / dl.z;
        if !(t > 0.0 && t < tmax) {
            return None;
        }
        let p = ol + dl * t;
        let inside = if self.is_disk {
            p.x * p.x + p.y * p.y <= 1.0
        } else {
            p.x.abs() <= 1.0 && p.y.abs() <= 1.0
        };
        inside.then_some(t)
    }

    pub fn sample_position(&self, s: Vec2) -> Vec3A {
        let local = if self.is_disk {
            let (x, y) = square_to_uniform_disk_concentric(s);
            Vec3A::new(x, y, 0.0)
        } else {
            Vec3A::new(2.0 * s.x - 1.0, 2.0 * s.y - 1.0, 0.0)
        };
        self.to_world.transform_point3a(local)
    }

    pub fn bounds(&self) -> Bounds {
        let mut b = Bounds::EMPTY;
        for (x, y) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            b.expand(self.to_world.transform_point3a(Vec3A::new(x, y, 0.0)));
        }
        b
    }
}

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

impl Sphere {
    /// Ray–sphere intersection in double precision (as Mitsuba does), nearest t > 0.
    #[inline]
    pub fn intersect(&self, o: Vec3A, d: Vec3A, tmax: f32) -> Option<f32> {
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
        let (mut t0, mut t1) = (q / a, c / q);
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
        }
        let tmax = tmax as f64;
        if t0 > 0.0 && t0 < tmax {
            Some(t0 as f32)
        } else if t1 > 0.0 && t1 < tmax {
            Some(t1 as f32)
        } else {
            None
        }
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

    pub fn bounds(&self) -> Bounds {
        Bounds {
            min: self.center - Vec3A::splat(self.radius),
            max: self.center + Vec3A::splat(self.radius),
        }
    }
}

impl Geometry {
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
