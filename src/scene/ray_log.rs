//! A record of the rays a render casts into the scene (`mediareg render --ray-log
//! FILE`), for `scripts/cast_bound`: it times Mitsuba 3's own ray caster (Embree) on
//! exactly these rays, a lower bound on the time a sample takes in any renderer that
//! casts them one by one at Embree's speed (so an upper bound on its samples/s).
//!
//! Logged are the casts that search the scene's shapes: closest hits
//! ([`Scene::intersect`], every surface segment and free flight cast against the scene),
//! shadow searches ([`Scene::crossings`]) and occlusion tests ([`Scene::occluded`]).
//! A convex medium's flights, tested against its one shape (`geometry::convex`), are
//! not casts into the scene and are not logged, so the time stays a lower bound.
//!
//! The file is 8 little-endian f32 per ray: kind (0 closest hit, 1 shadow search, 2
//! occlusion), origin x y z, direction x y z, tmax (∞ for none).

use std::path::Path;
use std::sync::Mutex;
use std::time::Instant;

use glam::Vec3A;

use super::Scene;
use crate::geometry::accel::CrossingList;

/// What a logged cast asks of the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cast {
    ClosestHit = 0,
    Crossings = 1,
    Occluded = 2,
}

impl Cast {
    pub const ALL: [Cast; 3] = [Cast::ClosestHit, Cast::Crossings, Cast::Occluded];

    pub fn name(self) -> &'static str {
        match self {
            Cast::ClosestHit => "closest hit",
            Cast::Crossings => "shadow search",
            Cast::Occluded => "occlusion",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoggedRay {
    pub kind: Cast,
    pub o: Vec3A,
    pub d: Vec3A,
    pub tmax: f32,
}

/// The rays cast while it is attached to a scene (`Scene::ray_log`).
#[derive(Default)]
pub struct RayLog {
    rays: Mutex<Vec<LoggedRay>>,
}

impl RayLog {
    /// Out of line: the casts' own code stays as it is without a log.
    #[cold]
    #[inline(never)]
    pub fn record(&self, kind: Cast, o: Vec3A, d: Vec3A, tmax: f32) {
        let ray = LoggedRay { kind, o, d, tmax };
        // A poisoned lock only means another render thread panicked; the rays are fine.
        self.rays
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .push(ray);
    }

    pub fn into_rays(self) -> Vec<LoggedRay> {
        self.rays.into_inner().unwrap_or_else(|e| e.into_inner())
    }
}

pub fn write(path: &Path, rays: &[LoggedRay]) -> std::io::Result<()> {
    let mut bytes = Vec::with_capacity(rays.len() * 32);
    for r in rays {
        let v = [
            r.kind as u8 as f32,
            r.o.x,
            r.o.y,
            r.o.z,
            r.d.x,
            r.d.y,
            r.d.z,
            r.tmax,
        ];
        for x in v {
            bytes.extend_from_slice(&x.to_le_bytes());
        }
    }
    std::fs::write(path, bytes)
}

/// How long one cast of a kind takes here, cast again one by one on this thread.
#[derive(Clone, Copy, Debug)]
pub struct CastTiming {
    pub kind: Cast,
    pub count: usize,
    /// The best of `repeats` passes over them, per ray.
    pub ns_per_ray: f64,
}

/// Casts `rays` again (each kind by itself, `repeats` times, the fastest pass kept), as
/// the render did but without shading: a closest hit's surface is not looked up. The
/// scene's own log must be off (taken), or these casts would be logged too.
pub fn time_casts(scene: &Scene, rays: &[LoggedRay], repeats: usize) -> Vec<CastTiming> {
    let g = &scene.geometries;
    let mut out = Vec::new();
    for kind in Cast::ALL {
        let of_kind: Vec<&LoggedRay> = rays.iter().filter(|r| r.kind == kind).collect();
        if of_kind.is_empty() {
            continue;
        }
        let mut best = f64::INFINITY;
        let mut crossings = CrossingList::new();
        for _ in 0..repeats.max(1) {
            let start = Instant::now();
            let mut answers = 0usize;
            for r in &of_kind {
                let found = match kind {
                    Cast::ClosestHit => scene.accel.intersect(g, r.o, r.d, r.tmax).is_some(),
                    Cast::Crossings => {
                        let _ = scene.crossings(r.o, r.d, r.tmax, &mut crossings);
                        !crossings.is_empty()
                    }
                    Cast::Occluded => scene.occluded(r.o, r.d, r.tmax),
                };
                answers += found as usize;
            }
            // The answers are used, so the casts are not optimised away.
            std::hint::black_box(answers);
            best = best.min(start.elapsed().as_secs_f64());
        }
        out.push(CastTiming {
            kind,
            count: of_kind.len(),
            ns_per_ray: best / of_kind.len() as f64 * 1e9,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The file back as rays (the format `scripts/cast_bound` reads).
    fn read(path: &Path) -> Result<Vec<LoggedRay>, String> {
        let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        if bytes.len() % 32 != 0 {
            return Err(format!(
                "{}: {} bytes is not a whole number of 32-byte rays",
                path.display(),
                bytes.len()
            ));
        }
        bytes
            .chunks_exact(32)
            .map(|c| {
                let f = |i: usize| {
                    f32::from_le_bytes([c[4 * i], c[4 * i + 1], c[4 * i + 2], c[4 * i + 3]])
                };
                let kind = match f(0) as u32 {
                    0 => Cast::ClosestHit,
                    1 => Cast::Crossings,
                    2 => Cast::Occluded,
                    k => return Err(format!("{}: unknown cast kind {k}", path.display())),
                };
                Ok(LoggedRay {
                    kind,
                    o: Vec3A::new(f(1), f(2), f(3)),
                    d: Vec3A::new(f(4), f(5), f(6)),
                    tmax: f(7),
                })
            })
            .collect()
    }

    fn temp(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("mediareg_ray_log_{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join(name)
    }

    #[test]
    fn rays_written_are_read_back_the_same() {
        let rays = [
            LoggedRay {
                kind: Cast::ClosestHit,
                o: Vec3A::new(1.0, -2.0, 3.5),
                d: Vec3A::new(0.0, 0.6, -0.8),
                tmax: f32::INFINITY,
            },
            LoggedRay {
                kind: Cast::Crossings,
                o: Vec3A::new(-0.25, 0.0, 1e-7),
                d: Vec3A::X,
                tmax: 4.5,
            },
            LoggedRay {
                kind: Cast::Occluded,
                o: Vec3A::ZERO,
                d: Vec3A::NEG_Z,
                tmax: 1e30,
            },
        ];
        let path = temp("rays.bin");
        write(&path, &rays).unwrap();
        assert_eq!(std::fs::metadata(&path).unwrap().len(), 3 * 32);
        assert_eq!(read(&path).unwrap(), rays);
    }

    #[test]
    fn a_file_that_is_no_ray_log_is_refused_by_name() {
        let path = temp("short.bin");
        std::fs::write(&path, [0u8; 40]).unwrap();
        let e = read(&path).unwrap_err();
        assert!(e.contains("short.bin") && e.contains("32-byte"), "{e}");
        let path = temp("kind.bin");
        let mut bytes = vec![0u8; 32];
        bytes[..4].copy_from_slice(&7.0f32.to_le_bytes());
        std::fs::write(&path, bytes).unwrap();
        let e = read(&path).unwrap_err();
        assert!(e.contains("kind.bin") && e.contains("kind 7"), "{e}");
    }
}
