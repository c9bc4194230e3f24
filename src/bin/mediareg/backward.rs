//! `mediareg backward`: reverse-mode gradients of a grid medium's voxels
//! (`mediareg::integrator::backward`), written as Mitsuba `.vol` files.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::{anyhow, bail, Context, Result};
use clap::Args;

use mediareg::image;
use mediareg::integrator::backward::{self, BackwardOptions};
use mediareg::medium::grid::{write_vol_like, Source, Volume};

use crate::common::{medium_error, prepare, SceneArgs};
use crate::interrupt::{install_handler, INTERRUPT};

/// The gradient of L = Σ A · I (A an adjoint image, I the render) in every value of a
/// grid medium's sigma_t and albedo volumes, by path replay: writes OUT_sigma_t.vol
/// and OUT_albedo.vol, shaped as the medium's grids (Mitsuba's gridvolume format).
#[derive(Args)]
pub struct BackwardArgs {
    #[command(flatten)]
    pub args: SceneArgs,
    /// The adjoint image A: ∂L/∂(pixel, channel), an RGB EXR of the film's size.
    #[arg(long, value_name = "A.exr")]
    pub adjoint: PathBuf,
    /// The volumes to differentiate, comma-separated: sigma_t, albedo.
    #[arg(long, value_name = "PARAMS", default_value = "sigma_t")]
    pub params: String,
    /// The medium: its XML id, its slot (interior, exterior) or its mi.traverse key
    /// (SHAPE_ID.interior_medium); needed when the scene has several.
    #[arg(long, value_name = "NAME")]
    pub medium: Option<String>,
}

/// Which volumes a `--params` list names.
pub fn parse_volume_params(list: &str) -> Result<(bool, bool)> {
    let (mut sigma_t, mut albedo) = (false, false);
    for name in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        match name {
            "sigma_t" => sigma_t = true,
            "albedo" => albedo = true,
            other => bail!(
                "--params: unknown volume '{other}' (reverse mode differentiates the voxels \
                 of sigma_t and albedo; a medium's scale or g: render --gradient)"
            ),
        }
    }
    if !sigma_t && !albedo {
        bail!("--params: name sigma_t, albedo or both");
    }
    Ok((sigma_t, albedo))
}

/// `volume`'s data replaced by `values`, as a .vol file at `path`.
pub fn write_grid(path: &Path, volume: &Volume, values: &[f32]) -> Result<()> {
    let Source::Grid { grid, .. } = &volume.source else {
        bail!("{}: the volume is no grid", path.display());
    };
    std::fs::write(path, write_vol_like(grid, values))
        .with_context(|| format!("writing {}", path.display()))
}

pub fn run(mut cmd: BackwardArgs) -> Result<()> {
    let (sigma_t, albedo) = parse_volume_params(&cmd.params)?;
    // -o is a prefix here, not an EXR.
    let prefix = cmd.args.output.take();
    let adjoint = image::read_exr(&cmd.adjoint)
        .map_err(|e| anyhow!("--adjoint {}: {e}", cmd.adjoint.display()))?;
    let (scene, out) = prepare(&cmd.args)?;
    let medium = scene
        .medium_index(cmd.medium.as_deref())
        .map_err(medium_error)?;
    install_handler()?;
    let opts = BackwardOptions {
        medium,
        sigma_t,
        albedo,
        show_progress: std::io::stderr().is_terminal(),
        cancel: Some(Arc::clone(&INTERRUPT)),
        defect: None,
    };
    let grads = backward::backward(&scene, &scene.shot, &adjoint, &opts)
        .map_err(|e| anyhow!("{}: {e}", cmd.args.scene.display()))?;
    if grads.interrupted {
        eprintln!("interrupted: the gradient of the rows done, scaled to the whole image");
    }
    let het = scene.media[medium as usize]
        .heterogeneous
        .as_deref()
        .ok_or_else(|| anyhow!("the medium is not heterogeneous"))?;
    let prefix = prefix.unwrap_or_else(|| out.with_extension(""));
    let mut written = Vec::new();
    for (name, values, volume) in [
        ("sigma_t", &grads.sigma_t, &het.sigma_t),
        ("albedo", &grads.albedo, &het.albedo),
    ] {
        if let Some(v) = values {
            let path = PathBuf::from(format!("{}_{name}.vol", prefix.display()));
            write_grid(&path, volume, v)?;
            written.push(path.display().to_string());
        }
    }
    eprintln!(
        "{} spp in {:.2} s: {}",
        scene.shot.spp,
        grads.seconds,
        written.join(", ")
    );
    Ok(())
}
