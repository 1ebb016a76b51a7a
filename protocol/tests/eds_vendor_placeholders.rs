//! A vendor's file taken as its own device takes it (issue 33, items 2 and 3), the classes
//! the Elmo files brought (protocol/src/od/placeholders.rs), each with a minimal file of its
//! own in tests/eds/minimal: PDO maps whose entries and counts have no value, an encoder
//! resolution of 1 increment per revolution in an all-ones factor group, read-only PDO
//! COB-IDs.
mod common;
use common::*;
use drive_protocol::od::eds_parse::{decode_text, parse, EdsFile};
use drive_protocol::od::{BuildReport, Fate, ObjectDictionary};
use drive_protocol::NodeConfig;
use std::path::Path;

fn text(name: &str) -> String {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/eds/minimal")
        .join(name);
    decode_text(&std::fs::read(&p).unwrap())
}

fn bench(f: &EdsFile) -> (Bench, BuildReport) {
    let (od, report) = ObjectDictionary::from_eds(f, &info()).unwrap();
    (
        Bench::with_config(NodeConfig::new(ID, info()).with_od(od)),
        report,
    )
}

fn why(report: &BuildReport, index: u16, sub: u8) -> String {
    report
        .lines
        .iter()
        .find(|l| l.index == index && l.sub == sub)
        .map(|l| l.why.clone())
        .unwrap_or_default()
}

/// The Elmo Gold DCFs leave mapping entries 2..8 (and some counts) without any value: the
/// device ships those entries unused and counts the entries given. So the drive serves 0 and
/// the count of the given entries (a ParameterValue count stands), python canopen's
/// `load_configuration()` (invalidate, count 0, the entries, the count) is taken, and the
/// 64-bit TPDO carries its one object; before, the standard map's entries filled the gaps
/// and the count write was refused with 0x06040042 (PDO length exceeded).
#[test]
fn mapping_entries_without_a_value_are_unused_and_the_count_counts_the_given_ones() {
    let f = parse(&text("pdo-map-gaps.dcf")).unwrap();
    let (mut b, report) = bench(&f);
    for (index, count) in [(0x1600u16, 1u8), (0x1A00, 1), (0x1A01, 2)] {
        assert_eq!(
            b.sdo_read(index, 0).unwrap(),
            vec![count],
            "0x{index:04X}:0"
        );
        for sub in count + 1..=8 {
            assert_eq!(b.r32(index, sub), 0, "0x{index:04X}:{sub}");
            assert!(
                why(&report, index, sub).contains("an unused mapping entry (0)"),
                "0x{index:04X}:{sub}: {:?}",
                why(&report, index, sub)
            );
        }
    }
    assert!(
        why(&report, 0x1A00, 0).contains("the count of the mapping entries it gives (1)"),
        "{:?}",
        why(&report, 0x1A00, 0)
    );
    assert!(
        !report.notes.iter().any(|n| n.contains("cannot be mapped")),
        "{:?}",
        report.notes
    );
    // load_configuration() of TPDO1 as python canopen does it, counts from the drive
    let cob = 0x180 + u32::from(ID);
    b.w32(0x1800, 1, cob | 0x8000_0000).unwrap();
    b.w8(0x1A00, 0, 0).unwrap();
    b.w32(0x1A00, 1, 0x2013_0040).unwrap();
    b.w8(0x1A00, 0, 1).unwrap();
    b.w32(0x1800, 1, cob).unwrap();
    // one more 64-bit entry is still too long
    b.w32(0x1800, 1, cob | 0x8000_0000).unwrap();
    b.w8(0x1A00, 0, 0).unwrap();
    b.w32(0x1A00, 2, 0x6041_0010).unwrap();
    assert_eq!(b.w8(0x1A00, 0, 2), Err(0x0604_0042));
    b.w8(0x1A00, 0, 1).unwrap();
    b.w32(0x1800, 1, cob).unwrap();
    b.start();
    b.take();
    b.sync();
    let t = b.sent(cob);
    assert_eq!(t.len(), 1, "{t:?}");
    assert_eq!(t[0].len, 8, "{t:?}");
}

/// The Elmo files give 0x608F = 1 increment per motor revolution with gear 1:1 and feed 1 per
/// revolution: no servo encoder is that coarse, and their windows and limits (0x6067 = 100,
/// 0x607D = +-9e8) are encoder increments. The drive serves its encoder's increments per
/// revolution in 0x608F:1 and as many user units per shaft revolution in 0x6092:1: 1 uu = 1
/// increment, and a PP move of 5000 uu moves the motor 5000 increments and ends with bit 10
/// within the file's window. A feed constant other than 1 is the file's and stands.
#[test]
fn an_encoder_resolution_of_one_is_the_drives_own_and_a_factor_group_of_ones_counts_increments() {
    let src = text("encoder-one-per-rev.eds");
    let f = parse(&src).unwrap();
    let (mut b, report) = bench(&f);
    let enc = info().encoder_increments_per_rev;
    assert_eq!(b.r32(0x608F, 1), enc);
    assert_eq!(b.r32(0x608F, 2), 1);
    assert_eq!(b.r32(0x6092, 1), enc);
    assert_eq!(b.r32(0x6092, 2), 1);
    assert!(
        why(&report, 0x608F, 1).contains("placeholder"),
        "{report:?}"
    );
    assert!(
        why(&report, 0x6092, 1).contains("1 uu = 1 increment"),
        "{report:?}"
    );
    assert_eq!(b.r32(0x6067, 0), 100, "the file's window stands");
    b.start();
    b.enable(1);
    let p0 = b.node.position_actual();
    b.w32(0x6081, 0, 20_000).unwrap();
    b.w32(0x6083, 0, 200_000).unwrap();
    b.w32(0x6084, 0, 200_000).unwrap();
    b.w32(0x607A, 0, (p0 + 5000) as u32).unwrap();
    b.cw(0x1F);
    b.cw(0x0F);
    let mut reached = false;
    for _ in 0..3000 {
        b.tick();
        let p = b.node.position_actual();
        if b.statusword() & (1 << 10) != 0 && (p - (p0 + 5000)).abs() <= 100 {
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
        (b.drive.pos - (p0 as f64 + 5000.0)).abs() <= 100.0,
        "motor at {} inc, target {}",
        b.drive.pos,
        p0 + 5000
    );
    // a feed constant of 1000 per revolution is the file's: kept, the encoder still the drive's
    let other = src.replacen(
        "[6092sub1]\nParameterName=Feed\nDataType=0x0007\nAccessType=rw\nDefaultValue=1",
        "[6092sub1]\nParameterName=Feed\nDataType=0x0007\nAccessType=rw\nDefaultValue=1000",
        1,
    );
    assert_ne!(other, src);
    let (mut b, _) = bench(&parse(&other).unwrap());
    assert_eq!(b.r32(0x608F, 1), enc);
    assert_eq!(b.r32(0x6092, 1), 1000);
    // a real resolution is the file's
    let real = src.replacen(
        "[608Fsub1]\nParameterName=Encoder increments\nDataType=0x0007\nAccessType=rw\nDefaultValue=1",
        "[608Fsub1]\nParameterName=Encoder increments\nDataType=0x0007\nAccessType=rw\nDefaultValue=4096",
        1,
    );
    assert_ne!(real, src);
    let (mut b, _) = bench(&parse(&real).unwrap());
    assert_eq!(b.r32(0x608F, 1), 4096);
    assert_eq!(b.r32(0x6092, 1), 1);
}

/// The scanned Elmo SimplIQ DCF marks every PDO COB-ID read-only; python canopen's
/// `load_configuration()` writes each COB-ID with bit 31 set, then clear, and was refused
/// with 0x06010002. The drive takes the switch of bit 31 (the PDO off while it is set: no
/// TPDO on SYNC) and refuses any other change of the COB-ID with 0x06010002, as `ro` says.
#[test]
fn a_read_only_pdo_cob_id_switches_bit_31_only() {
    let f = parse(&text("ro-pdo-cob-id.dcf")).unwrap();
    let (mut b, report) = bench(&f);
    assert!(
        why(&report, 0x1800, 1).contains("CAN-ID is fixed"),
        "{report:?}"
    );
    let tx = 0x4000_0180 + u32::from(ID);
    let rx = 0x200 + u32::from(ID);
    b.start();
    b.w32(0x1800, 1, tx | 0x8000_0000).unwrap();
    b.w32(0x1400, 1, rx | 0x8000_0000).unwrap();
    assert_eq!(b.r32(0x1800, 1), tx | 0x8000_0000);
    b.take();
    b.sync();
    assert!(b.sent(tx & 0x7FF).is_empty(), "TPDO1 is off");
    for (index, bad) in [
        (0x1800u16, tx + 1),
        (0x1800, (tx + 1) | 0x8000_0000),
        (0x1800, tx & 0x7FF),
        (0x1400, rx + 0x100),
    ] {
        assert_eq!(b.w32(index, 1, bad), Err(0x0601_0002), "0x{bad:08X}");
    }
    b.w32(0x1800, 1, tx).unwrap();
    b.w32(0x1400, 1, rx).unwrap();
    b.take();
    b.sync();
    assert_eq!(b.sent(tx & 0x7FF).len(), 1, "TPDO1 is on again");
    // a file's rw COB-ID still changes its CAN-ID while the PDO is off
    let rw = text("ro-pdo-cob-id.dcf").replacen(
        "[1800sub1]\nParameterName=COB-ID\nDataType=0x0007\nAccessType=ro",
        "[1800sub1]\nParameterName=COB-ID\nDataType=0x0007\nAccessType=rw",
        1,
    );
    let (mut b, _) = bench(&parse(&rw).unwrap());
    b.w32(0x1800, 1, tx | 0x8000_0000).unwrap();
    b.w32(0x1800, 1, (tx + 1) | 0x8000_0000).unwrap();
}

/// The Whistle Gold DCF's ParameterValues write the placeholder factor group back (0x608F:1
/// = 1, 0x6092:1 = 1, through python canopen's `load_configuration()`): the master reads back
/// what it wrote, and the drive runs as with the file's own placeholder
/// (`od::placeholders::running_factor_group`): 1 uu = 1 increment of its encoder, its top
/// motor speed 0x6080 in its encoder's increments. Before, the drive took 1 increment per
/// revolution for its encoder: 3000 rev/min were 50 increments/s and the move below (5000
/// uu at 20000 uu/s) crawled for 100 s.
#[test]
fn a_placeholder_factor_group_written_back_runs_as_the_files_own() {
    let f = parse(&text("encoder-one-per-rev.eds")).unwrap();
    let (mut b, _) = bench(&f);
    b.w32(0x608F, 1, 1).unwrap();
    b.w32(0x6092, 1, 1).unwrap();
    assert_eq!(b.r32(0x608F, 1), 1, "what the master wrote reads back");
    assert_eq!(b.r32(0x6092, 1), 1);
    b.start();
    b.enable(1);
    let p0 = b.node.position_actual();
    let m0 = b.drive.pos;
    b.w32(0x6081, 0, 20_000).unwrap();
    b.w32(0x6083, 0, 200_000).unwrap();
    b.w32(0x6084, 0, 200_000).unwrap();
    b.w32(0x607A, 0, (p0 + 5000) as u32).unwrap();
    b.cw(0x1F);
    b.cw(0x0F);
    let mut ticks = None;
    for k in 0..3000 {
        b.tick();
        let p = b.node.position_actual();
        if b.statusword() & (1 << 10) != 0 && (p - (p0 + 5000)).abs() <= 100 {
            ticks = Some(k);
            break;
        }
    }
    assert!(
        ticks.is_some(),
        "moved {} of 5000 uu in 3 s",
        b.node.position_actual() - p0
    );
    // 1 uu = 1 increment of the encoder, as before the write
    assert!(
        (b.drive.pos - m0 - 5000.0).abs() <= 100.0,
        "motor moved {} inc for 5000 uu",
        b.drive.pos - m0
    );
    // a real resolution written is taken as it is: 1 uu = 4096 / 1 increments
    let (mut b, _) = bench(&f);
    b.w32(0x608F, 1, 4096).unwrap();
    b.w32(0x6092, 1, 1).unwrap();
    b.start();
    b.enable(1);
    let p0 = b.node.position_actual();
    let m0 = b.drive.pos;
    b.w32(0x6081, 0, 5).unwrap();
    b.w32(0x6083, 0, 50).unwrap();
    b.w32(0x6084, 0, 50).unwrap();
    b.w32(0x607A, 0, (p0 + 2) as u32).unwrap();
    b.cw(0x1F);
    b.cw(0x0F);
    b.ticks(2000);
    assert!(
        (b.drive.pos - m0 - 2.0 * 4096.0).abs() <= 100.0,
        "motor moved {} inc for 2 uu of 4096",
        b.drive.pos - m0
    );
}

/// AMD's Kria KD240 file makes every map's number of entries `const` and its entries `rw`: a
/// fixed mapping. python canopen's `load_configuration()` writes the file's own map (count 0,
/// refused 0x06010002 and passed over by python canopen, the entries, the count) and was
/// refused with 0x06010000 at the first entry (CiA 301: entries only while the count is 0,
/// which it never is here). The drive takes an entry written as it stands and refuses any
/// other value, as before; a map whose count is writable still refuses any entry while the
/// count is not 0.
#[test]
fn a_fixed_mapping_takes_its_entries_as_they_stand_only() {
    let f = parse(&text("fixed-pdo-map.eds")).unwrap();
    let (mut b, report) = bench(&f);
    for index in [0x1600u16, 0x1A00] {
        assert!(
            report.notes.iter().any(
                |n| n.starts_with(&format!("0x{index:04X}: ")) && n.contains("a fixed mapping")
            ),
            "{:?}",
            report.notes
        );
    }
    let rx = 0x200 + u32::from(ID);
    let tx = 0x4000_0180 + u32::from(ID);
    // python canopen's save(): the PDO off, count 0 (refused: const), the entry, the count
    b.w32(0x1400, 1, rx | 0x8000_0000).unwrap();
    b.w32(0x1800, 1, tx | 0x8000_0000).unwrap();
    assert_eq!(b.w8(0x1600, 0, 0), Err(0x0601_0002));
    b.w32(0x1600, 1, 0x6040_0010).unwrap();
    b.w32(0x1A00, 1, 0x6041_0010).unwrap();
    assert_eq!(b.w8(0x1600, 0, 1), Err(0x0601_0002));
    // any other entry is refused and the map stays
    assert_eq!(b.w32(0x1600, 1, 0x6060_0008), Err(0x0601_0000));
    assert_eq!(b.w32(0x1A00, 1, 0x6064_0020), Err(0x0601_0000));
    assert_eq!(b.w32(0x1600, 1, 0), Err(0x0601_0000));
    assert_eq!(b.r32(0x1600, 1), 0x6040_0010);
    assert_eq!(b.r32(0x1A00, 1), 0x6041_0010);
    b.w32(0x1400, 1, rx).unwrap();
    b.w32(0x1800, 1, tx).unwrap();
    // a writable count: CiA 301 as before, no entry written while it is not 0
    let rw = text("fixed-pdo-map.eds").replacen(
        "[1600sub0]\nParameterName=Number of entries\nDataType=0x0005\nAccessType=const",
        "[1600sub0]\nParameterName=Number of entries\nDataType=0x0005\nAccessType=rw",
        1,
    );
    let (mut b, report) = bench(&parse(&rw).unwrap());
    assert!(!report.notes.iter().any(|n| n.starts_with("0x1600: ")));
    b.w32(0x1400, 1, rx | 0x8000_0000).unwrap();
    assert_eq!(b.w32(0x1600, 1, 0x6040_0010), Err(0x0601_0000));
    b.w8(0x1600, 0, 0).unwrap();
    b.w32(0x1600, 1, 0x6060_0008).unwrap();
}

/// SEVCON's Gen4 has 0x1014 = 0 (issue 33): CAN-ID 0 is NMT's and CiA 301 allows no EMCY
/// there, but the device takes its own file's 0 as "EMCY on the predefined CAN-ID". The drive
/// serving such a file reads 0 back, takes 0 written back (`load_configuration`), sends EMCY
/// on $NODEID + 0x80 and never on CAN-ID 0; the report says so. Our own drive still refuses 0.
#[test]
fn a_file_whose_emcy_cob_id_is_0_sends_emcy_on_the_predefined_can_id() {
    let f = parse(&text("emcy-cob-id-zero.eds")).unwrap();
    let (mut b, report) = bench(&f);
    assert!(
        report.notes.iter().any(
            |n| n.starts_with("0x1014 (COB-ID EMCY): the file's value is 0")
                && n.contains("$NODEID+0x80")
        ),
        "{:?}",
        report.notes
    );
    assert_eq!(b.r32(0x1014, 0), 0, "the file's 0 reads back");
    assert_eq!(b.w32(0x1014, 0, 0), Ok(()), "written back");
    b.start();
    b.drive.fault = Some(0x2310);
    b.ticks(3);
    assert_eq!(b.emcys(), vec![0x2310], "EMCY on 0x80 + node ID");
    assert!(b.sent(0).is_empty(), "nothing on NMT's CAN-ID");
    // another COB-ID works as on any drive, and 0 is this device's own value again
    assert_eq!(b.w32(0x1014, 0, 0x90), Ok(()));
    assert_eq!(b.w32(0x1014, 0, 0x7F), Err(0x0609_0030), "restricted");
    assert_eq!(b.w32(0x1014, 0, 0), Ok(()));

    let mut own = Bench::new();
    assert_eq!(
        own.w32(0x1014, 0, 0),
        Err(0x0609_0030),
        "CiA 301: a master's 0 on a drive whose file does not have it"
    );
    assert_eq!(own.r32(0x1014, 0), 0x80 + ID as u32);
}

/// SEVCON's Gen4 EDS maps 0x6C11 sub 4 in its default RPDO1 but lists 0x6C11 subs 1..3 only,
/// with sub 0 = 7 (issue 33). The device has the member; the drive adds it (the listed
/// members' type and access), so the default map is valid and a master writing it back
/// (`load_configuration`) is not refused; members no map names, or above sub 0's count, are
/// not invented.
#[test]
fn a_member_the_files_default_map_names_is_added_below_sub_0s_count() {
    let file = parse(&text("mapped-member-missing.eds")).unwrap();
    let (mut b, report) = bench(&file);
    assert_eq!(
        report.fate(0x2C11, 4),
        Some(Fate::Added),
        "{:?}",
        report.lines
    );
    assert!(
        why(&report, 0x2C11, 4).contains("named by the file's default map 0x1600 sub 2"),
        "{}",
        why(&report, 0x2C11, 4)
    );
    assert!(
        !report.notes.iter().any(|n| n.contains("cannot be mapped")),
        "{:?}",
        report.notes
    );
    assert_eq!(b.sdo_read(0x2C11, 4).unwrap(), vec![0, 0], "INTEGER16, 0");
    assert_eq!(
        b.sdo_read(0x2C11, 5),
        Err(0x0609_0011),
        "not named by a map"
    );
    // load_configuration: invalidate, count 0, the entries, the count
    b.w32(0x1400, 1, 0x8000_0200 + ID as u32).unwrap();
    b.w8(0x1600, 0, 0).unwrap();
    assert_eq!(b.w32(0x1600, 2, 0x2C11_0410), Ok(()));
    assert_eq!(
        b.w32(0x1600, 2, 0x2C11_0810),
        Err(0x0604_0041),
        "above sub 0's 7"
    );
    b.w32(0x1600, 2, 0x2C11_0410).unwrap();
    b.w8(0x1600, 0, 2).unwrap();
    b.w32(0x1400, 1, 0x200 + ID as u32).unwrap();
    b.start();
    b.send(f(0x200 + ID as u32, &[0x06, 0x00, 0x34, 0x12]));
    assert_eq!(
        b.sdo_read(0x2C11, 4).unwrap(),
        vec![0x34, 0x12],
        "RPDO1 carries it"
    );
}

/// SEVCON's Gen4 DCF (read from a live controller) has TPDOs on CAN-IDs CiA 301 restricts
/// (0x120, 0x145, 0x178) and ParameterValues below the file's own LowLimit (0x1280 sub 3 = 0):
/// the device holds them, so a master loading the DCF writes them and the drive takes them;
/// another restricted CAN-ID, or that one on another PDO, is still refused.
#[test]
fn a_dcfs_own_restricted_pdo_can_id_and_values_below_its_limits_are_taken() {
    let file = parse(&text("shipped-restricted-pdo-cob-id.dcf")).unwrap();
    let (mut b, report) = bench(&file);
    assert!(
        report
            .notes
            .iter()
            .any(|n| n.starts_with("0x1800 sub 1: the file gives the PDO CAN-ID 0x178")),
        "{:?}",
        report.notes
    );
    assert!(why(&report, 0x2001, 0).contains("ParameterValue is below its LowLimit"));
    assert_eq!(b.w8(0x2001, 0, 0), Ok(()), "the DCF's 0");
    assert_eq!(b.w32(0x1800, 1, 0x8000_0178), Ok(()));
    assert_eq!(b.w32(0x1800, 1, 0x178), Ok(()), "valid on the DCF's CAN-ID");
    assert_eq!(b.w32(0x1800, 1, 0x8000_0178), Ok(()));
    assert_eq!(
        b.w32(0x1800, 1, 0x177),
        Err(0x0609_0030),
        "another restricted one"
    );
    b.w32(0x1800, 1, 0x178).unwrap();
    b.start();
    b.sync();
    assert_eq!(b.sent(0x178).len(), 1, "TPDO1 on 0x178");
    let mut own = Bench::new();
    own.w32(0x1800, 1, 0x8000_0000 | (0x180 + ID as u32))
        .unwrap();
    assert_eq!(own.w32(0x1800, 1, 0x178), Err(0x0609_0030), "our own drive");
}

/// SEVCON's Gen4 files themselves (issue 33): `eds --from` says what the drive takes and why,
/// the SYNC producer with the file's period, the EMCY COB-ID 0, the added 0x6C11 sub 4 (EDS)
/// and the TPDOs on restricted CAN-IDs (DCF); the drive runs PT, the Gen4's own mode.
#[test]
fn the_gen4_files_are_taken_and_the_report_says_how() {
    let load = |name: &str| {
        let p = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../tests/eds/vendors")
            .join(name);
        parse(&decode_text(&std::fs::read(&p).unwrap())).unwrap()
    };
    // the DCF's default is the EDS's 100 ms; its ParameterValue 20 ms is what a master writes
    for (name, period) in [("sevcon-gen4.eds", 100_000), ("sevcon-gen4.dcf", 100_000)] {
        let (mut b, report) = bench(&load(name));
        let has = |s: &str| report.notes.iter().any(|n| n.contains(s));
        assert!(
            has(&format!(
                "0x1005 = 0x40000080: the device is the SYNC producer (bit 30): the drive sends \
                 SYNC on CAN-ID 0x080 every 0x1006 = {period} us at boot"
            )),
            "{name}: {:?}",
            report.notes
        );
        assert!(has("0x1014 (COB-ID EMCY): the file's value is 0"), "{name}");
        assert_eq!(b.r32(0x6502, 0) & 0xC, 0xC, "{name}: PV and PT");
        assert_eq!(b.w8(0x6060, 0, 4), Ok(()), "{name}: PT");
        if name.ends_with(".eds") {
            assert_eq!(report.fate(0x6C11, 4), Some(Fate::Added), "{name}");
            // RPDO2, RPDO5 and TPDO2 map BOOLEANs in 1 bit each: taken, and said
            for entry in [0x2120_0001u32, 0x2127_0001, 0x2140_0001, 0x2320_0001] {
                assert!(
                    has(&format!("0x{entry:08X} maps 1 of the 8 bits")),
                    "{entry:08X}"
                );
            }
            assert!(!has("cannot be mapped"), "{:?}", report.notes);
            // RPDO2 (0x282, event-driven): bit k of its one byte is 0x2120 + k
            b.w32(0x1401, 1, 0x282).unwrap();
            b.start();
            b.send(common::f(0x282, &[0b1000_0101]));
            b.tick();
            for (index, want) in [(0x2120u16, 1u8), (0x2121, 0), (0x2122, 1), (0x2127, 1)] {
                assert_eq!(b.sdo_read(index, 0).unwrap(), vec![want], "{index:04X}");
            }
        } else {
            for id in [0x120, 0x145, 0x178] {
                assert!(
                    has(&format!("the PDO CAN-ID 0x{id:03X}")),
                    "{name}: {id:#x}"
                );
            }
            assert!(
                !has("the PDO CAN-ID 0x000"),
                "an invalid PDO's CAN-ID needs nothing"
            );
        }
    }
}
