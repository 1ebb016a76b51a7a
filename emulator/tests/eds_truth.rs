//! `drive-emu eds` tells the truth and passes independent checkers.
//!
//! - Every object's DefaultValue is what the drive answers to an SDO upload right after boot
//!   (manufacturer REAL32 parameters from the preset and --set included), for every preset.
//! - `--node N` writes [DeviceComissioning] NodeID=N; [FileInfo] is complete.
//! - eds-utils' `eds-validate` and Lely's `dcfchk` accept the EDS of every preset for several
//!   node IDs, and Lely's `dcfgen` makes a master DCF from `tests/ros2/bus.yml` (the
//!   ros2_canopen bus configuration shown in the README). The checkers are pinned in
//!   tests/requirements.txt; a missing checker FAILS the test.
//! - python canopen reads the REAL32 defaults of `--real32 decimal`; canopen-monitor parses
//!   the EDS, and attaches the one written with `--canopen-monitor` to its node.

use drive_emu::cli::eds::{eds_text, EdsArgs, Real32Arg};
use drive_emu::drive::axis_drive::AxisDrive;
use drive_emu::presets::{preset_names, AxisConfig};
use drive_protocol::{CanFrame, Node};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Sections of an INI file: name -> key -> value (keys as written).
fn parse_ini(text: &str) -> BTreeMap<String, BTreeMap<String, String>> {
    let mut out: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    let mut cur = String::new();
    for line in text.lines() {
        let line = line.trim();
        if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            cur = name.to_string();
            out.entry(cur.clone()).or_default();
        } else if let Some((k, v)) = line.split_once('=') {
            out.entry(cur.clone())
                .or_default()
                .insert(k.trim().to_string(), v.trim().to_string());
        }
    }
    out
}

fn args(preset: &str, node: Option<u8>, set: &[&str]) -> EdsArgs {
    EdsArgs {
        preset: preset.into(),
        node,
        set: set.iter().map(|s| s.to_string()).collect(),
        worn: false,
        real32: Real32Arg::Bits,
        canopen_monitor: false,
        from: None,
        objects_base: None,
        profile: None,
        quirk: vec![],
        no_quirk: vec![],
    }
}

/// SDO upload (expedited or segmented) through the node, as a master would do it.
fn sdo_upload(node: &mut Node, drive: &mut AxisDrive, index: u16, sub: u8) -> Result<Vec<u8>, u32> {
    let id = u32::from(node.node_id());
    let i = index.to_le_bytes();
    let ask = |node: &mut Node, drive: &mut AxisDrive, req: [u8; 8]| -> [u8; 8] {
        node.handle(&CanFrame::new(0x600 + id, &req), 0, drive);
        let mut answer = None;
        while let Some(f) = node.pop_tx() {
            if f.id == 0x580 + id {
                answer = Some(f.data);
            }
        }
        answer.expect("an SDO answer")
    };
    let r = ask(node, drive, [0x40, i[0], i[1], sub, 0, 0, 0, 0]);
    match r[0] {
        0x80 => Err(u32::from_le_bytes([r[4], r[5], r[6], r[7]])),
        cs if cs & 0xE2 == 0x42 => {
            let n = if cs & 0x01 != 0 {
                4 - usize::from((cs >> 2) & 3)
            } else {
                4
            };
            Ok(r[4..4 + n].to_vec())
        }
        0x41 => {
            let mut data = Vec::new();
            let mut toggle = 0u8;
            loop {
                let s = ask(node, drive, [0x60 | toggle, 0, 0, 0, 0, 0, 0, 0]);
                assert_eq!(s[0] & 0xE0, 0x00, "segment answer {s:02X?}");
                let n = 7 - usize::from((s[0] >> 1) & 7);
                data.extend_from_slice(&s[1..1 + n]);
                if s[0] & 1 != 0 {
                    return Ok(data);
                }
                toggle ^= 0x10;
            }
        }
        x => panic!("unexpected SDO answer {x:#x}"),
    }
}

/// The EDS DefaultValue of an object in the bytes an SDO upload returns.
fn eds_default_bytes(value: &str, data_type: u8, size: usize, node_id: u8) -> Vec<u8> {
    if data_type == 0x09 {
        return value.as_bytes().to_vec();
    }
    let v = value.replace(' ', "");
    let (base, v) = match v.strip_prefix("$NODEID+") {
        Some(rest) => (i64::from(node_id), rest.to_string()),
        None => (0, v),
    };
    let n: i64 = if let Some(h) = v.strip_prefix("0x").or_else(|| v.strip_prefix("0X")) {
        i64::from_str_radix(h, 16).unwrap_or_else(|e| panic!("{value}: {e}"))
    } else {
        v.parse().unwrap_or_else(|e| panic!("{value}: {e}"))
    };
    (base + n).to_le_bytes()[..size].to_vec()
}

#[test]
fn every_default_in_the_eds_is_what_an_sdo_read_returns() {
    let cases: Vec<(String, Vec<&str>)> = preset_names()
        .map(|p| (p.to_string(), vec![]))
        .chain([
            ("cnc1".to_string(), vec!["backlash_mm=0.05", "kv_per_s=20"]),
            ("cnc3".to_string(), vec!["kv_per_s=12.5"]),
        ])
        .collect();
    for (preset, set) in &cases {
        let node_id = 9;
        let eds = eds_text(&args(preset, Some(node_id), set)).unwrap();
        let ini = parse_ini(&eds);
        let cfg = AxisConfig::from_preset(preset)
            .unwrap()
            .with_overrides(set.iter().copied())
            .unwrap();
        // what `run` serves: healthy unless the overrides give a gap
        let cfg = drive_emu::drive::machine::served(
            cfg,
            drive_emu::drive::machine::sets_ask_for_wear(set),
        );
        let mut drive = AxisDrive::from_config(&cfg).unwrap();
        let mut node = drive_emu::drive::node(&mut drive, node_id).unwrap();
        node.boot(0);
        while node.pop_tx().is_some() {}
        let mut compared = 0;
        let mut params = 0;
        let entries: Vec<_> = node.od().iter().map(|(_, e)| e.clone()).collect();
        for o in &entries {
            let section = if o.otype == drive_protocol::od::ObjType::Var {
                format!("{:04X}", o.index)
            } else {
                format!("{:04X}sub{:X}", o.index, o.sub)
            };
            let entry = &ini[&section];
            if !o.access.readable() {
                continue;
            }
            // Process values (actual position, statusword, loop statistics) are measured, not
            // configured: their EDS default is the table's, the drive reports what it sees.
            let process_value = o.access == drive_protocol::od::Access::Ro
                && (o.pdo || o.index == 0x2100 || o.index == 0x1001);
            if process_value {
                continue;
            }
            let dv = &entry["DefaultValue"];
            let got = sdo_upload(&mut node, &mut drive, o.index, o.sub)
                .unwrap_or_else(|a| panic!("{preset} {section}: SDO abort {a:#010X}"));
            let want = eds_default_bytes(dv, o.dtype.code() as u8, got.len(), node_id);
            assert_eq!(
                got, want,
                "{preset} {set:?} [{section}] {}: EDS DefaultValue={dv}, SDO read {got:02X?}",
                entry["ParameterName"]
            );
            if (0x2000..0x2100).contains(&o.index) {
                params += 1;
            }
            compared += 1;
        }
        assert!(compared > 150, "{preset}: compared {compared} objects");
        let objects = drive_physics::params::PARAMS
            .iter()
            .filter(|p| p.object_offset.is_some())
            .count();
        assert_eq!(
            params, objects,
            "{preset}: every manufacturer parameter compared"
        );
        // the parameters are not all zero: the preset's values are in the EDS
        let kv =
            u32::from_str_radix(ini["2007"]["DefaultValue"].trim_start_matches("0x"), 16).unwrap();
        let want_kv = set
            .iter()
            .find_map(|s| s.strip_prefix("kv_per_s="))
            .map_or(cfg.kv_per_s as f32, |v| v.parse().unwrap());
        assert_eq!(f32::from_bits(kv), want_kv, "{preset}: 0x2007 kv_per_s");
    }
}

#[test]
fn node_id_and_file_info_are_written() {
    let e5 = eds_text(&args("cnc1", Some(5), &[])).unwrap();
    let e6 = eds_text(&args("cnc1", Some(6), &[])).unwrap();
    assert_ne!(e5, e6);
    let (i5, i6) = (parse_ini(&e5), parse_ini(&e6));
    assert_eq!(i5["DeviceComissioning"]["NodeID"], "5");
    assert_eq!(i6["DeviceComissioning"]["NodeID"], "6");
    assert_eq!(i5["DeviceComissioning"]["LSS_SerialNumber"], "5");
    let generic = parse_ini(&eds_text(&args("cnc1", None, &[])).unwrap());
    assert!(!generic.contains_key("DeviceComissioning"));
    for key in [
        "FileName",
        "FileVersion",
        "FileRevision",
        "EDSVersion",
        "Description",
        "CreationTime",
        "CreationDate",
        "CreatedBy",
        "ModificationTime",
        "ModificationDate",
        "ModifiedBy",
    ] {
        let v = i5["FileInfo"].get(key).map(String::as_str).unwrap_or("");
        assert!(!v.is_empty(), "[FileInfo] {key} missing");
    }
    let (t, d) = drive_emu::cli::eds::eds_time_date(1_795_305_600 + 13 * 3600 + 5 * 60);
    assert_eq!((t.as_str(), d.as_str()), ("01:05PM", "11-22-2026"));
    let (t, d) = drive_emu::cli::eds::eds_time_date(951_782_400); // 2000-02-29 00:00
    assert_eq!((t.as_str(), d.as_str()), ("12:00AM", "02-29-2000"));
}

fn tool(name: &str) -> PathBuf {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .map(|d| d.join(name))
        .find(|p| p.is_file())
        .unwrap_or_else(|| {
            panic!(
                "`{name}` not found on PATH: run `pip install -r tests/requirements.txt` \
                 (eds-utils, dcf-tools)"
            )
        })
}

fn run_tool(name: &str, args: &[&str], dir: &Path) -> String {
    let out = Command::new(tool(name))
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.status.success(),
        "{name} {args:?} failed ({}):\n{text}",
        out.status
    );
    text
}

#[test]
fn eds_validate_dcfchk_and_dcfgen_accept_the_eds() {
    let dir = std::env::temp_dir().join(format!("drive-emu-eds-check-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for preset in preset_names() {
        for node in [None, Some(1u8), Some(127)] {
            let eds = eds_text(&args(preset, node, &["kv_per_s=25"])).unwrap();
            let file = format!("{preset}-{node:?}.eds");
            std::fs::write(dir.join(&file), &eds).unwrap();
            let out = run_tool("eds-validate", &[&file], &dir);
            assert!(out.trim().is_empty(), "eds-validate {file}:\n{out}");
            let mut a = vec![file.clone()];
            if node.is_none() {
                a = vec!["--node_id".into(), "7".into(), file.clone()];
            }
            let a: Vec<&str> = a.iter().map(String::as_str).collect();
            let out = run_tool("dcfchk", &a, &dir);
            assert!(!out.contains("Warning"), "dcfchk {file}:\n{out}");
        }
    }
    // ros2_canopen: the README's bus.yml through Lely's dcfgen, then dcfchk on its output
    let eds = eds_text(&args("cnc1", Some(5), &[])).unwrap();
    std::fs::write(dir.join("drive-emu-cnc1.eds"), eds).unwrap();
    let bus = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../tests/ros2/bus.yml"
    ))
    .unwrap()
    .replace("@BUS_CONFIG_PATH@", &dir.display().to_string());
    std::fs::write(dir.join("bus.yml"), bus).unwrap();
    let dir_s = dir.display().to_string();
    run_tool("dcfgen", &["-r", "-d", &dir_s, "bus.yml"], &dir);
    let master = std::fs::read_to_string(dir.join("master.dcf")).expect("dcfgen wrote master.dcf");
    assert!(
        master.contains("[1F22]"),
        "the master DCF has the concise DCFs"
    );
    assert!(
        std::fs::metadata(dir.join("x_axis.bin"))
            .map(|m| m.len() > 0)
            .unwrap_or(false),
        "dcfgen wrote the node's concise DCF"
    );
    let out = run_tool("dcfchk", &["master.dcf"], &dir);
    assert!(!out.contains("Warning"), "dcfchk master.dcf:\n{out}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Run a python snippet with `argv[1..]`; its stdout parsed as JSON.
fn python_json(script: &str, args: &[&str]) -> serde_json::Value {
    let out = Command::new("python3")
        .arg("-c")
        .arg(script)
        .args(args)
        .output()
        .expect("python3");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "python failed ({}): {}{}",
        out.status,
        stdout,
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&stdout).unwrap_or_else(|e| panic!("{e}: {stdout}"))
}

/// python canopen (pinned 2.4.1) reads REAL32 defaults only as decimals (`float(value)`; a
/// hex default becomes None): `eds --real32 decimal` gives it every manufacturer REAL32
/// default as the drive has it, the same numbers as the bit patterns Lely reads, for every
/// preset with and without --set; eds-validate accepts that form too.
#[test]
fn python_canopen_reads_the_real32_defaults_of_the_decimal_eds() {
    let dir = std::env::temp_dir().join(format!("drive-emu-eds-py-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    const SCRIPT: &str = r#"
import canopen, json, sys
od = canopen.import_od(sys.argv[1], int(sys.argv[2]))
out = {}
for obj in od.values():
    if isinstance(obj, canopen.objectdictionary.ODVariable):
        if obj.data_type == 0x8:
            out[f"{obj.index:04X}"] = obj.default
    else:
        for sub in obj.values():
            if sub.data_type == 0x8:
                out[f"{obj.index:04X}sub{sub.subindex:X}"] = sub.default
print(json.dumps(out))
"#;
    for preset in preset_names() {
        for set in [vec![], vec!["kv_per_s=25", "speed_ti_ms=4"]] {
            let bits = eds_text(&args(preset, Some(5), &set)).unwrap();
            let mut a = args(preset, Some(5), &set);
            a.real32 = Real32Arg::Decimal;
            let decimal = eds_text(&a).unwrap();
            let file = dir.join(format!("{preset}-{}.eds", set.len()));
            std::fs::write(&file, &decimal).unwrap();
            let py = python_json(SCRIPT, &[file.to_str().unwrap(), "5"]);
            let ini = parse_ini(&bits);
            let mut n = 0;
            for (section, keys) in &ini {
                if keys.get("DataType").map(String::as_str) != Some("0x0008") {
                    continue;
                }
                let hex = keys["DefaultValue"].trim_start_matches("0x");
                let want = f32::from_bits(u32::from_str_radix(hex, 16).unwrap());
                let got = py[section.as_str()].as_f64().unwrap_or_else(|| {
                    panic!(
                        "{preset} {set:?}: [{section}] read as {}",
                        py[section.as_str()]
                    )
                });
                assert_eq!(got as f32, want, "{preset} {set:?}: [{section}]");
                n += 1;
            }
            assert!(n >= 10, "{preset}: {n} REAL32 objects");
            let kv = py["2007"].as_f64().unwrap();
            let want_kv = if set.is_empty() {
                AxisConfig::from_preset(preset).unwrap().kv_per_s
            } else {
                25.0
            };
            assert_eq!(
                kv as f32, want_kv as f32,
                "{preset} {set:?}: 0x2007 kv_per_s"
            );
            let name = file.file_name().unwrap().to_str().unwrap();
            let out = run_tool("eds-validate", &[name], &dir);
            assert!(out.trim().is_empty(), "eds-validate {name}:\n{out}");
        }
    }
    // cnc1 as the issue names it: 0x2007 = 30.0
    let mut a = args("cnc1", Some(5), &[]);
    a.real32 = Real32Arg::Decimal;
    assert!(eds_text(&a).unwrap().contains("[2007]\nParameterName=kv_per_s\nObjectType=0x7\nDataType=0x0008\nAccessType=rw\nDefaultValue=30.0\n"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// canopen-monitor (pinned 4.1.0), as it loads an EDS (`canopen_monitor.parse.eds`): every
/// object of ours parsed with its name and data type, [FileInfo]'s date read, and with the EDS
/// attached to the node, our TPDO1 decoded through its PDO parser. (It cannot attach a CiA 306
/// EDS to a node by itself: it reads the node ID from a section it spells
/// `DeviceCommissioning` with a key `NodeId`, where CiA 306 writes `[DeviceComissioning]
/// NodeID`, and otherwise from object 0x2101's default, OreSat's own convention; `eds
/// --canopen-monitor` adds its section, see the next test and the README.)
#[test]
fn canopen_monitor_parses_the_eds_and_decodes_its_tpdo() {
    let dir = std::env::temp_dir().join(format!("drive-emu-eds-cm-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    const SCRIPT: &str = r#"
import json, sys
from canopen_monitor.parse import eds as E, pdo as P
od = E.load_eds_file(sys.argv[1])
objs = {}
for key, idx in od.indices.items():
    objs[f"{int(key, 16):04X}"] = [idx.parameter_name, str(idx.data_type) if hasattr(idx, "data_type") else None]
    for sub, s in (idx.sub_indices or {}).items():
        objs[f"{int(key, 16):04X}sub{sub:X}"] = [s.parameter_name, str(s.data_type) if hasattr(s, "data_type") else None]
print(json.dumps({
    "objects": objs,
    "date": str(od.file_info.creation_date),
    "tpdo1": P.parse(0x180 + 5, bytes([0x37, 0x02, 0x01]), od),
}))
"#;
    for preset in preset_names() {
        let eds = eds_text(&args(preset, Some(5), &[])).unwrap();
        let file = dir.join(format!("{preset}.eds"));
        std::fs::write(&file, &eds).unwrap();
        let cm = python_json(SCRIPT, &[file.to_str().unwrap()]);
        let ini = parse_ini(&eds);
        let mut n = 0;
        for (section, keys) in &ini {
            let Some(name) = keys.get("ParameterName") else {
                continue;
            };
            let got = &cm["objects"][section.as_str()];
            // canopen-monitor turns any value of hex digits alone into a number: 0x6092:1's
            // CiA 402 name "Feed" comes back as 0xFEED.
            match u64::from_str_radix(name, 16) {
                Ok(v) => assert_eq!(got[0].as_u64(), Some(v), "{preset} [{section}]: {got}"),
                Err(_) => assert_eq!(
                    got[0].as_str(),
                    Some(name.as_str()),
                    "{preset} [{section}]: {got}"
                ),
            }
            if let Some(dt) = keys.get("DataType") {
                // canopen-monitor keeps 0x-prefixed values as text
                assert_eq!(got[1].as_str(), Some(dt.as_str()), "{preset} [{section}]");
            }
            n += 1;
        }
        assert!(n > 100, "{preset}: {n} objects");
        let date = &ini["FileInfo"]["CreationDate"]; // MM-DD-YYYY
        let (m, rest) = date.split_at(2);
        let iso = format!("{}-{m}-{}", &rest[4..], &rest[1..3]);
        assert_eq!(cm["date"].as_str(), Some(iso.as_str()), "{preset}");
        assert_eq!(
            cm["tpdo1"].as_str(),
            Some("Statusword - 567 Modes of operation display - 1"),
            "{preset}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `eds --node 5 --canopen-monitor`: canopen-monitor 4.1.0, loading its EDS directory as the
/// application does (`load_eds_files`, keyed by the node ID it reads), attaches the file to
/// node 5 and names the node; the same EDS without the flag it attaches to no node ID (the
/// text `0x0` of object 0x2101). python canopen still reads the CiA 306 `[DeviceComissioning]
/// NodeID` of the flagged file; eds-validate rejects its extra section, as the help says.
#[test]
fn canopen_monitor_attaches_the_eds_written_for_it_to_its_node() {
    const SCRIPT: &str = r#"
import json, sys
from canopen_monitor.parse import eds as E, CANOpenParser
configs = E.load_eds_files(sys.argv[1])
names = {}
for node_id in configs:
    if isinstance(node_id, int):
        class M: pass
        m = M(); m.node_id = node_id
        names[str(node_id)] = CANOpenParser(configs).get_name(m)
print(json.dumps({"node_ids": [str(k) for k in configs], "names": names}))
"#;
    for (flag, node) in [(false, 5u8), (true, 5), (true, 42)] {
        let dir = std::env::temp_dir().join(format!(
            "drive-emu-eds-cm-attach-{}-{flag}-{node}",
            std::process::id()
        ));
        std::fs::create_dir_all(&dir).unwrap();
        let mut a = args("cnc1", Some(node), &[]);
        a.canopen_monitor = flag;
        let eds = eds_text(&a).unwrap();
        let file = dir.join("drive.eds");
        std::fs::write(&file, &eds).unwrap();
        let cm = python_json(SCRIPT, &[dir.to_str().unwrap()]);
        let ids: Vec<&str> = cm["node_ids"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        if flag {
            assert_eq!(ids, [node.to_string()], "--canopen-monitor --node {node}");
            assert_eq!(
                cm["names"][node.to_string()].as_str(),
                Some(format!("drive-emu node {node}").as_str()),
                "{cm}"
            );
            // The CiA 306 section is still there and still what python canopen reads.
            let py = python_json(
                "import canopen, json, sys; print(json.dumps(canopen.import_od(sys.argv[1]).node_id))",
                &[file.to_str().unwrap()],
            );
            assert_eq!(py.as_u64(), Some(u64::from(node)));
            assert!(eds.contains(&format!("[DeviceComissioning]\nNodeID={node}\n")));
            let out = Command::new(tool("eds-validate"))
                .arg(&file)
                .output()
                .expect("eds-validate");
            let text = format!(
                "{}{}",
                String::from_utf8_lossy(&out.stdout),
                String::from_utf8_lossy(&out.stderr)
            );
            assert!(
                !out.status.success() && text.contains("Unknown header: [DeviceCommissioning]"),
                "eds-validate on the extra section: {out:?}"
            );
        } else {
            assert!(
                !ids.contains(&node.to_string().as_str()),
                "canopen-monitor attached a CiA 306 EDS by itself: {ids:?} (drop the flag?)"
            );
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}

/// docs/objects.md is the dictionary of the default drive (cnc1, node 5), generated.
#[test]
fn docs_objects_md_is_current() {
    use drive_protocol::od::{eds::objects_markdown, Backing, Entry};
    use drive_protocol::Drive;
    let mut drive = AxisDrive::from_config(&AxisConfig::from_preset("cnc1").unwrap()).unwrap();
    let node = drive_emu::drive::node(&mut drive, 5).unwrap();
    let intro =
        "Generated from the object dictionary of the default drive (`drive-emu run`: preset \
                 cnc1, node ID 5): the standard objects of `protocol/src/od/standard.rs` and the \
                 emulator's own of `runtime/src/drive/objects.rs`. Do not edit; run \
                 `UPDATE_OBJECTS_MD=1 cargo test -p drive-emu --test eds_truth`.";
    let mut buf = [0u8; 8];
    let mut value_of = |e: &Entry| match e.backing {
        Backing::Handler(tag) if e.access.readable() => drive
            .read_object(tag, e.index, e.sub, &mut buf)
            .ok()
            .map(|n| e.decode(&buf[..n])),
        _ => None,
    };
    let md = objects_markdown(node.od(), intro, &mut value_of);
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/objects.md");
    if std::env::var_os("UPDATE_OBJECTS_MD").is_some() {
        std::fs::write(path, &md).unwrap();
    }
    let on_disk = std::fs::read_to_string(path).unwrap_or_default();
    assert!(
        on_disk == md,
        "docs/objects.md is stale: run UPDATE_OBJECTS_MD=1 cargo test -p drive-emu --test eds_truth"
    );
}

/// Issue 33, item 4: the EDS describes the drive `run` serves: a healthy axis (the backlash
/// object 0x2000 at 0) unless wear is asked for, by --worn (the preset's gap) or a gap of its
/// own in --set.
#[test]
fn the_eds_describes_the_healthy_axis_unless_wear_is_asked_for() {
    let backlash = |a: EdsArgs| -> f32 {
        let ini = parse_ini(&eds_text(&a).unwrap());
        let v = &ini["2000"]["DefaultValue"];
        f32::from_bits(u32::from_str_radix(v.trim_start_matches("0x"), 16).unwrap())
    };
    for preset in preset_names() {
        let cfg = AxisConfig::from_preset(preset).unwrap();
        let shipped = cfg.backlash_mm.or(cfg.backlash_deg).unwrap() as f32;
        assert!(
            shipped > 0.0,
            "{preset}: the preset is the paper's worn machine"
        );
        assert_eq!(backlash(args(preset, None, &[])), 0.0, "{preset}");
        let worn = EdsArgs {
            worn: true,
            ..args(preset, None, &[])
        };
        assert_eq!(backlash(worn), shipped, "{preset}");
    }
    assert_eq!(backlash(args("cnc1", None, &["backlash_mm=0.05"])), 0.05);
    assert_eq!(backlash(args("cnc3", None, &["backlash_deg=0.01"])), 0.01);
    // other overrides leave the axis healthy
    assert_eq!(backlash(args("cnc1", None, &["kv_per_s=20"])), 0.0);
}
