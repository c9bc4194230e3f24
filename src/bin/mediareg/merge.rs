//! `mediareg merge`: one image from renders of a shot made in chunks.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use mediareg::image::{self, merge};

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
    let written = merge::write_merged(&args.out, &merged)?;
    if merged.var.is_none() {
        eprintln!("warning: one chunk has no spread: no variance written");
    }
    let written: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    println!(
        "merged {} chunks, {} spp; wrote {}",
        merged.chunks,
        merged.spp,
        written.join(", ")
    );
    Ok(())
}
