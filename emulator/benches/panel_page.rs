//! What the live panel's page costs a browser on this machine: a drive with the panel on an
//! in-process bus cruising in CSP at 10 mm/s (the host browser test's rig), Chromium's headless
//! shell showing the page (the browser tests' WebDriver client); per plot span, the share of
//! wall time the page's main thread is busy (DevTools `Performance.getMetrics`: TaskDuration,
//! ScriptDuration) and the drawings per second.
//!
//!     cargo bench -p drive-emu --bench panel_page [-- SECONDS]
//!
//! bench/panel-page.sh measures the same inside user-mode Linux against `run --panel` on vcan.

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
    let secs: f64 = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(10.0);
    let rig = Rig::start(RigOptions {
        program: cruise_csp_10_mm_s(),
        ..Default::default()
    });
    let d = Driver::start();
    d.go(&format!("{}/", rig.base));
    let t0 = Instant::now();
    while d.js(
        "const p = panel.plotted(0); return !!(p && p.points > 0)",
        json!([]),
    ) != json!(true)
    {
        assert!(t0.elapsed() < Duration::from_secs(60), "nothing plotted");
        std::thread::sleep(Duration::from_millis(200));
    }
    d.cdp("Performance.enable", json!({}));
    for span in [5, 60] {
        d.click(&format!("#span option[value='{span}']"));
        std::thread::sleep(Duration::from_secs(2));
        let (task0, script0, w0, p0) = metrics(&d);
        std::thread::sleep(Duration::from_secs_f64(secs));
        let (task1, script1, w1, p1) = metrics(&d);
        let wall = (w1 - w0).as_secs_f64();
        let n = |p: &Value, k: usize| p[k].as_f64().unwrap_or(f64::NAN);
        println!(
            "span {span:>2} s: main thread busy {:.1} %, script {:.1} %, {:.1} drawings/s, \
             {} points a plot",
            100.0 * (task1 - task0) / wall,
            100.0 * (script1 - script0) / wall,
            (n(&p1, 1) - n(&p0, 1)) / wall,
            p1[0],
        );
    }
    drop(d);
    rig.stop();
}
