//! Measurement (ignored): where OIDN goes in the method's split, against plain volpath
//! through OIDN and the control (plain radiance blended over the same frames).

mod common;

use mediareg::denoise::{self, AuxUse};
use mediareg::image::Image;
use mediareg::integrator::{self, aovs, RenderOptions};
use mediareg::regularize::sequence::{image_centre_point, CameraPath};
use mediareg::regularize::{self, Method, OidnUse, Options, Reproject};
use mediareg::report::metrics::mse_against;

use common::{load_seeded, root};

fn add(a: &Image, b: &Image) -> Image {
    let mut o = a.clone();
    for (p, q) in o.pixels.iter_mut().zip(&b.pixels) {
        for c in 0..3 {
            p[c] += q[c];
        }
    }
    o
}

#[test]
#[ignore]
fn measure_oidn_placement() {
    let spps = std::env::var("MEDIAREG_EXP_SPP")
        .unwrap_or_else(|_| "bunny=16,candle=70,lucy=25".to_string());
    let factors: Vec<f32> = std::env::var("MEDIAREG_EXP_FACTORS")
        .unwrap_or_else(|_| "0.2".into())
        .split(',')
        .map(|f| f.parse().unwrap())
        .collect();
    let still: u32 = std::env::var("MEDIAREG_EXP_STILL")
        .map(|s| s.parse().unwrap())
        .unwrap_or(0);
    let seed: u64 = std::env::var("MEDIAREG_EXP_SEED")
        .map(|s| s.parse().unwrap())
        .unwrap_or(1);
    for entry in spps.split(',') {
        let (name, spp) = entry.split_once('=').unwrap();
        let spp: u32 = spp.parse().unwrap();
        let scene = load_seeded(
            &root().join(format!("mitsuba_scenes/{name}.xml")),
            &[],
            spp,
            seed,
        );
        let (reference, var) = common::reference_images(name);
        let err = |img: &Image| mse_against(img, &reference, &var).1;
        let plain = integrator::render(
            &scene,
            &scene.shot,
            &RenderOptions {
                seen_emission: true,
                ..Default::default()
            },
        );
        let t = std::time::Instant::now();
        let plain_oidn =
            integrator::denoised::oidn(&scene, &scene.shot, &plain, AuxUse::None, None).unwrap();
        let e_plain = err(&plain.image);
        println!(
            "{name} seed {seed} {spp} spp: plain {e_plain:.3e} ({:.2} s), plain+oidn {:.4} ({:.2} s)",
            plain.stats.seconds,
            err(&plain_oidn) / e_plain,
            t.elapsed().as_secs_f64()
        );
        let target = image_centre_point(&scene, &scene.shot).unwrap();
        let base = Options {
            frames: 11,
            path: CameraPath::Orbit {
                degrees_per_frame: 0.5,
                target,
            },
            reproject: Reproject::Exact,
            spatial: None,
            oidn: OidnUse::Difference,
            method: Method::Difference,
            ..Default::default()
        };
        if std::env::var("MEDIAREG_EXP_FRAMES").is_ok() {
            let frames = Options {
                oidn: OidnUse::Frames,
                ..base.clone()
            };
            let ctl = regularize::regularize(
                &scene,
                &scene.shot,
                &Options {
                    method: Method::Radiance,
                    ..frames.clone()
                },
            )
            .unwrap();
            println!(
                "{name}: blend of OIDN'd plain frames {:.4} ({:.1} s frames incl. denoise)",
                err(&ctl.predicted) / e_plain,
                ctl.timings.frames
            );
            for &f in &factors {
                let r = regularize::regularize(
                    &scene,
                    &scene.shot,
                    &Options {
                        factor: f,
                        ..frames.clone()
                    },
                )
                .unwrap();
                let rs_d =
                    denoise::oidn(&r.source, r.seen_emission.as_ref(), None, AuxUse::None).unwrap();
                println!(
                    "{name} factor {f}: R_s + blend(oidn D_k) {:.4}, oidn(R_s) + blend(oidn D_k) {:.4}",
                    err(&r.predicted) / e_plain,
                    err(&add(&rs_d, &r.blended)) / e_plain,
                );
            }
            continue;
        }
        let ctl = regularize::regularize(
            &scene,
            &scene.shot,
            &Options {
                method: Method::Radiance,
                ..base.clone()
            },
        )
        .unwrap();
        println!(
            "{name}: control blend {:.4}, blend+oidn {:.4} ({:.1} s frames)",
            err(&ctl.blended) / e_plain,
            err(&ctl.predicted) / e_plain,
            ctl.timings.frames
        );
        for &f in &factors {
            let r = regularize::regularize(
                &scene,
                &scene.shot,
                &Options {
                    factor: f,
                    ..base.clone()
                },
            )
            .unwrap();
            let seen = r.seen_emission.as_ref();
            let raw = add(&r.source, &r.blended);
            let b2 = denoise::oidn(&raw, seen, None, AuxUse::None).unwrap();
            let rs_d = denoise::oidn(&r.source, seen, None, AuxUse::None).unwrap();
            let b3 = add(&rs_d, &r.gradient);
            let mut rs_only = r.source.clone();
            aovs::sharpen_seen_emission(&scene, &scene.shot, &mut rs_only);
            println!(
                "{name} factor {f}: R_s+blend {:.4}, R_s+oidn(D) {:.4}, oidn(R_s+blend) {:.4}, oidn(R_s)+oidn(D) {:.4}; R_s alone vs plain {:.4} ({:.1} s frames, target {:.2} s)",
                err(&raw) / e_plain,
                err(&r.predicted) / e_plain,
                err(&b2) / e_plain,
                err(&b3) / e_plain,
                err(&r.source) / e_plain,
                r.timings.frames,
                r.timings.target_frame
            );
        }
        if still > 1 {
            let shot = scene.shot.with(spp * still, seed + 50);
            let p = integrator::render(
                &scene,
                &shot,
                &RenderOptions {
                    seen_emission: true,
                    ..Default::default()
                },
            );
            let po = integrator::denoised::oidn(&scene, &shot, &p, AuxUse::None, None).unwrap();
            let e_p = err(&p.image);
            println!(
                "{name} still x{still}: plain {:.4} of frame plain, plain+oidn {:.4} of still plain",
                e_p / e_plain,
                err(&po) / e_p
            );
            for &f in &factors {
                let r = regularize::regularize(
                    &scene,
                    &shot,
                    &Options {
                        factor: f,
                        frames: 1,
                        path: CameraPath::Static,
                        ..base.clone()
                    },
                )
                .unwrap();
                let seen = r.seen_emission.as_ref();
                let raw = add(&r.source, &r.blended);
                let b2 = denoise::oidn(&raw, seen, None, AuxUse::None).unwrap();
                println!(
                    "{name} still factor {f}: R_s+D {:.4}, R_s+oidn(D) {:.4}, oidn(R_s+D) {:.4} of still plain ({:.1} s vs plain {:.1} s)",
                    err(&raw) / e_p,
                    err(&r.predicted) / e_p,
                    err(&b2) / e_p,
                    r.timings.frames,
                    p.stats.seconds
                );
            }
        }
    }
}
