//! Emitter samples from the packet's points: in lanes where the scene has one emitter of
//! a kind the packet samples ([`LaneEmitter`]), else by the scalar code lane by lane.

use glam::Vec3;

use super::lanes::{lanes_of, mask_of, L, V3, WIDTH};
use super::scene::{LaneEmitter, PacketScene};
use crate::emitter::direction::{
    along_direction, toward_area_point, toward_point, toward_sphere, DirectionSample,
};
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
/// ([`LaneEmitter`]: `emitter::direction`'s kernels, which the scalar code runs), else
/// by the scalar code per lane (`volpath`'s `medium_emitter_sample` and
/// `sample_light_at_surface` up to the shadow ray).
pub fn sample_emitters(
    scene: &Scene,
    ps: &PacketScene,
    p: V3,
    mask: L,
    rngs: &mut [Pcg32],
) -> EmitterLanes {
    let lanes = |s: DirectionSample<L>, delta: bool| EmitterLanes {
        d: s.d,
        dist: s.dist * L::splat(1.0 - SHADOW_EPSILON),
        some: mask & s.valid & !s.weight.is_zero(),
        value: s.weight,
        pdf: s.pdf,
        delta: if delta { mask } else { L::ZERO },
    };
    let u = rngs.draw_2d(mask);
    match &ps.lane_emitter {
        LaneEmitter::Point {
            position,
            intensity,
        } => lanes(toward_point(V3::splat(*position), *intensity, p), true),
        LaneEmitter::Directional {
            toward,
            irradiance,
            bsphere,
        } => lanes(along_direction(*toward, *irradiance, *bsphere, p), true),
        LaneEmitter::Rectangle { light, radiance } => {
            let at = (
                light.rectangle_point(u.0, u.1),
                V3::splat(light.normal.into()),
            );
            lanes(
                toward_area_point(at, L::splat(light.area), *radiance, p),
                false,
            )
        }
        LaneEmitter::Sphere {
            center,
            radius,
            radiance,
        } => {
            let (s, inside) = toward_sphere((*center, *radius, false), *radiance, p, u);
            let out = lanes(s, false);
            let inside = mask & inside;
            if inside.any() {
                // A point inside the light (a path cannot be there but by rounding): its
                // area, by the scalar code, from the same draws.
                return per_lane(scene, p, inside, u).or(out, inside);
            }
            out
        }
        LaneEmitter::Scalar => per_lane(scene, p, mask, u),
    }
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
