//! Clearance: a lower bound, at any point, on its distance to the nearest surface of the
//! scene, read from a voxel grid in one memory access.
//!
//! Two uses in a medium (see `integrator::volpath`), both exact:
//! * a free flight of length `t < clearance(p)` cannot reach a surface, so it needs no
//!   ray cast: the result of the cast is known to be "no hit";
//! * a shadow ray from `p` runs at least `min(clearance(p), dist)` through the medium
//!   it starts in, so its transmittance is at most `e^{−σ_t · min(clearance, dist)}`:
//!   the bound lets the integrator play Russian roulette on shadow rays that can only
//!   carry little (deep inside a dense medium).
//!
//! Construction. Every cell a surface may pass through is marked (conservatively: a
//! cell is marked if the surface's bounding box overlaps it and, for primitives larger
//! than a couple of cells, the surface comes within the cell's half-diagonal of its
//! centre). The exact Euclidean distance transform (Felzenszwalb &
//! Huttenlocher 2012, separable lower envelopes of parabolas) gives each cell's
//! distance `D` (in cells) from its centre to the nearest marked centre. A point `p` in
//! cell `v` and a surface point `s` in marked cell `w` lie within `√3/2` cells of their
//! centres, so
//!
//! ```text
//! |p − s| ≥ |c_v − c_w| − √3 h ≥ (D(v) − √3) h.
//! ```
//!
//! The grid covers where the media are (the interiors' boxes, or the whole scene when a
//! medium is outside some shape or around the camera). Outside it the bound is the
//! distance to the scene's bounding box (every surface lies in it) when the grid covers
//! that box, else 0. Bounds are stored rounded down to quarter cells in a byte per cell.

use glam::Vec3A;

use super::shape::Geometry;
use super::Bounds;

/// Cells along the longest axis of the grid's region (where the media are).
const CELLS_LONGEST_AXIS: f32 = 128.0;
/// Stored bounds are multiples of `h / QUANTUM` (rounded down), up to 255 of them.
const QUANTUM: f32 = 4.0;
/// Primitives whose box spans at most this many cells per axis mark their whole box
/// (cheaper than testing each cell, and still conservative).
const SMALL_SPAN: usize = 2;

pub struct Clearance {
    /// The grid's corner (one cell outside the region's box on every side).
    origin: Vec3A,
    inv_h: f32,
    /// The length a stored unit stands for: `h / QUANTUM`.
    unit: f32,
    /// The bound everywhere when there is no grid: 0 (nothing known), or ∞ (a scene
    /// without surfaces).
    no_grid: f32,
    dims: [usize; 3],
    /// Per cell, x fastest: the bound in units of `unit`.
    cells: Vec<u8>,
    /// The scene's bounding box, if the grid covers it: outside the grid, the distance
    /// to it is the bound (empty: the bound is 0 there).
    scene: Bounds,
}

impl Clearance {
    /// No bound (0 everywhere): every free flight is cast, no shadow ray is skipped.
    pub fn none() -> Clearance {
        Clearance {
            origin: Vec3A::ZERO,
            inv_h: 0.0,
            unit: 0.0,
            no_grid: 0.0,
            dims: [0; 3],
            cells: Vec::new(),
            scene: Bounds::EMPTY,
        }
    }

    /// The grid covers `region` (where the media are: the bounds are wanted there
    /// only), with every shape of the scene marked in it. Outside it the bound is the
    /// distance to the `scene`'s box if the region covers that box, else 0.
    pub fn build(geometries: &[Geometry], region: Bounds, scene: Bounds) -> Clearance {
        if geometries.is_empty() || scene.is_empty() {
            // Nothing to hit anywhere.
            return Clearance {
                no_grid: f32::INFINITY,
                ..Clearance::none()
            };
        }
        let region = Bounds {
            min: region.min.max(scene.min),
            max: region.max.min(scene.max),
        };
        if region.is_empty() {
            return Clearance::none();
        }
        let covers_scene = region.min == scene.min && region.max == scene.max;
        let extent = region.max - region.min;
        let h = extent.max_element() / CELLS_LONGEST_AXIS;
        if !(h.is_finite() && h > 0.0) {
            return Clearance::none();
        }
        let origin = region.min - Vec3A::splat(h);
        let dims = [0, 1, 2].map(|a| (extent[a] / h).ceil() as usize + 2);
        let mut grid = Grid {
            origin,
            h,
            dims,
            dist2: vec![f32::INFINITY; dims[0] * dims[1] * dims[2]],
        };
        for g in geometries {
            grid.mark(g);
        }
        if !covers_scene {
            // Surfaces outside the grid are nearer than its outer layer of cells.
            grid.mark_outer_layer();
        }
        grid.distance_transform();
        let cells = grid
            .dist2
            .iter()
            .map(|&d2| {
                let cells = d2.sqrt() - 3f32.sqrt() - 0.01;
                (cells.max(0.0) * QUANTUM).floor().min(255.0) as u8
            })
            .collect();
        Clearance {
            origin,
            inv_h: 1.0 / h,
            unit: h / QUANTUM * (1.0 - 1e-4),
            no_grid: 0.0,
            dims,
            cells,
            scene: if covers_scene { scene } else { Bounds::EMPTY },
        }
    }

    /// A distance within which no surface lies around `p` (0 when nothing is known).
    #[inline]
    pub fn at(&self, p: Vec3A) -> f32 {
        if self.cells.is_empty() {
            return self.no_grid;
        }
        let c = (p - self.origin) * self.inv_h;
        let (x, y, z) = (c.x.floor(), c.y.floor(), c.z.floor());
        // NaN fails these comparisons too, and gets 0.
        let inside = x >= 0.0
            && y >= 0.0
            && z >= 0.0
            && x < self.dims[0] as f32
            && y < self.dims[1] as f32
            && z < self.dims[2] as f32;
        if inside {
            let i = x as usize + self.dims[0] * (y as usize + self.dims[1] * z as usize);
            self.cells[i] as f32 * self.unit
        } else if self.scene.is_empty() {
            0.0
        } else {
            let out = (self.scene.min - p)
                .max(p - self.scene.max)
                .max(Vec3A::ZERO);
            let d = out.length() * (1.0 - 1e-4);
            if d.is_finite() {
                d
            } else {
                0.0
            }
        }
    }
}

/// The grid while it is built: squared distances in cells (0 on marked cells).
struct Grid {
    origin: Vec3A,
    h: f32,
    dims: [usize; 3],
    dist2: Vec<f32>,
}

impl Grid {
    /// The cell range `[lo, hi]` (inclusive, clamped) that the box `b` overlaps.
    fn range(&self, b: &Bounds) -> ([usize; 3], [usize; 3]) {
        let lo = (b.min - self.origin) / self.h;
        let hi = (b.max - self.origin) / self.h;
        let clamp = |v: f32, a: usize| (v.floor().max(0.0) as usize).min(self.dims[a] - 1);
        (
            [0, 1, 2].map(|a| clamp(lo[a], a)),
            [0, 1, 2].map(|a| clamp(hi[a], a)),
        )
    }

    fn centre(&self, i: [usize; 3]) -> Vec3A {
        self.origin + (Vec3A::new(i[0] as f32, i[1] as f32, i[2] as f32) + 0.5) * self.h
    }

    /// Marks every cell of `b`'s range for which `hits(centre)` holds (all of them for
    /// a small range).
    fn mark_box(&mut self, b: &Bounds, hits: impl Fn(Vec3A) -> bool) {
        // A box wholly outside the grid marks nothing: the grid covers only part of the
        // scene then, and its outer layer is marked for what lies beyond.
        let far = self.origin
            + Vec3A::new(
                self.dims[0] as f32,
                self.dims[1] as f32,
                self.dims[2] as f32,
            ) * self.h;
        if b.max.cmplt(self.origin).any() || b.min.cmpgt(far).any() {
            return;
        }
        let (lo, hi) = self.range(b);
        let small = (0..3).all(|a| hi[a] - lo[a] < SMALL_SPAN);
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    if small || hits(self.centre([x, y, z])) {
                        let i = x + self.dims[0] * (y + self.dims[1] * z);
                        self.dist2[i] = 0.0;
                    }
                }
            }
        }
    }

    fn mark_outer_layer(&mut self) {
        let [nx, ny, nz] = self.dims;
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    if x == 0 || y == 0 || z == 0 || x == nx - 1 || y == ny - 1 || z == nz - 1 {
                        self.dist2[x + nx * (y + ny * z)] = 0.0;
                    }
                }
            }
        }
    }

    /// Marks the cells triangle (a, b, c) may pass through: a cell meets it only if the
    /// cell's centre lies within the half-diagonal of it (padded for rounding).
    fn mark_triangle(&mut self, [a, b, c]: [Vec3A; 3]) {
        let reach = 0.5 * self.h * 3f32.sqrt() * 1.01;
        let mut bounds = Bounds::EMPTY;
        for p in [a, b, c] {
            bounds.expand(p);
        }
        self.mark_box(&bounds, |x| point_triangle(x, a, b, c) <= reach);
    }

    /// Marks the cells `g`'s surface may pass through.
    fn mark(&mut self, g: &Geometry) {
        match g {
            Geometry::Mesh(m) => {
                for t in 0..m.triangles.len() as u32 {
                    self.mark_triangle(m.vertices(t));
                }
            }
            Geometry::Sphere(s) => {
                // A cell meets the sphere only if its centre is within the half-diagonal
                // of it.
                let reach = 0.5 * self.h * 3f32.sqrt() * 1.01;
                let (c, r) = (s.center, s.radius);
                self.mark_box(&s.bounds(), |x| ((x - c).length() - r).abs() <= reach);
            }
            Geometry::Planar(p) => {
                // The rectangle as two triangles; the disk inside the regular octagon
                // around the unit circle (vertices at radius 1 / cos(π/8)), a fan of six.
                // Affine maps keep the containment.
                let corners: Vec<Vec3A> = if p.is_disk {
                    let r = 1.0 / (std::f32::consts::PI / 8.0).cos();
                    (0..8)
                        .map(|k| {
                            let phi = k as f32 * std::f32::consts::FRAC_PI_4;
                            Vec3A::new(r * phi.cos(), r * phi.sin(), 0.0)
                        })
                        .collect()
                } else {
                    [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
                        .map(|(x, y)| Vec3A::new(x, y, 0.0))
                        .to_vec()
                };
                let w: Vec<Vec3A> = corners
                    .iter()
                    .map(|&c| p.to_world.transform_point3a(c))
                    .collect();
                for k in 1..w.len() - 1 {
                    self.mark_triangle([w[0], w[k], w[k + 1]]);
                }
            }
        }
    }

    /// Exact squared Euclidean distance transform, one axis at a time.
    fn distance_transform(&mut self) {
        let [nx, ny, nz] = self.dims;
        let n = nx.max(ny).max(nz);
        let mut line = vec![0.0f32; n];
        let mut out = vec![0.0f32; n];
        let mut env = Envelope::new(n);
        let strides = [1, nx, nx * ny];
        for axis in 0..3 {
            let len = self.dims[axis];
            let stride = strides[axis];
            // Every line along `axis`: its start runs over the other two axes.
            let (a, b) = match axis {
                0 => (1, 2),
                1 => (0, 2),
                _ => (0, 1),
            };
            for j in 0..self.dims[b] {
                for i in 0..self.dims[a] {
                    let start = i * strides[a] + j * strides[b];
                    for (k, l) in line[..len].iter_mut().enumerate() {
                        *l = self.dist2[start + k * stride];
                    }
                    env.transform(&line[..len], &mut out[..len]);
                    for (k, &o) in out[..len].iter().enumerate() {
                        self.dist2[start + k * stride] = o;
                    }
                }
            }
        }
    }
}

/// Distance from `p` to triangle (a, b, c) (Ericson, Real-Time Collision Detection
/// 5.1.5, closest point on a triangle).
fn point_triangle(p: Vec3A, a: Vec3A, b: Vec3A, c: Vec3A) -> f32 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (p - a).length();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (p - b).length();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (p - (a + ab * (d1 / (d1 - d3)))).length();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (p - c).length();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (p - (a + ac * (d2 / (d2 - d6)))).length();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * w)).length();
    }
    let denom = 1.0 / (va + vb + vc);
    (p - (a + ab * (vb * denom) + ac * (vc * denom))).length()
}

/// Felzenszwalb–Huttenlocher's 1-D transform: `out[q] = min_p (q − p)² + f[p]`, by the
/// lower envelope of the parabolas rooted at the finite `f[p]`.
struct Envelope {
    /// Roots of the parabolas in the envelope.
    v: Vec<usize>,
    /// Boundaries between them (`z[k]` .. `z[k+1]` belongs to `v[k]`).
    z: Vec<f32>,
}

impl Envelope {
    fn new(n: usize) -> Self {
        Envelope {
            v: vec![0; n],
            z: vec![0.0; n + 1],
        }
    }

    fn transform(&mut self, f: &[f32], out: &mut [f32]) {
        let mut k: isize = -1;
        for q in 0..f.len() {
            if !f[q].is_finite() {
                continue;
            }
            let qf = q as f32;
            loop {
                if k < 0 {
                    k = 0;
                    self.v[0] = q;
                    self.z[0] = f32::NEG_INFINITY;
                    self.z[1] = f32::INFINITY;
                    break;
                }
                let p = self.v[k as usize];
                let pf = p as f32;
                // Where the parabolas of p and q cross.
                let s = ((f[q] + qf * qf) - (f[p] + pf * pf)) / (2.0 * (qf - pf));
                if s <= self.z[k as usize] {
                    k -= 1;
                    continue;
                }
                k += 1;
                self.v[k as usize] = q;
                self.z[k as usize] = s;
                self.z[k as usize + 1] = f32::INFINITY;
                break;
            }
        }
        if k < 0 {
            out.fill(f32::INFINITY);
            return;
        }
        let mut j = 0usize;
        for (q, o) in out.iter_mut().enumerate() {
            let qf = q as f32;
            while self.z[j + 1] < qf {
                j += 1;
            }
            let p = self.v[j];
            let d = qf - p as f32;
            *o = d * d + f[p];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::{cube, TriangleMesh};
    use crate::geometry::shape::{Planar, Sphere};
    use glam::{Mat3A, Mat4, Vec3};
    use std::path::Path;

    /// A rotated cube (12 large triangles), a sphere and a tilted disk.
    fn shapes() -> Vec<Geometry> {
        let to_world = Mat4::from_translation(Vec3::new(0.3, -0.2, 0.1))
            * Mat4::from_rotation_y(0.7)
            * Mat4::from_rotation_x(0.4)
            * Mat4::from_scale(Vec3::new(1.0, 0.6, 0.8));
        let mesh = TriangleMesh::new(cube(), &to_world, true, false, Path::new("cube"))
            .expect("the cube is a valid mesh");
        let sphere = Sphere {
            center: Vec3A::new(2.5, 0.5, -1.0),
            radius: 0.7,
            flip_normals: false,
            axes: Mat3A::IDENTITY,
        };
        let disk = Planar::new(
            Mat4::from_translation(Vec3::new(-1.0, -1.5, 0.5))
                * Mat4::from_rotation_x(-1.1)
                * Mat4::from_scale(Vec3::splat(2.0)),
            false,
            true,
        );
        vec![
            Geometry::Mesh(mesh),
            Geometry::Sphere(sphere),
            Geometry::Planar(disk),
        ]
    }

    /// The true distance from `p` to the shapes above (the disk by sampling its plane
    /// exactly: distance to the plane, or to the rim where the projection falls outside).
    fn distance(shapes: &[Geometry], p: Vec3A) -> f32 {
        shapes
            .iter()
            .map(|g| match g {
                Geometry::Mesh(m) => (0..m.triangles.len() as u32)
                    .map(|t| {
                        let [a, b, c] = m.vertices(t);
                        point_triangle(p, a, b, c)
                    })
                    .fold(f32::INFINITY, f32::min),
                Geometry::Sphere(s) => ((p - s.center).length() - s.radius).abs(),
                Geometry::Planar(d) => {
                    // Uniform scale 2: local distances are world distances / 2.
                    let l = d.to_local.transform_point3a(p);
                    let r = (l.x * l.x + l.y * l.y).sqrt();
                    let radial = (r - 1.0).max(0.0);
                    2.0 * (radial * radial + l.z * l.z).sqrt()
                }
            })
            .fold(f32::INFINITY, f32::min)
    }

    fn scene_bounds(shapes: &[Geometry]) -> Bounds {
        shapes
            .iter()
            .fold(Bounds::EMPTY, |b, g| b.union(&g.bounds()))
    }

    #[test]
    fn clearance_is_a_lower_bound_and_not_a_useless_one() {
        let shapes = shapes();
        let bounds = scene_bounds(&shapes);
        let c = Clearance::build(&shapes, bounds, bounds);
        let mut rng = crate::sampling::Pcg32::new(7, 1);
        let lo = bounds.min - Vec3A::splat(1.0);
        let size = bounds.max - bounds.min + Vec3A::splat(2.0);
        let (mut useful, mut checked, n) = (0, 0, 20_000);
        for _ in 0..n {
            let u = Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d());
            let p = lo + u * size;
            let (bound, truth) = (c.at(p), distance(&shapes, p));
            assert!(bound <= truth, "at {p}: bound {bound} > distance {truth}");
            // The bound is worth having: within 3 cells (plus quantisation) of the truth.
            let h = (bounds.max - bounds.min).max_element() / CELLS_LONGEST_AXIS;
            let inside = (p.cmpge(bounds.min) & p.cmple(bounds.max)).all();
            if inside && truth < 60.0 * h {
                checked += 1;
                if truth - bound <= 2.0 * 3f32.sqrt() * h + h / QUANTUM {
                    useful += 1;
                }
            }
        }
        // Not all: the disk is marked by its octagon.
        assert!(
            checked > n / 4 && useful as f32 >= 0.95 * checked as f32,
            "only {useful} of {checked} bounds are within 2√3 cells of the distance"
        );
    }

    #[test]
    fn a_grid_over_part_of_the_scene_is_still_a_lower_bound() {
        let shapes = shapes();
        let bounds = scene_bounds(&shapes);
        // The cube's box only: the sphere and most of the disk lie outside the grid.
        let region = shapes[0].bounds();
        let c = Clearance::build(&shapes, region, bounds);
        let mut rng = crate::sampling::Pcg32::new(9, 1);
        let lo = bounds.min - Vec3A::splat(1.0);
        let size = bounds.max - bounds.min + Vec3A::splat(2.0);
        let mut positive = 0;
        for _ in 0..20_000 {
            let u = Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d());
            let p = lo + u * size;
            let (bound, truth) = (c.at(p), distance(&shapes, p));
            assert!(bound <= truth, "at {p}: bound {bound} > distance {truth}");
            positive += (bound > 0.0) as u32;
        }
        assert!(
            positive > 100,
            "only {positive} points have a positive bound"
        );
    }

    #[test]
    fn no_geometry_no_surface_anywhere() {
        let c = Clearance::build(&[], Bounds::EMPTY, Bounds::EMPTY);
        assert_eq!(c.at(Vec3A::ZERO), f32::INFINITY);
        assert_eq!(Clearance::none().at(Vec3A::ONE), 0.0);
    }

    #[test]
    fn distance_transform_is_exact_in_one_dimension() {
        let f = [
            f32::INFINITY,
            0.0,
            f32::INFINITY,
            f32::INFINITY,
            0.0,
            f32::INFINITY,
        ];
        let mut out = [0.0; 6];
        Envelope::new(6).transform(&f, &mut out);
        assert_eq!(out, [1.0, 0.0, 1.0, 1.0, 0.0, 1.0]);
    }
}
