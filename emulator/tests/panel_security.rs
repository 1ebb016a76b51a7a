//! The panel against a hostile client or a hostile local user (issue 32): idle and half-sent
//! connections, slow bodies, cross-site requests, framing, the token's sources and forms,
//! recordings swapped for symlinks, and the caps on recordings. A drive on an in-process bus
//! with the panel on an ephemeral loopback port, as in `panel_live.rs`.

mod panel_rig;

use panel_rig::{Rig, RigOptions};
use serde_json::{json, Value};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

/// A raw HTTP/1.1 exchange: `request` sent as is, the whole reply read (the panel closes the
/// connection: `Connection: close` is added by the caller). (status, headers, body).
fn raw(rig: &Rig, request: &str) -> (u16, String, String) {
    let addr = rig.panel().addr;
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    s.write_all(request.as_bytes()).unwrap();
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    let text = String::from_utf8_lossy(&out).into_owned();
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
    let status = head
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    (status, head.to_ascii_lowercase(), body.to_string())
}

fn get(rig: &Rig, path: &str, headers: &[&str]) -> (u16, String, String) {
    let mut req = format!("GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n");
    for h in headers {
        req.push_str(h);
        req.push_str("\r\n");
    }
    req.push_str("\r\n");
    raw(rig, &req)
}

fn post(rig: &Rig, path: &str, body: &Value, headers: &[&str]) -> (u16, String, String) {
    let b = body.to_string();
    let mut req = format!(
        "POST {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\
         Content-Type: application/json\r\nContent-Length: {}\r\n",
        b.len()
    );
    for h in headers {
        req.push_str(h);
        req.push_str("\r\n");
    }
    req.push_str("\r\n");
    req.push_str(&b);
    raw(rig, &req)
}

/// The descriptors this process may open: raised to `want` (or the hard limit).
fn raise_fd_limit(want: u64) -> u64 {
    let mut l = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: a valid rlimit to fill and then set.
    unsafe {
        assert_eq!(libc::getrlimit(libc::RLIMIT_NOFILE, &mut l), 0);
        l.rlim_cur = want.min(l.rlim_max);
        assert_eq!(libc::setrlimit(libc::RLIMIT_NOFILE, &l), 0);
    }
    l.rlim_cur
}

#[test]
fn eleven_hundred_idle_connections_leave_new_requests_answered() {
    let limit = raise_fd_limit(4096);
    assert!(
        limit >= 2400,
        "the test needs 2400 descriptors, the hard limit is {limit}"
    );
    let rig = Rig::start(RigOptions::default());
    let addr = rig.panel().addr;
    let mut idle = Vec::new();
    for i in 0..1100 {
        let mut s = TcpStream::connect(addr).unwrap();
        if i % 2 == 0 {
            // Half a request: the head never ends.
            let _ = s.write_all(b"GET /api/info HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ");
        }
        idle.push(s);
    }
    // New requests are answered while all 1100 are still open on this side.
    for _ in 0..3 {
        let (st, _, body) = get(&rig, "/api/info", &[]);
        assert_eq!(st, 200, "{body}");
        let v: Value = serde_json::from_str(&body).unwrap();
        assert_eq!(v["type"], "hello");
    }
    // The panel holds at most its limit: the others were closed by it (it closes them as it
    // accepts; on a busy machine that takes a moment: looked at until a generous deadline).
    let want = 1100 - drive_emu::panel::server::MAX_CONNECTIONS;
    let mut open: Vec<TcpStream> = idle;
    let mut closed = 0;
    let t0 = std::time::Instant::now();
    while closed < want && t0.elapsed() < Duration::from_secs(60) {
        let mut still = Vec::new();
        for mut s in open {
            s.set_read_timeout(Some(Duration::from_millis(1))).unwrap();
            let mut b = [0u8; 1];
            match s.read(&mut b) {
                Ok(0) => closed += 1,
                Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => closed += 1,
                _ => still.push(s),
            }
        }
        open = still;
    }
    assert!(
        closed >= want,
        "{closed} of 1100 idle connections closed by the panel"
    );
    let idle = open;
    drop(idle);
    rig.stop();
}

#[test]
fn a_half_sent_head_and_a_slow_body_are_cut_off_before_the_token() {
    let rig = Rig::start(RigOptions {
        token: Some("s3cret".into()),
        ..RigOptions::default()
    });
    let addr = rig.panel().addr;
    let head = std::thread::spawn(move || {
        let mut s = TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(120))).unwrap();
        s.write_all(b"GET /api/info HTTP/1.1\r\nHost: 127.0.0.1\r\n")
            .unwrap();
        let mut out = Vec::new();
        // Closed by the panel (EOF), not by this read's own timeout.
        s.read_to_end(&mut out).map(|_| out.len())
    });
    let body = std::thread::spawn(move || {
        let mut s = TcpStream::connect(addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(120))).unwrap();
        s.write_all(
            b"POST /api/inject HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n\
              Content-Length: 100\r\n\r\n{\"set\":",
        )
        .unwrap();
        let mut out = Vec::new();
        let _ = s.read_to_end(&mut out);
        String::from_utf8_lossy(&out).into_owned()
    });
    let n = head.join().unwrap();
    assert!(n.is_ok(), "the half-sent head was not closed: {n:?}");
    let reply = body.join().unwrap();
    assert!(reply.starts_with("HTTP/1.1 408"), "{reply}");
    assert!(reply.contains("did not arrive within"), "{reply}");
    rig.stop();
}

#[test]
fn every_reply_forbids_framing_and_referrers() {
    let rig = Rig::start(RigOptions::default());
    for path in ["/", "/assets/panel.js", "/api/info", "/nothing"] {
        let (_, head, _) = get(&rig, path, &[]);
        for want in [
            "referrer-policy: no-referrer",
            "content-security-policy: frame-ancestors 'none'",
            "x-frame-options: deny",
        ] {
            assert!(head.contains(want), "{path}: no {want}: {head}");
        }
    }
    rig.stop();
}

#[test]
fn a_cross_site_write_or_stream_is_refused() {
    let rig = Rig::start(RigOptions::default());
    let inj = json!({"set": "backlash_mm", "value": 0.03});
    for site in ["cross-site", "same-site"] {
        let h = format!("Sec-Fetch-Site: {site}");
        let (st, _, body) = post(&rig, "/api/inject", &inj, &[&h]);
        assert_eq!(st, 403, "{site}: {body}");
        assert!(body.contains("Sec-Fetch-Site"), "{body}");
        // Issue 32, finding 8: the reason reads as one sentence (it had 18 stray spaces).
        let why: Value = serde_json::from_str(&body).unwrap();
        assert_eq!(
            why["error"], "a request from a page of another site is refused (Sec-Fetch-Site)",
            "{body}"
        );
        let (st, _, _) = post(&rig, "/api/record", &json!({"action": "start"}), &[&h]);
        assert_eq!(st, 403, "{site}");
        let (st, _, _) = get(&rig, "/api/stream", &[&h]);
        assert_eq!(st, 403, "{site}");
    }
    // The panel's own page and a typed address pass.
    let (st, _, body) = post(&rig, "/api/inject", &inj, &["Sec-Fetch-Site: same-origin"]);
    assert_eq!(st, 200, "{body}");
    let (st, _, _) = get(&rig, "/api/info", &["Sec-Fetch-Site: none"]);
    assert_eq!(st, 200);
    // Without a token the panel answers loopback names only; the reason reads cleanly.
    let (st, _, body) = raw(
        &rig,
        "GET /api/info HTTP/1.1\r\nHost: example.com\r\nConnection: close\r\n\r\n",
    );
    assert_eq!(st, 403);
    let v: Value = serde_json::from_str(&body).unwrap();
    let why = v["error"].as_str().unwrap();
    assert_eq!(
        why,
        "without a token the panel answers requests to 127.0.0.1, [::1] or localhost only"
    );
    // Another origin's page: refused, the reason one clean sentence.
    let (st, _, body) = post(&rig, "/api/inject", &inj, &["Origin: http://evil.example"]);
    assert_eq!(st, 403, "{body}");
    let v: Value = serde_json::from_str(&body).unwrap();
    assert_eq!(
        v["error"], "a request from a page of another origin is refused",
        "{body}"
    );
    rig.stop();
}

#[test]
fn the_bearer_scheme_is_case_insensitive() {
    let rig = Rig::start(RigOptions {
        token: Some("s3cret".into()),
        ..RigOptions::default()
    });
    for scheme in ["Bearer", "bearer", "BEARER"] {
        let h = format!("Authorization: {scheme} s3cret");
        let (st, _, body) = get(&rig, "/api/info", &[&h]);
        assert_eq!(st, 200, "{scheme}: {body}");
    }
    let (st, _, _) = get(&rig, "/api/info", &["Authorization: bearer wrong"]);
    assert_eq!(st, 401);
    rig.stop();
}

/// Record about `s` seconds of the drive's time; the files written.
fn record(rig: &Rig, s: f64) -> (u16, Value) {
    let (st, _, body) = post(rig, "/api/record", &json!({"action": "start"}), &[]);
    if st != 200 {
        return (st, serde_json::from_str(&body).unwrap_or(Value::Null));
    }
    let t0 = rig.now_s();
    assert!(rig.wait_for(Duration::from_secs(60), || rig.now_s() > t0 + s));
    let (st, _, body) = post(rig, "/api/record", &json!({"action": "stop"}), &[]);
    (st, serde_json::from_str(&body).unwrap())
}

#[test]
fn a_recording_swapped_for_a_symlink_or_fifo_is_not_served() {
    let rig = Rig::start(RigOptions::default());
    let (st, v) = record(&rig, 0.2);
    assert_eq!(st, 200, "{v}");
    let dir = rig.panel().record_dir().to_path_buf();
    let m = std::fs::metadata(&dir).unwrap();
    use std::os::unix::fs::PermissionsExt;
    assert_eq!(m.permissions().mode() & 0o777, 0o700, "private directory");
    let name = "rec-1-node5.csv";
    let (st, _, body) = get(&rig, &format!("/api/record/file/{name}"), &[]);
    assert_eq!(st, 200);
    assert!(body.contains("t_s,statusword,"), "streamed: {body:.60}");
    let secret = dir.join("secret");
    std::fs::write(&secret, "root-only secret\n").unwrap();
    for target in [secret.as_path(), std::path::Path::new("/dev/zero")] {
        std::fs::remove_file(dir.join(name)).unwrap();
        std::os::unix::fs::symlink(target, dir.join(name)).unwrap();
        let (st, _, body) = get(&rig, &format!("/api/record/file/{name}"), &[]);
        assert_eq!(st, 500, "{target:?}: {body:.80}");
        assert!(
            !body.contains("secret\n") && body.contains("cannot serve"),
            "{body:.200}"
        );
    }
    std::fs::remove_file(dir.join(name)).unwrap();
    let c = std::ffi::CString::new(dir.join(name).to_str().unwrap()).unwrap();
    // SAFETY: a valid C string.
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    let (st, _, body) = get(&rig, &format!("/api/record/file/{name}"), &[]);
    assert_eq!(st, 500, "{body}");
    assert!(body.contains("not a regular file"), "{body}");
    rig.stop();
}

#[test]
fn recordings_are_capped_in_count_and_size() {
    let rig = Rig::start(RigOptions::default());
    rig.panel()
        .set_record_limits(drive_emu::panel::record::RecordLimits {
            max_recordings: 2,
            max_bytes: 16 << 10,
        });
    // 1 s at 1 kHz is about 70 KB of CSV: the first recording stops at 16 KiB and says so.
    let (st, _, body) = post(&rig, "/api/record", &json!({"action": "start"}), &[]);
    assert_eq!(st, 200, "{body}");
    let t0 = rig.now_s();
    assert!(rig.wait_for(Duration::from_secs(60), || rig.now_s() > t0 + 1.0));
    assert!(rig.wait_for(Duration::from_secs(30), || {
        let (_, _, b) = get(&rig, "/api/record", &[]);
        let v: Value = serde_json::from_str(&b).unwrap();
        v["active"]["cap"].as_str().is_some()
    }));
    let (_, _, b) = get(&rig, "/api/record", &[]);
    let v: Value = serde_json::from_str(&b).unwrap();
    let note = v["active"]["cap"].as_str().unwrap();
    assert!(note.contains("cap of 16384 bytes"), "{note}");
    assert!(v["active"]["bytes"].as_u64().unwrap() <= 16 << 10, "{v}");
    let (st, _, _) = post(&rig, "/api/record", &json!({"action": "stop"}), &[]);
    assert_eq!(st, 200);
    let len = std::fs::metadata(rig.panel().record_dir().join("rec-1-node5.csv"))
        .unwrap()
        .len();
    assert!(len <= 16 << 10, "{len}");
    let (st, v) = record(&rig, 0.05);
    assert_eq!(st, 200, "{v}");
    let (st, v) = record(&rig, 0.05);
    assert_eq!(st, 409, "{v}");
    assert!(
        v["error"].as_str().unwrap().contains("made 2 recordings"),
        "{v}"
    );
    rig.stop();
}

/// `drive-emu ARGS` with `env` set: (exit status, stderr).
fn drive_emu(args: &[&str], env: &[(&str, &str)]) -> (i32, String) {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_drive-emu"));
    c.args(args).env_remove("DRIVE_EMU_PANEL_TOKEN");
    for (k, v) in env {
        c.env(k, v);
    }
    let out = c.output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn a_token_from_the_environment_or_a_file_is_taken_and_the_command_line_warned() {
    let base = ["run", "--iface", "no-such-can9", "--panel", "0.0.0.0:0"];
    // No token: refused at start for the non-loopback address.
    let (code, err) = drive_emu(&base, &[]);
    assert_ne!(code, 0);
    assert!(err.contains("not a loopback address"), "{err}");
    // From the environment: accepted (the run goes on to the interface, which is missing),
    // nothing on the command line, no warning.
    let (code, err) = drive_emu(&base, &[("DRIVE_EMU_PANEL_TOKEN", "t0k-from-env")]);
    assert_ne!(code, 0);
    assert!(
        err.contains("no-such-can9") && !err.contains("loopback") && !err.contains("warning"),
        "{err}"
    );
    // From a file.
    let dir = std::env::temp_dir().join(format!("panel-sec-token-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let f = dir.join("token");
    std::fs::write(&f, "t0k-from-file\n").unwrap();
    let mut args = base.to_vec();
    args.extend(["--panel-token-file", f.to_str().unwrap()]);
    let (_, err) = drive_emu(&args, &[]);
    assert!(
        err.contains("no-such-can9") && !err.contains("warning"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
    // On the command line: taken, with a warning that `ps` shows it.
    let mut args = base.to_vec();
    args.extend(["--panel-token", "t0k"]);
    let (_, err) = drive_emu(&args, &[]);
    assert!(
        err.contains("warning: --panel-token on the command line is visible")
            && err.contains("DRIVE_EMU_PANEL_TOKEN"),
        "{err}"
    );
    // Two sources: which one is meant is not guessed.
    let (code, err) = drive_emu(&args, &[("DRIVE_EMU_PANEL_TOKEN", "other")]);
    assert_ne!(code, 0);
    assert!(err.contains("one of"), "{err}");
}

#[test]
fn a_stream_outlives_the_header_and_idle_timeout() {
    let rig = Rig::start(RigOptions::default());
    let mut s = TcpStream::connect(rig.panel().addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    s.write_all(b"GET /api/stream HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        .unwrap();
    let limit = drive_emu::panel::server::HEADER_TIMEOUT + Duration::from_secs(2);
    let t0 = std::time::Instant::now();
    let mut buf = vec![0u8; 64 << 10];
    let mut late = 0usize;
    while t0.elapsed() < limit + Duration::from_secs(1) {
        let n = s.read(&mut buf).expect("the stream goes on");
        assert!(n > 0, "the stream was closed after {:?}", t0.elapsed());
        if t0.elapsed() > limit {
            late += n;
        }
    }
    assert!(late > 0, "nothing arrived after the header timeout");
    drop(s);
    rig.stop();
}

/// A child process, killed and reaped when dropped.
struct Running(std::process::Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A `drive-emu run --socketcand 127.0.0.1:0 --panel 127.0.0.1:0` started with `args` and
/// `env`, up to its panel line on stderr: the child and the panel's address.
fn start_run_with_panel(args: &[&str], env: &[(&str, &str)]) -> (Running, String) {
    use std::io::BufRead;
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_drive-emu"));
    c.args([
        "run",
        "--socketcand",
        "127.0.0.1:0",
        "--rt-priority",
        "0",
        "--no-mlock",
    ])
    .args(["--panel", "127.0.0.1:0"])
    .args(args)
    .env_remove("DRIVE_EMU_PANEL_TOKEN")
    .stdin(std::process::Stdio::null())
    .stdout(std::process::Stdio::null())
    .stderr(std::process::Stdio::piped());
    for (k, v) in env {
        c.env(k, v);
    }
    let mut child = Running(c.spawn().expect("start drive-emu"));
    let mut err = std::io::BufReader::new(child.0.stderr.take().unwrap());
    let mut seen = String::new();
    loop {
        let mut line = String::new();
        if err.read_line(&mut line).unwrap_or(0) == 0 {
            drop(child);
            panic!("{args:?}: no panel line on stderr:\n{seen}");
        }
        seen.push_str(&line);
        if let Some(rest) = line.trim().strip_prefix("drive-emu: panel on http://") {
            let addr = rest.split(['/', ' ']).next().unwrap().to_string();
            // Keep draining stderr so the drive never blocks on a full pipe.
            std::thread::spawn(move || std::io::copy(&mut err, &mut std::io::sink()));
            return (child, addr);
        }
    }
}

/// `GET path` on `addr` with `headers`: the status.
fn status_at(addr: &str, path: &str, headers: &[&str]) -> u16 {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let mut req = format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n");
    for h in headers {
        req.push_str(h);
        req.push_str("\r\n");
    }
    req.push_str("\r\n");
    s.write_all(req.as_bytes()).unwrap();
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    let text = String::from_utf8_lossy(&out);
    text.split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0)
}

/// Issue 32, finding 3: what every user of the machine sees of a running drive (`ps`, that
/// is /proc/PID/cmdline) holds no token when the token comes from the environment or a
/// file, while the drive does take that token; on the command line it is there to see (and
/// `run` warns of it: the test above).
#[test]
fn ps_shows_no_token_from_the_environment_or_a_file() {
    const SECRET: &str = "s3cret-not-in-ps";
    let dir = std::env::temp_dir().join(format!("panel-sec-ps-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("token");
    std::fs::write(&file, format!("{SECRET}\n")).unwrap();
    let file_args = ["--panel-token-file", file.to_str().unwrap()];
    let cli_args = ["--panel-token", SECRET];
    // (how, arguments, environment, whether ps shows the token)
    type Case<'a> = (&'a str, &'a [&'a str], &'a [(&'a str, &'a str)], bool);
    let cases: [Case; 3] = [
        (
            "environment",
            &[],
            &[("DRIVE_EMU_PANEL_TOKEN", SECRET)],
            false,
        ),
        ("file", &file_args, &[], false),
        ("command line", &cli_args, &[], true),
    ];
    for (how, args, env, shown) in cases {
        let (child, addr) = start_run_with_panel(args, env);
        let cmdline = std::fs::read(format!("/proc/{}/cmdline", child.0.id())).unwrap();
        let cmdline = String::from_utf8_lossy(&cmdline).replace('\0', " ");
        // The token is the panel's: refused without it, taken with it.
        let without = status_at(&addr, "/api/info", &[]);
        let with = status_at(
            &addr,
            "/api/info",
            &[&format!("Authorization: Bearer {SECRET}")],
        );
        drop(child);
        assert_eq!((without, with), (401, 200), "{how}");
        assert_eq!(
            cmdline.contains(SECRET),
            shown,
            "{how}: ps shows `{cmdline}`"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
