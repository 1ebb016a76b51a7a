//! The simulated drive: the [`drive_protocol::Drive`] adapter on the servo axis (units, physics
//! limits, supervision), the emulator's own objects in its dictionary, the building of its
//! node, the quirk profiles (vendor behaviour, `quirk_profile.rs`), and the machine file that
//! says which axes one process serves.

pub mod axis_drive;
pub mod machine;
pub mod node;
pub mod objects;
pub mod quirk_profile;
pub mod vendor;

pub use node::{build_node, node, node_config, node_setup, NodeOptions, NodeSetup};
pub use objects::{AxisParam, ParamError};
