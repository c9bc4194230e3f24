//! `reports/index.html`: per scene the reference, each method's image and a false-colour
//! map of its error side by side, the table, and the figures. Built from what `table`
//! and `figures` wrote (table1.json, run.json, figN.json, the images), so the page shows
//! exactly the measured run.
//!
//! The page checks itself: a script counts the images that loaded and writes
//! `data-images-loaded="N/M"` on `<body>` (tests/report_html.rs reads it from headless
//! Chromium).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};

use super::output::{interval, paper_cells, summaries_of, RunInfo, PAPER_HEADER};
use super::reference::read_reference_images;
use super::table::{Method, Row};
use crate::image;
use crate::image::Image;

/// Per pixel, |image − reference| averaged over channels, as a false-colour PNG on
/// the scale [0, `scale`] (black → blue → red → yellow → white).
pub fn write_error_map(path: &Path, img: &Image, reference: &Image, scale: f32) -> Result<()> {
    let err = abs_error(img, reference);
    let mut rgb = Vec::with_capacity(err.len() * 3);
    for e in err {
        let t = (e / scale.max(1e-12)).clamp(0.0, 1.0);
        rgb.extend_from_slice(&heat(t));
    }
    let file =
        std::fs::File::create(path).with_context(|| format!("cannot write {}", path.display()))?;
    let mut enc = png::Encoder::new(
        std::io::BufWriter::new(file),
        img.width as u32,
        img.height as u32,
    );
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut w = enc.write_header()?;
    w.write_image_data(&rgb)?;
    Ok(())
}

fn abs_error(img: &Image, reference: &Image) -> Vec<f32> {
    img.pixels
        .iter()
        .zip(&reference.pixels)
        .map(|(a, b)| ((a[0] - b[0]).abs() + (a[1] - b[1]).abs() + (a[2] - b[2]).abs()) / 3.0)
        .collect()
}

/// A black-body-like ramp: t in [0, 1] → sRGB bytes.
fn heat(t: f32) -> [u8; 3] {
    let stops: [(f32, [f32; 3]); 5] = [
        (0.0, [0.0, 0.0, 0.0]),
        (0.25, [0.1, 0.1, 0.6]),
        (0.5, [0.8, 0.1, 0.2]),
        (0.75, [1.0, 0.8, 0.0]),
        (1.0, [1.0, 1.0, 1.0]),
    ];
    let i = stops.iter().rposition(|s| s.0 <= t).unwrap_or(0).min(3);
    let (t0, c0) = stops[i];
    let (t1, c1) = stops[i + 1];
    let u = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
    let mut out = [0u8; 3];
    for k in 0..3 {
        out[k] = ((c0[k] + u * (c1[k] - c0[k])) * 255.0).round() as u8;
    }
    out
}

/// The 99th percentile of a scene's plain-volpath error: one scale for all its maps.
fn error_scale(img: &Image, reference: &Image) -> f32 {
    let mut e = abs_error(img, reference);
    e.sort_by(f32::total_cmp);
    e[((e.len() - 1) as f64 * 0.99) as usize].max(1e-6)
}

fn rel(path: &Path, base: &Path) -> String {
    pathdiff::diff_paths(path, base)
        .unwrap_or_else(|| path.to_path_buf())
        .to_string_lossy()
        .replace('\\', "/")
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Captions of the figures, in page order.
const FIGURE_CAPTIONS: [(&str, &str); 8] = [
    ("fig7", "Fig. 7: the three prediction functions on a row of pixels of the Cube, against the reference."),
    ("fig11", "Fig. 11: MSE against time on the Cube: where the biased method stops winning."),
    ("fig12", "Fig. 12: albedo 0.5, the paper's failure case: no gain expected."),
    ("fig6", "Fig. 6: σ_t sweep on the Bunny, regularized against equal-time volpath."),
    ("fig9", "Fig. 9: MSE against the source factor on Lucy."),
    ("speed_bunny", "Speed against error, Bunny."),
    ("speed_candle", "Speed against error, Candle."),
    ("speed_lucy", "Speed against error, Lucy."),
];

/// Writes `out` (an HTML file) from the table in `table_dir` and the figures in
/// `figures_dir`; error maps are written beside the table's images.
pub fn write_report(out: &Path, table_dir: &Path, figures_dir: &Path) -> Result<PathBuf> {
    let page_dir = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."))
        .to_path_buf();
    let abs = |p: &Path| std::fs::canonicalize(p).with_context(|| format!("{}", p.display()));
    let page_abs = abs(&page_dir)?;
    let table_abs = abs(table_dir)?;
    let all: Vec<Row> = serde_json::from_str(
        &std::fs::read_to_string(table_dir.join("table1_seeds.json"))
            .with_context(|| format!("no table in {}: run mediareg table", table_dir.display()))?,
    )
    .context("table1_seeds.json")?;
    let rows = super::output::first_seed_rows(&all);
    let run: RunInfo = serde_json::from_str(&std::fs::read_to_string(table_dir.join("run.json"))?)
        .context("run.json")?;

    let mut html = String::new();
    html.push_str(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n\
         <title>mediareg: the paper's Table 1 and figures against Mitsuba 3</title>\n<style>\n\
         body{font-family:sans-serif;max-width:1400px;margin:auto;padding:1em}\n\
         table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #ccc;padding:4px 8px;text-align:right}\n\
         th{background:#f0f0f0}td:first-child,td:nth-child(2){text-align:left}\n\
         .row{display:flex;flex-wrap:wrap;gap:8px}.row figure{margin:0}\n\
         .row img{width:240px;image-rendering:pixelated}figcaption{font-size:12px;max-width:240px}\n\
         .plot img{max-width:900px;width:100%}\n</style></head>\n<body>\n",
    );
    writeln!(
        html,
        "<h1>The paper's Table 1 and figures, against Mitsuba 3</h1>\n<p>{}; {} threads. MSE against each scene's Mitsuba 3 reference; <em>corrected</em> subtracts the reference's own variance. Made by <code>mediareg table</code>, <code>mediareg figures</code> and <code>mediareg report</code>; every number is in <code>table/table1.json</code> and <code>figures/*.json</code>.</p>",
        esc(&run.budget),
        run.threads
    )?;

    // The table: the summaries over seeds.
    let summaries = summaries_of(&run, &all);
    html.push_str("<h2>Table 1</h2>\n<table><tr><th>scene</th><th>method</th><th>accounting</th><th>spp</th><th>seconds</th><th>MSE corrected</th><th>÷ volpath [95% CI]</th><th>÷ best [95% CI]</th><th>best</th></tr>\n");
    for r in &summaries {
        writeln!(
            html,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.0}</td><td>{:.2}</td><td>{:.3e}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&r.scene),
            r.method.as_str(),
            r.accounting.as_str(),
            r.spp,
            r.seconds,
            r.mse_corrected,
            interval(r.ratio_to_volpath),
            interval(r.ratio_to_best),
            r.best.map_or("–", |b| b.as_str())
        )?;
    }
    writeln!(
        html,
        "</table>\n<table><tr><th>{}</th></tr>",
        PAPER_HEADER.map(esc).join("</th><th>")
    )?;
    let mut scenes: Vec<&str> = rows.iter().map(|r| r.scene.as_str()).collect();
    scenes.dedup();
    for s in &scenes {
        let cells = paper_cells(&summaries, s);
        writeln!(
            html,
            "<tr><td>{}</td><td>{}</td></tr>",
            esc(s),
            cells.map(|c| esc(&c)).join("</td><td>")
        )?;
    }
    html.push_str("</table>\n");

    // Images per scene.
    for s in &scenes {
        let scene_rows: Vec<&Row> = rows.iter().filter(|r| r.scene == *s).collect();
        let reference_exr = table_abs.join(&scene_rows[0].reference);
        // Checked against its JSON's images_sha256 again: the report may be made long
        // after the table, from a reference replaced since.
        let name = (reference_exr.file_stem())
            .with_context(|| format!("{}: no reference name", reference_exr.display()))?;
        let (reference, _, _) = read_reference_images(
            reference_exr.parent().unwrap_or(Path::new(".")),
            &name.to_string_lossy(),
        )?;
        let volpath = scene_rows
            .iter()
            .find(|r| r.method == Method::Volpath)
            .context("the table has no volpath row")?;
        let scale = error_scale(
            &image::read_exr(&table_abs.join(&volpath.image))?,
            &reference,
        );
        writeln!(
            html,
            "<h2>{}</h2>\n<p>Error maps: |image − reference| (channel mean), black 0 to white {scale:.3e} (the 99th percentile of volpath's error).</p>\n<div class=\"row\">",
            esc(s)
        )?;
        let reference_png = table_abs.join(format!("{s}_reference.png"));
        writeln!(
            html,
            "<figure><img src=\"{}\" alt=\"{s} reference\"><figcaption>Mitsuba 3 reference</figcaption></figure>",
            rel(&reference_png, &page_abs)
        )?;
        html.push_str("</div>\n<div class=\"row\">");
        for r in &scene_rows {
            let exr = table_abs.join(&r.image);
            writeln!(
                html,
                "<figure><img src=\"{}\" alt=\"{s} {m}\"><figcaption>{m}: {} spp, {:.1} s, MSE {:.2e}</figcaption></figure>",
                rel(&exr.with_extension("png"), &page_abs),
                r.spp,
                r.seconds,
                r.mse_corrected,
                m = r.method.as_str()
            )?;
        }
        html.push_str("</div>\n<div class=\"row\">");
        for r in &scene_rows {
            let exr = table_abs.join(&r.image);
            let map = exr.with_file_name(format!(
                "{}_error.png",
                exr.file_stem().unwrap_or_default().to_string_lossy()
            ));
            write_error_map(&map, &image::read_exr(&exr)?, &reference, scale)?;
            writeln!(
                html,
                "<figure><img src=\"{}\" alt=\"{s} {m} error\"><figcaption>{m}: error</figcaption></figure>",
                rel(&map, &page_abs),
                m = r.method.as_str()
            )?;
        }
        html.push_str("</div>\n");
    }

    // Figures.
    html.push_str("<h2>Figures</h2>\n");
    if figures_dir.is_dir() {
        let fig_abs = abs(figures_dir)?;
        for (name, caption) in FIGURE_CAPTIONS {
            let png = fig_abs.join(format!("{name}.png"));
            if png.exists() {
                writeln!(
                    html,
                    "<figure class=\"plot\"><img src=\"{}\" alt=\"{name}\"><figcaption>{} Numbers: <a href=\"{}\">{name}.json</a>.</figcaption></figure>",
                    rel(&png, &page_abs),
                    esc(caption),
                    rel(&fig_abs.join(format!("{name}.json")), &page_abs)
                )?;
            }
        }
    }
    sweep_section(&mut html, table_dir, &page_abs)?;
    if !run.notes.is_empty() {
        html.push_str("<h2>Notes</h2>\n<ul>\n");
        for n in &run.notes {
            writeln!(html, "<li>{}</li>", esc(n))?;
        }
        html.push_str("</ul>\n");
    }
    html.push_str(
        "<script>\nwindow.addEventListener('load', () => {\n  const imgs = [...document.images];\n  const ok = imgs.filter(i => i.complete && i.naturalWidth > 0).length;\n  document.body.dataset.imagesLoaded = ok + '/' + imgs.length;\n});\n</script>\n</body></html>\n",
    );
    std::fs::write(out, html).with_context(|| format!("cannot write {}", out.display()))?;
    Ok(out.to_path_buf())
}

/// The budget sweep (`mediareg sweep`, `sweep.json` beside the table), where it ran:
/// its plots, one per scene and accounting.
fn sweep_section(html: &mut String, table_dir: &Path, page_abs: &Path) -> Result<()> {
    let json = table_dir.join("sweep.json");
    if !json.exists() {
        return Ok(());
    }
    let dir =
        std::fs::canonicalize(table_dir).with_context(|| format!("{}", table_dir.display()))?;
    let mut plots: Vec<PathBuf> = std::fs::read_dir(&dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
            name.starts_with("sweep_") && name.ends_with(".png")
        })
        .collect();
    plots.sort();
    html.push_str("<h2>Across budgets</h2>\n<p>Every method at five budgets per frame, 3 seeds each, at 128×128 against 128×128 references (<code>mediareg sweep</code>): mean corrected MSE against the seconds charged, log–log, with a band of two standard errors over the seeds. Numbers: ");
    writeln!(
        html,
        "<a href=\"{}\">sweep.json</a>.</p>",
        rel(&dir.join("sweep.json"), page_abs)
    )?;
    for png in plots {
        let name = png
            .file_stem()
            .and_then(|n| n.to_str())
            .unwrap_or("")
            .to_string();
        writeln!(
            html,
            "<figure class=\"plot\"><img src=\"{}\" alt=\"{name}\"><figcaption>{}</figcaption></figure>",
            rel(&png, page_abs),
            esc(&name.replacen("sweep_", "", 1).replace('_', ", "))
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heat_ramp_runs_from_black_to_white() {
        assert_eq!(heat(0.0), [0, 0, 0]);
        assert_eq!(heat(1.0), [255, 255, 255]);
        let mid = heat(0.5);
        assert!(mid[0] > 150 && mid[2] < 100, "{mid:?}");
    }
}
