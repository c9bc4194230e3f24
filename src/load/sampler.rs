//! Mitsuba 3's samplers: `independent`, `stratified`, `multijitter`, `orthogonal` and
//! `ldsampler` (`src/samplers/*.cpp`). They change the noise, not the expected image, so
//! mediareg reads their parameters as Mitsuba does and renders with its own sampler
//! (one line says so). `sample_count` keeps its meaning: the four structured samplers
//! round it up as Mitsuba's `set_sample_count` does, for the file's count and for
//! `--spp` alike (Mitsuba rounds what `mi.render(spp=…)` asks for too).

use super::props::Props;
use super::{unsupported, Builder};
use crate::error::Result;
use crate::xml::description::ObjId;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SamplerKind {
    Independent,
    Stratified,
    Multijitter,
    Orthogonal,
    Ldsampler,
}

impl SamplerKind {
    pub const ALL: [SamplerKind; 5] = [
        SamplerKind::Independent,
        SamplerKind::Stratified,
        SamplerKind::Multijitter,
        SamplerKind::Orthogonal,
        SamplerKind::Ldsampler,
    ];

    pub fn name(self) -> &'static str {
        match self {
            SamplerKind::Independent => "independent",
            SamplerKind::Stratified => "stratified",
            SamplerKind::Multijitter => "multijitter",
            SamplerKind::Orthogonal => "orthogonal",
            SamplerKind::Ldsampler => "ldsampler",
        }
    }

    /// The sample count Mitsuba 3 renders with when asked for `n`.
    pub fn sample_count(self, n: u32) -> u32 {
        match self {
            SamplerKind::Independent => n,
            // The smallest square ≥ n.
            SamplerKind::Stratified => {
                let mut r = 1u64;
                while r * r < n as u64 {
                    r += 1;
                }
                (r * r) as u32
            }
            // Strata as close to square as fit n: ⌊√n⌋ rows (√ in single precision,
            // as Mitsuba's) of ⌈n / rows⌉.
            SamplerKind::Multijitter => {
                let rows = ((n as f32).sqrt() as u32).max(1);
                n.div_ceil(rows) * rows
            }
            // The square of the smallest prime ≥ 2 whose square is ≥ n.
            SamplerKind::Orthogonal => {
                let prime = |x: u64| (2..=x / 2).all(|i| !x.is_multiple_of(i));
                let mut r = 2u64;
                while r * r < n as u64 || !prime(r) {
                    r += 1;
                }
                (r * r) as u32
            }
            // The square of the smallest power of two ≥ 2 whose square is ≥ n.
            SamplerKind::Ldsampler => {
                let mut r = 2u64;
                while r * r < n as u64 {
                    r = (r + 1).next_power_of_two();
                }
                (r * r) as u32
            }
        }
    }
}

/// What a `<sampler>` asks for: its kind, sample count (as rounded) and seed, and the
/// line that says how it is rendered.
pub(super) struct SamplerSpec {
    pub kind: SamplerKind,
    pub spp: u32,
    pub seed: u64,
    pub note: Option<String>,
}

impl SamplerSpec {
    /// Mitsuba's default: `independent`, 4 samples, seed 0.
    pub const DEFAULT: SamplerSpec = SamplerSpec {
        kind: SamplerKind::Independent,
        spp: 4,
        seed: 0,
        note: None,
    };
}

impl Builder<'_> {
    pub(super) fn sampler(&self, id: ObjId) -> Result<SamplerSpec> {
        let p = Props::new(self.desc, id);
        let Some(kind) = SamplerKind::ALL
            .into_iter()
            .find(|k| k.name() == p.obj.plugin)
        else {
            let names: Vec<&str> = SamplerKind::ALL.iter().map(|k| k.name()).collect();
            return Err(unsupported(&p, "sampler", &names.join(", ")));
        };
        let asked = p.int("sample_count", 4)?;
        if !(1..=1 << 24).contains(&asked) {
            return Err(p.error(format!(
                "sample_count = {asked}: must be in [1, {}]",
                1 << 24
            )));
        }
        let seed = p.int("seed", 0)?;
        if !(0..=u32::MAX as i64).contains(&seed) {
            return Err(p.error(format!(
                "seed = {seed}: must be in [0, {}] (Mitsuba reads it as a 32-bit unsigned integer)",
                u32::MAX
            )));
        }
        // Read as Mitsuba reads them; they only shape the noise.
        let mut read = vec![];
        if matches!(
            kind,
            SamplerKind::Stratified | SamplerKind::Multijitter | SamplerKind::Orthogonal
        ) {
            read.push(format!("jitter {}", p.bool("jitter", true)?));
        }
        if kind == SamplerKind::Orthogonal {
            let strength = p.int("strength", 2)?;
            if strength < 2 {
                return Err(p.error(format!("strength = {strength}: must be at least 2")));
            }
            read.push(format!("strength {strength}"));
        }
        let loc = p.loc().clone();
        p.finish(match kind {
            SamplerKind::Independent | SamplerKind::Ldsampler => "sample_count, seed",
            SamplerKind::Orthogonal => "sample_count, seed, jitter, strength",
            _ => "sample_count, seed, jitter",
        })?;
        let spp = kind.sample_count(asked as u32);
        let note = (kind != SamplerKind::Independent).then(|| {
            let rounded = if spp != asked as u32 {
                format!(", sample_count {asked} rounded to {spp} as Mitsuba 3 rounds it")
            } else {
                String::new()
            };
            format!(
                "{}: sampler \"{}\" ({}{rounded}): rendered with mediareg's sampler, which gives the same image in expectation with other noise",
                loc,
                kind.name(),
                if read.is_empty() { "read".to_string() } else { read.join(", ") },
            )
        });
        Ok(SamplerSpec {
            kind,
            spp,
            seed: seed as u64,
            note,
        })
    }
}
