//! A vendor's units (issue 33, item 3), each with a minimal file of its own in tests/eds/units:
//! a placeholder maximum is filled in the units the file's SI unit objects give velocities and
//! accelerations (0x60A9, 0x60AA), not in position user units per second; 0x60AA is the
//! acceleration user unit; 0x60A8 gives the feed constant a file lacks, so a position user
//! unit is its unit on the simulated axis.
mod common;
use common::*;
use drive_protocol::od::eds_parse::{decode_text, parse, EdsFile};
use drive_protocol::od::{BuildReport, ObjectDictionary};
use drive_protocol::NodeConfig;
use std::path::Path;

fn load(name: &str) -> EdsFile {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/eds/units")
        .join(name);
    parse(&decode_text(&std::fs::read(&p).unwrap())).unwrap()
}

fn bench(f: &EdsFile) -> (Bench, BuildReport) {
    let (od, report) = ObjectDictionary::from_eds(f, &info()).unwrap();
    (
        Bench::with_config(NodeConfig::new(ID, info()).with_od(od)),
        report,
    )
}

fn why(report: &BuildReport, index: u16) -> &str {
    &report
        .lines
        .iter()
        .find(|l| l.index == index && l.sub == 0)
        .unwrap_or_else(|| panic!("no report line for 0x{index:04X}"))
        .why
}

/// The axis's default of a standard object.
fn axis(index: u16) -> u64 {
    ObjectDictionary::standard(&info())
        .get(index, 0)
        .unwrap()
        .1
        .default_raw(ID)
}

/// A PP move of `dist` uu at `speed` / `acc`: (reached with bit 10, peak 0x606C, p0).
fn pp_move(b: &mut Bench, dist: i32, speed: u32, acc: u32) -> (bool, i32, i32) {
    b.start();
    b.enable(1);
    let p0 = b.node.position_actual();
    b.w32(0x6081, 0, speed).unwrap();
    b.w32(0x6083, 0, acc).unwrap();
    b.w32(0x6084, 0, acc).unwrap();
    b.w32(0x607A, 0, (p0 + dist) as u32).unwrap();
    b.cw(0x1F);
    b.cw(0x0F);
    let mut peak = 0i32;
    for _ in 0..3000 {
        b.tick();
        peak = peak.max(b.ri32(0x606C, 0));
        if b.statusword() & (1 << 10) != 0 && b.node.position_actual() >= p0 + dist * 49 / 50 {
            return (true, peak, p0);
        }
    }
    (false, peak, p0)
}

/// 0x60A9 = rev/min, 0x60AA = rev/s per second. The placeholder 0x607F = 0 becomes the
/// motor's top speed in rev/min (3000, the axis's 0x6080), where before it was the axis's
/// position-uu/s figure (500000) read as rev/min; 0x60C5 = 0 the axis's acceleration in
/// rev/s^2. A move at 600 rev/min with 100 rev/s^2 over 2.5 revolutions reaches 600 rev/min:
/// were an acceleration uu 1 rev/min per second (0x60AA not applied), it would peak near
/// 120 rev/min.
#[test]
fn placeholders_are_filled_in_the_si_units_and_0x60aa_is_the_acceleration_unit() {
    let f = load("acceleration-rev-s2.eds");
    let (mut b, report) = bench(&f);
    assert_eq!(axis(0x6080), 3000);
    assert_eq!(b.r32(0x607F, 0), 3000, "{}", why(&report, 0x607F));
    assert!(
        why(&report, 0x607F).contains("3000 in 0x60A9's unit, the simulated axis's value (0x607F)"),
        "{}",
        why(&report, 0x607F)
    );
    // the axis's 0x6083 (uu/s^2, 6.5536 increments of 65536 per revolution each) in rev/s^2
    let rev_s2 = (axis(0x6083) as f64 * INC_PER_UU / 65536.0)
        .round()
        .max(1.0) as u32;
    assert_eq!(b.r32(0x60C5, 0), rev_s2, "{}", why(&report, 0x60C5));
    assert!(why(&report, 0x60C5).contains("in 0x60AA's unit"));
    let (reached, peak, p0) = pp_move(&mut b, 5000, 600, 100);
    assert!(
        reached,
        "moved {} of 5000 uu",
        b.node.position_actual() - p0
    );
    assert!(
        (570..=630).contains(&peak),
        "peak {peak} rev/min, commanded 600"
    );
}

/// The same file with a 0x60AA this drive cannot apply (unit 0xB6): an acceleration uu is 0x60A9's unit per second (rev/min
/// per s), so the same move with 0x6083 = 100 peaks far below 600 rev/min; with 0x6083 =
/// 6000 (100 rev/s^2 in rev/min per s) it reaches 600 again.
#[test]
fn without_0x60aa_an_acceleration_unit_is_the_velocity_unit_per_second() {
    let text = decode_text(
        &std::fs::read(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("../tests/eds/units/acceleration-rev-s2.eds"),
        )
        .unwrap(),
    )
    .replace("DefaultValue=0x00B40300", "DefaultValue=0x00B60300");
    let f = parse(&text).unwrap();
    let (mut b, report) = bench(&f);
    assert!(why(&report, 0x60C5).contains("in 0x60A9's unit per s"));
    let (_, peak, _) = pp_move(&mut b, 5000, 600, 100);
    assert!(peak < 200, "peak {peak} rev/min with 100 rev/min per s");
    let (mut b, _) = bench(&f);
    let (reached, peak, _) = pp_move(&mut b, 5000, 600, 6000);
    assert!(reached && (570..=630).contains(&peak), "peak {peak}");
}

/// 0x60A8 = um and no 0x6092: the drive serves the feed constant that makes 1 uu one um of
/// the simulated axis (10 mm per revolution: 10000 uu per revolution), and the report says
/// so. A move of 5000 uu is half a revolution (1000 of the file's 2000 increments), at 0x60A9
/// mm/s; the placeholder 0x607F is the motor's 3000 rev/min = 500 mm/s.
#[test]
fn the_si_unit_position_gives_the_missing_feed_constant() {
    let f = load("position-micrometre.eds");
    let (mut b, report) = bench(&f);
    assert!(
        report.notes.iter().any(|n| n.contains(
            "0x60A8 SI unit position = 0xFA010000 applied: the file has no feed constant 0x6092, \
             so the drive serves 0x6092 = 10000/1 user units per shaft revolution"
        )),
        "{:?}",
        report.notes
    );
    // (0x6092 stays hidden: the file does not have it)
    assert_eq!(b.sdo_read(0x6092, 1), Err(0x0602_0000));
    assert_eq!(b.r32(0x607F, 0), 500, "{}", why(&report, 0x607F));
    let (reached, peak, p0) = pp_move(&mut b, 5000, 20, 200);
    assert!(
        reached,
        "moved {} of 5000 uu",
        b.node.position_actual() - p0
    );
    assert!((19..=21).contains(&peak), "peak {peak} mm/s, commanded 20");
    // the motor turned half a revolution: 1000 increments of 2000
    let inc0 = f64::from(p0) * 0.2;
    assert!(
        (b.drive.pos - (inc0 + 1000.0)).abs() < 15.0,
        "motor at {} inc, from {inc0}",
        b.drive.pos
    );
    // a file that has its own 0x6092 keeps it: 0x60A8 is then the unit's name only
    let f = load("acceleration-rev-s2.eds");
    let (mut b, report) = bench(&f);
    assert!(!report
        .notes
        .iter()
        .any(|n| n.contains("0x60A8 SI unit position")));
    assert_eq!(b.r32(0x6092, 1), 2000);
}

/// The motor's limits as placeholders (each its own class): 0x6080 max motor speed, 0x6073
/// max current and 0x60C6 max deceleration 0 are taken from the simulated axis (0x6080 in
/// rev/min, 0x6072 per mille, 0x6084 in the file's acceleration unit), each said, and a PP
/// move reaches its target.
#[test]
fn motor_limit_placeholders_are_taken_from_the_axis_and_the_drive_moves() {
    let p =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/eds/minimal/placeholders-motor.eds");
    let f = parse(&decode_text(&std::fs::read(&p).unwrap())).unwrap();
    let (mut b, report) = bench(&f);
    for (index, from) in [(0x6080u16, 0x6080u16), (0x6073, 0x6072), (0x60C6, 0x6084)] {
        let want = axis(from);
        assert!(want > 0, "0x{from:04X}");
        let bytes = b.sdo_read(index, 0).unwrap();
        let mut buf = [0u8; 8];
        buf[..bytes.len()].copy_from_slice(&bytes);
        let got = u64::from_le_bytes(buf);
        assert_eq!(got, want, "0x{index:04X}: {}", why(&report, index));
        let w = why(&report, index);
        assert!(
            w.starts_with("the file's default 0 is a placeholder (it would ")
                && w.contains(&format!(": {want}"))
                && w.contains(&format!("the simulated axis's value (0x{from:04X})")),
            "0x{index:04X}: {w}"
        );
    }
    // (the file has no 0x606C: the move is watched by position and statusword)
    b.start();
    b.enable(1);
    let p0 = b.node.position_actual();
    b.w32(0x6081, 0, 5000).unwrap();
    b.w32(0x6083, 0, 50_000).unwrap();
    b.w32(0x6084, 0, 50_000).unwrap();
    b.w32(0x607A, 0, (p0 + 500) as u32).unwrap();
    b.cw(0x1F);
    b.cw(0x0F);
    let mut reached = false;
    for _ in 0..3000 {
        b.tick();
        if b.statusword() & (1 << 10) != 0 && b.node.position_actual() >= p0 + 490 {
            reached = true;
            break;
        }
    }
    assert!(reached, "moved {} of 500", b.node.position_actual() - p0);
    assert_eq!(
        b.node.cia402_state(),
        drive_protocol::Cia402State::OperationEnabled
    );
}

/// 0x60A8 = mrad (0xFD100000) and no 0x6092 on a rotary axis: the drive serves the feed
/// constant that makes 1 uu one mrad of the drive shaft (2000 pi per revolution, the nearest
/// fraction of UNSIGNED32 terms), and the report says so. A move of 3142 uu (pi rad) is half
/// a revolution (1000 of the file's 2000 increments), at 0x60A9 mrad/s.
#[test]
fn the_si_unit_position_in_radians_gives_the_feed_constant() {
    let f = load("position-radian.eds");
    let mut rotary = info();
    rotary.rotary = true;
    let (od, report) = ObjectDictionary::from_eds(&f, &rotary).unwrap();
    let note = report
        .notes
        .iter()
        .find(|n| n.starts_with("0x60A8 SI unit position = 0xFD100000 applied: "))
        .unwrap_or_else(|| panic!("{:?}", report.notes));
    // "0x6092 = N/D user units per shaft revolution (2 pi rad ...)"
    let ratio = note
        .split("0x6092 = ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .unwrap();
    let (n, d) = ratio.split_once('/').unwrap();
    let per_rev = n.parse::<f64>().unwrap() / d.parse::<f64>().unwrap();
    assert!(
        (per_rev - 2000.0 * std::f64::consts::PI).abs() < 1e-6,
        "{note}"
    );
    assert!(note.contains("2 pi rad of the drive shaft"), "{note}");
    let mut b = Bench::with_config(NodeConfig::new(ID, rotary).with_od(od));
    let (reached, peak, p0) = pp_move(&mut b, 3142, 2000, 20_000);
    assert!(
        reached,
        "moved {} of 3142 uu",
        b.node.position_actual() - p0
    );
    assert!(
        (1900..=2100).contains(&peak),
        "peak {peak} mrad/s, commanded 2000"
    );
    let inc0 = f64::from(p0) * 2000.0 / per_rev;
    assert!(
        (b.drive.pos - (inc0 + 1000.0)).abs() < 15.0,
        "motor at {} inc, from {inc0}",
        b.drive.pos
    );
}
