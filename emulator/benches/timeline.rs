//! Cost of a scenario's timeline against its number of events (issue 23: it used to look at
//! every event at every step, and the file check counted lines from the start for every
//! event, so 10^4 events took seconds and 10^5 minutes).
//!
//! `cargo bench -p drive-emu --bench timeline` prints, for 10^3, 10^4 and 10^5 events:
//! - the timeline alone: ns per step over 10 000 steps of 1 ms, the events spread over
//!   them (one in ten conditional, on a state or an EMCY code);
//! - a whole scenario file of that many events (`set` events spread over a 5 s cruise):
//!   parse and check, and the offline run (5000 ticks), wall seconds.

use drive_emu::scenario::timeline::{Action, Event, Observation, Timeline, Trigger};
use drive_emu::scenario::{self, runner};
use drive_protocol::Cia402State;
use std::path::Path;
use std::time::Instant;

const STEPS: u64 = 10_000;
const STEP_US: u64 = 1000;

fn events(n: usize) -> Vec<Event> {
    (0..n)
        .map(|i| {
            let t = i as u64 * STEPS * STEP_US / n as u64;
            let trigger = match i % 20 {
                0 => Trigger::OnState {
                    state: Cia402State::OperationEnabled,
                    delay_us: t,
                },
                10 => Trigger::OnEmcy {
                    code: 0x8100 + (i % 7) as u16,
                    delay_us: t / 2,
                },
                _ => Trigger::At(t),
            };
            Event {
                id: None,
                trigger,
                action: Action::CanRestore,
                line: i + 1,
            }
        })
        .collect()
}

/// ns per step, best of three passes.
fn timeline_ns_per_step(n: usize) -> (f64, usize) {
    let evs = events(n);
    let mut best = f64::INFINITY;
    let mut fired = 0;
    for _ in 0..3 {
        let mut tl = Timeline::new(evs.clone());
        let t0 = Instant::now();
        fired = 0;
        for step in 0..STEPS {
            let codes = [0x8100 + (step % 11) as u16];
            let obs = Observation {
                state: (step > 100).then_some(Cia402State::OperationEnabled),
                new_emcy: if step % 500 == 0 { &codes } else { &[] },
            };
            fired += tl.due(step * STEP_US, &obs).count();
        }
        best = best.min(t0.elapsed().as_secs_f64() * 1e9 / STEPS as f64);
    }
    (best, fired)
}

fn scenario_text(n: usize) -> String {
    let mut s = String::from(
        "name = \"bench\"\n[machine]\npreset = \"cnc1\"\n[[motion]]\nstep = \"enable\"\n\
         mode = \"csp\"\n[[motion]]\nstep = \"cruise\"\nvelocity_mm_min = 600.0\n\
         accel_mm_s2 = 500.0\nduration = \"5 s\"\n",
    );
    for i in 0..n {
        let t = 5_000_000 * i as u64 / n as u64;
        s += &format!(
            "[[event]]\nat = \"{t} us\"\nset = \"load_force_n\"\nvalue = {}.0\n",
            i % 50
        );
    }
    s
}

fn main() {
    println!("events  timeline ns/step  fired   file MB  parse+check s  run s");
    for n in [1_000usize, 10_000, 100_000] {
        let (ns, fired) = timeline_ns_per_step(n);
        let text = scenario_text(n);
        let t0 = Instant::now();
        let s = scenario::parse(&text, Path::new("bench.toml")).unwrap_or_else(|e| panic!("{e}"));
        let parse_s = t0.elapsed().as_secs_f64();
        let opts = runner::RunOptions {
            progress: false,
            ..Default::default()
        };
        let t0 = Instant::now();
        let out = runner::run(&s, &opts).unwrap();
        let run_s = t0.elapsed().as_secs_f64();
        assert!(out.passed, "{:?}", out.runs[0].unfinished);
        println!(
            "{n:>6}  {ns:>16.0}  {fired:>6}  {:>7.1}  {parse_s:>13.2}  {run_s:>5.2}",
            text.len() as f64 / 1e6
        );
    }
}
