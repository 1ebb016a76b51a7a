//! The exported EDS loads in python canopen (pinned in tests/requirements.txt) with every
//! object's type and access as the object table says. Missing python/canopen FAILS.
use drive_protocol::od::eds::objects_json;
use std::process::Command;

mod common;

#[test]
fn python_canopen_loads_the_eds() {
    let node = drive_protocol::Node::new(7, common::info()).unwrap();
    let eds = node.export_eds();
    let dir = std::env::temp_dir().join(format!("drive-protocol-eds-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let eds_path = dir.join("drive.eds");
    let json_path = dir.join("objects.json");
    std::fs::write(&eds_path, &eds).unwrap();
    std::fs::write(&json_path, objects_json()).unwrap();
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

#[test]
fn eds_is_generated_from_the_table() {
    let node = drive_protocol::Node::new(7, common::info()).unwrap();
    let eds = node.export_eds();
    for o in drive_protocol::od::OBJECTS {
        let section = if o.otype == drive_protocol::od::ObjType::Var {
            format!("[{:04X}]", o.index)
        } else {
            format!("[{:04X}sub{:X}]", o.index, o.sub)
        };
        assert!(eds.contains(&section), "{section} missing");
    }
    assert!(eds.contains("ParameterName=backlash_mm"));
    assert!(eds.contains("DefaultValue=$NODEID+0x180"));
    // a rotary axis names its parameters in degrees
    let mut info = common::info();
    info.rotary = true;
    let eds = drive_protocol::Node::new(7, info).unwrap().export_eds();
    assert!(eds.contains("ParameterName=backlash_deg"));
}

#[test]
fn docs_objects_md_is_current() {
    let md = drive_protocol::od::eds::objects_markdown(common::ID, &common::info());
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/objects.md");
    if std::env::var_os("UPDATE_OBJECTS_MD").is_some() {
        std::fs::write(path, &md).unwrap();
    }
    let on_disk = std::fs::read_to_string(path).unwrap_or_default();
    assert!(
        on_disk == md,
        "docs/objects.md is stale: run UPDATE_OBJECTS_MD=1 cargo test -p drive-protocol --test eds"
    );
}
