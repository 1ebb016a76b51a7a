//! Line contours through the drives (docs/contour.md): a line along X leaves Y at its noise;
//! on a diagonal there and back the lost motion at the reversal grows with the backlash over
//! 0 / 0.03 / 0.05 mm and sits near the gap, the master's compensation set to the gap cuts it
//! by at least half, a healthy axis shows none; three axes of three presets from a machine
//! file; the figures `drive-emu contour --json` prints equal those recomputed here from its own
//! `--trace` (with code of this file, not the library's); bad arguments give clear errors.
//! Short paths (10 mm) at 600 mm/min: about 3 s simulated per program.

mod scratch;

use std::collections::BTreeMap;
use std::path::Path;
use std::process::{Command, Output};
use std::sync::atomic::AtomicBool;

use drive_emu::analysis::ballbar::line::{run, ContourAxis, ContourReport, ContourSetup};
use drive_emu::presets::AxisConfig;

const FEED_MM_MIN: f64 = 600.0;
const ACCEL_MM_S2: f64 = 100.0;
/// Guideway friction, N, as in tests/ballbar.rs: it holds the load on its flank while the
/// axis decelerates into a corner (150 N / 800 kg = 190 mm/s^2 on cnc1, above the ramps').
const GUIDEWAY_FRICTION_N: f64 = 150.0;

/// Axes `names` of cnc1 with `backlash_mm`, the position loop on the motor encoder (the
/// indirect measuring system a compensation is for), compensation `comp_mm` on each.
fn measure(names: &[&str], points: &[[f64; 3]], backlash_mm: f64, comp_mm: f64) -> ContourReport {
    let cfg = AxisConfig::from_preset("cnc1")
        .and_then(|c| {
            c.with_overrides(
                [
                    format!("backlash_mm={backlash_mm}"),
                    "position_from_direct=false".to_string(),
                    format!("load_coulomb_friction_n={GUIDEWAY_FRICTION_N}"),
                ]
                .iter()
                .map(String::as_str),
            )
        })
        .unwrap();
    let setup = ContourSetup {
        axes: names
            .iter()
            .map(|n| ContourAxis {
                name: n.to_string(),
                config: cfg.clone(),
                backlash_comp_mm: comp_mm,
            })
            .collect(),
        points_mm: points.to_vec(),
        feed_mm_per_min: FEED_MM_MIN,
        accel_mm_s2: ACCEL_MM_S2,
    };
    run(&setup, &AtomicBool::new(false)).unwrap().report
}

/// X there and back with Y standing: Y's measured position never leaves its commanded 0 by
/// more than 0.5 um (measured: 0), so the contour error (the distance from the X line) is
/// Y's noise alone, and Y shows no reversal; X's lost motion is its gap.
#[test]
fn a_line_along_x_leaves_y_at_its_noise() {
    let cfg = AxisConfig::from_preset("cnc1")
        .and_then(|c| {
            c.with_overrides([
                "backlash_mm=0.05",
                "position_from_direct=false",
                "load_coulomb_friction_n=150",
            ])
        })
        .unwrap();
    let axis = |n: &str| ContourAxis {
        name: n.into(),
        config: cfg.clone(),
        backlash_comp_mm: 0.0,
    };
    let setup = ContourSetup {
        axes: vec![axis("X"), axis("Y")],
        points_mm: vec![[0.0; 3], [10.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
        feed_mm_per_min: FEED_MM_MIN,
        accel_mm_s2: ACCEL_MM_S2,
    };
    let r = run(&setup, &AtomicBool::new(false)).unwrap();
    let y = &r.trace.actual_mm[1];
    let worst = y.iter().map(|v| v.abs()).fold(0.0, f64::max);
    // X moved: the trace is not at rest everywhere
    let x_max = r.trace.actual_mm[0].iter().copied().fold(0.0, f64::max);
    println!(
        "line along X: Y within {worst} mm, X up to {x_max} mm, {:?}",
        r.report
    );
    assert!((x_max - 10.0).abs() < 0.1, "X reached {x_max} mm");
    assert!(worst < 0.5e-3, "Y left 0 by {worst} mm");
    for s in &r.report.segments {
        assert!(s.max_contour_error_um < 0.5, "{s:?}");
        assert!(s.end_point_error_um["Y"].abs() < 0.5, "{s:?}");
    }
    assert_eq!(r.report.reversals["Y"], 0);
    assert_eq!(r.report.reversals["X"], 1);
    let lost = r.report.segments[1].lost_motion_um["X"];
    assert!((40.0..=62.5).contains(&lost), "X lost motion {lost} um");
}

/// The diagonal X10 Y5 and back (and a third axis Z2 and back in one of the runs): each
/// axis's lost motion at the reversal grows with the gap over 0 / 0.03 / 0.05 mm and sits
/// within 0.9-1.2 of it (measured: the gap + 1.5 um, the guideway friction's deflection of
/// the drive train); with no gap it is below 3 um (measured 1.4-1.5 um); the compensation set
/// to the gap cuts it by at least half (measured: to 1.4-1.5 um).
#[test]
fn lost_motion_grows_with_the_backlash_sits_near_the_gap_and_compensation_cuts_it() {
    let xy: &[&str] = &["X", "Y"];
    let xyz: &[&str] = &["X", "Y", "Z"];
    for (names, there) in [(xy, [10.0, 5.0, 0.0]), (xyz, [10.0, 5.0, 2.0])] {
        let points = [[0.0; 3], there, [0.0; 3]];
        let mut last = vec![f64::NEG_INFINITY; names.len()];
        for gap_mm in [0.0, 0.03, 0.05] {
            let r = measure(names, &points, gap_mm, 0.0);
            let seg = &r.segments[1];
            println!(
                "{names:?} gap {gap_mm} mm: lost motion {:?} um, contour error max {:.2} um",
                seg.lost_motion_um, seg.max_contour_error_um
            );
            let gap_um = gap_mm * 1e3;
            for (k, n) in names.iter().enumerate() {
                let v = seg.lost_motion_um[*n];
                if gap_mm == 0.0 {
                    assert!(v.abs() < 3.0, "healthy {n}: {v} um");
                } else {
                    assert!(
                        (0.9 * gap_um..=1.2 * gap_um).contains(&v),
                        "{n}: {v} um for a gap of {gap_um} um"
                    );
                }
                assert!(
                    v > last[k] + 10.0,
                    "{n}: {v} um does not grow from {}",
                    last[k]
                );
                last[k] = v;
                assert_eq!(r.reversals[*n], 1);
            }
            if gap_mm > 0.0 {
                let on = measure(names, &points, gap_mm, gap_mm);
                for n in names {
                    let (off, comp) = (seg.lost_motion_um[*n], on.segments[1].lost_motion_um[*n]);
                    println!("  {n} compensated: {off:.2} -> {comp:.2} um");
                    assert!(comp.abs() <= 0.5 * off, "{n}: {off} -> {comp} um");
                }
            }
        }
    }
}

// ---- the CLI, and the figures recomputed from its trace ----

fn drive_emu(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .args(args)
        .output()
        .expect("start drive-emu")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The trace's columns by name.
fn read_csv(path: &Path) -> BTreeMap<String, Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); header.len()];
    for l in lines {
        for (k, v) in l.split(',').enumerate() {
            cols[k].push(v.parse().unwrap());
        }
    }
    header.into_iter().zip(cols).collect()
}

/// Per segment, as docs/contour.md defines them from the trace: (max and RMS distance of the
/// measured point from the segment's line over its rows, um; per reversing axis the
/// commanded minus measured travel in the new direction from the row before the segment to
/// its last row, um; the end error per axis at its last row, um).
#[allow(clippy::type_complexity)]
fn recompute(
    c: &BTreeMap<String, Vec<f64>>,
    names: &[&str],
    points: &[Vec<f64>],
) -> Vec<(f64, f64, BTreeMap<String, f64>, BTreeMap<String, f64>)> {
    let seg = &c["segment"];
    let mut out = Vec::new();
    let mut last_dir = vec![0.0f64; names.len()];
    for s in 1..points.len() {
        let rows: Vec<usize> = (0..seg.len()).filter(|&i| seg[i] == s as f64).collect();
        let (a, b) = (&points[s - 1], &points[s]);
        let d: Vec<f64> = (0..names.len()).map(|k| b[k] - a[k]).collect();
        let len2: f64 = d.iter().map(|v| v * v).sum();
        let errs: Vec<f64> = rows
            .iter()
            .map(|&i| {
                let r: Vec<f64> = names
                    .iter()
                    .enumerate()
                    .map(|(k, n)| c[&format!("{n}_mm")][i] - a[k])
                    .collect();
                let along: f64 = r.iter().zip(&d).map(|(x, y)| x * y).sum::<f64>() / len2;
                r.iter()
                    .zip(&d)
                    .map(|(x, y)| (x - along * y).powi(2))
                    .sum::<f64>()
                    .sqrt()
                    * 1e3
            })
            .collect();
        let max = errs.iter().copied().fold(0.0, f64::max);
        let rms = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt();
        let (i0, i1) = (rows[0] - 1, *rows.last().unwrap());
        let mut lost = BTreeMap::new();
        let mut end = BTreeMap::new();
        for (k, n) in names.iter().enumerate() {
            let err = |i: usize| c[&format!("{n}_mm")][i] - c[&format!("{n}_cmd_mm")][i];
            let dir = d[k].signum() * f64::from(u8::from(d[k] != 0.0));
            if dir != 0.0 {
                if last_dir[k] == -dir {
                    lost.insert(n.to_string(), dir * (err(i0) - err(i1)) * 1e3);
                }
                last_dir[k] = dir;
            }
            end.insert(n.to_string(), (c[&format!("{n}_mm")][i1] - b[k]) * 1e3);
        }
        out.push((max, rms, lost, end));
    }
    out
}

/// `contour --json` prints the figures this test recomputes from the CLI's own `--trace`,
/// and the trace's commanded path goes through the program's points: a two-axis preset run
/// and a three-axis machine file of three presets (X cnc1 0.05 mm, Y cnc2 0.02 mm
/// compensated by name, Z cnc4 healthy) with its own acceleration.
#[test]
fn cli_figures_equal_those_recomputed_from_its_trace() {
    let machine = scratch::path("contour-xyz.toml");
    std::fs::write(
        &machine,
        "[contour]\naxes = [\"X\", \"Y\", \"Z\"]\naccel_mm_s2 = 80.0\n\
         [[axis]]\nnode_id = 5\nname = \"X\"\npreset = \"cnc1\"\n\
         set = { backlash_mm = 0.05, position_from_direct = false, load_coulomb_friction_n = 150.0 }\n\
         [[axis]]\nnode_id = 6\nname = \"Y\"\npreset = \"cnc2\"\n\
         set = { backlash_mm = 0.02, position_from_direct = false, load_coulomb_friction_n = 150.0 }\n\
         [[axis]]\nnode_id = 7\nname = \"Z\"\npreset = \"cnc4\"\n\
         set = { backlash_mm = 0.0, position_from_direct = false, load_coulomb_friction_n = 150.0 }\n",
    )
    .unwrap();
    let m = machine.to_str().unwrap().to_string();
    let cases: Vec<(Vec<&str>, Vec<&str>)> = vec![
        (
            vec![
                "--set",
                "backlash_mm=0.04",
                "--set",
                "position_from_direct=false",
                "--path",
                "X8 Y-3; X0 Y0; Y4",
            ],
            vec!["X", "Y"],
        ),
        (
            vec![
                "--config",
                &m,
                "--backlash-comp-mm",
                "Y=0.02",
                "--path",
                "X10 Y5 Z2; X0 Y0 Z0; Z3",
            ],
            vec!["X", "Y", "Z"],
        ),
    ];
    for (k, (args, names)) in cases.iter().enumerate() {
        let trace = scratch::path(&format!("contour-{k}.csv"));
        let mut all = vec!["contour", "--feed-mm-min", "600", "--json", "--trace"];
        all.push(trace.to_str().unwrap());
        all.extend(args.iter().copied());
        let o = drive_emu(&all);
        assert!(o.status.success(), "{}", stderr(&o));
        let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        let c = read_csv(&trace);
        let points: Vec<Vec<f64>> = j["points_mm"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| names.iter().map(|n| p[*n].as_f64().unwrap()).collect())
            .collect();
        // the commanded path stops at every point: the last row of each segment is its end
        for (s, p) in points.iter().enumerate().skip(1) {
            let last = (0..c["segment"].len())
                .rfind(|&i| c["segment"][i] == s as f64)
                .unwrap();
            for (a, n) in names.iter().enumerate() {
                assert!((c[&format!("{n}_cmd_mm")][last] - p[a]).abs() < 1e-9);
            }
        }
        let mine = recompute(&c, names, &points);
        let segs = j["segments"].as_array().unwrap();
        assert_eq!(segs.len(), mine.len());
        let near = |a: f64, b: &serde_json::Value, what: &str| {
            let b = b.as_f64().unwrap_or_else(|| panic!("{what}: {b}"));
            assert!(
                (a - b).abs() <= 0.01,
                "case {k} {what}: recomputed {a}, CLI {b}"
            );
        };
        for (s, (max, rms, lost, end)) in segs.iter().zip(&mine) {
            println!("case {k}: max {max:.2} rms {rms:.2} lost {lost:?} end {end:?}");
            near(*max, &s["max_contour_error_um"], "max contour error");
            near(*rms, &s["rms_contour_error_um"], "rms contour error");
            let cli_lost = s["lost_motion_um"].as_object().unwrap();
            assert_eq!(
                cli_lost.keys().collect::<Vec<_>>(),
                lost.keys().collect::<Vec<_>>()
            );
            for (n, v) in lost {
                near(*v, &cli_lost[n], "lost motion");
            }
            for (n, v) in end {
                near(*v, &s["end_point_error_um"][n], "end-point error");
            }
        }
        if k == 1 {
            // the machine file's axes, acceleration and compensation by name
            assert_eq!(j["presets"]["Z"], "cnc4");
            assert_eq!(j["accel_mm_s2"], 80.0);
            assert_eq!(j["backlash_comp_mm"]["Y"], 0.02);
            let l = &segs[1]["lost_motion_um"];
            let (x, y) = (l["X"].as_f64().unwrap(), l["Y"].as_f64().unwrap());
            assert!((45.0..=60.0).contains(&x), "X {x}");
            assert!(y.abs() < 5.0, "Y compensated {y}");
        }
    }
}

/// Bad arguments: one clear line naming the flag, word or key and the reason, exit status 2,
/// no trace file left behind.
#[test]
fn bad_arguments_give_clear_errors() {
    let file = |name: &str, text: &str| {
        let p = scratch::path(name);
        std::fs::write(&p, text).unwrap();
        p.to_str().unwrap().to_string()
    };
    let axis = |n: &str, node: u8, preset: &str| {
        format!("[[axis]]\nnode_id = {node}\nname = \"{n}\"\npreset = \"{preset}\"\n")
    };
    let no_section = file("c-none.toml", &axis("X", 5, "cnc1"));
    let unknown = file(
        "c-unknown.toml",
        &format!("[contour]\naxes = [\"X\", \"Q\"]\n{}", axis("X", 5, "cnc1")),
    );
    let one = file(
        "c-one.toml",
        &format!("[contour]\naxes = [\"X\"]\n{}", axis("X", 5, "cnc1")),
    );
    let twice = file(
        "c-twice.toml",
        &format!("[contour]\naxes = [\"X\", \"X\"]\n{}", axis("X", 5, "cnc1")),
    );
    let digits = file(
        "c-digits.toml",
        &format!(
            "[contour]\naxes = [\"X\", \"Y2\"]\n{}{}",
            axis("X", 5, "cnc1"),
            axis("Y2", 6, "cnc1")
        ),
    );
    let accel = file(
        "c-accel.toml",
        &format!(
            "[contour]\naxes = [\"X\", \"Y\"]\naccel_mm_s2 = -1.0\n{}{}",
            axis("X", 5, "cnc1"),
            axis("Y", 6, "cnc1")
        ),
    );
    let rotary = file(
        "c-rotary.toml",
        &format!(
            "[contour]\naxes = [\"X\", \"C\"]\n{}{}",
            axis("X", 5, "cnc1"),
            axis("C", 6, "cnc3")
        ),
    );
    let trace = scratch::path("never.csv");
    let p = |path: &str| vec!["--path".to_string(), path.to_string()];
    let with = |extra: &[&str], path: &str| {
        let mut v: Vec<String> = extra.iter().map(|s| s.to_string()).collect();
        v.extend(p(path));
        v
    };
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            p("X10 A5"),
            "--path word \"A5\" (point 1): no axis \"A\" (the axes are X, Y)",
        ),
        (
            p("X10; Xten"),
            "--path word \"Xten\" (point 2): \"ten\" is not a coordinate in mm",
        ),
        (p("X10;; X0"), "point 2 is empty"),
        (p("X1 X2"), "axis X is named twice"),
        (p("X0 Y0"), "--path point 1 is where the axes already stand"),
        (
            p("X10; X10"),
            "--path point 2 is where the axes already stand",
        ),
        (p("X9000"), "--path point 1: X9000 is outside +-5000 mm"),
        (
            p("X1 Y"),
            "--path word \"Y\" (point 1): \"\" is not a coordinate",
        ),
        (
            with(&["--feed-mm-min", "0"], "X1"),
            "--feed-mm-min 0: must be a finite feed > 0",
        ),
        (
            with(&["--feed-mm-min", "40000"], "X1"),
            "above axis X (cnc1)'s maximum speed",
        ),
        (
            with(&["--accel-mm-s2", "0"], "X1"),
            "--accel-mm-s2 0: must be a finite",
        ),
        (
            with(&["--feed-mm-min", "1"], "X4000"),
            "above the cap of 600 s",
        ),
        (with(&["--preset", "cnc3"], "X1"), "is a rotary axis"),
        (
            with(&["--backlash-comp-mm", "-0.01"], "X1"),
            "--backlash-comp-mm -0.01",
        ),
        (
            with(&["--backlash-comp-mm", "Q=0.01"], "X1"),
            "no axis Q (the axes are X, Y)",
        ),
        (
            with(&["--config", &no_section], "X1"),
            "no [contour] section",
        ),
        (
            with(&["--config", &unknown], "X1"),
            "key `contour.axes`: no axis is named \"Q\"",
        ),
        (
            with(&["--config", &one], "X1"),
            "key `contour.axes`: 1 axes",
        ),
        (
            with(&["--config", &twice], "X1"),
            "key `contour.axes`: \"X\" is named twice",
        ),
        (
            with(&["--config", &digits], "X1"),
            "key `contour.axes`: \"Y2\" is not a name of letters",
        ),
        (
            with(&["--config", &accel], "X1"),
            "key `contour.accel_mm_s2`: -1",
        ),
        (
            with(&["--config", &rotary], "X1"),
            "axis C (cnc3) is a rotary axis",
        ),
    ];
    for (args, want) in cases {
        let mut all: Vec<String> = vec!["contour".into()];
        if !args.iter().any(|a| a == "--feed-mm-min") {
            all.extend(["--feed-mm-min".into(), "600".into()]);
        }
        all.extend(args.iter().cloned());
        all.extend(["--trace".into(), trace.to_str().unwrap().into()]);
        let o = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
            .args(&all)
            .output()
            .unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(e.contains(want), "{args:?}: want {want:?} in {e}");
        assert!(!e.contains("panicked"), "{e}");
        assert!(!trace.exists(), "{args:?} left a trace file");
    }
}
