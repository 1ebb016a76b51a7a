//! `drive-emu analyze CAPTURE --ballbar X,Y` (issue 31, item 3): the ballbar's figures from
//! a candump capture of a master interpolating the circle on two drives in CSP.
//!
//! The capture here is written from an offline ballbar run, frame by frame as a master and
//! two drives with the default PDO mapping would put it on the bus (per position cycle: each
//! node's RPDO2 with controlword and target position 0x607A, SYNC, each node's TPDO2 with
//! statusword and position 0x6064, in um): what the analysis must find from the command alone
//! (centre, radius, passes, data circles, ramps) the offline run knows from its plan. Claim:
//! the figures from the capture equal the offline run's within the bus' 1 um resolution (G,
//! radius deviation and every reversal spike within 2 um, the backlash estimates within
//! 2 um), over two gaps; and a capture without a full circle both ways, or one whose data
//! circle does not start at +X, is refused with why.

use std::process::Command;
use std::sync::atomic::AtomicBool;

use drive_emu::analysis::ballbar::{run, BallbarAxis, BallbarRun, BallbarSetup};
use drive_emu::presets::AxisConfig;

const RADIUS_MM: f64 = 20.0;
const FEED_MM_MIN: f64 = 2000.0;

fn offline(backlash_mm: f64) -> BallbarRun {
    let cfg = AxisConfig::from_preset("cnc1")
        .and_then(|c| {
            c.with_overrides(
                [
                    format!("backlash_mm={backlash_mm}"),
                    "position_from_direct=false".to_string(),
                    // guideway friction that holds the load on its flank until the axis
                    // reverses, as tests/ballbar.rs (docs/ballbar.md)
                    "load_coulomb_friction_n=150".to_string(),
                ]
                .iter()
                .map(String::as_str),
            )
        })
        .unwrap();
    let axis = |name: &str| BallbarAxis {
        name: name.into(),
        config: cfg.clone(),
        backlash_comp_mm: 0.0,
    };
    let setup = BallbarSetup {
        axes: [axis("X"), axis("Y")],
        radius_mm: RADIUS_MM,
        feed_mm_per_min: FEED_MM_MIN,
    };
    run(&setup, &AtomicBool::new(false)).unwrap()
}

/// The run as a candump -L log: nodes 5 (X) and 6 (Y), 1 ms SYNC, positions in um; the
/// measured path is the direct encoder, sent as 0x6064 (a drive whose loop is on it).
fn capture_of(r: &BallbarRun, skip_rows: usize) -> String {
    let t = &r.trace;
    let um = |mm: f64| (mm * 1000.0).round() as i32;
    let hex = |b: &[u8]| b.iter().map(|x| format!("{x:02X}")).collect::<String>();
    let mut out = String::new();
    let mut stamp = 1_700_000_000_000_000u64;
    let mut line = |cob: u16, data: &[u8], stamp: &mut u64| {
        *stamp += 50;
        out += &format!(
            "({}.{:06}) vcan0 {cob:03X}#{}\n",
            *stamp / 1_000_000,
            *stamp % 1_000_000,
            hex(data)
        );
    };
    for i in skip_rows..t.len() {
        for (node, cmd) in [(5u16, t.x_cmd_mm[i]), (6, t.y_cmd_mm[i])] {
            let mut d = 0x0Fu16.to_le_bytes().to_vec();
            d.extend(um(cmd).to_le_bytes());
            line(0x300 + node, &d, &mut stamp);
        }
        line(0x080, &[], &mut stamp);
        for (node, pos) in [(5u16, t.x_mm[i]), (6, t.y_mm[i])] {
            let mut d = 0x1237u16.to_le_bytes().to_vec();
            d.extend(um(pos).to_le_bytes());
            line(0x280 + node, &d, &mut stamp);
        }
        stamp += 1000 - 250;
    }
    out
}

fn analyze(log: &str, name: &str) -> (Option<i32>, serde_json::Value, String) {
    let dir = std::env::temp_dir().join(format!("drive-emu-bbcap-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, log).unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .args([
            "analyze",
            path.to_str().unwrap(),
            "--ballbar",
            "5,6",
            "--json",
        ])
        .args(["--radius-mm", &RADIUS_MM.to_string()])
        .output()
        .unwrap();
    let _ = std::fs::remove_file(&path);
    let json = serde_json::from_slice(&o.stdout).unwrap_or(serde_json::Value::Null);
    (
        o.status.code(),
        json,
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn the_figures_from_a_capture_equal_those_of_the_run_it_records() {
    let mut failures = Vec::new();
    for backlash_mm in [0.0, 0.03] {
        let r = offline(backlash_mm);
        let (code, j, err) = analyze(&capture_of(&r, 0), &format!("bb-{backlash_mm}.log"));
        assert_eq!(code, Some(0), "{err}");
        let rep = &j["report"];
        assert!(
            (j["radius_mm"].as_f64().unwrap() - RADIUS_MM).abs() < 1e-3,
            "fitted radius {}",
            j["radius_mm"]
        );
        assert_eq!(j["passes"], 2);
        let near = |what: String, got: f64, want: f64| {
            if (got - want).abs() > 2.0 {
                Some(format!(
                    "gap {backlash_mm}: {what}: {got:.2} from the capture, {want:.2} offline"
                ))
            } else {
                None
            }
        };
        for (dir, off) in [("cw", &r.report.cw), ("ccw", &r.report.ccw)] {
            let d = &rep[dir];
            failures.extend(near(
                format!("{dir} G"),
                d["circular_deviation_um"].as_f64().unwrap(),
                off.circular_deviation_um,
            ));
            failures.extend(near(
                format!("{dir} radius deviation"),
                d["radius_deviation_um"].as_f64().unwrap(),
                off.radius_deviation_um,
            ));
            for axis in ["X", "Y"] {
                for k in 0..2 {
                    failures.extend(near(
                        format!("{dir} spike {axis}[{k}]"),
                        d["reversal_spikes_um"][axis][k].as_f64().unwrap(),
                        off.reversal_spikes_um[axis][k],
                    ));
                }
            }
        }
        for axis in ["X", "Y"] {
            failures.extend(near(
                format!("estimate {axis} (um)"),
                rep["backlash_estimate_mm"][axis].as_f64().unwrap() * 1e3,
                r.report.backlash_estimate_mm[axis] * 1e3,
            ));
        }
        if backlash_mm > 0.0 {
            // the worn axes' spikes are there to be found (the offline test's own claim)
            let est = rep["backlash_estimate_mm"]["X"].as_f64().unwrap();
            assert!(
                est > 0.5 * backlash_mm,
                "estimate {est} mm for {backlash_mm} mm"
            );
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn a_capture_without_a_circle_both_ways_is_refused_with_why() {
    let r = offline(0.0);
    // cut after the CW pass: no CCW pass
    let half = capture_of(&r, 0);
    let lines: Vec<&str> = half.lines().collect();
    let cut = lines[..lines.len() / 2].join("\n") + "\n";
    let (code, _, err) = analyze(&cut, "half.log");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("no full circle both ways"), "{err}");
    // only node 5 in the log
    let one: String = half
        .lines()
        .filter(|l| !l.contains(" 306#") && !l.contains(" 286#"))
        .map(|l| format!("{l}\n"))
        .collect();
    let (code, _, err) = analyze(&one, "one.log");
    assert_ne!(code, Some(0), "{err}");
    assert!(err.contains("node 6"), "{err}");
    // nonsense node list
    let (code, _, err) = {
        let o = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
            .args(["analyze", "x.log", "--ballbar", "5"])
            .output()
            .unwrap();
        (
            o.status.code(),
            (),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--ballbar 5"), "{err}");
}
