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

impl Reference {
    /// Loads `dir/NAME.exr`, `NAME_var.exr` and `NAME.json`, and checks that the
    /// reference was made from the files `desc` reads (sha256 of the scene, its includes
    /// and assets) and the `-D` parameters it was loaded with (`load`).
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
        let mean = image::read_exr(&path)?;
        let var = image::read_exr(&dir.join(format!("{name}_var.exr")))?;
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
