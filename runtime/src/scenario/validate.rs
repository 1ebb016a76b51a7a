//! From the file's serde structures to a [`Scenario`]: which keys go together, which are
//! required, units converted. Every error carries the span of the key or value at fault.

use super::expect::{Expect, Expectation};
use super::file::*;
use super::timeline::{Action, CanFault, Event, Trigger};
use super::units::AxisKind;
use super::*;
use crate::master::{MasterConfig, Step};
use crate::presets::{AxisConfig, AxisKind as PresetKind};
use std::collections::{BTreeMap, HashMap, HashSet};
use std::ops::Range;
use toml::Spanned;

struct Ctx<'a> {
    src: &'a str,
    file: &'a Path,
    /// Byte offset of every line break in `src`: a line number in O(log n), so that a file of
    /// many events is checked in O(n log n).
    breaks: Vec<usize>,
    /// Units family seen so far in the motion program: (rotary, span of the first key).
    units: Option<(bool, Range<usize>)>,
    /// The fastest velocity the motion program asks for, checked against each machine's
    /// top speed once the presets are resolved.
    fastest: Option<Fastest>,
    /// The physics tick, us (load profiles are applied once per tick).
    tick_us: u64,
}

/// A velocity key of the motion program: its value in user units per second, where it is,
/// and how it was written.
struct Fastest {
    uu_per_s: f64,
    span: Range<usize>,
    key: &'static str,
    /// User units per unit of the key.
    scale: f64,
}

/// Longest CAN delay, in ticks: 1 s at the default 1 kHz tick. A frame later than that has
/// tripped every CANopen supervision (SYNC 1.5 periods, heartbeat, SDO 1 s): it is lost, and
/// `drop` says so. Bounds the frames the fault injector holds.
pub(crate) const MAX_CAN_DELAY_TICKS: u32 = 1000;

type R<T> = Result<T, ScenarioError>;

impl Ctx<'_> {
    fn err(
        &self,
        span: Range<usize>,
        key: Option<&str>,
        reason: impl Into<String>,
    ) -> ScenarioError {
        error_at(self.src, self.file, span, key, reason)
    }
    fn line(&self, span: &Range<usize>) -> usize {
        self.breaks.partition_point(|&b| b < span.start) + 1
    }
    /// More than `cap` entries of an array of tables (`[[name]]`): an error at the first one
    /// beyond the cap, with the cap and the count.
    fn cap<T>(&self, name: &str, what: &str, items: &[Spanned<T>], cap: usize) -> R<()> {
        let Some(first_beyond) = items.get(cap) else {
            return Ok(());
        };
        let (line, column) = line_col(self.src, first_beyond.span().start);
        Err(ScenarioError {
            file: self.file.to_path_buf(),
            line,
            column,
            key: name.to_string(),
            reason: format!(
                "{} {what}, above the cap of {cap} per scenario file (this is number {})",
                items.len(),
                cap + 1
            ),
        })
    }
    /// Reject keys not in `allowed`.
    fn only(
        &self,
        present: &[(&'static str, Range<usize>)],
        allowed: &[&str],
        what: &str,
    ) -> R<()> {
        for (k, span) in present {
            if !allowed.contains(k) {
                return Err(self.err(
                    span.clone(),
                    Some(k),
                    format!(
                        "`{k}` does not apply to {what} (allowed here: {})",
                        allowed.join(", ")
                    ),
                ));
            }
        }
        Ok(())
    }
    fn unit_family(&mut self, rotary: bool, key: &str, span: Range<usize>) -> R<()> {
        match &self.units {
            Some((r, first)) if *r != rotary => Err(self.err(
                span,
                Some(key),
                format!(
                    "mixes {} units with the {} units used at line {}",
                    if rotary {
                        "rotary (deg)"
                    } else {
                        "linear (mm)"
                    },
                    if *r { "rotary (deg)" } else { "linear (mm)" },
                    self.line(first)
                ),
            )),
            Some(_) => Ok(()),
            None => {
                self.units = Some((rotary, span));
                Ok(())
            }
        }
    }
}

fn positive(ctx: &Ctx, v: &Spanned<f64>, key: &str) -> R<f64> {
    let x = *v.get_ref();
    if !(x.is_finite() && x > 0.0) {
        return Err(ctx.err(
            v.span(),
            Some(key),
            format!("must be a positive number, got {x}"),
        ));
    }
    Ok(x)
}

fn finite(ctx: &Ctx, v: &Spanned<f64>, key: &str) -> R<f64> {
    let x = *v.get_ref();
    if !x.is_finite() {
        return Err(ctx.err(v.span(), Some(key), "must be a finite number"));
    }
    Ok(x)
}

/// Exactly one of the given optional keys: returns its index.
fn exactly_one(
    ctx: &Ctx,
    at: Range<usize>,
    keys: &[(&'static str, Option<Range<usize>>)],
    what: &str,
) -> R<usize> {
    let given: Vec<usize> = (0..keys.len()).filter(|&i| keys[i].1.is_some()).collect();
    let names = keys.iter().map(|k| k.0).collect::<Vec<_>>().join(", ");
    match given.as_slice() {
        [i] => Ok(*i),
        [] => Err(ctx.err(at, Some(keys[0].0), format!("{what} needs one of: {names}"))),
        [_, j, ..] => Err(ctx.err(
            keys[*j].1.clone().unwrap(),
            Some(keys[*j].0),
            format!("{what} takes only one of: {names}"),
        )),
    }
}

fn mode(m: ModeName) -> i8 {
    m.value()
}

/// Velocity (uu/s) from whichever velocity key is present.
fn velocity(ctx: &mut Ctx, s: &RawStep, required: bool, signed: bool) -> R<Option<f64>> {
    let keys = [
        ("velocity_mm_min", &s.velocity_mm_min, 1000.0 / 60.0, false),
        ("velocity_mm_s", &s.velocity_mm_s, 1000.0, false),
        ("velocity_deg_s", &s.velocity_deg_s, 1000.0, true),
        ("velocity_deg_min", &s.velocity_deg_min, 1000.0 / 60.0, true),
        ("velocity_uu_s", &s.velocity_uu_s, 1.0, false),
    ];
    let spans: Vec<_> = keys
        .iter()
        .map(|k| (k.0, k.1.as_ref().map(|v| v.span())))
        .collect();
    if !required && spans.iter().all(|s| s.1.is_none()) {
        return Ok(None);
    }
    let i = exactly_one(ctx, s.step.span(), &spans, "this step")?;
    let (key, v, scale, rotary) = keys[i];
    let v = v.as_ref().unwrap();
    if key != "velocity_uu_s" {
        ctx.unit_family(rotary, key, v.span())?;
    }
    let x = if signed {
        finite(ctx, v, key)?
    } else {
        positive(ctx, v, key)?
    };
    let uu_per_s = x * scale;
    if ctx
        .fastest
        .as_ref()
        .is_none_or(|f| uu_per_s.abs() > f.uu_per_s)
    {
        ctx.fastest = Some(Fastest {
            uu_per_s: uu_per_s.abs(),
            span: v.span(),
            key,
            scale,
        });
    }
    Ok(Some(uu_per_s))
}

fn accel(ctx: &mut Ctx, s: &RawStep) -> R<f64> {
    let keys = [
        ("accel_mm_s2", &s.accel_mm_s2, false),
        ("accel_deg_s2", &s.accel_deg_s2, true),
        ("accel_uu_s2", &s.accel_uu_s2, false),
    ];
    let spans: Vec<_> = keys
        .iter()
        .map(|k| (k.0, k.1.as_ref().map(|v| v.span())))
        .collect();
    let i = exactly_one(ctx, s.step.span(), &spans, "this step")?;
    let (key, v, rotary) = keys[i];
    let v = v.as_ref().unwrap();
    if key == "accel_uu_s2" {
        return positive(ctx, v, key);
    }
    ctx.unit_family(rotary, key, v.span())?;
    Ok(positive(ctx, v, key)? * 1000.0)
}

fn required<'a, T>(
    ctx: &Ctx,
    v: &'a Option<Spanned<T>>,
    key: &str,
    at: &Spanned<StepKind>,
) -> R<&'a T> {
    v.as_ref().map(|x| x.get_ref()).ok_or_else(|| {
        ctx.err(
            at.span(),
            Some(key),
            format!("a `{}` step needs `{key}`", step_name(at.get_ref())),
        )
    })
}

/// The velocity keys a step may carry (one at a time).
const VELOCITY_KEYS: &[&str] = &[
    "velocity_mm_min",
    "velocity_mm_s",
    "velocity_deg_s",
    "velocity_deg_min",
    "velocity_uu_s",
];
/// The acceleration keys a step may carry (one at a time).
const ACCEL_KEYS: &[&str] = &["accel_mm_s2", "accel_deg_s2", "accel_uu_s2"];

/// The motion program: each step checked and appended to `out`; a `repeat` unrolled.
fn steps(
    ctx: &mut Ctx,
    raw: &[Spanned<RawStep>],
    out: &mut Vec<ProgramStep>,
    depth: usize,
) -> R<()> {
    for s in raw {
        step(ctx, s.get_ref(), out, depth)?;
    }
    Ok(())
}

/// One step: only the keys its kind takes, converted; appended to `out`.
fn step(ctx: &mut Ctx, s: &RawStep, out: &mut Vec<ProgramStep>, depth: usize) -> R<()> {
    let kind = *s.step.get_ref();
    let present = s.present();
    let what = format!("a `{}` step", step_name(&kind));
    match kind {
        StepKind::Enable | StepKind::SetMode => {
            ctx.only(&present, &["mode"], &what)?;
            let m = mode(*required(ctx, &s.mode, "mode", &s.step)?);
            out.push(ProgramStep::Master(if kind == StepKind::Enable {
                Step::Enable { mode: m }
            } else {
                Step::SetMode { mode: m }
            }));
        }
        StepKind::MoveTo => {
            ctx.only(
                &present,
                &[
                    VELOCITY_KEYS,
                    ACCEL_KEYS,
                    &["target_mm", "target_deg", "target_uu"],
                ]
                .concat(),
                &what,
            )?;
            out.push(move_to_step(ctx, s, &what)?);
        }
        StepKind::Cruise => {
            ctx.only(
                &present,
                &[VELOCITY_KEYS, ACCEL_KEYS, &["duration"]].concat(),
                &what,
            )?;
            let v = velocity(ctx, s, true, true)?.unwrap();
            let a = accel(ctx, s)?;
            let d = duration_us(ctx, s)?;
            out.push(ProgramStep::Master(Step::Cruise {
                velocity_uu_s: v,
                accel_uu_s2: a,
                duration_s: d as f64 * 1e-6,
            }));
        }
        StepKind::Dwell | StepKind::Idle => {
            ctx.only(&present, &["duration"], &what)?;
            let d = duration_us(ctx, s)?;
            out.push(if kind == StepKind::Dwell {
                ProgramStep::Master(Step::Dwell {
                    duration_s: d as f64 * 1e-6,
                })
            } else {
                ProgramStep::Idle { duration_us: d }
            });
        }
        StepKind::WriteSdo => {
            ctx.only(&present, &["index", "sub", "value", "len"], &what)?;
            out.push(write_sdo_step(ctx, s)?);
        }
        StepKind::StopHeartbeat | StepKind::StopSync | StepKind::Disable => {
            ctx.only(&present, &[], &what)?;
            out.push(ProgramStep::Master(match kind {
                StepKind::StopHeartbeat => Step::StopHeartbeat,
                StepKind::StopSync => Step::StopSync,
                _ => Step::Disable,
            }));
        }
        StepKind::Repeat => {
            ctx.only(&present, &["times", "body"], &what)?;
            repeat_step(ctx, s, out, depth)?;
        }
    }
    Ok(())
}

/// A step's `duration`, us (> 0).
fn duration_us(ctx: &Ctx, s: &RawStep) -> R<u64> {
    let d = required(ctx, &s.duration, "duration", &s.step)?;
    if d.us() == 0 {
        return Err(ctx.err(
            s.duration.as_ref().unwrap().span(),
            Some("duration"),
            "must be longer than 0 s",
        ));
    }
    Ok(d.us())
}

/// `move_to`: one target key (mm, deg or uu) within the 32-bit range, velocity, acceleration.
fn move_to_step(ctx: &mut Ctx, s: &RawStep, what: &str) -> R<ProgramStep> {
    let targets = [
        ("target_mm", s.target_mm.as_ref().map(|v| v.span())),
        ("target_deg", s.target_deg.as_ref().map(|v| v.span())),
        ("target_uu", s.target_uu.as_ref().map(|v| v.span())),
    ];
    let i = exactly_one(ctx, s.step.span(), &targets, what)?;
    let (key, t, scale) = match i {
        0 => ("target_mm", s.target_mm.as_ref().unwrap(), 1000.0),
        1 => ("target_deg", s.target_deg.as_ref().unwrap(), 1000.0),
        _ => ("target_uu", s.target_uu.as_ref().unwrap(), 1.0),
    };
    if i < 2 {
        ctx.unit_family(i == 1, key, t.span())?;
    }
    let uu = finite(ctx, t, key)? * scale;
    if uu.abs() > i32::MAX as f64 {
        return Err(ctx.err(t.span(), Some(key), "outside the 32-bit position range"));
    }
    let v = velocity(ctx, s, true, false)?.unwrap();
    let a = accel(ctx, s)?;
    Ok(ProgramStep::Master(Step::MoveTo {
        target_uu: uu.round() as i32,
        velocity_uu_s: v.round().max(1.0) as u32,
        accel_uu_s2: a.round().max(1.0) as u32,
    }))
}

/// `write_sdo`: index, sub (default 0), value and a length of 1, 2 or 4 bytes.
fn write_sdo_step(ctx: &Ctx, s: &RawStep) -> R<ProgramStep> {
    let index = *required(ctx, &s.index, "index", &s.step)?;
    let value = *required(ctx, &s.value, "value", &s.step)?;
    let len = *required(ctx, &s.len, "len", &s.step)?;
    if !matches!(len, 1 | 2 | 4) {
        return Err(ctx.err(
            s.len.as_ref().unwrap().span(),
            Some("len"),
            "must be 1, 2 or 4 bytes",
        ));
    }
    Ok(ProgramStep::Master(Step::WriteSdo {
        index,
        sub: s.sub.as_ref().map_or(0, |x| *x.get_ref()),
        value: value as u32,
        len,
    }))
}

/// `repeat`: the body checked once and appended `times` times (at most 4 deep, at most
/// [`MAX_PROGRAM_STEPS`] in the program).
fn repeat_step(ctx: &mut Ctx, s: &RawStep, out: &mut Vec<ProgramStep>, depth: usize) -> R<()> {
    let times = *required(ctx, &s.times, "times", &s.step)?;
    let body = s.body.as_ref().ok_or_else(|| {
        ctx.err(
            s.step.span(),
            Some("body"),
            "a `repeat` step needs `body`, a list of steps",
        )
    })?;
    if body.is_empty() || times == 0 {
        return Err(ctx.err(
            s.step.span(),
            Some("body"),
            "a `repeat` needs times >= 1 and a non-empty body",
        ));
    }
    if depth > 3 {
        return Err(ctx.err(s.step.span(), Some("body"), "repeats nest at most 4 deep"));
    }
    let mut inner = Vec::new();
    steps(ctx, body, &mut inner, depth + 1)?;
    let total = out.len() as u64 + inner.len() as u64 * u64::from(times);
    if total > MAX_PROGRAM_STEPS as u64 {
        return Err(ctx.err(
            s.times.as_ref().unwrap().span(),
            Some("times"),
            format!(
                "the program would have {total} steps with this repeat unrolled, above the cap \
                 of {MAX_PROGRAM_STEPS}"
            ),
        ));
    }
    for _ in 0..times {
        out.extend(inner.iter().cloned());
    }
    Ok(())
}

fn param_value(ctx: &Ctx, key: &ParamKey, v: &Spanned<f64>, name: &str) -> R<f64> {
    let x = finite(ctx, v, name)?;
    if x < key.min {
        return Err(ctx.err(
            v.span(),
            Some(name),
            format!("{} must be at least {}, got {x}", key.key, key.min),
        ));
    }
    Ok(x)
}

/// The span of an optional key, if given.
fn span_of<T>(v: &Option<Spanned<T>>) -> Option<Range<usize>> {
    v.as_ref().map(|x| x.span())
}

/// `what` needs `key`: an error at the event (`at`) when it is not `given`.
fn need(ctx: &Ctx, at: &Range<usize>, given: Option<Range<usize>>, key: &str, what: &str) -> R<()> {
    if given.is_none() {
        return Err(ctx.err(at.clone(), Some(key), format!("{what} needs `{key}`")));
    }
    Ok(())
}

/// One `[[event]]`: its trigger, its action, and the action's parameter in the program's
/// units family.
fn event(ctx: &mut Ctx, e: &Spanned<RawEvent>) -> R<Event> {
    let span = e.span();
    let e = e.get_ref();
    let trigger = event_trigger(ctx, e, &span)?;
    let action = event_action(ctx, e, &span)?;
    // Parameter keys must fit the program's units family.
    if let Action::Set { key, .. } | Action::Ramp { key, .. } | Action::Profile { key, .. } =
        &action
    {
        let name_span = span_of(&e.set)
            .or(span_of(&e.ramp))
            .or(span_of(&e.profile))
            .unwrap();
        if key.axis != AxisKind::Any {
            ctx.unit_family(key.axis == AxisKind::Rotary, key.key, name_span)?;
        }
    }
    Ok(Event {
        id: e.id.as_ref().map(|i| i.get_ref().clone()),
        trigger,
        action,
        line: ctx.line(&span),
    })
}

/// `at`, or `on_state` / `on_emcy` with an optional `after` delay.
fn event_trigger(ctx: &Ctx, e: &RawEvent, span: &Range<usize>) -> R<Trigger> {
    let trig = exactly_one(
        ctx,
        span.clone(),
        &[
            ("at", span_of(&e.at)),
            ("on_state", span_of(&e.on_state)),
            ("on_emcy", span_of(&e.on_emcy)),
        ],
        "an event",
    )?;
    let delay = e.after.as_ref().map_or(0, |a| a.get_ref().us());
    if trig == 0 {
        if let Some(a) = &e.after {
            return Err(ctx.err(
                a.span(),
                Some("after"),
                "`after` delays a condition (on_state, on_emcy); with `at` give the time directly",
            ));
        }
    }
    Ok(match trig {
        0 => Trigger::At(e.at.as_ref().unwrap().get_ref().us()),
        1 => Trigger::OnState {
            state: e.on_state.as_ref().unwrap().get_ref().0,
            delay_us: delay,
        },
        _ => Trigger::OnEmcy {
            code: e.on_emcy.as_ref().unwrap().get_ref().0,
            delay_us: delay,
        },
    })
}

/// An event's action from outside a file (the live panel's JSON, read into the same
/// [`RawEvent`] as a file's `[[event]]`): the same keys, checks and reasons, on an axis that is
/// `rotary` or linear. No trigger (the caller's is "now"); an error names the key, with no
/// line (there is none).
pub(super) fn action_of(raw: &RawEvent, rotary: bool) -> R<Action> {
    let ctx = Ctx {
        src: "",
        file: Path::new("panel"),
        breaks: Vec::new(),
        units: None,
        fastest: None,
        tick_us: 1000,
    };
    let action = event_action(&ctx, raw, &(0..0))?;
    if let Action::Set { key, .. } | Action::Ramp { key, .. } | Action::Profile { key, .. } =
        &action
    {
        if key.axis != AxisKind::Any && (key.axis == AxisKind::Rotary) != rotary {
            let name = [
                ("set", &raw.set),
                ("ramp", &raw.ramp),
                ("profile", &raw.profile),
            ]
            .into_iter()
            .find_map(|(n, v)| v.as_ref().map(|_| n));
            return Err(ctx.err(
                0..0,
                name,
                format!(
                    "`{}` is a {} key: this is a {}",
                    key.key,
                    if rotary {
                        "linear (mm)"
                    } else {
                        "rotary (deg)"
                    },
                    if rotary {
                        "rotary axis (deg)"
                    } else {
                        "linear axis (mm)"
                    }
                ),
            ));
        }
    }
    Ok(action)
}

/// The keys an event gives for its action (besides the action's own name).
fn event_action_keys(e: &RawEvent) -> Vec<(&'static str, Range<usize>)> {
    let mut present: Vec<(&'static str, Range<usize>)> = Vec::new();
    macro_rules! p {
        ($($f:ident),*) => {$( if let Some(x) = &e.$f { present.push((stringify!($f), x.span())); } )*};
    }
    p!(
        value,
        from,
        to,
        over,
        shape,
        mean,
        amplitude,
        frequency_hz,
        counts,
        share,
        ticks,
        cob_id,
        frames,
        hold,
        al_code
    );
    present
}

/// One of `set`, `ramp`, `profile`, `sensor`, `can`, with only the keys it takes.
fn event_action(ctx: &Ctx, e: &RawEvent, span: &Range<usize>) -> R<Action> {
    let which = exactly_one(
        ctx,
        span.clone(),
        &[
            ("set", span_of(&e.set)),
            ("ramp", span_of(&e.ramp)),
            ("profile", span_of(&e.profile)),
            ("sensor", span_of(&e.sensor)),
            ("can", span_of(&e.can)),
            ("ethercat", span_of(&e.ethercat)),
        ],
        "an event",
    )?;
    let present = event_action_keys(e);
    match which {
        0 => {
            ctx.only(&present, &["value"], "a `set` event")?;
            need(ctx, span, span_of(&e.value), "value", "a `set` event")?;
            let key = e.set.as_ref().unwrap().get_ref().0;
            Ok(Action::Set {
                key,
                value: param_value(ctx, key, e.value.as_ref().unwrap(), "value")?,
            })
        }
        1 => {
            ctx.only(&present, &["from", "to", "over"], "a `ramp` event")?;
            need(ctx, span, span_of(&e.to), "to", "a `ramp` event")?;
            need(ctx, span, span_of(&e.over), "over", "a `ramp` event")?;
            let key = e.ramp.as_ref().unwrap().get_ref().0;
            Ok(Action::Ramp {
                key,
                from: e
                    .from
                    .as_ref()
                    .map(|f| param_value(ctx, key, f, "from"))
                    .transpose()?,
                to: param_value(ctx, key, e.to.as_ref().unwrap(), "to")?,
                over_us: e.over.as_ref().unwrap().get_ref().us(),
            })
        }
        2 => profile_action(ctx, e, span, &present),
        3 => sensor_action(ctx, e, span, &present),
        4 => can_action(ctx, e, span, &present),
        _ => ethercat_action(ctx, e, span, &present),
    }
}

/// `ethercat`: lost frames (`frames`, or `share` with `over`), a late cycle (`hold`), the
/// link down, bad working counters (`share`), a slave out of OP (`al_code`), or restore.
fn ethercat_action(
    ctx: &Ctx,
    e: &RawEvent,
    span: &Range<usize>,
    present: &[(&'static str, Range<usize>)],
) -> R<Action> {
    use crate::bus::ethercat::{EcatFault, MAX_HOLD_US};
    let kind = *e.ethercat.as_ref().unwrap().get_ref();
    let over_us = e.over.as_ref().map(|o| o.get_ref().us());
    let share = e.share.as_ref().map(|s| s.get_ref().0);
    let fault = match kind {
        EcatKind::Lost | EcatKind::Corrupt => {
            let what = if kind == EcatKind::Lost {
                "lost EtherCAT frames"
            } else {
                "corrupted EtherCAT frames"
            };
            ctx.only(present, &["frames", "share", "over"], what)?;
            let (frames, share) = match (&e.frames, share) {
                (Some(f), None) => {
                    if let Some(o) = &e.over {
                        return Err(ctx.err(
                            o.span(),
                            Some("over"),
                            "`frames` counts the frames; `over` goes with `share`",
                        ));
                    }
                    if *f.get_ref() == 0 {
                        return Err(ctx.err(
                            f.span(),
                            Some("frames"),
                            "0 frames: give at least 1 (or `share` with `over`)",
                        ));
                    }
                    (*f.get_ref(), 0.0)
                }
                (None, Some(share)) => (0, share),
                _ => {
                    return Err(ctx.err(
                        e.ethercat.as_ref().unwrap().span(),
                        Some("ethercat"),
                        format!("{what} take either `frames` (the next N frames) or `share` (0..1 of the frames, with `over`), not both nor neither"),
                    ))
                }
            };
            if kind == EcatKind::Lost {
                EcatFault::Lost { frames, share }
            } else {
                EcatFault::Corrupt { frames, share }
            }
        }
        EcatKind::Late => {
            ctx.only(present, &["hold", "over"], "a late EtherCAT cycle")?;
            need(ctx, span, span_of(&e.hold), "hold", "a late EtherCAT cycle")?;
            let hold = e.hold.as_ref().unwrap();
            let hold_us = hold.get_ref().us();
            if hold_us == 0 || hold_us > MAX_HOLD_US {
                return Err(ctx.err(
                    hold.span(),
                    Some("hold"),
                    format!(
                        "{} us: a late cycle holds a frame for more than 0 and at most {} s (a frame later than that is lost to every master: use `ethercat = \"lost\"`)",
                        hold_us,
                        MAX_HOLD_US / 1_000_000
                    ),
                ));
            }
            EcatFault::Late { hold_us }
        }
        EcatKind::LinkDown => {
            ctx.only(present, &["over"], "an EtherCAT link down")?;
            EcatFault::LinkDown
        }
        EcatKind::BadWkc => {
            ctx.only(present, &["share", "over"], "bad EtherCAT working counters")?;
            EcatFault::BadWkc {
                share: share.unwrap_or(1.0),
            }
        }
        EcatKind::OutOfOp => {
            ctx.only(present, &["al_code"], "a slave out of OP")?;
            let al_code = match &e.al_code {
                Some(c) if c.get_ref().0 == 0 => {
                    return Err(ctx.err(
                        c.span(),
                        Some("al_code"),
                        "AL status code 0 means no error: give the code the slave reports (ETG.1000.6, e.g. \"0x001A\" synchronization error)",
                    ))
                }
                Some(c) => c.get_ref().0,
                // ETG.1000.6: unspecified error
                None => 0x0001,
            };
            EcatFault::OutOfOp { al_code }
        }
        EcatKind::Restore => {
            ctx.only(present, &[], "an EtherCAT restore")?;
            return Ok(Action::EthercatRestore);
        }
    };
    Ok(Action::Ethercat { fault, over_us })
}

/// `profile`: a periodic parameter (shape, mean, amplitude, frequency, optional duration).
fn profile_action(
    ctx: &Ctx,
    e: &RawEvent,
    span: &Range<usize>,
    present: &[(&'static str, Range<usize>)],
) -> R<Action> {
    ctx.only(
        present,
        &["shape", "mean", "amplitude", "frequency_hz", "over"],
        "a `profile` event",
    )?;
    need(
        ctx,
        span,
        span_of(&e.amplitude),
        "amplitude",
        "a `profile` event",
    )?;
    need(
        ctx,
        span,
        span_of(&e.frequency_hz),
        "frequency_hz",
        "a `profile` event",
    )?;
    let key = e.profile.as_ref().unwrap().get_ref().0;
    Ok(Action::Profile {
        key,
        shape: e
            .shape
            .as_ref()
            .map_or(ProfileShape::Sine, |s| *s.get_ref()),
        mean: e
            .mean
            .as_ref()
            .map(|m| finite(ctx, m, "mean"))
            .transpose()?
            .unwrap_or(0.0),
        amplitude: finite(ctx, e.amplitude.as_ref().unwrap(), "amplitude")?,
        frequency_hz: profile_frequency(ctx, e.frequency_hz.as_ref().unwrap())?,
        over_us: e.over.as_ref().map(|o| o.get_ref().us()),
    })
}

/// A profile's frequency: positive and below half the rate at which it is applied (once per
/// tick): at or above that its samples alias into a slower force than the one asked for.
fn profile_frequency(ctx: &Ctx, v: &Spanned<f64>) -> R<f64> {
    let f = positive(ctx, v, "frequency_hz")?;
    let nyquist_hz = 0.5e6 / ctx.tick_us as f64;
    if f >= nyquist_hz {
        return Err(ctx.err(
            v.span(),
            Some("frequency_hz"),
            format!(
                "{} Hz: a load profile is applied once per tick ({} us, {} Hz), so it must \
                 stay below {nyquist_hz} Hz, half that rate (above, its samples describe a \
                 slower force); a shorter [master] tick_us raises the limit",
                number(f),
                ctx.tick_us,
                1e6 / ctx.tick_us as f64
            ),
        ));
    }
    Ok(f)
}

/// `sensor`: an encoder glitch (with `counts`) or another sensor fault (no keys).
fn sensor_action(
    ctx: &Ctx,
    e: &RawEvent,
    span: &Range<usize>,
    present: &[(&'static str, Range<usize>)],
) -> R<Action> {
    let kind = *e.sensor.as_ref().unwrap().get_ref();
    let glitch = matches!(
        kind,
        SensorKind::MotorEncoderGlitch | SensorKind::DirectEncoderGlitch
    );
    if glitch {
        ctx.only(present, &["counts"], "an encoder glitch")?;
        need(ctx, span, span_of(&e.counts), "counts", "an encoder glitch")?;
    } else {
        ctx.only(present, &[], "this sensor event")?;
    }
    Ok(Action::Sensor {
        kind,
        counts: e.counts.as_ref().map_or(0, |c| *c.get_ref()),
    })
}

/// `can`: drop, delay, SYNC or heartbeat loss (each with its keys), or restore.
fn can_action(
    ctx: &Ctx,
    e: &RawEvent,
    span: &Range<usize>,
    present: &[(&'static str, Range<usize>)],
) -> R<Action> {
    let kind = *e.can.as_ref().unwrap().get_ref();
    let over_us = e.over.as_ref().map(|o| o.get_ref().us());
    let cob = e.cob_id.as_ref().map(|c| c.get_ref().0);
    let share = e.share.as_ref().map(|s| s.get_ref().0);
    Ok(match kind {
        CanKind::Drop => {
            ctx.only(present, &["share", "cob_id", "over"], "a CAN drop")?;
            need(ctx, span, span_of(&e.share), "share", "a CAN drop")?;
            Action::Can {
                fault: CanFault::Drop {
                    share: share.unwrap(),
                    cob_id: cob,
                },
                over_us,
            }
        }
        CanKind::Delay => {
            ctx.only(
                present,
                &["share", "ticks", "cob_id", "over"],
                "a CAN delay",
            )?;
            need(ctx, span, span_of(&e.share), "share", "a CAN delay")?;
            need(ctx, span, span_of(&e.ticks), "ticks", "a CAN delay")?;
            let ticks = e.ticks.as_ref().unwrap();
            if *ticks.get_ref() > MAX_CAN_DELAY_TICKS {
                return Err(ctx.err(
                    ticks.span(),
                    Some("ticks"),
                    format!(
                        "{} ticks: a CAN delay is at most {MAX_CAN_DELAY_TICKS} ticks ({} s at \
                         this file's {} us tick); a frame later than that has tripped every \
                         supervision (SYNC, heartbeat, SDO timeout): use `can = \"drop\"`",
                        ticks.get_ref(),
                        f64::from(MAX_CAN_DELAY_TICKS) * ctx.tick_us as f64 * 1e-6,
                        ctx.tick_us
                    ),
                ));
            }
            Action::Can {
                fault: CanFault::Delay {
                    share: share.unwrap(),
                    ticks: *ticks.get_ref(),
                    cob_id: cob,
                },
                over_us,
            }
        }
        CanKind::SyncLoss | CanKind::HeartbeatLoss => {
            ctx.only(present, &["over"], "a CAN loss")?;
            Action::Can {
                fault: if kind == CanKind::SyncLoss {
                    CanFault::SyncLoss
                } else {
                    CanFault::HeartbeatLoss
                },
                over_us,
            }
        }
        CanKind::Restore => {
            ctx.only(present, &[], "a CAN restore")?;
            Action::CanRestore
        }
    })
}

/// An optional time key, us.
fn time_us(v: &Option<Spanned<Time>>) -> Option<u64> {
    v.as_ref().map(|t| t.get_ref().us())
}

/// One `[[expect]]`: exactly one kind, with only the keys that kind takes.
fn expectation(ctx: &mut Ctx, x: &Spanned<RawExpect>, ids: &HashSet<String>) -> R<Expect> {
    let span = x.span();
    let x = x.get_ref();
    let kinds = [
        ("emcy", span_of(&x.emcy)),
        ("no_emcy", span_of(&x.no_emcy)),
        ("state", span_of(&x.state)),
        ("following_error_max_mm", span_of(&x.following_error_max_mm)),
        (
            "following_error_max_deg",
            span_of(&x.following_error_max_deg),
        ),
        ("verdict", span_of(&x.verdict)),
        ("frequency_hz", span_of(&x.frequency_hz)),
        (
            "frequency_over_kv_min",
            span_of(&x.frequency_over_kv_min).or(span_of(&x.frequency_over_kv_max)),
        ),
        ("program", span_of(&x.program)),
    ];
    let which = exactly_one(ctx, span.clone(), &kinds, "an expectation")?;
    let present = expectation_keys(x, which);
    check_window_order(ctx, x)?;
    let what = match which {
        0 => emcy_expectation(ctx, x, &present, ids)?,
        1 => {
            ctx.only(&present, &["from", "until"], "a `no_emcy` expectation")?;
            if !*x.no_emcy.as_ref().unwrap().get_ref() {
                return Err(ctx.err(
                    span_of(&x.no_emcy).unwrap(),
                    Some("no_emcy"),
                    "write `no_emcy = true` or leave it out",
                ));
            }
            Expectation::NoEmcy {
                from_us: time_us(&x.from).unwrap_or(0),
                until_us: time_us(&x.until),
            }
        }
        2 => {
            ctx.only(&present, &["at"], "a `state` expectation")?;
            Expectation::State {
                state: x.state.as_ref().unwrap().get_ref().0,
                at_us: time_us(&x.at),
            }
        }
        3 | 4 => following_error_expectation(ctx, x, &present, which == 4)?,
        5 => {
            ctx.only(&present, &["by", "not_before"], "a `verdict` expectation")?;
            Expectation::Verdict {
                verdict: *x.verdict.as_ref().unwrap().get_ref(),
                by_us: time_us(&x.by),
                not_before_us: time_us(&x.not_before),
            }
        }
        6 => {
            ctx.only(&present, &["tolerance_pct"], "a `frequency_hz` expectation")?;
            Expectation::FrequencyHz {
                hz: positive(ctx, x.frequency_hz.as_ref().unwrap(), "frequency_hz")?,
                tolerance_pct: x
                    .tolerance_pct
                    .as_ref()
                    .map(|v| positive(ctx, v, "tolerance_pct"))
                    .transpose()?
                    .unwrap_or(5.0),
            }
        }
        7 => frequency_over_kv_expectation(ctx, x, &present)?,
        _ => {
            ctx.only(&present, &[], "a `program` expectation")?;
            Expectation::Program(*x.program.as_ref().unwrap().get_ref())
        }
    };
    Ok(Expect {
        what,
        line: ctx.line(&span),
    })
}

/// The keys an expectation gives besides its kind (`which`, an index into the kinds).
fn expectation_keys(x: &RawExpect, which: usize) -> Vec<(&'static str, Range<usize>)> {
    let mut present: Vec<(&'static str, Range<usize>)> = Vec::new();
    macro_rules! p {
        ($($f:ident),*) => {$( if let Some(v) = &x.$f { present.push((stringify!($f), v.span())); } )*};
    }
    p!(
        within,
        after,
        at,
        from,
        until,
        by,
        not_before,
        tolerance_pct
    );
    // frequency_over_kv_max belongs to the frequency_over_kv kind (index 7).
    if which != 7 {
        p!(frequency_over_kv_max);
    }
    present
}

/// `from` .. `until` must not be an empty window.
fn check_window_order(ctx: &Ctx, x: &RawExpect) -> R<()> {
    if let (Some(f), Some(u)) = (&x.from, &x.until) {
        if u.get_ref() < f.get_ref() {
            return Err(ctx.err(
                u.span(),
                Some("until"),
                format!(
                    "`until` ({} s) is before `from` ({} s): the window would be empty",
                    u.get_ref().secs(),
                    f.get_ref().secs()
                ),
            ));
        }
    }
    Ok(())
}

/// `emcy`: a code, optionally `within` a time `after` a named event.
fn emcy_expectation(
    ctx: &Ctx,
    x: &RawExpect,
    present: &[(&'static str, Range<usize>)],
    ids: &HashSet<String>,
) -> R<Expectation> {
    ctx.only(present, &["within", "after"], "an `emcy` expectation")?;
    if let Some(a) = &x.after {
        if !ids.contains(a.get_ref()) {
            return Err(ctx.err(
                a.span(),
                Some("after"),
                format!("no event has id `{}`", a.get_ref()),
            ));
        }
    }
    Ok(Expectation::Emcy {
        code: x.emcy.as_ref().unwrap().get_ref().0,
        within_us: time_us(&x.within),
        after: x.after.as_ref().map(|a| a.get_ref().clone()),
    })
}

/// `following_error_max_mm` / `_deg` (in the program's units family) over a window.
fn following_error_expectation(
    ctx: &mut Ctx,
    x: &RawExpect,
    present: &[(&'static str, Range<usize>)],
    rotary: bool,
) -> R<Expectation> {
    ctx.only(present, &["from", "until"], "a following-error expectation")?;
    let (key, v) = if rotary {
        (
            "following_error_max_deg",
            x.following_error_max_deg.as_ref().unwrap(),
        )
    } else {
        (
            "following_error_max_mm",
            x.following_error_max_mm.as_ref().unwrap(),
        )
    };
    ctx.unit_family(rotary, key, v.span())?;
    Ok(Expectation::FollowingError {
        max_uu: positive(ctx, v, key)? * 1000.0,
        from_us: time_us(&x.from).unwrap_or(0),
        until_us: time_us(&x.until),
    })
}

/// `frequency_over_kv_min` / `_max`: a band (either side open), min <= max.
fn frequency_over_kv_expectation(
    ctx: &Ctx,
    x: &RawExpect,
    present: &[(&'static str, Range<usize>)],
) -> R<Expectation> {
    ctx.only(present, &[], "a `frequency_over_kv` expectation")?;
    let min = x
        .frequency_over_kv_min
        .as_ref()
        .map(|v| finite(ctx, v, "frequency_over_kv_min"))
        .transpose()?;
    let max = x
        .frequency_over_kv_max
        .as_ref()
        .map(|v| finite(ctx, v, "frequency_over_kv_max"))
        .transpose()?;
    let (min, max) = (min.unwrap_or(0.0), max.unwrap_or(f64::INFINITY));
    if min > max {
        return Err(ctx.err(
            span_of(&x.frequency_over_kv_min).unwrap(),
            Some("frequency_over_kv_min"),
            "is above frequency_over_kv_max",
        ));
    }
    Ok(Expectation::FrequencyOverKv { min, max })
}

/// The whole file: name, machine, master and timing, program, events, expectations, then
/// the presets resolved with the overrides, then the detector (errors in that order).
pub(super) fn validate(raw: RawScenario, src: &str, file: &Path) -> R<Scenario> {
    let mut ctx = Ctx {
        src,
        file,
        breaks: src.match_indices('\n').map(|(i, _)| i).collect(),
        units: None,
        fastest: None,
        tick_us: 1000,
    };
    ctx.cap("event", "events", &raw.event, MAX_EVENTS)?;
    ctx.cap("expect", "expectations", &raw.expect, MAX_EXPECTATIONS)?;
    ctx.cap("motion", "motion steps", &raw.motion, MAX_PROGRAM_STEPS)?;
    let name = scenario_name(&ctx, &raw.name)?;
    let m = raw.machine.get_ref();
    let presets = machine_presets(&ctx, &raw.machine)?;
    let overrides = m
        .overrides
        .iter()
        .map(|(k, v)| (k.to_string(), v.get_ref().to_string()))
        .collect();
    let (master, tick_us) = master_timing(&ctx, &raw.master, raw.machine.span())?;
    ctx.tick_us = tick_us;
    let program = motion_program(&mut ctx, &raw.motion)?;
    let (events, ids) = events(&mut ctx, &raw.event)?;
    if let Some(d) = &raw.duration {
        events_before_the_end(&ctx, &raw.event, &events, d)?;
    }
    let mut expectations = Vec::new();
    for x in &raw.expect {
        expectations.push(expectation(&mut ctx, x, &ids)?);
    }
    let configs = resolve_presets(&ctx, m, &presets)?;
    let detector = detector_spec(&ctx, &raw.detector)?;
    Ok(Scenario {
        name,
        description: raw.description,
        path: file.to_path_buf(),
        machine: MachineSpec {
            presets,
            overrides,
            configs,
            rotary_units: ctx.units.as_ref().map(|u| u.0),
        },
        run: RunSpec {
            master,
            tick_us,
            seed: raw.seed.unwrap_or(1),
            duration_us: raw.duration.map(|d| d.get_ref().us()),
            fast_forward_idle: raw.fast_forward_idle.unwrap_or(true),
        },
        program,
        events,
        expectations,
        detector,
    })
}

/// The scenario's name: it names the output directory.
fn scenario_name(ctx: &Ctx, raw: &Spanned<String>) -> R<String> {
    let name = raw.get_ref().trim().to_string();
    if name.is_empty()
        || !name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.')
    {
        return Err(ctx.err(
            raw.span(),
            Some("name"),
            "must be non-empty and use only letters, digits, - _ . (it names the output directory)",
        ));
    }
    Ok(name)
}

/// `preset`, or a non-empty `presets` list for a sweep.
fn machine_presets(ctx: &Ctx, machine: &Spanned<RawMachine>) -> R<Vec<String>> {
    let m = machine.get_ref();
    match (&m.preset, &m.presets) {
        (Some(p), None) => Ok(vec![p.get_ref().clone()]),
        (None, Some(ps)) if !ps.get_ref().is_empty() => {
            Ok(ps.get_ref().iter().map(|p| p.get_ref().clone()).collect())
        }
        (None, _) => Err(ctx.err(
            machine.span(),
            Some("machine.preset"),
            "[machine] needs `preset` (or a non-empty `presets` list for a sweep)",
        )),
        (Some(_), Some(ps)) => Err(ctx.err(
            ps.span(),
            Some("machine.presets"),
            "give `preset` or `presets`, not both",
        )),
    }
}

/// `[master]` over the defaults, and the tick (a divisor of the SYNC period), us. Errors
/// point at `[machine]` (`at`): `[master]` is optional and may have no span.
fn master_timing(ctx: &Ctx, mr: &RawMaster, at: Range<usize>) -> R<(MasterConfig, u64)> {
    let d = MasterConfig::default();
    let master = MasterConfig {
        node_id: mr.node_id.unwrap_or(d.node_id),
        master_id: mr.master_id.unwrap_or(d.master_id),
        sync_period_us: mr.sync_period_us.unwrap_or(d.sync_period_us),
        heartbeat_ms: mr.heartbeat_ms.unwrap_or(d.heartbeat_ms),
        drive_heartbeat_ms: mr.drive_heartbeat_ms.unwrap_or(d.drive_heartbeat_ms),
        step_timeout_us: mr.step_timeout.map_or(d.step_timeout_us, |t| t.us()),
        sdo_timeout_us: d.sdo_timeout_us,
        position_loop: mr
            .position_loop
            .as_ref()
            .map(|p| crate::master::outer_loop::PositionLoop {
                kv_per_s: p.kv_per_s,
                encoder: p
                    .encoder
                    .unwrap_or(crate::master::outer_loop::LoopEncoder::Direct),
            }),
    };
    if let Some(p) = &master.position_loop {
        if !(p.kv_per_s.is_finite() && p.kv_per_s > 0.0 && p.kv_per_s <= 1000.0) {
            return Err(ctx.err(
                at,
                Some("master.position_loop.kv_per_s"),
                "a position-loop gain in 1/s, more than 0 and at most 1000",
            ));
        }
    }
    if !(1..=127).contains(&master.node_id) || !(1..=127).contains(&master.master_id) {
        return Err(ctx.err(at, Some("master.node_id"), "node IDs are 1..127"));
    }
    if master.sync_period_us < 100 {
        return Err(ctx.err(at, Some("master.sync_period_us"), "at least 100 us"));
    }
    let tick_us = u64::from(mr.tick_us.unwrap_or(master.sync_period_us));
    if tick_us == 0 || u64::from(master.sync_period_us) % tick_us != 0 {
        return Err(ctx.err(at, Some("master.tick_us"), "must divide the SYNC period"));
    }
    Ok((master, tick_us))
}

/// The `[[motion]]` steps, unrolled; a non-empty program starts with `enable`.
fn motion_program(ctx: &mut Ctx, motion: &[Spanned<RawStep>]) -> R<Vec<ProgramStep>> {
    let mut program = Vec::new();
    steps(ctx, motion, &mut program, 0)?;
    if program.len() > MAX_PROGRAM_STEPS {
        let at = motion.last().map(|s| s.span()).unwrap_or(0..0);
        return Err(ctx.err(
            at,
            Some("motion"),
            format!(
                "the program has {} steps with every repeat unrolled, above the cap of \
                 {MAX_PROGRAM_STEPS}",
                program.len()
            ),
        ));
    }
    if !matches!(
        program.first(),
        Some(ProgramStep::Master(Step::Enable { .. }))
    ) && !program.is_empty()
    {
        let at = motion.first().map(|s| s.span()).unwrap_or(0..0);
        return Err(ctx.err(
            at,
            Some("motion[0].step"),
            "the motion program must start with an `enable` step",
        ));
    }
    Ok(program)
}

/// The `[[event]]`s and their ids (each used once); timed ramps of one parameter must not
/// overlap.
fn events(ctx: &mut Ctx, raw: &[Spanned<RawEvent>]) -> R<(Vec<Event>, HashSet<String>)> {
    let mut events = Vec::new();
    let mut ids = HashSet::new();
    let mut ramps = RampSchedule::default();
    for e in raw {
        let ev = event(ctx, e)?;
        if let Some(id) = &ev.id {
            if !ids.insert(id.clone()) {
                let sp = e.get_ref().id.as_ref().unwrap().span();
                return Err(ctx.err(sp, Some("id"), format!("event id `{id}` used twice")));
            }
        }
        ramps.add(ctx, e.span(), &ev)?;
        events.push(ev);
    }
    Ok((events, ids))
}

/// Every event can fire before the scenario's `duration` ends the run: one timed at or
/// after the end, or delayed by that much after its condition, would never fire.
fn events_before_the_end(
    ctx: &Ctx,
    raw: &[Spanned<RawEvent>],
    events: &[Event],
    duration: &Spanned<Time>,
) -> R<()> {
    let end_us = duration.get_ref().us();
    for (e, ev) in raw.iter().zip(events) {
        let (key, span, t) = match ev.trigger {
            Trigger::At(t) => ("at", span_of(&e.get_ref().at), t),
            Trigger::OnState { delay_us, .. } | Trigger::OnEmcy { delay_us, .. } => {
                ("after", span_of(&e.get_ref().after), delay_us)
            }
        };
        if t >= end_us {
            let what = if key == "at" {
                format!("{} s is", t as f64 * 1e-6)
            } else {
                format!("a delay of {} s after its condition is", t as f64 * 1e-6)
            };
            return Err(ctx.err(
                span.unwrap_or_else(|| e.span()),
                Some(key),
                format!(
                    "{what} at or after the scenario's end (duration = {} s, line {}): the \
                     event would never fire",
                    end_us as f64 * 1e-6,
                    ctx.line(&duration.span())
                ),
            ));
        }
    }
    Ok(())
}

/// The timed ramps accepted so far, per parameter: start -> (latest end of a ramp starting
/// there, its line). Accepted ramps of one parameter do not overlap, so a new one can only
/// overlap the one starting last before its end: O(log n) per ramp.
#[derive(Default)]
struct RampSchedule(HashMap<&'static str, BTreeMap<u64, (u64, usize)>>);

impl RampSchedule {
    /// Two timed ramps of one parameter that overlap would fight over its value.
    fn add(&mut self, ctx: &Ctx, at: Range<usize>, ev: &Event) -> R<()> {
        let (Trigger::At(t), Action::Ramp { key, over_us, .. }) = (&ev.trigger, &ev.action) else {
            return Ok(());
        };
        let (b0, b1) = (*t, t.saturating_add(*over_us));
        let starts = self.0.entry(key.key).or_default();
        if let Some((&a0, &(a1, line))) = starts.range(..b1).next_back() {
            if b0 < a1 {
                return Err(ctx.err(
                    at,
                    Some("ramp"),
                    format!(
                        "ramp of `{}` from {} s to {} s overlaps the ramp at line {line} ({} \
                         s to {} s): one parameter can follow one ramp at a time",
                        key.key,
                        b0 as f64 * 1e-6,
                        b1 as f64 * 1e-6,
                        a0 as f64 * 1e-6,
                        a1 as f64 * 1e-6
                    ),
                ));
            }
        }
        let end = starts.entry(b0).or_insert((b1, ev.line));
        if b1 > end.0 {
            *end = (b1, ev.line);
        }
        Ok(())
    }
}

/// Every preset with the overrides, so a bad value is reported here, with its line; each
/// preset's kind must fit the program's units family.
fn resolve_presets(ctx: &Ctx, m: &RawMachine, presets: &[String]) -> R<Vec<AxisConfig>> {
    let mut configs = Vec::new();
    for (i, p) in presets.iter().enumerate() {
        let pspan = match (&m.preset, &m.presets) {
            (Some(s), _) => s.span(),
            (_, Some(list)) => list.get_ref()[i].span(),
            _ => unreachable!(),
        };
        let key = if m.preset.is_some() {
            "preset"
        } else {
            "presets"
        };
        let mut cfg =
            AxisConfig::from_preset(p).map_err(|e| ctx.err(pspan.clone(), Some(key), e.reason))?;
        for (k, v) in &m.overrides {
            cfg = cfg
                .with_override(k, &v.get_ref().to_string())
                .map_err(|e| ctx.err(v.span(), Some(k), format!("{} (preset {p})", e.reason)))?;
        }
        if let Some(f) = &ctx.fastest {
            let top = cfg
                .max_speed_uu_per_s()
                .map_err(|e| ctx.err(pspan.clone(), Some(key), format!("{e} (preset {p})")))?;
            if f.uu_per_s > top {
                return Err(ctx.err(
                    f.span.clone(),
                    Some(f.key),
                    format!(
                        "{} is beyond the top speed of the {p} axis, {} {} (its motor's \
                         max_speed_rpm = {} through the transmission): the drive would only \
                         trip on overspeed or following error",
                        number(f.uu_per_s / f.scale),
                        number(round_sig(top / f.scale)),
                        match f.key {
                            "velocity_mm_min" => "mm/min",
                            "velocity_mm_s" => "mm/s",
                            "velocity_deg_s" => "deg/s",
                            "velocity_deg_min" => "deg/min",
                            _ => "uu/s",
                        },
                        cfg.max_speed_rpm
                    ),
                ));
            }
        }
        let rotary = cfg.kind == PresetKind::Rotary;
        if let Some((r, first)) = &ctx.units {
            if *r != rotary {
                return Err(ctx.err(
                    pspan,
                    Some(key),
                    format!(
                        "preset {p} is a {} axis but the file uses {} units at line {} (use the *_uu keys for sweeps over both kinds)",
                        if rotary { "rotary" } else { "linear" },
                        if *r { "rotary (deg)" } else { "linear (mm)" },
                        ctx.line(first)
                    ),
                ));
            }
        }
        configs.push(cfg);
    }
    Ok(configs)
}

/// `[detector]`: optional thresholds (suspect <= alarm) and windows.
fn detector_spec(ctx: &Ctx, rd: &RawDetector) -> R<DetectorSpec> {
    let pos =
        |v: &Option<Spanned<f64>>, k: &str| v.as_ref().map(|v| positive(ctx, v, k)).transpose();
    let detector = DetectorSpec {
        enabled: rd.enabled.unwrap_or(true),
        kv_per_s: pos(&rd.kv_per_s, "kv_per_s")?,
        suspect_um: pos(&rd.suspect_um, "suspect_um")?,
        alarm_um: pos(&rd.alarm_um, "alarm_um")?,
        min_window_s: rd.min_window.as_ref().map(|t| t.get_ref().secs()),
        settle_s: rd.settle.as_ref().map(|t| t.get_ref().secs()),
        confirm_windows: rd
            .confirm_windows
            .as_ref()
            .map(|c| (*c.get_ref()).max(1) as usize),
    };
    if let (Some(s), Some(a)) = (detector.suspect_um, detector.alarm_um) {
        if s > a {
            return Err(ctx.err(
                rd.suspect_um.as_ref().unwrap().span(),
                Some("detector.suspect_um"),
                "is above alarm_um",
            ));
        }
    }
    Ok(detector)
}

/// A step's name as written in the file (`write_sdo`, `move_to`, ...).
fn step_name(k: &StepKind) -> &'static str {
    match k {
        StepKind::Enable => "enable",
        StepKind::SetMode => "set_mode",
        StepKind::MoveTo => "move_to",
        StepKind::Cruise => "cruise",
        StepKind::Dwell => "dwell",
        StepKind::Idle => "idle",
        StepKind::WriteSdo => "write_sdo",
        StepKind::StopHeartbeat => "stop_heartbeat",
        StepKind::StopSync => "stop_sync",
        StepKind::Disable => "disable",
        StepKind::Repeat => "repeat",
    }
}

/// A value rounded to 4 significant digits, for messages.
fn round_sig(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let p = 10f64.powi(3 - x.abs().log10().floor() as i32);
    (x * p).round() / p
}

/// A number for messages: plain where it reads well, else in exponent form (`1e300`, not
/// three hundred digits).
fn number(x: f64) -> String {
    if x == 0.0 || (1e-4..1e9).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}
