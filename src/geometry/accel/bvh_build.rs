//! The build of obvhs's compressed wide BVH (CWBVH) over the primitives' boxes: in one
//! piece below [`LARGE_MESH`], in chunks from there on.
//!
//! obvhs builds a binary BVH (PLOC, then reinsertion) and converts it to the wide one.
//! The conversion's cost table holds 7 decisions for each of the binary tree's 2n − 1
//! nodes: on a mesh of millions of triangles that table, the binary tree and PLOC's
//! buffers (each touched page a fault) were most of the load's time and twice Mitsuba
//! 3's peak memory. A large mesh is therefore cut along the Morton curve of its boxes'
//! centres into chunks of at most [`CHUNK`] primitives, whose wide BVHs are built one per
//! thread, and a top BVH over the chunks' boxes (one chunk a leaf) is stitched to
//! their roots: each top leaf becomes an inner child, the chunk's root.

use std::time::Duration;

use glam::{DVec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::cwbvh::CwBvh;
use obvhs::ploc::morton::morton_encode_u64_unorm;
use obvhs::BvhBuildParams;
use rayon::prelude::*;

/// From this many triangles a mesh is large: a quicker build (here and in Embree's
/// backend), and a render without Embree says what Embree would save.
pub(crate) const LARGE_MESH: usize = 1_000_000;

/// Primitives per chunk of a large mesh's build: small enough that a chunk's transients
/// stay in a few tens of MiB, large enough that the top BVH over the chunks is a few
/// levels.
pub(super) const CHUNK: usize = 1 << 18;

/// obvhs's BVH over `n` primitives whose boxes `prim_box` gives (its
/// `primitive_indices` give the leaf order).
pub(super) fn build(n: usize, prim_box: impl Fn(usize) -> Aabb + Sync) -> CwBvh {
    if n < LARGE_MESH {
        // The slowest build (most reinsertion): ~10% faster renders of the Bunny than
        // `medium_build`, for 0.25 s more on a 100k-triangle mesh. On a large mesh its
        // reinsertion grew to most of the load (a 5M-triangle sphere: 43 of 45 s) and
        // rendered no faster (docs/performance.md, "Large meshes without Embree"): its
        // chunks are `fast_build`s.
        let aabbs: Vec<Aabb> = (0..n).map(&prim_box).collect();
        return build_one(&aabbs, BvhBuildParams::very_slow_build());
    }
    build_chunked(n, prim_box, CHUNK)
}

/// One CWBVH over `aabbs`, obvhs's build with `params`.
fn build_one(aabbs: &[Aabb], params: BvhBuildParams) -> CwBvh {
    let params = BvhBuildParams {
        // Pre-splitting needs the triangles, not boxes.
        pre_split: false,
        ..params
    };
    build_cwbvh(aabbs, params, &mut Duration::default())
}

/// The BVH of a large mesh from chunks of at most `max_chunk` primitives, as many as
/// that asks for and of even sizes (so none is left with a handful): see the module's
/// note.
pub(super) fn build_chunked(
    n: usize,
    prim_box: impl Fn(usize) -> Aabb + Sync,
    max_chunk: usize,
) -> CwBvh {
    let chunk = n.div_ceil(n.div_ceil(max_chunk.max(1)).max(1)).max(1);
    let order = morton_order(n, &prim_box);
    let chunks: Vec<CwBvh> = order
        .par_chunks(chunk)
        .map(|ids| {
            let aabbs: Vec<Aabb> = ids.iter().map(|&i| prim_box(i as usize)).collect();
            build_one(&aabbs, BvhBuildParams::fast_build())
        })
        .collect();
    // A chunk's box is its root's: the union of its primitives' boxes.
    let boxes: Vec<Aabb> = chunks.iter().map(|c| c.total_aabb).collect();
    let top = (chunks.len() > 1).then(|| {
        let params = BvhBuildParams {
            max_prims_per_leaf: 1,
            ..BvhBuildParams::very_slow_build()
        };
        build_one(&boxes, params)
    });
    stitch(top, chunks, &order, chunk)
}

/// The primitives' indices in the Morton order of their boxes' centres (ties by index).
fn morton_order(n: usize, prim_box: &(impl Fn(usize) -> Aabb + Sync)) -> Vec<u32> {
    let centre = |i: usize| {
        let b = prim_box(i);
        (b.min + b.max) * 0.5
    };
    let (lo, hi) = (0..n)
        .into_par_iter()
        .fold(
            || (Vec3A::INFINITY, Vec3A::NEG_INFINITY),
            |(lo, hi), i| {
                let c = centre(i);
                (lo.min(c), hi.max(c))
            },
        )
        .reduce(
            || (Vec3A::INFINITY, Vec3A::NEG_INFINITY),
            |a, b| (a.0.min(b.0), a.1.max(b.1)),
        );
    let lo = lo.as_dvec3();
    // A flat extent (all centres in a plane) maps that axis to 0.
    let scale = (hi.as_dvec3() - lo).max(DVec3::splat(1e-30)).recip();
    let mut keyed: Vec<(u64, u32)> = (0..n)
        .into_par_iter()
        .map(|i| {
            let unit = ((centre(i).as_dvec3() - lo) * scale).clamp(DVec3::ZERO, DVec3::ONE);
            (morton_encode_u64_unorm(unit), i as u32)
        })
        .collect();
    keyed.par_sort_unstable();
    keyed.into_iter().map(|(_, i)| i).collect()
}

/// One CWBVH from the chunks' (chunk `c` holding `order[c · chunk ..]`'s primitives)
/// and the top BVH over their boxes with one chunk a leaf (None for a single chunk):
/// each top leaf becomes an inner child, that chunk's root, so the top node's children
/// are all inner and lie side by side (as the node format asks: child k of a node at
/// `child_base_idx` + the inner children before slot k).
fn stitch(top: Option<CwBvh>, chunks: Vec<CwBvh>, order: &[u32], chunk: usize) -> CwBvh {
    // Each chunk's leaf slots, in its own order, then the next chunk's.
    let mut primitive_indices = Vec::with_capacity(order.len());
    let mut first_slot = Vec::with_capacity(chunks.len());
    for (c, bvh) in chunks.iter().enumerate() {
        first_slot.push(primitive_indices.len() as u32);
        let ids = &order[c * chunk..];
        primitive_indices.extend(bvh.primitive_indices.iter().map(|&i| ids[i as usize]));
    }
    let Some(top) = top else {
        let one = chunks.into_iter().next().unwrap_or_default();
        return CwBvh {
            primitive_indices,
            ..one
        };
    };
    let total = chunks.iter().map(|c| c.nodes.len()).sum::<usize>() + top.nodes.len();
    let mut stitched = Stitched {
        nodes: vec![CwBvhNode::default()],
        top: &top,
        chunks: &chunks,
        first_slot: &first_slot,
    };
    stitched.nodes.reserve(total);
    stitched.place_top(0, 0);
    CwBvh {
        nodes: stitched.nodes,
        primitive_indices,
        total_aabb: top.total_aabb,
        exact_node_aabbs: None,
        uses_spatial_splits: false,
    }
}

struct Stitched<'a> {
    nodes: Vec<CwBvhNode>,
    top: &'a CwBvh,
    chunks: &'a [CwBvh],
    first_slot: &'a [u32],
}

impl Stitched<'_> {
    /// Top node `t` written at `at`, then its subtrees: its inner children and its
    /// leaves' chunks, side by side in slot order.
    fn place_top(&mut self, t: usize, at: usize) {
        let mut node = self.top.nodes[t];
        let base = self.nodes.len();
        let mut children = Vec::with_capacity(8);
        let mut inner = 0;
        for slot in 0..8 {
            let meta = node.child_meta[slot];
            if meta == 0 {
                continue;
            }
            if node.imask & (1 << slot) != 0 {
                children.push(Child::Top(node.child_base_idx as usize + inner));
                inner += 1;
            } else {
                // One chunk a leaf (the top's leaves hold one primitive): its slot
                // offset in the low 5 bits, the unary count 1 in the high 3.
                debug_assert_eq!(meta >> 5, 0b001);
                let leaf = node.primitive_base_idx as usize + (meta & 0b1_1111) as usize;
                children.push(Child::Chunk(self.top.primitive_indices[leaf] as usize));
                node.imask |= 1 << slot;
                node.child_meta[slot] = (24 + slot as u8) | 0b0010_0000;
            }
        }
        node.child_base_idx = base as u32;
        node.primitive_base_idx = 0;
        self.nodes[at] = node;
        self.nodes
            .resize(base + children.len(), CwBvhNode::default());
        for (k, child) in children.into_iter().enumerate() {
            match child {
                Child::Top(t) => self.place_top(t, base + k),
                Child::Chunk(c) => self.place_chunk(c, base + k),
            }
        }
    }

    /// Chunk `c`'s root at `at`, its other nodes after everything placed so far (their
    /// child and leaf indices shifted to where they now lie).
    fn place_chunk(&mut self, c: usize, at: usize) {
        let bvh = &self.chunks[c];
        // Node j ≥ 1 of the chunk lands at offset + j − 1; no node's child is the root,
        // and every child_base_idx is ≥ 1.
        let offset = self.nodes.len() as u32;
        let first_slot = self.first_slot[c];
        let shift = |mut n: CwBvhNode| {
            n.child_base_idx = n.child_base_idx + offset - 1;
            n.primitive_base_idx += first_slot;
            n
        };
        self.nodes[at] = shift(bvh.nodes[0]);
        self.nodes.extend(bvh.nodes[1..].iter().map(|&n| shift(n)));
    }
}

enum Child {
    Top(usize),
    Chunk(usize),
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::accel::triangle::LeafTriangle;
    use crate::sampling::Pcg32;
    use obvhs::ray::{Ray, RayHit};

    /// `n` small random triangles in the unit cube.
    fn soup(n: usize) -> Vec<LeafTriangle> {
        let mut rng = Pcg32::new(7, 1);
        let mut v = |s: f32| Vec3A::new(rng.next_1d(), rng.next_1d(), rng.next_1d()) * s;
        (0..n)
            .map(|_| {
                let p0 = v(1.0);
                LeafTriangle {
                    p0,
                    e1: v(0.05) - 0.025,
                    e2: v(0.05) - 0.025,
                }
            })
            .collect()
    }

    fn bounds(t: &LeafTriangle) -> Aabb {
        let mut b = Aabb::empty();
        for p in [t.p0, t.p0 + t.e1, t.p0 + t.e2] {
            b.extend(p);
        }
        b
    }

    /// The closest hit (t, triangle) along each ray, through `bvh` or (None) by testing
    /// every triangle.
    fn closest(tris: &[LeafTriangle], bvh: Option<&CwBvh>, o: Vec3A, d: Vec3A) -> (f32, u32) {
        let test =
            |i: usize, tmax: f32| tris[i].intersect(o, d, tmax).map_or(f32::INFINITY, |h| h.0);
        let Some(bvh) = bvh else {
            let mut best = (f32::INFINITY, u32::MAX);
            for i in 0..tris.len() {
                let t = test(i, best.0);
                if t < best.0 {
                    best = (t, i as u32);
                }
            }
            return best;
        };
        let mut hit = RayHit::none();
        bvh.ray_traverse(Ray::new_inf(o, d), &mut hit, |ray, slot| {
            test(bvh.primitive_indices[slot] as usize, ray.tmax)
        });
        let id = match hit.t.is_finite() {
            true => bvh.primitive_indices[hit.primitive_id as usize],
            false => u32::MAX,
        };
        (hit.t, id)
    }

    /// The chunked build is a valid CWBVH (obvhs's own check: every node's boxes hold
    /// its subtree, every primitive in one leaf) and finds the brute-force closest hit
    /// of 3,000 random rays, for one chunk, a top of one node, and tops of two and three
    /// levels. Power: the same rays through the build with one chunk's leaf indices
    /// left unshifted miss hits.
    #[test]
    fn chunked_build_finds_every_closest_hit() {
        let n = 20_000;
        let tris = soup(n);
        let boxes: Vec<Aabb> = tris.iter().map(bounds).collect();
        let mut rng = Pcg32::new(9, 2);
        let rays: Vec<(Vec3A, Vec3A)> = (0..3000)
            .map(|_| {
                let mut u = || rng.next_1d();
                let o = Vec3A::new(u(), u(), u()) * 3.0 - 1.0;
                let target = Vec3A::new(u(), u(), u());
                (o, (target - o).normalize())
            })
            .collect();
        let want: Vec<(f32, u32)> = rays
            .iter()
            .map(|&(o, d)| closest(&tris, None, o, d))
            .collect();
        assert!(want.iter().filter(|h| h.0.is_finite()).count() > 1000);
        for max_chunk in [n, 4000, 700, 90] {
            let bvh = build_chunked(n, |i| boxes[i], max_chunk);
            bvh.validate(&boxes, false);
            let mut seen = vec![false; n];
            for &i in &bvh.primitive_indices {
                assert!(
                    !std::mem::replace(&mut seen[i as usize], true),
                    "{max_chunk}: {i} twice"
                );
            }
            assert!(
                seen.iter().all(|&s| s),
                "{max_chunk}: a primitive in no leaf"
            );
            for (k, &(o, d)) in rays.iter().enumerate() {
                let got = closest(&tris, Some(&bvh), o, d);
                assert_eq!(got, want[k], "max_chunk {max_chunk}, ray {k}: {o} {d}");
            }
        }
        // Power: chunk 1's leaves read chunk 0's slots.
        let mut broken = build_chunked(n, |i| boxes[i], 4000);
        let shifted = broken
            .nodes
            .iter()
            .filter(|n| n.primitive_base_idx >= 4000)
            .count();
        assert!(shifted > 0);
        for node in &mut broken.nodes {
            if (4000..8000).contains(&node.primitive_base_idx) {
                node.primitive_base_idx -= 4000;
            }
        }
        let wrong = rays
            .iter()
            .zip(&want)
            .filter(|&(&(o, d), w)| closest(&tris, Some(&broken), o, d) != *w)
            .count();
        assert!(wrong > 50, "a broken stitch missed only {wrong} hits");
    }
}
