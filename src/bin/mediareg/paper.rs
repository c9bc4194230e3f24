//! `mediareg table`, `figures` and `report`: the paper's Table 1 and figures on this
//! machine, and the HTML page of both.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use mediareg::report;

use crate::common::{table_options, TableArgs};

pub fn table(args: TableArgs) -> Result<()> {
    let opts = table_options(args, "out/table")?;
    let run = report::run_table(&opts)?;
    report::output::write_outputs(&opts, &run)?;
    for n in &run.notes {
        eprintln!("note: {n}");
    }
    println!(
        "wrote {} rows to {}/table1.md, table1.csv, table1.json",
        run.rows.len(),
        opts.out.display()
    );
    Ok(())
}

/// The paper's figures (Fig. 6, 7, 9, 11, 12 and speed against error) as PNG plots
/// with their numbers (figN.json), from reduced-size sweeps against the references
/// in reference/figures/ (Fig. 7: the full-size cube).
#[derive(Args)]
pub struct FiguresArgs {
    #[command(flatten)]
    pub table: TableArgs,
    /// Make only these (fig7, fig11, fig12, fig6, fig9, speed).
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    #[arg(long, default_value = "reference/figures")]
    pub figure_reference_dir: PathBuf,
    /// Resolution of the sweeps.
    #[arg(long, default_value_t = 128)]
    pub res: u32,
    /// Seconds per method of the sweeps over time (Fig. 11, 12, speed).
    #[arg(long, value_delimiter = ',', default_value = "0.5,1,2,4,8")]
    pub budgets: Vec<f64>,
    /// Seconds per method of the sweeps over a parameter (Fig. 6, 9).
    #[arg(long, default_value_t = 2.0)]
    pub sweep_budget: f64,
    /// Samples per pixel per frame of Fig. 7.
    #[arg(long, default_value_t = 64)]
    pub fig7_spp: u32,
}

pub fn figures(cmd: FiguresArgs) -> Result<()> {
    let FiguresArgs {
        table,
        only,
        figure_reference_dir,
        res,
        budgets,
        sweep_budget,
        fig7_spp,
    } = cmd;
    let base = table_options(table, "out/figures")?;
    let opts = report::figures::FigureOptions {
        base,
        figure_reference_dir,
        res,
        budgets,
        budget: sweep_budget,
        fig7_spp,
        only,
    };
    let written = report::figures::make_figures(&opts)?;
    let names: Vec<String> = written.iter().map(|p| p.display().to_string()).collect();
    println!("wrote {}", names.join(", "));
    Ok(())
}

/// Table 1's methods across budgets (`report::sweep`).
#[derive(Args)]
pub struct SweepArgs {
    #[command(flatten)]
    pub table: TableArgs,
    /// Seconds per method and frame.
    #[arg(long, value_delimiter = ',', default_value = "0.2,0.4,0.8,1.6,3.2")]
    pub budgets: Vec<f64>,
    /// Resolution (`-D res=`), with references made for it.
    #[arg(long, default_value_t = 128)]
    pub res: u32,
    #[arg(long, default_value = "reference/figures")]
    pub figure_reference_dir: PathBuf,
}

pub fn sweep(cmd: SweepArgs) -> Result<()> {
    let threads = cmd.table.threads;
    let base = table_options(cmd.table, "out/sweep")?;
    let opts = report::sweep::SweepOptions {
        base,
        reference_dir: cmd.figure_reference_dir,
        res: cmd.res,
        budgets: cmd.budgets,
    };
    let json = report::sweep::run_sweep(&opts, threads)?;
    println!("wrote {}", json.display());
    Ok(())
}

/// An HTML page (reports/index.html) from a table run and the figures: per scene the
/// reference, each method's image and error map, the table, the plots. Also remakes
/// the table's table1.md from its JSON files.
#[derive(Args)]
pub struct ReportArgs {
    #[arg(long, default_value = "reports/table")]
    pub table: PathBuf,
    #[arg(long, default_value = "reports/figures")]
    pub figures: PathBuf,
    #[arg(short = 'o', long = "output", default_value = "reports/index.html")]
    pub output: PathBuf,
}

pub fn report(args: ReportArgs) -> Result<()> {
    report::output::rewrite_markdown(&args.table)?;
    let page = report::html::write_report(&args.output, &args.table, &args.figures)?;
    println!("wrote {}", page.display());
    Ok(())
}
