//! The cascade's gains and cycle times: their one copy, read by the cascade and handed to
//! the position and speed controllers (which hold state only), changed by [`Servo`]'s
//! setters. In a file of its own so the controllers and the cascade both depend on it and
//! not on each other.
//!
//! [`Servo`]: super::cascade::Servo

/// Controller gains and cycle times (SI).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CascadeParams {
    /// Position gain k_v, 1/s.
    pub kv: f64,
    /// Speed-loop proportional gain k_sp, N m s/rad.
    pub speed_kp: f64,
    /// Speed-loop integral time T_si, s.
    pub speed_ti: f64,
    /// Speed-measurement filter time constant, s.
    pub speed_filter: f64,
    /// True: the direct encoder closes the position loop; false: the motor encoder does.
    pub position_from_direct: bool,
    /// Speed (and torque demand) cycle, s; an integer multiple of the physics step.
    pub speed_cycle: f64,
    /// Position cycle, s; an integer multiple of the speed cycle.
    pub position_cycle: f64,
}
