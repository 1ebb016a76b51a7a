//! Sans-IO CANopen node for a CiA 402 servo drive: frames and a monotonic time go in,
//! frames come out. No threads, sockets or clocks in here.

pub mod drive;

pub use drive::{AxisParam, Drive, DriveCommand, DriveInfo, Feedback, ParamError, Setpoint};
