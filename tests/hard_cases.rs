//! The hard-case matrix: a sphere or cube of homogeneous medium (null boundary) in a
//! white furnace (constant environment of radiance 1), over
//! albedo × sigma_t × g × camera outside/inside × scale.
//!
//! Every cell: no NaN, Inf or negative pixel, no dropped sample, and the image mean not
//! above the furnace bound 1 (scattering only redirects or removes light). Where the
//! answer is known exactly the image must match it statistically:
//! * albedo 1, no depth cap: every pixel is 1;
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
use mediareg::integrator::volpath::Gradient;
use mediareg::integrator::{render_with, RenderOptions};
use mediareg::scene::Scene;
use mediareg::BuildOverrides;

const RES: usize = 16;
const SPP: u32 = 16;
const Z_MAX: f64 = 5.0;
/// max_depth where the expected path is long (see the module comment).
const DEPTH_CAP: i32 = 64;

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
  <integrator type="volpath"><integer name="max_depth" value="{depth}"/></integrator>
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
        let path = write(&dir, "scene.xml", &self.xml());
        mediareg::load_scene(
            &path,
            &common::options_in(&[], vec![]),
            &BuildOverrides {
                spp: None,
                seed: Some(seed),
            },
        )
        .unwrap_or_else(|e| panic!("{}: {e}", self.tag()))
    }
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

/// z of a mean against `expected`; an exactly matching noiseless mean gives 0.
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
            let o2 = mediareg::geometry::offset_point(h.p, h.n, d, scene.offset_scale);
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
                let ray = scene.camera.sample_ray(pos);
                s += chord_t(ray.o, ray.d, ray.tmax);
            }
        }
        s / (n * n) as f64
    };
    let (w, h) = (scene.film.width, scene.film.height);
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
    let gradient = if c.albedo == 0.0 || c.albedo == 1.0 {
        Gradient::Albedo(0)
    } else {
        Gradient::None
    };
    let start = std::time::Instant::now();
    let r = render_with(
        &scene,
        &RenderOptions {
            show_progress: false,
            gradient,
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
    if c.albedo == 1.0 && !c.capped() {
        let z = z_of(m, se, 1.0);
        note += &format!(", furnace z {z:+.1}");
        if z.abs() > Z_MAX {
            fail(format!(
                "furnace: mean {m:.5} ± {se:.1e}, exact 1 (z {z:.1})"
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
        let z = dm / (var.sqrt() + quad_err);
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
