//! The live panel in a real browser: Debian's Chromium headless shell, driven by chromium-driver
//! through the WebDriver HTTP API (a small client here), against a drive with the panel on an
//! in-process bus, moved by the reference master at constant speed in CSP:
//! - the page shows the drive reach OPERATION ENABLED;
//! - the position the page plotted at a time equals 0x6064 read over SDO at that time (the
//!   axis moving at 10 mm/s: within what it travels between two plotted samples);
//! - a backlash set on the page (its control, typed and clicked) reads back over SDO from
//!   0x2000, and the page's detector then reports the limit cycle it causes;
//! - messages that arrive while the page is busy are drawn together, not one by one;
//! - each plot is as wide as its column of the page's grid, each y axis as its longest label;
//! - a page opened with `?token=T` drops the token from the address bar and the history at
//!   once, and still works (its stream and its API calls carry the token).
//!
//! With `DRIVE_EMU_PANEL_SCREENSHOT=PATH` the page's screenshot at the end is written there
//! (docs/img/panel.png was made so). A missing chromium or chromedriver fails the test with
//! what to install (CI: `.ci/run` installs both).

mod panel_rig;
mod webdriver;

use panel_rig::{backlash_mm, cruise_csp_10_mm_s, Rig, RigOptions};
use serde_json::json;
use std::time::Duration;
use webdriver::Driver;

#[test]
fn the_page_shows_the_drive_live_and_its_backlash_control_reaches_the_drive() {
    let rig = Rig::start(RigOptions {
        program: cruise_csp_10_mm_s(),
        // A healthy axis to start with: the limit cycle comes from the page's injection.
        overrides: vec![("backlash_mm", "0")],
        ..Default::default()
    });
    let d = Driver::start();
    d.go(&format!("{}/", rig.base));
    // The state goes to OPERATION ENABLED, on the page.
    let st = d.wait_js(
        Duration::from_secs(60),
        "return panel.state(0) === 'OPERATION ENABLED' ? panel.state(0) : null",
    );
    assert_eq!(st, "OPERATION ENABLED", "the page shows {st}");
    let shown = d.js(
        "return document.getElementById('state-0').textContent",
        json!([]),
    );
    assert_eq!(shown, "OPERATION ENABLED");
    // The plotted position follows 0x6064 read over SDO: at the time of each read, the page
    // plotted the same position, within the travel between two plotted samples (2 ms at
    // 10 mm/s: 20 uu) and one tick.
    let mut reads = Vec::new();
    for _ in 0..6 {
        std::thread::sleep(Duration::from_millis(400));
        let (raw, t_us) = rig.sdo_read_at(0x6064, 0).expect("SDO read of 0x6064");
        let t_s = t_us as f64 * 1e-6;
        let v = d.wait_js(
            Duration::from_secs(30),
            &format!("const p = panel.plotted(0); return p && p.t_s >= {t_s} ? panel.plottedAt(0, {t_s}) : null"),
        );
        let plotted = v["position_actual_uu"]
            .as_f64()
            .unwrap_or_else(|| panic!("nothing plotted at t = {t_s} s: {v}"));
        let sdo = f64::from(raw as i32);
        let at = v["t_s"].as_f64().unwrap();
        assert!(
            (plotted - sdo).abs() <= 10_000.0 * (t_s - at + 0.001) + 2.0,
            "t = {t_s} s: 0x6064 over SDO {sdo} uu, plotted {plotted} uu at {at} s"
        );
        reads.push(sdo);
    }
    assert!(
        reads.windows(2).all(|w| w[1] > w[0] + 1000.0),
        "the axis moved between the reads: {reads:?}"
    );
    // A backlash change made on the page reads back over SDO (0x2000, mm, REAL32).
    assert_eq!(backlash_mm(&rig), Some(0.0));
    d.click("#param-key option[value='backlash_mm']");
    d.type_into("#param-value", "0.05");
    d.click("#param-set");
    let logged = d.wait_js(
        Duration::from_secs(30),
        "const li = document.querySelector('#injections li'); return li && li.textContent",
    );
    assert!(
        logged
            .as_str()
            .is_some_and(|t| t.contains("set backlash_mm = 0.05") && t.starts_with("t=")),
        "the page logged {logged}"
    );
    let b = backlash_mm(&rig).expect("SDO read of 0x2000");
    assert!((b - 0.05).abs() < 1e-6, "0x2000 reads {b} mm");
    // The limit cycle the backlash causes: the page's detector reports it (f near 0.6 k_v).
    let verdict = d.wait_js(
        Duration::from_secs(120),
        "const v = document.getElementById('verdict-0').textContent; \
         return /detector[^:]*: backlash/.test(v) ? v : null",
    );
    let text = verdict
        .as_str()
        .unwrap_or_else(|| panic!("the page's detector never reported the backlash"));
    assert!(
        text.contains("f/k_v 0.") || text.contains("f/k_v 1"),
        "{text}"
    );
    // Every y axis is as wide as its longest tick label: the position has grown to six
    // digits by now, whose labels a fixed 60 px axis cut ("148,000" showed ".48,000").
    let fit = d.js("return panel.axisFit()", json!([]));
    let fit = fit.as_array().expect("panel.axisFit() is a list");
    assert!(fit.len() >= 5, "every plot's y axes: {fit:?}");
    assert!(
        fit.iter()
            .any(|a| a["label"].as_str().is_some_and(|l| l.len() >= 6)),
        "a long label among {fit:?}"
    );
    for a in fit {
        let (size, need) = (a["size"].as_f64().unwrap(), a["need"].as_f64().unwrap());
        assert!(size + 0.5 >= need, "a y axis narrower than its labels: {a}");
    }
    // Drawing is paced by its own cost: messages that arrive while the page is busy are
    // drawn together. Keep its main thread busy for 1.5 s (25 messages a second queue up
    // meanwhile): the backlog is then drawn in a drawing or two, not once per message.
    let before = d.js("return panel.counts()", json!([]));
    d.js(
        "const t = Date.now(); while (Date.now() - t < 1500) {} return 1",
        json!([]),
    );
    let after = d.wait_js(
        Duration::from_secs(30),
        &format!(
            "const c = panel.counts(); return c.messages >= {} + 20 && c.draws > {} ? c : null",
            before["messages"], before["draws"]
        ),
    );
    let n = |v: &serde_json::Value, k: &str| v[k].as_u64().unwrap_or(0);
    let (messages, draws) = (
        n(&after, "messages") - n(&before, "messages"),
        n(&after, "draws") - n(&before, "draws"),
    );
    eprintln!("a busy page: {messages} messages taken, {draws} drawings made");
    assert!(
        messages >= 20 && draws * 2 <= messages,
        "{messages} messages taken, {draws} drawings made: {before} -> {after}"
    );
    // Each plot is as wide as its column of the grid (two columns in this 1600 px window).
    let widths = d.js(
        "return [...document.querySelectorAll('#axis-0 .plots > div')].map(\
         (c) => [c.clientWidth, c.querySelector('canvas').getBoundingClientRect().width])",
        json!([]),
    );
    let widths: Vec<(f64, f64)> = widths
        .as_array()
        .expect("plot widths")
        .iter()
        .map(|w| (w[0].as_f64().unwrap(), w[1].as_f64().unwrap()))
        .collect();
    assert_eq!(widths.len(), 5, "{widths:?}");
    assert!(
        widths
            .iter()
            .all(|&(cell, canvas)| cell >= 420.0 && (cell - canvas).abs() <= 1.0),
        "plot columns and their canvases (px): {widths:?}"
    );
    // The picture for the README: a 10 s span shows the limit cycle set in.
    d.select("#span", "10");
    std::thread::sleep(Duration::from_millis(500));
    d.screenshot_to("DRIVE_EMU_PANEL_SCREENSHOT");
    drop(d);
    rig.stop();
}

/// docs/panel.md's screenshot command: `chromium --headless --virtual-time-budget
/// --screenshot` on the page with `?snapshot` returns (it never did while the page's stream
/// stayed open) and writes a PNG of the page with the run's recent past drawn.
#[test]
fn a_headless_screenshot_of_the_snapshot_page_returns() {
    use std::process::{Command, Stdio};
    let rig = Rig::start(RigOptions {
        program: cruise_csp_10_mm_s(),
        ..Default::default()
    });
    assert!(
        rig.wait_for(Duration::from_secs(120), || rig.now_s() > 3.0),
        "the run never reached 3 s"
    );
    // The snapshot page: the recent past drawn (seconds of samples at once, not the fraction
    // of a second since it opened), then the stream closed.
    {
        let d = Driver::start();
        d.go(&format!("{}/?snapshot", rig.base));
        let v = d.wait_js(
            Duration::from_secs(60),
            "const p = panel.plotted(0); \
             return document.getElementById('conn').textContent === 'snapshot' && p ? p : null",
        );
        let first = d.js(
            "const p = panel.plotted(0); return panel.plottedAt(0, p.t_s - 2.0)",
            json!([]),
        );
        assert!(
            v["points"].as_u64().unwrap_or(0) > 500 && !first.is_null(),
            "the snapshot drew {v} (2 s before its end: {first})"
        );
    }
    let dir = std::env::temp_dir().join(format!("drive-emu-snapshot-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("panel.png");
    let browser = ["chromium", "/usr/bin/chromium"]
        .into_iter()
        .find(|b| Command::new(b).arg("--version").output().is_ok())
        .expect("chromium is not installed: apt-get install -y chromium");
    let mut child = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            &format!("--user-data-dir={}", dir.join("profile").display()),
            "--window-size=1400,1900",
            "--virtual-time-budget=5000",
            &format!("--screenshot={}", png.display()),
            &format!("{}/?snapshot", rig.base),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("start chromium");
    // A hang guard, not a measurement: the command must return at all.
    let t0 = std::time::Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t0.elapsed() > Duration::from_secs(300) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("chromium --screenshot on ?snapshot did not return in 300 s");
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    assert!(status.success(), "chromium: {status}");
    let bytes = std::fs::read(&png).expect("the screenshot");
    assert!(bytes.starts_with(b"\x89PNG\r\n\x1a\n"), "not a PNG");
    assert!(
        bytes.len() > 20_000,
        "a page with plots, not a blank one: {} bytes",
        bytes.len()
    );
    let _ = std::fs::remove_dir_all(&dir);
    rig.stop();
}

/// Issue 32, finding 3: the page opened as `/?token=T` (the address `drive-emu` prints) takes
/// the token, then drops it from the address bar and the history (`history.replaceState`),
/// keeping the other query parameters and the fragment; the page still works: its stream
/// shows the drive, and an API call with the token it kept is answered where one without
/// the token is refused.
#[test]
fn the_page_drops_its_token_from_the_address_bar_and_still_works() {
    const TOKEN: &str = "T0ken-in-the-URL";
    let rig = Rig::start(RigOptions {
        token: Some(TOKEN.into()),
        ..Default::default()
    });
    let d = Driver::start();
    d.go(&format!("{}/?span=10&token={TOKEN}#axis-0", rig.base));
    // The stream needs the token: the state reaches the page only if the page kept it.
    let st = d.wait_js(
        Duration::from_secs(60),
        "const s = panel.state(0); return s && s !== '-' ? s : null",
    );
    assert!(st.is_string(), "the page shows no state: {st}");
    let href = d.js("return location.href", json!([]));
    let href = href.as_str().expect("location.href");
    assert!(!href.contains(TOKEN) && !href.contains("token"), "{href}");
    assert_eq!(href, format!("{}/?span=10#axis-0", rig.base));
    // An API call the page makes with its kept token is answered; without it, refused.
    d.js(
        "window.__st = {}; \
         fetch(withToken('/api/info')).then((r) => { window.__st.with = r.status; }); \
         fetch('/api/info').then((r) => { window.__st.without = r.status; }); return 1",
        json!([]),
    );
    let st = d.wait_js(
        Duration::from_secs(60),
        "return window.__st.with && window.__st.without ? window.__st : null",
    );
    assert_eq!(st, json!({"with": 200, "without": 401}), "{st}");
    drop(d);
    rig.stop();
}
