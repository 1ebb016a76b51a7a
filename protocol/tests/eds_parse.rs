//! The EDS/DCF parser (`drive_protocol::od::eds_parse`): every rule of its module doc, each
//! broken case with its location in the message (inline strings and the files of
//! `tests/eds/broken/`, whose first line says the expected message), and a round trip of our
//! own EDS export.
use drive_protocol::od::eds::{EdsMeta, Real32Notation};
use drive_protocol::od::eds_parse::{
    decode_text, parse, EdsError, EdsFile, ObjectCode, ValueExpr, MAX_INPUT_BYTES, MAX_OBJECTS,
    MAX_VALUE_BYTES,
};
use drive_protocol::od::{
    Access, Backing, DataType, DefaultValue, Entry, ObjType, ObjectDictionary,
};
use drive_protocol::{Node, NodeConfig};

mod common;

/// A small complete EDS: the three mandatory objects and what `body` adds. Objects in `body`
/// are listed in [OptionalObjects] when given in `optional`.
fn eds(optional: &[u16], body: &str) -> String {
    let mut s = String::from(
        "[FileInfo]\nFileName=t.eds\nEDSVersion=4.0\n\n\
         [DeviceInfo]\nVendorName=ACME\nVendorNumber=0x1234\nProductName=Axis\nProductNumber=7\n\
         RevisionNumber=0x00010002\nOrderCode=A-1\nBaudRate_125=1\nBaudRate_1000=1\nBaudRate_10=0\n\
         SimpleBootUpSlave=1\nGranularity=8\nNrOfRXPDO=4\nNrOfTXPDO=4\nLSS_Supported=1\n\n\
         [MandatoryObjects]\nSupportedObjects=3\n1=0x1000\n2=0x1001\n3=0x1018\n\n",
    );
    s.push_str(&format!(
        "[OptionalObjects]\nSupportedObjects={}\n",
        optional.len()
    ));
    for (i, x) in optional.iter().enumerate() {
        s.push_str(&format!("{}=0x{x:04X}\n", i + 1));
    }
    s.push_str(
        "\n[1000]\nParameterName=Device type\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\nDefaultValue=0x00020192\n\n\
         [1001]\nParameterName=Error register\nDataType=0x0005\nAccessType=ro\n\n\
         [1018]\nParameterName=Identity\nObjectType=0x9\nSubNumber=2\n\n\
         [1018sub0]\nParameterName=Highest sub-index\nDataType=0x0005\nAccessType=ro\nDefaultValue=1\n\n\
         [1018sub1]\nParameterName=Vendor-ID\nDataType=0x0007\nAccessType=ro\nDefaultValue=0x1234\n\n",
    );
    s.push_str(body);
    s
}

fn ok(text: &str) -> EdsFile {
    parse(text).unwrap_or_else(|e| panic!("parse failed: {e}\n{text}"))
}

fn fails(text: &str) -> EdsError {
    match parse(text) {
        Ok(_) => panic!("parsed, expected an error:\n{text}"),
        Err(e) => e,
    }
}

/// The file reads, with a warning at `line` whose reason contains `why`.
fn warned(text: &str, line: usize, why: &str) -> EdsFile {
    let f = ok(text);
    assert!(
        f.warnings
            .iter()
            .any(|w| w.line == line && w.reason.contains(why)),
        "no warning at line {line} with '{why}': {:?}",
        f.warnings
    );
    f
}

/// Line of the first line of `text` that starts with `needle`.
fn line_of(text: &str, needle: &str) -> usize {
    text.lines()
        .position(|l| l.starts_with(needle))
        .expect(needle)
        + 1
}

/// Line of the first line starting with `needle` after the header `section`.
fn line_in(text: &str, section: &str, needle: &str) -> usize {
    let start = line_of(text, section);
    text.lines()
        .skip(start)
        .position(|l| l.starts_with(needle))
        .expect(needle)
        + start
        + 1
}

fn bytes(v: &ValueExpr, t: DataType, id: Option<u8>) -> Vec<u8> {
    v.resolve(t, id)
        .unwrap_or_else(|e| panic!("{v:?} as {t:?}: {e}"))
}

fn default_of(f: &EdsFile, index: u16, sub: u8) -> Vec<u8> {
    let s = f.sub(index, sub).unwrap();
    bytes(s.default.as_ref().unwrap(), s.data_type, Some(5))
}

#[test]
fn a_complete_eds_reads_into_the_model() {
    let f = ok(&eds(
        &[],
        "[Comments]\nLines=2\nLine1=first\nLine2=second\n\n[DummyUsage]\nDummy0001=0\nDummy0002=1\nDummy0007=1\n",
    ));
    let d = &f.device_info;
    assert_eq!(d.vendor_name.as_deref(), Some("ACME"));
    assert_eq!(d.vendor_number, Some(0x1234));
    assert_eq!(d.product_number, Some(7));
    assert_eq!(d.revision_number, Some(0x0001_0002));
    assert_eq!(d.order_code.as_deref(), Some("A-1"));
    assert_eq!(d.baud_rates_kbit, vec![125, 1000]);
    assert_eq!(d.simple_boot_up_slave, Some(true));
    assert_eq!(d.simple_boot_up_master, None);
    assert_eq!(d.granularity, Some(8));
    assert_eq!((d.nr_of_rx_pdo, d.nr_of_tx_pdo), (Some(4), Some(4)));
    assert_eq!(d.lss_supported, Some(true));
    assert_eq!(f.file_info.file_name.as_deref(), Some("t.eds"));
    assert_eq!(f.comments, vec!["first", "second"]);
    assert_eq!(
        f.dummy_usage,
        [false, false, true, false, false, false, false, true]
    );
    assert!(f.commissioning.is_none());
    assert_eq!(
        f.objects.iter().map(|o| o.index).collect::<Vec<_>>(),
        vec![0x1000, 0x1001, 0x1018]
    );
    let o = f.object(0x1000).unwrap();
    assert_eq!(o.code, ObjectCode::Var);
    assert_eq!(o.data_type, Some(DataType::U32));
    assert_eq!(o.subs.len(), 1);
    assert_eq!(o.line, line_of(&eds(&[], ""), "[1000]"));
    assert_eq!(default_of(&f, 0x1000, 0), 0x0002_0192u32.to_le_bytes());
    // ObjectType missing: VAR (both readers); no DefaultValue: None
    let o = f.object(0x1001).unwrap();
    assert_eq!(o.code, ObjectCode::Var);
    assert_eq!(o.subs[0].default, None);
    let r = f.object(0x1018).unwrap();
    assert_eq!(r.code, ObjectCode::Record);
    assert_eq!(r.subs.iter().map(|s| s.sub).collect::<Vec<_>>(), vec![0, 1]);
    assert_eq!(r.subs[1].name, "Vendor-ID");
    assert_eq!(r.subs[1].access, Access::Ro);
    assert!(f.warnings.is_empty(), "{:?}", f.warnings);
}

#[test]
fn crlf_bom_comments_case_and_spaces_read_the_same() {
    let plain = eds(&[0x2000], "[2000]\nParameterName=Gain\nDataType=0x0006\nAccessType=rw\nDefaultValue=300\nPDOMapping=1\n");
    let want = ok(&plain);
    let variants = [
        plain.replace('\n', "\r\n"),
        format!("\u{FEFF}{plain}"),
        plain.replace(
            "[2000]",
            "; a comment\n# another\n[2000]   ; trailing comment",
        ),
        plain.replace("DefaultValue=300", "DefaultValue = 300 ; three hundred"),
        plain.replace("DefaultValue=300", "  defaultvalue   =   300"),
        plain
            .replace("[2000]", "[2000 ]")
            .replace("[DeviceInfo]", "[deviceinfo]"),
        plain
            .replace("AccessType=rw", "ACCESSTYPE=RW")
            .replace("[OptionalObjects]", "[OPTIONALOBJECTS]"),
        plain.replace("DefaultValue=300", "DefaultValue=300 # dcf-tools comment"),
    ];
    for v in variants {
        let f = ok(&v);
        let (a, b) = (f.sub(0x2000, 0).unwrap(), want.sub(0x2000, 0).unwrap());
        assert_eq!(
            (a.data_type, a.access, a.pdo_mapping, &a.default),
            (b.data_type, b.access, b.pdo_mapping, &b.default),
            "{v}"
        );
        assert_eq!(f.device_info, want.device_info);
    }
    // a '#' in a name is kept (python canopen), a ';' after a space starts a comment
    let f = ok(&plain.replace("ParameterName=Gain", "ParameterName=Gain #1;x ; note"));
    assert_eq!(f.object(0x2000).unwrap().name, "Gain #1;x");
}

#[test]
fn latin1_bytes_decode_and_utf8_stays() {
    let text = eds(&[0x2001], "[2001]\nParameterName=Lage \u{b5}m \u{b0}C\nDataType=0x0009\nAccessType=ro\nDefaultValue=Gr\u{fc}n\n");
    let latin1: Vec<u8> = text.chars().map(|c| c as u32 as u8).collect();
    assert!(std::str::from_utf8(&latin1).is_err());
    let decoded = decode_text(&latin1);
    assert_eq!(decoded, text);
    let f = ok(&decoded);
    assert_eq!(f.object(0x2001).unwrap().name, "Lage µm °C");
    // the same text as UTF-8 is kept as UTF-8
    assert_eq!(decode_text(text.as_bytes()), text);
    // a VISIBLE_STRING default is its UTF-8 bytes
    assert_eq!(default_of(&f, 0x2001, 0), "Grün".as_bytes());
}

#[test]
fn sub_index_sections_in_any_spelling() {
    for spelling in ["1018sub1", "1018Sub1", "1018SUB01", "1018sub001"] {
        let f = ok(&eds(&[], "").replace("[1018sub1]", &format!("[{spelling}]")));
        assert_eq!(
            default_of(&f, 0x1018, 1),
            0x1234u32.to_le_bytes(),
            "{spelling}"
        );
    }
    // the same sub-index twice
    let text = eds(
        &[],
        "[1018sub01]\nParameterName=again\nDataType=0x0007\nAccessType=ro\n",
    );
    // read as one section, the later keys winning (Lely), with a warning at each
    let f = warned(
        &text,
        line_of(&text, "[1018sub01]"),
        "names the same thing as [1018sub1] at line",
    );
    assert_eq!(f.sub(0x1018, 1).unwrap().name, "again");
    assert!(f
        .warnings
        .iter()
        .any(|w| w.key.as_deref() == Some("ParameterName")
            && w.reason.contains("the last one, 'again', is read")));
}

#[test]
fn nodeid_forms_in_any_order_case_and_spacing() {
    for (text, want) in [
        ("$NODEID+0x180", 0x185),
        ("$NODEID + 0x180", 0x185),
        ("$nodeid+384", 0x185),
        ("$NodeID+0x180", 0x185),
        ("0x180+$NODEID", 0x185),
        ("0x180 + $NodeId", 0x185),
        ("$NODEID", 5),
        ("$NODEID-1", 4),
        ("$NODEID - 0x1", 4),
        ("0x40000180+$NODEID", 0x4000_0185),
    ] {
        let f = ok(&eds(&[0x1800], &format!(
            "[1800]\nParameterName=TPDO1\nObjectType=0x9\nSubNumber=2\n\n[1800sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\nDefaultValue=2\n\n\
             [1800sub1]\nParameterName=COB-ID\nDataType=0x0007\nAccessType=rw\nDefaultValue={text}\n"
        )));
        let v = f.sub(0x1800, 1).unwrap().default.clone().unwrap();
        assert!(v.uses_node_id(), "{text}");
        assert_eq!(
            bytes(&v, DataType::U32, Some(5)),
            (want as u32).to_le_bytes(),
            "{text}"
        );
        // no node ID to put in: an error
        assert!(
            v.resolve(DataType::U32, None)
                .unwrap_err()
                .contains("$NODEID"),
            "{text}"
        );
    }
    for bad in [
        "$NODEID+$NODEID",
        "-$NODEID",
        "$NODEID*2",
        "1+$NODEID+2",
        "$NODEID+",
    ] {
        let text = eds(
            &[0x2000],
            &format!(
                "[2000]\nParameterName=x\nDataType=0x0007\nAccessType=rw\nDefaultValue={bad}\n"
            ),
        );
        let e = fails(&text);
        assert_eq!(
            (e.line, e.key.as_deref()),
            (
                line_in(&text, "[2000]", "DefaultValue"),
                Some("DefaultValue")
            ),
            "{bad}: {e}"
        );
        assert!(e.reason.contains("$NODEID"), "{bad}: {e}");
    }
    // $NODEID where the type cannot hold every node ID: an error at the value
    let text = eds(
        &[0x2000],
        "[2000]\nParameterName=x\nDataType=0x0005\nAccessType=rw\nDefaultValue=$NODEID+0x81\n",
    );
    let e = fails(&text);
    assert_eq!(
        e.to_string(),
        format!(
            "line {}, [2000] DefaultValue: 256 is outside the range of UNSIGNED8 (0..=255) (with $NODEID = 127)",
            line_in(&text, "[2000]", "DefaultValue")
        )
    );
}

#[test]
fn real32_and_real64_from_bits_or_decimal() {
    let var = |t: &str, v: &str| {
        format!("[2000]\nParameterName=k\nDataType={t}\nAccessType=rw\nDefaultValue={v}\n")
    };
    let thirty = 30.0f32.to_le_bytes().to_vec();
    for v in ["0x41F00000", "30.0", "30.", "3e1", "3.0E+1"] {
        let f = ok(&eds(&[0x2000], &var("0x0008", v)));
        assert_eq!(default_of(&f, 0x2000, 0), thirty, "{v}");
        assert!(f.warnings.is_empty(), "{v}: {:?}", f.warnings);
    }
    // a plain decimal integer: the number (python canopen), with a warning (Lely reads bits)
    let f = ok(&eds(&[0x2000], &var("0x0008", "30")));
    assert_eq!(default_of(&f, 0x2000, 0), thirty);
    assert!(
        f.warnings
            .iter()
            .any(|w| w.reason.contains("Lely reads it as IEEE 754 bits")),
        "{:?}",
        f.warnings
    );
    let f = ok(&eds(&[0x2000], &var("0x0008", "-0.1")));
    assert_eq!(default_of(&f, 0x2000, 0), (-0.1f32).to_le_bytes());
    let f = ok(&eds(&[0x2000], &var("0x0011", "0x4059000000000000")));
    assert_eq!(default_of(&f, 0x2000, 0), 100.0f64.to_le_bytes());
    let f = ok(&eds(&[0x2000], &var("0x0011", "1e300")));
    assert_eq!(default_of(&f, 0x2000, 0), 1e300f64.to_le_bytes());
    for (t, bad, why) in [
        ("0x0008", "0x141F00000", "more than the 32 bits of a REAL32"),
        ("0x0008", "1e39", "outside the range of REAL32"),
        ("0x0008", "$NODEID+1", "$NODEID in a REAL32 value"),
        ("0x0008", "3.0f", "not a number"),
    ] {
        let text = eds(&[0x2000], &var(t, bad));
        let e = fails(&text);
        assert_eq!(e.line, line_in(&text, "[2000]", "DefaultValue"), "{bad}");
        assert!(e.reason.contains(why), "{bad}: {e}");
    }
}

#[test]
fn integers_in_decimal_hex_and_octal_within_the_type() {
    let var = |t: &str, v: &str| {
        format!("[2000]\nParameterName=k\nDataType={t}\nAccessType=rw\nDefaultValue={v}\n")
    };
    for (t, v, want) in [
        ("0x0005", "255", vec![255u8]),
        ("0x0005", "0xFF", vec![255]),
        ("0x0005", "0377", vec![255]),
        ("0x0002", "-128", vec![0x80]),
        ("0x0002", "0x80", vec![0x80]), // two's complement pattern
        ("0x0003", "0xFFFF", vec![0xFF, 0xFF]),
        ("0x0004", "0x80000000", vec![0, 0, 0, 0x80]),
        ("0x0004", "-0x10", (-16i32).to_le_bytes().to_vec()),
        ("0x0010", "-1", vec![0xFF, 0xFF, 0xFF]),
        ("0x0016", "0xABCDEF", vec![0xEF, 0xCD, 0xAB]),
        ("0x0012", "-2", vec![0xFE, 0xFF, 0xFF, 0xFF, 0xFF]),
        ("0x001B", "0xFFFFFFFFFFFFFFFF", vec![0xFF; 8]),
        (
            "0x0015",
            "-9223372036854775808",
            i64::MIN.to_le_bytes().to_vec(),
        ),
        ("0x0001", "1", vec![1]),
        ("0x0001", "0", vec![0]),
        (
            "0x000C",
            "0x123456789ABC",
            vec![0xBC, 0x9A, 0x78, 0x56, 0x34, 0x12],
        ),
    ] {
        let f = ok(&eds(&[0x2000], &var(t, v)));
        assert_eq!(default_of(&f, 0x2000, 0), want, "{t} {v}");
    }
    // octal that differs from the decimal reading: read, with a warning
    let f = ok(&eds(&[0x2000], &var("0x0005", "010")));
    assert_eq!(default_of(&f, 0x2000, 0), vec![8]);
    assert!(
        f.warnings.iter().any(|w| w.reason.contains("octal")),
        "{:?}",
        f.warnings
    );
    // a leading 0 before an 8 or 9: not octal, the decimal is the only reading (warned)
    for (v, want) in [("08", 8u8), ("0099", 99)] {
        let text = eds(&[0x2000], &var("0x0005", v));
        let f = warned(
            &text,
            line_in(&text, "[2000]", "DefaultValue"),
            "read as the decimal",
        );
        assert_eq!(default_of(&f, 0x2000, 0), vec![want]);
    }
    for (t, v, why) in [
        (
            "0x0005",
            "256",
            "256 is outside the range of UNSIGNED8 (0..=255)",
        ),
        ("0x0005", "-1", "outside the range of UNSIGNED8"),
        ("0x0002", "0x100", "outside the range of INTEGER8"),
        ("0x0002", "128", "outside the range of INTEGER8"),
        ("0x0001", "2", "outside the range of BOOLEAN"),
        ("0x0005", "12a", "'12a' is not a number"),
        ("0x0005", "0b101", "not a number"),
        ("0x0005", "1.5", "the decimal 1.5 is not a UNSIGNED8 value"),
        (
            "0x001B",
            "0x10000000000000000",
            "outside the range of UNSIGNED64",
        ),
        ("0x000D", "0x1000000000000", "outside the 48 bits"),
    ] {
        let text = eds(&[0x2000], &var(t, v));
        let e = fails(&text);
        assert_eq!(
            (e.line, e.section.as_deref(), e.key.as_deref()),
            (
                line_in(&text, "[2000]", "DefaultValue"),
                Some("2000"),
                Some("DefaultValue")
            ),
            "{t} {v}"
        );
        assert!(e.reason.contains(why), "{t} {v}: {e}");
    }
}

#[test]
fn strings_octets_and_domains() {
    let var = |t: &str, v: &str| {
        format!("[2000]\nParameterName=k\nDataType={t}\nAccessType=rw\nDefaultValue={v}\n")
    };
    let f = ok(&eds(&[0x2000], &var("0x0009", "drive 1.0")));
    assert_eq!(default_of(&f, 0x2000, 0), b"drive 1.0");
    let f = ok(&eds(&[0x2000], &var("0x000B", "Aé")));
    assert_eq!(default_of(&f, 0x2000, 0), vec![0x41, 0, 0xE9, 0]);
    let f = ok(&eds(&[0x2000], &var("0x000A", "01 02 ab CD")));
    assert_eq!(default_of(&f, 0x2000, 0), vec![1, 2, 0xAB, 0xCD]);
    let f = ok(&eds(&[0x2000], &var("0x000F", "deadBEEF")));
    assert_eq!(default_of(&f, 0x2000, 0), vec![0xDE, 0xAD, 0xBE, 0xEF]);
    // an empty value is no value
    let f = ok(&eds(&[0x2000], &var("0x0009", "")));
    assert_eq!(f.sub(0x2000, 0).unwrap().default, None);
    for (v, why) in [
        ("abc", "odd number of hex digits"),
        // `0x` and digits is read (with a warning, below); `0x` and a non-digit is not
        ("0x0g", "no 0x prefix"),
        ("0 1", "odd digit before a space"),
    ] {
        let e = fails(&eds(&[0x2000], &var("0x000A", v)));
        assert!(e.reason.contains(why), "{v}: {e}");
    }
}

/// OCTET_STRING and DOMAIN values written as numbers with 0x (issue 33: SEVCON's Gen4 EDS
/// and DCFs, Ingenia's EVE files; python canopen 2.4.1 drops such a value, Lely's dcfchk does
/// not check it): read as their hex digits in pairs in the order written, a DCF's
/// ParameterValue too, each with a warning naming line, section and key and the bytes read;
/// the export writes them back as CiA 306 does (digit pairs, no 0x), which reads back to the
/// same dictionary without a warning.
#[test]
fn octet_strings_written_with_0x_read_with_a_warning_and_export_as_digit_pairs() {
    let body = "[2100]\nParameterName=System FIFO\nDataType=0x000F\nAccessType=rw\n\
                DefaultValue=0x000400000000002c00002401\nParameterValue=0x0\n\n\
                [2101]\nParameterName=Key\nDataType=0x000A\nAccessType=rw\nDefaultValue=0X0a0B\n";
    let text = eds(&[0x2100, 0x2101], body);
    let f = ok(&text);
    let at = |section: &str, key: &str| {
        f.warnings
            .iter()
            .find(|w| {
                w.section.as_deref() == Some(section)
                    && w.key.as_deref() == Some(key)
                    && w.reason.contains("written as a number with 0x")
            })
            .unwrap_or_else(|| panic!("no 0x warning at [{section}] {key}: {:?}", f.warnings))
    };
    let w = at("2100", "DefaultValue");
    assert_eq!(w.line, line_in(&text, "[2100]", "DefaultValue"));
    assert!(
        w.reason
            .contains("read as the 12 bytes 00 04 00 00 00 00 00 2c .."),
        "{w}"
    );
    assert!(
        w.reason
            .contains("CiA 306 writes octet strings as hex digit pairs without 0x"),
        "{w}"
    );
    let w = at("2100", "ParameterValue");
    assert_eq!(w.line, line_in(&text, "[2100]", "ParameterValue"));
    assert!(w.reason.contains("read as the 1 byte 00 "), "{w}");
    assert!(at("2101", "DefaultValue")
        .reason
        .contains("the 2 bytes 0a 0b"));
    let s = f.sub(0x2100, 0).unwrap();
    assert_eq!(s.parameter_value, Some(ValueExpr::Octets(vec![0])));
    assert_eq!(
        default_of(&f, 0x2100, 0),
        [0, 4, 0, 0, 0, 0, 0, 0x2c, 0, 0, 0x24, 1]
    );
    assert_eq!(default_of(&f, 0x2101, 0), [0x0a, 0x0b]);
    // the export writes digit pairs without 0x, and they read back the same, unwarned
    let (od, _) = ObjectDictionary::from_eds(&f, &common::info()).unwrap();
    let out = drive_protocol::od::eds::export(&od, &EdsMeta::default(), &mut |_| None);
    let again = ok(&out);
    assert!(
        !again.warnings.iter().any(|w| w.reason.contains("0x")
            && (w.section.as_deref() == Some("2100") || w.section.as_deref() == Some("2101"))),
        "{:?}",
        again.warnings
    );
    for (index, bytes) in [(0x2100u16, "000400000000002C00002401"), (0x2101, "0A0B")] {
        let sec = format!("[{index:04X}]");
        let line = line_in(&out, &sec, "DefaultValue");
        assert_eq!(
            out.lines().nth(line - 1),
            Some(format!("DefaultValue={bytes}").as_str()),
            "{out}"
        );
    }
    let (od2, _) = ObjectDictionary::from_eds(&again, &common::info()).unwrap();
    assert_eq!(
        drive_protocol::od::eds::objects_json(&od2),
        drive_protocol::od::eds::objects_json(&od)
    );
}

#[test]
fn domain_objects_with_upload_and_download_files() {
    let f = ok(&eds(
        &[0x1F50, 0x2FFF],
        "[1F50]\nParameterName=Program\nObjectType=0x2\nAccessType=wo\nDownloadFile=firmware.bin\n\n\
         [2FFF]\nParameterName=Log\nObjectType=0x2\nDataType=0x000F\nUploadFile=log.bin\n",
    ));
    let p = f.object(0x1F50).unwrap();
    assert_eq!(
        (p.code, p.data_type),
        (ObjectCode::Domain, Some(DataType::Domain))
    );
    assert_eq!(p.subs[0].download_file.as_deref(), Some("firmware.bin"));
    assert_eq!(p.subs[0].access, Access::Wo);
    let l = f.sub(0x2FFF, 0).unwrap();
    assert_eq!(l.upload_file.as_deref(), Some("log.bin"));
    // no AccessType on a DOMAIN: rw (Lely), with a warning
    assert_eq!(l.access, Access::Rw);
    assert!(f
        .warnings
        .iter()
        .any(|w| w.section.as_deref() == Some("2FFF") && w.key.as_deref() == Some("AccessType")));
}

#[test]
fn compact_sub_obj_expands_as_lely_names_it() {
    let body = "[1003]\nParameterName=Error field\nObjectType=0x8\nDataType=0x0007\nAccessType=ro\nDefaultValue=0\nCompactSubObj=3\n";
    let f = ok(&eds(&[0x1003], body));
    let o = f.object(0x1003).unwrap();
    assert_eq!(
        (o.code, o.data_type),
        (ObjectCode::Array, Some(DataType::U32))
    );
    let names: Vec<&str> = o.subs.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(
        names,
        vec![
            "NrOfObjects",
            "Error field1",
            "Error field2",
            "Error field3"
        ]
    );
    let s0 = o.sub(0).unwrap();
    assert_eq!((s0.data_type, s0.access), (DataType::U8, Access::Ro));
    assert_eq!(default_of(&f, 0x1003, 0), vec![3]);
    for s in &o.subs[1..] {
        assert_eq!((s.data_type, s.access), (DataType::U32, Access::Ro));
        assert_eq!(default_of(&f, 0x1003, s.sub), vec![0; 4]);
    }
    // [1003Name] names them, [1003Value] gives their ParameterValue (Lely)
    let f = ok(&eds(
        &[0x1003],
        &format!("{body}\n[1003Name]\nNrOfEntries=2\n1=Newest\n3=Oldest\n\n[1003Value]\nNrOfEntries=1\n2=0x8130\n"),
    ));
    let o = f.object(0x1003).unwrap();
    assert_eq!(o.sub(1).unwrap().name, "Newest");
    assert_eq!(o.sub(2).unwrap().name, "Error field2");
    assert_eq!(o.sub(3).unwrap().name, "Oldest");
    let pv = o.sub(2).unwrap().parameter_value.as_ref().unwrap();
    assert_eq!(bytes(pv, DataType::U32, None), 0x8130u32.to_le_bytes());
    assert_eq!(o.sub(1).unwrap().parameter_value, None);
    // a name beyond CompactSubObj, both SubNumber and CompactSubObj: errors
    let text = eds(
        &[0x1003],
        &format!("{body}\n[1003Name]\nNrOfEntries=1\n4=Beyond\n"),
    );
    let e = fails(&text);
    assert_eq!(
        (e.line, e.key.as_deref()),
        (line_of(&text, "4=Beyond"), Some("4"))
    );
    assert!(e.reason.contains("CompactSubObj=3"), "{e}");
    let e = fails(&eds(
        &[0x1003],
        &body.replace("CompactSubObj=3", "CompactSubObj=3\nSubNumber=4"),
    ));
    assert!(e.reason.contains("both SubNumber and CompactSubObj"), "{e}");
}

#[test]
fn object_links_dummy_usage_and_deftype_entries() {
    let f = ok(&eds(
        &[0x0002, 0x0007, 0x2000],
        "[0002]\nParameterName=INTEGER8\nObjectType=0x5\nDataType=0x0007\nAccessType=ro\nDefaultValue=8\n\n\
         [0007]\nParameterName=UNSIGNED32\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\nDefaultValue=32\n\n\
         [2000]\nParameterName=Group\nObjectType=0x9\nSubNumber=1\n\n[2000sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\nDefaultValue=0\n\n\
         [2000ObjectLinks]\nObjectLinks=2\n1=0x6040\n2=0x6041\n",
    ));
    let t = f.object(0x0002).unwrap();
    assert_eq!(t.code, ObjectCode::DefType);
    assert!(t.defines_type());
    assert!(f.object(0x0007).unwrap().defines_type());
    assert!(!f.object(0x2000).unwrap().defines_type());
    assert_eq!(f.object(0x2000).unwrap().object_links, vec![0x6040, 0x6041]);
}

#[test]
fn a_dcf_gives_parameter_values_denotations_and_commissioning() {
    for spelling in ["DeviceComissioning", "DeviceCommissioning"] {
        let f = ok(&eds(
            &[0x2000],
            &format!(
                "[{spelling}]\nNodeID=0x22\nNodeName=X axis\nBaudrate=500\nNetNumber=1\nNetworkName=mill\nCANopenManager=0\nLSS_SerialNumber=4711\n\n\
                 [2000]\nParameterName=Gain\nDenotation=X gain\nDataType=0x0004\nAccessType=rw\nDefaultValue=1\nParameterValue=-7\nLowLimit=-10\nHighLimit=10\n"
            ),
        ));
        let c = f.commissioning.as_ref().unwrap();
        assert_eq!(f.node_id(), Some(0x22));
        assert_eq!(
            (c.node_name.as_deref(), c.baudrate_kbit, c.net_number),
            (Some("X axis"), Some(500), Some(1))
        );
        assert_eq!(
            (
                c.network_name.as_deref(),
                c.canopen_manager,
                c.lss_serial_number
            ),
            (Some("mill"), Some(false), Some(4711))
        );
        let s = f.sub(0x2000, 0).unwrap();
        assert_eq!(s.denotation.as_deref(), Some("X gain"));
        assert_eq!(
            f.object(0x2000).unwrap().denotation.as_deref(),
            Some("X gain")
        );
        assert_eq!(
            bytes(s.parameter_value.as_ref().unwrap(), s.data_type, None),
            (-7i32).to_le_bytes()
        );
        assert_eq!(
            bytes(s.low.as_ref().unwrap(), s.data_type, None),
            (-10i32).to_le_bytes()
        );
    }
    let text = eds(&[], "[DeviceComissioning]\nNodeID=128\n");
    let f = warned(
        &text,
        line_of(&text, "NodeID"),
        "node ID 128 is outside 1..=127: read as not given",
    );
    assert_eq!(f.node_id(), None);
}

#[test]
fn limits_checked_against_each_other_and_the_values() {
    let var =
        |extra: &str| format!("[2000]\nParameterName=k\nDataType=0x0003\nAccessType=rw\n{extra}\n");
    let text = eds(&[0x2000], &var("LowLimit=10\nHighLimit=5\nDefaultValue=7"));
    let e = fails(&text);
    assert_eq!(
        e.to_string(),
        format!(
            "line {}, [2000] LowLimit: LowLimit is greater than HighLimit",
            line_in(&text, "[2000]", "LowLimit")
        )
    );
    // a default outside the limits: a warning at its line
    let text = eds(
        &[0x2000],
        &var("LowLimit=-5\nHighLimit=5\nDefaultValue=7\nParameterValue=-6"),
    );
    let f = ok(&text);
    let w: Vec<String> = f.warnings.iter().map(|w| w.to_string()).collect();
    assert!(
        w.contains(&format!(
            "line {}, [2000] DefaultValue: DefaultValue is above the limits",
            line_in(&text, "[2000]", "DefaultValue")
        )),
        "{w:?}"
    );
    assert!(
        w.contains(&format!(
            "line {}, [2000] ParameterValue: ParameterValue is below the limits",
            line_in(&text, "[2000]", "ParameterValue")
        )),
        "{w:?}"
    );
    // a limit beyond the type's range: the type's bound (Lely clamps), with a warning
    let f = ok(&eds(
        &[0x2000],
        &var("HighLimit=65536").replace("0x0003", "0x0006"),
    ));
    assert_eq!(
        bytes(
            f.sub(0x2000, 0).unwrap().high.as_ref().unwrap(),
            DataType::U16,
            None
        ),
        vec![0xFF, 0xFF]
    );
    assert!(f
        .warnings
        .iter()
        .any(|w| w.reason.contains("read as 65535")));
    // REAL32 limits compare as numbers, bits and decimals alike
    let e = fails(&eds(
        &[0x2000],
        &var("LowLimit=0x41F00000\nHighLimit=29.5").replace("0x0003", "0x0008"),
    ));
    assert!(
        e.reason.contains("LowLimit is greater than HighLimit"),
        "{e}"
    );
}

#[test]
fn object_lists_against_the_sections() {
    // listed but missing: read past (python canopen reads the sections), warned at the entry
    let text = eds(&[0x2000], "");
    let f = warned(
        &text,
        line_of(&text, "1=0x2000"),
        "object 0x2000 is listed but has no section [2000]; entry ignored",
    );
    assert!(f.object(0x2000).is_none());
    // a section no list names: kept, with a warning
    let text = eds(
        &[],
        "[2000]\nParameterName=k\nDataType=0x0005\nAccessType=rw\n",
    );
    let f = ok(&text);
    assert!(f.object(0x2000).is_some());
    assert!(
        f.warnings
            .iter()
            .any(|w| w.line == line_of(&text, "[2000]") && w.reason.contains("not named in")),
        "{:?}",
        f.warnings
    );
    // an entry missing from a list
    let text = eds(
        &[0x2000],
        "[2000]\nParameterName=k\nDataType=0x0005\nAccessType=rw\n",
    )
    .replace("1=0x2000", "2=0x2000");
    let f = warned(
        &text,
        line_of(&text, "[OptionalObjects]"),
        "SupportedObjects=1 but entry 1 is missing",
    );
    assert!(f.object(0x2000).is_some());
    // no SupportedObjects: the numbered entries are read
    let text = eds(
        &[0x2000],
        "[2000]\nParameterName=k\nDataType=0x0005\nAccessType=rw\n",
    )
    .replace(
        "[OptionalObjects]\nSupportedObjects=1\n",
        "[OptionalObjects]\n",
    );
    let f = warned(
        &text,
        line_of(&text, "[OptionalObjects]"),
        "the 1 numbered entries are read",
    );
    assert!(!f.warnings.iter().any(|w| w.reason.contains("not named in")));
    // no SupportedObjects and an entry numbered 699185165023 (the eds fuzz target's
    // out-of-memory input): the list is read up to 65535 entries, the missing ones said once,
    // the entry beyond ignored with its line; bounded in time and memory
    let text = eds(
        &[0x2000],
        "[2000]\nParameterName=k\nDataType=0x0005\nAccessType=rw\n",
    )
    .replace(
        "[OptionalObjects]\nSupportedObjects=1\n",
        "[OptionalObjects]\n699185165023=0x2000\n70000=0x2000\n65535=0x2000\n",
    );
    let f = warned(
        &text,
        line_of(&text, "[OptionalObjects]"),
        "SupportedObjects=65535 but 65533 entries are missing (the first: 2)",
    );
    assert!(f.object(0x2000).is_some());
    let beyond = f
        .warnings
        .iter()
        .filter(|w| w.reason.contains("entry beyond SupportedObjects=65535"))
        .count();
    assert!(beyond >= 2, "{:?}", f.warnings);
    assert!(f.warnings.len() < 50, "{} warnings", f.warnings.len());
}

#[test]
fn sub_number_against_the_sub_sections() {
    // more sections than SubNumber: all read (python canopen; Lely reads SubNumber of them)
    let text = eds(&[], "").replace("SubNumber=2", "SubNumber=1");
    let f = warned(
        &text,
        line_of(&text, "SubNumber=1"),
        "SubNumber=1 but 2 sub-index sections are present (sub 0, 1): all are read",
    );
    assert_eq!(f.object(0x1018).unwrap().subs.len(), 2);
    // fewer: read what is there, warn
    let text = eds(&[], "").replace("SubNumber=2", "SubNumber=5");
    let f = ok(&text);
    assert_eq!(f.object(0x1018).unwrap().subs.len(), 2);
    assert!(f
        .warnings
        .iter()
        .any(|w| w.line == line_of(&text, "SubNumber=5")));
}

/// Each broken case: the text and the whole expected message.
#[test]
fn broken_inline_cases_say_where_and_why() {
    let base = eds(&[], "");
    let cases: Vec<(String, &str, String)> = vec![
        (base.replace("[1018sub1]\nParameterName=Vendor-ID\nDataType=0x0007", "[1018sub1]\nParameterName=Vendor-ID\nDataType=0x0033"), "DataType=0x0033", "[1018sub1] DataType: unknown data type 0x0033".into()),
        (base.replace("[1018sub1]\nParameterName=Vendor-ID\nDataType=0x0007", "[1018sub1]\nParameterName=Vendor-ID\nDataType=0x0023"), "DataType=0x0023", "[1018sub1] DataType: complex data type 0x0023 (IDENTITY) on a sub-index: a sub-index holds a basic type".into()),
        (format!("{base}\n[1019sub1]\nParameterName=x\nDataType=0x0005\nAccessType=ro\n"), "[1019sub1]", "[1019sub1]: section without its object [1019]".into()),
        (base.replace("DefaultValue=0x00020192", "DefaultValue=0x0002019G"), "DefaultValue=0x0002019G", "[1000] DefaultValue: '0x0002019G' is not a number".into()),
        (base.replace("DefaultValue=0x00020192", "DefaultValue=0x100000000"), "DefaultValue=0x100000000", "[1000] DefaultValue: 4294967296 is outside the range of UNSIGNED32 (0..=4294967295)".into()),
        (base.replace("AccessType=ro\nDefaultValue=0x00020192", "AccessType=rx\nDefaultValue=0x00020192"), "AccessType=rx", "[1000] AccessType: 'rx' is not an access type (ro, wo, rw, rwr, rww, const)".into()),
        (base.replace("[1001]\nParameterName=Error register\nDataType=0x0005\nAccessType=ro", "[1001]\nParameterName=Error register\nDataType=0x0005"), "[1001]", "[1001] AccessType: AccessType is missing".into()),
        (base.replace("[1001]\nParameterName=Error register\n", "[1001]\n"), "[1001]", "[1001] ParameterName: ParameterName is missing".into()),
        (base.replace("ParameterName=Device type\nObjectType=0x7", "ParameterName=Device type\nObjectType=0x3"), "ObjectType=0x3", "[1000] ObjectType: object type 3 is none of NULL 0, DOMAIN 2, DEFTYPE 5, DEFSTRUCT 6, VAR 7, ARRAY 8, RECORD 9".into()),
        (base.replace("[1001]\nParameterName=Error register\nDataType=0x0005", "[1001]\nParameterName=Error register"), "[1001]", "[1001] DataType: DataType is missing".into()),
        (base.replace("[1018sub1]", "[1018subFF]"), "[1018subFF]", "[1018subFF]: sub-index 0xFF is out of range (0..=0xFE; 0xFF is reserved for the structure, CiA 301)".into()),
        (base.replace("[FileInfo]\n", "FileName=x\n[FileInfo]\n"), "FileName=x", "FileName: key=value before the first [section]".into()),
        (base.replace("EDSVersion=4.0", "EDSVersion 4.0"), "EDSVersion 4.0", "[FileInfo]: 'EDSVersion 4.0' is neither a [section], a key=value pair nor a comment".into()),
        (base.replace("[DeviceInfo]", "[DeviceInfo"), "[DeviceInfo", "section header '[DeviceInfo' has no closing ]".into()),
        (base.replace("[1000]\n", "[0000]\n"), "[0000]", "[0000]: object index 0x0000 does not exist".into()),
        (base.replace("ObjectType=0x9\nSubNumber=2", "ObjectType=0x9"), "", String::new()), // no SubNumber: warning only (see below)
    ];
    for (text, at, want) in cases {
        if want.is_empty() {
            let f = ok(&text);
            assert!(f
                .warnings
                .iter()
                .any(|w| w.reason.contains("SubNumber missing")));
            continue;
        }
        let e = fails(&text);
        // the last line that starts with `at` (the second of a duplicate)
        let line = text
            .lines()
            .enumerate()
            .filter(|(_, l)| l.starts_with(at))
            .last()
            .expect(at)
            .0
            + 1;
        let got = e.to_string();
        assert!(
            got == format!("line {line}, {want}") || got == format!("line {line}: {want}"),
            "want line {line}, {want}\n got {got}"
        );
    }
}

/// The files of tests/eds/lenient, one per class of deviation from CiA 306 that python
/// canopen or Lely read past: each reads, with a warning naming its line, section and key
/// (`; warns: line N, [section] key: text` in the file's head: the warning's display starts
/// with everything before the text and contains the text; `; warns: none`: no warning at
/// all), and the value it says (`; reads: IIII S HEX`: the default's wire bytes;
/// `reads-at-node-5`: with $NODEID = 5).
#[test]
fn lenient_files_read_with_a_warning_naming_line_section_and_key() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/eds/lenient");
    let mut n = 0;
    let mut paths: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    paths.sort();
    for path in paths {
        let text = decode_text(&std::fs::read(&path).unwrap());
        let f = parse(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let shown: Vec<String> = f.warnings.iter().map(|w| w.to_string()).collect();
        let mut expectations = 0;
        for l in text
            .lines()
            .map(|l| l.trim_start_matches('\u{FEFF}').trim_end())
        {
            if l == "; warns: none" {
                assert!(shown.is_empty(), "{}: {shown:?}", path.display());
                expectations += 1;
            } else if let Some(w) = l.strip_prefix("; warns: ") {
                let (at, what) = w.split_at(w.find("]").unwrap() + 1);
                let (key, what) = what.split_once(": ").unwrap();
                let head = format!("{at}{key}: ");
                assert!(
                    shown
                        .iter()
                        .any(|s| s.starts_with(&head) && s.contains(what)),
                    "{}: no warning '{head}...{what}...' in {shown:#?}",
                    path.display()
                );
                expectations += 1;
            } else if let Some((node, r)) = l
                .strip_prefix("; reads: ")
                .map(|r| (None, r))
                .or_else(|| l.strip_prefix("; reads-at-node-5: ").map(|r| (Some(5), r)))
            {
                let p: Vec<&str> = r.split(' ').collect();
                let (index, sub) = (
                    u16::from_str_radix(p[0], 16).unwrap(),
                    p[1].parse::<u8>().unwrap(),
                );
                let want: Vec<u8> = (0..p[2].len() / 2)
                    .map(|i| u8::from_str_radix(&p[2][2 * i..2 * i + 2], 16).unwrap())
                    .collect();
                let s = f
                    .sub(index, sub)
                    .unwrap_or_else(|| panic!("{}: no {r}", path.display()));
                let got = s
                    .default
                    .as_ref()
                    .unwrap()
                    .resolve(s.data_type, node)
                    .unwrap();
                assert_eq!(got, want, "{}: {r}", path.display());
                expectations += 1;
            }
        }
        assert!(expectations > 0, "{}: no expectations", path.display());
        n += 1;
    }
    assert!(n >= 14, "only {n} lenient files");
}

/// The files of tests/eds/broken: first line `; expect: <the whole message>`.
#[test]
fn broken_files_say_where_and_why() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/eds/broken");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let text = decode_text(&std::fs::read(&path).unwrap());
        let first = text.lines().next().unwrap_or("");
        let want = first.strip_prefix("; expect: ").unwrap_or_else(|| {
            panic!("{}: first line must be '; expect: MESSAGE'", path.display())
        });
        match parse(&text) {
            Ok(_) => panic!("{} parsed, expected: {want}", path.display()),
            Err(e) => assert_eq!(e.to_string(), want, "{}", path.display()),
        }
        n += 1;
    }
    assert!(n >= 4, "only {n} broken files");
}

#[test]
fn bounds_give_clear_errors() {
    // input size
    let mut big = eds(&[], "[Comments]\n");
    let line = "Line=".to_string() + &"x".repeat(1000) + "\n";
    while big.len() <= MAX_INPUT_BYTES {
        big.push_str(&line);
    }
    let e = fails(&big);
    assert!(e.reason.contains("more than the 8 MiB"), "{e}");
    assert!(e.line > 1 && e.line <= big.lines().count(), "{}", e.line);
    // objects
    let mut many = eds(&[], "");
    for i in 0..=MAX_OBJECTS {
        many.push_str(&format!(
            "[{:04X}]\nParameterName=x\nDataType=0x0005\nAccessType=rw\n",
            0x2000 + i
        ));
    }
    let e = fails(&many);
    assert!(
        e.reason
            .contains(&format!("more than {MAX_OBJECTS} objects")),
        "{e}"
    );
    // a value
    let text = eds(
        &[0x2000],
        &format!(
            "[2000]\nParameterName=x\nDataType=0x0009\nAccessType=rw\nDefaultValue={}\n",
            "y".repeat(MAX_VALUE_BYTES + 1)
        ),
    );
    let e = fails(&text);
    assert_eq!(
        (e.line, e.key.as_deref()),
        (
            line_in(&text, "[2000]", "DefaultValue"),
            Some("DefaultValue")
        )
    );
    // a large valid file: MAX_OBJECTS objects of 254 compact sub-indices would pass MAX_SUBS
    let mut wide = eds(&[], "");
    for i in 0..500 {
        wide.push_str(&format!("[{:04X}]\nParameterName=x\nObjectType=0x8\nDataType=0x0005\nAccessType=rw\nCompactSubObj=254\n", 0x2000 + i));
    }
    let e = fails(&wide);
    assert!(e.reason.contains("sub-indices in all objects"), "{e}");
}

#[test]
fn unknown_sections_and_keys_are_warnings() {
    let text = eds(&[0x2000], "[Tools]\nItems=0\n\n[2000]\nParameterName=k\nDataType=0x0005\nAccessType=rw\nFactor=0.5\nUnit=mm\n\n[2001sub0]\n");
    // [2001sub0] without [2001] is an error; drop it
    let text = text.replace("\n[2001sub0]\n", "\n");
    let f = ok(&text);
    assert!(f
        .warnings
        .iter()
        .any(|w| w.section.as_deref() == Some("Tools")));
    assert!(f.warnings.iter().any(
        |w| w.key.as_deref() == Some("Factor") && w.line == line_in(&text, "[2000]", "Factor")
    ));
}

// ------------------------------------------------------------------------------------------
// round trip of our own export

/// A dictionary with one of every kind our export writes: the standard objects, the test
/// drive's handler record, and stored REAL32, REAL64, INTEGER24, UNSIGNED64, string and DOMAIN
/// entries with awkward values and limits.
fn dictionary() -> ObjectDictionary {
    let mut od = common::od_with_handler();
    let entries = [
        Entry::var(0x2400, "kv_per_s", DataType::Real32, Access::Rw)
            .with_default(DefaultValue::Value(30.0f32.to_bits() as u64)),
        Entry::var(0x2401, "tiny", DataType::Real32, Access::Rw)
            .with_default(DefaultValue::Value((-1.0e-7f32).to_bits() as u64)),
        Entry::var(0x2402, "huge", DataType::Real32, Access::Rw)
            .with_default(DefaultValue::Value(3.4e38f32.to_bits() as u64)),
        Entry::var(0x2403, "scale", DataType::Real64, Access::Rw)
            .with_default(DefaultValue::Value(0.1f64.to_bits())),
        Entry::var(0x2404, "trim", DataType::I24, Access::Rw)
            .with_pdo(true)
            .with_limits(Some(-5000), Some(5000))
            .with_default(DefaultValue::Value(-42i64 as u64)),
        Entry::var(0x2405, "energy", DataType::U64, Access::Ro)
            .with_default(DefaultValue::Value(u64::MAX - 1)),
        Entry::var(0x2406, "axis name", DataType::VisibleString, Access::Rw)
            .with_default(DefaultValue::Bytes(b"X axis".to_vec())),
        Entry::var(0x2407, "blob", DataType::Domain, Access::Rw)
            .with_default(DefaultValue::Bytes(vec![0xDE, 0xAD, 0x00, 0x01])),
    ];
    for e in entries {
        od.insert(e).unwrap();
    }
    od
}

/// What an entry's EDS DefaultValue must resolve to: the handler's value for the drive's own
/// objects, else the dictionary's default.
fn want_default(e: &Entry, drive: &mut common::SimDrive, node_id: u8) -> Vec<u8> {
    use drive_protocol::Drive;
    if let Backing::Handler(tag) = e.backing {
        if e.access.readable() {
            let mut buf = [0u8; 8];
            let n = drive.read_object(tag, e.index, e.sub, &mut buf).unwrap();
            return buf[..n].to_vec();
        }
    }
    match &e.default {
        DefaultValue::Bytes(b) => b.clone(),
        _ => e.default_raw(node_id).to_le_bytes()[..e.dtype.size()].to_vec(),
    }
}

#[test]
fn our_exported_eds_parses_back_to_the_dictionary_in_both_real32_notations() {
    let node_id = 7;
    let od = dictionary();
    let node = Node::new(NodeConfig::new(node_id, common::info()).with_od(od)).unwrap();
    let mut drive = common::SimDrive {
        params: [0.0, 0.125, -0.0, 1.0],
        ..Default::default()
    };
    for real32 in [Real32Notation::Bits, Real32Notation::Decimal] {
        let meta = EdsMeta {
            node_id: Some(node_id),
            real32,
            ..EdsMeta::default()
        };
        let text = node.export_eds(&mut drive, &meta);
        let f = parse(&text).unwrap_or_else(|e| panic!("{real32:?}: {e}"));
        assert_eq!(f.node_id(), Some(node_id));
        let mut rows = 0;
        for (_, e) in node.od().iter() {
            let s = f
                .sub(e.index, e.sub)
                .unwrap_or_else(|| panic!("0x{:04X}sub{} missing", e.index, e.sub));
            let where_ = format!("{real32:?} 0x{:04X}sub{}", e.index, e.sub);
            assert_eq!(s.data_type, e.dtype, "{where_}");
            assert_eq!(s.access, e.access, "{where_}");
            assert_eq!(s.pdo_mapping, e.pdo, "{where_}");
            let code = f.object(e.index).unwrap().code;
            let want_code = match (e.otype, e.dtype) {
                (ObjType::Var, DataType::Domain) => ObjectCode::Domain,
                (ObjType::Var, _) => ObjectCode::Var,
                (ObjType::Array, _) => ObjectCode::Array,
                (ObjType::Record, _) => ObjectCode::Record,
            };
            assert_eq!(code, want_code, "{where_}");
            let got = s
                .default
                .as_ref()
                .unwrap_or_else(|| panic!("{where_}: no default"))
                .resolve(s.data_type, Some(node_id))
                .unwrap();
            assert_eq!(got, want_default(e, &mut drive, node_id), "{where_}");
            for (lim, want) in [(&s.low, e.low), (&s.high, e.high)] {
                match (lim, want) {
                    (Some(v), Some(w)) => {
                        let b = v.resolve(s.data_type, None).unwrap();
                        assert_eq!(b, w.to_le_bytes()[..b.len()], "{where_} limit");
                    }
                    (None, None) => {}
                    other => panic!("{where_}: limits {other:?}"),
                }
            }
            rows += 1;
        }
        assert_eq!(rows, node.od().len());
        let n: usize = f.objects.iter().map(|o| o.subs.len()).sum();
        assert_eq!(n, node.od().len(), "{real32:?}: no extra sub-indices");
        assert!(f.warnings.is_empty(), "{real32:?}: {:?}", f.warnings);
    }
}

/// A character that must not reach a terminal as is (checked here independently of the
/// renderer): a control character or a bidirectional control.
fn raw_control(c: char) -> bool {
    c.is_control()
        || matches!(c, '\u{200E}' | '\u{200F}' | '\u{202A}'..='\u{202E}' | '\u{2066}'..='\u{2069}')
}

/// Bad content in a key of object 0x2000 (line 3 of its section), for the quoting tests.
fn eds_with_bad_data_type(value: &str) -> (String, usize) {
    let text = eds(
        &[0x2000],
        &format!("[2000]\nParameterName=p\nDataType={value}\nAccessType=rw\n"),
    );
    // The last DataType= of the file is the one of [2000].
    let line = text
        .split('\n')
        .enumerate()
        .filter(|(_, l)| l.starts_with("DataType="))
        .map(|(i, _)| i + 1)
        .last()
        .expect("a DataType line");
    (text, line)
}

/// Issue 32, finding 8: the file's text in an error (a section, a key, a value the reason
/// quotes) is rendered by `drive_protocol::quote`: an escape sequence, a lone carriage return
/// or a 10 kB value give one line with the line number and the key, control characters
/// escaped, the length capped.
#[test]
fn file_content_in_an_error_is_escaped_and_capped_on_one_line() {
    let cases = [
        (
            "an escape sequence",
            "0x0007\u{1b}[2J\u{1b}[31m".to_string(),
        ),
        (
            "a lone carriage return",
            "0x0007\rAccessType=ro".to_string(),
        ),
        ("a 10 kB value", "7".repeat(10_000)),
        ("a bidi override", "\u{202e}7000x0".to_string()),
    ];
    for (what, value) in cases {
        let (text, line) = eds_with_bad_data_type(&value);
        let e = fails(&text);
        assert_eq!(e.line, line, "{what}: {e}");
        let msg = e.to_string();
        assert!(
            msg.starts_with(&format!("line {line}, [2000] DataType: ")),
            "{what}: {msg:?}"
        );
        assert!(
            !msg.chars().any(raw_control),
            "{what}: a raw control character in {msg:?}"
        );
        assert!(
            msg.chars().count() < 600,
            "{what}: {} characters",
            msg.len()
        );
    }
    // The escape is shown, not dropped: what was in the file can still be read.
    let (text, _) = eds_with_bad_data_type("0x0007\u{1b}[2J");
    assert!(fails(&text).to_string().contains("\\u{1b}[2J"));
    // A section header's text and a warning's key are rendered the same way.
    let e = fails(&eds(&[], "[20\u{1b}[2J00\n"));
    assert!(!e.to_string().chars().any(raw_control), "{e}");
    let f = ok(&eds(&[], "[FileInfo]\nX\u{1b}Y=1\nX\u{1b}Y=2\n"));
    for w in &f.warnings {
        assert!(!w.to_string().chars().any(raw_control), "{w}");
    }
}
