//! The panel's HTTP routes (axum on a single-threaded tokio runtime, on a thread of its own).
//!
//! - `GET /` and `GET /assets/{name}`: the page (no token: it holds no data);
//! - `GET /api/stream`: server-sent events, every message of [`super::stream`];
//! - `GET /api/info`: the `hello` message (axes, units, controls and their bounds);
//! - `POST /api/inject`: one injection ([`super::control`]);
//! - `POST /api/record` `{"action": "start" | "stop"}`, `GET /api/record`,
//!   `GET /api/record/file/{name}`: recordings ([`super::record`]);
//! - `GET /api/session`: the session as a scenario file;
//! - `GET /api/status`: clients connected, messages sent, requests refused.
//!
//! Everything under `/api/` needs the token when there is one, and is refused when it could
//! come from a page of another site (see `cross_site`). A body over [`MAX_BODY`]
//! bytes, a body that is not JSON, or a write the checks refuse gets an error status with a
//! JSON body `{"error": reason, "key": key or null}` and changes nothing.

use super::auth::{offered, Auth};
use super::control::{self, Controls, Session, SessionEvent, MAX_SESSION_EVENTS};
use super::history::History;
pub use super::history::Message;
use super::record::{self, RecordState};
use super::{assets, PanelSetup};
use crate::observe::Observation;
use crate::scenario::inject::Injection;
use crate::scenario::live::LiveLink;
use axum::body::{Body, Bytes};
use axum::extract::rejection::BytesRejection;
use axum::extract::{DefaultBodyLimit, Path, Request, State};
use axum::http::{header, StatusCode};
use axum::middleware::{self, Next};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::collections::VecDeque;
use std::convert::Infallible;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::{broadcast, watch};

/// Largest request body accepted, bytes (a write is a few dozen).
pub const MAX_BODY: usize = 4096;
/// Most stream clients at once; one more gets 503.
pub const MAX_CLIENTS: usize = 64;
/// Messages a client may fall behind before it loses the oldest (it is told how many).
pub const CLIENT_BACKLOG: usize = 256;
/// How long an injection request waits for the loop to apply it before answering "queued".
const APPLY_WAIT: Duration = Duration::from_secs(1);

/// A stream client, as the client table lists it.
#[derive(Debug, Clone)]
pub struct ClientEntry {
    pub since: Instant,
}

/// What the server, the collector and the panel handle share.
pub struct Shared {
    pub auth: Auth,
    pub setup: PanelSetup,
    pub controls: Controls,
    pub obs: Arc<Observation>,
    /// The panel's injection queue to the loop.
    pub link: Arc<LiveLink>,
    pub record_dir: record::RecordDir,
    pub record_limits: Mutex<record::RecordLimits>,
    pub record: Mutex<RecordState>,
    pub session: Mutex<Session>,
    pub tx: broadcast::Sender<Arc<Message>>,
    /// The stream's recent past, sent to a client when it connects (taken with the
    /// subscription under this lock, so a client misses nothing and gets nothing twice).
    pub history: Mutex<History>,
    pub clients: Mutex<BTreeMap<u64, ClientEntry>>,
    next_client: AtomicU64,
    pub stop: AtomicBool,
    pub shutdown_tx: watch::Sender<bool>,
    pub messages_sent: AtomicU64,
    pub refused: AtomicU64,
}

impl Shared {
    pub fn new(
        auth: Auth,
        setup: PanelSetup,
        controls: Controls,
        obs: Arc<Observation>,
        link: Arc<LiveLink>,
        record_dir: record::RecordDir,
    ) -> Self {
        Shared {
            auth,
            setup,
            controls,
            obs,
            link,
            record_dir,
            record_limits: Mutex::new(record::RecordLimits::default()),
            record: Mutex::new(RecordState {
                next_number: 1,
                ..Default::default()
            }),
            session: Mutex::new(Session::default()),
            tx: broadcast::channel(CLIENT_BACKLOG).0,
            history: Mutex::new(History::default()),
            clients: Mutex::new(BTreeMap::new()),
            next_client: AtomicU64::new(1),
            stop: AtomicBool::new(false),
            shutdown_tx: watch::channel(false).0,
            messages_sent: AtomicU64::new(0),
            refused: AtomicU64::new(0),
        }
    }

    /// Finish a recording still running when the panel stops.
    pub fn finish_recording(&self) {
        let active = self.record.lock().ok().and_then(|mut r| r.active.take());
        if let Some(r) = active {
            let (names, _) = r.finish();
            for n in names {
                eprintln!(
                    "drive-emu: panel: recording written: {}",
                    self.record_dir.path.join(n).display()
                );
            }
        }
    }

    pub fn client_count(&self) -> usize {
        self.clients.lock().map_or(0, |c| c.len())
    }

    /// The drive's simulated time, us.
    pub fn now_us(&self) -> u64 {
        self.obs.board.sim_time_us.load(Ordering::Relaxed)
    }

    /// Send a message to every client (none connected: dropped).
    pub fn broadcast(&self, kind: &'static str, v: Value) {
        let m = Arc::new(Message {
            kind,
            json: v.to_string(),
        });
        let axis = v.get("axis").and_then(Value::as_u64);
        match self.history.lock() {
            Ok(mut h) => {
                h.keep(&m, axis);
                let _ = self.tx.send(m);
            }
            Err(_) => {
                let _ = self.tx.send(m);
            }
        }
        self.messages_sent.fetch_add(1, Ordering::Relaxed);
    }

    /// The `hello` message: the run, its axes and units, the controls.
    pub fn hello(&self) -> Value {
        let s = &self.setup;
        json!({
            "type": "hello",
            "version": 1,
            "t_s": self.now_us() as f64 * 1e-6,
            "iface": s.iface,
            "bus": s.bus.key(),
            "tick_hz": s.tick_hz,
            "lockstep": s.lockstep,
            "stream_period_ms": super::rate::PERIOD_MS,
            "samples_per_s": super::rate::stream_rate_hz(s.tick_hz),
            "token_required": self.auth.required(),
            "axes": s.axes.iter().enumerate().map(|(i, a)| {
                let rotary = a.config.kind == crate::presets::AxisKind::Rotary;
                json!({
                    "index": i, "node_id": a.node_id, "preset": a.preset, "rotary": rotary,
                    "user_unit": crate::report::user_unit(rotary),
                    "kv_per_s": a.config.kv_per_s,
                })
            }).collect::<Vec<_>>(),
            "controls": self.controls.to_json(),
        })
    }
}

/// An error reply: status and `{"error": reason, "key": null}`.
fn error(status: StatusCode, reason: impl Into<String>) -> Response {
    (status, Json(json!({"error": reason.into(), "key": null}))).into_response()
}

/// The host part of a `Host` header or an origin's authority (`[::1]:8080` -> `::1`).
fn host_part(authority: &str) -> &str {
    let a = authority.trim();
    if let Some(rest) = a.strip_prefix('[') {
        return rest.split(']').next().unwrap_or(rest);
    }
    a.rsplit_once(':').map_or(a, |(h, _)| h)
}

/// Whether a request could come from a page of another site (cross-site request forgery,
/// DNS rebinding): the reason to refuse it, if so. Without a token the panel is on loopback
/// and answers only requests addressed to a loopback IP or `localhost`; a request that says
/// where it comes from (`Origin`) must come from the panel's own address; a write must be
/// `application/json` (a browser sends that cross-site only after a preflight, which the
/// panel does not grant).
fn cross_site(sh: &Shared, req: &Request) -> Option<(StatusCode, &'static str)> {
    cross_site_refusal(sh.auth.required(), req.method(), req.headers())
}

/// [`cross_site`] on a request's method and headers alone (a pure function: the fuzz target
/// `panel` calls it); `token_required`: the panel has a token.
pub fn cross_site_refusal(
    token_required: bool,
    method: &axum::http::Method,
    h: &axum::http::HeaderMap,
) -> Option<(StatusCode, &'static str)> {
    let host = h
        .get(header::HOST)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("");
    if !token_required {
        let name = host_part(host);
        let loopback = name.eq_ignore_ascii_case("localhost")
            || name
                .parse::<std::net::IpAddr>()
                .is_ok_and(|ip| ip.is_loopback());
        if !loopback {
            return Some((
                StatusCode::FORBIDDEN,
                "without a token the panel answers requests to 127.0.0.1, [::1] or localhost \
                 only",
            ));
        }
    }
    // A browser says where a request comes from: only the panel's own page ("same-origin")
    // and the user's own action ("none": typed, bookmarked) pass; "same-site" is another
    // port or subdomain of the same host (another local web application).
    if let Some(site) = h.get("sec-fetch-site").and_then(|v| v.to_str().ok()) {
        let site = site.trim();
        if !(site.eq_ignore_ascii_case("same-origin") || site.eq_ignore_ascii_case("none")) {
            return Some((
                StatusCode::FORBIDDEN,
                "a request from a page of another site is refused (Sec-Fetch-Site)",
            ));
        }
    }
    if let Some(origin) = h.get(header::ORIGIN).and_then(|v| v.to_str().ok()) {
        let authority = origin.split_once("://").map_or(origin, |(_, a)| a);
        if !authority.eq_ignore_ascii_case(host) {
            return Some((
                StatusCode::FORBIDDEN,
                "a request from a page of another origin is refused",
            ));
        }
    }
    if method == axum::http::Method::POST {
        let json = h
            .get(header::CONTENT_TYPE)
            .and_then(|v| v.to_str().ok())
            .is_some_and(|ct| ct.trim_start().starts_with("application/json"));
        if !json {
            return Some((
                StatusCode::UNSUPPORTED_MEDIA_TYPE,
                "a write must be sent as Content-Type: application/json",
            ));
        }
    }
    None
}

async fn require_token(State(sh): State<Arc<Shared>>, req: Request, next: Next) -> Response {
    if let Some((status, why)) = cross_site(&sh, &req) {
        sh.refused.fetch_add(1, Ordering::Relaxed);
        return error(status, why);
    }
    let ok = sh
        .auth
        .check(offered(req.headers(), req.uri().query()))
        .map_err(|why| {
            sh.refused.fetch_add(1, Ordering::Relaxed);
            error(StatusCode::UNAUTHORIZED, why)
        });
    match ok {
        Ok(()) => next.run(req).await,
        Err(r) => r,
    }
}

/// The routes.
pub fn router(shared: Arc<Shared>) -> Router {
    let api = Router::new()
        .route("/api/stream", get(stream))
        .route("/api/info", get(info))
        .route("/api/status", get(status))
        .route("/api/inject", post(inject))
        .route("/api/record", post(record_cmd).get(record_state))
        .route("/api/record/file/{name}", get(record_file))
        .route("/api/session", get(session))
        .route_layer(middleware::from_fn_with_state(
            Arc::clone(&shared),
            require_token,
        ));
    Router::new()
        .route(
            "/",
            get(|| async { page(assets::INDEX_HTML, "text/html; charset=utf-8") }),
        )
        .route("/assets/{name}", get(asset))
        .merge(api)
        .fallback(|| async { error(StatusCode::NOT_FOUND, "no such page") })
        .layer(DefaultBodyLimit::max(MAX_BODY))
        .layer(middleware::from_fn_with_state(
            Arc::clone(&shared),
            body_deadline,
        ))
        .layer(middleware::map_response(security_headers))
        .with_state(shared)
}

/// On every response: no `Referer` with the token leaves the page; no other site may frame
/// the page (its injection buttons could be clickjacked); the browser does not guess types.
async fn security_headers(mut r: Response) -> Response {
    let h = r.headers_mut();
    h.insert(
        header::REFERRER_POLICY,
        header::HeaderValue::from_static("no-referrer"),
    );
    h.insert(
        header::CONTENT_SECURITY_POLICY,
        header::HeaderValue::from_static("frame-ancestors 'none'"),
    );
    h.insert(
        header::X_FRAME_OPTIONS,
        header::HeaderValue::from_static("DENY"),
    );
    h.insert(
        header::X_CONTENT_TYPE_OPTIONS,
        header::HeaderValue::from_static("nosniff"),
    );
    r
}

fn page(body: &'static [u8], content_type: &'static str) -> Response {
    (
        [
            (header::CONTENT_TYPE, content_type),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        body,
    )
        .into_response()
}

async fn asset(Path(name): Path<String>) -> Response {
    match assets::get(&name) {
        Some((body, ct)) => page(body, ct),
        None => error(StatusCode::NOT_FOUND, "no such asset"),
    }
}

async fn info(State(sh): State<Arc<Shared>>) -> Response {
    Json(sh.hello()).into_response()
}

async fn status(State(sh): State<Arc<Shared>>) -> Response {
    Json(json!({
        "t_s": sh.now_us() as f64 * 1e-6,
        "clients": sh.client_count(),
        "messages_sent": sh.messages_sent.load(Ordering::Relaxed),
        "requests_refused": sh.refused.load(Ordering::Relaxed),
        "session_events": sh.session.lock().map_or(0, |s| s.events.len()),
    }))
    .into_response()
}

/// Removes its client from the table when the stream ends (client gone, panel stopping).
struct ClientGuard {
    shared: Arc<Shared>,
    id: u64,
}

impl Drop for ClientGuard {
    fn drop(&mut self) {
        if let Ok(mut c) = self.shared.clients.lock() {
            c.remove(&self.id);
        }
    }
}

struct StreamState {
    hello: Option<String>,
    /// The history, sent after `hello` and before the live messages.
    replay: VecDeque<Arc<Message>>,
    /// How many messages the replay had, until the `live` message has said so.
    replayed: Option<usize>,
    rx: broadcast::Receiver<Arc<Message>>,
    shutdown: watch::Receiver<bool>,
    _guard: ClientGuard,
}

async fn stream(State(sh): State<Arc<Shared>>) -> Response {
    let id = sh.next_client.fetch_add(1, Ordering::Relaxed);
    {
        let Ok(mut c) = sh.clients.lock() else {
            return error(StatusCode::INTERNAL_SERVER_ERROR, "client table poisoned");
        };
        if c.len() >= MAX_CLIENTS {
            sh.refused.fetch_add(1, Ordering::Relaxed);
            return error(
                StatusCode::SERVICE_UNAVAILABLE,
                format!("{MAX_CLIENTS} stream clients are connected already"),
            );
        }
        c.insert(
            id,
            ClientEntry {
                since: Instant::now(),
            },
        );
    }
    let (rx, replay) = match sh.history.lock() {
        Ok(h) => (sh.tx.subscribe(), h.replay()),
        Err(_) => (sh.tx.subscribe(), VecDeque::new()),
    };
    let st = StreamState {
        hello: Some(sh.hello().to_string()),
        replayed: Some(replay.len()),
        replay,
        rx,
        shutdown: sh.shutdown_tx.subscribe(),
        _guard: ClientGuard {
            shared: Arc::clone(&sh),
            id,
        },
    };
    let events = futures_util::stream::unfold(st, |mut st| async move {
        if let Some(h) = st.hello.take() {
            return Some((
                Ok::<_, Infallible>(Event::default().event("hello").data(h)),
                st,
            ));
        }
        if *st.shutdown.borrow() {
            return None;
        }
        if let Some(m) = st.replay.pop_front() {
            let ev = Event::default().event(m.kind).data(&m.json);
            return Some((Ok(ev), st));
        }
        if let Some(n) = st.replayed.take() {
            // The seam between the past and the live messages (a page taking a snapshot
            // closes the stream here).
            let v = json!({"type": "live", "replayed": n});
            return Some((Ok(Event::default().event("live").data(v.to_string())), st));
        }
        tokio::select! {
            r = st.rx.recv() => match r {
                Ok(m) => {
                    let ev = Event::default().event(m.kind).data(&m.json);
                    Some((Ok(ev), st))
                }
                Err(broadcast::error::RecvError::Lagged(n)) => {
                    let v = json!({"type": "lagged", "messages": n});
                    Some((Ok(Event::default().event("lagged").data(v.to_string())), st))
                }
                Err(broadcast::error::RecvError::Closed) => None,
            },
            _ = st.shutdown.changed() => None,
        }
    });
    Sse::new(events)
        .keep_alive(KeepAlive::default())
        .into_response()
}

/// The body as JSON, or the error reply (too large, unreadable, not JSON).
fn json_body(sh: &Shared, body: Result<Bytes, BytesRejection>) -> Result<Value, Box<Response>> {
    let refuse = |status, why: String| {
        sh.refused.fetch_add(1, Ordering::Relaxed);
        Box::new(error(status, why))
    };
    let b = body.map_err(|e| {
        let status = e.status();
        let why = if status == StatusCode::PAYLOAD_TOO_LARGE {
            format!("the body is larger than {MAX_BODY} bytes")
        } else {
            e.body_text()
        };
        refuse(status, why)
    })?;
    parse_json_body(&b).map_err(|why| refuse(StatusCode::BAD_REQUEST, why))
}

/// A request body as JSON, or why not (the reason sent back).
pub fn parse_json_body(b: &[u8]) -> Result<Value, String> {
    serde_json::from_slice(b).map_err(|e| format!("the body is not JSON: {e}"))
}

/// What `POST /api/record` asks.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RecordAction {
    Start,
    Stop,
}

/// The action of a `POST /api/record` body: exactly `{"action": "start"}` or
/// `{"action": "stop"}`; anything else is refused with the reply's JSON.
pub fn record_action(v: &Value) -> Result<RecordAction, Value> {
    let action = v.get("action").and_then(Value::as_str);
    let extra = v
        .as_object()
        .is_some_and(|o| o.keys().any(|k| k != "action"));
    match action {
        Some("start") if !extra => Ok(RecordAction::Start),
        Some("stop") if !extra => Ok(RecordAction::Stop),
        _ => Err(
            json!({"error": "expected {\"action\": \"start\"} or {\"action\": \"stop\"}",
                    "key": "action"}),
        ),
    }
}

async fn inject(State(sh): State<Arc<Shared>>, body: Result<Bytes, BytesRejection>) -> Response {
    let v = match json_body(&sh, body) {
        Ok(v) => v,
        Err(r) => return *r,
    };
    let checked = match sh.controls.check(&v) {
        Ok(c) => c,
        Err(why) => {
            sh.refused.fetch_add(1, Ordering::Relaxed);
            return (StatusCode::BAD_REQUEST, Json(why.to_json())).into_response();
        }
    };
    let now = sh.now_us();
    let inj = control::injection(&checked, now);
    // Queue under the session's lock: the injection and its mark go in together, in order.
    let index = {
        let Ok(mut s) = sh.session.lock() else {
            return error(StatusCode::INTERNAL_SERVER_ERROR, "session poisoned");
        };
        if s.events.len() >= MAX_SESSION_EVENTS {
            sh.refused.fetch_add(1, Ordering::Relaxed);
            return error(
                StatusCode::CONFLICT,
                format!(
                    "this session has {MAX_SESSION_EVENTS} injections: save it \
                     (GET /api/session) and start another run"
                ),
            );
        }
        let q = &sh.link.injections;
        if q.capacity() - q.len() < 2 {
            sh.refused.fetch_add(1, Ordering::Relaxed);
            return error(
                StatusCode::SERVICE_UNAVAILABLE,
                "the loop is not taking injections (is it stopped?)",
            );
        }
        let index = s.events.len();
        if let Some(i) = inj {
            let _ = q.push(i);
        }
        let _ = q.push(Injection::Mark {
            event: index as u32,
        });
        s.events.push(SessionEvent {
            toml_lines: checked.toml_lines.clone(),
            describe: checked.describe.clone(),
            queued_us: now,
            applied_us: None,
        });
        index
    };
    // The collector records when the loop applied it; wait a little for that.
    let start = Instant::now();
    let applied = loop {
        let t = sh
            .session
            .lock()
            .ok()
            .and_then(|s| s.events.get(index).and_then(|e| e.applied_us));
        if t.is_some() || start.elapsed() > APPLY_WAIT {
            break t;
        }
        tokio::time::sleep(Duration::from_millis(5)).await;
    };
    Json(json!({
        "ok": true,
        "index": index,
        "event": checked.describe,
        "status": if applied.is_some() { "applied" } else { "queued" },
        "t_s": applied.map(|t| t as f64 * 1e-6),
        "queued_t_s": now as f64 * 1e-6,
    }))
    .into_response()
}

/// The recordings: the one running, the files written.
fn record_json(sh: &Shared, st: &RecordState) -> Value {
    json!({
        "type": "recording",
        "active": st.active.as_ref().map(|r| json!({
            "number": r.number,
            "started_t_s": r.started_us as f64 * 1e-6,
            "samples": r.samples,
            "lost": r.lost,
            "frames": r.frames(),
            "csv": r.csv_names,
            "capture": r.capture_name,
            "note": r.capture_note,
            "bytes": r.bytes(),
            "cap": r.cap_note(),
        })),
        "files": st.files,
        "dir": sh.record_dir.path.display().to_string(),
    })
}

async fn record_state(State(sh): State<Arc<Shared>>) -> Response {
    let Ok(st) = sh.record.lock() else {
        return error(
            StatusCode::INTERNAL_SERVER_ERROR,
            "recording state poisoned",
        );
    };
    Json(record_json(&sh, &st)).into_response()
}

async fn record_cmd(
    State(sh): State<Arc<Shared>>,
    body: Result<Bytes, BytesRejection>,
) -> Response {
    let v = match json_body(&sh, body) {
        Ok(v) => v,
        Err(r) => return *r,
    };
    let action = match record_action(&v) {
        Ok(a) => a,
        Err(reply) => {
            sh.refused.fetch_add(1, Ordering::Relaxed);
            return (StatusCode::BAD_REQUEST, Json(reply)).into_response();
        }
    };
    let Ok(mut st) = sh.record.lock() else {
        return error(
            StatusCode::INTERNAL_SERVER_ERROR,
            "recording state poisoned",
        );
    };
    if action == RecordAction::Start {
        if st.active.is_some() {
            sh.refused.fetch_add(1, Ordering::Relaxed);
            return error(StatusCode::CONFLICT, "a recording is running already");
        }
        let limits = sh.record_limits.lock().map(|l| *l).unwrap_or_default();
        let n = st.next_number;
        if n > limits.max_recordings {
            sh.refused.fetch_add(1, Ordering::Relaxed);
            return error(
                StatusCode::CONFLICT,
                format!(
                    "this run made {} recordings, the most a run makes: download what you \
                     need and start another run",
                    limits.max_recordings
                ),
            );
        }
        let ids: Vec<u8> = sh.setup.axes.iter().map(|a| a.node_id).collect();
        match record::start(
            &sh.record_dir.path,
            n,
            &ids,
            sh.setup.iface.as_deref(),
            sh.now_us(),
            limits.max_bytes,
        ) {
            Ok(r) => {
                st.active = Some(r);
                st.next_number += 1;
            }
            Err(e) => return error(StatusCode::INTERNAL_SERVER_ERROR, e.to_string()),
        }
    } else {
        let Some(r) = st.active.take() else {
            sh.refused.fetch_add(1, Ordering::Relaxed);
            return error(StatusCode::CONFLICT, "no recording is running");
        };
        let (names, problem) = r.finish();
        for n in &names {
            println!(
                "drive-emu: panel: recording written: {}",
                sh.record_dir.path.join(n).display()
            );
        }
        st.files.extend(names);
        if let Some(p) = problem {
            eprintln!("drive-emu: panel: recording: {p}");
        }
    }
    let v = record_json(&sh, &st);
    drop(st);
    sh.broadcast("recording", v.clone());
    Json(v).into_response()
}

async fn record_file(State(sh): State<Arc<Shared>>, Path(name): Path<String>) -> Response {
    let path = {
        let Ok(st) = sh.record.lock() else {
            return error(
                StatusCode::INTERNAL_SERVER_ERROR,
                "recording state poisoned",
            );
        };
        record::served_path(&sh.record_dir.path, &st, &name)
    };
    let Some(path) = path else {
        return error(
            StatusCode::NOT_FOUND,
            "no such recording (finished ones only)",
        );
    };
    let (file, size) = match record::open_served(&path) {
        Ok(x) => x,
        Err(e) => {
            sh.refused.fetch_add(1, Ordering::Relaxed);
            return error(
                StatusCode::INTERNAL_SERVER_ERROR,
                format!("{name}: cannot serve: {e}"),
            );
        }
    };
    let ct = if name.ends_with(".csv") {
        "text/csv; charset=utf-8"
    } else {
        "text/plain; charset=utf-8"
    };
    (
        [
            (header::CONTENT_TYPE, ct.to_string()),
            (
                header::CONTENT_DISPOSITION,
                format!("attachment; filename=\"{name}\""),
            ),
        ],
        Body::from_stream(file_chunks(file, size)),
    )
        .into_response()
}

/// Bytes served per read of a download.
const CHUNK_BYTES: usize = 64 << 10;

/// A file as a stream of chunks, at most `size` bytes (the size `fstat` gave when it was
/// opened: a file that grows is not followed), read one chunk at a time.
fn file_chunks(
    file: std::fs::File,
    size: u64,
) -> impl futures_util::Stream<Item = std::io::Result<Bytes>> + Send + 'static {
    futures_util::stream::unfold((file, size), |(mut f, left)| async move {
        use std::io::Read;
        if left == 0 {
            return None;
        }
        let mut buf = vec![0u8; CHUNK_BYTES.min(left as usize)];
        match f.read(&mut buf) {
            Ok(0) => None,
            Ok(n) => {
                buf.truncate(n);
                Some((Ok(Bytes::from(buf)), (f, left - n as u64)))
            }
            Err(e) => Some((Err(e), (f, 0))),
        }
    })
}

async fn session(State(sh): State<Arc<Shared>>) -> Response {
    let master_id = {
        let hb = sh.obs.board.heartbeat_consumer_1016.load(Ordering::Relaxed);
        match ((hb >> 16) & 0x7F) as u8 {
            0 => sh.setup.master_id,
            id => id,
        }
    };
    let text = match sh.session.lock() {
        Ok(s) => s.scenario_text(&sh.setup.axes[0], master_id, sh.now_us()),
        Err(_) => return error(StatusCode::INTERNAL_SERVER_ERROR, "session poisoned"),
    };
    (
        [
            (header::CONTENT_TYPE, "application/toml; charset=utf-8"),
            (
                header::CONTENT_DISPOSITION,
                "attachment; filename=\"panel-session.toml\"",
            ),
        ],
        text,
    )
        .into_response()
}

/// Most connections served at once. At the limit a new connection takes the place of the
/// oldest one that is not in a request (waiting for its first request, or idle between two):
/// idle connections cannot keep a request out; if every connection is in a request, the new
/// one is closed.
pub const MAX_CONNECTIONS: usize = 256;
/// How long a connection may take to send a request's head (start line and headers), and how
/// long it may stay idle before its next one: then it is closed. Checked before the token.
pub const HEADER_TIMEOUT: Duration = Duration::from_secs(10);
/// How long a request may take to send its body (at most [`MAX_BODY`] bytes); then 408.
pub const BODY_TIMEOUT: Duration = Duration::from_secs(10);

/// One connection, as the accept loop sees it.
struct Conn {
    id: u64,
    /// Requests in progress on it (a stream's lasts as long as the stream).
    busy: AtomicU64,
    /// Told to close (its place taken by a new connection).
    evicted: AtomicBool,
    evict: tokio::sync::Notify,
}

/// The connections served now.
#[derive(Default)]
struct Conns {
    list: Mutex<Vec<Arc<Conn>>>,
}

impl Conns {
    /// Room for one more: true if there is (after closing the oldest idle one if need be).
    fn make_room(&self) -> bool {
        let Ok(list) = self.list.lock() else {
            return false;
        };
        let closing = list
            .iter()
            .filter(|c| c.evicted.load(Ordering::Relaxed))
            .count();
        if list.len() - closing < MAX_CONNECTIONS {
            return true;
        }
        let idle = list
            .iter()
            .find(|c| c.busy.load(Ordering::Acquire) == 0 && !c.evicted.load(Ordering::Relaxed));
        match idle {
            Some(c) => {
                c.evicted.store(true, Ordering::Relaxed);
                c.evict.notify_one();
                true
            }
            None => false,
        }
    }
}

/// Keeps a connection counted busy until the response's body is done (or dropped).
struct BusyGuard(Arc<Conn>);

impl BusyGuard {
    fn new(c: &Arc<Conn>) -> Self {
        c.busy.fetch_add(1, Ordering::AcqRel);
        BusyGuard(Arc::clone(c))
    }
}

impl Drop for BusyGuard {
    fn drop(&mut self) {
        self.0.busy.fetch_sub(1, Ordering::AcqRel);
    }
}

/// Serve one accepted connection until it ends, is evicted, or the panel stops.
async fn serve_conn(
    stream: tokio::net::TcpStream,
    app: Router,
    conn: Arc<Conn>,
    conns: Arc<Conns>,
    mut stop: watch::Receiver<bool>,
) {
    use futures_util::StreamExt;
    let svc_conn = Arc::clone(&conn);
    let service = hyper::service::service_fn(move |req: hyper::Request<hyper::body::Incoming>| {
        let guard = BusyGuard::new(&svc_conn);
        let app = app.clone();
        async move {
            use hyper::service::Service;
            let svc = hyper_util::service::TowerToHyperService::new(app);
            let resp = svc.call(req.map(Body::new)).await?;
            Ok::<_, Infallible>(resp.map(|body| {
                let data = body.into_data_stream().map(move |chunk| {
                    let _keep = &guard;
                    chunk
                });
                Body::from_stream(data)
            }))
        }
    });
    let mut builder = hyper::server::conn::http1::Builder::new();
    builder
        .timer(hyper_util::rt::TokioTimer::new())
        .header_read_timeout(HEADER_TIMEOUT)
        .max_buf_size(64 << 10);
    let io = hyper_util::rt::TokioIo::new(stream);
    let c = builder.serve_connection(io, service);
    tokio::pin!(c);
    let mut shutting = false;
    loop {
        tokio::select! {
            _ = c.as_mut() => break,
            _ = conn.evict.notified(), if !shutting => break,
            _ = stop.wait_for(|v| *v), if !shutting => {
                shutting = true;
                c.as_mut().graceful_shutdown();
            }
        }
    }
    if let Ok(mut l) = conns.list.lock() {
        l.retain(|x| x.id != conn.id);
    }
}

/// Before the routes and the token: a request's body read whole within [`BODY_TIMEOUT`] and
/// [`MAX_BODY`] bytes (408 or 413 otherwise).
async fn body_deadline(State(sh): State<Arc<Shared>>, req: Request, next: Next) -> Response {
    let (parts, body) = req.into_parts();
    let read = tokio::time::timeout(BODY_TIMEOUT, axum::body::to_bytes(body, MAX_BODY)).await;
    let bytes = match read {
        Ok(Ok(b)) => b,
        Ok(Err(_)) => {
            sh.refused.fetch_add(1, Ordering::Relaxed);
            return error(
                StatusCode::PAYLOAD_TOO_LARGE,
                format!("the body is larger than {MAX_BODY} bytes (or was cut off)"),
            );
        }
        Err(_) => {
            sh.refused.fetch_add(1, Ordering::Relaxed);
            return error(
                StatusCode::REQUEST_TIMEOUT,
                format!(
                    "the body did not arrive within {} s",
                    BODY_TIMEOUT.as_secs()
                ),
            );
        }
    };
    next.run(Request::from_parts(parts, Body::from(bytes)))
        .await
}

/// Start the server thread on `listener` (already bound). It ends when the panel stops: the
/// streams close at once, other requests get 2 s to finish.
pub fn spawn(
    listener: std::net::TcpListener,
    shared: Arc<Shared>,
) -> anyhow::Result<std::thread::JoinHandle<()>> {
    listener.set_nonblocking(true)?;
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    Ok(std::thread::Builder::new()
        .name("drive-emu-panel-http".into())
        .spawn(move || {
            rt.block_on(async move {
                let listener = match tokio::net::TcpListener::from_std(listener) {
                    Ok(l) => l,
                    Err(e) => {
                        eprintln!("drive-emu: panel: cannot serve: {e}");
                        return;
                    }
                };
                let mut stop = shared.shutdown_tx.subscribe();
                let app = router(Arc::clone(&shared));
                let conns = Arc::new(Conns::default());
                let mut next_id = 0u64;
                loop {
                    let accepted = tokio::select! {
                        a = listener.accept() => a,
                        _ = stop.wait_for(|v| *v) => break,
                    };
                    let stream = match accepted {
                        Ok((s, _)) => s,
                        Err(_) => {
                            // Out of descriptors or the like: let a connection end first.
                            tokio::time::sleep(Duration::from_millis(50)).await;
                            continue;
                        }
                    };
                    if !conns.make_room() {
                        shared.refused.fetch_add(1, Ordering::Relaxed);
                        drop(stream);
                        continue;
                    }
                    let _ = stream.set_nodelay(true);
                    next_id += 1;
                    let conn = Arc::new(Conn {
                        id: next_id,
                        busy: AtomicU64::new(0),
                        evicted: AtomicBool::new(false),
                        evict: tokio::sync::Notify::new(),
                    });
                    if let Ok(mut l) = conns.list.lock() {
                        l.push(Arc::clone(&conn));
                    }
                    tokio::spawn(serve_conn(
                        stream,
                        app.clone(),
                        conn,
                        Arc::clone(&conns),
                        shared.shutdown_tx.subscribe(),
                    ));
                }
                // Stopping: the streams end on the shutdown signal; other requests get 2 s.
                let deadline = tokio::time::Instant::now() + Duration::from_secs(2);
                while conns.list.lock().map_or(0, |l| l.len()) > 0
                    && tokio::time::Instant::now() < deadline
                {
                    tokio::time::sleep(Duration::from_millis(10)).await;
                }
            });
        })?)
}
