//! The experiment's HTML report in a real headless browser (Chromium): the page loads, every
//! image decodes, every plot is drawn, and the console stays silent. A page with a broken
//! image and a script error is caught by the same check.
//!
//! Skips when no Chromium is installed, unless `REQUIRE_BROWSER` is set (`.ci/run` sets it
//! and installs Chromium).

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::xtask;

/// Chromium's executable: `$CHROMIUM`, else the first of the usual names on PATH.
fn chromium() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    let path = std::env::var_os("PATH")?;
    for name in ["chromium", "chromium-browser", "google-chrome", "chrome"] {
        for dir in std::env::split_paths(&path) {
            let p = dir.join(name);
            if p.is_file() {
                return Some(p);
            }
        }
    }
    None
}

/// Loads `page` headless; returns the page's self-check (`<body data-check>`) and the
/// console lines Chromium logged.
fn load(browser: &Path, page: &Path) -> (String, Vec<String>) {
    let profile = page.with_extension("profile");
    let out = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--enable-logging=stderr",
            "--v=0",
            "--virtual-time-budget=10000",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg("--dump-dom")
        .arg(format!("file://{}", page.display()))
        .output()
        .expect("run chromium");
    assert!(
        out.status.success(),
        "chromium failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let dom = String::from_utf8_lossy(&out.stdout);
    let check = dom
        .split("data-check=\"")
        .nth(1)
        .and_then(|t| t.split('"').next())
        .unwrap_or("no self-check ran")
        .to_string();
    let console = String::from_utf8_lossy(&out.stderr)
        .lines()
        .filter(|l| l.contains(":CONSOLE"))
        .map(str::to_string)
        .collect();
    let _ = std::fs::remove_dir_all(&profile);
    (check, console)
}

fn field(check: &str, name: &str) -> usize {
    check
        .split_whitespace()
        .find_map(|w| w.strip_prefix(&format!("{name}=")))
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("{name} missing in '{check}'"))
}

#[test]
fn the_report_loads_in_chromium_with_every_image_and_plot_and_no_console_error() {
    let Some(browser) = chromium() else {
        assert!(
            std::env::var_os("REQUIRE_BROWSER").is_none(),
            "REQUIRE_BROWSER is set but no Chromium was found (install chromium or set CHROMIUM)"
        );
        eprintln!("no Chromium on PATH; skipping the browser check of the report");
        return;
    };
    let out = std::env::temp_dir().join(format!("xtask-report-browser-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let o = xtask()
        .args(["experiment", "--scene", "cornell-point", "--views", "2"])
        .args(["--size", "32x24", "--spp", "16", "--repeats", "1"])
        .args(["--techniques", "dl,isr-24,relight-64,ibrr-32-16"])
        .args(["--sequence-frames", "3"])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let page = out.join("report.html");
    let (check, console) = load(&browser, &page);
    eprintln!("{check}");
    // 2 views x (reference + 4 techniques + 4 error maps).
    assert!(check.starts_with("ok "), "{check}");
    assert_eq!(field(&check, "images"), 2 * 9, "{check}");
    assert_eq!(field(&check, "broken"), 0, "{check}");
    // One speed-against-error plot per bounce limit (1, inf), two sequence plots, the
    // colour bar and the two per-view plots.
    assert_eq!(field(&check, "plots"), 2 + 2 + 1 + 2, "{check}");
    assert!(console.is_empty(), "console: {console:?}");

    // The same check catches a missing image and a script error.
    let html = std::fs::read_to_string(&page).unwrap();
    let broken = html
        .replacen("errmap-dl-binf.png", "no-such-file.png", 1)
        .replace("</body>", "<script>noSuchFunction();</script></body>");
    let bad = out.join("broken.html");
    std::fs::write(&bad, broken).unwrap();
    let (check, console) = load(&browser, &bad);
    assert_eq!(field(&check, "broken"), 1, "{check}");
    assert!(
        console.iter().any(|l| l.contains("noSuchFunction")),
        "{console:?}"
    );
    std::fs::remove_dir_all(&out).ok();
}
