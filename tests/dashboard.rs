//! The dashboard in a real browser: `tests/browser/dashboard.py`, Playwright for Python
//! driving Chromium headless against a coordinator with local workers (log in, submit, watch
//! tiles and the preview, pause, resume, cancel, reprioritise, delete, a blocklisted worker,
//! the API docs; no console errors). Screenshots of each page go to
//! `target/tmp/dashboard-screenshots/`.
//!
//! It needs Python's `playwright` and a Chromium (`.ci/run` installs both). Where either is
//! missing the test says so and passes, unless `TESSERA_BROWSER_TESTS=require` (CI sets it),
//! where it fails.

use std::path::Path;
use std::process::Command;

#[test]
fn the_dashboard_works_in_a_real_browser() {
    let required = std::env::var("TESSERA_BROWSER_TESTS").is_ok_and(|v| v == "require");
    let chromium = ["/usr/bin/chromium", "/usr/bin/chromium-browser"]
        .into_iter()
        .find(|p| Path::new(p).exists());
    let playwright = Command::new("python3")
        .args(["-c", "import playwright.sync_api"])
        .output()
        .is_ok_and(|o| o.status.success());
    let (Some(chromium), true) = (chromium, playwright) else {
        let missing =
            "Chromium (apt-get install chromium) and Python's playwright (pip install playwright)";
        assert!(
            !required,
            "TESSERA_BROWSER_TESTS=require, but {missing} are not both installed"
        );
        eprintln!("skipped: the browser test needs {missing}; .ci/run installs them");
        return;
    };
    let out = Path::new(env!("CARGO_TARGET_TMPDIR")).join("dashboard-screenshots");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/browser/dashboard.py");
    let o = Command::new("python3")
        .arg(&script)
        .args([
            "--tessera",
            env!("CARGO_BIN_EXE_tessera"),
            "--chromium",
            chromium,
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .expect("run python3");
    let stdout = String::from_utf8_lossy(&o.stdout);
    let stderr = String::from_utf8_lossy(&o.stderr);
    println!("{stdout}");
    assert!(o.status.success(), "{stdout}\n{stderr}");
    for page in [
        "login",
        "jobs",
        "job-running",
        "job-paused",
        "job-blocklist",
        "workers",
        "docs",
    ] {
        assert!(
            out.join(format!("{page}.png")).is_file(),
            "no screenshot of {page}"
        );
    }
}
