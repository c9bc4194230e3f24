//! What the accelerator answers: a closest hit, and the surfaces a shadow ray crosses.

use arrayvec::ArrayVec;

use crate::geometry::cuboid::{Cuboid, CuboidHit};

/// The closest hit of a ray: which shape and primitive, at which distance, and the
/// triangle barycentrics (zero for analytic shapes).
#[derive(Clone, Copy, Debug, Default)]
pub struct Hit {
    pub t: f32,
    pub shape: u32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
    /// The triangle's place in the accelerator's own copy ([`super::Accel::triangle_surface`]),
    /// `u32::MAX` for analytic shapes.
    pub leaf: u32,
    /// The triangle's geometric normal (p1 − p0) × (p2 − p0), not normalised, where the
    /// ray caster gives it with the hit (Embree); zero where it does not (then
    /// [`super::Accel::triangle_surface`] reads it from the accelerator's copy).
    pub ng: [f32; 3],
}

impl Hit {
    /// A hit of analytic shape `shape` at distance `t` (no triangle, no barycentrics).
    #[inline]
    pub fn analytic(shape: u32, t: f32) -> Hit {
        Hit {
            t,
            shape,
            prim: 0,
            u: 0.0,
            v: 0.0,
            leaf: u32::MAX,
            ng: [0.0; 3],
        }
    }
}

/// How a surface treats a shadow ray (see [`super::Accel::crossings`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShadowPass {
    /// Stops it (every BSDF but the two below).
    Blocks,
    /// Lets it through unchanged (`null`).
    Passes,
    /// Lets part of it through, by the angle (`thindielectric`).
    Partial,
}

/// The answer of [`super::Accel::crossings`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Crossings {
    Blocked,
    /// Every pass-through hit, in `out`.
    Found,
    /// The caller must cast one ray per crossing.
    Unsupported,
}

/// A surface a shadow ray crosses: where, which shape, and whether the ray crosses
/// along the surface's geometric normal (`d · n > 0`, `n` after `flip_normals`), all
/// it needs to know which medium lies beyond (Mitsuba's `target_medium`). The side is
/// read where the hit test has the surface at hand: no normal is looked up after.
#[derive(Clone, Copy, Debug)]
pub struct Crossing {
    pub t: f32,
    pub shape: u32,
    pub along_normal: bool,
}

/// Crossings one shadow traversal collects before it gives up (see
/// [`super::Accel::crossings`]).
pub const MAX_CROSSINGS: usize = 16;

/// Where [`super::Accel::crossings`] puts them. Its storage is not initialised: zeroing an
/// array of 16 for every search cost the medium cube 5% of its render time (about two
/// searches a sample, most of them finding one or two crossings).
pub type CrossingList = ArrayVec<Crossing, MAX_CROSSINGS>;

/// A cuboid's hit as the BVH would give it: the mesh triangle and its barycentrics.
#[inline(always)]
pub(in crate::geometry) fn cuboid_hit(c: &Cuboid, h: CuboidHit) -> Hit {
    Hit {
        t: h.t,
        shape: c.shape,
        prim: h.prim,
        u: h.u,
        v: h.v,
        leaf: h.leaf,
        ng: [0.0; 3],
    }
}
