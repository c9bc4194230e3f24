//! Mitsuba's `cube` as the accelerator tests it: one slab test against the box
//! [-1, 1]³ in the shape's own space instead of a BVH over its 12 triangles.
//!
//! The shape stays a triangle mesh (as in Mitsuba 3: its normals, texture
//! coordinates, area sampling and clearance are the mesh's). Only the hit search
//! changes, and a hit names the mesh triangle it lies on with its barycentrics, as a
//! BVH hit does, so everything after the search reads the same data.
//!
//! `to_world` is affine, so a ray `o + t d` maps to `o' + t d'` in the box's space with
//! the same `t`, and the box's faces are the planes `x_k = ±1`. Slab test (Kay & Kajiya
//! 1986): on axis `k` the ray is between the planes for `t` in
//! `[(−1 − o'_k) / d'_k, (1 − o'_k) / d'_k]` (ordered), and in the box on the
//! intersection of the three intervals `[t_near, t_far]`: it enters through the face of
//! the axis that sets `t_near` and leaves through the one that sets `t_far`.
//!
//! Barycentrics are affine in the face's own coordinates (affine maps keep them), so
//! each of a face's two triangles stores the map from the face point to its (u, v).

use glam::{Affine3A, Mat4, Vec3, Vec3A, Vec4};

use super::mesh::TriangleMesh;
use crate::simd::{Float, Vector3};

/// How far (in the box's own units) a vertex may lie from a corner of [-1, 1]³ for the
/// mesh to be tested as a box (else it is left to the BVH).
const CORNER_TOLERANCE: f32 = 1e-4;

/// One triangle of a face: which mesh triangle, and the affine map from the face point
/// (a, b) to its barycentrics: `u = u_map · (a, b, 1)`, `v = v_map · (a, b, 1)`.
#[derive(Clone, Copy, Debug)]
struct FaceTriangle {
    prim: u32,
    u_map: Vec3,
    v_map: Vec3,
}

impl FaceTriangle {
    #[inline]
    fn barycentrics(&self, a: f32, b: f32) -> (f32, f32) {
        let x = Vec3::new(a, b, 1.0);
        (self.u_map.dot(x), self.v_map.dot(x))
    }
}

/// A hit of a ray with a cuboid: its distance and the mesh triangle it lies on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CuboidHit {
    pub t: f32,
    pub prim: u32,
    pub leaf: u32,
    pub u: f32,
    pub v: f32,
}

#[derive(Clone, Debug)]
pub struct Cuboid {
    /// The shape's index in the scene.
    pub shape: u32,
    /// Where its triangles start in the accelerator's triangle copy (mesh triangle `i`
    /// at `first_leaf + i`): what a hit's `leaf` names.
    pub first_leaf: u32,
    to_local: Affine3A,
    /// Per axis k: 1 / |∇x'_k|, the world distance per unit of the box's coordinate k
    /// across its faces (see [`Cuboid::distance_inside`]).
    face_spacing: Vec3A,
    /// Per face `2k + (side > 0)` on axis `k`: its two triangles.
    faces: [[FaceTriangle; 2]; 6],
    /// Whether a ray leaving the box crosses along the triangles' geometric normals
    /// (after `flip_normals`; one entering then crosses against them): what a shadow
    /// ray needs of its crossings. None when the mesh's triangles face both ways.
    pub exit_along_normal: Option<bool>,
}

/// The face coordinates (a, b) of a point on a face of axis `k`: the next two axes.
#[inline]
fn face_coords(p: Vec3A, axis: usize) -> (f32, f32) {
    (p[(axis + 1) % 3], p[(axis + 2) % 3])
}

impl Cuboid {
    /// The box of `mesh`, Mitsuba's `cube` placed by `to_world`; None if the mesh is
    /// not the image of [-1, 1]³ with two triangles per face (then the BVH takes it).
    pub fn new(shape: u32, mesh: &TriangleMesh, to_world: &Mat4) -> Option<Cuboid> {
        let to_local = Affine3A::from_mat4(*to_world).inverse();
        if !to_local.is_finite() || mesh.triangles.len() != 12 {
            return None;
        }
        let local: Vec<Vec3A> = mesh
            .positions
            .iter()
            .map(|&p| to_local.transform_point3a(p))
            .collect();
        if local.iter().any(|p| {
            (p.abs() - Vec3A::ONE).abs().max_element() > CORNER_TOLERANCE || !p.is_finite()
        }) {
            return None;
        }
        let mut faces: [Vec<FaceTriangle>; 6] = Default::default();
        for (prim, tri) in mesh.triangles.iter().enumerate() {
            let q = tri.map(|i| local[i as usize].signum());
            // The face all three vertices lie on: an axis where their signs agree.
            let axis = (0..3).find(|&k| q[0][k] == q[1][k] && q[1][k] == q[2][k])?;
            let face = 2 * axis + (q[0][axis] > 0.0) as usize;
            let [q0, q1, q2] = q.map(|p| {
                let (a, b) = face_coords(p, axis);
                glam::Vec2::new(a, b)
            });
            // [u v]ᵀ = E⁻¹ (x − q0), E = [q1 − q0, q2 − q0].
            let inv = glam::Mat2::from_cols(q1 - q0, q2 - q0).inverse();
            if !inv.is_finite() {
                return None;
            }
            let (r0, r1) = (inv.row(0), inv.row(1));
            faces[face].push(FaceTriangle {
                prim: prim as u32,
                u_map: Vec3::new(r0.x, r0.y, -r0.dot(q0)),
                v_map: Vec3::new(r1.x, r1.y, -r1.dot(q0)),
            });
        }
        let faces = faces.map(|f| <[FaceTriangle; 2]>::try_from(f).ok());
        if faces.iter().any(Option::is_none) {
            return None;
        }
        // Each triangle faces out if its normal (p1 − p0) × (p2 − p0) points away from
        // the box's centre.
        let centre = Vec3A::from(to_world.transform_point3(Vec3::ZERO));
        let faces_out: Vec<bool> = (0..12)
            .map(|i| {
                let [p0, p1, p2] = mesh.vertices(i);
                (p1 - p0).cross(p2 - p0).dot((p0 + p1 + p2) / 3.0 - centre) > 0.0
            })
            .collect();
        let exit_along_normal = faces_out
            .iter()
            .all(|&o| o == faces_out[0])
            .then_some(faces_out[0] != mesh.flip_normals);
        let m = to_local.matrix3;
        let grad_len = (m.x_axis * m.x_axis + m.y_axis * m.y_axis + m.z_axis * m.z_axis).sqrt();
        Some(Cuboid {
            shape,
            first_leaf: 0,
            to_local,
            face_spacing: grad_len.recip(),
            faces: faces.map(Option::unwrap),
            exit_along_normal,
        })
    }

    /// The rows of the map to the box's [-1, 1]³ (`to_world`'s inverse), for lanes.
    pub fn rows(&self) -> [Vec4; 3] {
        affine_rows(&self.to_local)
    }

    /// The ray in the box's space, and where it is inside the box: (t_near, entry face,
    /// t_far, exit face), or None if its line misses the box.
    #[inline(always)]
    fn slabs(&self, o: Vec3A, d: Vec3A) -> Option<(Vec3A, Vec3A, f32, usize, f32, usize)> {
        let ol = self.to_local.transform_point3a(o);
        let dl = self.to_local.transform_vector3a(d);
        let s = slabs::<f32>(ol.into(), dl.into());
        if s.t_near > s.t_far {
            return None;
        }
        let (near_axis, far_axis) = (s.near_axis as usize, s.far_axis as usize);
        // Entering a face on axis k through its side facing the ray: −1 if d'_k > 0.
        let near_face = 2 * near_axis + (dl[near_axis] < 0.0) as usize;
        let far_face = 2 * far_axis + (dl[far_axis] > 0.0) as usize;
        Some((ol, dl, s.t_near, near_face, s.t_far, far_face))
    }

    /// The hit at `t` on `face` of the ray (ol, dl) in the box's space: the face
    /// triangle it lies in (the nearer one, by barycentrics, on their shared edge).
    #[inline]
    fn hit_on(&self, ol: Vec3A, dl: Vec3A, t: f32, face: usize) -> CuboidHit {
        let (a, b) = face_coords(ol + dl * t, face / 2);
        let [f0, f1] = &self.faces[face];
        let (u0, v0) = f0.barycentrics(a, b);
        let outside0 = (-u0).max(-v0).max(u0 + v0 - 1.0);
        let (f, u, v) = if outside0 <= 0.0 {
            (f0, u0, v0)
        } else {
            let (u1, v1) = f1.barycentrics(a, b);
            let outside1 = (-u1).max(-v1).max(u1 + v1 - 1.0);
            if outside1 <= outside0 {
                (f1, u1, v1)
            } else {
                (f0, u0, v0)
            }
        };
        // Rounding may put a point on a face's edge just outside both: clamp it in.
        let (u, v) = (u.max(0.0), v.max(0.0));
        let s = (u + v).max(1.0);
        CuboidHit {
            t,
            prim: f.prim,
            leaf: self.first_leaf + f.prim,
            u: u / s,
            v: v / s,
        }
    }

    /// The nearest hit with 0 < t < tmax.
    #[inline]
    pub fn intersect(&self, o: Vec3A, d: Vec3A, tmax: f32) -> Option<CuboidHit> {
        let (ol, dl, t_near, near_face, t_far, far_face) = self.slabs(o, d)?;
        if t_near > 0.0 {
            (t_near < tmax).then(|| self.hit_on(ol, dl, t_near, near_face))
        } else {
            (t_far > 0.0 && t_far < tmax).then(|| self.hit_on(ol, dl, t_far, far_face))
        }
    }

    /// The distance from `p` inside the box to its surface (0 outside): the nearest of
    /// the face planes. Plane `x'_k = ±1` lies `(1 − |x'_k|) / |∇x'_k|` away, where
    /// `∇x'_k` is row k of the map to the box's space (affine maps keep planes).
    #[inline]
    pub fn distance_inside(&self, p: Vec3A) -> f32 {
        let l = self.to_local.transform_point3a(p);
        ((Vec3A::ONE - l.abs()) * self.face_spacing)
            .min_element()
            .max(0.0)
    }

    /// Both hits with 0 < t < tmax (entry, exit), nearest first.
    #[inline]
    pub fn hits_within(&self, o: Vec3A, d: Vec3A, tmax: f32) -> [Option<CuboidHit>; 2] {
        let Some((ol, dl, t_near, near_face, t_far, far_face)) = self.slabs(o, d) else {
            return [None, None];
        };
        let within = |t: f32| t > 0.0 && t < tmax;
        [
            within(t_near).then(|| self.hit_on(ol, dl, t_near, near_face)),
            within(t_far).then(|| self.hit_on(ol, dl, t_far, far_face)),
        ]
    }

    /// The entry and exit distances within 0 < t < tmax (each None where outside).
    #[inline]
    pub fn span_within(&self, o: Vec3A, d: Vec3A, tmax: f32) -> [Option<f32>; 2] {
        let Some((_, _, t_near, _, t_far, _)) = self.slabs(o, d) else {
            return [None, None];
        };
        let within = |t: f32| (t > 0.0 && t < tmax).then_some(t);
        [within(t_near), within(t_far)]
    }

    /// Whether anything of the box lies on the ray for 0 < t < tmax.
    #[inline]
    pub fn hit_within(&self, o: Vec3A, d: Vec3A, tmax: f32) -> bool {
        self.slabs(o, d).is_some_and(|(_, _, t_near, _, t_far, _)| {
            (t_near > 0.0 && t_near < tmax) || (t_far > 0.0 && t_far < tmax)
        })
    }
}

/// The rows of an affine map: its 3×3 part's, with the translation's component in w.
pub fn affine_rows(m: &Affine3A) -> [Vec4; 3] {
    std::array::from_fn(|k| m.matrix3.row(k).extend(m.translation[k]))
}

/// A ray's slab test against the box [-1, 1]³, for a path or lanes.
pub struct Slabs<F: Float> {
    /// Where the line enters the intersection of the three slabs and leaves it (t_near >
    /// t_far where it misses the box), and the axes whose faces those are.
    pub t_near: F,
    pub t_far: F,
    pub near_axis: F,
    pub far_axis: F,
}

/// The slab test of the module's note on the ray `ol + t dl` in the box's space (one
/// path maps it with glam, lanes with `geometry::affine_point`/`affine_vector`: the
/// same bits). A ray parallel to a pair of planes gives ±∞ on that axis, or NaN exactly
/// on one of them, which the comparisons below pass over: the other axes decide. Each
/// interval is ordered as SSE's min and max order it (the second value where either is
/// NaN), each axis taken where its bound is strictly tighter, so that one path and
/// lanes round and decide alike.
#[inline(always)]
pub fn slabs<F: Float>(ol: Vector3<F>, dl: Vector3<F>) -> Slabs<F> {
    let one = F::one();
    let mut t_near = F::of(f64::NEG_INFINITY);
    let mut t_far = F::of(f64::INFINITY);
    let (mut near_axis, mut far_axis) = (F::zero(), F::zero());
    for k in 0..3 {
        let (o, d) = (ol.component(k), dl.component(k));
        let inv = one / d;
        let (lo, hi) = ((one.negate() - o) * inv, (one - o) * inv);
        let near = F::select(lo.lt(hi), lo, hi);
        let far = F::select(lo.gt(hi), lo, hi);
        let (tighter_near, tighter_far) = (near.gt(t_near), far.lt(t_far));
        t_near = F::select(tighter_near, near, t_near);
        near_axis = F::select(tighter_near, F::of(k as f64), near_axis);
        t_far = F::select(tighter_far, far, t_far);
        far_axis = F::select(tighter_far, F::of(k as f64), far_axis);
    }
    Slabs {
        t_near,
        t_far,
        near_axis,
        far_axis,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::cube;
    use crate::sampling::warp::square_to_uniform_sphere;
    use crate::sampling::Pcg32;
    use glam::Mat3;
    use std::path::Path;

    /// Every hit of the ray with the mesh's triangles (Möller–Trumbore), sorted: (t,
    /// triangle).
    fn triangle_hits(m: &TriangleMesh, o: Vec3A, d: Vec3A, tmax: f32) -> Vec<(f32, u32)> {
        let mut hits: Vec<(f32, u32)> = (0..m.triangles.len() as u32)
            .filter_map(|i| {
                let [p0, p1, p2] = m.vertices(i);
                let (e1, e2) = (p1 - p0, p2 - p0);
                let pv = d.cross(e2);
                let inv = 1.0 / e1.dot(pv);
                let tv = o - p0;
                let u = tv.dot(pv) * inv;
                let qv = tv.cross(e1);
                let v = d.dot(qv) * inv;
                let t = e2.dot(qv) * inv;
                (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0 && t < tmax).then_some((t, i))
            })
            .collect();
        hits.sort_by(|a, b| a.0.total_cmp(&b.0));
        hits
    }

    /// On turned, stretched, sheared and mirrored cubes, random rays from outside and
    /// inside find the hits the 12 triangles give: the same distances, and a triangle
    /// and barycentrics that put the hit where the ray does.
    #[test]
    fn box_hits_are_the_triangle_hits() {
        let transforms = [
            Mat4::IDENTITY,
            Mat4::from_translation(glam::Vec3::new(0.5, -1.0, 2.0))
                * Mat4::from_rotation_y(0.5)
                * Mat4::from_scale(glam::Vec3::new(0.5, 0.5, 0.5)),
            Mat4::from_rotation_x(1.0) * Mat4::from_scale(glam::Vec3::new(2.0, 0.3, 0.9)),
            // Shear, and a mirror (which reverses the winding of the triangles).
            Mat4::from_mat3(Mat3::from_cols_array(&[
                1.0, 0.0, 0.0, 0.6, 1.0, 0.0, 0.0, 0.3, 1.0,
            ])),
            Mat4::from_rotation_z(0.3) * Mat4::from_scale(glam::Vec3::new(-1.0, 0.7, 1.2)),
        ];
        let mut rng = Pcg32::new(11, 2);
        for (k, to_world) in transforms.iter().enumerate() {
            let m = TriangleMesh::new(cube(), to_world, true, false, Path::new("cube")).unwrap();
            let c = Cuboid::new(0, &m, to_world).expect("a cube is a box");
            let (mut n_hits, mut n_inside) = (0, 0);
            for i in 0..20_000 {
                let corner = |u: Vec3A| to_world.transform_point3a(u * 2.0 - Vec3A::ONE);
                let random =
                    |rng: &mut Pcg32| Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d());
                // Half from inside the box, half from around it toward a point in it.
                let (o, d) = if i % 2 == 0 {
                    (
                        corner(random(&mut rng)),
                        square_to_uniform_sphere(rng.next_2d()),
                    )
                } else {
                    let o = corner(random(&mut rng) * 3.0 - Vec3A::ONE);
                    (o, (corner(random(&mut rng)) - o).normalize())
                };
                let tmax = if i % 3 == 0 { 0.7 } else { f32::INFINITY };
                let want = triangle_hits(&m, o, d, tmax);
                let got: Vec<CuboidHit> = c.hits_within(o, d, tmax).into_iter().flatten().collect();
                // A ray through an edge hits two triangles at one distance: the box once.
                let mut want_t: Vec<f32> = want.iter().map(|h| h.0).collect();
                want_t.dedup_by(|a, b| (*a - *b).abs() <= 1e-5 * b.abs().max(1.0));
                assert_eq!(
                    got.len(),
                    want_t.len(),
                    "cube {k}, ray {o} {d} {tmax}: {got:?} vs {want:?}"
                );
                for (h, t) in got.iter().zip(&want_t) {
                    // Distances agree up to rounding, which a grazing ray stretches by
                    // 1 / cos: compare how far apart the two points are off the face.
                    let [p0, p1, p2] = m.vertices(h.prim);
                    let cos = d.dot((p1 - p0).cross(p2 - p0).normalize()).abs();
                    let off = (h.t - t).abs() * cos;
                    assert!(
                        off <= 1e-5 * (1.0 + t),
                        "cube {k}: t {} vs {t}, cos {cos}",
                        h.t
                    );
                    assert!(h.u >= 0.0 && h.v >= 0.0 && h.u + h.v <= 1.0 + 1e-6);
                    let p = p0 + (p1 - p0) * h.u + (p2 - p0) * h.v;
                    let err = (p - (o + d * h.t)).length();
                    assert!(
                        err <= 1e-5 * (1.0 + h.t),
                        "cube {k}: triangle point off by {err}"
                    );
                    assert_eq!(h.leaf, h.prim, "first_leaf is 0 here");
                }
                assert_eq!(c.intersect(o, d, tmax), got.first().copied());
                assert_eq!(c.hit_within(o, d, tmax), !got.is_empty());
                n_hits += got.len();
                n_inside += (got.len() == 1) as u32;
            }
            assert!(
                n_hits > 20_000 && n_inside > 5_000,
                "cube {k}: {n_hits} hits, {n_inside} single"
            );
        }
    }

    /// A mesh that is not a box (a vertex moved) is left to the BVH.
    #[test]
    fn a_mesh_that_is_no_box_is_refused() {
        let mut raw = cube();
        raw.positions[0].x += 0.1;
        let m = TriangleMesh::new(raw, &Mat4::IDENTITY, true, false, Path::new("cube")).unwrap();
        assert!(Cuboid::new(0, &m, &Mat4::IDENTITY).is_none());
        let flat = Mat4::from_scale(glam::Vec3::new(1.0, 0.0, 1.0));
        let m = TriangleMesh::new(cube(), &flat, true, false, Path::new("cube")).unwrap();
        assert!(Cuboid::new(0, &m, &flat).is_none(), "a degenerate box");
    }

    /// A ray leaving the box crosses along the triangles' normals where they face out
    /// (as the cube's do, mirrored too) and against them with `flip_normals`, as each
    /// face's triangle itself says; a mesh wound both ways has no one side.
    #[test]
    fn the_exit_side_is_the_triangles() {
        let mirror = Mat4::from_rotation_y(0.4) * Mat4::from_scale(Vec3::new(-1.0, 0.5, 1.0));
        for (to_world, flip) in [
            (Mat4::IDENTITY, false),
            (Mat4::IDENTITY, true),
            (mirror, false),
            (mirror, true),
        ] {
            let m = TriangleMesh::new(cube(), &to_world, true, flip, Path::new("cube")).unwrap();
            let c = Cuboid::new(0, &m, &to_world).expect("a cube is a box");
            assert_eq!(c.exit_along_normal, Some(!flip), "{to_world} flip {flip}");
            // Out of the centre through every face (off its diagonal): the hit triangle's
            // normal agrees.
            let o = to_world.transform_point3a(Vec3A::ZERO);
            for k in 0..6 {
                let mut axis = Vec3A::splat(0.3);
                axis[(k / 2 + 1) % 3] = -0.2;
                axis[k / 2] = if k % 2 == 0 { -1.0 } else { 1.0 };
                let d = to_world.transform_vector3a(axis).normalize();
                let (_, prim) = triangle_hits(&m, o, d, f32::INFINITY)[0];
                let [p0, p1, p2] = m.vertices(prim);
                let n = (p1 - p0).cross(p2 - p0) * if flip { -1.0 } else { 1.0 };
                assert_eq!(d.dot(n) > 0.0, !flip, "{to_world} flip {flip} face {k}");
            }
        }
        let mut raw = cube();
        raw.triangles[3].swap(1, 2);
        let m = TriangleMesh::new(raw, &Mat4::IDENTITY, true, false, Path::new("cube")).unwrap();
        let c = Cuboid::new(0, &m, &Mat4::IDENTITY).expect("still a box");
        assert_eq!(c.exit_along_normal, None);
    }
}
