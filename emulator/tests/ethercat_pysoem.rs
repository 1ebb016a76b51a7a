//! `drive-emu run --ethercat` against an independent master: SOEM through pysoem
//! (tests/python/ethercat_pysoem.py) on a veth pair of the host, three slaves in one process:
//! config_init finds them with their SII identity equal to CoE 0x1018, SDO read/write,
//! complete access of 0x1C12, the abort of a missing object, SAFE-OP and OP with the working
//! counter SOEM expects in every cycle, CiA 402 enable and a CSP move whose 0x6064 comes back
//! in the process data.
//!
//! Needs root (a veth pair, a raw socket) and pysoem (tests/requirements.txt). As root, or in
//! CI (`CI` set), a veth pair that cannot be made fails the test; as a user outside CI it says
//! why and does nothing. The veth pair has a name of this process and is deleted at the end,
//! also when the test fails.

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

struct Veth {
    master: String,
}

impl Veth {
    fn create(master: &str, slave: &str) -> Result<Veth, String> {
        let ip = |args: &[&str]| {
            let out = Command::new("ip")
                .args(args)
                .output()
                .map_err(|e| format!("ip {}: {e}", args.join(" ")))?;
            if out.status.success() {
                Ok(())
            } else {
                Err(format!(
                    "ip {}: {}",
                    args.join(" "),
                    String::from_utf8_lossy(&out.stderr)
                ))
            }
        };
        ip(&["link", "add", master, "type", "veth", "peer", "name", slave])?;
        let v = Veth {
            master: master.into(),
        };
        ip(&["link", "set", master, "up"])?;
        ip(&["link", "set", slave, "up"])?;
        Ok(v)
    }
}

impl Drop for Veth {
    fn drop(&mut self) {
        // deleting one end deletes the pair
        let _ = Command::new("ip")
            .args(["link", "del", &self.master])
            .status();
    }
}

/// The emulator process, stopped (SIGINT) and reaped when dropped.
struct Emulator(Child);

impl Drop for Emulator {
    fn drop(&mut self) {
        // SAFETY: a signal to our own child, by its pid.
        unsafe {
            libc::kill(self.0.id() as libc::pid_t, libc::SIGINT);
        }
        let _ = self.0.wait();
    }
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

#[test]
fn pysoem_configures_three_slaves_and_moves_them_in_csp() {
    // SAFETY: geteuid has no preconditions.
    let root = unsafe { libc::geteuid() } == 0;
    let ci = std::env::var_os("CI").is_some();
    if !root && !ci {
        eprintln!("ethercat_pysoem: not root and not in CI: a veth pair needs root; not run");
        return;
    }
    let tag = std::process::id() % 100_000;
    let (m_name, s_name) = (format!("ecm{tag}"), format!("ecs{tag}"));
    let _veth = Veth::create(&m_name, &s_name)
        .unwrap_or_else(|e| panic!("cannot create the veth pair (root: {root}): {e}"));
    let dir = std::env::temp_dir().join(format!("drive-emu-ethercat-{tag}"));
    std::fs::create_dir_all(&dir).unwrap();
    let machine = dir.join("machine.toml");
    std::fs::write(
        &machine,
        "tick_hz = 1000\n[[axis]]\nnode_id = 1\npreset = \"cnc1\"\n[[axis]]\nnode_id = 2\n\
         preset = \"cnc1\"\n[[axis]]\nnode_id = 3\npreset = \"cnc1\"\n",
    )
    .unwrap();
    let child = Command::new(env!("CARGO_BIN_EXE_drive-emu"))
        .args(["run", "--ethercat", &s_name, "--config"])
        .arg(&machine)
        .args(["--ready", "--json", "--rt-priority", "0", "--no-mlock"])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("drive-emu runs");
    let mut emu = Emulator(child);
    let mut stdout = BufReader::new(emu.0.stdout.take().unwrap());
    let mut line = String::new();
    stdout.read_line(&mut line).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    let ready: serde_json::Value =
        serde_json::from_str(&line).unwrap_or_else(|e| panic!("ready line {line:?}: {e}"));
    assert_eq!(ready["event"], "ready");
    assert_eq!(ready["nodes"].as_array().map(Vec::len), Some(3));

    let script = repo().join("tests/python/ethercat_pysoem.py");
    let out = Command::new("timeout")
        .arg("180")
        .arg("python3")
        .arg(&script)
        .args([&m_name, "3"])
        .output()
        .expect("python3 runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "the pysoem master failed ({}):\n{}\n{}\n(pysoem missing? pip install -r tests/requirements.txt)",
        out.status,
        text,
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_str(text.lines().last().unwrap_or(""))
        .unwrap_or_else(|e| panic!("pysoem's report {text:?}: {e}"));
    assert_eq!(report["slaves"], 3);
    assert_eq!(report["expected_wkc"], 9);
    assert!(report["cycles"].as_u64().unwrap() > 1000);
    for p in report["position_actual"].as_array().unwrap() {
        let p = p.as_i64().unwrap();
        assert!((p - 2000).abs() <= 20, "0x6064 {p}");
    }
    // stopped: the emulator's own count of what it answered and refused
    // SAFETY: a signal to our own child, by its pid.
    unsafe {
        libc::kill(emu.0.id() as libc::pid_t, libc::SIGINT);
    }
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut stdout, &mut rest).unwrap();
    let stats: serde_json::Value =
        serde_json::from_str(rest.trim()).unwrap_or_else(|e| panic!("statistics {rest:?}: {e}"));
    assert!(stats["frames"].as_u64().unwrap() > 1000, "{stats}");
    assert_eq!(stats["refused"], 0, "{stats}");
    assert_eq!(stats["socket_errors"], 0, "{stats}");
}
