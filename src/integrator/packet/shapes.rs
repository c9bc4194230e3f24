//! Ray tests in lanes against the packet scene's shapes: one ray per lane, each shape in
//! turn (a packet scene has a handful). No spawn offsets: a path inside a medium's
//! sphere or box meets only its far side, a path in empty space only those it enters
//! from outside, and the surface a path leaves is skipped (a ray leaving a plane or a convex
//! surface outwards cannot meet it again).

use glam::{Vec3, Vec4};
use wide::{CmpEq, CmpGe, CmpGt, CmpLe, CmpLt};

use super::lanes::{L, V3};
use super::scene::{MediumKind, PacketScene, SurfaceShape};
use crate::geometry::cuboid::slabs;
use crate::geometry::shape::plane_hit;
use crate::geometry::{affine_point, affine_row_point, affine_vector};
use crate::medium::Transmitted;
use crate::sampling::Pcg32;
use crate::scene::Scene;

/// A ray's quadratic against a sphere (unit direction): |o + t d − c|² = r² is
/// t² + 2bt + c = 0 with b = (o − c)·d and c = |o − c|² − r².
pub struct SphereRoots {
    b: L,
    c: L,
    disc: L,
    root: L,
}

impl SphereRoots {
    #[inline(always)]
    pub fn new(o: V3, d: V3, center: Vec3, radius2: f32) -> SphereRoots {
        let oc = o.sub(V3::splat(center));
        let b = oc.dot(d);
        let c = oc.dot(oc) - L::splat(radius2);
        let disc = b * b - c;
        SphereRoots {
            b,
            c,
            disc,
            root: disc.max(L::ZERO).sqrt(),
        }
    }

    /// From inside (c ≤ 0): the far root −b + √disc, written −c / (b + √disc) where
    /// b > 0 (no cancellation); never below 0.
    #[inline(always)]
    pub fn exit(&self) -> L {
        let (b, c, root) = (self.b, self.c, self.root);
        b.cmp_le(L::ZERO)
            .blend(root - b, -c / (b + root))
            .max(L::ZERO)
    }

    /// From outside: where the ray enters (c > 0, heading in: b < 0, and not missing),
    /// the near root c / (−b + √disc) and the far one −b + √disc.
    #[inline(always)]
    pub fn entry(&self) -> (L, L, L) {
        let (b, c, root) = (self.b, self.c, self.root);
        let enters = b.cmp_lt(L::ZERO) & c.cmp_gt(L::ZERO) & self.disc.cmp_gt(L::ZERO);
        (enters, c / (root - b), root - b)
    }
}

/// A ray against a medium's shape: where it leaves it from inside, and whether and
/// where it enters it from outside and leaves again.
pub struct MediumSpan {
    /// From inside: the distance to the boundary (never below 0).
    pub exit: L,
    /// From outside: the lanes whose ray enters, at `near`, leaving at `far`.
    pub enters: L,
    pub near: L,
    pub far: L,
}

impl MediumSpan {
    #[inline(always)]
    pub fn new(kind: &MediumKind, o: V3, d: V3) -> MediumSpan {
        match kind {
            MediumKind::Sphere { center, radius2 } => {
                let roots = SphereRoots::new(o, d, *center, *radius2);
                let (enters, near, far) = roots.entry();
                MediumSpan {
                    exit: roots.exit(),
                    enters,
                    near,
                    far,
                }
            }
            MediumKind::Box { rows } => {
                // The slab test (`geometry::cuboid::slabs`).
                let s = slabs(affine_point(rows, o), affine_vector(rows, d));
                MediumSpan {
                    exit: s.t_far.max(L::ZERO),
                    enters: s.t_near.cmp_gt(L::ZERO) & s.t_near.cmp_le(s.t_far),
                    near: s.t_near,
                    far: s.t_far,
                }
            }
        }
    }
}

/// The outward normal of a medium's shape at its points `p`.
#[inline(always)]
pub fn medium_normal(kind: &MediumKind, p: V3) -> V3 {
    match kind {
        MediumKind::Sphere { center, radius2 } => p
            .sub(V3::splat(*center))
            .scale(L::splat(1.0 / radius2.sqrt())),
        MediumKind::Box { rows } => box_normal(rows, p),
    }
}

/// The outward normal of the box `rows` (the map to its [-1, 1]³) at its points `p`:
/// that of the face whose coordinate is ±1 there (the largest in magnitude).
#[inline(always)]
fn box_normal(rows: &[Vec4; 3], p: V3) -> V3 {
    let [x, y, z] = rows.map(|r| affine_row_point(r, p));
    let (ax, ay, az) = (x.abs(), y.abs(), z.abs());
    let on_x = ax.cmp_ge(ay) & ax.cmp_ge(az);
    let on_y = !on_x & ay.cmp_ge(az);
    // The face's normal is the gradient of its coordinate (a row of the map), signed
    // by the side.
    let grad = |r: Vec4| V3::splat(r.truncate());
    let g = grad(rows[2])
        .select(on_y, grad(rows[1]))
        .select(on_x, grad(rows[0]));
    let side = on_x.blend(x, on_y.blend(y, z));
    let g = g.scale(L::ONE.copysign(side));
    g.scale(L::ONE / g.dot(g).sqrt())
}

/// Where the ray meets surface `k` from its origin (not the surface it is on: `skip`):
/// (mask, t).
#[inline(always)]
pub fn surface_hit(ps: &PacketScene, k: usize, o: V3, d: V3, skip: L) -> (L, L) {
    let not_skipped = !skip.cmp_eq(L::splat(k as f32));
    let (hit, t) = match &ps.surfaces[k].shape {
        SurfaceShape::Sphere { center, radius2 } => {
            let (enters, near, _) = SphereRoots::new(o, d, *center, *radius2).entry();
            (enters, near)
        }
        SurfaceShape::Planar { rows, disk, .. } => {
            let (ol, dl) = (affine_point(rows, o), affine_vector(rows, d));
            plane_hit(ol, dl, *disk, L::splat(f32::INFINITY))
        }
        SurfaceShape::Box { rows } => {
            let span = MediumSpan::new(&MediumKind::Box { rows: *rows }, o, d);
            (span.enters, span.near)
        }
    };
    (hit & not_skipped, t)
}

/// The outward normal of surface `k` at its points `p`.
#[inline(always)]
pub fn surface_normal(ps: &PacketScene, k: usize, p: V3) -> V3 {
    match &ps.surfaces[k].shape {
        SurfaceShape::Sphere { center, radius2 } => p
            .sub(V3::splat(*center))
            .scale(L::splat(1.0 / radius2.sqrt())),
        SurfaceShape::Planar { normal, .. } => V3::splat(*normal),
        SurfaceShape::Box { rows } => box_normal(rows, p),
    }
}

/// The transmittance of shadow rays from `o` along unit `d` over `dist`, the origin in
/// medium shape `inside` (−1: empty space) and on surface `skip` (−1: none), for the
/// lanes of `mask`: e^{−σ_t ℓ} for the length ℓ of the ray in each homogeneous medium,
/// ratio tracking's estimate in a heterogeneous one (drawing from `rngs`), 0 where a
/// surface or a dielectric boundary blocks it; with ∂ ln T in the extinction of medium
/// `extinction` where it is differentiated.
#[inline(always)]
pub fn shadow_transmittance(
    scene: &Scene,
    ps: &PacketScene,
    (o, d, dist): (V3, V3, L),
    (inside, skip): (L, L),
    mask: L,
    extinction: Option<u32>,
    rngs: &mut [Pcg32],
) -> Transmitted<L> {
    let mut blocked = !mask;
    for k in 0..ps.surfaces.len() {
        let (hit, t) = surface_hit(ps, k, o, d, skip);
        blocked |= hit & t.cmp_lt(dist);
    }
    let mut out = Transmitted::clear();
    for (i, m) in ps.media_shapes.iter().enumerate() {
        let span = MediumSpan::new(&m.kind, o, d);
        let from_inside = inside.cmp_eq(L::splat(i as f32));
        if m.dielectric.is_some() {
            // A dielectric boundary blocks shadow rays (it is no null surface).
            blocked |= from_inside | (span.enters & span.near.cmp_lt(dist));
            continue;
        }
        let from_outside = span.enters & span.near.cmp_lt(dist);
        let start = from_inside.blend(L::ZERO, span.near);
        let end = from_inside.blend(span.exit, span.far).min(dist);
        let through = !blocked & (from_inside | from_outside);
        let medium = &scene.media[m.medium as usize];
        let chosen = extinction == Some(m.medium);
        let seg = medium.segment_transmittance((o, d), (start, end), through, chosen, rngs);
        out = out.then(seg);
    }
    out.tr = out.tr.select(blocked, V3::splat(Vec3::ZERO));
    out
}
