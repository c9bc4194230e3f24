//! Mitsuba 3 as a method of the table: `scripts/mitsuba_render.py` renders the same XML
//! with the real Mitsuba 3 (the `mitsuba` Python package) at a spp or a time budget.

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context, Result};
use serde::Deserialize;

/// How to run Mitsuba 3.
#[derive(Clone, Debug)]
pub struct MitsubaRunner {
    /// The Python interpreter that has `mitsuba` installed.
    pub python: PathBuf,
    /// `scripts/mitsuba_render.py`.
    pub script: PathBuf,
}

/// What `scripts/mitsuba_render.py` is asked to render: the scene file loaded as
/// Mitsuba's `load_file` loads it (with `-D` defines, `-a` search folders), rendered
/// at `spp`, or at as many spp as fit in `budget` seconds, from `seed`.
#[derive(Clone, Copy, Debug)]
pub struct MitsubaRequest<'a> {
    /// The scene's XML file.
    pub scene: &'a Path,
    /// Where the image goes (EXR).
    pub out: &'a Path,
    /// `-D name=value`: the scene file's parameters.
    pub defines: &'a [(String, String)],
    /// `-a`: folders the file resolver searches.
    pub search: &'a [PathBuf],
    /// Samples per pixel; when set, `budget` is ignored.
    pub spp: Option<u32>,
    /// Seconds to spend when `spp` is `None` (one of the two must be set).
    pub budget: Option<f64>,
    pub seed: u64,
}

/// What the script reports.
#[derive(Clone, Debug, Deserialize)]
pub struct MitsubaRender {
    pub spp: u32,
    pub seconds: f64,
    pub variant: String,
    pub mitsuba_version: String,
}

/// Why Mitsuba 3 did not render.
#[derive(Debug)]
pub enum Unavailable {
    /// The interpreter or the script is missing, or `mitsuba` cannot be imported.
    NotInstalled(String),
    Failed(anyhow::Error),
}

/// The script's exit status when `import mitsuba` fails.
const EXIT_NO_MITSUBA: i32 = 3;

impl MitsubaRunner {
    /// `.venv/bin/python` when present (where README's setup installs Mitsuba 3), else
    /// `python3`; the script from `scripts/`.
    pub fn default_in(root: &Path) -> MitsubaRunner {
        let venv = root.join(".venv/bin/python");
        MitsubaRunner {
            python: if venv.exists() {
                venv
            } else {
                PathBuf::from("python3")
            },
            script: root.join("scripts/mitsuba_render.py"),
        }
    }

    /// Renders `request.scene` into `request.out` (EXR) at `request.spp`, or for about
    /// `request.budget` seconds.
    pub fn render(
        &self,
        request: &MitsubaRequest,
    ) -> std::result::Result<MitsubaRender, Unavailable> {
        if !self.script.exists() {
            return Err(Unavailable::NotInstalled(format!(
                "{} not found (run from the project's root)",
                self.script.display()
            )));
        }
        let mut cmd = Command::new(&self.python);
        cmd.arg(&self.script)
            .arg(request.scene)
            .arg("--out")
            .arg(request.out)
            .arg("--seed")
            .arg(request.seed.to_string());
        match (request.spp, request.budget) {
            (Some(n), _) => cmd.arg("--spp").arg(n.to_string()),
            (None, Some(b)) => cmd.arg("--budget").arg(format!("{b}")),
            (None, None) => unreachable!("a spp or a budget"),
        };
        for dir in request.search {
            cmd.arg("-a").arg(dir);
        }
        for (k, v) in request.defines {
            cmd.arg("-D").arg(format!("{k}={v}"));
        }
        let output = match cmd.output() {
            Ok(o) => o,
            Err(e) => {
                return Err(Unavailable::NotInstalled(format!(
                    "cannot run {}: {e}",
                    self.python.display()
                )))
            }
        };
        let stderr = String::from_utf8_lossy(&output.stderr);
        if output.status.code() == Some(EXIT_NO_MITSUBA) {
            return Err(Unavailable::NotInstalled(stderr.trim().to_string()));
        }
        let parse = || -> Result<MitsubaRender> {
            if !output.status.success() {
                let tail: Vec<&str> = stderr.lines().rev().take(5).collect();
                bail!(
                    "{} failed ({}): {}",
                    self.script.display(),
                    output.status,
                    tail.into_iter().rev().collect::<Vec<_>>().join(" | ")
                );
            }
            let stdout = String::from_utf8_lossy(&output.stdout);
            let line = stdout
                .lines()
                .rev()
                .find(|l| l.starts_with('{'))
                .context("Mitsuba's render printed no result line")?;
            serde_json::from_str(line).context("cannot read Mitsuba's result line")
        };
        parse().map_err(Unavailable::Failed)
    }
}
