//! The simulated drive: the [`drive_protocol::Drive`] adapter on the servo axis (units, physics
//! limits, supervision) and the machine file that says which axes one process serves.

pub mod axis_drive;
pub mod machine;
