//! Files older than version 2.0 (Mitsuba 0.5/0.6, the paper's own renderer).
//!
//! What Mitsuba 3 upgrades (`upgrade_from_v1`, `src/core/parser.cpp`) is upgraded the
//! same way and silently: camelCase names become snake_case (in `load.rs`, where
//! properties are read), `lookAt` becomes `lookat`, a `diffuse` bsdf's
//! `diffuse_reflectance` becomes `reflectance`, and `uoffset`/`voffset`/`uscale`/`vscale`
//! become a `to_uv` transform.
//!
//! What Mitsuba 3 does not upgrade, but a 0.6 file means unambiguously, is loaded as its
//! author meant, with one line of output per conversion (`--strict-v3` turns each into an
//! error, for users who want Mitsuba 3's reading):
//! * a homogeneous medium given by `sigmaS` and `sigmaA` gets σ_t = σ_s + σ_a and
//!   albedo = σ_s / σ_t (0 where σ_t = 0); a chromatic σ_t keeps its largest component
//!   in `scale`, so the `<rgb>` stays in [0, 1] as Mitsuba 3 requires;
//! * `density`, 0.5's name of the medium's `scale`, becomes `scale`;
//! * a shape with a medium and no bsdf was index-matched (Mitsuba 0.6 passed light
//!   straight through it) and gets a `null` bsdf; Mitsuba 3 would make it diffuse.
//!
//! * 0.5's `<spectrum value="r, g, b"/>` (three values, no wavelengths) was the
//!   spectrum's three samples, i.e. RGB in 0.5's RGB mode, and is read as `<rgb>`
//!   (`rgb_spectrum`, called by the property reader in `load.rs`);
//! * a medium `material` preset (0.6's table of measured media, `media_presets`)
//!   becomes the σ_s, σ_a 0.6 rendered with (× 100, σ_s reduced by 1 − g), then σ_t and
//!   albedo as above; the medium's `scale` (or 0.5's `density`) multiplies them as in 0.6.

use glam::{DMat4, DVec3};

use super::description::{Child, ObjId, Object, ObjectKind, Property, Value};
use crate::error::{err_at, Loc, Result, SceneError};

/// Upgrades `obj` (just read from a file older than 2.0): Mitsuba 3's own rules, then the
/// 0.6 meanings (a line each in `notes`, or an error when `strict`); shapes get
/// [`index_matched_boundary`] once references are resolved.
pub fn from_v1(obj: &mut Object, notes: &mut Vec<String>, strict: bool) -> Result<()> {
    // ---- Mitsuba 3's upgrade ----
    if obj.kind == ObjectKind::Bsdf && obj.plugin == "diffuse" {
        for p in obj
            .props
            .iter_mut()
            .filter(|p| p.name == "diffuse_reflectance")
        {
            p.name = "reflectance".into();
        }
        for c in obj.children.iter_mut() {
            if c.name.as_deref() == Some("diffuse_reflectance") {
                c.name = Some("reflectance".into());
            }
        }
    }
    uv_offsets_to_transform(obj)?;

    // ---- 0.6 meanings Mitsuba 3 does not carry over ----
    let mut convert = |obj: &Object, what: String| reading(obj, what, notes, strict);
    if obj.kind == ObjectKind::Medium && obj.plugin == "homogeneous" {
        if let Some(i) = obj.props.iter().position(|p| p.name == "density") {
            if obj.props.iter().any(|p| p.name == "scale") {
                return err_at(
                    &obj.props[i].loc,
                    "give either density (Mitsuba 0.5) or scale, not both",
                );
            }
            obj.props[i].name = "scale".into();
            convert(obj, "density read as scale".into())?;
        }
        if let Some(preset) = material_preset(obj)? {
            let what = sigma_s_a_to_t_albedo(obj)?;
            convert(obj, format!("{preset}: {what}"))?;
        } else if obj
            .props
            .iter()
            .any(|p| p.name == "sigma_s" || p.name == "sigma_a")
        {
            let what = sigma_s_a_to_t_albedo(obj)?;
            convert(obj, what)?;
        }
    }
    Ok(())
}

/// 0.5's `<spectrum name value="r, g, b"/>` at `loc`: in 0.5's RGB mode a spectrum had
/// three samples, so three values without wavelengths were an RGB colour; read as
/// `<rgb>` with a note (an error under `strict`: Mitsuba 3 does not read it).
pub fn rgb_spectrum(
    loc: &Loc,
    name: &str,
    rgb: DVec3,
    notes: &mut Vec<String>,
    strict: bool,
) -> Result<Value> {
    let what = format!(
        "<spectrum name=\"{name}\"> with three values and no wavelengths read as <rgb value=\"{}, {}, {}\"> (Mitsuba 0.5's RGB mode)",
        rgb.x, rgb.y, rgb.z
    );
    if strict {
        return Err(SceneError::at(
            loc,
            format!("a Mitsuba 0.5 form that Mitsuba 3 does not read (--strict-v3): {what}"),
        )
        .with_hint(
            "without --strict-v3 mediareg reads it so; or write <rgb name=... value=\"r, g, b\"/>",
        ));
    }
    notes.push(format!("{loc}: 0.5 file: {what}"));
    Ok(Value::Rgb(rgb))
}

/// `uoffset`, `voffset`, `uscale`, `vscale` → `to_uv` = scale · translate, as Mitsuba 3.
fn uv_offsets_to_transform(obj: &mut Object) -> Result<()> {
    let names = ["uoffset", "voffset", "uscale", "vscale"];
    if !obj.props.iter().any(|p| names.contains(&p.name.as_str())) {
        return Ok(());
    }
    let mut offset = DVec3::ZERO;
    let mut scale = DVec3::ONE;
    let mut loc = obj.loc.clone();
    for p in obj
        .props
        .iter()
        .filter(|p| names.contains(&p.name.as_str()))
    {
        let v = match p.value {
            Value::Float(v) => v,
            Value::Integer(v) => v as f64,
            _ => return err_at(&p.loc, format!("\"{}\" must be a <float>", p.name)),
        };
        match p.name.as_str() {
            "uoffset" => offset.x = v,
            "voffset" => offset.y = v,
            "uscale" => scale.x = v,
            _ => scale.y = v,
        }
        loc = p.loc.clone();
    }
    if obj.props.iter().any(|p| p.name == "to_uv") {
        return err_at(&loc, "give either to_uv or uoffset/voffset/uscale/vscale");
    }
    obj.props.retain(|p| !names.contains(&p.name.as_str()));
    obj.props.push(Property {
        name: "to_uv".into(),
        value: Value::Transform(DMat4::from_scale(scale) * DMat4::from_translation(offset)),
        loc,
    });
    Ok(())
}

/// A 0.6 `material` preset on a homogeneous medium: replaced by the `sigma_s` and
/// `sigma_a` 0.6 rendered with (a medium `g` property, which 0.6 used to reduce σ_s, is
/// consumed); returns what was read, for the note. 0.6 refuses a preset together with
/// explicit coefficients, and so does this.
fn material_preset(obj: &mut Object) -> Result<Option<String>> {
    use super::media_presets::{coefficients, find, names};
    let Some(i) = obj.props.iter().position(|p| p.name == "material") else {
        return Ok(None);
    };
    let p = &obj.props[i];
    let Value::String(name) = &p.value else {
        return err_at(&p.loc, "\"material\" must be a <string>");
    };
    let loc = p.loc.clone();
    let Some(preset) = find(name) else {
        return Err(SceneError::at(
            &loc,
            format!(
                "{}: unknown Mitsuba 0.6 medium material \"{name}\"",
                obj.label()
            ),
        )
        .with_hint(format!("the presets are: {}", names())));
    };
    let manual = ["sigma_s", "sigma_a", "sigma_t", "albedo"];
    if let Some(q) = obj.props.iter().find(|q| manual.contains(&q.name.as_str())) {
        return err_at(
            &q.loc,
            format!(
                "{}: give either the material preset \"{name}\" or scattering coefficients, not both (as Mitsuba 0.6)",
                obj.label()
            ),
        );
    }
    let g = match obj.props.iter().find(|q| q.name == "g") {
        Some(q) => Some(constant_rgb(q)?.to_array()),
        None => None,
    };
    let (s, a) = coefficients(preset, g);
    let what = format!(
        "material \"{}\" (mm⁻¹ × 100, σ_s × (1 − g{}))",
        preset.name,
        if g.is_some() { " of the medium" } else { "" }
    );
    obj.props.retain(|q| q.name != "material" && q.name != "g");
    for (n, v) in [("sigma_s", s), ("sigma_a", a)] {
        obj.props.push(Property {
            name: n.into(),
            value: Value::Rgb(DVec3::from_array(v)),
            loc: loc.clone(),
        });
    }
    Ok(Some(what))
}

/// A constant colour property as RGB (float, rgb or constant spectrum).
fn constant_rgb(p: &Property) -> Result<DVec3> {
    match p.value {
        Value::Float(v) | Value::Spectrum(v) => Ok(DVec3::splat(v)),
        Value::Integer(v) => Ok(DVec3::splat(v as f64)),
        Value::Rgb(c) => Ok(c),
        _ => err_at(
            &p.loc,
            format!(
                "\"{}\" must be a constant <float>, <rgb> or <spectrum> to be converted",
                p.name
            ),
        ),
    }
}

/// σ_s, σ_a → σ_t = σ_s + σ_a and albedo = σ_s / σ_t, written as Mitsuba 3 properties;
/// returns what was done, for the note.
fn sigma_s_a_to_t_albedo(obj: &mut Object) -> Result<String> {
    let find = |n: &str| obj.props.iter().find(|p| p.name == n);
    let (Some(ps), Some(pa)) = (find("sigma_s"), find("sigma_a")) else {
        return err_at(
            &obj.loc,
            format!(
                "{}: a Mitsuba 0.6 medium needs both sigmaS and sigmaA",
                obj.label()
            ),
        );
    };
    if find("sigma_t").is_some() || find("albedo").is_some() {
        return err_at(
            &obj.loc,
            format!(
                "{}: give sigmaS and sigmaA, or sigma_t and albedo, not both",
                obj.label()
            ),
        );
    }
    let (s, a, loc) = (constant_rgb(ps)?, constant_rgb(pa)?, ps.loc.clone());
    if s.min_element() < 0.0 || a.min_element() < 0.0 {
        return err_at(&loc, "sigmaS and sigmaA must be nonnegative");
    }
    let t = s + a;
    let albedo = DVec3::select(t.cmpgt(DVec3::ZERO), s / t, DVec3::ZERO);
    let grey = |c: DVec3| c.min_element() == c.max_element();
    let note = format!("sigmaS {s} + sigmaA {a} read as sigma_t {t}, albedo {albedo}");
    // A chromatic σ_t is an <rgb>, which Mitsuba 3 keeps in [0, 1]: its magnitude goes
    // into `scale`.
    let (sigma_t, factor) = if grey(t) {
        (Value::Float(t.x), 1.0)
    } else {
        let m = t.max_element();
        (Value::Rgb(t / m), m)
    };
    obj.props
        .retain(|p| p.name != "sigma_s" && p.name != "sigma_a");
    if factor != 1.0 {
        match obj.props.iter_mut().find(|p| p.name == "scale") {
            Some(p) => match &mut p.value {
                Value::Float(v) => *v *= factor,
                _ => return err_at(&p.loc, "\"scale\" must be a <float>"),
            },
            None => obj.props.push(Property {
                name: "scale".into(),
                value: Value::Float(factor),
                loc: loc.clone(),
            }),
        }
    }
    obj.props.push(Property {
        name: "sigma_t".into(),
        value: sigma_t,
        loc: loc.clone(),
    });
    obj.props.push(Property {
        name: "albedo".into(),
        value: if grey(albedo) {
            Value::Float(albedo.x)
        } else {
            Value::Rgb(albedo)
        },
        loc,
    });
    Ok(note)
}

/// One 0.6 reading: a line in `notes`, or with `strict` (`--strict-v3`) an error.
fn reading(obj: &Object, what: String, notes: &mut Vec<String>, strict: bool) -> Result<()> {
    if strict {
        return Err(SceneError::at(
            &obj.loc,
            format!(
                "{}: a Mitsuba 0.6 form that Mitsuba 3 does not read (--strict-v3): {what}",
                obj.label()
            ),
        )
        .with_hint("without --strict-v3 mediareg reads it so; or write it in Mitsuba 3's form"));
    }
    notes.push(format!("{}: {}: 0.6 file: {what}", obj.loc, obj.label()));
    Ok(())
}

/// A shape of a file older than 2.0 with a medium and no bsdf was index-matched in 0.6
/// (light passed straight through): it gets a `null` bsdf. Run once the file's
/// references are resolved (a `<ref>` may name a medium or bsdf declared later).
pub fn index_matched_boundary(
    shape: ObjId,
    objects: &mut Vec<Object>,
    notes: &mut Vec<String>,
    strict: bool,
) -> Result<()> {
    let obj = &objects[shape];
    let kind_of = |c: &Child| objects[c.object].kind;
    let has_medium = obj
        .children
        .iter()
        .any(|c| kind_of(c) == ObjectKind::Medium);
    let has_bsdf = obj.children.iter().any(|c| kind_of(c) == ObjectKind::Bsdf);
    if !has_medium || has_bsdf {
        return Ok(());
    }
    let id: ObjId = objects.len();
    let loc = obj.loc.clone();
    objects.push(Object {
        kind: ObjectKind::Bsdf,
        plugin: "null".into(),
        id: None,
        props: Vec::new(),
        children: Vec::new(),
        loc: loc.clone(),
        legacy: true,
    });
    objects[shape].children.push(Child {
        name: None,
        object: id,
        loc,
    });
    reading(
        &objects[shape],
        "a medium boundary with no bsdf read as index-matched (a null bsdf); Mitsuba 3 would make it diffuse".into(),
        notes,
        strict,
    )
}
