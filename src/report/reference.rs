//! The Mitsuba 3 reference a table row is measured against, checked to have been made
//! from the very files and `-D` parameters of the run.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{anyhow, bail, Context, Result};
use serde::Deserialize;
use sha2::{Digest, Sha256};

use crate::image::Image;
use crate::{image, xml};

/// What a reference's JSON records (written by `scripts/mitsuba_reference.py`).
#[derive(Deserialize, Clone, Debug)]
pub struct ReferenceMeta {
    pub mitsuba_version: String,
    pub variant: String,
    pub spp: u32,
    pub chunks: u32,
    pub seconds: f64,
    #[serde(default)]
    pub params: BTreeMap<String, String>,
    pub width: usize,
    pub height: usize,
    /// The crop window `[x, y, w, h]` of the film the reference covers (`--crop`).
    #[serde(default)]
    pub crop: Option<[usize; 4]>,
    pub sha256: BTreeMap<String, String>,
    /// The sha256 of its own images, `NAME.exr` and `NAME_var.exr`, as the script wrote
    /// them: an image replaced afterwards (say by a render of ours) is refused.
    #[serde(default)]
    pub images_sha256: BTreeMap<String, String>,
    /// The scene file, as the script was given it (for the command that remakes it).
    #[serde(default)]
    pub scene: Option<String>,
}

pub struct Reference {
    pub path: PathBuf,
    pub mean: Image,
    pub var: Image,
    pub meta: ReferenceMeta,
}

fn sha256_file(path: &Path) -> Result<String> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    Ok(format!("{:x}", Sha256::digest(&bytes)))
}

fn remake_hint(name: &str, xml: &Path, params: &[(String, String)], dir: &Path) -> String {
    let defines: String = params.iter().map(|(k, v)| format!(" -D {k}={v}")).collect();
    format!(
        "make it with: .venv/bin/python scripts/mitsuba_reference.py {} --spp 4096 --chunks 16 -a .cache/meshes{defines} --out {} --name {name}",
        xml.display(),
        dir.display()
    )
}

/// The command that remakes reference `name` in `dir` from what its JSON records.
fn regenerate_hint(meta: &ReferenceMeta, dir: &Path, name: &str) -> String {
    let defines: String = (meta.params.iter())
        .map(|(k, v)| format!(" -D {k}={v}"))
        .collect();
    let crop = (meta.crop)
        .map(|[x, y, w, h]| format!(" --crop {x},{y},{w},{h}"))
        .unwrap_or_default();
    format!(
        "regenerate it with Mitsuba 3: .venv/bin/python scripts/mitsuba_reference.py {} --spp {} --chunks {}{defines}{crop} -a .cache/meshes --out {} --name {name} (with --alpha or --derivative as it was made), which writes the images and their sha256",
        meta.scene.as_deref().unwrap_or("SCENE.xml"),
        meta.spp,
        meta.chunks,
        dir.display()
    )
}

/// Reads reference `name`'s images, `dir/NAME.exr` and `NAME_var.exr`, after checking
/// each against the sha256 `NAME.json` records for it (`images_sha256`): the mean and
/// the variance of the mean, and the JSON. A mismatch or a missing record is an error
/// naming the file and how to regenerate it.
pub fn read_reference_images(dir: &Path, name: &str) -> Result<(Image, Image, ReferenceMeta)> {
    let json_path = dir.join(format!("{name}.json"));
    let text = std::fs::read_to_string(&json_path)
        .with_context(|| format!("no Mitsuba 3 reference {name}: {}", json_path.display()))?;
    let meta: ReferenceMeta = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a reference description", json_path.display()))?;
    let mut images = Vec::new();
    for path in [
        dir.join(format!("{name}.exr")),
        dir.join(format!("{name}_var.exr")),
    ] {
        // Keyed by file name, as the scene's files are (`name` may hold a folder).
        let file = (path.file_name())
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default();
        let Some(want) = meta.images_sha256.get(&file) else {
            bail!(
                "{} records no sha256 of {file} (\"images_sha256\"), so nothing shows that {} is the image Mitsuba 3 rendered; {}",
                json_path.display(),
                path.display(),
                regenerate_hint(&meta, dir, name)
            );
        };
        let got = sha256_file(&path)?;
        if got != *want {
            bail!(
                "{} has sha256 {got}, not the {want} that {} records: it is not the image Mitsuba 3 rendered for this reference (a render of ours copied over it?); restore it (git checkout -- {}) or {}",
                path.display(),
                json_path.display(),
                path.display(),
                regenerate_hint(&meta, dir, name)
            );
        }
        images.push(image::read_exr(&path)?);
    }
    let var = images.pop().expect("two images");
    let mean = images.pop().expect("two images");
    Ok((mean, var, meta))
}

impl Reference {
    /// Loads `dir/NAME.exr`, `NAME_var.exr` and `NAME.json`, and checks that the
    /// reference was made from the files `desc` reads (sha256 of the scene, its includes
    /// and assets) and the `-D` parameters it was loaded with (`load`), and that its
    /// images are the ones the script wrote ([`read_reference_images`]).
    pub fn load(
        dir: &Path,
        name: &str,
        xml_path: &Path,
        load: &xml::LoadOptions,
        desc: &xml::SceneDescription,
    ) -> Result<Reference> {
        let hint = || remake_hint(name, xml_path, &load.params, dir);
        let json_path = dir.join(format!("{name}.json"));
        let text = std::fs::read_to_string(&json_path).map_err(|e| {
            anyhow!(
                "no Mitsuba 3 reference for {name}: {}: {e}; {}",
                json_path.display(),
                hint()
            )
        })?;
        let meta: ReferenceMeta = serde_json::from_str(&text)
            .with_context(|| format!("{}: not a reference description", json_path.display()))?;
        let given: BTreeMap<String, String> = load.params.iter().cloned().collect();
        if given != meta.params {
            bail!(
                "{} was made with -D {:?}, this run has -D {:?}: MSEs would compare different scenes; {}",
                json_path.display(),
                meta.params,
                given,
                hint()
            );
        }
        let mut seen = Vec::new();
        for f in desc.referenced_files() {
            let base = f
                .file_name()
                .map(|b| b.to_string_lossy().into_owned())
                .unwrap_or_default();
            match meta.sha256.get(&base) {
                Some(want) if *want == sha256_file(&f)? => seen.push(base),
                Some(_) => bail!(
                    "{} changed since {} was made: the reference is stale; {}",
                    f.display(),
                    json_path.display(),
                    hint()
                ),
                None => bail!(
                    "{} does not record {base}, which the scene reads: the reference is stale; {}",
                    json_path.display(),
                    hint()
                ),
            }
        }
        if let Some(k) = meta.sha256.keys().find(|k| !seen.contains(k)) {
            bail!(
                "{} records {k}, which the scene no longer reads: the reference is stale; {}",
                json_path.display(),
                hint()
            );
        }
        let path = dir.join(format!("{name}.exr"));
        let (mean, var, _) = read_reference_images(dir, name)?;
        if (mean.width, mean.height) != (meta.width, meta.height)
            || (var.width, var.height) != (meta.width, meta.height)
        {
            bail!(
                "{}: its images are not {}x{} as its JSON says",
                dir.display(),
                meta.width,
                meta.height
            );
        }
        Ok(Reference {
            path,
            mean,
            var,
            meta,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// reference/films (.json, .exr, _var.exr) copied into a fresh folder.
    fn films_copy(tag: &str) -> PathBuf {
        let from = Path::new(env!("CARGO_MANIFEST_DIR")).join("reference");
        let dir = std::env::temp_dir()
            .join(format!("mediareg_reference_{}", std::process::id()))
            .join(tag);
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        for f in ["films.json", "films.exr", "films_var.exr"] {
            std::fs::copy(from.join(f), dir.join(f)).unwrap();
        }
        dir
    }

    fn refused(dir: &Path) -> String {
        match read_reference_images(dir, "films") {
            Ok(_) => panic!(
                "{}: a replaced or unrecorded image was taken",
                dir.display()
            ),
            Err(e) => format!("{e:#}"),
        }
    }

    /// Every committed reference's images are the ones its JSON records, those no test
    /// compares against included.
    #[test]
    fn every_committed_reference_has_its_recorded_images() {
        fn walk(dir: &Path, found: &mut Vec<PathBuf>) {
            for e in std::fs::read_dir(dir).unwrap() {
                let p = e.unwrap().path();
                // reference/derivatives holds numbers (Mitsuba 3's derivatives), no images.
                if p.is_dir() && !p.ends_with("derivatives") {
                    walk(&p, found);
                } else if p.extension().is_some_and(|x| x == "json") {
                    found.push(p);
                }
            }
        }
        let mut jsons = Vec::new();
        walk(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("reference"),
            &mut jsons,
        );
        assert!(jsons.len() > 50, "{} references", jsons.len());
        for json in jsons {
            let name = json.file_stem().unwrap().to_string_lossy();
            if let Err(e) = read_reference_images(json.parent().unwrap(), &name) {
                panic!("{e:#}");
            }
        }
    }

    /// The committed images load; either one replaced by an image of ours (the same
    /// size, 0.1% off) or with one byte changed is refused naming the file, its JSON and
    /// how to regenerate it; a JSON that records no sha256 of its images is refused too.
    #[test]
    fn reference_images_must_be_the_ones_the_script_wrote() {
        let dir = films_copy("intact");
        let (mean, var, meta) = read_reference_images(&dir, "films").unwrap();
        assert_eq!((mean.width, mean.height), (meta.width, meta.height));
        assert_eq!((var.width, var.height), (meta.width, meta.height));

        for (file, img) in [("films.exr", &mean), ("films_var.exr", &var)] {
            let dir = films_copy(file);
            let ours = Image {
                pixels: img.pixels.iter().map(|p| p.map(|c| c * 1.001)).collect(),
                ..img.clone()
            };
            image::write_exr(&dir.join(file), &ours).unwrap();
            let e = refused(&dir);
            for part in [
                file,
                "films.json",
                "scripts/mitsuba_reference.py",
                "git checkout",
            ] {
                assert!(e.contains(part), "{file}: no \"{part}\" in: {e}");
            }
        }

        // Through Reference::load (what `mediareg table` runs): one byte of either image
        // changed is refused, the intact copy loads.
        let xml_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("mitsuba_scenes/films.xml");
        let load = xml::LoadOptions::default();
        let desc = xml::load_file(&xml_path, &load).unwrap();
        let reference = |dir: &Path| Reference::load(dir, "films", &xml_path, &load, &desc);
        assert!(reference(&films_copy("loaded")).is_ok());
        for file in ["films.exr", "films_var.exr"] {
            let dir = films_copy(&format!("byte_{file}"));
            let mut bytes = std::fs::read(dir.join(file)).unwrap();
            let mid = bytes.len() / 2;
            bytes[mid] ^= 1;
            std::fs::write(dir.join(file), bytes).unwrap();
            let e = format!(
                "{:#}",
                reference(&dir).err().expect("a changed byte loaded")
            );
            assert!(e.contains(&format!("{file} has sha256")), "{e}");
        }

        let dir = films_copy("unrecorded");
        let json = dir.join("films.json");
        let mut value: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        assert!(value
            .as_object_mut()
            .unwrap()
            .remove("images_sha256")
            .is_some());
        std::fs::write(&json, value.to_string()).unwrap();
        let e = refused(&dir);
        assert!(e.contains("records no sha256 of films.exr"), "{e}");
    }
}
