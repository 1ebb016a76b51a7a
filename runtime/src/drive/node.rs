//! The one place a simulated drive gets its CANopen node: the object dictionary (the
//! standard CiA 301 / CiA 402 objects, or a vendor's EDS, `vendor.rs`; plus the emulator's
//! own, `objects.rs`), the vendor behaviour (a profile's switches, identity and boot delays,
//! `quirk_profile.rs`), the node's configuration, and the link from the drive to its objects.

use super::axis_drive::AxisDrive;
use super::objects;
use super::quirk_profile::QuirkProfile;
use super::vendor::VendorEds;
use drive_protocol::od::{BuildReport, DefaultValue, ObjectDictionary};
use drive_protocol::{Drive, LssConfig, Node, NodeConfig};
use std::sync::Arc;

/// How to build a drive's node.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeOptions {
    /// Node ID 1..=127.
    pub node_id: u8,
    /// Time from power-on or an NMT reset to the boot-up message, us.
    pub boot_delay_us: u64,
    /// First index of the emulator's own objects (`objects.rs`); `None`: 0x2000, or with a
    /// vendor's EDS the first free base.
    pub objects_base: Option<u16>,
    /// The vendor's EDS or DCF whose dictionary the drive serves (`None`: the standard one).
    pub eds: Option<Arc<VendorEds>>,
    /// The LSS slave's power-on bit timing and who writes a store configuration (the slave
    /// exists where the dictionary says LSS_Supported: always for ours).
    pub lss: LssConfig,
    /// The identity's serial number 0x1018:4, part of the LSS address (`None`: the
    /// dictionary's default; the standard one's is the node-ID). Give it when the node-ID
    /// may change (LSS, a stored node-ID) so that the address stays.
    pub serial_number: Option<u32>,
    /// The vendor behaviour (profile, switches, identity, boot delays; `None`: the strict
    /// drive with the emulator's identity).
    pub quirk_profile: Option<Arc<QuirkProfile>>,
    /// An LSS slave even where the vendor's EDS says LSS_Supported=0 or omits it
    /// (`run --force-lss`).
    pub force_lss: bool,
}

impl NodeOptions {
    /// Node `node_id`, no boot delay, the standard dictionary, the emulator's objects at
    /// 0x2000.
    pub fn new(node_id: u8) -> NodeOptions {
        NodeOptions {
            node_id,
            boot_delay_us: 0,
            objects_base: None,
            eds: None,
            lss: LssConfig::default(),
            serial_number: None,
            quirk_profile: None,
            force_lss: false,
        }
    }

    /// The same with a boot delay.
    pub fn with_boot_delay_us(mut self, delay_us: u64) -> NodeOptions {
        self.boot_delay_us = delay_us;
        self
    }
}

/// A node's configuration and what went into it.
#[derive(Clone, Debug)]
pub struct NodeSetup {
    /// The configuration to build the node from.
    pub config: NodeConfig,
    /// Where the emulator's objects are.
    pub objects_base: u16,
    /// With a vendor's EDS: what became of its objects.
    pub report: Option<BuildReport>,
}

/// The configuration of the node for `drive`: the standard dictionary or the vendor's, plus
/// the emulator's objects, whose slots `drive` learns (so build the node from this
/// configuration).
pub fn node_setup(drive: &mut AxisDrive, opts: &NodeOptions) -> anyhow::Result<NodeSetup> {
    let info = drive.info();
    let (od, objects, report) = match &opts.eds {
        Some(eds) => {
            let base = eds.objects_base(opts.objects_base)?;
            let (od, objects, report) = eds.dictionary(&info, base, info.rotary)?;
            (od, objects, Some(report))
        }
        None => {
            let mut od = ObjectDictionary::standard(&info);
            let base = opts.objects_base.unwrap_or(objects::DEFAULT_BASE);
            let objects = objects::register(&mut od, base, info.rotary)
                .map_err(|e| anyhow::anyhow!("the emulator's objects: {e}"))?;
            (od, objects, None)
        }
    };
    let mut od = od;
    if let Some(serial) = opts.serial_number {
        od.set_default(0x1018, 4, DefaultValue::Value(u64::from(serial)))
            .map_err(|e| anyhow::anyhow!("serial number: {e}"))?;
    }
    if let Some(b) = &opts.quirk_profile {
        apply_identity(&mut od, b, opts.eds.as_deref())?;
    }
    let objects_base = objects.base;
    drive.objects = Some(objects);
    if !od.device.lss_supported && opts.force_lss {
        od.device.lss_supported = true;
    }
    if !od.device.lss_supported && opts.node_id == 255 {
        let said = match opts.eds.as_deref() {
            Some(v) => format!(
                "{} {}",
                v.path.display(),
                match v.file.device_info.lss_supported {
                    Some(_) => "says LSS_Supported=0 in [DeviceInfo]",
                    None => "has no LSS_Supported in [DeviceInfo] (CiA 306: no LSS)",
                }
            ),
            None => "the dictionary has no LSS".into(),
        };
        anyhow::bail!(
            "node id 255 (non-configured, waiting for a node-ID by LSS): {said}, so the drive \
             has no LSS slave and no master could give it a node-ID. Give a node ID 1..=127, or \
             --force-lss to serve LSS (CiA 305) with this file anyway"
        );
    }
    let lss = od.device.lss_supported.then_some(opts.lss);
    let mut config = NodeConfig::new(opts.node_id, info)
        .with_od(od)
        .with_boot_delay_us(opts.boot_delay_us);
    config.lss = lss;
    if let Some(b) = &opts.quirk_profile {
        let id = &b.identity;
        let us = |ms: u32| u64::from(ms) * 1000;
        if let Some(ms) = id.boot_delay_ms {
            config.boot_delay_us = us(ms);
        }
        config.reset_node_boot_delay_us = id.reset_node_boot_delay_ms.map(us);
        config.reset_communication_boot_delay_us = id.reset_communication_boot_delay_ms.map(us);
        config.quirks = b.quirks.clone();
    }
    Ok(NodeSetup {
        config,
        objects_base,
        report,
    })
}

/// The profile's `[identity]` in the dictionary: without a vendor's EDS its values become the
/// defaults of 0x1000, 0x1018:1-3 and 0x1008; with one, the EDS is authoritative and a key
/// that disagrees with it is an error naming both values.
fn apply_identity(
    od: &mut ObjectDictionary,
    b: &QuirkProfile,
    eds: Option<&VendorEds>,
) -> anyhow::Result<()> {
    let profile = b.profile.as_deref().unwrap_or("the command line");
    let id = &b.identity;
    for (index, sub, key, value) in id.objects() {
        match eds {
            Some(v) => {
                let have = od.get(index, sub).map(|(_, e)| e.default_raw(0) as u32);
                if have != Some(value) {
                    anyhow::bail!(
                        "profile {profile}: [identity] {key} = 0x{value:08X}, but the EDS {} \
                         says 0x{index:04X}:{sub} = {} (the EDS is authoritative for the \
                         identity: drop the key from the profile, or use the vendor's EDS)",
                        v.path.display(),
                        have.map_or("nothing".into(), |h| format!("0x{h:08X}"))
                    );
                }
            }
            None => od
                .set_default(index, sub, DefaultValue::Value(u64::from(value)))
                .map_err(|e| anyhow::anyhow!("profile {profile}: [identity] {key}: {e}"))?,
        }
    }
    if let Some(name) = &id.device_name {
        let bytes = DefaultValue::Bytes(name.as_bytes().to_vec());
        match eds {
            Some(v) => {
                let have = od.get(0x1008, 0).map(|(_, e)| e.default.clone());
                if have.as_ref() != Some(&bytes) {
                    anyhow::bail!(
                        "profile {profile}: [identity] device_name = \"{name}\", but the EDS {} \
                         says 0x1008 = {} (the EDS is authoritative for the identity)",
                        v.path.display(),
                        match have {
                            Some(DefaultValue::Bytes(b)) =>
                                format!("\"{}\"", String::from_utf8_lossy(&b)),
                            _ => "nothing".into(),
                        }
                    );
                }
            }
            None => od
                .set_default(0x1008, 0, bytes)
                .map_err(|e| anyhow::anyhow!("profile {profile}: [identity] device_name: {e}"))?,
        }
    }
    Ok(())
}

/// [`node_setup`]'s configuration.
pub fn node_config(drive: &mut AxisDrive, opts: &NodeOptions) -> anyhow::Result<NodeConfig> {
    Ok(node_setup(drive, opts)?.config)
}

/// The node for `drive` (not booted yet), from [`node_setup`].
pub fn build_node(drive: &mut AxisDrive, opts: &NodeOptions) -> anyhow::Result<Node> {
    let cfg = node_config(drive, opts)?;
    Node::new(cfg).map_err(|e| anyhow::anyhow!("node {}: {e}", opts.node_id))
}

/// [`build_node`] with node ID `node_id` and nothing else asked for.
pub fn node(drive: &mut AxisDrive, node_id: u8) -> anyhow::Result<Node> {
    build_node(drive, &NodeOptions::new(node_id))
}
