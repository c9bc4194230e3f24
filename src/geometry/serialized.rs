//! Mitsuba's `.serialized` meshes (`src/shapes/serialized.cpp`), little endian:
//!
//! ```text
//! u16 0x041C, u16 version (3 or 4), then a zlib stream:
//!   u32 flags (0x1 normals, 0x2 texture coordinates, 0x8 colours, 0x2000 f64 data)
//!   version 4: the shape's name, a NUL-terminated string
//!   u64 vertex count, u64 triangle count
//!   positions (xyz), [normals (xyz)], [uv], [colours (rgb)]: f32, or f64 with 0x2000
//!   triangles: u32 × 3
//! ```
//!
//! A file may hold several meshes, each with its own header and stream; it ends with a
//! dictionary of their offsets (u64 in version 4, u32 in version 3) and their count (u32).
//! `shape_index` picks one. As in Mitsuba 3, vertex colours are skipped and the 0x10
//! (face normals) flag is not read: the `face_normals` property decides.

use std::io::Read;
use std::path::Path;

use flate2::read::ZlibDecoder;
use glam::{Vec2, Vec3A};

use super::mesh::RawMesh;
use crate::error::{Loc, Result, SceneError};

const MAGIC: u16 = 0x041C;
const HAS_NORMALS: u32 = 0x0001;
const HAS_TEXCOORDS: u32 = 0x0002;
const HAS_COLORS: u32 = 0x0008;
const DOUBLE_PRECISION: u32 = 0x2000;
/// zlib expands at most ~1032:1, so a stream of n bytes cannot hold more than this many
/// times n bytes: larger counts are corrupt, refused before allocating for them.
const MAX_EXPANSION: u64 = 1100;

fn error(path: &Path, shape_index: u32, msg: impl Into<String>) -> SceneError {
    SceneError::new(
        Some(Loc::file_only(path)),
        format!(
            "serialized mesh (shape_index {shape_index}): {}",
            msg.into()
        ),
    )
}

/// Reads mesh `shape_index` of the `.serialized` file at `path`.
pub fn read_serialized(path: &Path, shape_index: u32) -> Result<RawMesh> {
    let fail = |msg: String| error(path, shape_index, msg);
    let bytes = std::fs::read(path).map_err(|e| fail(format!("cannot open the file: {e}")))?;
    let u16_at = |o: usize| {
        bytes
            .get(o..o + 2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]))
    };
    let (Some(magic), Some(version)) = (u16_at(0), u16_at(2)) else {
        return Err(fail("the file is shorter than its 4-byte header".into()));
    };
    if magic != MAGIC {
        return Err(fail(format!(
            "not a Mitsuba .serialized file (it starts with 0x{magic:04X}, expected 0x041C)"
        )));
    }
    if version != 3 && version != 4 {
        return Err(fail(format!(
            "format version {version} is not supported (Mitsuba writes versions 3 and 4)"
        )));
    }
    let start = if shape_index == 0 {
        0
    } else {
        mesh_offset(&bytes, version, shape_index).map_err(fail)?
    };
    // Each mesh repeats the 4-byte header before its stream.
    let stream = bytes.get(start + 4..).ok_or_else(|| {
        fail(format!(
            "the offset of the mesh ({start}) is past the end of the file"
        ))
    })?;
    let budget = stream.len() as u64 * MAX_EXPANSION;
    let mut r = Reader {
        z: ZlibDecoder::new(stream),
    };
    let truncated = |e: std::io::Error| {
        fail(format!(
            "the compressed data is truncated or corrupt ({e}); re-export the mesh"
        ))
    };

    let flags = r.u32().map_err(truncated)?;
    if version == 4 {
        // The shape's name: NUL-terminated (bounded, so a corrupt file cannot run on).
        let mut n = 0;
        while r.u8().map_err(truncated)? != 0 {
            n += 1;
            if n > 1 << 16 {
                return Err(fail("the shape's name has no end (corrupt file)".into()));
            }
        }
    }
    let vertex_count = r.u64().map_err(truncated)?;
    let face_count = r.u64().map_err(truncated)?;
    let real = if flags & DOUBLE_PRECISION != 0 { 8 } else { 4 };
    let per_vertex = 3
        + if flags & HAS_NORMALS != 0 { 3 } else { 0 }
        + if flags & HAS_TEXCOORDS != 0 { 2 } else { 0 }
        + if flags & HAS_COLORS != 0 { 3 } else { 0 };
    let needed = vertex_count
        .checked_mul(per_vertex * real)
        .and_then(|v| face_count.checked_mul(12).and_then(|f| v.checked_add(f)));
    if vertex_count > u32::MAX as u64 || needed.is_none_or(|n| n > budget) {
        return Err(fail(format!(
            "{vertex_count} vertices and {face_count} triangles cannot fit in this file (corrupt counts)"
        )));
    }
    super::mesh::check_fits(path, face_count, vertex_count)?;
    let (nv, nf) = (vertex_count as usize, face_count as usize);

    let mut read_reals = |dim: usize| -> Result<Vec<f32>> {
        let mut raw = vec![0u8; nv * dim * real as usize];
        r.z.read_exact(&mut raw).map_err(truncated)?;
        Ok(if real == 8 {
            raw.chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().unwrap()) as f32)
                .collect()
        } else {
            raw.chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
                .collect()
        })
    };
    let positions: Vec<Vec3A> = read_reals(3)?
        .chunks_exact(3)
        .map(|c| Vec3A::new(c[0], c[1], c[2]))
        .collect();
    let normals = if flags & HAS_NORMALS != 0 {
        Some(
            read_reals(3)?
                .chunks_exact(3)
                .map(|c| Vec3A::new(c[0], c[1], c[2]))
                .collect::<Vec<_>>(),
        )
    } else {
        None
    };
    let uvs = if flags & HAS_TEXCOORDS != 0 {
        Some(
            read_reals(2)?
                .chunks_exact(2)
                .map(|c| Vec2::new(c[0], c[1]))
                .collect::<Vec<_>>(),
        )
    } else {
        None
    };
    if flags & HAS_COLORS != 0 {
        read_reals(3)?;
    }
    let mut raw = vec![0u8; nf * 12];
    r.z.read_exact(&mut raw).map_err(truncated)?;
    let triangles: Vec<[u32; 3]> = raw
        .chunks_exact(12)
        .map(|c| [0, 1, 2].map(|k| u32::from_le_bytes(c[4 * k..4 * k + 4].try_into().unwrap())))
        .collect();
    if let Some((i, t)) = triangles
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&v| v as usize >= nv))
    {
        return Err(fail(format!(
            "triangle {i} refers to vertex {} but the mesh has {nv} vertices",
            t.iter().max().unwrap()
        )));
    }
    Ok(RawMesh {
        positions,
        normals,
        triangles,
        uvs,
        warnings: Vec::new(),
    })
}

/// The byte offset of mesh `index` from the dictionary at the end of the file.
fn mesh_offset(bytes: &[u8], version: u16, index: u32) -> std::result::Result<usize, String> {
    let len = bytes.len();
    let count = len
        .checked_sub(4)
        .map(|o| u32::from_le_bytes(bytes[o..o + 4].try_into().unwrap()))
        .ok_or("the file has no dictionary of meshes at its end")?;
    if index >= count {
        return Err(format!(
            "the file holds {count} mesh(es), indices 0..{}; shape_index {index} is out of range",
            count.saturating_sub(1)
        ));
    }
    let entry = if version == 4 { 8 } else { 4 };
    let from_end = entry * (count - index) as usize + 4;
    let at = len
        .checked_sub(from_end)
        .ok_or("the dictionary of meshes at the end of the file is truncated")?;
    let offset = if version == 4 {
        u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap())
    } else {
        u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as u64
    };
    usize::try_from(offset)
        .ok()
        .filter(|&o| o + 4 <= len)
        .ok_or_else(|| format!("mesh {index} starts at byte {offset}, past the end of the file"))
}

struct Reader<'a> {
    z: ZlibDecoder<&'a [u8]>,
}

impl Reader<'_> {
    fn bytes<const N: usize>(&mut self) -> std::io::Result<[u8; N]> {
        let mut b = [0u8; N];
        self.z.read_exact(&mut b)?;
        Ok(b)
    }
    fn u8(&mut self) -> std::io::Result<u8> {
        Ok(self.bytes::<1>()?[0])
    }
    fn u32(&mut self) -> std::io::Result<u32> {
        Ok(u32::from_le_bytes(self.bytes()?))
    }
    fn u64(&mut self) -> std::io::Result<u64> {
        Ok(u64::from_le_bytes(self.bytes()?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use flate2::write::ZlibEncoder;
    use flate2::Compression;
    use std::io::Write;

    /// One mesh's bytes (header + zlib stream): a unit right triangle pair with uvs.
    fn mesh_bytes(version: u16, double: bool, shift: f32) -> Vec<u8> {
        let mut s = Vec::new();
        let flags = HAS_TEXCOORDS | HAS_COLORS | if double { DOUBLE_PRECISION } else { 0 };
        s.extend(flags.to_le_bytes());
        if version == 4 {
            s.extend(b"quad\0");
        }
        s.extend(4u64.to_le_bytes());
        s.extend(2u64.to_le_bytes());
        let real = |s: &mut Vec<u8>, x: f32| {
            if double {
                s.extend((x as f64).to_le_bytes())
            } else {
                s.extend(x.to_le_bytes())
            }
        };
        let pos = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        for p in pos {
            for x in p {
                real(&mut s, x + shift);
            }
        }
        for p in pos {
            real(&mut s, p[0]);
            real(&mut s, p[1]);
        }
        for _ in 0..12 {
            real(&mut s, 0.5); // colours, skipped
        }
        for i in [0u32, 1, 2, 0, 2, 3] {
            s.extend(i.to_le_bytes());
        }
        let mut z = ZlibEncoder::new(Vec::new(), Compression::default());
        z.write_all(&s).unwrap();
        let mut out = Vec::new();
        out.extend(MAGIC.to_le_bytes());
        out.extend(version.to_le_bytes());
        out.extend(z.finish().unwrap());
        out
    }

    fn file_of(meshes: &[Vec<u8>], version: u16) -> Vec<u8> {
        let mut out = Vec::new();
        let mut offsets = Vec::new();
        for m in meshes {
            offsets.push(out.len() as u64);
            out.extend(m);
        }
        for o in &offsets {
            if version == 4 {
                out.extend(o.to_le_bytes());
            } else {
                out.extend((*o as u32).to_le_bytes());
            }
        }
        out.extend((meshes.len() as u32).to_le_bytes());
        out
    }

    fn write(name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("mediareg-serialized-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join(name);
        std::fs::write(&p, bytes).unwrap();
        p
    }

    #[test]
    fn reads_every_mesh_of_a_file_in_both_versions_and_precisions() {
        for version in [3u16, 4] {
            for double in [false, true] {
                let file = file_of(
                    &[
                        mesh_bytes(version, double, 0.0),
                        mesh_bytes(version, double, 10.0),
                    ],
                    version,
                );
                let p = write(&format!("v{version}_{double}.serialized"), &file);
                for (index, shift) in [(0u32, 0.0f32), (1, 10.0)] {
                    let m = read_serialized(&p, index).unwrap();
                    assert_eq!(m.positions.len(), 4);
                    assert_eq!(m.positions[2], Vec3A::new(1.0, 1.0, 0.0) + shift);
                    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
                    assert_eq!(m.uvs.as_ref().unwrap()[3], Vec2::new(0.0, 1.0));
                    assert!(m.normals.is_none());
                }
                let e = read_serialized(&p, 2).unwrap_err().to_string();
                assert!(
                    e.contains("holds 2 mesh(es)") && e.contains("out of range"),
                    "{e}"
                );
            }
        }
    }

    #[test]
    fn bad_files_are_refused_with_the_reason() {
        let good = file_of(&[mesh_bytes(4, false, 0.0)], 4);
        let cases: Vec<(&str, Vec<u8>, &str)> = vec![
            ("short", vec![0x1C], "shorter than its 4-byte header"),
            (
                "magic",
                [&[0u8, 0][..], &good[2..]].concat(),
                "not a Mitsuba .serialized",
            ),
            (
                "version",
                [&good[..2], &[9u8, 0][..], &good[4..]].concat(),
                "version 9",
            ),
            (
                "truncated",
                good[..good.len() / 2].to_vec(),
                "truncated or corrupt",
            ),
            (
                "garbage",
                [&good[..4], &[0xFFu8; 64][..]].concat(),
                "truncated or corrupt",
            ),
        ];
        for (name, bytes, want) in cases {
            let p = write(&format!("{name}.serialized"), &bytes);
            let e = read_serialized(&p, 0).unwrap_err().to_string();
            assert!(e.contains(want), "{name}: {e}");
            assert!(
                e.contains(&format!("{name}.serialized")),
                "{name}: names the file: {e}"
            );
        }
        let missing = read_serialized(Path::new("/nonexistent/x.serialized"), 0).unwrap_err();
        assert!(missing.to_string().contains("cannot open"), "{missing}");
    }

    #[test]
    fn corrupt_counts_and_indices_are_refused_before_allocating() {
        // A version-4 file of one mesh: flags 0, an empty name, the counts, then `data`.
        let file = |vertices: u64, faces: u64, data: &[u8]| {
            let mut s = Vec::new();
            s.extend(0u32.to_le_bytes());
            s.extend(b"\0");
            s.extend(vertices.to_le_bytes());
            s.extend(faces.to_le_bytes());
            s.extend(data);
            let mut z = ZlibEncoder::new(Vec::new(), Compression::default());
            z.write_all(&s).unwrap();
            [
                &MAGIC.to_le_bytes()[..],
                &4u16.to_le_bytes(),
                &z.finish().unwrap(),
            ]
            .concat()
        };
        // 2^40 vertices claimed.
        let p = write("huge.serialized", &file(1 << 40, 1, &[]));
        let e = read_serialized(&p, 0).unwrap_err().to_string();
        assert!(e.contains("cannot fit"), "{e}");
        // A triangle that names vertex 7 of 3.
        let mut data = vec![0u8; 36];
        for i in [0u32, 1, 7] {
            data.extend(i.to_le_bytes());
        }
        let p = write("index.serialized", &file(3, 1, &data));
        let e = read_serialized(&p, 0).unwrap_err().to_string();
        assert!(e.contains("refers to vertex 7"), "{e}");
    }
}
