//! The HTML report opened in headless Chromium: every image and plot on the page must
//! load. The page counts them itself on `load` and writes `data-images-loaded="N/M"` on
//! its body, which `--dump-dom` shows. CI installs Chromium (.ci/run); elsewhere the test
//! needs it too (`apt-get install chromium`), or MEDIAREG_NO_BROWSER=1 to skip.

mod common;

use std::path::Path;
use std::process::Command;

/// (loaded, total) images of the page, as Chromium saw them; None when skipped.
fn images_loaded(page: &Path) -> Option<(usize, usize)> {
    if std::env::var_os("MEDIAREG_NO_BROWSER").is_some() {
        eprintln!("MEDIAREG_NO_BROWSER set: not opening {}", page.display());
        return None;
    }
    let url = format!("file://{}", std::fs::canonicalize(page).unwrap().display());
    let out = Command::new("chromium")
        .args(["--headless", "--no-sandbox", "--disable-gpu"])
        .args(["--virtual-time-budget=10000", "--dump-dom"])
        .arg(&url)
        .output()
        .expect(
            "chromium must be installed (apt-get install chromium), or set MEDIAREG_NO_BROWSER=1",
        );
    let dom = String::from_utf8_lossy(&out.stdout);
    let key = "data-images-loaded=\"";
    let start = dom.find(key).unwrap_or_else(|| {
        panic!(
            "the page's image check did not run: {}",
            dom.chars().take(300).collect::<String>()
        )
    }) + key.len();
    let value = &dom[start..start + dom[start..].find('"').unwrap()];
    let (ok, all) = value.split_once('/').unwrap();
    Some((ok.parse().unwrap(), all.parse().unwrap()))
}

#[test]
fn a_generated_report_shows_every_image() {
    let dir = std::env::temp_dir().join(format!("mediareg_report_{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let table = dir.join("table");
    // A copy of the references, to replace one below.
    let refs = dir.join("reference");
    std::fs::create_dir_all(&refs).unwrap();
    for f in ["cube.json", "cube.exr", "cube_var.exr"] {
        std::fs::copy(
            common::root().join("reference/table_small").join(f),
            refs.join(f),
        )
        .unwrap();
    }
    let bin = env!("CARGO_BIN_EXE_mediareg");
    let o = Command::new(bin)
        .current_dir(common::root())
        .args([
            "table", "--scenes", "cube", "-D", "res=32", "--budget", "0.3",
        ])
        .args(["--frames", "3", "--reference-dir"])
        .arg(&refs)
        .args(["--seeds", "2", "--no-mitsuba", "--out"])
        .arg(&table)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let page = dir.join("index.html");
    let report = || {
        Command::new(bin)
            .current_dir(common::root())
            .arg("report")
            .arg("--table")
            .arg(&table)
            .arg("--figures")
            .arg(dir.join("no_figures"))
            .arg("-o")
            .arg(&page)
            .output()
            .unwrap()
    };
    let o = report();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let html = std::fs::read_to_string(&page).unwrap();
    // The reference, the first seed's frame rows (volpath, volpath_oidn where OIDN
    // loads, regularized_paper, regularized, volpath_filtered) and their error maps.
    let methods = 4 + common::oidn_present() as usize;
    let n = 1 + 2 * methods;
    assert_eq!(html.matches("<img ").count(), n);
    if let Some((ok, all)) = images_loaded(&page) {
        assert_eq!((ok, all), (n, n));
    }
    // A broken link is caught: remove one image and look again.
    std::fs::remove_file(table.join("cube_volpath_error.png")).unwrap();
    if let Some((ok, all)) = images_loaded(&page) {
        assert_eq!(
            (ok, all),
            (n - 1, n),
            "a missing image must count as not loaded"
        );
    }
    // A reference replaced after the table (one byte of its EXR changed) is refused.
    let exr = refs.join("cube.exr");
    let mut bytes = std::fs::read(&exr).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 1;
    std::fs::write(&exr, bytes).unwrap();
    let o = report();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "a replaced reference was shown");
    assert!(
        stderr.contains("cube.exr has sha256") && stderr.contains("mitsuba_reference.py"),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_committed_report_shows_every_image_and_plot() {
    let page = common::root().join("reports/index.html");
    let html = std::fs::read_to_string(&page).expect("reports/index.html is committed");
    let n = html.matches("<img ").count();
    // Three scenes × (reference + 6 methods + 6 error maps), and the plots.
    assert!(n >= 3 * 13 + 3, "only {n} images on the page");
    if let Some((ok, all)) = images_loaded(&page) {
        assert_eq!(
            (ok, all),
            (n, n),
            "images that did not load on {}",
            page.display()
        );
    }
}
