//! Triangle meshes: PLY (ply-rs) and OBJ (tobj) readers, Mitsuba's `cube`, vertex
//! normals, ray–triangle intersection and uniform area sampling.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

use glam::{Mat4, Vec2, Vec3A};

use crate::error::{Loc, Result, SceneError};

/// A triangle mesh in world space.
#[derive(Clone, Debug)]
pub struct TriangleMesh {
    pub positions: Vec<Vec3A>,
    /// Per-vertex shading normals; `None` with `face_normals` and for a flat mesh.
    pub normals: Option<Vec<Vec3A>>,
    pub triangles: Vec<[u32; 3]>,
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

fn mesh_error(path: &Path, msg: impl Into<String>) -> SceneError {
    SceneError::new(Some(Loc::file_only(path)), msg.into())
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

/// Element counts (and the format's version numbers) in the header must be numbers
/// below 2³²: ply-rs panics on one that overflows u64, and no mesh this renderer can
/// hold has more.
fn check_ply_counts(path: &Path, bytes: &[u8]) -> Result<()> {
    use std::io::BufRead;
    let mut line = Vec::new();
    let mut reader = bytes;
    for number in 1..=10_000 {
        line.clear();
        match reader.read_until(b'\n', &mut line) {
            Ok(0) | Err(_) => break,
            Ok(_) => {}
        }
        let text = String::from_utf8_lossy(&line);
        let words: Vec<&str> = text.split_whitespace().collect();
        // ply-rs converts a run of digits as soon as its grammar matches it, before it
        // knows whether the rest of the line parses.
        let overflows = |w: &str| {
            let digits: String = w.chars().take_while(|c| c.is_ascii_digit()).collect();
            !digits.is_empty() && digits.parse::<u32>().is_err()
        };
        match words[..] {
            ["end_header"] => break,
            ["element", name, count, ..] if overflows(count) => {
                return Err(mesh_error(
                    path,
                    format!("PLY header line {number}: element \"{name}\" has count \"{count}\"; expected a number below 2^32"),
                ));
            }
            ["format", _, version, ..] if version.split('.').any(overflows) => {
                return Err(mesh_error(
                    path,
                    format!("PLY header line {number}: format version \"{version}\" is not a version number such as 1.0"),
                ));
            }
            _ => {}
        }
    }
    Ok(())
}

/// Reads a PLY file (ASCII or binary): vertex x, y, z and optional nx, ny, nz; faces from
/// `vertex_indices` (or `vertex_index`), polygons fan-triangulated.
pub fn read_ply(path: &Path) -> Result<RawMesh> {
    use ply_rs::parser::Parser;
    use ply_rs::ply::{DefaultElement, Property};
    // One read of the file serves the header check, the parser and the trailing-data check.
    let bytes =
        std::fs::read(path).map_err(|e| mesh_error(path, format!("cannot open PLY file: {e}")))?;
    check_ply_counts(path, &bytes)?;
    let (payload, trailing) = guarded(path, "PLY", || {
        let mut reader = bytes.as_slice();
        // Header and payload from one reader (read_ply would buffer past the payload).
        let parser = Parser::<DefaultElement>::new();
        let payload = parser
            .read_header(&mut reader)
            .and_then(|header| parser.read_payload(&mut reader, &header))
            .map_err(|e| {
                mesh_error(
                    path,
                    format!(
                        "cannot parse PLY file: {e} (the data ends before the element counts \
                         its header declares, or is not in the header's format: ascii vs binary)"
                    ),
                )
            })?;
        // Data past the declared elements: Mitsuba ignores it, and so does this reader,
        // but a header count that is too small is worth a word.
        Ok((payload, reader.iter().any(|b| !b.is_ascii_whitespace())))
    })?;

    let scalar = |p: &Property| -> Option<f64> {
        Some(match p {
            Property::Char(v) => *v as f64,
            Property::UChar(v) => *v as f64,
            Property::Short(v) => *v as f64,
            Property::UShort(v) => *v as f64,
            Property::Int(v) => *v as f64,
            Property::UInt(v) => *v as f64,
            Property::Float(v) => *v as f64,
            Property::Double(v) => *v,
            _ => return None,
        })
    };
    let list = |p: &Property| -> Option<Vec<i64>> {
        Some(match p {
            Property::ListChar(v) => v.iter().map(|&x| x as i64).collect(),
            Property::ListUChar(v) => v.iter().map(|&x| x as i64).collect(),
            Property::ListShort(v) => v.iter().map(|&x| x as i64).collect(),
            Property::ListUShort(v) => v.iter().map(|&x| x as i64).collect(),
            Property::ListInt(v) => v.iter().map(|&x| x as i64).collect(),
            Property::ListUInt(v) => v.iter().map(|&x| x as i64).collect(),
            _ => return None,
        })
    };

    let vertices = payload
        .get("vertex")
        .ok_or_else(|| mesh_error(path, "PLY file has no \"vertex\" element"))?;
    let mut positions = Vec::with_capacity(vertices.len());
    let mut normals = Vec::new();
    let has_normals = vertices
        .first()
        .is_some_and(|v| v.contains_key("nx") && v.contains_key("ny") && v.contains_key("nz"));
    // Texture coordinates under any of the names Mitsuba's PLY reader accepts.
    let uv_names = [
        ("u", "v"),
        ("s", "t"),
        ("texture_u", "texture_v"),
        ("texture_s", "texture_t"),
    ]
    .into_iter()
    .find(|(a, b)| {
        vertices
            .first()
            .is_some_and(|v| v.contains_key(*a) && v.contains_key(*b))
    });
    let mut uvs = Vec::new();
    for (i, v) in vertices.iter().enumerate() {
        let get = |k: &str| v.get(k).and_then(scalar);
        if let Some((a, b)) = uv_names {
            let (Some(u), Some(w)) = (get(a), get(b)) else {
                return Err(mesh_error(
                    path,
                    format!("PLY vertex {i} lacks numeric {a}, {b}"),
                ));
            };
            uvs.push(Vec2::new(u as f32, w as f32));
        }
        let (Some(x), Some(y), Some(z)) = (get("x"), get("y"), get("z")) else {
            return Err(mesh_error(
                path,
                format!("PLY vertex {i} lacks numeric x, y, z"),
            ));
        };
        positions.push(Vec3A::new(x as f32, y as f32, z as f32));
        if has_normals {
            let (Some(nx), Some(ny), Some(nz)) = (get("nx"), get("ny"), get("nz")) else {
                return Err(mesh_error(
                    path,
                    format!("PLY vertex {i} lacks numeric nx, ny, nz"),
                ));
            };
            normals.push(Vec3A::new(nx as f32, ny as f32, nz as f32));
        }
    }
    let faces = payload
        .get("face")
        .ok_or_else(|| mesh_error(path, "PLY file has no \"face\" element"))?;
    let mut polys = Vec::with_capacity(faces.len());
    for (i, f) in faces.iter().enumerate() {
        let idx = f
            .get("vertex_indices")
            .or_else(|| f.get("vertex_index"))
            .and_then(list)
            .ok_or_else(|| mesh_error(path, format!("PLY face {i} has no vertex_indices list")))?;
        polys.push(idx);
    }
    let triangles = triangulate(path, &polys, positions.len())?;
    let mut warnings = Vec::new();
    if trailing {
        warnings.push(format!(
            "{}: data after the {} vertices and {} faces the header declares is ignored (as Mitsuba does); is a count in the header too small?",
            path.display(),
            positions.len(),
            polys.len()
        ));
    }
    Ok(RawMesh {
        positions,
        normals: has_normals.then_some(normals),
        triangles,
        uvs: uv_names.map(|_| uvs),
        warnings,
    })
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
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    let mut all_have_normals = true;
    let mut uvs = Vec::new();
    let mut all_have_uvs = true;
    let mut polys = Vec::new();
    for m in &models {
        let mesh = &m.mesh;
        let base = positions.len() as i64;
        let nv = mesh.positions.len() / 3;
        for i in 0..nv {
            let p = &mesh.positions[3 * i..3 * i + 3];
            positions.push(Vec3A::new(p[0], p[1], p[2]));
        }
        if mesh.normals.len() == mesh.positions.len() {
            for i in 0..nv {
                let n = &mesh.normals[3 * i..3 * i + 3];
                normals.push(Vec3A::new(n[0], n[1], n[2]));
            }
        } else {
            all_have_normals = false;
        }
        if mesh.texcoords.len() == 2 * nv {
            uvs.extend(mesh.texcoords.chunks(2).map(|t| Vec2::new(t[0], t[1])));
        } else {
            all_have_uvs = false;
        }
        for tri in mesh.indices.chunks(3) {
            polys.push(tri.iter().map(|&i| i as i64 + base).collect::<Vec<_>>());
        }
    }
    let triangles = triangulate(path, &polys, positions.len())?;
    Ok(RawMesh {
        positions,
        normals: (all_have_normals && !normals.is_empty()).then_some(normals),
        triangles,
        uvs: (all_have_uvs && !uvs.is_empty()).then_some(uvs),
        warnings: Vec::new(),
    })
}

/// Checks indices and fan-triangulates polygons.
fn triangulate(path: &Path, polys: &[Vec<i64>], n_vertices: usize) -> Result<Vec<[u32; 3]>> {
    let mut tris = Vec::with_capacity(polys.len());
    for (i, poly) in polys.iter().enumerate() {
        if poly.len() < 3 {
            return Err(mesh_error(
                path,
                format!("face {i} has {} vertices (at least 3 needed)", poly.len()),
            ));
        }
        for &v in poly {
            if v < 0 || v as usize >= n_vertices {
                return Err(mesh_error(
                    path,
                    format!(
                        "face {i} refers to vertex {v}, but the mesh has {n_vertices} vertices"
                    ),
                ));
            }
        }
        for k in 1..poly.len() - 1 {
            tris.push([poly[0] as u32, poly[k] as u32, poly[k + 1] as u32]);
        }
    }
    if tris.is_empty() {
        return Err(mesh_error(path, "mesh has no faces"));
    }
    Ok(tris)
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
        let positions: Vec<Vec3A> = raw
            .positions
            .iter()
            .map(|&p| to_world.transform_point3a(p))
            .collect();
        if positions.iter().any(|p| !p.is_finite()) {
            return Err(mesh_error(path, "mesh has a non-finite vertex position"));
        }
        // A mirroring transform would turn the geometric normals inward: Mitsuba reverses
        // the winding then, so they keep pointing where the file's winding said.
        let mut raw = raw;
        if to_world.determinant() < 0.0 {
            for t in &mut raw.triangles {
                t.swap(1, 2);
            }
        }
        let normals = if face_normals {
            None
        } else {
            let inv_t = to_world.inverse().transpose();
            Some(match raw.normals {
                Some(ns) => ns
                    .iter()
                    .map(|&n| inv_t.transform_vector3a(n).normalize_or_zero())
                    .collect(),
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
            positions,
            normals,
            triangles: raw.triangles,
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

    /// PLY texture coordinates are read under Mitsuba's names (here `s`, `t`), unflipped.
    #[test]
    fn ply_texture_coordinates() {
        let dir = std::env::temp_dir().join(format!("mediareg_ply_uv_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("tri.ply");
        std::fs::write(
            &path,
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float s\nproperty float t\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 0.1 0.2\n1 0 0 0.9 0.2\n0 1 0 0.1 0.8\n3 0 1 2\n",
        )
        .unwrap();
        let m = read_ply(&path).unwrap();
        assert_eq!(
            m.uvs,
            Some(vec![
                Vec2::new(0.1, 0.2),
                Vec2::new(0.9, 0.2),
                Vec2::new(0.1, 0.8)
            ])
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
