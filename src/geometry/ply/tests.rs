//! The reader against hand-made files: every encoding and the property types, orders
//! and names it accepts give the same mesh; what it refuses names what is wrong.

use super::*;

/// A file under the temporary folder, removed when dropped.
struct TempPly(std::path::PathBuf);

impl TempPly {
    fn new(name: &str, bytes: &[u8]) -> TempPly {
        let dir = std::env::temp_dir().join(format!("mediareg_ply_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        TempPly(path)
    }
}

impl Drop for TempPly {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

fn read(name: &str, bytes: &[u8]) -> Result<RawMesh> {
    read_ply(&TempPly::new(name, bytes).0)
}

fn error(name: &str, bytes: &[u8]) -> String {
    let e = read(name, bytes).expect_err("the file should be refused");
    let msg = e.to_string();
    assert!(msg.contains(name), "{msg}");
    msg
}

/// A quad, fan-triangulated, with normals and texture coordinates.
fn quad_positions() -> Vec<Vec3A> {
    vec![
        Vec3A::new(0.0, 0.0, 0.0),
        Vec3A::new(1.0, 0.0, 0.0),
        Vec3A::new(1.0, 1.0, 0.5),
        Vec3A::new(0.1, 1.0, -0.25),
    ]
}

const QUAD_HEADER_TAIL: &str =
    "element face 2\nproperty list uchar int vertex_indices\nend_header\n";

/// The quad in binary: vertex properties `props` (name, type) in that order, the values
/// of x y z nx ny nz u v looked up by name (0 for others), in `big`-endian order.
fn binary_quad(big: bool, props: &[(&str, &str)]) -> Vec<u8> {
    let format = if big {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let mut h = format!("ply\nformat {format} 1.0\ncomment made by a test\nelement vertex 4\n");
    for (name, ty) in props {
        h += &format!("property {ty} {name}\n");
    }
    h += "element face 2\nproperty list uchar int vertex_indices\nend_header\n";
    let mut b = h.into_bytes();
    for (i, p) in quad_positions().iter().enumerate() {
        for (name, ty) in props {
            let v = match *name {
                "x" => p.x,
                "y" => p.y,
                "z" => p.z,
                "nz" => 1.0,
                "u" => 0.25 * i as f32,
                "v" => 0.5,
                _ => 0.0,
            };
            match (*ty, big) {
                ("float", false) => b.extend(v.to_le_bytes()),
                ("float", true) => b.extend(v.to_be_bytes()),
                ("double", false) => b.extend((v as f64).to_le_bytes()),
                ("double", true) => b.extend((v as f64).to_be_bytes()),
                ("uchar", _) => b.push(7),
                _ => unreachable!(),
            }
        }
    }
    for face in [[0i32, 1, 2], [0, 2, 3]] {
        b.push(3);
        for i in face {
            b.extend(if big {
                i.to_be_bytes()
            } else {
                i.to_le_bytes()
            });
        }
    }
    b
}

#[test]
fn every_encoding_and_property_order_gives_the_same_mesh() {
    let plain = [("x", "float"), ("y", "float"), ("z", "float")];
    let reference = read("plain.ply", &binary_quad(false, &plain)).unwrap();
    assert_eq!(reference.positions, quad_positions());
    assert_eq!(reference.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    assert!(reference.normals.is_none() && reference.uvs.is_none());
    assert_eq!(
        read("big.ply", &binary_quad(true, &plain))
            .unwrap()
            .positions,
        quad_positions()
    );
    // Shuffled, with doubles, a skipped property, normals and texture coordinates.
    let shuffled = [
        ("nz", "float"),
        ("z", "double"),
        ("red", "uchar"),
        ("u", "float"),
        ("x", "float"),
        ("ny", "float"),
        ("v", "double"),
        ("y", "float"),
        ("nx", "float"),
    ];
    for big in [false, true] {
        let m = read("shuffled.ply", &binary_quad(big, &shuffled)).unwrap();
        assert_eq!(m.positions, quad_positions());
        assert_eq!(m.triangles, reference.triangles);
        assert_eq!(m.normals, Some(vec![Vec3A::Z; 4]));
        let uvs: Vec<Vec2> = (0..4).map(|i| Vec2::new(0.25 * i as f32, 0.5)).collect();
        assert_eq!(m.uvs, Some(uvs));
    }
    let ascii = format!(
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n{QUAD_HEADER_TAIL}0 0 0\n1 0 0\n1 1 0.5\n0.1 1 -0.25\n3 0 1 2\n3 0 2 3\n"
    );
    let m = read("ascii.ply", ascii.as_bytes()).unwrap();
    assert_eq!(
        (m.positions, m.triangles),
        (reference.positions, reference.triangles)
    );
}

/// Quads and polygons fan-triangulated, under `vertex_index` with ushort counts and
/// uint indices, integer positions, CRLF lines and other elements around.
#[test]
fn polygons_other_elements_and_integer_types() {
    let text = "ply\r\nformat ascii 1.0\r\nelement material 1\r\nproperty list uchar float rgb\r\nelement vertex 5\r\nproperty int x\r\nproperty short y\r\nproperty uchar z\r\nelement face 2\r\nproperty uchar flags\r\nproperty list ushort uint vertex_index\r\nelement edge 1\r\nproperty int a\r\nend_header\r\n3 0.5 0.5 0.5\r\n0 0 0\r\n1 0 0\r\n1 1 0\r\n0 1 0\r\n-1 -1 9\r\n0 5 0 1 2 3 4\r\n1 3 1 2 4\r\n0\r\n";
    let m = read("polygon.ply", text.as_bytes()).unwrap();
    assert_eq!(m.positions[4], Vec3A::new(-1.0, -1.0, 9.0));
    assert_eq!(
        m.triangles,
        vec![[0, 1, 2], [0, 2, 3], [0, 3, 4], [1, 2, 4]]
    );
    assert!(m.warnings.is_empty());
}

#[test]
fn refusals_name_the_file_and_the_fault() {
    let head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
    let face = "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    let body = "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    let cases: [(String, &str); 11] = [
        ("plx\n".into(), "not a PLY file"),
        (format!("{head}{face}0 0 0\n1 0 0\n"), "cannot parse PLY"),
        (format!("{head}{face}0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n"), "face 0 refers to vertex 3, but the mesh has 3 vertices"),
        (format!("{head}{face}0 0 0\n1 0 0\n0 1 0\n2 0 1\n"), "face 0 has 2 vertices"),
        (format!("{head}end_header\n{body}"), "no \"face\" element"),
        (format!("ply\nformat ascii 1.0\n{face}3 0 1 2\n"), "no \"vertex\" element"),
        (
            format!("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n{face}{body}"),
            "lacks numeric x, y, z",
        ),
        (
            format!("{head}element face 1\nproperty list uchar float vertex_indices\nend_header\n{body}"),
            "face 0 has no vertex_indices list",
        ),
        (format!("{head}element face 0\nend_header\n0 0 0\n1 0 0\n0 1 0\n"), "mesh has no faces"),
        (head.replace("vertex 3", "vertex 99999999999"), "below 2^32"),
        (head.replace("1.0", "1"), "not a version number"),
    ];
    for (text, expected) in cases {
        let msg = error("bad.ply", text.as_bytes());
        assert!(msg.contains(expected), "{expected:?} not in {msg}");
    }
    // Binary: a truncated payload and a negative list length.
    let mut b = binary_quad(false, &[("x", "float"), ("y", "float"), ("z", "float")]);
    b.truncate(b.len() - 3);
    assert!(error("short.ply", &b).contains("ascii vs binary"));
    let mut b = binary_quad(false, &[("x", "float"), ("y", "float"), ("z", "float")]);
    let first_face = b.len() - 26;
    b[first_face] = 0;
    assert!(error("empty_face.ply", &b).contains("face 0 has 0 vertices"));
}

/// A header that declares far more than the file holds is refused without reserving
/// memory for what it declares.
#[test]
fn huge_declared_counts_in_a_small_file() {
    let text = "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\nproperty float z\nelement face 4000000000\nproperty list uint int vertex_indices\nend_header\n\0\0\0\0";
    assert!(error("huge.ply", text.as_bytes()).contains("cannot parse PLY"));
}

/// PLY texture coordinates are read under Mitsuba's names (here `s`, `t`), unflipped.
#[test]
fn ply_texture_coordinates() {
    let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float s\nproperty float t\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 0.1 0.2\n1 0 0 0.9 0.2\n0 1 0 0.1 0.8\n3 0 1 2\n";
    let m = read("tri_uv.ply", text.as_bytes()).unwrap();
    let uvs = [(0.1, 0.2), (0.9, 0.2), (0.1, 0.8)].map(|(u, v)| Vec2::new(u, v));
    assert_eq!(m.uvs, Some(uvs.to_vec()));
}

/// A mesh whose arrays cannot fit in the memory available is refused before anything is
/// read, naming what it needs and what there is; the memory is an argument, so the test
/// does not depend on the host's. A mesh of T triangles and V vertices needs at least
/// T·44 + V·32 bytes (`mesh::check_fits`). Power: with that much available it is read,
/// with an unknown amount (off Linux) too, and the same header on a file too short for
/// its counts fails as truncated, not for memory.
#[test]
fn a_mesh_that_cannot_fit_is_refused_before_reading() {
    let header = |faces: u64, vertices: u64| {
        format!(
            "ply\nformat binary_little_endian 1.0\nelement vertex {vertices}\nproperty float x\n\
             property float y\nproperty float z\nelement face {faces}\n\
             property list uchar int vertex_indices\nend_header\n"
        )
    };
    let (faces, vertices) = (100u64, 102u64);
    let mut bytes = header(faces, vertices).into_bytes();
    let short = bytes.clone();
    for i in 0..vertices {
        let a = i as f32 * 0.1;
        for x in [a.cos(), a.sin(), 0.0f32] {
            bytes.extend_from_slice(&x.to_le_bytes());
        }
    }
    for i in 0..faces as i32 {
        bytes.push(3);
        for v in [0, i + 1, i + 2] {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    let file = TempPly::new("fits_or_not.ply", &bytes);
    let need = faces * 44 + vertices * 32;
    let msg = read_ply_within(&file.0, Some(need - 1))
        .expect_err("refused")
        .to_string();
    assert!(
        msg.contains("fits_or_not.ply")
            && msg.contains("GiB of memory")
            && msg.contains("available"),
        "{msg}"
    );
    for available in [Some(need), None] {
        let m =
            read_ply_within(&file.0, available).unwrap_or_else(|e| panic!("{available:?}: {e}"));
        assert_eq!(m.triangles.len(), faces as usize);
    }
    // The same counts in a file that holds only the header: a truncation.
    let file = TempPly::new("short.ply", &short);
    let msg = read_ply_within(&file.0, Some(0))
        .expect_err("truncated")
        .to_string();
    assert!(!msg.contains("GiB"), "{msg}");
}
