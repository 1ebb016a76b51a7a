//! A small WebDriver client (W3C WebDriver over HTTP) for chromium-driver, with Debian's
//! Chromium headless: what the panel's browser tests need (a session, navigation, script,
//! elements, clicks, typing, a screenshot). Shared by `emulator/tests/panel_browser.rs` and
//! the e2e test `tests/tests/panel_vcan.rs` (`#[path]`). A missing browser or chromedriver
//! fails with what to install.
//!
//! The browser: `$DRIVE_EMU_CHROME` if set, else Chromium's headless shell (Debian package
//! `chromium-headless-shell`, the same Blink and V8 as `chromium` without the desktop
//! browser around them), else `chromium --headless`. Inside user-mode Linux, where every
//! system call is a round trip through the host, the full browser took 25 s to open a
//! session and 30 s more for its first `about:blank`; the headless shell 11 s and 1.3 s.
#![allow(dead_code)]

use base64::Engine;
use serde_json::{json, Value};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const ELEMENT: &str = "element-6066-11e4-a52e-4f735466cecf";

/// chromedriver as a child process, killed on drop.
pub struct Driver {
    child: Child,
    base: String,
    session: Option<String>,
    _profile: TempDir,
}

struct TempDir(std::path::PathBuf);

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Longest wait for one WebDriver command: an upper bound for a browser inside a loaded
/// single-CPU user-mode Linux, not a timing claim.
const COMMAND_TIMEOUT: Duration = Duration::from_secs(300);

fn agent() -> ureq::Agent {
    ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(COMMAND_TIMEOUT))
        .build()
        .into()
}

fn which(name: &str) -> Option<std::path::PathBuf> {
    std::env::var_os("PATH").and_then(|paths| {
        std::env::split_paths(&paths)
            .map(|p| p.join(name))
            .find(|p| p.is_file())
    })
}

impl Driver {
    pub fn start() -> Driver {
        let (browser, name) = Self::browser();
        let driver = which("chromedriver").unwrap_or_else(|| {
            panic!("chromedriver is not installed: apt-get install -y chromium-driver")
        });
        let port = {
            let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
            l.local_addr().unwrap().port()
        };
        let child = Command::new(&driver)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot start {}: {e}", driver.display()));
        let profile = TempDir(std::env::temp_dir().join(format!(
            "drive-emu-panel-chromium-{}-{port}",
            std::process::id()
        )));
        std::fs::create_dir_all(&profile.0).unwrap();
        let mut d = Driver {
            child,
            base: format!("http://127.0.0.1:{port}"),
            session: None,
            _profile: profile,
        };
        let t0 = Instant::now();
        loop {
            let ready = agent()
                .get(&format!("{}/status", d.base))
                .call()
                .ok()
                .and_then(|mut r| r.body_mut().read_json::<Value>().ok())
                .is_some_and(|v| v["value"]["ready"] == true);
            if ready {
                break;
            }
            assert!(
                t0.elapsed() < Duration::from_secs(60),
                "chromedriver did not become ready"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
        let caps = json!({"capabilities": {"alwaysMatch": {
            "browserName": name,
            "goog:chromeOptions": {
                "binary": browser.display().to_string(),
                "args": ["--headless", "--no-sandbox", "--disable-gpu",
                         "--disable-background-networking", "--disable-component-update",
                         "--disable-sync", "--no-first-run", "--disable-dev-shm-usage",
                         format!("--user-data-dir={}", d._profile.0.display()),
                         "--window-size=1600,1500"],
            },
        }}});
        let v = d.post("/session", caps);
        let id = v["sessionId"]
            .as_str()
            .unwrap_or_else(|| panic!("no session: {v}"))
            .to_string();
        d.session = Some(id);
        d
    }

    /// The browser to drive and its WebDriver `browserName` (chromedriver opens no page in the
    /// headless shell unless told it is one).
    fn browser() -> (std::path::PathBuf, &'static str) {
        if let Some(p) = std::env::var_os("DRIVE_EMU_CHROME") {
            let p = std::path::PathBuf::from(p);
            assert!(
                p.is_file(),
                "DRIVE_EMU_CHROME={}: no such file",
                p.display()
            );
            let shell = p
                .file_name()
                .is_some_and(|n| n.to_string_lossy().contains("headless-shell"));
            return (
                p,
                if shell {
                    "chrome-headless-shell"
                } else {
                    "chrome"
                },
            );
        }
        // Debian's /usr/bin/chromium-headless-shell is a shell script: chromedriver needs the
        // program itself.
        let shell = std::path::Path::new("/usr/lib/chromium/chromium-headless-shell");
        if shell.is_file() {
            return (shell.to_path_buf(), "chrome-headless-shell");
        }
        let chromium = which("chromium").unwrap_or_else(|| {
            panic!(
                "no browser: apt-get install -y chromium-headless-shell chromium-driver \
                 (or chromium), or set DRIVE_EMU_CHROME"
            )
        });
        (chromium, "chrome")
    }

    pub fn post(&self, path: &str, body: Value) -> Value {
        let mut r = agent()
            .post(&format!("{}{path}", self.base))
            .send_json(body)
            .unwrap_or_else(|e| panic!("{path}: {e}"));
        let v: Value = r.body_mut().read_json().unwrap();
        if v["value"].get("error").is_some() {
            panic!("WebDriver {path}: {}", v["value"]);
        }
        v["value"].clone()
    }

    pub fn s(&self, path: &str) -> String {
        format!("/session/{}{path}", self.session.as_ref().unwrap())
    }

    pub fn go(&self, url: &str) {
        self.post(&self.s("/url"), json!({"url": url}));
    }

    pub fn js(&self, script: &str, args: Value) -> Value {
        self.post(
            &self.s("/execute/sync"),
            json!({"script": script, "args": args}),
        )
    }

    /// A Chrome DevTools Protocol command through chromedriver (e.g. `Performance.getMetrics`).
    pub fn cdp(&self, cmd: &str, params: Value) -> Value {
        self.post(
            &self.s("/goog/cdp/execute"),
            json!({"cmd": cmd, "params": params}),
        )
    }

    pub fn element(&self, css: &str) -> String {
        let v = self.post(
            &self.s("/element"),
            json!({"using": "css selector", "value": css}),
        );
        v[ELEMENT].as_str().unwrap().to_string()
    }

    pub fn click(&self, css: &str) {
        let e = self.element(css);
        self.post(&self.s(&format!("/element/{e}/click")), json!({}));
    }

    pub fn type_into(&self, css: &str, text: &str) {
        let e = self.element(css);
        self.post(&self.s(&format!("/element/{e}/clear")), json!({}));
        self.post(
            &self.s(&format!("/element/{e}/value")),
            json!({"text": text}),
        );
    }

    pub fn screenshot(&self) -> Vec<u8> {
        let mut r = agent()
            .get(&format!("{}{}", self.base, self.s("/screenshot")))
            .call()
            .unwrap();
        let v: Value = r.body_mut().read_json().unwrap();
        base64::engine::general_purpose::STANDARD
            .decode(v["value"].as_str().unwrap())
            .unwrap()
    }

    /// Choose `value` in the `<select>` at `css`, as a user would (its change event fires).
    pub fn select(&self, css: &str, value: &str) {
        self.js(
            "const s = document.querySelector(arguments[0]); s.value = arguments[1]; \
             s.dispatchEvent(new Event('change')); return s.value",
            json!([css, value]),
        );
    }

    /// A screenshot of the page, checked to be a PNG of some substance, and written to the
    /// path in the environment variable `var` when there is one.
    pub fn screenshot_to(&self, var: &str) {
        let png = self.screenshot();
        assert!(
            png.starts_with(b"\x89PNG\r\n\x1a\n") && png.len() > 10_000,
            "a screenshot of {} bytes",
            png.len()
        );
        if let Some(p) = std::env::var_os(var) {
            std::fs::write(&p, &png).unwrap_or_else(|e| panic!("{var}: {e}"));
        }
    }

    /// Wait until the script returns something truthy; the last value.
    pub fn wait_js(&self, limit: Duration, script: &str) -> Value {
        let t0 = Instant::now();
        loop {
            let v = self.js(script, json!([]));
            let truthy =
                !matches!(&v, Value::Null | Value::Bool(false)) && v != json!("") && v != json!(0);
            if truthy || t0.elapsed() > limit {
                return v;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

impl Drop for Driver {
    fn drop(&mut self) {
        if let Some(id) = self.session.take() {
            let _ = agent()
                .delete(&format!("{}/session/{id}", self.base))
                .call();
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
