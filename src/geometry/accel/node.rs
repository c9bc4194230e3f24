//! The ray against a CWBVH node: the ray the traversal is handed (started behind its
//! origin, past obvhs's clamp) and the AVX2 test of a node's eight child boxes.

use glam::Vec3A;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::ray::Ray as BvhRay;

/// obvhs's CWBVH node test clamps a box's entry distance to an absolute 1e-4
/// (`cwbvh::node::EPSILON`): a box the ray leaves within 1e-4 of its origin is culled.
/// That loses hits near the origin: every boundary of a scene scaled down, and in a
/// dense medium (σ_t 1e4: a mean free path is 1e-4) the mesh boundary next to a
/// scattering vertex, so the path walks out of the medium unseen.
pub(super) const NODE_TMIN: f32 = 1e-4;

/// The ray handed to the traversal: started `back` behind `o`, with `back` above the
/// node test's clamp even after rounding `o − back·d` to f32, so every box the true
/// ray meets at t ≥ 0 is visited. Primitives are still intersected with the true ray,
/// and their distances reported to the traversal as `t + back`.
#[inline(always)]
pub(super) fn traversal_ray(o: Vec3A, d: Vec3A, tmax: f32) -> (BvhRay, f32) {
    let back = 2.0 * NODE_TMIN + o.abs().max_element() * 1e-6;
    (BvhRay::new(o - d * back, d, 0.0, tmax + back), back)
}

/// Which children of a CWBVH node the ray meets, as obvhs's `intersect_ray` answers
/// (the hit mask `traverse!` reads). The same slab test on the node's quantized child
/// boxes, but all eight children in one AVX2 register: each axis's eight bytes widen to
/// floats in two instructions (obvhs builds them one by one, four at a time in SSE,
/// which it notes is the most expensive part of its test). Where AVX2 is not compiled
/// in, obvhs's own test.
#[inline(always)]
pub(super) fn node_hits(node: &CwBvhNode, ray: &BvhRay, oct_inv4: u32) -> u32 {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2"))]
    {
        use std::arch::x86_64::*;
        // Child box planes are p + extent · q for the byte q: along axis k the ray is at
        // t = (p + e q − o) / d = q · (e / d) + (p − o) / d.
        let scale = node.compute_extent() * ray.inv_direction;
        let offset = (Vec3A::from(node.p) - ray.origin) * ray.inv_direction;
        // SAFETY: AVX2 is enabled at compile time (the cfg above); the loads
        // read the 8 bytes of an [u8; 8].
        let mask = unsafe {
            let widen = |q: &[u8; 8]| {
                _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(
                    q.as_ptr() as *const __m128i
                )))
            };
            // (near, far) planes' distances on one axis: a negative direction meets
            // the max plane first.
            let axis = |lo: &[u8; 8], hi: &[u8; 8], negative: bool, scale: f32, offset: f32| {
                let (near, far) = if negative { (hi, lo) } else { (lo, hi) };
                let (s, o) = (_mm256_set1_ps(scale), _mm256_set1_ps(offset));
                // FMA (obvhs multiplies, then adds: 3-5% slower renders of the Bunny
                // and Lucy). It rounds once where obvhs rounds twice, so a box the ray
                // grazes to within that rounding may be answered otherwise; either
                // answer is right, as quantized child boxes are padded by far more.
                (
                    _mm256_fmadd_ps(widen(near), s, o),
                    _mm256_fmadd_ps(widen(far), s, o),
                )
            };
            let d = ray.direction;
            let (x0, x1) = axis(
                &node.child_min_x,
                &node.child_max_x,
                d.x < 0.0,
                scale.x,
                offset.x,
            );
            let (y0, y1) = axis(
                &node.child_min_y,
                &node.child_max_y,
                d.y < 0.0,
                scale.y,
                offset.y,
            );
            let (z0, z1) = axis(
                &node.child_min_z,
                &node.child_max_z,
                d.z < 0.0,
                scale.z,
                offset.z,
            );
            // In obvhs's order, so a NaN (0 · ∞ on an axis the ray runs along) falls out
            // the same way: max/min answer their second operand when one is NaN.
            let t_near = _mm256_max_ps(x0, _mm256_max_ps(y0, z0));
            let t_far = _mm256_min_ps(x1, _mm256_min_ps(y1, z1));
            let t_near = _mm256_max_ps(t_near, _mm256_set1_ps(NODE_TMIN));
            let t_far = _mm256_min_ps(t_far, _mm256_set1_ps(ray.tmax));
            _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t_near, t_far)) as u32
        };
        // Per child met: its bits (1 for an inner node, the unary primitive count for a
        // leaf) shifted to its place in the hit mask (see obvhs's CwBvhNode).
        let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
        let mut hit_mask = 0u32;
        let mut m = mask;
        while m != 0 {
            let shift = 8 * m.trailing_zeros();
            m &= m - 1;
            let bits = ((child_bits8 >> shift) & 0xff) as u32;
            let index = ((bit_index8 >> shift) & 0xff) as u32;
            hit_mask |= bits << index;
        }
        hit_mask
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
    {
        node.intersect_ray(ray, oct_inv4)
    }
}
