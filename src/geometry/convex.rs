//! A medium that fills one closed convex shape (a sphere, or a Mitsuba `cube`) with no
//! other surface inside: from any point in it, the first surface a ray meets is that
//! shape's, where the ray leaves it. Free flights in such a medium test that one shape
//! instead of the scene, and are not cast at all when shorter than the distance to it
//! (volpath). Shadow rays keep the scene's search: they go on beyond the shape.

use glam::Vec3A;

use super::accel::{cuboid_hit, Hit};
use super::cuboid::Cuboid;
use super::shape::Geometry;

/// The convex shape a medium fills.
#[derive(Clone, Debug)]
pub enum ConvexBoundary {
    /// A sphere (the shape's index).
    Sphere(u32),
    /// A cube, tested as a box. `leaf_valid`: its hits name triangles in the
    /// accelerator's copy (else `leaf` is `u32::MAX` and the mesh's own arrays are read).
    Box {
        cuboid: Box<Cuboid>,
        leaf_valid: bool,
    },
}

impl ConvexBoundary {
    /// The shape's index in the scene.
    pub fn shape(&self) -> u32 {
        match self {
            ConvexBoundary::Sphere(s) => *s,
            ConvexBoundary::Box { cuboid, .. } => cuboid.shape,
        }
    }

    /// A distance `p` (inside) lies from the shape's surface, a little short of it: no
    /// surface is closer.
    #[inline]
    pub fn clearance(&self, shapes: &[Geometry], p: Vec3A) -> f32 {
        let d = match self {
            ConvexBoundary::Sphere(si) => match &shapes[*si as usize] {
                Geometry::Sphere(s) => (s.radius - (p - s.center).length()).max(0.0),
                _ => 0.0,
            },
            ConvexBoundary::Box { cuboid, .. } => cuboid.distance_inside(p),
        };
        d * (1.0 - 1e-4)
    }

    /// Where the ray (o, d) from inside leaves the shape, if before `tmax`: the hit the
    /// scene's closest-hit query gives for it.
    #[inline]
    pub fn exit(&self, shapes: &[Geometry], o: Vec3A, d: Vec3A, tmax: f32) -> Option<Hit> {
        match self {
            ConvexBoundary::Sphere(si) => {
                let Geometry::Sphere(s) = &shapes[*si as usize] else {
                    return None;
                };
                let [a, b] = s.hits_within(o, d, tmax);
                a.or(b).map(|t| Hit::analytic(*si, t))
            }
            ConvexBoundary::Box { cuboid, leaf_valid } => cuboid.intersect(o, d, tmax).map(|h| {
                let hit = cuboid_hit(cuboid, h);
                Hit {
                    leaf: if *leaf_valid { hit.leaf } else { u32::MAX },
                    ..hit
                }
            }),
        }
    }
}
