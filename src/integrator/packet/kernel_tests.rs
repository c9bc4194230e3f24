//! The physics kernels in lanes against the same kernels on one path: each is one
//! generic function, run here over `f32x8` and over `f32` lane by lane on random
//! inputs. Where a kernel uses only +, −, ×, ÷, √, min, max and selects, each lane must
//! equal the scalar result bit for bit (IEEE rounds each the same in a register and in
//! a lane). Where it takes exp, ln or sin/cos, the lanes use `wide`'s polynomials and
//! the scalar path libm's: there a stated bound in ulp (or, for results that cross 0,
//! an absolute one) applies.

use glam::Vec3;
use wide::f32x8;

use crate::bsdf::fresnel::fresnel;
use crate::emitter::direction::{
    along_direction, toward_area_point, toward_point, toward_sphere, DirectionSample,
};
use crate::geometry::cuboid::{affine_rows, slabs};
use crate::geometry::shape::{plane_hit, sample_sphere_cone, Planar};
use crate::geometry::{affine_point, affine_vector};
use crate::geometry::{around, coordinate_system, to_world};
use crate::integrator::roulette::continue_probability;
use crate::medium::heterogeneous::{
    null_weight, ratio_roulette, ratio_weight, real_probability, real_weight,
};
use crate::medium::phase::{direction_at, hg_eval, hg_log_derivative_g, hg_sample};
use crate::medium::tracking::{optical_depth, MajorantSegment};
use crate::medium::{
    collision_weight, collision_weight_d_sigma, expected_pass_weight, pass_weight, sample_distance,
    transmittance_rgb,
};
use crate::sampling::warp::cosine_hemisphere;
use crate::sampling::{mis_weight, Pcg32};
use crate::simd::{Float, Vector3};

type L = f32x8;
const W: usize = 8;
const TRIALS: usize = 2000;

/// How far a lane may be from the scalar result.
#[derive(Clone, Copy, Debug)]
enum Bound {
    /// The same bits (NaN equal to NaN).
    Exact,
    /// Within this many ulp, or this far absolutely (for results near 0, where an ulp
    /// is tiny).
    Near { ulp: u32, abs: f32 },
}

fn ulp_distance(a: f32, b: f32) -> u32 {
    let key = |x: f32| {
        let i = x.to_bits() as i32;
        if i < 0 {
            i32::MIN - i
        } else {
            i
        }
    };
    (key(a) as i64 - key(b) as i64)
        .unsigned_abs()
        .min(u32::MAX as u64) as u32
}

fn agrees(a: f32, b: f32, bound: Bound) -> bool {
    if a.is_nan() || b.is_nan() {
        return a.is_nan() && b.is_nan();
    }
    match bound {
        Bound::Exact => a.to_bits() == b.to_bits(),
        Bound::Near { ulp, abs } => a == b || ulp_distance(a, b) <= ulp || (a - b).abs() <= abs,
    }
}

/// Runs `lanes` on [`W`] input tuples drawn by `draw` and `scalar` on each tuple alone,
/// [`TRIALS`] times, and checks every output of every lane against the scalar one.
/// Returns the largest ulp distance and the largest absolute difference seen.
fn check<const I: usize>(
    name: &str,
    bound: Bound,
    draw: impl Fn(&mut Pcg32) -> [f32; I],
    lanes: impl Fn([L; I]) -> Vec<L>,
    scalar: impl Fn([f32; I]) -> Vec<f32>,
) -> (u32, f32) {
    let mut rng = Pcg32::new(54, name.len() as u64);
    let (mut worst, mut worst_abs) = (0, 0f32);
    for _ in 0..TRIALS {
        let inputs: [[f32; I]; W] = std::array::from_fn(|_| draw(&mut rng));
        let lane_in: [L; I] =
            std::array::from_fn(|i| L::from(std::array::from_fn(|k| inputs[k][i])));
        let out = lanes(lane_in);
        for (k, input) in inputs.iter().enumerate() {
            let want = scalar(*input);
            assert_eq!(want.len(), out.len(), "{name}: outputs");
            for (j, w) in want.iter().enumerate() {
                let got = out[j].to_array()[k];
                assert!(
                    agrees(got, *w, bound),
                    "{name}, output {j}, inputs {input:?}: lane {got} against scalar {w} ({bound:?})"
                );
                if !got.is_nan() {
                    worst = worst.max(ulp_distance(got, *w));
                    worst_abs = worst_abs.max((got - w).abs());
                }
            }
        }
    }
    (worst, worst_abs)
}

fn v3<F: crate::simd::Float>(a: F, b: F, c: F) -> Vector3<F> {
    Vector3::new(a, b, c)
}

fn out3<F: Copy>(v: Vector3<F>) -> Vec<F> {
    vec![v.x, v.y, v.z]
}

/// A unit vector from three draws.
fn unit(rng: &mut Pcg32) -> [f32; 3] {
    let v = Vec3::new(
        rng.next_1d() - 0.5,
        rng.next_1d() - 0.5,
        rng.next_1d() - 0.5,
    )
    .normalize_or(Vec3::Z);
    v.to_array()
}

/// Values with zeros, ones and the edges among them, as kernels meet them.
fn value(rng: &mut Pcg32, lo: f32, hi: f32) -> f32 {
    match (rng.next_1d() * 16.0) as u32 {
        0 => lo,
        1 => hi,
        _ => lo + (hi - lo) * rng.next_1d(),
    }
}

/// A mask as a number: 1 where set.
fn mask_value<F: Float>(m: F::Mask) -> F {
    F::select(m, F::one(), F::zero())
}

fn fresnel_all<F: Float>([c, eta]: [F; 2]) -> Vec<F> {
    let (a, b, c, d) = fresnel(c, eta);
    vec![a, b, c, d]
}

fn hg_all<F: Float>([g, c, u]: [F; 3]) -> Vec<F> {
    let (w, p) = hg_sample(g, u);
    vec![hg_eval(g, c), w, p, hg_log_derivative_g(g, F::one() - c)]
}

fn frame_all<F: Float>([x, y, z, a, b, c]: [F; 6]) -> Vec<F> {
    let (s, t) = coordinate_system(v3(x, y, z));
    [out3(s), out3(t), out3(to_world(v3(x, y, z), v3(a, b, c)))].concat()
}

fn weights_all<F: Float>([t0, t1, t2, s0, s1, s2, r0, r1, r2]: [F; 9]) -> Vec<F> {
    let (tr, sigma, r) = (v3(t0, t1, t2), v3(s0, s1, s2), v3(r0, r1, r2));
    [
        out3(collision_weight(tr, sigma, s0, t0)),
        out3(collision_weight_d_sigma(tr, sigma, r1, s0, t0)),
        out3(pass_weight(tr, t1)),
        out3(expected_pass_weight(tr, t2, r)),
        vec![continue_probability(tr, sigma, r0), mis_weight(s1, s2)],
    ]
    .concat()
}

fn tracking_all<F: Float>([a, b, c, major, m]: [F; 5]) -> Vec<F> {
    let sigma = v3(a, b, c);
    let (nw, stuck) = null_weight(sigma, major);
    let (play, end) = ratio_roulette(m);
    [
        vec![real_probability(sigma, major)],
        out3(real_weight(sigma)),
        out3(nw),
        vec![mask_value::<F>(stuck)],
        out3(ratio_weight(sigma, major)),
        vec![mask_value::<F>(play), mask_value::<F>(end)],
    ]
    .concat()
}

fn next_collision_all<F: Float>([t, u, sigma_maj, t_max]: [F; 4]) -> Vec<F> {
    let segment = MajorantSegment {
        t_min: F::zero(),
        t_max,
        sigma_maj,
    };
    let (next, inside) = segment.next_collision(t, optical_depth(u));
    vec![next, mask_value::<F>(inside)]
}

fn directions_all<F: Float>([x, y, z, w, u]: [F; 5]) -> Vec<F> {
    let n = v3(x, y, z);
    let w = w * F::of(2.0);
    let (c, s) = (F::one() - w, (w * (F::of(2.0) - w)).max(F::zero()).sqrt());
    [out3(direction_at(n, w, u)), out3(around(n, c, s, u))].concat()
}

fn cone_all<F: Float>([x, y, z, u1, u2]: [F; 5]) -> Vec<F> {
    let c = sample_sphere_cone(Vector3::splat(Vec3::ZERO), 0.9, v3(x, y, z), u1, u2);
    [out3(c.d), vec![c.dist, c.pdf]].concat()
}

fn direction_out<F: Float>(s: DirectionSample<F>) -> Vec<F> {
    [
        out3(s.d),
        vec![s.dist, s.pdf],
        out3(s.weight),
        vec![mask_value::<F>(s.valid)],
    ]
    .concat()
}

/// A rectangle light tilted off the axes, lit on its front only.
fn rectangle_light() -> Planar {
    let to_world = glam::Mat4::from_scale_rotation_translation(
        Vec3::new(0.7, 1.3, 1.0),
        glam::Quat::from_euler(glam::EulerRot::XYZ, 0.4, -0.3, 1.1),
        Vec3::new(0.2, 0.1, 1.5),
    );
    Planar::new(to_world, false, false)
}

/// A turned, stretched box's map to its [-1, 1]³.
fn box_to_local() -> glam::Affine3A {
    glam::Affine3A::from_scale_rotation_translation(
        Vec3::new(0.6, 1.1, 0.8),
        glam::Quat::from_euler(glam::EulerRot::XYZ, -0.7, 0.2, 0.5),
        Vec3::new(0.1, -0.2, 0.3),
    )
    .inverse()
}

/// A ray from `(x, y, z)` along the unit `(a, b, c)` against the box (its slab test), a
/// turned rectangle and disk, each mapped to the shape's space by its
/// rows (`geometry::affine_point`, `affine_vector`).
fn shapes_all<F: Float>([x, y, z, a, b, c]: [F; 6]) -> Vec<F> {
    let (o, d) = (v3(x, y, z), v3(a, b, c));
    let rows = affine_rows(&box_to_local());
    let s = slabs(affine_point(&rows, o), affine_vector(&rows, d));
    let light = rectangle_light();
    let rows = [0, 1, 2].map(|k| light.to_local.row(k));
    let (ol, dl) = (affine_point(&rows, o), affine_vector(&rows, d));
    let (on_rect, t_rect) = plane_hit(ol, dl, false, F::of(f64::INFINITY));
    let (on_disk, t_disk) = plane_hit(ol, dl, true, F::of(3.0));
    [
        out3(ol),
        out3(dl),
        vec![s.t_near, s.t_far, s.near_axis, s.far_axis],
        vec![
            mask_value::<F>(on_rect),
            t_rect,
            mask_value::<F>(on_disk),
            t_disk,
        ],
    ]
    .concat()
}

/// The rows of an affine map applied as `geometry::affine_point`/`affine_vector` apply
/// them are glam's `transform_point3a`/`transform_vector3a`, bit for bit: the one path
/// maps rays into a shape's space with glam, the lanes with the rows.
#[test]
fn affine_rows_apply_as_glam_does() {
    let mut rng = Pcg32::new(3, 9);
    let box_map = box_to_local();
    let box_rows = affine_rows(&box_map);
    let plane_map = rectangle_light().to_local;
    let plane_rows = [0, 1, 2].map(|k| plane_map.row(k));
    let bits = |v: glam::Vec3A| v.to_array().map(f32::to_bits);
    for _ in 0..20_000 {
        let far = value(&mut rng, 0.0, 50.0);
        let p = glam::Vec3A::from(unit(&mut rng)) * far;
        let q: Vector3<f32> = p.into();
        let same = |a: Vector3<f32>, b: glam::Vec3A| bits(a.into()) == bits(b);
        assert!(
            same(affine_point(&box_rows, q), box_map.transform_point3a(p)),
            "{p}"
        );
        assert!(
            same(affine_vector(&box_rows, q), box_map.transform_vector3a(p)),
            "{p}"
        );
        assert!(
            same(affine_point(&plane_rows, q), plane_map.transform_point3a(p)),
            "{p}"
        );
        assert!(
            same(
                affine_vector(&plane_rows, q),
                plane_map.transform_vector3a(p)
            ),
            "{p}"
        );
    }
}

/// The point, directional and rectangle lights' samples from `(x, y, z)` (the
/// rectangle's from the draws `(u1, u2)`).
fn emitters_all<F: Float>([x, y, z, u1, u2]: [F; 5]) -> Vec<F> {
    let p = v3(x, y, z);
    let rgb = Vec3::new(0.5, 2.0, 7.0);
    let point = toward_point(Vector3::splat(Vec3::new(0.3, -0.2, 0.9)), rgb, p);
    let bounds = (Vec3::new(0.1, 0.2, -0.3), 1.7);
    let directional = along_direction(Vec3::new(0.0, 0.6, 0.8), rgb, bounds, p);
    let light = rectangle_light();
    let on = (
        light.rectangle_point(u1, u2),
        Vector3::splat(light.normal.into()),
    );
    let area = toward_area_point(on, F::of(light.area as f64), rgb, p);
    [
        direction_out(point),
        direction_out(directional),
        direction_out(area),
    ]
    .concat()
}

/// A sphere light's sample from `(x, y, z)`, and whether that is inside it.
fn sphere_light_all<F: Float>([x, y, z, u1, u2]: [F; 5]) -> Vec<F> {
    let light = (Vec3::new(0.1, 0.0, -0.1), 0.9, false);
    let (s, inside) = toward_sphere(light, Vec3::new(3.0, 1.0, 0.5), v3(x, y, z), (u1, u2));
    [direction_out(s), vec![mask_value::<F>(inside)]].concat()
}

#[test]
fn exact_kernels_equal_the_scalar_path_in_every_lane() {
    let exact = Bound::Exact;
    check(
        "fresnel",
        exact,
        |r| {
            [
                value(r, -1.0, 1.0),
                [1.0, 1.33, 1.5, 0.7][(r.next_1d() * 4.0) as usize % 4],
            ]
        },
        fresnel_all::<L>,
        fresnel_all::<f32>,
    );
    check(
        "hg",
        exact,
        |r| [value(r, -0.95, 0.95), value(r, -1.0, 1.0), r.next_1d()],
        hg_all::<L>,
        hg_all::<f32>,
    );
    check(
        "cosine_hemisphere",
        exact,
        |r| [value(r, 0.0, 1.0), value(r, 0.0, 1.0)],
        |[a, b]| out3(cosine_hemisphere::<L>(a, b)),
        |[a, b]| out3(cosine_hemisphere::<f32>(a, b)),
    );
    check(
        "coordinate_system and to_world",
        exact,
        |r| {
            let [x, y, z] = unit(r);
            let [a, b, c] = unit(r);
            [x, y, z, a, b, c]
        },
        frame_all::<L>,
        frame_all::<f32>,
    );
    check(
        "hero-channel weights, roulette, MIS",
        exact,
        |r| {
            [
                value(r, 0.0, 1.0),
                value(r, 0.01, 1.0),
                value(r, 0.0, 1.0),
                value(r, 0.1, 4.0),
                value(r, 0.0, 4.0),
                value(r, 0.0, 4.0),
                value(r, 0.5, 2.0),
                value(r, 0.5, 2.0),
                value(r, 0.5, 2.0),
            ]
        },
        weights_all::<L>,
        weights_all::<f32>,
    );
    // Rays from inside the shapes and outside, some along the axes (parallel to faces).
    check(
        "slab test and plane hits",
        exact,
        |r| {
            let far = value(r, 0.0, 4.0);
            let [x, y, z] = unit(r);
            let [a, b, c] = match (r.next_1d() * 8.0) as u32 {
                0 => [0.0, 0.0, 1.0],
                1 => [1.0, 0.0, 0.0],
                _ => unit(r),
            };
            [x * far, y * far, z * far, a, b, c]
        },
        shapes_all::<L>,
        shapes_all::<f32>,
    );
    // Points near the lights (and on them, as a draw of 0 or 1 puts them) and far.
    check(
        "emitter directions: point, directional, rectangle",
        exact,
        |r| {
            let [x, y, z] = unit(r);
            let far = value(r, 0.0, 30.0);
            [
                x * far,
                y * far,
                z * far,
                value(r, 0.0, 1.0),
                value(r, 0.0, 1.0),
            ]
        },
        emitters_all::<L>,
        emitters_all::<f32>,
    );
    check(
        "tracking steps",
        exact,
        |r| {
            [
                value(r, 0.0, 3.0),
                value(r, 0.0, 3.0),
                value(r, 0.0, 3.0),
                3.0,
                value(r, 0.0, 0.2),
            ]
        },
        tracking_all::<L>,
        tracking_all::<f32>,
    );
}

/// exp, ln, sin and cos: `wide`'s polynomials in lanes, libm on one path. The flights
/// and transmittances were measured at most 2 ulp apart; the directions (sin and cos
/// of the azimuth, in unit vectors whose components cross 0, where an ulp is tiny)
/// within 1.2e-7 absolute. Bounded here by 4 ulp or 5e-7.
#[test]
fn transcendental_kernels_stay_within_a_few_ulp_of_the_scalar_path() {
    let near = Bound::Near { ulp: 4, abs: 5e-7 };
    let mut worst = Vec::new();
    worst.push(check(
        "sample_distance",
        near,
        |r| [value(r, 0.0, 5.0), r.next_1d()],
        |[s, u]| vec![sample_distance(s, u)],
        |[s, u]| vec![sample_distance(s, u)],
    ));
    worst.push(check(
        "next_collision",
        near,
        |r| {
            [
                value(r, 0.0, 2.0),
                r.next_1d(),
                value(r, 0.1, 5.0),
                value(r, 0.5, 3.0),
            ]
        },
        |[t, u, m, e]| next_collision_all([t, u, m, e]),
        |[t, u, m, e]| next_collision_all([t, u, m, e]),
    ));
    worst.push(check(
        "transmittance",
        near,
        |r| {
            [
                value(r, 0.0, 3.0),
                value(r, 0.0, 3.0),
                value(r, 0.0, 3.0),
                value(r, 0.0, 4.0),
            ]
        },
        |[a, b, c, t]| out3(transmittance_rgb(v3(a, b, c), t)),
        |[a, b, c, t]| out3(transmittance_rgb(v3(a, b, c), t)),
    ));
    worst.push(check(
        "around and direction_at",
        near,
        |r| {
            let [x, y, z] = unit(r);
            [x, y, z, r.next_1d(), r.next_1d()]
        },
        directions_all::<L>,
        directions_all::<f32>,
    ));
    // Points outside the sphere only (radius 0.9, distance ≥ 1): inside, the cone's
    // values mean nothing.
    worst.push(check(
        "sample_sphere_cone",
        near,
        |r| {
            let [x, y, z] = unit(r);
            let far = value(r, 1.0, 60.0);
            [x * far, y * far, z * far, r.next_1d(), r.next_1d()]
        },
        cone_all::<L>,
        cone_all::<f32>,
    ));
    // The sphere light from outside it (radius 0.9 about a point 0.14 from the origin).
    worst.push(check(
        "sphere light",
        near,
        |r| {
            let [x, y, z] = unit(r);
            let far = value(r, 1.1, 60.0);
            [x * far, y * far, z * far, r.next_1d(), r.next_1d()]
        },
        sphere_light_all::<L>,
        sphere_light_all::<f32>,
    ));
    println!("largest (ulp, absolute) differences: {worst:?}");
}

/// Power: the comparison sees a kernel changed in its last bit (Fresnel's R nudged one
/// ulp in the lanes only), and one whose transcendental is off by more than the bound.
#[test]
fn the_kernel_comparison_catches_a_one_ulp_change() {
    let caught = std::panic::catch_unwind(|| {
        check(
            "fresnel nudged",
            Bound::Exact,
            |r| [value(r, 0.05, 1.0), 1.5],
            |[c, eta]| vec![fresnel(c, eta).0 * L::splat(1.0 + f32::EPSILON)],
            |[c, eta]| vec![fresnel(c, eta).0],
        )
    });
    assert!(caught.is_err(), "a one-ulp change went unseen");
    let caught = std::panic::catch_unwind(|| {
        check(
            "exp off",
            Bound::Near { ulp: 4, abs: 5e-7 },
            |r| [value(r, 0.1, 3.0), value(r, 0.1, 2.0)],
            |[s, t]| vec![transmittance_rgb(v3(s, s, s), t).x * L::splat(1.0 + 8.0 * f32::EPSILON)],
            |[s, t]| vec![transmittance_rgb(v3(s, s, s), t).x],
        )
    });
    assert!(caught.is_err(), "an exp 8 ulp off went unseen");
}
