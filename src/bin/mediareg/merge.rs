//! `mediareg merge`: one image from renders of a shot made in chunks.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use mediareg::image::{self, merge};

use crate::common::sibling;

/// Merge renders of one shot made in chunks (`mediareg render --seed S --spp N`, each
/// seed its own) into OUT.exr, weighted by the spp in each chunk's header, and
/// OUT_var.exr, the variance of that mean per pixel and channel (from the chunks'
/// spread; two chunks at least).
#[derive(Args)]
pub struct MergeArgs {
    /// The merged image (its header's spp: the chunks' total).
    pub out: PathBuf,
    /// The chunk EXRs.
    #[arg(required = true, num_args = 1..)]
    pub chunks: Vec<PathBuf>,
}

pub fn run(args: MergeArgs) -> Result<()> {
    let merged = merge::merge_files(&args.chunks)?;
    image::check_writable(&args.out)?;
    let spp = i32::try_from(merged.spp).unwrap_or(i32::MAX);
    image::write_exr_with(&args.out, &merged.mean, &[("spp", spp)])?;
    let mut written = vec![args.out.display().to_string()];
    match &merged.var {
        Some(var) => {
            let out_var = sibling(&args.out, "_var");
            image::write_exr_with(&out_var, var, &[("spp", spp)])?;
            written.push(out_var.display().to_string());
        }
        None => eprintln!("warning: one chunk has no spread: no variance written"),
    }
    println!(
        "merged {} chunks, {} spp; wrote {}",
        merged.chunks,
        merged.spp,
        written.join(", ")
    );
    Ok(())
}
