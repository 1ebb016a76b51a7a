//! `drive-emu run --ethercat` against a second, independent master: the ethercrab crate (pure
//! Rust, its own SII, CoE and PDI code; nothing shared with SOEM or with this project), used
//! as its users write it, on a veth pair of the host. One emulator process per slave count
//! (1 and 3 axes): discovery, the identity ethercrab read from the SII equal to CoE 0x1018,
//! an SDO write and read back, the abort of a missing object, PRE-OP -> SAFE-OP -> OP with
//! the working counter of the group's LRW (3 per slave) in every cycle, CiA 402 enable from
//! the controlword in the process data (0x6041 comes back) and a CSP move whose 0x6064 follows
//! in the inputs. A few hundred cycles of 1 ms.
//!
//! The three slaves run with distributed clocks as ethercrab's DC example sets them up: DC
//! SYNC0 chosen (0x1C32:1 = 2) and `DcSync::Sync0` in PRE-OP, the PDI's cycles with ethercrab's
//! FRMW of the reference clock's system time (`tx_rx_sync_system_time`: drift control in the
//! slaves behind it, their 0x092C read back small), `configure_dc_sync` with SYNC0 at 1 ms,
//! SAFE-OP, `request_into_op` and `tx_rx_dc` cycles; at OP each slave says DC SYNC0 in 0x1C32:1
//! and its drive is locked to SYNC0 (0x2100:8 = 2, period 1000 us), and moves.
//!
//! Root (or CI, where a veth pair that cannot be made fails the test): see ethercat_rig.

mod ethercat_rig;
use ethercat_rig::*;

use std::sync::Arc;
use std::time::Duration;

use ethercrab::error::{CoeAbortCode, Error, MailboxError};
use ethercrab::std::ethercat_now;
use ethercrab::subdevice_group::{DcConfiguration, Op, PreOp};
use ethercrab::{
    DcSync, DefaultLock, MainDevice, MainDeviceConfig, PduStorage, RegisterAddress, SubDeviceGroup,
    Timeouts,
};

const MAX_SUBDEVICES: usize = 4;
const PDI_LEN: usize = 64;
const MAX_FRAMES: usize = 16;
const MAX_PDU_DATA: usize = PduStorage::element_size(1100);

// one storage per test: a PduStorage splits once per process (cargo test runs both in one)
static PDU_ONE: PduStorage<MAX_FRAMES, MAX_PDU_DATA> = PduStorage::new();
static PDU_THREE: PduStorage<MAX_FRAMES, MAX_PDU_DATA> = PduStorage::new();

#[test]
fn ethercrab_drives_one_slave() {
    run(1, 'a', &PDU_ONE, false);
}

#[test]
fn ethercrab_drives_three_slaves_in_one_process_with_dc_sync0() {
    run(3, 'b', &PDU_THREE, true);
}

fn run(n: usize, tag: char, storage: &'static PduStorage<MAX_FRAMES, MAX_PDU_DATA>, dc: bool) {
    if !may_run("ethercat_ethercrab") {
        return;
    }
    let veth = Veth::create(tag).unwrap_or_else(|e| panic!("cannot create the veth pair: {e}"));
    let dir = std::env::temp_dir().join(format!("drive-emu-ethercrab-{}-{n}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let machine = dir.join("machine.toml");
    let mut text = String::from("tick_hz = 1000\n");
    for k in 1..=n {
        text.push_str(&format!("[[axis]]\nnode_id = {k}\npreset = \"cnc1\"\n"));
    }
    std::fs::write(&machine, text).unwrap();
    let mut emu = Emulator::start(&veth.slave, &["--config", machine.to_str().unwrap()]);
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(emu.ready["nodes"].as_array().map(Vec::len), Some(n));

    let (tx, rx, pdu_loop) = storage.try_split().expect("split once");
    let iface = veth.master.clone();
    // ethercrab's TX/RX task on a thread of its own (its socket is driven by async-io)
    std::thread::spawn(move || {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        let task = ethercrab::std::tx_rx_task(&iface, tx, rx).expect("raw socket on the veth");
        let _ = rt.block_on(task);
    });
    let maindevice = Arc::new(MainDevice::new(
        pdu_loop,
        Timeouts {
            wait_loop_delay: Duration::from_millis(2),
            mailbox_response: Duration::from_millis(2000),
            state_transition: Duration::from_secs(10),
            pdu: Duration::from_millis(500),
            // the default (10 ms) is a wire's: a loaded host answers later
            eeprom: Duration::from_millis(1000),
            mailbox_echo: Duration::from_millis(1000),
        },
        MainDeviceConfig {
            dc_static_sync_iterations: 100,
            ..MainDeviceConfig::default()
        },
    ));
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let positions = rt
        .block_on(scenario(&maindevice, n, dc))
        .unwrap_or_else(|e| panic!("ethercrab: {e}"));
    for p in positions {
        assert!((p - 2000).abs() <= 20, "0x6064 {p}");
    }
    let (stats, _) = emu.stop();
    assert!(stats["frames"].as_u64().unwrap() > 300, "{stats}");
    assert_eq!(stats["refused"], 0, "{stats}");
    assert_eq!(stats["socket_errors"], 0, "{stats}");
    if dc {
        // the loop locked to SYNC0 (how many cycles it took depends on the host's load; the
        // scenario read 0x2100 locked over CoE already)
        assert!(
            stats["sync0_locked_cycles"].as_u64().unwrap() > 0,
            "{stats}"
        );
    }
}

fn statusword(i: &[u8]) -> u16 {
    u16::from_le_bytes([i[0], i[1]])
}

fn position(i: &[u8]) -> i32 {
    i32::from_le_bytes([i[2], i[3], i[4], i[5]])
}

type Group<S, DC> = SubDeviceGroup<MAX_SUBDEVICES, PDI_LEN, DefaultLock, S, DC>;

fn e(what: &str) -> impl Fn(Error) -> String {
    let what = what.to_string();
    move |err: Error| format!("{what}: {err}")
}

/// What an ethercrab user writes; returns each slave's 0x6064 at the end. With `dc`, as
/// ethercrab's DC example: SYNC0 at 1 ms, the clocks aligned first.
async fn scenario(md: &MainDevice<'_>, n: usize, dc: bool) -> Result<Vec<i32>, String> {
    let mut group = md
        .init_single_group::<MAX_SUBDEVICES, PDI_LEN>(ethercat_now)
        .await
        .map_err(e("init_single_group"))?;
    if group.len() != n {
        return Err(format!("discovered {} slaves, expected {n}", group.len()));
    }
    check_slaves(md, &group).await?;
    if !dc {
        let group = group.into_safe_op(md).await.map_err(e("SAFE-OP"))?;
        check_image(md, &group)?;
        let group = group.into_op(md).await.map_err(e("OP"))?;
        let pos = enable_and_move(md, &group, n, async || {
            group.tx_rx(md).await.map(|r| r.working_counter)
        })
        .await?;
        let group = group.into_safe_op(md).await.map_err(e("OP -> SAFE-OP"))?;
        let group = group
            .into_pre_op(md)
            .await
            .map_err(e("SAFE-OP -> PRE-OP"))?;
        group.into_init(md).await.map_err(e("PRE-OP -> INIT"))?;
        return Ok(pos);
    }
    for mut s in group.iter_mut(md) {
        s.sdo_write(0x1C32, 1, 2u16)
            .await
            .map_err(e("0x1C32:1 = 2"))?;
        s.set_dc_sync(DcSync::Sync0);
    }
    let group = group.into_pre_op_pdi(md).await.map_err(e("PRE-OP PDI"))?;
    // the clocks aligned with ethercrab's FRMW of the reference's system time
    let mut tick = tokio::time::interval(Duration::from_millis(1));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    for _ in 0..200 {
        tick.tick().await;
        group
            .tx_rx_sync_system_time(md)
            .await
            .map_err(e("tx_rx_sync_system_time"))?;
    }
    for (k, s) in group.iter(md).enumerate() {
        let raw = s
            .register_read::<u32>(RegisterAddress::DcSystemTimeDifference)
            .await
            .map_err(e("0x092C"))?;
        // sign in bit 31, magnitude in bits 0..30
        let ns = raw & 0x7FFF_FFFF;
        if ns > 1000 {
            return Err(format!(
                "slave {k}: 0x092C {raw:#010x}: {ns} ns off the reference"
            ));
        }
    }
    let group = group
        .configure_dc_sync(
            md,
            DcConfiguration {
                start_delay: Duration::from_millis(100),
                sync0_period: Duration::from_millis(1),
                sync0_shift: Duration::ZERO,
            },
        )
        .await
        .map_err(e("configure_dc_sync"))?;
    let group = group.into_safe_op(md).await.map_err(e("SAFE-OP"))?;
    check_image(md, &group)?;
    let group = group.request_into_op(md).await.map_err(e("request OP"))?;
    let mut op = false;
    for _ in 0..5000 {
        tick.tick().await;
        if group.tx_rx_dc(md).await.map_err(e("tx_rx_dc"))?.all_op() {
            op = true;
            break;
        }
    }
    if !op {
        return Err("OP not reached with DC".into());
    }
    for (k, s) in group.iter(md).enumerate() {
        let sync = s.sdo_read::<u16>(0x1C32, 1).await.map_err(e("0x1C32:1"))?;
        if sync != 2 {
            return Err(format!(
                "slave {k} at OP: sync mode {sync}, not DC SYNC0 (2)"
            ));
        }
    }
    let pos = enable_and_move(md, &group, n, async || {
        group.tx_rx_dc(md).await.map(|r| r.working_counter)
    })
    .await?;
    // the drive's cycle locked to SYNC0 (16 good pulses after 8 for the period)
    let mut lock = Vec::new();
    for _ in 0..20 {
        lock.clear();
        for s in group.iter(md) {
            let state = s.sdo_read::<u32>(0x2100, 8).await.map_err(e("0x2100:8"))?;
            let period = s
                .sdo_read::<u32>(0x2100, 10)
                .await
                .map_err(e("0x2100:10"))?;
            lock.push((state, period));
        }
        if lock.iter().all(|&l| l == (2, 1000)) {
            break;
        }
        for _ in 0..100 {
            tick.tick().await;
            group.tx_rx_dc(md).await.map_err(e("tx_rx_dc"))?;
        }
    }
    if !lock.iter().all(|&l| l == (2, 1000)) {
        return Err(format!("0x2100 (lock state, SYNC period us): {lock:?}"));
    }
    let group = group.into_safe_op(md).await.map_err(e("OP -> SAFE-OP"))?;
    let group = group
        .into_pre_op(md)
        .await
        .map_err(e("SAFE-OP -> PRE-OP"))?;
    group.into_init(md).await.map_err(e("PRE-OP -> INIT"))?;
    Ok(pos)
}

/// In PRE-OP: identity, SDO write and read back, the abort of a missing object, CSP.
async fn check_slaves(
    md: &MainDevice<'_>,
    group: &Group<PreOp, ethercrab::subdevice_group::NoDc>,
) -> Result<(), String> {
    for (k, s) in group.iter(md).enumerate() {
        // the identity ethercrab read from the SII, against the dictionary's 0x1018
        let id = s.identity();
        let mut coe = [0u32; 4];
        for (sub, v) in coe.iter_mut().enumerate() {
            *v = s
                .sdo_read::<u32>(0x1018, sub as u8 + 1)
                .await
                .map_err(e("0x1018"))?;
        }
        if [id.vendor_id, id.product_id, id.revision, id.serial] != coe {
            return Err(format!(
                "slave {k}: SII identity {id:?} != CoE 0x1018 {coe:x?}"
            ));
        }
        let target = -1234 - k as i32;
        s.sdo_write(0x607A, 0, target)
            .await
            .map_err(e("0x607A write"))?;
        let got = s.sdo_read::<i32>(0x607A, 0).await.map_err(e("0x607A"))?;
        if got != target {
            return Err(format!("slave {k}: 0x607A read back {got}"));
        }
        match s.sdo_read::<u32>(0x2FFF, 0).await {
            Err(Error::Mailbox(MailboxError::Aborted {
                code: CoeAbortCode::NotFound,
                ..
            })) => {}
            other => return Err(format!("slave {k}: a read of 0x2FFF gave {other:?}")),
        }
        // CSP
        s.sdo_write(0x6060, 0, 8i8).await.map_err(e("0x6060"))?;
        s.sdo_write(0x607A, 0, 0i32).await.map_err(e("0x607A"))?;
    }
    Ok(())
}

/// The process image: 6 bytes in and out per slave (the default assignment).
fn check_image<S: ethercrab::subdevice_group::HasPdi, DC>(
    md: &MainDevice<'_>,
    group: &Group<S, DC>,
) -> Result<(), String> {
    for s in group.iter(md) {
        let io = s.io_raw();
        if (io.inputs().len(), io.outputs().len()) != (6, 6) {
            return Err(format!(
                "process data {} in / {} out bytes, expected 6 / 6",
                io.inputs().len(),
                io.outputs().len()
            ));
        }
    }
    Ok(())
}

/// In OP, cycling with `txrx` (its working counter) every 1 ms: CiA 402 enable, a CSP ramp
/// to 2000 followed in 0x6064, the group's working counter 3 per slave in every cycle.
/// Returns each slave's 0x6064.
async fn enable_and_move<DC>(
    md: &MainDevice<'_>,
    group: &Group<Op, DC>,
    n: usize,
    mut txrx: impl AsyncFnMut() -> Result<u16, Error>,
) -> Result<Vec<i32>, String> {
    let expected_wkc = 3 * n as u16;
    let mut wkcs = Vec::new();
    let mut tick = tokio::time::interval(Duration::from_millis(1));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    // CiA 402 enable: shutdown, switch on, enable operation, each until 0x6041 says so
    for (cw, mask, want) in [
        (0x06u16, 0x6F, 0x21),
        (0x07, 0x6F, 0x23),
        (0x0F, 0x6F, 0x27),
    ] {
        let mut reached = false;
        for _ in 0..2000 {
            tick.tick().await;
            for s in group.iter(md) {
                let mut io = s.io_raw_mut();
                io.outputs()[..2].copy_from_slice(&cw.to_le_bytes());
                io.outputs()[2..6].copy_from_slice(&0i32.to_le_bytes());
            }
            wkcs.push(txrx().await.map_err(e("tx_rx"))?);
            reached = group
                .iter(md)
                .all(|s| statusword(s.io_raw().inputs()) & mask == want);
            if reached {
                break;
            }
        }
        if !reached {
            let sw: Vec<String> = group
                .iter(md)
                .map(|s| format!("0x{:04X}", statusword(s.io_raw().inputs())))
                .collect();
            return Err(format!("controlword 0x{cw:02X}: statuswords {sw:?}"));
        }
    }
    // a CSP ramp to 2000 in the process data, then held until 0x6064 is there
    let start: Vec<i32> = group
        .iter(md)
        .map(|s| position(s.io_raw().inputs()))
        .collect();
    let mut at_target = false;
    for step in 1..=2000i32 {
        tick.tick().await;
        let target = (10 * step).min(2000);
        for s in group.iter(md) {
            let mut io = s.io_raw_mut();
            io.outputs()[..2].copy_from_slice(&0x0Fu16.to_le_bytes());
            io.outputs()[2..6].copy_from_slice(&target.to_le_bytes());
        }
        wkcs.push(txrx().await.map_err(e("tx_rx"))?);
        at_target = step > 200
            && group
                .iter(md)
                .all(|s| (position(s.io_raw().inputs()) - 2000).abs() <= 20);
        if at_target {
            break;
        }
    }
    let pos: Vec<i32> = group
        .iter(md)
        .map(|s| position(s.io_raw().inputs()))
        .collect();
    if !at_target {
        return Err(format!(
            "0x6064 does not follow the CSP ramp: {start:?} -> {pos:?}"
        ));
    }
    let bad: Vec<&u16> = wkcs.iter().filter(|&&w| w != expected_wkc).collect();
    if !bad.is_empty() {
        return Err(format!(
            "{} of {} cycles with a working counter other than {expected_wkc}: {:?}",
            bad.len(),
            wkcs.len(),
            &bad[..bad.len().min(10)]
        ));
    }
    Ok(pos)
}
