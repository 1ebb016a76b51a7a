//! Frame turnaround of the sans-IO line: one process-data frame (an LRW of the whole image,
//! as SOEM sends it every cycle) in, through `Segment::process`, and out, with 1, 16 and 64
//! slaves in OP, each cycle followed by the drives' cycle (`Segment::cycle`) as at a 1 kHz
//! cycle (1 ms of drive time per frame; the bench does not sleep between cycles). Prints the
//! p50 / p99 / max of the turnaround (the frame alone, not the drives' cycle) per line
//! length.
//!
//! cargo bench -p drive-ethercat --bench turnaround

#[path = "../tests/common/mod.rs"]
mod common;

use std::time::Instant;

use common::{op, outputs};

const CYCLES: usize = 20_000;
const WARM_UP: usize = 2_000;

fn percentile(sorted: &[u64], p: f64) -> u64 {
    let k = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[k]
}

fn main() {
    // `cargo test --benches` runs this too: keep that short
    let quick = std::env::args().any(|a| a == "--test");
    let cycles = if quick { 200 } else { CYCLES };
    println!("slaves  frame bytes  p50 us  p99 us  max us  ({cycles} cycles of 1 ms)");
    for n in [1usize, 16, 64] {
        let (mut m, o, i) = op(n);
        let mut image = vec![0u8; o + i];
        for k in 0..n {
            image[6 * k..6 * k + 6].copy_from_slice(&outputs(0x0F, 0));
        }
        let mut frame = drive_ethercat::frame::build([0x01; 6], &[(12, 0, 0, &image)]);
        let template = frame.clone();
        let mut times = Vec::with_capacity(cycles);
        for c in 0..WARM_UP.min(cycles) + cycles {
            frame.copy_from_slice(&template);
            m.now_ns += 1_000_000;
            let t = Instant::now();
            m.seg
                .process(&mut frame, m.now_ns, &mut m.drives)
                .expect("the frame comes back");
            let dt = t.elapsed().as_nanos() as u64;
            if c >= WARM_UP.min(cycles) {
                times.push(dt);
            }
            let us = m.now_ns / 1000;
            m.seg.cycle(drive_protocol::Clocks::same(us), &mut m.drives);
        }
        let back = drive_ethercat::frame::read_back(&frame).unwrap();
        assert_eq!(back[0].wkc as usize, 3 * n, "every slave in OP");
        times.sort_unstable();
        println!(
            "{n:>6}  {:>11}  {:>6.2}  {:>6.2}  {:>6.2}",
            frame.len(),
            percentile(&times, 0.5) as f64 / 1000.0,
            percentile(&times, 0.99) as f64 / 1000.0,
            *times.last().unwrap() as f64 / 1000.0
        );
    }
}
