//! The `mediareg` command line: argument parsing and reporting only, one file per
//! command (render, regularize, merge, and the paper's table, figures and report).

mod backward;
mod common;
mod fit;
mod interrupt;
mod merge;
mod optimize;
mod paper;
mod regularize;
mod render;

use std::process::ExitCode;
use std::sync::atomic::Ordering;

use anyhow::Result;
use clap::{Parser, Subcommand};

use common::TableArgs;
use interrupt::{EXIT_INTERRUPTED, INTERRUPT};

#[derive(Parser)]
#[command(
    name = "mediareg",
    version,
    long_version = long_version(),
    about = "A renderer for participating media that reads Mitsuba 3 scene files"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a Mitsuba 3 scene file to OUT.exr (linear RGB) and OUT.png (sRGB preview).
    Render(render::RenderArgs),
    /// The paper's method: render at source albedo factor × the scene's, denoise the
    /// albedo gradient over a camera sequence, predict the image at the scene's albedo.
    /// Writes OUT.exr (the prediction), OUT_source.exr, OUT_dalbedo_raw.exr and
    /// OUT_dalbedo.exr (denoised), each with a PNG preview.
    Regularize(regularize::RegularizeArgs),
    /// The paper's Table 1 on this machine: for each scene, at equal time (or spp), the
    /// regularized method (temporal and single-frame spatial), plain volpath and Mitsuba 3's
    /// volpath, each image's MSE against the scene's Mitsuba 3 reference. Writes
    /// OUT/table1.md, table1.csv, table1.json, run.json and every image.
    Table(TableArgs),
    /// An HTML page (reports/index.html) from a table run and the figures: per scene the
    /// reference, each method's image and error map, the table, the plots. Also remakes
    /// the table's table1.md from its JSON files.
    Report(paper::ReportArgs),
    /// The paper's figures (Fig. 6, 7, 9, 11, 12 and speed against error) as PNG plots
    /// with their numbers (figN.json), from reduced-size sweeps against the references
    /// in reference/figures/ (Fig. 7: the full-size cube).
    Figures(paper::FiguresArgs),
    /// Table 1's methods across budgets at the figures' reduced size, both accountings,
    /// several seeds: OUT/sweep.json (each ratio to the best baseline with its 95%
    /// interval) and a plot of MSE against seconds per scene and accounting.
    Sweep(paper::SweepArgs),
    /// Fit a medium's parameters (sigma_t, albedo, g, scale) to target images; writes
    /// OUT.json with the values, their 95% intervals and the loss per iteration.
    Fit(fit::FitArgs),
    /// Reverse-mode gradients: the gradient of Σ A · I (A an adjoint image) in every
    /// voxel of a grid medium's sigma_t (and albedo), written as PREFIX_sigma_t.vol.
    Backward(backward::BackwardArgs),
    /// Fit a grid medium's voxels to images of the scene's sensors (Mitsuba 3's volume
    /// tutorial): L2 loss, reverse-mode gradients, Adam, coarse to fine. Writes OUT.vol
    /// and OUT.json (the loss and seconds per iteration).
    Optimize(optimize::OptimizeArgs),
    /// Merge renders of one shot made in chunks (distinct seeds) into OUT.exr, weighted
    /// by each chunk's spp, and OUT_var.exr, the variance of that mean.
    Merge(merge::MergeArgs),
}

/// `mediareg --version`: the version, the ray caster a mesh scene gets here, and the
/// CPU features the build was compiled for (`.cargo/config.toml`: the building CPU's).
fn long_version() -> &'static str {
    let features: Vec<&str> = [
        ("sse4.2", cfg!(target_feature = "sse4.2")),
        ("avx", cfg!(target_feature = "avx")),
        ("avx2", cfg!(target_feature = "avx2")),
        ("fma", cfg!(target_feature = "fma")),
        ("bmi2", cfg!(target_feature = "bmi2")),
        ("avx512f", cfg!(target_feature = "avx512f")),
        ("avx512vl", cfg!(target_feature = "avx512vl")),
        ("neon", cfg!(target_feature = "neon")),
    ]
    .into_iter()
    .filter_map(|(name, on)| on.then_some(name))
    .collect();
    let text = format!(
        "{}\nray caster: {}\nCPU features: {}",
        env!("CARGO_PKG_VERSION"),
        mediareg::geometry::accel::Backend::describe(),
        if features.is_empty() {
            "none beyond the target's baseline".to_string()
        } else {
            features.join(" ")
        }
    );
    // Once per process, for clap's 'static string.
    Box::leak(text.into_boxed_str())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) if INTERRUPT.load(Ordering::SeqCst) => ExitCode::from(EXIT_INTERRUPTED),
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            if INTERRUPT.load(Ordering::SeqCst) {
                ExitCode::from(EXIT_INTERRUPTED)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}

fn run(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Render(args) => render::run(args),
        Command::Regularize(args) => regularize::run(args),
        Command::Table(args) => paper::table(args),
        Command::Report(args) => paper::report(args),
        Command::Figures(args) => paper::figures(args),
        Command::Sweep(args) => paper::sweep(args),
        Command::Merge(args) => merge::run(args),
        Command::Fit(args) => fit::run(args),
        Command::Backward(args) => backward::run(args),
        Command::Optimize(args) => optimize::run(args),
    }
}
