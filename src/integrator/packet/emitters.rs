//! Emitter samples from the packet's points: in lanes where the scene has one emitter of
//! a kind the packet samples ([`LaneEmitter`]), else by the scalar code lane by lane.

use glam::Vec3;
use wide::{CmpGt, CmpLt};

use super::lanes::{lanes_of, mask_of, L, V3, WIDTH};
use super::scene::{LaneEmitter, PacketScene};
use crate::geometry::shape::sample_sphere_cone;
use crate::geometry::SHADOW_EPSILON;
use crate::sampling::{mis_weight, Pcg32, Sampler};
use crate::scene::Scene;

/// Emitter samples from points of the lanes, before the shadow ray: direction,
/// distance, `L_e G / (pdf p_select)` (0 where nothing was sampled), the solid-angle
/// pdf with the selection's, and whether it is a delta light's (no MIS weight).
pub struct EmitterLanes {
    pub d: V3,
    pub dist: L,
    pub value: V3,
    pub some: L,
    pub pdf: L,
    pub delta: L,
}

impl EmitterLanes {
    /// These samples in the lanes of `mask`, `other`'s elsewhere.
    fn or(self, other: EmitterLanes, mask: L) -> EmitterLanes {
        EmitterLanes {
            d: other.d.select(mask, self.d),
            dist: mask.blend(self.dist, other.dist),
            value: other.value.select(mask, self.value),
            some: mask.blend(self.some, other.some),
            pdf: mask.blend(self.pdf, other.pdf),
            delta: mask.blend(self.delta, other.delta),
        }
    }

    /// The MIS weight against BSDF or phase sampling of pdf `other` (1 for a delta
    /// light).
    #[inline(always)]
    pub fn weight(&self, other: L) -> L {
        self.delta.blend(L::ONE, mis_weight(self.pdf, other))
    }
}

/// An emitter sample per lane of `mask` from its point `p`, one `next_2d` each: in
/// lanes where the scene has one emitter to pick of a kind the packet samples
/// ([`LaneEmitter`]), else by the scalar code per lane (`volpath`'s
/// `medium_emitter_sample` and `sample_light_at_surface` up to the shadow ray).
pub fn sample_emitters(
    scene: &Scene,
    ps: &PacketScene,
    p: V3,
    mask: L,
    rngs: &mut [Pcg32],
) -> EmitterLanes {
    let shorten = L::splat(1.0 - SHADOW_EPSILON);
    let lanes = |d: V3, dist: L, value: V3, some: L, pdf: L, delta: bool| EmitterLanes {
        d,
        dist: dist * shorten,
        some: mask & some & !value.is_zero(),
        value,
        pdf,
        delta: if delta { mask } else { L::ZERO },
    };
    match ps.lane_emitter {
        LaneEmitter::Point {
            position,
            intensity,
        } => {
            let _ = rngs.draw_2d(mask);
            let v = V3::splat(position).sub(p);
            let dist2 = v.dot(v);
            let dist = dist2.sqrt();
            let value = V3::splat(intensity).div(dist2);
            let some = dist2.cmp_gt(L::ZERO);
            return lanes(v.div(dist), dist, value, some, L::ONE, true);
        }
        LaneEmitter::Directional {
            toward,
            irradiance,
            bsphere: (center, radius),
        } => {
            let _ = rngs.draw_2d(mask);
            let c = p.sub(V3::splat(center));
            let r = L::splat(radius).max(c.dot(c).sqrt());
            let dist = L::splat(2.0) * r;
            return lanes(
                V3::splat(toward),
                dist,
                V3::splat(irradiance),
                mask,
                L::ONE,
                true,
            );
        }
        LaneEmitter::Rectangle {
            rows,
            normal,
            area,
            radiance,
        } => {
            // A point uniform on the rectangle; pdf_ω = pdf_A r² / |cos θ_light|, from
            // the front side only.
            let (u1, u2) = rngs.draw_2d(mask);
            let (x, y) = (L::splat(2.0) * u1 - L::ONE, L::splat(2.0) * u2 - L::ONE);
            let [px, py, pz] = rows.map(|r| L::splat(r.x) * x + L::splat(r.y) * y + L::splat(r.w));
            let v = V3 {
                x: px,
                y: py,
                z: pz,
            }
            .sub(p);
            let dist2 = v.dot(v);
            let dist = dist2.sqrt();
            let d = v.div(dist);
            let cos = V3::splat(normal).dot(d);
            let pdf = dist2 / (L::splat(area) * -cos);
            let some = cos.cmp_lt(L::ZERO) & pdf.is_finite() & pdf.cmp_gt(L::ZERO);
            let value = V3::splat(radiance).scale(some.blend(L::ONE / pdf, L::ZERO));
            return lanes(d, dist, value, some, pdf, false);
        }
        LaneEmitter::Sphere {
            center,
            radius,
            radiance,
        } => {
            let (u1, u2) = rngs.draw_2d(mask);
            let c = sample_cone(center, radius, p, u1, u2);
            let value = V3::splat(radiance).scale(c.ok.blend(L::ONE / c.pdf, L::ZERO));
            let out = lanes(c.d, c.dist, value, c.ok, c.pdf, false);
            let inside = mask & c.inside;
            if inside.any() {
                // A point inside the light (a path cannot be there but by rounding): its
                // area, by the scalar code, from the same draws.
                return per_lane(scene, p, inside, (u1, u2)).or(out, inside);
            }
            return out;
        }
        LaneEmitter::Scalar => {}
    }
    let u = rngs.draw_2d(mask);
    per_lane(scene, p, mask, u)
}

/// Emitter samples for the lanes of `mask` by the scalar code, lane by lane, from the
/// draws `u` (`emitter::selection`, then `Emitter::sample_direction`).
fn per_lane(scene: &Scene, p: V3, mask: L, (u1, u2): (L, L)) -> EmitterLanes {
    let (u1, u2) = (u1.to_array(), u2.to_array());
    let mut d = [Vec3::Z; WIDTH];
    let mut dist = [0f32; WIDTH];
    let mut value = [Vec3::ZERO; WIDTH];
    let mut pdf = [0f32; WIDTH];
    let mut delta = [false; WIDTH];
    for k in lanes_of(mask.move_mask()) {
        let u = glam::Vec2::new(u1[k], u2[k]);
        let pk = p.lane_a(k);
        let Some((idx, u, p_select)) = scene.emitter_selection.select(pk, u) else {
            continue;
        };
        let e = &scene.emitters[idx];
        if let Some(es) = e.sample_direction(pk, u, &scene.geometries, &scene.bsphere) {
            d[k] = Vec3::from(es.d);
            dist[k] = (es.p - pk).length() * (1.0 - SHADOW_EPSILON);
            value[k] = es.weight / p_select;
            pdf[k] = es.pdf * p_select;
            delta[k] = es.delta;
        }
    }
    let value = V3::from_fn(|k| value[k]);
    EmitterLanes {
        d: V3::from_fn(|k| d[k]),
        dist: L::from(dist),
        some: mask & !value.is_zero(),
        value,
        pdf: L::from(pdf),
        delta: mask_of(|k| delta[k]),
    }
}

/// A direction toward a sphere from [`sample_cone`].
pub struct ConeLanes {
    /// Unit direction from the reference point.
    pub d: V3,
    /// Distance to where it meets the sphere.
    pub dist: L,
    /// Solid-angle pdf.
    pub pdf: L,
    /// The lanes whose point sees the sphere from outside and whose sample is valid
    /// (the light's side faces it, the pdf is finite).
    pub ok: L,
    /// The lanes whose point is inside the sphere (deeper than the ray epsilon): the
    /// scalar code samples its area there.
    pub inside: L,
}

/// `geometry::shape::sample_sphere_cone` in lanes, with the lanes whose sample is valid.
#[inline(always)]
pub(super) fn sample_cone(center: Vec3, radius: f32, p: V3, u1: L, u2: L) -> ConeLanes {
    let c = sample_sphere_cone(V3::splat(center), radius, p, u1, u2);
    // The outward normal where it meets the sphere must face back along d.
    let toward_center = V3::splat(center).sub(p).sub(c.d.scale(c.dist));
    let ok = !c.inside
        & c.dist.cmp_gt(L::ZERO)
        & toward_center.dot(c.d).cmp_gt(L::ZERO)
        & c.pdf.is_finite();
    ConeLanes {
        d: c.d,
        dist: c.dist,
        pdf: c.pdf,
        ok,
        inside: c.inside,
    }
}
