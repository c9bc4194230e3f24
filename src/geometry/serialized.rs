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

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
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

/// Reads mesh `shape_index` of the `.serialized` file at `path`: only that mesh's
/// stream is read, inflated as it is decoded (a file of many meshes, each a shape of
/// the scene, is then read about once in all, and no copy of it is held).
pub fn read_serialized(path: &Path, shape_index: u32) -> Result<RawMesh> {
    let fail = |msg: String| error(path, shape_index, msg);
    let open_error = |e: std::io::Error| fail(format!("cannot open the file: {e}"));
    let mut file = File::open(path).map_err(open_error)?;
    let len = file.metadata().map_err(open_error)?.len();
    let mut header = [0u8; 4];
    if file.read_exact(&mut header).is_err() {
        return Err(fail("the file is shorter than its 4-byte header".into()));
    }
    let magic = u16::from_le_bytes([header[0], header[1]]);
    let version = u16::from_le_bytes([header[2], header[3]]);
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
        mesh_offset(&mut file, len, version, shape_index).map_err(fail)?
    };
    // Each mesh repeats the 4-byte header before its stream.
    file.seek(SeekFrom::Start(start + 4))
        .map_err(|e| fail(format!("cannot read the file: {e}")))?;
    let budget = (len - start - 4) * MAX_EXPANSION;
    let mut r = Reader {
        z: ZlibDecoder::new(BufReader::new(file)),
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
    super::mesh::check_fits(
        path,
        face_count,
        vertex_count,
        super::mesh::available_memory(),
    )?;
    let (nv, nf) = (vertex_count as usize, face_count as usize);

    let vec3 = |c: [f32; 3]| Vec3A::from_array(c);
    let positions = r.reals(nv, real, vec3).map_err(truncated)?;
    let normals = match flags & HAS_NORMALS != 0 {
        true => Some(r.reals(nv, real, vec3).map_err(truncated)?),
        false => None,
    };
    let uvs = match flags & HAS_TEXCOORDS != 0 {
        true => Some(r.reals(nv, real, Vec2::from_array).map_err(truncated)?),
        false => None,
    };
    if flags & HAS_COLORS != 0 {
        r.reals(nv, real, |_: [f32; 3]| ()).map_err(truncated)?;
    }
    let triangles = r
        .records(nf, 12, |c| {
            [0, 1, 2].map(|k| u32::from_le_bytes(c[4 * k..4 * k + 4].try_into().unwrap()))
        })
        .map_err(truncated)?;
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

/// The byte offset of mesh `index` from the dictionary at the end of the file (`len`
/// bytes long).
fn mesh_offset(
    file: &mut File,
    len: u64,
    version: u16,
    index: u32,
) -> std::result::Result<u64, String> {
    let mut read_at = |at: u64, n: usize| -> std::result::Result<[u8; 8], String> {
        let mut b = [0u8; 8];
        file.seek(SeekFrom::Start(at))
            .and_then(|_| file.read_exact(&mut b[..n]))
            .map_err(|e| {
                format!("cannot read the dictionary of meshes at the end of the file: {e}")
            })?;
        Ok(b)
    };
    let count_at = len
        .checked_sub(4)
        .ok_or("the file has no dictionary of meshes at its end")?;
    let b = read_at(count_at, 4)?;
    let count = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    if index >= count {
        return Err(format!(
            "the file holds {count} mesh(es), indices 0..{}; shape_index {index} is out of range",
            count.saturating_sub(1)
        ));
    }
    let entry: u64 = if version == 4 { 8 } else { 4 };
    let from_end = entry * (count - index) as u64 + 4;
    let at = len
        .checked_sub(from_end)
        .ok_or("the dictionary of meshes at the end of the file is truncated")?;
    let b = read_at(at, entry as usize)?;
    let offset = match version {
        4 => u64::from_le_bytes(b),
        _ => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as u64,
    };
    Some(offset)
        .filter(|&o| o.checked_add(4).is_some_and(|e| e <= len))
        .ok_or_else(|| format!("mesh {index} starts at byte {offset}, past the end of the file"))
}

/// A mesh's stream, inflated as it is read.
struct Reader {
    z: ZlibDecoder<BufReader<File>>,
}

/// Records decoded per chunk of this many bytes (the inflated arrays are never held
/// whole beside the decoded ones).
const CHUNK: usize = 1 << 16;

impl Reader {
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

    /// `n` records of `size` bytes each, each decoded by `decode`.
    fn records<T>(
        &mut self,
        n: usize,
        size: usize,
        mut decode: impl FnMut(&[u8]) -> T,
    ) -> std::io::Result<Vec<T>> {
        let mut out = Vec::with_capacity(n);
        let mut buf = vec![0u8; (CHUNK / size).max(1) * size];
        let mut left = n;
        while left > 0 {
            let take = left.min(buf.len() / size);
            let chunk = &mut buf[..take * size];
            self.z.read_exact(chunk)?;
            out.extend(chunk.chunks_exact(size).map(&mut decode));
            left -= take;
        }
        Ok(out)
    }

    /// `n` vectors of D reals (f32, or f64 where `real` is 8, narrowed), mapped by `f`.
    fn reals<const D: usize, T>(
        &mut self,
        n: usize,
        real: u64,
        f: impl Fn([f32; D]) -> T,
    ) -> std::io::Result<Vec<T>> {
        let real = real as usize;
        self.records(n, D * real, |c| {
            f(std::array::from_fn(|k| match real {
                8 => f64::from_le_bytes(c[8 * k..8 * k + 8].try_into().unwrap()) as f32,
                _ => f32::from_le_bytes(c[4 * k..4 * k + 4].try_into().unwrap()),
            }))
        })
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
