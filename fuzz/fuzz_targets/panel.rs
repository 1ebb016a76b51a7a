//! Any bytes as a request to the live panel (`run --panel`), through everything the panel
//! parses of it before and after the token: the cross-site checks on the method and headers,
//! the token offered (`Authorization: Bearer`, `X-Panel-Token`, `?token=`), the JSON body of
//! an injection (`POST /api/inject`, checked as a scenario event and against the drive's
//! range) and of a recording command (`POST /api/record`), and a recording's file name
//! (`GET /api/record/file/NAME`). Never a panic; the token is accepted only when offered
//! exactly; a refusal's reason and key are clean lines (the request's own text quoted); an
//! accepted write sets a parameter the panel offers, within its range, and its event text
//! is TOML that the session file parses back.
//!
//! Input: `method byte, headers (name: value lines), 0, query, 0, body, 0, file name`.
//! Run: cargo fuzz run --sanitizer none --debug-assertions panel.
#![no_main]

use axum::http::{HeaderMap, HeaderName, HeaderValue, Method, StatusCode};
use drive_emu::panel::auth::{offered, Auth};
use drive_emu::panel::control::Controls;
use drive_emu::panel::record::is_served_name;
use drive_emu::panel::server::{cross_site_refusal, parse_json_body, record_action, RecordAction};
use drive_emu::panel::{PanelAxis, PanelBus, PanelSetup};
use drive_emu::presets::AxisConfig;
use drive_emu::scenario::timeline::Action;
use drive_protocol_fuzz::assert_clean_message;
use libfuzzer_sys::fuzz_target;
use std::sync::OnceLock;

const TOKEN: &str = "tok-Fuzz_123";

/// The controls of a CAN run (`ethercat == false`) or of `run --ethercat`, and what they offer.
fn controls(ethercat: bool) -> &'static (Controls, serde_json::Value) {
    static C: [OnceLock<(Controls, serde_json::Value)>; 2] = [OnceLock::new(), OnceLock::new()];
    C[usize::from(ethercat)].get_or_init(|| {
        let setup = PanelSetup {
            bus: if ethercat {
                PanelBus::Ethercat
            } else {
                PanelBus::Can
            },
            axes: vec![PanelAxis {
                node_id: 5,
                preset: "cnc1".into(),
                config: AxisConfig::from_preset("cnc1").expect("preset cnc1"),
                overrides: vec![],
            }],
            iface: None,
            tick_hz: 1000,
            lockstep: false,
            master_id: 0x7F,
            json_stdout: false,
        };
        let c = Controls::new(&setup).expect("controls of cnc1");
        let j = c.to_json();
        (c, j)
    })
}

fuzz_target!(|data: &[u8]| {
    let Some((&m, rest)) = data.split_first() else {
        return;
    };
    let mut parts = rest.splitn(4, |&b| b == 0);
    let head = parts.next().unwrap_or_default();
    let query = parts.next().map(String::from_utf8_lossy);
    let body = parts.next().unwrap_or_default();
    let name = String::from_utf8_lossy(parts.next().unwrap_or_default());

    let method = if m & 1 == 0 {
        Method::GET
    } else {
        Method::POST
    };
    let mut headers = HeaderMap::new();
    for line in head.split(|&b| b == b'\n') {
        let Some(colon) = line.iter().position(|&b| b == b':') else {
            continue;
        };
        let (Ok(n), Ok(v)) = (
            HeaderName::from_bytes(&line[..colon]),
            HeaderValue::from_bytes(line[colon + 1..].trim_ascii()),
        ) else {
            continue;
        };
        headers.append(n, v);
    }

    // Before the token: the cross-site checks, with and without a token.
    for required in [false, true] {
        if let Some((status, why)) = cross_site_refusal(required, &method, &headers) {
            assert!(
                status == StatusCode::FORBIDDEN || status == StatusCode::UNSUPPORTED_MEDIA_TYPE,
                "{status}"
            );
            assert_clean_message("cross-site refusal", why);
        }
    }

    // The token: accepted exactly when the one offered is the panel's.
    let offer = offered(&headers, query.as_deref());
    let auth = Auth::new(Some(TOKEN.to_string()));
    match auth.check(offer) {
        Ok(()) => assert_eq!(offer, Some(TOKEN)),
        Err(why) => {
            assert_ne!(offer, Some(TOKEN));
            assert_clean_message("token refusal", why);
        }
    }
    assert!(Auth::new(None).check(offer).is_ok());

    // The body, as an injection and as a recording command.
    let v = match parse_json_body(body) {
        Ok(v) => v,
        Err(why) => {
            assert_clean_message("body", &why);
            return;
        }
    };
    let ethercat = m & 2 != 0;
    let (controls, offered_json) = controls(ethercat);
    match controls.check(&v) {
        Err(r) => {
            assert_clean_message("injection refusal", &r.reason);
            if let Some(k) = &r.key {
                assert_clean_message("injection refusal key", k);
            }
        }
        Ok(c) => {
            assert_clean_message("injection", &c.describe);
            // only the run's own bus's faults get through
            let bus = if ethercat { "ethercat" } else { "can" };
            assert!(
                c.action.bus().is_none_or(|b| b == bus),
                "a {bus} run took {:?}",
                c.action
            );
            c.toml_lines
                .parse::<toml::Table>()
                .unwrap_or_else(|e| panic!("event text {:?}: {e}", c.toml_lines));
            if let Action::Set { key, value } = &c.action {
                let p = offered_json["set"]
                    .as_array()
                    .and_then(|a| a.iter().find(|p| p["key"] == key.key))
                    .unwrap_or_else(|| panic!("{} is not offered", key.key));
                assert!(value.is_finite(), "{} = {value}", key.key);
                if let (Some(lo), Some(hi)) = (p["min"].as_f64(), p["max"].as_f64()) {
                    assert!(
                        (lo..=hi).contains(value),
                        "{} = {value}, not in {lo}..{hi}",
                        key.key
                    );
                }
            }
        }
    }
    match record_action(&v) {
        Ok(a) => {
            let want = if a == RecordAction::Start {
                "start"
            } else {
                "stop"
            };
            assert_eq!(v, serde_json::json!({ "action": want }));
        }
        Err(reply) => assert!(reply["error"].is_string()),
    }

    // A recording's name: served only if it is one of the panel's own names.
    if is_served_name(&name) {
        assert!(name.starts_with("rec-") && !name.contains('/') && !name.contains('\0'));
    }
});
