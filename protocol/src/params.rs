//! Manufacturer objects 0x2000 and up: the axis parameters of [`AxisParam`], one line per
//! parameter, as REAL32 in the engineering unit named in the object's name. The node converts
//! `engineering = SI * scale` before [`crate::Drive::set_param`] / after [`crate::Drive::param`].
//!
//! Rotary axes use the `rotary_name` / `rotary_scale` column (SI is rad there).

use crate::drive::AxisParam;

/// One manufacturer parameter object.
#[derive(Clone, Copy, Debug)]
pub struct ParamDef {
    pub index: u16,
    pub param: AxisParam,
    pub name: &'static str,
    /// Engineering units per SI unit.
    pub scale: f64,
    pub rotary_name: &'static str,
    pub rotary_scale: f64,
}

const DEG: f64 = 180.0 / core::f64::consts::PI;
const ARCSEC: f64 = DEG * 3600.0;

const fn p(
    index: u16,
    param: AxisParam,
    name: &'static str,
    scale: f64,
    rotary_name: &'static str,
    rotary_scale: f64,
) -> ParamDef {
    ParamDef {
        index,
        param,
        name,
        scale,
        rotary_name,
        rotary_scale,
    }
}

#[rustfmt::skip]
pub const PARAMS: [ParamDef; 14] = [
    //  index   parameter                          linear name (unit)                 scale  rotary name                         scale
    p(0x2000, AxisParam::Backlash,             "backlash_mm",                      1e3,  "backlash_deg",                     DEG),
    p(0x2001, AxisParam::Stiffness,            "stiffness_N_per_um",               1e-6, "stiffness_Nm_per_rad",             1.0),
    p(0x2002, AxisParam::Damping,              "damping_Ns_per_m",                 1.0,  "damping_Nms_per_rad",              1.0),
    p(0x2003, AxisParam::LoadCoulombFriction,  "load_coulomb_friction_N",          1.0,  "load_coulomb_friction_Nm",         1.0),
    p(0x2004, AxisParam::LoadViscousFriction,  "load_viscous_friction_Ns_per_m",   1.0,  "load_viscous_friction_Nms_per_rad",1.0),
    p(0x2005, AxisParam::MotorCoulombFriction, "motor_coulomb_friction_Nm",        1.0,  "motor_coulomb_friction_Nm",        1.0),
    p(0x2006, AxisParam::ExternalLoad,         "external_load_N",                  1.0,  "external_load_Nm",                 1.0),
    p(0x2007, AxisParam::Kv,                   "kv_per_s",                         1.0,  "kv_per_s",                         1.0),
    p(0x2008, AxisParam::SpeedKp,              "speed_kp_Nms_per_rad",             1.0,  "speed_kp_Nms_per_rad",             1.0),
    p(0x2009, AxisParam::SpeedTi,              "speed_ti_ms",                      1e3,  "speed_ti_ms",                      1e3),
    p(0x200A, AxisParam::MotorEncoderNoise,    "motor_encoder_noise_inc",          1.0,  "motor_encoder_noise_inc",          1.0),
    p(0x200B, AxisParam::DirectEncoderNoise,   "direct_encoder_noise_um",          1e6,  "direct_encoder_noise_arcsec",      ARCSEC),
    p(0x200C, AxisParam::DirectEncoderOffset,  "direct_encoder_offset_um",         1e6,  "direct_encoder_offset_arcsec",     ARCSEC),
    p(0x200D, AxisParam::PositionFromDirect,   "position_from_direct",             1.0,  "position_from_direct",             1.0),
];

/// Runtime statistics record (read-only U32), set by the runtime via
/// [`crate::Node::set_runtime_stats`].
pub const STATS_INDEX: u16 = 0x2100;
/// Write-only U16: a non-zero value injects a simulated drive fault with that error code
/// (for testing a master's fault handling); 0 clears the injected cause.
pub const INJECT_FAULT_INDEX: u16 = 0x2101;

/// Sub-indices 1.. of 0x2100. `sync_lock_state`: 0 free-running, 1 acquiring, 2 locked to
/// SYNC; `sync_phase_error_us`: smoothed magnitude of the SYNC's arrival minus the loop's
/// prediction; `sync_period_us`: the SYNC period the loop measured; `tx_full_waits`: times the
/// transport's transmit queue was full and the loop waited for room; `sync_window_missed`:
/// synchronous TPDOs not sent because the 0x1007 window had closed; `rx_overflows`: frames
/// the kernel dropped because the receive queue of the runtime's socket was full
/// (SO_RXQ_OVFL, cumulative; a lock-step drive that lost SYNCs there says so here).
#[rustfmt::skip]
pub const STATS_NAMES: [&str; 13] = [
    "ticks", "overruns", "lateness_p50_us", "lateness_p99_us", "lateness_max_us",
    "dropped_tx_frames", "node_tx_queue_overflows", "sync_lock_state", "sync_phase_error_us",
    "sync_period_us", "tx_full_waits", "sync_window_missed", "rx_overflows",
];

/// Which parameter lives at `index`.
pub fn param_at(index: u16) -> Option<&'static ParamDef> {
    PARAMS.iter().find(|d| d.index == index)
}
