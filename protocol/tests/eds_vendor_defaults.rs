//! A vendor's file taken as the device takes it (issue 33, item 2): default PDO maps that map
//! fewer bits of an object than it has (a DCF mapping 32 bits of a 64-bit `wo` object) are
//! valid, carry the low bytes, and a master writing them back (`load_configuration`) is not
//! refused; a short entry the file does not ship still is.
mod common;
use common::*;
use drive_protocol::od::eds_parse::{decode_text, parse, EdsFile};
use drive_protocol::od::ObjectDictionary;
use drive_protocol::NodeConfig;
use std::path::Path;

fn load(name: &str) -> EdsFile {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/eds/minimal")
        .join(name);
    parse(&decode_text(&std::fs::read(&p).unwrap())).unwrap()
}

fn bench(f: &EdsFile) -> (Bench, drive_protocol::od::BuildReport) {
    let (od, report) = ObjectDictionary::from_eds(f, &info()).unwrap();
    (
        Bench::with_config(NodeConfig::new(ID, info()).with_od(od)),
        report,
    )
}

#[test]
fn a_shipped_short_mapping_is_taken_and_carries_the_low_bytes() {
    let f = load("short-pdo-map.dcf");
    let (mut b, report) = bench(&f);
    for (entry, dir) in [
        (0x2100_0020u32, "RPDO1"),
        (0x2101_0020, "RPDO1"),
        (0x2200_0020, "TPDO1"),
    ] {
        assert!(
            report.notes.iter().any(|n| n.starts_with(dir)
                && n.contains(&format!("0x{entry:08X} maps 32 of the 64 bits"))),
            "{entry:08X}: {:?}",
            report.notes
        );
    }
    assert!(
        !report.notes.iter().any(|n| n.contains("cannot be mapped")),
        "{:?}",
        report.notes
    );
    b.start();
    // RPDO1: 4 bytes for each 64-bit object; the rww one reads back zero-extended
    b.send(f_(0x200 + ID as u32, &[1, 2, 3, 4, 0xF0, 0xDE, 0xBC, 0x9A]));
    assert_eq!(
        b.sdo_read(0x2101, 0).unwrap(),
        0x9ABC_DEF0u64.to_le_bytes().to_vec()
    );
    assert_eq!(
        b.sdo_read(0x2100, 0),
        Err(0x0601_0001),
        "wo stays write-only"
    );
    // TPDO1 on SYNC: the low 4 bytes of 0x2200
    b.take();
    b.sync();
    let t = b.sent(0x180 + ID as u32);
    assert_eq!(t.len(), 1, "{t:?}");
    assert_eq!(
        &t[0].data[..t[0].len as usize],
        &0x5566_7788u32.to_le_bytes()
    );
}

#[test]
fn load_configuration_of_the_dcf_writes_its_short_mapping_back() {
    let f = load("short-pdo-map.dcf");
    let (mut b, _) = bench(&f);
    // what python canopen's load_configuration does for the DCF's ParameterValues, in the
    // order of the file, after the PDO is made invalid (as a remap does)
    let cob = 0x200 + ID as u32;
    b.w32(0x1400, 1, cob | 0x8000_0000).unwrap();
    b.w8(0x1600, 0, 0).unwrap();
    b.w32(0x1600, 1, 0x2100_0020).unwrap();
    b.w32(0x1600, 2, 0x2101_0020).unwrap();
    b.w8(0x1600, 0, 2).unwrap();
    b.w32(0x1400, 1, cob).unwrap();
    // a short entry the file does not ship is refused as before
    b.w32(0x1400, 1, cob | 0x8000_0000).unwrap();
    b.w8(0x1600, 0, 0).unwrap();
    assert_eq!(b.w32(0x1600, 1, 0x2101_0010), Err(0x0604_0041));
    assert_eq!(
        b.w32(0x1600, 1, 0x2100_0040),
        Ok(()),
        "the whole object still maps"
    );
}

fn f_(id: u32, data: &[u8]) -> drive_protocol::CanFrame {
    common::f(id, data)
}

/// Issue 33, item 3: a default 0 for a maximum or a following-error window is a placeholder
/// (the real drive is set up by its vendor's tool): the simulated axis's value is served and
/// the report says which and why; 0xFFFFFFFF for a window is CiA 402's "off", kept and said.
/// The drive then moves: a PP move reaches its target (bit 10) without a fault.
#[test]
fn placeholder_zeros_are_taken_from_the_axis_and_the_drive_moves() {
    let f = load("placeholders.eds");
    let (mut b, report) = bench(&f);
    let std = ObjectDictionary::standard(&info());
    for (index, from) in [
        (0x607Fu16, 0x607Fu16),
        (0x6065, 0x6065),
        (0x6072, 0x6072),
        (0x60C5, 0x6083),
    ] {
        let axis = std.get(from, 0).unwrap().1.default_raw(ID);
        assert!(axis > 0, "{from:04X}");
        let got = b.sdo_read(index, 0).unwrap();
        let mut buf = [0u8; 8];
        buf[..got.len()].copy_from_slice(&got);
        assert_eq!(u64::from_le_bytes(buf), axis, "{index:04X}");
        let line = report
            .lines
            .iter()
            .find(|l| l.index == index && l.sub == 0)
            .unwrap();
        assert!(
            line.why
                .starts_with("the file's default 0 is a placeholder (it ")
                && line.why.contains(&format!(": {axis}"))
                && line
                    .why
                    .contains(&format!("the simulated axis's value (0x{from:04X})")),
            "{index:04X}: {}",
            line.why
        );
    }
    let line = report.lines.iter().find(|l| l.index == 0x6067).unwrap();
    assert_eq!(
        line.why,
        "0xFFFFFFFF: the window is off (CiA 402), as the file says"
    );
    assert_eq!(b.r32(0x6067, 0), u32::MAX);

    b.start();
    b.enable(1);
    assert_eq!(
        b.node.cia402_state(),
        drive_protocol::Cia402State::OperationEnabled
    );
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
        if b.statusword() & (1 << 10) != 0 && b.node.position_actual() > p0 + 400 {
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

/// Issue 33, item 5: the identity strings as the file gives them: a name without a default
/// and an empty one read empty (not the emulator's), a given one as given.
#[test]
fn identity_strings_are_the_files_empty_stays_empty() {
    let f = load("placeholders.eds");
    let (mut b, report) = bench(&f);
    assert_eq!(b.sdo_read(0x1008, 0).unwrap(), b"");
    assert_eq!(b.sdo_read(0x1009, 0).unwrap(), b"");
    assert_eq!(b.sdo_read(0x100A, 0).unwrap(), b"FW 1.2");
    let why = |i: u16| {
        report
            .lines
            .iter()
            .find(|l| l.index == i)
            .unwrap()
            .why
            .clone()
    };
    assert_eq!(
        why(0x1009),
        "no DefaultValue in the file: empty, as the file says"
    );
}

/// A PP move of 5000 uu at `speed` (0x6081) with `acc` (0x6083/0x6084) in the file's own
/// units: whether it reached its target (bit 10, within 100 uu) and the peak of 0x606C.
fn pp_move(b: &mut Bench, speed: u32, acc: u32) -> (bool, i32, i32) {
    b.start();
    b.enable(1);
    let p0 = b.node.position_actual();
    b.w32(0x6081, 0, speed).unwrap();
    b.w32(0x6083, 0, acc).unwrap();
    b.w32(0x6084, 0, acc).unwrap();
    b.w32(0x607A, 0, (p0 + 5000) as u32).unwrap();
    b.cw(0x1F);
    b.cw(0x0F);
    let mut peak = 0i32;
    for _ in 0..3000 {
        b.tick();
        peak = peak.max(b.ri32(0x606C, 0));
        if b.statusword() & (1 << 10) != 0 && b.node.position_actual() > p0 + 4900 {
            return (true, peak, p0);
        }
    }
    (false, peak, p0)
}

/// Issue 33, item 2: the SI unit velocity 0x60A9 = 0xFFB44700 (0.1 rev/min) with 0x608F:1 =
/// 2000 increments per revolution: 0x6081 = 3000 is 300 rev/min = 10000 increments/s = 10000
/// position uu/s (1 uu = 1 increment by the factor group); 0x6083 = 30000 is 3000 rev/min per
/// second. The move runs at that speed (0x606C reads back in 0.1 rev/min, the motor's
/// increments per second agree) and ends at its target; the report says the unit applies.
#[test]
fn the_si_unit_velocity_is_the_velocity_user_unit() {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/eds/units/velocity-tenth-rpm.eds");
    let f = parse(&decode_text(&std::fs::read(&p).unwrap())).unwrap();
    let (mut b, _) = bench(&f);
    let (reached, peak, p0) = pp_move(&mut b, 3000, 30_000);
    assert!(
        reached,
        "moved {} of 5000 uu",
        b.node.position_actual() - p0
    );
    assert!(
        (2_850..=3_150).contains(&peak),
        "peak speed {peak} x 0.1 rev/min, commanded 3000"
    );
    // the motor: 10000 increments/s at the peak (the test drive follows the command)
    assert!(
        (b.drive.pos - (p0 as f64 + 5000.0)).abs() < 60.0,
        "motor at {} inc",
        b.drive.pos
    );
    // the same file without 0x60A9 (velocities in uu/s): 0x6081 = 3000 is 3000 inc/s, a third
    // of the speed, and 0x606C reads it in uu/s
    let text = decode_text(&std::fs::read(&p).unwrap())
        .replace("DefaultValue=0xFFB44700", "DefaultValue=0x00B50000");
    let (mut b, _) = bench(&parse(&text).unwrap());
    let (reached, peak, _) = pp_move(&mut b, 3000, 30_000);
    assert!(reached);
    assert!((2_850..=3_150).contains(&peak), "peak {peak} uu/s");
}

/// Issue 33, item 4: the file's factor group is the user unit on the bus. 0x608F:1 = 2000
/// increments per revolution and 0x6092:1 = 2000 per revolution make 1 uu one increment;
/// its SI unit velocity 0x60A9 = 0x00B44700 makes a velocity uu one rev/min: a PP move at
/// 0x6081 = 300 rev/min runs at 10000 uu/s (the speed the motor reaches; 0x606C reads 300)
/// and ends at its target in those units.
#[test]
fn the_files_factor_group_is_the_user_unit_and_the_move_runs_at_its_speed() {
    let f = load("factor-2000.eds");
    let (mut b, _) = bench(&f);
    b.start();
    b.enable(1);
    let p0 = b.node.position_actual();
    b.w32(0x6081, 0, 300).unwrap();
    b.w32(0x6083, 0, 3000).unwrap();
    b.w32(0x6084, 0, 3000).unwrap();
    b.w32(0x607A, 0, (p0 + 5000) as u32).unwrap();
    b.cw(0x1F);
    b.cw(0x0F);
    let mut peak = 0i32;
    let mut reached = false;
    for _ in 0..3000 {
        b.tick();
        peak = peak.max(b.ri32(0x606C, 0));
        if b.statusword() & (1 << 10) != 0 && b.node.position_actual() > p0 + 4900 {
            reached = true;
            break;
        }
    }
    assert!(
        reached,
        "moved {} of 5000 uu",
        b.node.position_actual() - p0
    );
    assert!(
        (285..=315).contains(&peak),
        "peak speed {peak} rev/min, commanded 300"
    );
    // and the same number of increments reached the motor: 1 uu = 1 increment (the test
    // drive's axis counts what the node commands)
    assert!(
        (b.drive.pos - (p0 as f64 + 5000.0)).abs() < 60.0,
        "motor at {} inc",
        b.drive.pos
    );
}

/// A DCF's ParameterValue 0 for a placeholder object is what a master writes: the report says
/// that the drive then takes it as CiA 402 says (the boot value is still the axis's).
#[test]
fn a_dcf_parameter_value_zero_for_a_placeholder_is_said() {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/eds/minimal/placeholders.eds");
    let text = decode_text(&std::fs::read(&p).unwrap()).replace(
        "ParameterName=Following error window\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\nDefaultValue=0\n",
        "ParameterName=Following error window\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\nDefaultValue=0\nParameterValue=0\n",
    );
    let f = parse(&text).unwrap();
    let (mut b, report) = bench(&f);
    assert!(
        report.notes.iter().any(
            |n| n.starts_with("0x6065 (Following error window): the DCF's ParameterValue is 0")
        ),
        "{:?}",
        report.notes
    );
    assert_ne!(b.r32(0x6065, 0), 0);
}

/// Issue 33, item 3: a DCF whose ParameterValue for the following-error window 0x6065 is 0
/// (its vendor documents 0 as "off"): the drive boots with the file's default, a master's
/// load_configuration() writes the 0, and the drive does not fault at the first motion, a
/// stuck axis included (its following error grows without bound); the report says so. Our own
/// drive, given 0 (CiA 402 defines only 0xFFFFFFFF as off), faults: the check is live.
#[test]
fn a_dcf_that_loads_a_following_error_window_of_0_switches_the_check_off() {
    let f = load("fe-window-zero.dcf");
    let (mut b, report) = bench(&f);
    assert!(
        report.notes.iter().any(|n| n
            .starts_with("0x6065 (Following error window): the DCF's ParameterValue is 0")
            && n.contains("the following-error check off")),
        "{:?}",
        report.notes
    );
    assert_eq!(b.r32(0x6065, 0), 2000, "the file's default at boot");
    let stuck_move = |b: &mut Bench| {
        b.start();
        b.w32(0x6065, 0, 0).unwrap(); // load_configuration
        let _ = b.w16(0x6066, 0, 5); // where the file has it
        b.enable(1);
        b.drive.stuck = true;
        let p0 = b.node.position_actual();
        b.w32(0x6081, 0, 300).unwrap();
        b.w32(0x607A, 0, (p0 + 5000) as u32).unwrap();
        b.cw(0x1F);
        b.cw(0x0F);
        b.ticks(200);
    };
    stuck_move(&mut b);
    assert!(
        b.node.following_error() > 100.0,
        "following error {}",
        b.node.following_error()
    );
    assert!(!b.emcys().contains(&0x8611), "{:?}", b.emcys());
    assert_eq!(
        b.node.cia402_state(),
        drive_protocol::Cia402State::OperationEnabled
    );
    // unstuck, the move ends at its target
    b.drive.stuck = false;
    let p0 = b.node.position_actual();
    let mut reached = false;
    for _ in 0..3000 {
        b.tick();
        if b.statusword() & (1 << 10) != 0 {
            reached = true;
            break;
        }
    }
    assert!(reached, "at {} from {p0}", b.node.position_actual());

    let mut own = Bench::new();
    stuck_move(&mut own);
    assert!(own.emcys().contains(&0x8611), "{:?}", own.emcys());
    assert_eq!(own.node.cia402_state(), drive_protocol::Cia402State::Fault);
}
