//! The corpus of real vendor EDS/DCF files (`tests/eds/vendors/`, sources in SOURCES.md there)
//! against our parser, python canopen 2.4.1 and Lely's dcfchk (dcf-tools 2.4.2), all pinned in
//! tests/requirements.txt. A missing python3, canopen or dcfchk FAILS with what to install.
use drive_protocol::od::eds_parse::{decode_text, parse, EdsFile, ObjectCode};
use drive_protocol::od::DataType;
use std::path::{Path, PathBuf};
use std::process::Command;

const NODE_ID: u8 = 5;

fn vendor_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/eds/vendors")
}

fn vendor_files() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(vendor_dir())
        .expect("tests/eds/vendors")
        .map(|e| e.unwrap().path())
        .filter(|p| matches!(p.extension().and_then(|e| e.to_str()), Some("eds" | "dcf")))
        .collect();
    v.sort();
    assert!(
        v.len() >= 5,
        "at least five vendor files, found {}",
        v.len()
    );
    v
}

fn load(path: &Path) -> EdsFile {
    let text = decode_text(&std::fs::read(path).unwrap());
    parse(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

#[test]
fn every_vendor_file_parses_as_a_cia402_drive() {
    let mut vendors = std::collections::BTreeSet::new();
    for path in vendor_files() {
        let f = load(&path);
        let name = path.file_name().unwrap().to_string_lossy();
        for w in &f.warnings {
            println!("{name}: warning: {w}");
        }
        // a CiA 402 drive: identity, device type, controlword, statusword, modes
        for index in [0x1000u16, 0x1001, 0x1018, 0x6040, 0x6041, 0x6060, 0x6061] {
            assert!(f.object(index).is_some(), "{name}: 0x{index:04X} missing");
        }
        assert!(f.objects.windows(2).all(|w| w[0].index < w[1].index));
        let mut n = 0;
        for o in &f.objects {
            assert!(
                o.subs.windows(2).all(|w| w[0].sub < w[1].sub),
                "{name}: 0x{:04X} subs unsorted",
                o.index
            );
            if o.code == ObjectCode::Var {
                assert_eq!(o.subs.len(), 1);
                assert_eq!(o.subs[0].sub, 0);
            }
            for s in &o.subs {
                for v in [&s.default, &s.parameter_value, &s.low, &s.high]
                    .into_iter()
                    .flatten()
                {
                    let b = v
                        .resolve(s.data_type, Some(NODE_ID))
                        .unwrap_or_else(|e| panic!("{name}: 0x{:04X}sub{:X}: {e}", o.index, s.sub));
                    if !s.data_type.variable() {
                        assert_eq!(
                            b.len(),
                            s.data_type.size(),
                            "{name}: 0x{:04X}sub{:X}",
                            o.index,
                            s.sub
                        );
                    }
                    n += 1;
                }
            }
        }
        assert!(n > 50, "{name}: only {n} values");
        // the identity the master checks at boot
        if let (Some(v), Some(s)) = (f.device_info.vendor_number, f.sub(0x1018, 1)) {
            if let Some(d) = &s.default {
                let b = d.resolve(DataType::U32, Some(NODE_ID)).unwrap();
                let id = u32::from_le_bytes(b.try_into().unwrap());
                if id != 0 {
                    assert_eq!(id, v, "{name}: 0x1018:1 and VendorNumber disagree");
                }
            }
        }
        vendors.insert(
            f.device_info
                .vendor_name
                .clone()
                .unwrap_or_else(|| name.to_string()),
        );
    }
    assert!(vendors.len() >= 5, "five vendors: {vendors:?}");
}

#[test]
fn every_vendor_file_is_in_sources_md() {
    let sources = std::fs::read_to_string(vendor_dir().join("SOURCES.md")).unwrap();
    for path in vendor_files() {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        assert!(
            sources.contains(&format!("`{name}`")),
            "{name} not described in SOURCES.md"
        );
    }
}

/// Our parse as the JSON compare_eds.py reads.
fn ours_json(f: &EdsFile) -> String {
    let mut s = String::from("[");
    for (i, o) in f.objects.iter().enumerate() {
        if i > 0 {
            s.push(',');
        }
        let compact =
            o.code.structured() && o.subs.first().is_some_and(|s| s.name == "NrOfObjects");
        s.push_str(&format!(
            "{{\"index\":{},\"code\":{},\"compact\":{},\"subs\":[",
            o.index, o.code as u8, compact
        ));
        for (j, sub) in o.subs.iter().enumerate() {
            if j > 0 {
                s.push(',');
            }
            let default = match &sub.default {
                Some(v) => format!(
                    "\"{}\"",
                    hex(&v.resolve(sub.data_type, Some(NODE_ID)).unwrap())
                ),
                None => "null".into(),
            };
            s.push_str(&format!(
                "{{\"sub\":{},\"data_type\":{},\"access\":\"{}\",\"default\":{}}}",
                sub.sub,
                sub.data_type.code(),
                sub.access.eds(),
                default
            ));
        }
        s.push_str("]}");
    }
    s.push(']');
    s
}

fn run_python(script: &str, args: &[&Path], extra: &[&str]) -> std::process::Output {
    let out = Command::new("python3")
        .arg(script)
        .args(args)
        .args(extra)
        .output()
        .unwrap_or_else(|e| panic!("python3 not runnable ({e}); install python3 and `pip install -r tests/requirements.txt`"));
    if out.status.code() == Some(2) {
        panic!(
            "python canopen missing: run `pip install -r tests/requirements.txt` (canopen==2.4.1)\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    out
}

#[test]
fn python_canopen_reads_the_vendor_files_as_we_do() {
    let dir =
        std::env::temp_dir().join(format!("drive-protocol-eds-vendors-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/compare_eds.py");
    let mut failures = Vec::new();
    for path in vendor_files() {
        let f = load(&path);
        let json = dir.join(format!(
            "{}.json",
            path.file_name().unwrap().to_string_lossy()
        ));
        std::fs::write(&json, ours_json(&f)).unwrap();
        let out = run_python(script, &[&path, &json], &[&NODE_ID.to_string()]);
        print!("{}", String::from_utf8_lossy(&out.stdout));
        if !out.status.success() {
            failures.push(format!(
                "{}:\n{}",
                path.display(),
                String::from_utf8_lossy(&out.stderr)
            ));
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        failures.is_empty(),
        "python canopen reads differently:\n{}",
        failures.join("\n")
    );
}

/// dcfchk's complaints about a file, one per line ("UserWarning: ..." and a final exception).
fn dcfchk_complaints(path: &Path) -> Vec<String> {
    let out = Command::new("dcfchk")
        .arg("-n")
        .arg(NODE_ID.to_string())
        .arg(path)
        .output()
        .unwrap_or_else(|e| {
            panic!("dcfchk not runnable ({e}): `pip install -r tests/requirements.txt` (dcf-tools==2.4.2)")
        });
    let stderr = String::from_utf8_lossy(&out.stderr);
    let mut v: Vec<String> = stderr
        .lines()
        .filter_map(|l| {
            l.split_once("UserWarning: ")
                .map(|(_, m)| m.trim().to_string())
                .or_else(|| {
                    (!l.starts_with(' ') && (l.contains("Error:") || l.contains("Exception:")))
                        .then(|| l.trim().to_string())
                })
        })
        .collect();
    v.push(format!("exit {}", out.status.code().unwrap_or(-1)));
    v
}

#[test]
fn lely_dcfchk_accepts_each_vendor_file_or_its_complaints_are_listed() {
    let expected_path = vendor_dir().join("dcfchk-complaints.txt");
    let mut got = String::from(
        "# What Lely's dcfchk (dcf-tools 2.4.2, `dcfchk -n 5 FILE`) says about each vendor file.\n\
         # Generated by protocol/tests/eds_vendors.rs (UPDATE_DCFCHK=1 rewrites it); a change fails the test.\n",
    );
    for path in vendor_files() {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        for c in dcfchk_complaints(&path) {
            got.push_str(&format!("{name}: {c}\n"));
        }
    }
    if std::env::var_os("UPDATE_DCFCHK").is_some() {
        std::fs::write(&expected_path, &got).unwrap();
    }
    let expected = std::fs::read_to_string(&expected_path).unwrap_or_default();
    assert!(
        expected == got,
        "dcfchk says something else than {} lists (UPDATE_DCFCHK=1 to rewrite after checking):\n{got}",
        expected_path.display()
    );
}

/// Four broken copies of each vendor file, each refused with the line, section and key at
/// fault (issue 33): an unknown data type, a missing AccessType, a default outside its type,
/// a line that is no key=value. Each is made in the file's device type object [1000] (every
/// file has one), keeping its line ends.
#[test]
fn four_broken_copies_of_each_vendor_file_are_refused_with_line_section_and_key() {
    for path in vendor_files() {
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let text = decode_text(&std::fs::read(&path).unwrap());
        let eol = if text.contains("\r\n") { "\r\n" } else { "\n" };
        let lines: Vec<&str> = text.split('\n').map(|l| l.trim_end_matches('\r')).collect();
        let header = lines
            .iter()
            .position(|l| l.trim().eq_ignore_ascii_case("[1000]"))
            .unwrap_or_else(|| panic!("{name}: no [1000]"));
        let end = (header + 1..lines.len())
            .find(|&i| lines[i].trim_start().starts_with('['))
            .unwrap_or(lines.len());
        let key_line = |key: &str| {
            (header + 1..end).find(|&i| {
                lines[i]
                    .split('=')
                    .next()
                    .is_some_and(|k| k.trim().eq_ignore_ascii_case(key))
            })
        };
        let join = |v: &[String]| v.join(eol);
        let owned: Vec<String> = lines.iter().map(|l| l.to_string()).collect();
        // (text, 1-based line, key, what the reason says)
        let mut cases: Vec<(String, usize, Option<&str>, &str)> = Vec::new();
        let dt = key_line("DataType").unwrap_or_else(|| panic!("{name}: [1000] DataType"));
        let mut v = owned.clone();
        v[dt] = "DataType=0x0033".into();
        cases.push((
            join(&v),
            dt + 1,
            Some("DataType"),
            "unknown data type 0x0033",
        ));
        let at = key_line("AccessType").unwrap_or_else(|| panic!("{name}: [1000] AccessType"));
        let mut v = owned.clone();
        v.remove(at);
        cases.push((
            join(&v),
            header + 1,
            Some("AccessType"),
            "AccessType is missing",
        ));
        let mut v = owned.clone();
        let dv = match key_line("DefaultValue") {
            Some(i) => {
                v[i] = "DefaultValue=0x1FFFFFFFF".into();
                i
            }
            None => {
                v.insert(header + 1, "DefaultValue=0x1FFFFFFFF".into());
                header + 1
            }
        };
        cases.push((
            join(&v),
            dv + 1,
            Some("DefaultValue"),
            "outside the range of UNSIGNED32",
        ));
        let mut v = owned.clone();
        v.insert(
            header + 1,
            "this line is no key=value pair".replace('=', " "),
        );
        cases.push((
            join(&v),
            header + 2,
            None,
            "is neither a [section], a key=value pair nor a comment",
        ));
        for (broken, line, key, why) in cases {
            let e = match parse(&broken) {
                Ok(_) => panic!("{name}: a copy with '{why}' parsed"),
                Err(e) => e,
            };
            assert_eq!(
                (e.line, e.section.as_deref(), e.key.as_deref()),
                (
                    line,
                    Some(lines[header].trim().trim_matches(['[', ']'])),
                    key
                ),
                "{name}: {e}"
            );
            assert!(e.reason.contains(why), "{name}: {e}");
        }
    }
}
