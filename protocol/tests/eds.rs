//! The exported EDS loads in python canopen (pinned in tests/requirements.txt) with every
//! object's type and access as the dictionary says. Missing python/canopen FAILS.
use drive_protocol::od::eds::{objects_json, EdsMeta};
use drive_protocol::od::ObjType;
use drive_protocol::{Node, NodeConfig};
use std::process::Command;

mod common;

fn node() -> Node {
    Node::new(NodeConfig::new(7, common::info()).with_od(common::od_with_handler())).unwrap()
}

#[test]
fn python_canopen_loads_the_eds() {
    let node = node();
    let eds = node.export_eds(&mut common::SimDrive::default(), &EdsMeta::default());
    let dir = std::env::temp_dir().join(format!("drive-protocol-eds-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let eds_path = dir.join("drive.eds");
    let json_path = dir.join("objects.json");
    std::fs::write(&eds_path, &eds).unwrap();
    std::fs::write(&json_path, objects_json(node.od())).unwrap();
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/python/check_eds.py");
    let out = Command::new("python3")
        .arg(script)
        .arg(&eds_path)
        .arg(&json_path)
        .arg("7")
        .output()
        .unwrap_or_else(|e| panic!("python3 not runnable ({e}); install python3 and `pip install -r tests/requirements.txt`"));
    let stderr = String::from_utf8_lossy(&out.stderr);
    if out.status.code() == Some(2) {
        panic!("python canopen missing: run `pip install -r tests/requirements.txt` (canopen==2.4.1)\n{stderr}");
    }
    assert!(
        out.status.success(),
        "EDS check failed:\n{stderr}\n{}",
        String::from_utf8_lossy(&out.stdout)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// Every visible entry is in the EDS, the handler objects with the value the drive answers
/// (not the dictionary's default), `$NODEID` forms kept; a removed entry is not there.
#[test]
fn eds_is_generated_from_the_dictionary() {
    let mut drive = common::SimDrive::default();
    drive.params[2] = 0.25;
    let mut cfg = NodeConfig::new(7, common::info()).with_od(common::od_with_handler());
    cfg.od.remove(0x60E4, 1);
    let node = Node::new(cfg).unwrap();
    let eds = node.export_eds(&mut drive, &EdsMeta::default());
    for (_, e) in node.od().iter() {
        let section = if e.otype == ObjType::Var {
            format!("[{:04X}]", e.index)
        } else {
            format!("[{:04X}sub{:X}]", e.index, e.sub)
        };
        assert!(eds.contains(&section), "{section} missing");
    }
    assert!(!eds.contains("[60E4sub1]"), "a removed entry stays out");
    assert!(eds.contains("DefaultValue=$NODEID+0x180"));
    let sub2 = eds.split("[2200sub2]").nth(1).unwrap();
    assert!(
        sub2.contains(&format!("DefaultValue=0x{:08X}", 0.25f32.to_bits())),
        "the handler's value: {sub2}"
    );
}
