//! What the live panel's page costs a browser on this machine: Chromium's headless shell
//! showing the page (the browser tests' WebDriver client); per plot span, the share of wall
//! time the page's main thread is busy (DevTools `Performance.getMetrics`: TaskDuration,
//! ScriptDuration) and the drawings per second. Without `--url`, of a drive with the panel on
//! an in-process bus cruising in CSP at 10 mm/s (the host browser test's rig):
//!
//!     cargo bench -p drive-emu --bench panel_page [-- SECONDS]
//!     panel_page --url http://127.0.0.1:8080/ [--label TEXT] [SECONDS]   # a running `run --panel`
//!
//! bench/panel-page.sh runs it with `--url` inside user-mode Linux against `run --panel` on
//! vcan. A span whose measurement fails (a page too busy to answer its scripts) is said so,
//! and the next is measured.

#[path = "../tests/panel_rig/mod.rs"]
mod panel_rig;
#[path = "../tests/webdriver/mod.rs"]
mod webdriver;

use panel_rig::{cruise_csp_10_mm_s, Rig, RigOptions};
use serde_json::{json, Value};
use std::time::{Duration, Instant};
use webdriver::Driver;

fn metrics(d: &Driver) -> (f64, f64, Instant, Value) {
    let m = d.cdp("Performance.getMetrics", json!({}));
    let get = |name: &str| {
        m["metrics"]
            .as_array()
            .and_then(|a| a.iter().find(|x| x["name"] == name))
            .and_then(|x| x["value"].as_f64())
            .unwrap_or(f64::NAN)
    };
    let p = d.js(
        "const p = panel.plotted(0), c = panel.counts ? panel.counts() : {}; \
         return p && [p.points, c.draws]",
        json!([]),
    );
    (
        get("TaskDuration"),
        get("ScriptDuration"),
        Instant::now(),
        p,
    )
}

fn main() {
    let (mut secs, mut url, mut label) = (10.0, None, String::new());
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--url" => url = args.next(),
            "--label" => label = args.next().unwrap_or_default(),
            _ => secs = a.parse().unwrap_or(secs),
        }
    }
    let rig = url.is_none().then(|| {
        Rig::start(RigOptions {
            program: cruise_csp_10_mm_s(),
            ..Default::default()
        })
    });
    let url = url.unwrap_or_else(|| format!("{}/", rig.as_ref().unwrap().base));
    let d = Driver::start();
    d.go(&url);
    let plotted = d.wait_js(
        Duration::from_secs(120),
        "const p = panel.plotted(0); return !!(p && p.points > 0)",
    );
    assert_eq!(plotted, json!(true), "nothing plotted in 120 s at {url}");
    d.cdp("Performance.enable", json!({}));
    for span in [5, 60] {
        let measured = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            d.select("#span", &span.to_string());
            std::thread::sleep(Duration::from_secs(2));
            let (task0, script0, w0, p0) = metrics(&d);
            std::thread::sleep(Duration::from_secs_f64(secs));
            let (task1, script1, w1, p1) = metrics(&d);
            let wall = (w1 - w0).as_secs_f64();
            let n = |p: &Value, k: usize| p[k].as_f64().unwrap_or(f64::NAN);
            format!(
                "main thread busy {:.1} %, script {:.1} %, {:.1} drawings/s, {} points a plot",
                100.0 * (task1 - task0) / wall,
                100.0 * (script1 - script0) / wall,
                (n(&p1, 1) - n(&p0, 1)) / wall,
                p1[0],
            )
        }));
        let said = measured.unwrap_or_else(|_| "not measured (see the panic above)".into());
        println!("{label}span {span:>2} s: {said}");
    }
    drop(d);
    if let Some(rig) = rig {
        rig.stop();
    }
}
