//! The live panel on the host: a drive on an in-process bus moved by the reference master,
//! the panel's server on an ephemeral loopback port, clients over real HTTP. The stream's
//! messages, the token, bad and oversized writes, an injection reaching the drive (read back
//! over SDO), recordings, 50 clients connecting and leaving, and a saved session replayed.

mod panel_rig;

use drive_emu::master::{Step, MODE_CSP};
use drive_emu::scenario::{self, runner, timeline::Trigger};
use panel_rig::{backlash_mm, cruise_csp_10_mm_s, Rig, RigOptions, SseReader};
use serde_json::{json, Value};
use std::io::{BufReader, Read, Write};
use std::net::TcpStream;
use std::time::Duration;

fn agent() -> ureq::Agent {
    ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(Duration::from_secs(20)))
        .build()
        .into()
}

/// (status, JSON body) of a request.
fn call(method: &str, url: &str, headers: &[(&str, &str)], body: Option<&[u8]>) -> (u16, Value) {
    let a = agent();
    let mut resp = match (method, body) {
        ("GET", _) => {
            let mut r = a.get(url);
            for (k, v) in headers {
                r = r.header(*k, *v);
            }
            r.call().unwrap()
        }
        (_, b) => {
            let mut r = a.post(url).header("content-type", "application/json");
            for (k, v) in headers {
                r = r.header(*k, *v);
            }
            r.send(b.unwrap_or(b"")).unwrap()
        }
    };
    let status = resp.status().as_u16();
    let text = resp.body_mut().read_to_string().unwrap_or_default();
    let v = serde_json::from_str(&text).unwrap_or(Value::String(text));
    (status, v)
}

fn post(rig: &Rig, path: &str, body: Value) -> (u16, Value) {
    call(
        "POST",
        &format!("{}{path}", rig.base),
        &[],
        Some(body.to_string().as_bytes()),
    )
}

/// An SSE client (ureq reads the chunked body).
fn stream(url: &str) -> SseReader<BufReader<Box<dyn Read + Send + Sync + 'static>>> {
    let resp = agent().get(url).call().unwrap();
    assert_eq!(resp.status().as_u16(), 200, "{url}");
    let ct = resp
        .headers()
        .get("content-type")
        .and_then(|v| v.to_str().ok())
        .unwrap_or_default()
        .to_string();
    assert!(ct.starts_with("text/event-stream"), "{ct}");
    let reader: Box<dyn Read + Send + Sync> = Box::new(resp.into_body().into_reader());
    SseReader {
        reader: BufReader::new(reader),
    }
}

/// The next message of `kind` (others skipped), within `limit` messages.
fn next_of(s: &mut SseReader<impl std::io::BufRead>, kind: &str, limit: usize) -> Value {
    for _ in 0..limit {
        let (ev, data) = s.next_event().expect("the stream ended");
        let v: Value = serde_json::from_str(&data).unwrap();
        assert_eq!(
            v["type"],
            ev.as_str(),
            "the SSE event name is the message type"
        );
        if ev == kind {
            return v;
        }
    }
    panic!("no {kind} message in {limit} messages");
}

#[test]
fn the_stream_says_hello_then_samples_states_stats_and_spectra() {
    let rig = Rig::start(RigOptions::default());
    let mut s = stream(&format!("{}/api/stream", rig.base));
    let hello = next_of(&mut s, "hello", 1);
    assert_eq!(hello["version"], 1);
    assert_eq!(hello["axes"][0]["node_id"], 5);
    assert_eq!(hello["axes"][0]["preset"], "cnc1");
    assert_eq!(hello["axes"][0]["user_unit"], "1 µm");
    let bl = hello["controls"]["set"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["key"] == "backlash_mm")
        .expect("a backlash control");
    assert_eq!(bl["unit"], "mm");
    assert_eq!(bl["min"], 0.0);
    assert!(bl["max"].as_f64().unwrap() > 0.1);
    // Samples: columns of one length, times increasing, the state decoded; the master enables
    // the drive, so OPERATION ENABLED shows up.
    let mut last_t = -1.0;
    let mut enabled = false;
    for _ in 0..400 {
        let m = next_of(&mut s, "samples", 50);
        let ax = &m["axes"][0];
        assert_eq!(ax["node_id"], 5);
        let cols = &ax["samples"];
        let n = cols["t_s"].as_array().unwrap().len();
        for k in [
            "position_demand_uu",
            "position_actual_uu",
            "following_error_uu",
            "velocity_uu_s",
            "motor_speed_rpm",
            "load_speed_uu_per_s",
            "current_a",
        ] {
            assert_eq!(cols[k].as_array().unwrap().len(), n, "{k}");
        }
        for t in cols["t_s"].as_array().unwrap() {
            let t = t.as_f64().unwrap();
            assert!(t > last_t, "{t} after {last_t}");
            last_t = t;
        }
        let st = &ax["state"];
        assert!(st["statusword"].is_u64() && st["controlword"].is_u64());
        if st["cia402_state"] == "OPERATION ENABLED" {
            assert_eq!(st["nmt_name"], "OPERATIONAL");
            assert_eq!(st["mode_name"], "PP");
            assert_eq!(st["statusword"].as_u64().unwrap() & 0x6F, 0x27);
            assert_eq!(st["controlword"].as_u64().unwrap() & 0x0F, 0x0F);
            enabled = true;
            break;
        }
    }
    assert!(enabled, "the page never saw OPERATION ENABLED");
    // The loop's statistics reach 0x2100 every 256 ticks: a drive enabled within its first
    // quarter second may still show the first, all-zero publication.
    let mut stats = next_of(&mut s, "stats", 100);
    for _ in 0..10 {
        if stats["ticks"].as_u64().unwrap() > 0 {
            break;
        }
        stats = next_of(&mut s, "stats", 100);
    }
    assert!(stats["ticks"].as_u64().unwrap() > 0, "{stats}");
    assert!(stats.get("lateness_p99_us").is_some() && stats.get("rx_overflows").is_some());
    let sp = next_of(&mut s, "spectrum", 1000);
    let amps = sp["amplitude_uu_s"].as_array().unwrap();
    assert!(amps.len() > 10, "{}", amps.len());
    assert!(sp["resolution_hz"].as_f64().unwrap() > 0.0);
    let verdict = sp["detector"]["verdict"].as_str().unwrap().to_string();
    assert!(
        ["ok", "backlash_suspected", "backlash", "inconclusive"].contains(&verdict.as_str()),
        "{verdict}"
    );
    rig.stop();
}

#[test]
fn the_stream_and_every_write_need_the_token_when_there_is_one() {
    let rig = Rig::start(RigOptions {
        token: Some("tok-123".into()),
        ..Default::default()
    });
    let base = &rig.base;
    // The page itself holds no data: no token needed.
    let (st, _) = call("GET", &format!("{base}/"), &[], None);
    assert_eq!(st, 200);
    for (url, headers) in [
        (format!("{base}/api/stream"), vec![]),
        (format!("{base}/api/stream?token=nope"), vec![]),
        (
            format!("{base}/api/info"),
            vec![("authorization", "Bearer nope")],
        ),
        (format!("{base}/api/session"), vec![]),
    ] {
        let (st, v) = call("GET", &url, &headers, None);
        assert_eq!(st, 401, "{url}: {v}");
        assert!(v["error"].as_str().unwrap().contains("token"), "{v}");
    }
    let before = backlash_mm(&rig).unwrap();
    let write = json!({"set": "backlash_mm", "value": 0.031}).to_string();
    for headers in [
        vec![],
        vec![("authorization", "Bearer nope")],
        vec![("x-panel-token", "tok-12")],
    ] {
        let (st, _) = call(
            "POST",
            &format!("{base}/api/inject"),
            &headers,
            Some(write.as_bytes()),
        );
        assert_eq!(st, 401);
    }
    let (st, _) = call(
        "POST",
        &format!("{base}/api/record"),
        &[],
        Some(br#"{"action":"start"}"#),
    );
    assert_eq!(st, 401);
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(
        backlash_mm(&rig),
        Some(before),
        "a refused write changed the drive"
    );
    // With the token: in the header, or in the query.
    let mut s = stream(&format!("{base}/api/stream?token=tok-123"));
    assert_eq!(next_of(&mut s, "hello", 1)["token_required"], true);
    let (st, v) = call(
        "POST",
        &format!("{base}/api/inject"),
        &[("authorization", "Bearer tok-123")],
        Some(write.as_bytes()),
    );
    assert_eq!(st, 200, "{v}");
    assert!((backlash_mm(&rig).unwrap() - 0.031).abs() < 1e-6);
    rig.stop();
}

#[test]
fn bad_and_oversized_messages_get_an_error_and_change_nothing() {
    let rig = Rig::start(RigOptions::default());
    let before = backlash_mm(&rig).unwrap();
    let big = format!(
        r#"{{"set": "backlash_mm", "value": 0.05, "pad": "{}"}}"#,
        "x".repeat(5000)
    );
    let cases: Vec<(&str, Vec<u8>, u16, &str)> = vec![
        (
            "/api/inject",
            big.into_bytes(),
            413,
            "larger than 4096 bytes",
        ),
        ("/api/inject", b"set backlash".to_vec(), 400, "not JSON"),
        ("/api/inject", b"".to_vec(), 400, "not JSON"),
        (
            "/api/inject",
            br#"{"set": "backlash_mm", "value": -1}"#.to_vec(),
            400,
            "at least 0",
        ),
        (
            "/api/inject",
            br#"{"set": "backlash_mm", "value": 5000}"#.to_vec(),
            400,
            "within",
        ),
        (
            "/api/inject",
            br#"{"set": "backlash_mm"}"#.to_vec(),
            400,
            "needs `value`",
        ),
        (
            "/api/inject",
            br#"{"set": "warp_drive", "value": 1}"#.to_vec(),
            400,
            "unknown parameter",
        ),
        (
            "/api/inject",
            br#"{"set": "backlash_mm", "value": 1e999}"#.to_vec(),
            400,
            "not JSON",
        ),
        (
            "/api/inject",
            br#"{"can": "drop", "share": 3}"#.to_vec(),
            400,
            "outside 0..1",
        ),
        ("/api/inject", br#"[1,2,3]"#.to_vec(), 400, "JSON object"),
        (
            "/api/inject",
            br#"{"set": "backlash_mm", "value": "0.05"}"#.to_vec(),
            400,
            "invalid type",
        ),
        (
            "/api/inject",
            b"{\"set\": \"backlash_mm\", \"value\": \"\x00\"}".to_vec(),
            400,
            "not JSON",
        ),
        (
            "/api/record",
            br#"{"action": "explode"}"#.to_vec(),
            400,
            "expected",
        ),
        (
            "/api/record",
            br#"{"action": "stop"}"#.to_vec(),
            409,
            "no recording",
        ),
    ];
    for (path, body, status, why) in cases {
        let (st, v) = call("POST", &format!("{}{path}", rig.base), &[], Some(&body));
        assert_eq!(
            st,
            status,
            "{path} {}: {v}",
            String::from_utf8_lossy(&body[..body.len().min(60)])
        );
        let e = v["error"]
            .as_str()
            .unwrap_or_else(|| panic!("no error text: {v}"));
        assert!(e.contains(why), "{e:?} should say {why:?}");
    }
    // Requests a page of another site could make: a write that is not JSON (a cross-site
    // form or a no-cors fetch), a request from another origin, a request to another host name
    // (DNS rebinding).
    let raw = |head: &str, body: &str| {
        let mut c = TcpStream::connect(rig.panel().addr).unwrap();
        write!(
            c,
            "{head}Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
            body.len()
        )
        .unwrap();
        let mut answer = String::new();
        let _ = c.read_to_string(&mut answer);
        answer
    };
    let write = r#"{"set": "backlash_mm", "value": 0.05}"#;
    let host = format!("Host: {}\r\n", rig.panel().addr);
    for (head, status) in [
        (format!("POST /api/inject HTTP/1.1\r\n{host}Content-Type: text/plain\r\n"), "415"),
        (format!("POST /api/inject HTTP/1.1\r\n{host}"), "415"),
        (
            format!("POST /api/inject HTTP/1.1\r\n{host}Content-Type: application/json\r\nOrigin: http://evil.example\r\n"),
            "403",
        ),
        (
            "POST /api/inject HTTP/1.1\r\nHost: evil.example:8080\r\nContent-Type: application/json\r\n".to_string(),
            "403",
        ),
        ("GET /api/stream HTTP/1.1\r\nHost: evil.example:8080\r\n".to_string(), "403"),
    ] {
        let answer = raw(&head, write);
        assert!(answer.starts_with(&format!("HTTP/1.1 {status}")), "{head:?}: {answer}");
    }
    // The page's own requests pass: same origin, localhost by name.
    let ok = raw(
        &format!(
            "POST /api/inject HTTP/1.1\r\nHost: localhost:{}\r\nContent-Type: application/json\r\nOrigin: http://localhost:{}\r\n",
            rig.panel().addr.port(),
            rig.panel().addr.port()
        ),
        r#"{"set": "kv_per_s", "value": 30}"#,
    );
    assert!(ok.starts_with("HTTP/1.1 200"), "{ok}");
    let (st, v) = call("GET", &format!("{}/api/nothing-here", rig.base), &[], None);
    assert_eq!((st, v["error"].as_str().is_some()), (404, true));
    // Nothing changed: the drive, the session, the recordings.
    assert_eq!(backlash_mm(&rig), Some(before));
    let (_, status) = call("GET", &format!("{}/api/status", rig.base), &[], None);
    assert_eq!(
        status["session_events"], 1,
        "only the page's own kv_per_s write"
    );
    assert!(
        status["requests_refused"].as_u64().unwrap() >= 13,
        "{status}"
    );
    let (_, rec) = call("GET", &format!("{}/api/record", rig.base), &[], None);
    assert_eq!(rec["active"], Value::Null);
    // A raw request with a body larger than the limit, sent in full: the same answer.
    let mut c = TcpStream::connect(rig.panel().addr).unwrap();
    let body = vec![b'{'; 100_000];
    write!(
        c,
        "POST /api/inject HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        body.len()
    )
    .unwrap();
    let _ = c.write_all(&body);
    let mut answer = String::new();
    let _ = c.read_to_string(&mut answer);
    assert!(
        answer.starts_with("HTTP/1.1 413"),
        "{}",
        &answer[..answer.len().min(200)]
    );
    assert_eq!(backlash_mm(&rig), Some(before));
    rig.stop();
}

#[test]
fn an_injection_reaches_the_drive_and_is_logged_with_the_drives_time() {
    let rig = Rig::start(RigOptions::default());
    let mut s = stream(&format!("{}/api/stream", rig.base));
    next_of(&mut s, "hello", 1);
    let (st, v) = post(
        &rig,
        "/api/inject",
        json!({"set": "backlash_mm", "value": 0.05}),
    );
    assert_eq!(st, 200, "{v}");
    assert_eq!(v["status"], "applied");
    assert_eq!(v["event"], "set backlash_mm = 0.05");
    let t = v["t_s"].as_f64().unwrap();
    assert!(t >= v["queued_t_s"].as_f64().unwrap());
    // Read back over SDO: 0x2000 is the backlash in mm (REAL32).
    assert!((backlash_mm(&rig).unwrap() - 0.05).abs() < 1e-6);
    let m = next_of(&mut s, "injection", 500);
    assert_eq!(m["event"], "set backlash_mm = 0.05");
    assert_eq!(m["node_id"], 5);
    assert!((m["t_s"].as_f64().unwrap() - t).abs() < 1e-9, "{m}");
    // A sensor fault: the drive raises EMCY 0x7300, which the stream reports.
    let (st, v) = post(&rig, "/api/inject", json!({"sensor": "motor_encoder_loss"}));
    assert_eq!(st, 200, "{v}");
    let e = next_of(&mut s, "emcy", 2000);
    assert_eq!(e["code"], "0x7300");
    assert_eq!(e["raised"], true);
    assert!(e["t_s"].as_f64().unwrap() >= v["t_s"].as_f64().unwrap());
    rig.stop();
}

#[test]
fn a_recording_is_csv_as_run_trace_and_downloadable() {
    let rig = Rig::start(RigOptions::default());
    let (st, v) = post(&rig, "/api/record", json!({"action": "start"}));
    assert_eq!(st, 200, "{v}");
    assert!(
        v["active"]["note"].as_str().unwrap().contains("no capture"),
        "{v}"
    );
    let (st, _) = post(&rig, "/api/record", json!({"action": "start"}));
    assert_eq!(st, 409, "one recording at a time");
    let t0 = rig.now_s();
    assert!(rig.wait_for(Duration::from_secs(60), || rig.now_s() > t0 + 1.0));
    let (st, v) = post(&rig, "/api/record", json!({"action": "stop"}));
    assert_eq!(st, 200, "{v}");
    let files = v["files"].as_array().unwrap();
    assert_eq!(files.len(), 1, "{v}");
    let name = files[0].as_str().unwrap();
    assert_eq!(name, "rec-1-node5.csv");
    let a = agent();
    let mut resp = a
        .get(&format!("{}/api/record/file/{name}", rig.base))
        .call()
        .unwrap();
    assert_eq!(resp.status().as_u16(), 200);
    let csv = resp.body_mut().read_to_string().unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some(drive_emu::samples::Sample::CSV_HEADER));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
        .collect();
    assert!(
        rows.len() > 900,
        "{} rows for over a second at 1 kHz",
        rows.len()
    );
    // Every tick, in order, 1 ms apart (nothing lost on the way).
    for w in rows.windows(2) {
        assert!(
            (w[1][0] - w[0][0] - 0.001).abs() < 1e-9,
            "{:?} -> {:?}",
            w[0],
            w[1]
        );
    }
    // The CSV is what `analyze` reads.
    let (cols, _) = drive_emu::samples::csv::parse_csv(std::path::Path::new(name), &csv).unwrap();
    assert!(cols.len() >= 11, "{} columns", cols.len());
    let (st, _) = call(
        "GET",
        &format!("{}/api/record/file/..%2F..%2Fetc%2Fpasswd", rig.base),
        &[],
        None,
    );
    assert_eq!(st, 404);
    rig.stop();
}

/// Open descriptors and threads of this process.
fn fds_and_threads() -> (usize, usize) {
    let n = |p: &str| std::fs::read_dir(p).unwrap().count();
    (n("/proc/self/fd"), n("/proc/self/task"))
}

#[test]
fn fifty_clients_connecting_and_leaving_leak_nothing() {
    let rig = Rig::start(RigOptions::default());
    // One client first, so everything lazily made on the first connection exists.
    {
        let mut s = stream(&format!("{}/api/stream", rig.base));
        next_of(&mut s, "samples", 10);
    }
    assert!(rig.wait_for(Duration::from_secs(10), || rig.panel().clients() == 0));
    let (fds0, threads0) = fds_and_threads();
    for i in 0..50 {
        let mut c = TcpStream::connect(rig.panel().addr).unwrap();
        c.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        write!(c, "GET /api/stream HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n").unwrap();
        // Read until a samples message went by, then leave (half of them mid-message).
        let mut got = Vec::new();
        let mut buf = [0u8; 4096];
        while !String::from_utf8_lossy(&got).contains("event: samples") {
            let n = c.read(&mut buf).unwrap();
            assert!(n > 0, "client {i}: the stream closed");
            got.extend_from_slice(&buf[..n]);
        }
        assert!(String::from_utf8_lossy(&got).starts_with("HTTP/1.1 200"));
        if i % 2 == 0 {
            let _ = c.shutdown(std::net::Shutdown::Both);
        }
        drop(c);
        // Several at once, too.
        if i % 10 == 9 {
            let many: Vec<_> = (0..5)
                .map(|_| {
                    let mut c = TcpStream::connect(rig.panel().addr).unwrap();
                    write!(c, "GET /api/stream HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n").unwrap();
                    c
                })
                .collect();
            assert!(rig.wait_for(Duration::from_secs(10), || rig.panel().clients() >= 5));
            drop(many);
        }
    }
    // The server notices a client gone at its next message (25 a second).
    assert!(
        rig.wait_for(Duration::from_secs(20), || rig.panel().clients() == 0),
        "{} clients left in the table",
        rig.panel().clients()
    );
    let settled = rig.wait_for(Duration::from_secs(20), || {
        fds_and_threads() == (fds0, threads0)
    });
    let (fds1, threads1) = fds_and_threads();
    assert!(
        settled,
        "descriptors {fds0} -> {fds1}, threads {threads0} -> {threads1}"
    );
    // And the panel still serves.
    let mut s = stream(&format!("{}/api/stream", rig.base));
    next_of(&mut s, "samples", 10);
    rig.stop();
}

#[test]
fn more_than_the_client_limit_get_503_and_the_others_keep_streaming() {
    let rig = Rig::start(RigOptions::default());
    let limit = drive_emu::panel::server::MAX_CLIENTS;
    let mut held: Vec<_> = (0..limit)
        .map(|_| stream(&format!("{}/api/stream", rig.base)))
        .collect();
    let (st, v) = call("GET", &format!("{}/api/stream", rig.base), &[], None);
    assert_eq!(st, 503, "{v}");
    next_of(&mut held[0], "samples", 10);
    drop(held);
    assert!(rig.wait_for(Duration::from_secs(20), || rig.panel().clients() == 0));
    rig.stop();
}

#[test]
fn a_saved_session_replays_the_same_events_at_the_same_times() {
    let rig = Rig::start(RigOptions {
        program: cruise_csp_10_mm_s(),
        overrides: vec![("backlash_mm", "0.01")],
        ..Default::default()
    });
    let writes = [
        json!({"set": "backlash_mm", "value": 0.04}),
        json!({"can": "drop", "share": 0.25, "over": "300 ms"}),
        json!({"set": "load_force_n", "value": 120.5}),
        json!({"sensor": "direct_encoder_glitch", "counts": 25}),
    ];
    let mut applied = Vec::new();
    for w in &writes {
        let t0 = rig.now_s();
        assert!(rig.wait_for(Duration::from_secs(60), || rig.now_s() > t0 + 0.2));
        let (st, v) = post(&rig, "/api/inject", w.clone());
        assert_eq!(st, 200, "{v}");
        assert_eq!(v["status"], "applied", "{v}");
        applied.push((
            v["event"].as_str().unwrap().to_string(),
            (v["t_s"].as_f64().unwrap() * 1e6).round() as u64,
        ));
    }
    let a = agent();
    let mut resp = a.get(&format!("{}/api/session", rig.base)).call().unwrap();
    let text = resp.body_mut().read_to_string().unwrap();
    rig.stop();
    let s = scenario::parse(&text, std::path::Path::new("panel-session.toml"))
        .unwrap_or_else(|e| panic!("{e}\n{text}"));
    let events: Vec<(String, u64)> = s
        .events
        .iter()
        .map(|e| match e.trigger {
            Trigger::At(t) => (e.describe(), t),
            ref other => panic!("{other:?}"),
        })
        .collect();
    assert_eq!(
        events, applied,
        "the file holds the injections at the drive's times"
    );
    assert_eq!(
        s.machine.overrides,
        vec![("backlash_mm".to_string(), "0.01".to_string())]
    );
    // Replayed offline: the same events fire at the same times.
    let out = runner::run(
        &s,
        &runner::RunOptions {
            progress: false,
            ..Default::default()
        },
    )
    .unwrap();
    let fired: Vec<(String, u64)> = out.runs[0]
        .events
        .iter()
        .map(|(t, what)| (what.clone(), (t * 1e6).round() as u64))
        .collect();
    assert_eq!(fired.len(), applied.len(), "{fired:?}");
    for ((w0, t0), (w1, t1)) in applied.iter().zip(&fired) {
        assert!(w1.contains(w0.as_str()), "{w1:?} is {w0:?}");
        assert!(
            t1.abs_diff(*t0) <= 1000,
            "{w0}: {t0} us live, {t1} us replayed"
        );
    }
}

/// python/examples/panel_stream.py (stdlib only) against the panel: its injection is applied
/// (read back over SDO) and it reads the stream's messages.
#[test]
fn the_python_example_reads_the_stream_and_injects() {
    let rig = Rig::start(RigOptions {
        token: Some("py-tok".into()),
        ..Default::default()
    });
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../python/examples/panel_stream.py"
    );
    let python = std::env::var("DRIVE_EMU_PYTHON").unwrap_or_else(|_| "python3".into());
    let run = |extra: &[&str]| {
        let out = std::process::Command::new(&python)
            .arg(script)
            .args(["--url", &rig.base, "--count", "30"])
            .args(extra)
            .output()
            .unwrap_or_else(|e| panic!("cannot run {python}: {e}"));
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    // Without the token: refused, and it says so.
    let (code, _, err) = run(&[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("401"), "{err}");
    let (code, out, err) = run(&[
        "--token",
        "py-tok",
        "--inject",
        r#"{"set": "backlash_mm", "value": 0.045}"#,
    ]);
    assert_eq!(code, Some(0), "{out}\n{err}");
    let lines: Vec<&str> = out.lines().collect();
    assert!(lines[0].starts_with("inject: ") && lines[0].contains("set backlash_mm = 0.045"));
    assert!(lines[1].starts_with("hello: 1000 Hz, 500") && lines[1].contains("node 5 (cnc1"));
    assert!(
        lines
            .iter()
            .filter(|l| l.contains(" samples, position "))
            .count()
            >= 20,
        "{out}"
    );
    assert!((backlash_mm(&rig).unwrap() - 0.045).abs() < 1e-6);
    // --json: one message per line, each with its type.
    let (code, out, err) = run(&["--token", "py-tok", "--json"]);
    assert_eq!(code, Some(0), "{err}");
    for l in out.lines() {
        let v: Value = serde_json::from_str(l).unwrap();
        assert!(v["type"].is_string(), "{l}");
    }
    rig.stop();
}

/// `run --scenario ... --panel`: the scenario's injections go through the panel's loop half,
/// and the fan-out, which drains the node's events once per tick, hands axis 0's EMCYs to the
/// scenario (its expectations hold) while the page's stream reports them too.
#[test]
fn a_live_scenario_beside_the_panel_gets_its_emcys_through_the_fan_out() {
    use drive_emu::bus::fault::FaultyBus;
    use drive_emu::bus::inproc::InProcBus;
    use drive_emu::bus::CanBus;
    use drive_emu::drive::axis_drive::AxisDrive;
    use drive_emu::drive::AxisParam;
    use drive_emu::master::{Master, MasterConfig};
    use drive_emu::panel::{PanelAxis, PanelSetup};
    use drive_emu::runtime::{AxisSlot, Runtime};
    use drive_emu::scenario::live::{run_timeline, LiveEnd, LiveLink};
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    const SCENARIO: &str = r#"
name = "live-panel"
duration = "2.5 s"
[machine]
preset = "cnc1"
[[motion]]
step = "enable"
mode = "csp"
[[event]]
at = "0.3 s"
set = "backlash_mm"
value = 0.06
[[event]]
id = "loss"
at = "1.5 s"
sensor = "direct_encoder_loss"
[[expect]]
emcy = "0x7300"
after = "loss"
within = "100 ms"
[[expect]]
no_emcy = true
until = "1.4 s"
"#;
    let s = scenario::parse(SCENARIO, std::path::Path::new("live-panel.toml")).unwrap();
    let cfg = s.machine.configs[0].clone();
    let mut drive = AxisDrive::from_config(&cfg).unwrap();
    let snapshot = AxisDrive::from_config(&cfg).unwrap();
    let node = drive_emu::drive::node(&mut drive, 5).unwrap();
    let mut eps = InProcBus::endpoints(2, 4096);
    let mut master_bus = eps.pop().unwrap();
    let mut rt = Runtime::new(
        FaultyBus::new(eps.pop().unwrap(), 1),
        vec![AxisSlot { node, drive }],
        1000,
    );
    rt.boot();
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let setup = PanelSetup {
        bus: drive_emu::panel::PanelBus::Can,
        axes: vec![PanelAxis {
            node_id: 5,
            preset: "cnc1".into(),
            config: cfg.clone(),
            overrides: vec![],
        }],
        iface: None,
        tick_hz: 1000,
        lockstep: false,
        master_id: 0x7F,
        json_stdout: false,
    };
    let dir = std::env::temp_dir().join(format!("drive-emu-panel-scn-{}", std::process::id()));
    let (mut observer, obs) = drive_emu::observe::channel(1, 1 << 14);
    let (panel, mut panel_loop) =
        drive_emu::panel::start_on(listener, None, dir, setup, Arc::clone(&obs)).unwrap();
    let link = Arc::new(LiveLink::new());
    panel_loop.attach_scenario(Arc::clone(&link), s.run.master.master_id);
    let mut sse = stream(&format!("http://{}/api/stream", panel.addr));
    next_of(&mut sse, "hello", 1);
    let stop = Arc::new(AtomicBool::new(false));
    let scenario_thread = {
        let (s, cfg, link, stop) = (s.clone(), cfg.clone(), link.clone(), stop.clone());
        let obs = Arc::clone(&obs);
        std::thread::spawn(move || {
            let o = run_timeline(
                &s,
                &cfg,
                &snapshot,
                (&link, &obs),
                &stop,
                LiveEnd::for_scenario(&s, None),
            );
            stop.store(true, Ordering::Relaxed);
            o
        })
    };
    let mut master = Master::new(
        MasterConfig::default(),
        vec![
            Step::Enable { mode: MODE_CSP },
            Step::Cruise {
                velocity_uu_s: 10_000.0,
                accel_uu_s2: 100_000.0,
                duration_s: 10.0,
            },
        ],
    );
    let mut backlash_at_1s = None;
    while !stop.load(Ordering::Relaxed) && rt.sim_time_us < 10_000_000 {
        std::thread::sleep(Duration::from_micros(900));
        master.poll(rt.sim_time_us);
        while let Some(f) = master.pop_tx() {
            master_bus.send(&f).unwrap();
        }
        rt.tick();
        observer.publish(&mut rt);
        panel_loop.on_tick(&mut rt);
        while let Ok(Some(f)) = master_bus.recv() {
            master.handle(&f, rt.sim_time_us);
        }
        if rt.sim_time_us == 1_000_000 {
            backlash_at_1s = Some(rt.axes[0].drive.param(AxisParam::Backlash));
        }
    }
    let outcome = scenario_thread.join().unwrap();
    assert_eq!(
        backlash_at_1s,
        Some(0.06e-3),
        "the scenario's set reached the drive"
    );
    assert!(outcome.passed(), "{:?}", outcome.expectations);
    assert!(outcome.record.emcys.iter().any(|(_, c)| *c == 0x7300));
    let e = next_of(&mut sse, "emcy", 3000);
    assert_eq!(e["code"], "0x7300");
    let t = e["t_s"].as_f64().unwrap();
    assert!((1.5..1.6).contains(&t), "{t}");
    panel.stop();
}

/// A page opened on a run that has been going gets the run's recent past first (the span it
/// shows, the last spectrum, the EMCYs), then the live messages, with no sample missing or
/// sent twice at the seam.
#[test]
fn a_client_that_connects_late_gets_the_recent_past_first() {
    let rig = Rig::start(RigOptions {
        lockstep: true,
        ..Default::default()
    });
    let mut first = stream(&format!("{}/api/stream", rig.base));
    next_of(&mut first, "hello", 1);
    // Let the run go for 3 s of drive time and past its first spectrum.
    let mut seen_t = 0.0;
    next_of(&mut first, "spectrum", 2000);
    while seen_t < 3.0 {
        let m = next_of(&mut first, "samples", 100);
        if let Some(t) = m["axes"][0]["samples"]["t_s"]
            .as_array()
            .and_then(|t| t.last())
        {
            seen_t = t.as_f64().unwrap();
        }
    }
    let mut late = stream(&format!("{}/api/stream", rig.base));
    next_of(&mut late, "hello", 1);
    // The replay: samples from the run's start (60 s are kept), then the latest spectrum.
    let mut ts: Vec<f64> = Vec::new();
    let mut spectrum_at = None;
    let mut stats = None;
    let mut lost = 0;
    for k in 0..5000 {
        let (ev, data) = late.next_event().expect("the stream ended");
        let v: Value = serde_json::from_str(&data).unwrap();
        if ev == "samples" {
            lost = lost.max(v["axes"][0]["lost"].as_u64().unwrap_or(0));
            for t in v["axes"][0]["samples"]["t_s"].as_array().unwrap() {
                ts.push(t.as_f64().unwrap());
            }
        } else if ev == "stats" && stats.is_none() {
            stats = Some(v.clone());
        } else if ev == "spectrum" && spectrum_at.is_none() {
            spectrum_at = Some((k, ts.last().copied().unwrap_or(0.0)));
        }
        if ts.last().is_some_and(|t| *t > seen_t + 1.0) && spectrum_at.is_some() {
            break;
        }
    }
    assert!(
        ts.first().is_some_and(|t| *t < 0.5),
        "the late client's first sample is at {:?} s, the run was at {seen_t} s",
        ts.first()
    );
    let (k, t_spec) = spectrum_at.expect("a spectrum");
    assert!(
        t_spec < seen_t + 0.5,
        "the spectrum came with the replay (message {k}, after samples up to {t_spec} s), \
         not only with the next analysis"
    );
    // A lock-step run has no SYNC phase lock: its statistics say lock-step, not free-running.
    let stats = stats.expect("the statistics");
    assert_eq!(stats["sync_lock"], "lock-step", "{stats}");
    for w in ts.windows(2) {
        assert!(
            w[1] > w[0],
            "samples out of order or twice at {} -> {} s",
            w[0],
            w[1]
        );
    }
    // No gap at the seam: the stream's step between samples stays regular (unless the
    // collector itself lost ticks, which it counts: a very busy machine).
    let step = ts[1] - ts[0];
    for w in ts.windows(2).filter(|_| lost == 0) {
        assert!(
            w[1] - w[0] < 1.5 * step,
            "a gap from {} to {} s (step {step} s)",
            w[0],
            w[1]
        );
    }
    rig.stop();
}
