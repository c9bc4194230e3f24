//! Coincident surfaces and media: a null medium boundary with a surface lying in it,
//! as a box of milk resting on a table (the box's bottom face in the table's top).
//!
//! A ray in the medium meets the two at one distance, up to rounding, and which hit a
//! renderer returns is an accident of its traversal. When the boundary wins, the ray
//! leaves the medium there and is spawned just beyond it, past the table's surface: the
//! light the table should have reflected back into the medium is lost (Mitsuba 3 loses
//! it, in a band along the contact). mediareg lets the surface win: where a null
//! boundary and a surface lie within the spawn offset of each other, the surface is the
//! hit, so the ray reflects at the table and stays in the medium (a surface that is no
//! medium boundary keeps the ray's medium). The image is that of the same box without
//! its bottom face, closed by the table, which both renderers agree on.
//!
//! Only a scene with such a contact pays: [`tied_boundaries`] finds the boundaries at
//! load, and only hits on the triangles found tied look for a surface at the same place.

use glam::Vec3A;
use rayon::prelude::*;

use super::{Scene, ShapeInfo, SurfaceInteraction};
use crate::bsdf::Bsdf;
use crate::geometry::accel::Accel;
use crate::geometry::shape::Geometry;
use crate::geometry::{offset_magnitude, Bounds};

/// Surfaces closer than this (along the normal) to a point `p` count as coincident:
/// twice the offset a spawned ray takes ([`crate::geometry::offset_point`]), the
/// distance below which spawning cannot tell the two apart.
pub fn tie_distance(p: Vec3A, offset_scale: f32) -> f32 {
    2.0 * offset_magnitude(p.into(), offset_scale)
}

/// Whether shape `i` is a medium boundary that light passes (a `null` BSDF with an
/// interior or exterior medium).
fn is_null_boundary(info: &ShapeInfo, bsdfs: &[Bsdf]) -> bool {
    (info.interior.is_some() || info.exterior.is_some())
        && matches!(bsdfs[info.bsdf as usize], Bsdf::Null)
}

fn is_surface(info: &ShapeInfo, bsdfs: &[Bsdf]) -> bool {
    !matches!(bsdfs[info.bsdf as usize], Bsdf::Null)
}

/// Where a shape's hits may be tied with a surface.
#[derive(Clone, Debug, PartialEq)]
pub enum Ties {
    /// Nowhere (no null boundary, or no surface in it).
    None,
    /// Anywhere (a rectangle or disk with a surface in its plane).
    All,
    /// On these triangles of a mesh (a bit per triangle): the few that touch, so the rest
    /// of a large mesh resting on a floor pays nothing.
    Triangles(Vec<u64>),
}

impl Ties {
    /// Whether a hit on primitive `prim` (a triangle, or 0) may be tied.
    #[inline]
    pub fn at(&self, prim: u32) -> bool {
        match self {
            Ties::None => false,
            Ties::All => true,
            Ties::Triangles(bits) => bits[(prim / 64) as usize] & (1 << (prim % 64)) != 0,
        }
    }
}

/// Per shape: where it is a null medium boundary with a surface (a shape with a
/// non-null BSDF) coincident with it. Empty when no shape is.
///
/// Tested at sample points of the boundary (each triangle's centroid and three points
/// towards its corners; five points of a rectangle or disk) whose box meets a surface's
/// box: a short cast along the normal through the point, against surfaces only. A
/// sphere meets a plane in a point, never in a patch: spheres are not tested.
pub fn tied_boundaries(
    geometries: &[Geometry],
    shapes: &[ShapeInfo],
    bsdfs: &[Bsdf],
    accel: &Accel,
    offset_scale: f32,
) -> Vec<Ties> {
    let surfaces: Vec<Bounds> = shapes
        .iter()
        .zip(geometries)
        .filter(|(s, _)| is_surface(s, bsdfs))
        .map(|(_, g)| g.bounds())
        .collect();
    let near = |b: &Bounds| {
        let pad = Vec3A::splat(tie_distance(b.max.abs().max(b.min.abs()), offset_scale));
        let padded = Bounds {
            min: b.min - pad,
            max: b.max + pad,
        };
        surfaces.iter().any(|s| s.overlaps(&padded))
    };
    let touches = |p: Vec3A, n: Vec3A| {
        let w = tie_distance(p, offset_scale);
        accel
            .intersect_where(geometries, p + n * w, -n, 2.0 * w, |s| {
                is_surface(&shapes[s as usize], bsdfs)
            })
            .is_some()
    };
    let ties: Vec<Ties> = (0..shapes.len())
        .map(|i| {
            if !is_null_boundary(&shapes[i], bsdfs) || !near(&geometries[i].bounds()) {
                return Ties::None;
            }
            match &geometries[i] {
                Geometry::Mesh(m) => {
                    let tied: Vec<u32> = (0..m.triangles.len() as u32)
                        .into_par_iter()
                        .filter(|&t| {
                            let v = m.vertices(t);
                            let mut b = Bounds::EMPTY;
                            v.iter().for_each(|&p| b.expand(p));
                            let Some(n) = (v[1] - v[0]).cross(v[2] - v[0]).try_normalize() else {
                                return false;
                            };
                            let c = (v[0] + v[1] + v[2]) / 3.0;
                            near(&b)
                                && (touches(c, n)
                                    || v.iter().any(|&p| touches(c + (p - c) * 0.8, n)))
                        })
                        .collect();
                    if tied.is_empty() {
                        return Ties::None;
                    }
                    let mut bits = vec![0u64; m.triangles.len().div_ceil(64)];
                    for t in tied {
                        bits[(t / 64) as usize] |= 1 << (t % 64);
                    }
                    Ties::Triangles(bits)
                }
                Geometry::Planar(pl) => {
                    let points = [
                        (0.0, 0.0),
                        (0.5, 0.5),
                        (-0.5, 0.5),
                        (0.5, -0.5),
                        (-0.5, -0.5),
                    ];
                    let tied = points.iter().any(|&(x, y)| {
                        touches(
                            pl.to_world.transform_point3a(Vec3A::new(x, y, 0.0)),
                            pl.normal,
                        )
                    });
                    if tied {
                        Ties::All
                    } else {
                        Ties::None
                    }
                }
                Geometry::Sphere(_) => Ties::None,
            }
        })
        .collect();
    if ties.iter().any(|t| *t != Ties::None) {
        ties
    } else {
        Vec::new()
    }
}

impl Scene {
    /// `si`, the hit of `o + t d` on a null boundary with a surface somewhere in it, or
    /// the surface coincident with it there (see the module's note).
    #[cold]
    pub(super) fn surface_in_boundary(
        &self,
        o: Vec3A,
        d: Vec3A,
        si: SurfaceInteraction,
    ) -> SurfaceInteraction {
        // The tie distance along the ray; a grazing ray's is capped.
        let w = tie_distance(si.p, self.offset_scale) / d.dot(si.n).abs().max(1e-2);
        let start = (si.t - w).max(0.0);
        let surface =
            self.accel
                .intersect_where(&self.geometries, o + d * start, d, si.t + w - start, |s| {
                    is_surface(&self.shapes[s as usize], &self.bsdfs)
                });
        match surface {
            Some(mut hit) => {
                hit.t += start;
                self.interaction(o, d, &hit)
            }
            None => si,
        }
    }
}
