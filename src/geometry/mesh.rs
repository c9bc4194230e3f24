//! Triangle meshes: the OBJ reader (tobj; PLY's is `super::ply`), Mitsuba's `cube`, vertex
//! normals, ray–triangle intersection and uniform area sampling.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;
use std::sync::Arc;

use glam::{Mat4, Vec2, Vec3A};

use crate::error::{Loc, Result, SceneError};

/// A triangle mesh in world space.
#[derive(Clone, Debug)]
pub struct TriangleMesh {
    /// Shared (never changed once built) with the ray caster, which may point into it
    /// (Embree's shared buffers) instead of keeping a copy.
    pub positions: Arc<Vec<Vec3A>>,
    /// Per-vertex shading normals; `None` with `face_normals` and for a flat mesh.
    pub normals: Option<Vec<Vec3A>>,
    pub triangles: Arc<Vec<[u32; 3]>>,
    /// Per-vertex texture coordinates, when the file has them.
    pub uvs: Option<Vec<Vec2>>,
    pub flip_normals: bool,
    /// Each triangle's unit geometric normal (p1 − p0) × (p2 − p0), 0 where it has no
    /// area: a hit and a point sampled on an emitter read it instead of working it out.
    geometric_normals: Vec<Vec3A>,
    /// Cumulative triangle areas, for sampling a point uniformly by area.
    area_cdf: Vec<f32>,
    pub total_area: f32,
    /// Mitsuba's `cube` only: the `to_world` that places [-1, 1]³, so the accelerator
    /// can test it as a box (`geometry::cuboid`).
    pub cube_to_world: Option<Mat4>,
}

/// Mesh data as read from a file, in object space.
#[derive(Clone, Debug)]
pub struct RawMesh {
    pub positions: Vec<Vec3A>,
    pub normals: Option<Vec<Vec3A>>,
    pub triangles: Vec<[u32; 3]>,
    pub uvs: Option<Vec<Vec2>>,
    /// What the reader accepted but the user should hear about.
    pub warnings: Vec<String>,
}

pub(super) fn mesh_error(path: &Path, msg: impl Into<String>) -> SceneError {
    SceneError::new(Some(Loc::file_only(path)), msg.into())
}

/// Bytes a loaded mesh takes at the least per triangle (its indices, geometric normal
/// and area-CDF entry, and the ray caster's copy of the indices) and per vertex (its
/// position and vertex normal). A floor, not an estimate (the ray caster's tree comes on
/// top): only a mesh that cannot fit is refused.
const MIN_BYTES_PER_TRIANGLE: u64 = 12 + 16 + 4 + 12;
const MIN_BYTES_PER_VERTEX: u64 = 16 + 16;

/// Refuses, before anything is read, a mesh of `triangles` and `vertices` whose arrays
/// alone would not fit in `available` bytes (the readers pass [`available_memory`]),
/// instead of letting the machine swap; passes where that is not known.
pub(super) fn check_fits(
    path: &Path,
    triangles: u64,
    vertices: u64,
    available: Option<u64>,
) -> Result<()> {
    let need = triangles
        .saturating_mul(MIN_BYTES_PER_TRIANGLE)
        .saturating_add(vertices.saturating_mul(MIN_BYTES_PER_VERTEX));
    let Some(available) = available else {
        return Ok(());
    };
    if need <= available {
        return Ok(());
    }
    let gib = |b: u64| b as f64 / (1u64 << 30) as f64;
    Err(mesh_error(
        path,
        format!(
            "its {triangles} triangles and {vertices} vertices need at least {:.1} GiB of memory, and this machine has {:.1} GiB available: render it on a machine with more memory, or decimate the mesh",
            gib(need),
            gib(available)
        ),
    ))
}

/// MemAvailable of /proc/meminfo in bytes (None off Linux or where it is not readable).
pub(super) fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Runs a third-party reader, turning a panic inside it into an error naming the file.
fn guarded<T>(path: &Path, what: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(r) => r,
        Err(_) => Err(mesh_error(
            path,
            format!("the {what} reader failed on this file: it is malformed or truncated"),
        )),
    }
}

/// Reads a Wavefront OBJ file (positions, optional normals; faces fan-triangulated).
pub fn read_obj(path: &Path) -> Result<RawMesh> {
    if !path.exists() {
        return Err(mesh_error(path, "cannot open OBJ file: no such file"));
    }
    let opts = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, _) = guarded(path, "OBJ", || {
        tobj::load_obj(path, &opts)
            .map_err(|e| mesh_error(path, format!("cannot parse OBJ file: {e}")))
    })?;
    let n_vertices: usize = models.iter().map(|m| m.mesh.positions.len() / 3).sum();
    let n_indices: usize = models.iter().map(|m| m.mesh.indices.len()).sum();
    let mut positions = Vec::with_capacity(n_vertices);
    let mut normals = Vec::new();
    let mut all_have_normals = true;
    let mut uvs = Vec::new();
    let mut all_have_uvs = true;
    let mut faces = Triangulator::new(n_vertices as u64);
    faces.triangles.reserve_exact(n_indices / 3);
    let mut poly = Vec::with_capacity(3);
    for m in &models {
        let mesh = &m.mesh;
        let base = positions.len() as i64;
        let nv = mesh.positions.len() / 3;
        positions.extend(
            mesh.positions
                .chunks_exact(3)
                .map(|p| Vec3A::new(p[0], p[1], p[2])),
        );
        if all_have_normals && mesh.normals.len() == mesh.positions.len() {
            normals.reserve_exact(n_vertices);
            normals.extend(
                mesh.normals
                    .chunks_exact(3)
                    .map(|n| Vec3A::new(n[0], n[1], n[2])),
            );
        } else {
            all_have_normals = false;
            normals = Vec::new();
        }
        if all_have_uvs && mesh.texcoords.len() == 2 * nv {
            uvs.reserve_exact(n_vertices);
            uvs.extend(mesh.texcoords.chunks(2).map(|t| Vec2::new(t[0], t[1])));
        } else {
            all_have_uvs = false;
            uvs = Vec::new();
        }
        for tri in mesh.indices.chunks(3) {
            poly.clear();
            poly.extend(tri.iter().map(|&i| i as i64 + base));
            faces.add(&poly);
        }
    }
    // tobj's copy goes before the mesh is built from this one.
    drop(models);
    let triangles = faces.finish(path)?;
    Ok(RawMesh {
        positions,
        normals: (all_have_normals && !normals.is_empty()).then_some(normals),
        triangles,
        uvs: (all_have_uvs && !uvs.is_empty()).then_some(uvs),
        warnings: Vec::new(),
    })
}

/// Checks faces' vertex indices and fan-triangulates them as a reader hands them over;
/// the first bad face is the error [`Triangulator::finish`] reports.
pub(super) struct Triangulator {
    pub triangles: Vec<[u32; 3]>,
    n_vertices: u64,
    faces: usize,
    error: Option<String>,
}

impl Triangulator {
    pub fn new(n_vertices: u64) -> Self {
        Triangulator {
            triangles: Vec::new(),
            n_vertices,
            faces: 0,
            error: None,
        }
    }

    /// Adds face number `self.faces`, a polygon of vertex indices.
    #[inline]
    pub fn add(&mut self, poly: &[i64]) {
        let i = self.faces;
        self.faces += 1;
        if self.error.is_some() {
            return;
        }
        if poly.len() < 3 {
            self.error = Some(format!(
                "face {i} has {} vertices (at least 3 needed)",
                poly.len()
            ));
            return;
        }
        let n = self.n_vertices;
        if let Some(v) = poly.iter().find(|&&v| v < 0 || v as u64 >= n) {
            self.error = Some(format!(
                "face {i} refers to vertex {v}, but the mesh has {n} vertices"
            ));
            return;
        }
        for k in 1..poly.len() - 1 {
            self.triangles
                .push([poly[0] as u32, poly[k] as u32, poly[k + 1] as u32]);
        }
    }

    pub fn finish(self, path: &Path) -> Result<Vec<[u32; 3]>> {
        if let Some(e) = self.error {
            return Err(mesh_error(path, e));
        }
        if self.triangles.is_empty() {
            return Err(mesh_error(path, "mesh has no faces"));
        }
        Ok(self.triangles)
    }
}

/// Mitsuba 3's `cube`: [-1, 1]³, 6 faces × 2 triangles, 24 vertices with face normals.
pub fn cube() -> RawMesh {
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut triangles = Vec::new();
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut n = Vec3A::ZERO;
            n[axis] = sign;
            let u_axis = (axis + 1) % 3;
            let v_axis = (axis + 2) % 3;
            let base = positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                let mut p = n;
                p[u_axis] = a;
                p[v_axis] = b;
                positions.push(p);
                normals.push(n);
            }
            // Wind so that the geometric normal points outward.
            if sign > 0.0 {
                triangles.push([base, base + 1, base + 2]);
                triangles.push([base, base + 2, base + 3]);
            } else {
                triangles.push([base, base + 2, base + 1]);
                triangles.push([base, base + 3, base + 2]);
            }
        }
    }
    RawMesh {
        positions,
        normals: Some(normals),
        triangles,
        uvs: None,
        warnings: Vec::new(),
    }
}

impl TriangleMesh {
    /// Builds a world-space mesh. Without file normals and without `face_normals`, smooth
    /// vertex normals are computed (angle-weighted, as Mitsuba's `recompute_vertex_normals`).
    pub fn new(
        raw: RawMesh,
        to_world: &Mat4,
        face_normals: bool,
        flip_normals: bool,
        path: &Path,
    ) -> Result<Self> {
        // In place: the file's arrays become the mesh's, with no second copy.
        let mut raw = raw;
        let mut positions = std::mem::take(&mut raw.positions);
        for p in &mut positions {
            *p = to_world.transform_point3a(*p);
        }
        if positions.iter().any(|p| !p.is_finite()) {
            return Err(mesh_error(path, "mesh has a non-finite vertex position"));
        }
        // A mirroring transform would turn the geometric normals inward: Mitsuba reverses
        // the winding then, so they keep pointing where the file's winding said.
        if to_world.determinant() < 0.0 {
            for t in &mut raw.triangles {
                t.swap(1, 2);
            }
        }
        let normals = if face_normals {
            None
        } else {
            let inv_t = to_world.inverse().transpose();
            Some(match raw.normals.take() {
                Some(mut ns) => {
                    for n in &mut ns {
                        *n = inv_t.transform_vector3a(*n).normalize_or_zero();
                    }
                    ns
                }
                None => vertex_normals(&positions, &raw.triangles),
            })
        };
        // Each triangle's edge cross product gives its area (for sampling) and its
        // geometric normal.
        let mut area_cdf = Vec::with_capacity(raw.triangles.len());
        let mut geometric_normals = Vec::with_capacity(raw.triangles.len());
        let mut total = 0.0f64;
        for t in &raw.triangles {
            let [a, b, c] = t.map(|i| positions[i as usize]);
            let cross = (b - a).cross(c - a);
            total += 0.5 * cross.length() as f64;
            area_cdf.push(total as f32);
            geometric_normals.push(cross.normalize_or_zero());
        }
        // A flat mesh (a wall, a box: each triangle's vertex normals its own face
        // normal) keeps none: its shading normal is the geometric one, which a hit
        // then reads without three more loads and a square root.
        let normals = normals.filter(|ns| !is_flat(&raw.triangles, &geometric_normals, ns));
        Ok(TriangleMesh {
            positions: Arc::new(positions),
            normals,
            triangles: Arc::new(raw.triangles),
            uvs: raw.uvs,
            flip_normals,
            geometric_normals,
            area_cdf,
            total_area: total as f32,
            cube_to_world: None,
        })
    }

    pub fn vertices(&self, tri: u32) -> [Vec3A; 3] {
        self.triangles[tri as usize].map(|i| self.positions[i as usize])
    }

    /// Texture coordinates at barycentrics (u, v): interpolated from the file's, else
    /// (u, v) themselves, as Mitsuba does for a mesh without texture coordinates.
    pub fn uv(&self, tri: u32, u: f32, v: f32) -> Vec2 {
        match &self.uvs {
            Some(t) => {
                let [a, b, c] = self.triangles[tri as usize].map(|i| t[i as usize]);
                a * (1.0 - u - v) + b * u + c * v
            }
            None => Vec2::new(u, v),
        }
    }

    /// Position, geometric normal and shading normal at barycentrics (u, v).
    pub fn surface(&self, tri: u32, u: f32, v: f32) -> (Vec3A, Vec3A, Vec3A) {
        let idx = self.triangles[tri as usize];
        let [p0, p1, p2] = idx.map(|i| self.positions[i as usize]);
        let w = 1.0 - u - v;
        let p = p0 * w + p1 * u + p2 * v;
        let mut n = self.geometric_normals[tri as usize];
        let mut sh_n = match &self.normals {
            Some(ns) => {
                let s = ns[idx[0] as usize] * w + ns[idx[1] as usize] * u + ns[idx[2] as usize] * v;
                s.try_normalize().unwrap_or(n)
            }
            None => n,
        };
        if self.flip_normals {
            n = -n;
            sh_n = -sh_n;
        }
        (p, n, sh_n)
    }

    /// Mitsuba's ∂p/∂u on triangle `tri` with geometric normal `n`: from the texture
    /// coordinates when the mesh has them (coordinate_system(n) where they are
    /// degenerate), else the barycentric parameterisation's p1 − p0.
    pub fn dp_du(&self, tri: u32, n: Vec3A) -> Vec3A {
        let idx = self.triangles[tri as usize];
        let [p0, p1, p2] = idx.map(|i| self.positions[i as usize]);
        let (dp0, dp1) = (p1 - p0, p2 - p0);
        let Some(uvs) = &self.uvs else {
            return dp0;
        };
        let [uv0, uv1, uv2] = idx.map(|i| uvs[i as usize]);
        let (duv0, duv1) = (uv1 - uv0, uv2 - uv0);
        let det = duv0.x * duv1.y - duv0.y * duv1.x;
        if det == 0.0 {
            return super::Frame::new(n).s;
        }
        (dp0 * duv1.y - dp1 * duv0.y) / det
    }

    /// A point uniformly distributed over the surface; pdf (area) = 1 / total_area.
    pub fn sample_position(&self, sample: Vec2) -> (Vec3A, Vec3A) {
        let target = sample.x * self.total_area;
        let i = self
            .area_cdf
            .partition_point(|&c| c < target)
            .min(self.area_cdf.len() - 1);
        let lo = if i == 0 { 0.0 } else { self.area_cdf[i - 1] };
        let width = self.area_cdf[i] - lo;
        let x = if width > 0.0 {
            ((target - lo) / width).clamp(0.0, 1.0)
        } else {
            0.5
        };
        // Uniform barycentrics (square_to_uniform_triangle).
        let t = (1.0 - x).sqrt();
        let (u, v) = (1.0 - t, t * sample.y);
        let (p, _n, sh_n) = self.surface(i as u32, u, v);
        (p, sh_n)
    }
}

/// How far (per component) a vertex normal may lie from its triangle's face normal for
/// the triangle to count as flat: rounding, and no visible angle (about 2e-5 rad).
const FLAT_TOLERANCE: f32 = 1e-5;

/// Whether every triangle's vertex normals are its geometric normal (to rounding).
fn is_flat(triangles: &[[u32; 3]], geometric: &[Vec3A], normals: &[Vec3A]) -> bool {
    triangles.iter().zip(geometric).all(|(t, &n)| {
        t.iter()
            .all(|&i| (normals[i as usize] - n).abs().max_element() <= FLAT_TOLERANCE)
    })
}

/// Angle-weighted vertex normals ("Computing Vertex Normals from Polygonal Facets",
/// Thürmer & Wüthrich 1998), as Mitsuba 3 computes them for meshes without normals.
fn vertex_normals(positions: &[Vec3A], triangles: &[[u32; 3]]) -> Vec<Vec3A> {
    let mut normals = vec![Vec3A::ZERO; positions.len()];
    for t in triangles {
        let p = t.map(|i| positions[i as usize]);
        let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
        if n == Vec3A::ZERO {
            continue;
        }
        for k in 0..3 {
            let d0 = (p[(k + 1) % 3] - p[k]).normalize_or_zero();
            let d1 = (p[(k + 2) % 3] - p[k]).normalize_or_zero();
            let angle = d0.dot(d1).clamp(-1.0, 1.0).acos();
            normals[t[k] as usize] += n * angle;
        }
    }
    for n in &mut normals {
        *n = n.normalize_or_zero();
    }
    normals
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat mesh keeps no vertex normals (its shading normal is the geometric one,
    /// to the bit); a bent one keeps them, however slight the bend beyond rounding.
    #[test]
    fn flat_meshes_keep_no_vertex_normals() {
        let mesh = |z: f32| {
            let raw = RawMesh {
                positions: vec![
                    Vec3A::new(0.0, 0.0, 0.0),
                    Vec3A::new(1.0, 0.0, 0.0),
                    Vec3A::new(1.0, 1.0, z),
                    Vec3A::new(0.0, 1.0, 0.0),
                ],
                normals: None,
                triangles: vec![[0, 1, 2], [0, 2, 3]],
                uvs: None,
                warnings: Vec::new(),
            };
            TriangleMesh::new(raw, &Mat4::IDENTITY, false, false, Path::new("quad")).unwrap()
        };
        let flat = mesh(0.0);
        assert!(flat.normals.is_none());
        let (_, n, sh_n) = flat.surface(1, 0.2, 0.3);
        assert_eq!(n, sh_n);
        assert!(mesh(1e-3).normals.is_some());
        // A mirroring transform keeps the check on the reversed winding.
        let raw = RawMesh {
            positions: vec![Vec3A::ZERO, Vec3A::X, Vec3A::Y],
            normals: Some(vec![Vec3A::Z; 3]),
            triangles: vec![[0, 1, 2]],
            uvs: None,
            warnings: Vec::new(),
        };
        let mirror = Mat4::from_scale(glam::Vec3::new(-1.0, 1.0, 1.0));
        let m = TriangleMesh::new(raw, &mirror, false, false, Path::new("tri")).unwrap();
        assert!(m.normals.is_none(), "{:?}", m.normals);
    }
}
