//! The contract between the CANopen node and whatever drives the motor behind it.
//!
//! The node (CiA 301 + CiA 402) turns bus traffic into a [`Setpoint`] once per tick and reads
//! back [`Feedback`]. It never sees physics: the emulator implements [`Drive`] on top of its
//! simulated axis, protocol tests implement it with a trivial model.
//!
//! Units on this interface are the drive's *internal units*, as CiA 402 calls them:
//! - position: motor-encoder increments (`inc`), as `f64` for set-points and `i64` for
//!   encoder readings (the wire's 32-bit values wrap; these do not);
//! - velocity: increments per second;
//! - torque and current: per mille of the motor's rated torque / rated current (0x6076, 0x6075).
//!
//! The factor group (0x608F, 0x6091, 0x6092) that maps user units to increments lives in the
//! node; the conversion from increments to SI lives in the emulator's drive adapter. Nothing
//! else converts.

/// What the node asks the drive's control cascade to do this tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Setpoint {
    /// Power stage off: no torque, the axis coasts (CiA 402 states other than
    /// OPERATION ENABLED, QUICK STOP ACTIVE and FAULT REACTION ACTIVE).
    Disabled,
    /// Closed position loop in the drive (PP, HM, CSP, and quick stop / halt holding).
    Position {
        /// Position demand, increments.
        position_inc: f64,
        /// Velocity feed-forward, increments/s (profile velocity, or 0x60B1 offset in CSP).
        velocity_ff_inc_per_s: f64,
        /// Torque feed-forward, per mille of rated torque (0x60B2 in CSP).
        torque_ff_permille: f64,
    },
    /// Closed speed loop in the drive, position loop (if any) outside (PV, CSV).
    Velocity {
        /// Velocity demand, increments/s (0x60FF through the factor group; in PV after the ramp).
        velocity_inc_per_s: f64,
        /// Torque feed-forward, per mille of rated torque (0x60B2 in CSV).
        torque_ff_permille: f64,
    },
    /// Torque demand straight to the current loop (CST, TQ).
    Torque {
        /// Torque demand, per mille of rated torque (0x6071 target torque).
        torque_permille: f64,
    },
}

/// A full command for one tick: the set-point plus the limits the node enforces from the OD.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveCommand {
    /// What the control cascade should follow this tick.
    pub setpoint: Setpoint,
    /// 0x6072 max torque, per mille of rated torque.
    pub max_torque_permille: f64,
    /// 0x6080 max motor speed converted to increments/s (0.0 = no limit beyond the drive's own).
    pub max_velocity_inc_per_s: f64,
}

/// What the drive measured this tick. Only encoder-like values: never the true physical state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Feedback {
    /// Motor encoder (measuring system 1), increments.
    pub motor_position_inc: i64,
    /// Direct encoder (measuring system 2, the linear scale or table encoder), expressed in
    /// motor-encoder increments (load position times the kinematic ratio), quantized at the
    /// direct encoder's own resolution. Reported as 0x60E4 sub 1.
    pub direct_position_inc: i64,
    /// Which encoder closes the drive's position loop (0x6064 follows it): true = direct.
    pub position_from_direct: bool,
    /// Motor speed from the motor encoder, increments/s (0x6069, 0x606C).
    pub motor_velocity_inc_per_s: f64,
    /// Speed-loop demand, increments/s (0x606B).
    pub velocity_demand_inc_per_s: f64,
    /// Actual torque, per mille of rated (0x6077).
    pub torque_permille: f64,
    /// Actual current, per mille of rated (0x6078).
    pub current_permille: f64,
    /// Home switch input (0x60FD bit 2).
    pub home_switch: bool,
    /// Negative limit switch input (0x60FD bit 0).
    pub negative_limit_switch: bool,
    /// Positive limit switch input (0x60FD bit 1).
    pub positive_limit_switch: bool,
    /// A fault the drive hardware detected itself (encoder signal lost, over-temperature, ...):
    /// the CiA 402 / EMCY error code to report, e.g. 0x7300 sensor. The node enters FAULT
    /// REACTION ACTIVE and sends the EMCY on the rising edge; `None` when healthy.
    pub drive_fault: Option<u16>,
}

/// Static facts about the motor and mechanics, used for the node's defaults (0x608F, 0x6091,
/// 0x6092, 0x6075, 0x6076, 0x6080) and for the EDS.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveInfo {
    /// Motor encoder increments per motor revolution (0x608F sub 1).
    pub encoder_increments_per_rev: u32,
    /// Motor revolutions per driving-shaft revolution (0x6091 sub 1 / sub 2), as a fraction.
    pub gear_motor_revs: u32,
    /// Driving-shaft revolutions of that fraction (0x6091 sub 2).
    pub gear_shaft_revs: u32,
    /// Feed per driving-shaft revolution in user units (0x6092 sub 1 / sub 2), as a fraction.
    /// Example: a 10 mm screw with user unit 1 um: 10000 / 1.
    pub feed_user_units: u32,
    /// Driving-shaft revolutions of that fraction (0x6092 sub 2).
    pub feed_shaft_revs: u32,
    /// Motor rated torque, mNm (0x6076).
    pub rated_torque_mnm: u32,
    /// Motor rated current, mA (0x6075).
    pub rated_current_ma: u32,
    /// Maximum motor speed, rpm (0x6080).
    pub max_motor_speed_rpm: u32,
    /// True for a rotary axis (table), false for a linear axis: only for descriptions.
    pub rotary: bool,
}

/// The drive behind a node. The emulator implements this on the simulated axis.
///
/// Every method is called from the real-time path: implementations must not allocate, lock,
/// block or log.
pub trait Drive {
    /// Static facts, read when the node is built and on reset node.
    fn info(&self) -> DriveInfo;
    /// The latest encoder readings.
    fn feedback(&self) -> Feedback;
    /// Apply this tick's command. Called once per node tick.
    fn command(&mut self, command: &DriveCommand);
    /// SDO upload of an object whose value this drive keeps ([`crate::od::Backing::Handler`]
    /// with `tag`, the tag the application gave the entry): write its little-endian bytes
    /// into `out` (as many as the entry's type has) and return the length, or an SDO abort
    /// code (`crate::wire::abort`). The default has no such objects.
    fn read_object(&mut self, tag: u16, index: u16, sub: u8, out: &mut [u8]) -> Result<usize, u32> {
        let _ = (tag, index, sub, out);
        Err(crate::wire::sdo::abort::NO_OBJECT)
    }
    /// SDO download to an object this drive keeps: `data` has the entry's size (type and
    /// limits already checked by the node); Ok, or an SDO abort code. The default has none.
    fn write_object(&mut self, tag: u16, index: u16, sub: u8, data: &[u8]) -> Result<(), u32> {
        let _ = (tag, index, sub, data);
        Err(crate::wire::sdo::abort::NO_OBJECT)
    }
    /// Clear latched hardware faults on a CiA 402 fault reset. Returns false while the cause
    /// persists (the node then stays in FAULT).
    fn reset_fault(&mut self) -> bool;
    /// NMT reset node: the drive's application resets as well (parameters back to their
    /// power-on values, state re-initialised at rest). Latched faults whose cause is gone
    /// clear. The default does nothing.
    fn reset(&mut self) {}
}
