//! Injections from the panel, and the session they make.
//!
//! A write is a JSON object with the keys of a scenario file's `[[event]]` action (`set` +
//! `value`, `sensor` (+ `counts`), `can` + `share` / `ticks` / `cob_id` / `over`), without a
//! trigger: the panel's is "now". serde reads it straight into the scenario file reader's own
//! event type ([`RawEvent`]), and the scenario's checks make its action
//! ([`crate::scenario::action_of`]: the same keys, units family, lower bounds and reasons as in
//! a file); a parameter value is also checked against the drive's own range (the scenario's
//! `param_bounds`); only then does it become an [`Injection`] queued for the loop. Every
//! injection the loop applied is kept with its time; [`Session::scenario_text`] writes them
//! as a scenario file (each action's [`Action::file_lines`]) that `drive-emu scenario` and
//! `run --scenario` replay.

use super::{PanelAxis, PanelSetup};
use crate::drive::axis_drive::AxisDrive;
use crate::presets::AxisKind;
use crate::scenario::file::RawEvent;
use crate::scenario::inject::{param_bounds, Injection};
use crate::scenario::timeline::{Action, Event, Trigger};
use crate::scenario::units::{AxisKind as KeyKind, PARAM_KEYS};
use anyhow::Result;
use serde::Deserialize;
use serde_json::{json, Map, Value};

/// Keys a panel write may carry (the actions of `[[event]]`).
const ACTION_KEYS: &[&str] = &["set", "sensor", "can", "ethercat"];
/// Keys the panel sets itself or does not take live.
const REFUSED_KEYS: &[(&str, &str)] = &[
    (
        "at",
        "the panel injects now; a time belongs in a scenario file",
    ),
    (
        "on_state",
        "the panel injects now; a condition belongs in a scenario file",
    ),
    (
        "on_emcy",
        "the panel injects now; a condition belongs in a scenario file",
    ),
    (
        "after",
        "the panel injects now; a delay belongs in a scenario file",
    ),
    ("id", "the panel names its events itself"),
    (
        "ramp",
        "the panel sets values at once; ramps belong in a scenario file",
    ),
    (
        "profile",
        "the panel sets values at once; profiles belong in a scenario file",
    ),
];
/// Most events one session keeps (the loop's marks are 16-bit).
pub const MAX_SESSION_EVENTS: usize = 10_000;

/// One control of the panel (a parameter, a sensor fault, a CAN fault) as the page shows it.
#[derive(Debug, Clone)]
pub struct ParamControl {
    pub key: &'static str,
    pub unit: &'static str,
    pub min: f64,
    pub max: f64,
    /// The value at start, in the key's unit.
    pub initial: f64,
}

/// The controls of axis 0, with their bounds.
#[derive(Debug, Clone)]
pub struct Controls {
    pub params: Vec<ParamControl>,
    rotary: bool,
    /// The run's fieldbus: its faults are the only bus faults offered.
    bus: super::PanelBus,
}

/// The unit of a parameter key, for people (the parameter registry's).
pub fn unit_of(key: &str) -> &'static str {
    drive_physics::params::find(key).map_or("", |(_, form)| form.unit)
}

impl Controls {
    /// The parameter keys of axis 0's kind (linear: mm, rotary: deg, and the ones of any
    /// axis), each with the drive's range and its value at start.
    pub fn new(setup: &PanelSetup) -> Result<Self> {
        let ax: &PanelAxis = &setup.axes[0];
        let rotary = ax.config.kind == AxisKind::Rotary;
        let mut drive = AxisDrive::from_config(&ax.config)
            .map_err(|e| anyhow::anyhow!("axis node {}: {e}", ax.node_id))?;
        let want = if rotary {
            KeyKind::Rotary
        } else {
            KeyKind::Linear
        };
        let mut params = Vec::new();
        for k in PARAM_KEYS
            .iter()
            .filter(|k| k.axis == want || k.axis == KeyKind::Any)
        {
            let initial = drive.param(k.param) / k.scale;
            let Some((min, max)) = param_bounds(&mut drive, k) else {
                continue;
            };
            params.push(ParamControl {
                key: k.key,
                unit: unit_of(k.key),
                min,
                max,
                initial,
            });
        }
        Ok(Controls {
            params,
            rotary,
            bus: setup.bus,
        })
    }

    /// The controls as the stream's `hello` lists them: the bus faults of the run's bus only
    /// (`can` on CAN, `ethercat` on EtherCAT).
    pub fn to_json(&self) -> Value {
        let mut v = json!({
            "axis": 0,
            "set": self.params.iter().map(|p| json!({
                "key": p.key, "unit": p.unit, "min": finite_or_null(p.min),
                "max": finite_or_null(p.max), "initial": p.initial,
            })).collect::<Vec<_>>(),
            "sensor": ["motor_encoder_loss", "direct_encoder_loss", "motor_encoder_glitch",
                       "direct_encoder_glitch", "restore"],
        });
        v[self.bus.key()] = match self.bus {
            super::PanelBus::Can => json!({
                "drop": {"share": [0.0, 1.0], "cob_id": "optional, 0x000..0x7FF",
                         "over": "optional time, e.g. \"5 s\""},
                "delay": {"share": [0.0, 1.0], "ticks": "whole ticks, >= 0",
                          "cob_id": "optional", "over": "optional time"},
                "sync_loss": {"over": "optional time"},
                "heartbeat_loss": {"over": "optional time"},
                "restore": {},
            }),
            super::PanelBus::Ethercat => json!({
                "lost": {"frames": "the next N frames", "share": [0.0, 1.0],
                         "over": "with share: optional time"},
                "late": {"hold": "time each frame is held, e.g. \"20 ms\"",
                         "over": "optional time"},
                "link_down": {"over": "optional time"},
                "bad_wkc": {"share": [0.0, 1.0], "over": "optional time"},
                "out_of_op": {"al_code": "optional, e.g. \"0x001A\""},
                "corrupt": {"frames": "the next N frames", "share": [0.0, 1.0],
                            "over": "with share: optional time"},
                "restore": {},
            }),
        };
        v
    }
}

fn finite_or_null(x: f64) -> Value {
    if x.is_finite() {
        json!(x)
    } else {
        Value::Null
    }
}

/// A write the panel refused: the reason, and the key at fault when there is one.
#[derive(Debug, Clone, PartialEq)]
pub struct Refused {
    pub key: Option<String>,
    pub reason: String,
}

impl Refused {
    fn new(key: Option<&str>, reason: impl Into<String>) -> Self {
        // The key and the reason may repeat the request's own text: rendered.
        Refused {
            key: key.map(crate::quote::text),
            reason: crate::quote::text_max(&reason.into(), crate::quote::MAX_MESSAGE_CHARS),
        }
    }

    pub fn to_json(&self) -> Value {
        json!({"error": self.reason, "key": self.key})
    }
}

/// A checked write: the event (as its scenario text) and what the loop is to apply.
#[derive(Debug, Clone)]
pub struct Checked {
    /// The event's keys as TOML lines (`set = "backlash_mm"`, `value = 0.05`), for the saved
    /// session.
    pub toml_lines: String,
    pub action: Action,
    pub describe: String,
}

/// A JSON value where the file reader's [`RawEvent`] takes a value with its place in the file
/// (`toml::Spanned`, which serde reads as a struct of start, end and value): the same value,
/// at place 0..0 (the panel's JSON has no lines).
fn at_no_place(v: &Value) -> Value {
    use serde_spanned::__unstable::{END_FIELD, START_FIELD, VALUE_FIELD};
    let mut m = Map::new();
    m.insert(START_FIELD.into(), json!(0));
    m.insert(END_FIELD.into(), json!(0));
    m.insert(VALUE_FIELD.into(), v.clone());
    Value::Object(m)
}

/// The write as the scenario's event type: each key read on its own first, so that a value of
/// the wrong kind (a string for a number, an unknown name) names its key.
fn raw_event(obj: &Map<String, Value>) -> Result<RawEvent, Refused> {
    // From a borrowed value: the span struct's field names are read as borrowed strings.
    let read = |m: Map<String, Value>| RawEvent::deserialize(&Value::Object(m));
    let mut all = Map::new();
    for (k, v) in obj {
        if matches!(v, Value::Null | Value::Array(_) | Value::Object(_)) {
            return Err(Refused::new(
                Some(k),
                "must be a string, a number or a boolean",
            ));
        }
        let one = Map::from_iter([(k.clone(), at_no_place(v))]);
        if let Err(e) = read(one.clone()) {
            return Err(Refused::new(Some(k), e.to_string()));
        }
        all.extend(one);
    }
    read(all).map_err(|e| Refused::new(None, e.to_string()))
}

impl Controls {
    /// Check a write (a JSON object) as the scenario parser checks an event, and against the
    /// drive's range.
    pub fn check(&self, body: &Value) -> Result<Checked, Refused> {
        let obj = body
            .as_object()
            .ok_or_else(|| Refused::new(None, "the body must be a JSON object"))?;
        for (k, why) in REFUSED_KEYS {
            if obj.contains_key(*k) {
                return Err(Refused::new(Some(k), *why));
            }
        }
        if !ACTION_KEYS.iter().any(|k| obj.contains_key(*k)) {
            return Err(Refused::new(
                None,
                format!(
                    "a write needs one of: set (with value), sensor, {}",
                    self.bus.key()
                ),
            ));
        }
        // The other bus's faults: this run has no such wire.
        for (other, bus) in [
            ("can", super::PanelBus::Can),
            ("ethercat", super::PanelBus::Ethercat),
        ] {
            if bus != self.bus && obj.contains_key(other) {
                return Err(Refused::new(
                    Some(other),
                    format!(
                        "this run is on {}: its bus faults are `{}`",
                        match self.bus {
                            super::PanelBus::Can => "CAN",
                            super::PanelBus::Ethercat => "EtherCAT",
                        },
                        self.bus.key()
                    ),
                ));
            }
        }
        let raw = raw_event(obj)?;
        let action = crate::scenario::action_of(&raw, self.rotary)
            .map_err(|e| Refused::new((!e.key.is_empty()).then_some(e.key.as_str()), e.reason))?;
        let event = Event {
            id: None,
            trigger: Trigger::At(0),
            action,
            line: 0,
        };
        if let Action::Set { key, value } = &event.action {
            let c = self
                .params
                .iter()
                .find(|p| p.key == key.key)
                .ok_or_else(|| Refused::new(Some("set"), "this drive has no such parameter"))?;
            if !(value >= &c.min && value <= &c.max) {
                return Err(Refused::new(
                    Some("value"),
                    format!(
                        "{} must be within {} .. {} {}, got {value}",
                        c.key, c.min, c.max, c.unit
                    ),
                ));
            }
        }
        Ok(Checked {
            toml_lines: event.action.file_lines(),
            describe: event.describe(),
            action: event.action,
        })
    }

    pub fn rotary(&self) -> bool {
        self.rotary
    }
}

/// What the loop is to apply for a checked write at `now_us`.
pub fn injection(c: &Checked, now_us: u64) -> Option<Injection> {
    Injection::of_action(&c.action, now_us)
}

/// One injection of the session.
#[derive(Debug, Clone)]
pub struct SessionEvent {
    pub toml_lines: String,
    pub describe: String,
    /// When the server queued it (the drive's time then), us.
    pub queued_us: u64,
    /// When the loop applied it (the drive's time), us; `None` until then.
    pub applied_us: Option<u64>,
}

/// The injections of this run, in order.
#[derive(Debug, Default)]
pub struct Session {
    pub events: Vec<SessionEvent>,
}

impl Session {
    /// The session as a scenario file: axis 0's machine (preset and overrides), the master
    /// whose heartbeat a heartbeat loss drops, and every applied injection at the drive's time
    /// it was applied; `duration` is `end_us` (the drive's time when saved), so a replay runs
    /// as long as the session did.
    pub fn scenario_text(&self, axis: &PanelAxis, master_id: u8, end_us: u64) -> String {
        let mut out = String::new();
        out += "# A drive-emu panel session: the injections made on the panel, at the drive's\n";
        out += "# simulated time each was applied. Replay it with\n";
        out += "#   drive-emu run --scenario THIS_FILE ...   (live, with your master)\n";
        out += "#   drive-emu scenario THIS_FILE            (offline; no motion program)\n";
        out += "name = \"panel-session\"\n";
        out += &format!(
            "description = \"Injections made on the live panel, node {}\"\n",
            axis.node_id
        );
        let last = self
            .events
            .iter()
            .filter_map(|e| e.applied_us)
            .max()
            .unwrap_or(0);
        out += &format!("duration = \"{} us\"\n\n", end_us.max(last + 1000));
        out += "[machine]\n";
        // A JSON string is a TOML basic string (the same escapes).
        out += &format!(
            "preset = {}\n",
            serde_json::Value::String(axis.preset.clone())
        );
        for (k, v) in &axis.overrides {
            out += &format!("{k} = {v}\n");
        }
        out += &format!(
            "\n[master]\nnode_id = {}\nmaster_id = {master_id}\n",
            axis.node_id
        );
        for e in &self.events {
            let Some(t) = e.applied_us else { continue };
            out += &format!(
                "\n[[event]]\n# {}\nat = \"{t} us\"\n{}",
                e.describe, e.toml_lines
            );
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bus::ethercat::EcatFault;
    use crate::presets::AxisConfig;

    fn setup(preset: &str) -> PanelSetup {
        PanelSetup {
            bus: crate::panel::PanelBus::Can,
            axes: vec![PanelAxis {
                node_id: 5,
                preset: preset.into(),
                config: AxisConfig::from_preset(preset).unwrap(),
                overrides: vec![],
            }],
            iface: None,
            tick_hz: 1000,
            lockstep: false,
            master_id: 0x7F,
            json_stdout: false,
        }
    }

    #[test]
    fn units_come_from_the_key_names() {
        assert_eq!(unit_of("backlash_mm"), "mm");
        assert_eq!(unit_of("backlash_deg"), "deg");
        assert_eq!(unit_of("load_force_n"), "N");
        assert_eq!(unit_of("load_torque_nm"), "N m");
        assert_eq!(unit_of("kv_per_s"), "1/s");
        assert_eq!(unit_of("stiffness_n_per_um"), "N/µm");
        assert_eq!(unit_of("speed_ti_ms"), "ms");
        assert_eq!(unit_of("direct_encoder_noise_um"), "µm");
        assert_eq!(unit_of("load_viscous_friction_n_per_m_per_s"), "N/(m/s)");
        assert_eq!(unit_of("position_from_direct"), "0 or 1");
        for k in PARAM_KEYS.iter() {
            assert!(!unit_of(k.key).is_empty());
        }
    }

    #[test]
    fn a_linear_axis_offers_mm_keys_with_the_drives_range() {
        let c = Controls::new(&setup("cnc1")).unwrap();
        let b = c.params.iter().find(|p| p.key == "backlash_mm").unwrap();
        assert_eq!(b.min, 0.0);
        assert!(b.max > 0.1 && b.max.is_finite(), "{}", b.max);
        assert!(c.params.iter().all(|p| !p.key.ends_with("_deg")));
        assert!(c.params.iter().any(|p| p.key == "kv_per_s"));
        assert!(c
            .params
            .iter()
            .all(|p| p.min <= p.initial && p.initial <= p.max));
    }

    #[test]
    fn writes_are_checked_as_scenario_events() {
        let c = Controls::new(&setup("cnc1")).unwrap();
        let ok = c
            .check(&json!({"set": "backlash_mm", "value": 0.05}))
            .unwrap();
        assert_eq!(ok.describe, "set backlash_mm = 0.05");
        assert!(matches!(ok.action, Action::Set { value, .. } if value == 0.05));
        // An integer value is a float in TOML terms.
        assert!(c.check(&json!({"set": "backlash_mm", "value": 0})).is_ok());
        let cases = [
            (
                json!({"set": "backlash_mm", "value": -0.01}),
                "value",
                "at least 0",
            ),
            (
                json!({"set": "backlash_mm", "value": 1e9}),
                "value",
                "within",
            ),
            (
                json!({"set": "backlash_deg", "value": 0.1}),
                "set",
                "linear axis",
            ),
            (
                json!({"set": "no_such_key", "value": 1.0}),
                "set",
                "unknown parameter",
            ),
            (json!({"set": "backlash_mm"}), "value", "needs `value`"),
            (
                json!({"set": "backlash_mm", "value": "x"}),
                "value",
                "invalid type",
            ),
            (
                json!({"set": "backlash_mm", "value": 1, "share": 0.5}),
                "share",
                "does not apply",
            ),
            (
                json!({"sensor": "motor_encoder_glitch"}),
                "counts",
                "needs `counts`",
            ),
            (
                json!({"can": "drop", "share": 2.0}),
                "share",
                "outside 0..1",
            ),
            (
                json!({"can": "drop", "share": 0.5, "over": 5}),
                "over",
                "no unit",
            ),
            (json!({"can": "bogus"}), "can", "unknown variant"),
            (
                json!({"ramp": "backlash_mm", "to": 0.1, "over": "1 s"}),
                "ramp",
                "at once",
            ),
            (
                json!({"at": "1 s", "set": "kv_per_s", "value": 10.0}),
                "at",
                "now",
            ),
            (json!({"value": 1.0}), "", "needs one of"),
            (json!([1, 2]), "", "JSON object"),
            (
                json!({"set": ["backlash_mm"], "value": 1.0}),
                "set",
                "string, a number",
            ),
        ];
        for (body, key, why) in cases {
            let e = c.check(&body).expect_err(&body.to_string());
            assert!(e.reason.contains(why), "{body}: {e:?}");
            if !key.is_empty() {
                assert_eq!(e.key.as_deref(), Some(key), "{body}: {e:?}");
            }
        }
        for body in [
            json!({"sensor": "motor_encoder_loss"}),
            json!({"sensor": "restore"}),
            json!({"can": "sync_loss", "over": "2 s"}),
            json!({"can": "heartbeat_loss"}),
            json!({"can": "delay", "share": 0.5, "ticks": 3, "cob_id": "0x185"}),
            json!({"can": "restore"}),
            json!({"set": "load_force_n", "value": -100.0}),
        ] {
            c.check(&body).unwrap_or_else(|e| panic!("{body}: {e:?}"));
        }
    }

    #[test]
    fn each_bus_offers_and_takes_only_its_own_faults() {
        let can = Controls::new(&setup("cnc1")).unwrap();
        let mut st = setup("cnc1");
        st.bus = crate::panel::PanelBus::Ethercat;
        let ecat = Controls::new(&st).unwrap();
        assert!(can.to_json()["can"]["sync_loss"].is_object());
        assert!(can.to_json().get("ethercat").is_none());
        assert!(ecat.to_json()["ethercat"]["out_of_op"].is_object());
        assert!(ecat.to_json().get("can").is_none());
        // The other bus's fault: refused with the key and the run's bus.
        let e = can
            .check(&json!({"ethercat": "lost", "frames": 5}))
            .unwrap_err();
        assert_eq!(e.key.as_deref(), Some("ethercat"), "{e:?}");
        assert!(e.reason.contains("on CAN"), "{e:?}");
        let e = ecat.check(&json!({"can": "sync_loss"})).unwrap_err();
        assert_eq!(e.key.as_deref(), Some("can"), "{e:?}");
        assert!(e.reason.contains("on EtherCAT"), "{e:?}");
        // Each EtherCAT fault the page sends, checked by the scenario parser.
        for (body, want) in [
            (
                json!({"ethercat": "lost", "frames": 20}),
                EcatFault::Lost {
                    frames: 20,
                    share: 0.0,
                },
            ),
            (
                json!({"ethercat": "late", "hold": "20 ms", "over": "2 s"}),
                EcatFault::Late { hold_us: 20_000 },
            ),
            (
                json!({"ethercat": "link_down", "over": "2 s"}),
                EcatFault::LinkDown,
            ),
            (
                json!({"ethercat": "bad_wkc", "over": "2 s"}),
                EcatFault::BadWkc { share: 1.0 },
            ),
            (
                json!({"ethercat": "out_of_op", "al_code": "0x001A"}),
                EcatFault::OutOfOp { al_code: 0x001A },
            ),
            (
                json!({"ethercat": "corrupt", "frames": 5}),
                EcatFault::Corrupt {
                    frames: 5,
                    share: 0.0,
                },
            ),
        ] {
            let k = ecat
                .check(&body)
                .unwrap_or_else(|e| panic!("{body}: {e:?}"));
            assert!(
                matches!(&k.action, Action::Ethercat { fault, .. } if *fault == want),
                "{body}: {:?}",
                k.action
            );
        }
        assert!(matches!(
            ecat.check(&json!({"ethercat": "restore"})).unwrap().action,
            Action::EthercatRestore
        ));
        // A bad EtherCAT write names its key, as a scenario file's would.
        let e = ecat
            .check(&json!({"ethercat": "late", "hold": "0 ms"}))
            .unwrap_err();
        assert_eq!(e.key.as_deref(), Some("hold"), "{e:?}");
    }

    #[test]
    fn a_rotary_axis_takes_deg_keys() {
        let c = Controls::new(&setup("cnc3")).unwrap();
        assert!(c.rotary());
        assert!(c
            .check(&json!({"set": "backlash_deg", "value": 0.01}))
            .is_ok());
        let e = c
            .check(&json!({"set": "backlash_mm", "value": 0.01}))
            .unwrap_err();
        assert!(e.reason.contains("rotary"), "{e:?}");
    }

    #[test]
    fn a_session_is_a_scenario_file_that_parses_back_to_the_same_events() {
        let st = setup("cnc1");
        let c = Controls::new(&st).unwrap();
        let mut s = Session::default();
        let writes = [
            (json!({"set": "backlash_mm", "value": 0.05}), 1_234_000),
            (json!({"can": "sync_loss", "over": "2 s"}), 2_000_500),
            (
                json!({"sensor": "direct_encoder_glitch", "counts": -40}),
                3_000_000,
            ),
        ];
        for (w, t) in &writes {
            let k = c.check(w).unwrap();
            s.events.push(SessionEvent {
                toml_lines: k.toml_lines,
                describe: k.describe,
                queued_us: t - 1000,
                applied_us: Some(*t),
            });
        }
        // One queued and never applied: not in the file.
        let k = c.check(&json!({"can": "restore"})).unwrap();
        s.events.push(SessionEvent {
            toml_lines: k.toml_lines,
            describe: k.describe,
            queued_us: 4_000_000,
            applied_us: None,
        });
        let mut axis = st.axes[0].clone();
        axis.overrides = vec![("backlash_mm".into(), "0.01".into())];
        let text = s.scenario_text(&axis, 0x22, 5_000_000);
        let sc = crate::scenario::parse(&text, std::path::Path::new("session.toml")).unwrap();
        assert_eq!(sc.run.duration_us, Some(5_000_000));
        assert_eq!(sc.run.master.master_id, 0x22);
        assert_eq!(sc.run.master.node_id, 5);
        assert_eq!(
            sc.machine.overrides,
            vec![("backlash_mm".into(), "0.01".into())]
        );
        let got: Vec<(String, u64)> = sc
            .events
            .iter()
            .map(|e| match e.trigger {
                crate::scenario::timeline::Trigger::At(t) => (e.describe(), t),
                _ => panic!("{:?}", e.trigger),
            })
            .collect();
        assert_eq!(
            got,
            vec![
                ("set backlash_mm = 0.05".to_string(), 1_234_000),
                (
                    "CAN: SYNC lost (no SYNC reaches the drive) for 2 s".to_string(),
                    2_000_500
                ),
                (
                    "sensor: direct encoder jumps -40 counts".to_string(),
                    3_000_000
                ),
            ]
        );
    }
}
