//! The hard-case matrix: a sphere or cube of homogeneous medium (null boundary) in a
//! white furnace (constant environment of radiance 1), over
//! albedo × sigma_t × g × camera outside/inside × scale.
//!
//! Every cell: no NaN, Inf or negative pixel, no dropped sample, and the image mean not
//! above the furnace bound 1 (scattering only redirects or removes light). Where the
//! answer is known exactly the image must match it statistically:
//! * albedo 1, no depth cap: every pixel is 1, to rounding. These cells run without
//!   Russian roulette (rr_depth beyond any path), so that every sample is exactly 1 unless
//!   the transport loses or makes light: the sky is found by phase sampling alone (no
//!   emitter sampling of a `constant` emitter), and roulette's 0-or-0.95^{−k} samples
//!   would be the only noise, a few rare kills per image whose absence the spread of the
//!   pixel means cannot show (a z-test on it gave z 3.4 at 16 spp and ~1 at 4096 spp on
//!   one cell). Roulette is tested in the other cells and by the furnace scene against
//!   Mitsuba (tests/volpath_equivalence.rs);
//! * albedo 0: each sample is a Bernoulli with mean e^{−σ_t · chord}; the pixel mean is
//!   that averaged over the pixel, computed here by quadrature; the variance is known.
//! * Scaled scenes (all lengths × s, sigma_t / s, near/far clip × s) must give the same
//!   image: the pixelwise difference to the unscaled render (another seed) has mean 0.
//! * The albedo gradient is rendered at albedo 0 and 1: finite, and never negative (every
//!   path's weight is c·α^k, increasing in α).
//!
//! Where paths are long in expectation (optical radius σ_t R ≥ 100 at albedo ≥ 0.99) the
//! integrator's max_depth is capped, as a user would; the bound still holds.
//!
//! Tolerances: |z| < 5 for a mean whose standard error is estimated from the pixels
//! (≈ 6e-7 false alarms per check; the seeds are fixed).

mod common;

use common::scene_text::{tmp_dir, write};
use mediareg::integrator::volpath::Estimand;
use mediareg::integrator::{render, RenderOptions};
use mediareg::scene::Scene;
use mediareg::BuildOverrides;

const RES: usize = 16;
const SPP: u32 = 16;
const Z_MAX: f64 = 5.0;
/// max_depth where the expected path is long (see the module comment).
const DEPTH_CAP: i32 = 64;
/// How far from 1 an exact furnace pixel may be: f32 rounding of weights that are 1 in
/// exact arithmetic, far below the 1/SPP a lost or doubled sample makes.
const FURNACE_ROUNDING: f64 = 1e-5;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Shape {
    Sphere,
    Cube,
}

#[derive(Clone, Copy, Debug)]
struct Cell {
    shape: Shape,
    albedo: f64,
    sigma_t: f64,
    g: f64,
    inside: bool,
    scale: f64,
}

impl Cell {
    fn capped(&self) -> bool {
        self.sigma_t >= 100.0 && self.albedo >= 0.99
    }

    /// Every path ends by escaping, at weight 1: every pixel is 1.
    fn exact_furnace(&self) -> bool {
        self.albedo == 1.0 && !self.capped()
    }

    /// The scene file: lengths × scale, sigma_t / scale.
    fn xml(&self) -> String {
        let s = self.scale;
        let shape = match self.shape {
            Shape::Sphere => {
                format!(r#"<shape type="sphere"><float name="radius" value="{s:e}"/>"#)
            }
            Shape::Cube => format!(
                r#"<shape type="cube"><transform name="to_world"><scale value="{s:e}"/></transform>"#
            ),
        };
        let (origin, target) = if self.inside {
            ([0.2 * s, 0.1 * s, 0.3 * s], [0.0, 0.0, 0.0])
        } else {
            ([2.0 * s, 1.5 * s, 3.0 * s], [0.0, 0.0, 0.0])
        };
        let v = |p: [f64; 3]| format!("{:e}, {:e}, {:e}", p[0], p[1], p[2]);
        let camera_medium = if self.inside { r#"<ref id="m"/>"# } else { "" };
        format!(
            r#"<scene version="3.0.0">
  <integrator type="volpath"><integer name="max_depth" value="{depth}"/><integer name="rr_depth" value="{rr_depth}"/></integrator>
  <medium type="homogeneous" id="m">
    <float name="sigma_t" value="{sigma_t:e}"/>
    <float name="albedo" value="{albedo}"/>
    <phase type="hg"><float name="g" value="{g}"/></phase>
  </medium>
  <sensor type="perspective">
    <float name="fov" value="45"/>
    <float name="near_clip" value="{near:e}"/>
    <float name="far_clip" value="{far:e}"/>
    <transform name="to_world"><lookat origin="{o}" target="{t}" up="0, 1, 0"/></transform>
    {camera_medium}
    <sampler type="independent"><integer name="sample_count" value="{SPP}"/></sampler>
    <film type="hdrfilm"><integer name="width" value="{RES}"/><integer name="height" value="{RES}"/>
      <rfilter type="box"/></film>
  </sensor>
  {shape}<bsdf type="null"/><ref name="interior" id="m"/></shape>
  <emitter type="constant"><rgb name="radiance" value="1, 1, 1"/></emitter>
</scene>"#,
            depth = if self.capped() { DEPTH_CAP } else { -1 },
            rr_depth = if self.exact_furnace() { i32::MAX } else { 5 },
            sigma_t = self.sigma_t / s,
            albedo = self.albedo,
            g = self.g,
            near = 1e-2 * s,
            far = 1e4 * s,
            o = v(origin),
            t = v(target),
        )
    }

    fn tag(&self) -> String {
        format!(
            "{:?} albedo {} sigma_t {} g {} {} scale {}",
            self.shape,
            self.albedo,
            self.sigma_t,
            self.g,
            if self.inside { "inside" } else { "outside" },
            self.scale
        )
    }

    fn build(&self, seed: u64) -> Scene {
        let dir = tmp_dir("hard_cases", &format!("{:x}", seed_hash(&self.tag())));
        load_seeded(&write(&dir, "scene.xml", &self.xml()), seed)
    }
}

/// Loads a scene file written by a test, with `seed` (the file's spp).
fn load_seeded(path: &std::path::Path, seed: u64) -> Scene {
    mediareg::load_scene(
        path,
        &common::options_in(&[], vec![]),
        &BuildOverrides {
            seed: Some(seed),
            ..Default::default()
        },
    )
    .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn seed_hash(s: &str) -> u64 {
    s.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x100_0000_01b3)
    })
}

/// Mean and its standard error over values that share one expectation.
fn mean_se(v: &[f64]) -> (f64, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

/// z of a mean against `expected`; an exactly matching noiseless mean gives 0, and any
/// other noiseless mean a huge z.
fn z_of(m: f64, se: f64, expected: f64) -> f64 {
    let d = m - expected;
    if d == 0.0 {
        0.0
    } else {
        d / se.max(1e-12)
    }
}

/// The first channel of every pixel (the media are grey: channels are equal in
/// expectation, and correlated).
fn red(img: &[[f32; 3]]) -> Vec<f64> {
    img.iter().map(|p| p[0] as f64).collect()
}

/// Expected albedo-0 image: e^{−σ_t · chord} averaged over each pixel (n×n midpoints,
/// and the difference to (n/2)×(n/2) as the quadrature error).
fn transmittance_image(scene: &Scene, n: usize) -> (Vec<f64>, f64) {
    let m = &scene.media[0];
    let chord_t = |o, d, tmax: f32| -> f64 {
        // The ray from the camera passes the null boundary; every segment inside the
        // medium attenuates. Walk the crossings.
        let mut medium = scene.camera_medium.is_some();
        let (mut o, mut tmax) = (o, tmax);
        let mut tau = 0.0f64;
        for _ in 0..8 {
            let hit = scene.intersect(o, d, tmax);
            let seg = hit.map_or(tmax, |h| h.t);
            if medium {
                tau += m.sigma_t[0] as f64 * seg as f64;
            }
            let Some(h) = hit else { break };
            medium = d.dot(h.n) < 0.0;
            let o2 = h.offset_p(d, scene.offset_scale);
            tmax -= (o2 - o).length();
            o = o2;
        }
        (-tau).exp()
    };
    let pixel = |x: usize, y: usize, n: usize| -> f64 {
        let mut s = 0.0;
        for j in 0..n {
            for i in 0..n {
                let pos = glam::Vec2::new(
                    x as f32 + (i as f32 + 0.5) / n as f32,
                    y as f32 + (j as f32 + 0.5) / n as f32,
                );
                let ray = scene.shot.camera.sample_ray(pos);
                s += chord_t(ray.o, ray.d, ray.tmax);
            }
        }
        s / (n * n) as f64
    };
    let (w, h) = (scene.shot.film.width, scene.shot.film.height);
    let mut fine = Vec::with_capacity(w * h);
    let mut err: f64 = 0.0;
    for y in 0..h {
        for x in 0..w {
            let f = pixel(x, y, n);
            err = err.max((f - pixel(x, y, n / 2)).abs());
            fine.push(f);
        }
    }
    (fine, err)
}

/// One cell: its checks, and a one-line summary for the report.
fn run_cell(c: &Cell, reference: Option<&[f64]>, failures: &mut Vec<String>) -> (Vec<f64>, String) {
    let tag = c.tag();
    // Independent seeds per cell (the scaled cells are compared with the unscaled one).
    let scene = c.build(seed_hash(&format!("{c:?}")));
    let estimand = if c.albedo == 0.0 || c.albedo == 1.0 {
        Estimand::AlbedoDerivative(0)
    } else {
        Estimand::RadianceOnly
    };
    let start = std::time::Instant::now();
    let r = render(
        &scene,
        &scene.shot,
        &RenderOptions {
            show_progress: false,
            estimand,
            ..Default::default()
        },
    );
    let secs = start.elapsed().as_secs_f64();
    let px = &r.image.pixels;
    let mut fail = |what: String| failures.push(format!("{tag}: {what}"));
    if r.stats.invalid_samples > 0 {
        fail(format!(
            "{} NaN/Inf samples dropped",
            r.stats.invalid_samples
        ));
    }
    if let Some(bad) = px.iter().flatten().find(|v| !v.is_finite() || **v < 0.0) {
        fail(format!("pixel value {bad}"));
    }
    if let Some(g) = &r.gradient {
        if let Some(bad) = g
            .pixels
            .iter()
            .flatten()
            .find(|v| !v.is_finite() || **v < 0.0)
        {
            fail(format!("albedo gradient value {bad}"));
        }
    }
    let v = red(px);
    let (m, se) = mean_se(&v);
    // The furnace bound: E[pixel] ≤ 1 (the pixel spread overestimates the SE: safe).
    let z_bound = z_of(m, se, 1.0);
    if z_bound > Z_MAX {
        fail(format!(
            "image mean {m:.5} above the furnace bound 1 (z {z_bound:.1})"
        ));
    }
    let mut note = format!("mean {m:.4}");
    if c.exact_furnace() {
        // No noise: a lost path takes 1/spp from its pixel, a doubled one adds as much.
        let worst = v.iter().map(|p| (p - 1.0).abs()).fold(0.0, f64::max);
        note += &format!(", furnace |pixel - 1| <= {worst:.1e}");
        if worst > FURNACE_ROUNDING {
            fail(format!(
                "furnace: a pixel is {worst:.2e} from the exact 1 (rounding allows {FURNACE_ROUNDING:e})"
            ));
        }
    }
    if c.albedo == 0.0 && c.scale == 1.0 {
        let (t, quad_err) = transmittance_image(&scene, 16);
        // A sample is Bernoulli with mean T̄_p (the pixel's average transmittance), so
        // the pixel mean's variance is known: T̄_p (1 − T̄_p) / spp.
        let n = v.len() as f64;
        let dm = v.iter().zip(&t).map(|(a, b)| a - b).sum::<f64>() / n;
        let var = t.iter().map(|p| p * (1.0 - p)).sum::<f64>() / SPP as f64 / (n * n);
        // (A black image of a black answer has no variance: z 0, not 0/0.)
        let z = z_of(dm, var.sqrt() + quad_err, 0.0);
        note += &format!(", transmittance z {z:+.1}");
        if z.abs() > Z_MAX {
            fail(format!(
                "albedo 0: mean {m:.5} against the exact transmittance {:.5} (z {z:.1})",
                m - dm
            ));
        }
    }
    if let Some(base) = reference {
        let d: Vec<f64> = v.iter().zip(base).map(|(a, b)| a - b).collect();
        let (dm, dse) = mean_se(&d);
        let z = z_of(dm, dse, 0.0);
        note += &format!(", vs scale 1 z {z:+.1}");
        if z.abs() > Z_MAX {
            fail(format!(
                "scaled scene differs from scale 1: mean difference {dm:.2e} ± {dse:.1e} (z {z:.1})"
            ));
        }
    }
    note += &format!(", {secs:.3} s");
    (v, note)
}

#[test]
fn hard_case_matrix() {
    let mut failures = Vec::new();
    let mut cells = 0;
    for shape in [Shape::Sphere, Shape::Cube] {
        for inside in [false, true] {
            for albedo in [0.0, 0.5, 0.99, 0.999, 1.0] {
                for sigma_t in [1e-3, 1.0, 100.0, 1e4] {
                    for g in [-0.999, -0.5, 0.0, 0.5, 0.999] {
                        let base = Cell {
                            shape,
                            albedo,
                            sigma_t,
                            g,
                            inside,
                            scale: 1.0,
                        };
                        let (img, note) = run_cell(&base, None, &mut failures);
                        println!("{}: {note}", base.tag());
                        for scale in [1e-3, 1e3] {
                            let c = Cell { scale, ..base };
                            let (_, note) = run_cell(&c, Some(&img), &mut failures);
                            println!("{}: {note}", c.tag());
                        }
                        cells += 3;
                    }
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {cells} cells failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// An icosphere of radius 1 (vertices on the sphere) as OBJ text: `subdivisions` times
/// each triangle is cut into four and the new vertices pushed onto the sphere.
fn icosphere_obj(subdivisions: u32) -> String {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v: Vec<[f64; 3]> = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let norm = |p: [f64; 3]| {
        let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        [p[0] / l, p[1] / l, p[2] / l]
    };
    for p in v.iter_mut() {
        *p = norm(*p);
    }
    let mut f: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut mid = std::collections::HashMap::new();
        let mut midpoint = |a: usize, b: usize, v: &mut Vec<[f64; 3]>| {
            *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (p, q) = (v[a], v[b]);
                v.push(norm([p[0] + q[0], p[1] + q[1], p[2] + q[2]]));
                v.len() - 1
            })
        };
        let mut next = Vec::with_capacity(f.len() * 4);
        for [a, b, c] in f {
            let ab = midpoint(a, b, &mut v);
            let bc = midpoint(b, c, &mut v);
            let ca = midpoint(c, a, &mut v);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        f = next;
    }
    let mut s = String::new();
    for p in &v {
        s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for t in &f {
        s += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    s
}

/// A dense medium (σ_t 1e4: a mean free path of 1e-4) behind a triangle-mesh boundary
/// renders as behind the analytic sphere it approximates: no light leaks through the
/// mesh (a path that missed its exit would walk on outside, in "medium"), no path is
/// trapped at the boundary. The tessellation (5120 triangles) changes the silhouette by
/// ~1e-4 of the image, far below the noise.
#[test]
fn dense_medium_mesh_boundary_matches_analytic_sphere() {
    let dir = tmp_dir("hard_cases", "dense_mesh");
    write(&dir, "icosphere.obj", &icosphere_obj(4));
    for (albedo, depth) in [(0.9, -1), (0.999, 256)] {
        let scene_for = |shape: &str, seed: u64| {
            let xml = format!(
                r#"<scene version="3.0.0">
  <integrator type="volpath"><integer name="max_depth" value="{depth}"/></integrator>
  <sensor type="perspective">
    <float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0.5, 0.8, 3.2" target="0, 0, 0" up="0, 1, 0"/></transform>
    <sampler type="independent"><integer name="sample_count" value="16"/></sampler>
    <film type="hdrfilm"><integer name="width" value="32"/><integer name="height" value="32"/>
      <rfilter type="box"/></film>
  </sensor>
  {shape}
    <bsdf type="null"/>
    <medium type="homogeneous" name="interior">
      <float name="sigma_t" value="1e4"/>
      <float name="albedo" value="{albedo}"/>
      <phase type="hg"><float name="g" value="0.5"/></phase>
    </medium>
  </shape>
  <emitter type="constant"><rgb name="radiance" value="1, 1, 1"/></emitter>
  <emitter type="point"><point name="position" x="2" y="3" z="2"/><rgb name="intensity" value="8, 8, 8"/></emitter>
</scene>"#
            );
            let name = format!("scene_{seed}.xml");
            load_seeded(&write(&dir, &name, &xml), seed)
        };
        let render = |scene: &Scene| {
            let r = render(scene, &scene.shot, &RenderOptions::default());
            assert_eq!(r.stats.invalid_samples, 0, "NaN/Inf samples");
            assert!(r
                .image
                .pixels
                .iter()
                .flatten()
                .all(|v| v.is_finite() && *v >= 0.0));
            red(&r.image.pixels)
        };
        let analytic = render(&scene_for(
            r#"<shape type="sphere"><float name="radius" value="1"/>"#,
            1,
        ));
        let mesh = render(&scene_for(
            r#"<shape type="obj"><string name="filename" value="icosphere.obj"/>"#,
            2,
        ));
        let d: Vec<f64> = mesh.iter().zip(&analytic).map(|(a, b)| a - b).collect();
        let (dm, dse) = mean_se(&d);
        let z = z_of(dm, dse, 0.0);
        println!(
            "albedo {albedo}: analytic mean {:.4}, mesh mean {:.4}, z {z:+.2}",
            mean_se(&analytic).0,
            mean_se(&mesh).0
        );
        assert!(
            z.abs() < Z_MAX,
            "albedo {albedo}: the mesh boundary differs from the sphere: mean difference {dm:.3e} ± {dse:.1e} (z {z:.1})"
        );
    }
}

/// A render that would take very long (albedo 1, σ_t 1e4, Russian roulette out of
/// reach, no max_depth) is announced with a warning naming the remedy; bounding it with
/// max_depth, or keeping Mitsuba's default rr_depth, silences it.
#[test]
fn very_long_render_is_announced() {
    use mediareg::scene::cost::long_render_warning;
    let dir = tmp_dir("hard_cases", "long_render");
    let scene_with = |integrator: &str| {
        let xml = format!(
            r#"<scene version="3.0.0">
  <integrator type="volpath">{integrator}</integrator>
  <sensor type="perspective"><float name="fov" value="40"/>
    <transform name="to_world"><lookat origin="0, 0, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="64"/></film>
  </sensor>
  <shape type="sphere"><bsdf type="null"/>
    <medium type="homogeneous" name="interior" id="fog">
      <float name="sigma_t" value="1e4"/><float name="albedo" value="1"/>
    </medium>
  </shape>
  <emitter type="constant"/>
</scene>"#
        );
        let path = write(&dir, "scene.xml", &xml);
        mediareg::load_scene(
            &path,
            &common::options_in(&[], vec![]),
            &BuildOverrides::default(),
        )
        .unwrap_or_else(|e| panic!("{e}"))
    };
    let unbounded = scene_with(
        r#"<integer name="max_depth" value="-1"/><integer name="rr_depth" value="1000000000"/>"#,
    );
    let w = long_render_warning(&unbounded, &unbounded.shot, 2).expect("a warning");
    for needle in ["fog", "max_depth", "rr_depth", "hours"] {
        assert!(w.contains(needle), "warning lacks {needle:?}: {w}");
    }
    let capped = scene_with(
        r#"<integer name="max_depth" value="64"/><integer name="rr_depth" value="1000000000"/>"#,
    );
    assert_eq!(long_render_warning(&capped, &capped.shot, 2), None);
    let plain = scene_with("");
    assert_eq!(long_render_warning(&plain, &plain.shot, 2), None);
}
