//! The one place a simulated drive gets its CANopen node: the object dictionary (the
//! standard CiA 301 / CiA 402 objects plus the emulator's own, `objects.rs`), the node's
//! configuration, and the link from the drive to its objects.

use super::axis_drive::AxisDrive;
use super::objects;
use drive_protocol::od::ObjectDictionary;
use drive_protocol::{Drive, Node, NodeConfig};

/// How to build a drive's node.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeOptions {
    /// Node ID 1..=127.
    pub node_id: u8,
    /// Time from power-on or an NMT reset to the boot-up message, us.
    pub boot_delay_us: u64,
    /// First index of the emulator's own objects (`objects.rs`).
    pub objects_base: u16,
}

impl NodeOptions {
    /// Node `node_id`, no boot delay, the emulator's objects at 0x2000.
    pub fn new(node_id: u8) -> NodeOptions {
        NodeOptions {
            node_id,
            boot_delay_us: 0,
            objects_base: objects::DEFAULT_BASE,
        }
    }

    /// The same with a boot delay.
    pub fn with_boot_delay_us(mut self, delay_us: u64) -> NodeOptions {
        self.boot_delay_us = delay_us;
        self
    }
}

/// The configuration of the node for `drive`: its dictionary is the standard one plus the
/// emulator's objects, which `drive` learns the slots of (so build the node from this
/// configuration, [`build_node`]).
pub fn node_config(drive: &mut AxisDrive, opts: &NodeOptions) -> anyhow::Result<NodeConfig> {
    let info = drive.info();
    let mut od = ObjectDictionary::standard(&info);
    let objects = objects::register(&mut od, opts.objects_base, info.rotary)
        .map_err(|e| anyhow::anyhow!("the emulator's objects: {e}"))?;
    drive.objects = Some(objects);
    Ok(NodeConfig::new(opts.node_id, info)
        .with_od(od)
        .with_boot_delay_us(opts.boot_delay_us))
}

/// The node for `drive` (not booted yet), from [`node_config`].
pub fn build_node(drive: &mut AxisDrive, opts: &NodeOptions) -> anyhow::Result<Node> {
    let cfg = node_config(drive, opts)?;
    Node::new(cfg).map_err(|e| anyhow::anyhow!("node {}: {e}", opts.node_id))
}

/// [`build_node`] with node ID `node_id` and nothing else asked for.
pub fn node(drive: &mut AxisDrive, node_id: u8) -> anyhow::Result<Node> {
    build_node(drive, &NodeOptions::new(node_id))
}
