//! Wall time of the one-hour CNC1 wear ramp (scenarios/cnc1-wear-ramp.toml): offline run with
//! recording, detector and expectation checks (no plots), three repetitions.
//!
//! `cargo bench -p drive-emu --bench wear_ramp` (budget: 7 s, i.e. 500x real time).

use drive_emu::scenario::{self, runner};
use std::path::Path;
use std::time::Instant;

fn main() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/cnc1-wear-ramp.toml");
    let s = scenario::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let opts = runner::RunOptions {
        progress: false,
        ..Default::default()
    };
    let mut walls = Vec::new();
    for _ in 0..3 {
        let t = Instant::now();
        let out = runner::run(&s, &opts).unwrap();
        let wall = t.elapsed().as_secs_f64();
        let r = &out.runs[0];
        println!(
            "wear ramp: scenario {:.0} s, physical {:.1} s, fast-forwarded {:.0} s, wall {wall:.2} s \
             ({:.0}x real time), passed {}",
            r.scenario_s,
            r.physical_s,
            r.fast_forwarded_s,
            r.scenario_s / wall,
            out.passed
        );
        walls.push(wall);
    }
    walls.sort_by(f64::total_cmp);
    println!(
        "wear ramp wall time: min {:.2} s, median {:.2} s (budget 7 s)",
        walls[0], walls[1]
    );
}
