//! Mitsuba 3's named conductor materials (`conductor`/`roughconductor`
//! `material="Au"`, …): the spectral η and κ tables it ships (`data/ior/NAME.{eta,k}.spd`,
//! written into `conductor_ior.txt` by `scripts/conductor_ior.py`), turned into RGB when
//! the scene loads as its RGB variants do (`complex_ior_from_file` in
//! `include/mitsuba/render/ior.h`): `spectrum_list_to_srgb` without the D65 weight and
//! clipped at 0 only, which is [`SpectrumUse::Emission`]'s conversion.

use glam::Vec3;

use super::spectrum::{spectrum_to_srgb, SpectrumUse};

const TABLES: &str = include_str!("conductor_ior.txt");

/// The table lines: `NAME eta λ:v, …`, `NAME k λ:v, …`, or `NAME = OTHER` for a material
/// whose tables are another's.
fn lines() -> impl Iterator<Item = &'static str> {
    TABLES
        .lines()
        .filter(|l| !l.starts_with('#') && !l.is_empty())
}

/// Every material name, in the table's (alphabetical) order.
pub fn names() -> Vec<&'static str> {
    let mut v: Vec<&str> = lines().filter_map(|l| l.split(' ').next()).collect();
    v.dedup();
    v
}

fn table(name: &str, part: &str) -> Option<Vec<(f64, f64)>> {
    let prefix = format!("{name} {part} ");
    let line = lines().find_map(|l| l.strip_prefix(prefix.as_str()))?;
    line.split(", ")
        .map(|pair| {
            let (w, v) = pair.split_once(':')?;
            Some((w.parse().ok()?, v.parse().ok()?))
        })
        .collect()
}

/// The RGB η and κ of Mitsuba's material `name` (names are case-sensitive, as Mitsuba's
/// file lookup), or `None` when Mitsuba ships no such material.
pub fn named_conductor(name: &str) -> Option<(Vec3, Vec3)> {
    let alias = format!("{name} = ");
    let name = lines()
        .find_map(|l| l.strip_prefix(alias.as_str()))
        .unwrap_or(name);
    let rgb = |part| Some(spectrum_to_srgb(&table(name, part)?, SpectrumUse::Emission));
    Some((rgb("eta")?, rgb("k")?))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every table parses, has increasing wavelengths and an alias names a table.
    #[test]
    fn every_table_parses() {
        let names = names();
        assert!(names.len() >= 70, "{}", names.len());
        for n in &names {
            let (eta, k) = named_conductor(n).unwrap_or_else(|| panic!("{n}"));
            assert!(eta.is_finite() && k.is_finite(), "{n}");
            for part in ["eta", "k"] {
                let alias = lines().find_map(|l| l.strip_prefix(&format!("{n} = ")));
                let t = table(alias.unwrap_or(n), part).unwrap();
                assert!(t.windows(2).all(|w| w[0].0 < w[1].0), "{n} {part}");
            }
        }
        assert!(named_conductor("au").is_none() && named_conductor("none").is_none());
    }
}
