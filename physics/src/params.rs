//! The parameter registry: every parameter of the simulated axis, with its one spelling per
//! kind of axis (units in the name), its unit, its SI scale and where it may be set.
//!
//! Everything that names a parameter reads this table: the preset files and `--set`
//! (`presets::AxisConfig`), scenario files and the panel's controls (the emulator's
//! `scenario::units`), the drive's parameter objects 0x2000.. (the emulator's
//! `drive::objects`), sweep grids, demo flags and the Python module. A name that is not here is
//! refused with the nearest known one ([`suggest`]).

use std::f64::consts::PI;

/// Largest backlash a configuration (and the drive's 0x2000) accepts: 10 mm on a linear
/// axis, 0.1 rad (5.7 deg) on a rotary one; worn machines show 0.01-0.1 mm.
pub const MAX_BACKLASH_M: f64 = 0.01;
/// The same on a rotary axis, rad.
pub const MAX_BACKLASH_RAD: f64 = 0.1;

/// Axis parameters the master may read and write while the axis runs, in SI units.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum AxisParam {
    /// Backlash at the load, m (linear) or rad (rotary).
    Backlash,
    /// Drive-train stiffness at the load, N/m (linear) or N m/rad (rotary).
    Stiffness,
    /// Drive-train damping at the load, N s/m or N m s/rad.
    Damping,
    /// Coulomb friction at the load, N or N m.
    LoadCoulombFriction,
    /// Viscous friction at the load, N s/m or N m s/rad.
    LoadViscousFriction,
    /// Coulomb friction at the motor, N m.
    MotorCoulombFriction,
    /// External load force/torque at the load (cutting force), N or N m.
    ExternalLoad,
    /// Position-loop gain k_v, 1/s.
    Kv,
    /// Speed-loop proportional gain, N m s/rad.
    SpeedKp,
    /// Speed-loop integral time, s.
    SpeedTi,
    /// Motor-encoder noise, standard deviation in increments.
    MotorEncoderNoise,
    /// Direct-encoder noise, standard deviation in m or rad.
    DirectEncoderNoise,
    /// Direct-encoder offset (thermal drift of a linear scale), m or rad.
    DirectEncoderOffset,
    /// 1.0 = the direct encoder closes the position loop, 0.0 = the motor encoder does.
    PositionFromDirect,
    /// Electrical preload of a twin pinion: bias torque per motor as a fraction of each
    /// motor's rated torque (written in %). Only a twin-pinion axis takes a non-zero value.
    Preload,
}

/// Which kinds of axis a spelling applies to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Applies {
    /// Linear axes only.
    Linear,
    /// Rotary axes only.
    Rotary,
    /// Both (the same spelling on either).
    Any,
}

/// One spelling of a parameter: the key as written (unit in the name), its unit and scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Form {
    /// The key as written in files, `--set`, scenario events, the panel and Python.
    pub key: &'static str,
    /// The unit the key is written in, for people (`mm`, `N/µm`, `1/s`, `-` for a pure number).
    pub unit: &'static str,
    /// SI value = written value x `si_per_unit`.
    pub si_per_unit: f64,
    /// Which axes take this spelling.
    pub applies: Applies,
    /// Lowest written value accepted wherever the key enters (a preset or machine file,
    /// `--set`, a sweep case, Python, a demo flag); `-inf`: no registry bound (a live
    /// parameter's running range is the drive's, `param_bounds` in the emulator).
    pub min: f64,
    /// Highest written value accepted wherever the key enters; `+inf`: no registry bound.
    pub max: f64,
}

impl Form {
    /// The written value of `si`.
    pub fn from_si(&self, si: f64) -> f64 {
        si / self.si_per_unit
    }

    /// The SI value of `written`.
    pub fn to_si(&self, written: f64) -> f64 {
        written * self.si_per_unit
    }

    /// The spelling with the range `min ..= max` (written units).
    const fn within(self, min: f64, max: f64) -> Form {
        Form { min, max, ..self }
    }

    /// `written` within the registry's range, else why not: "must be within MIN ..= MAX
    /// UNIT, got V" (also for NaN and infinities).
    pub fn check(&self, written: f64) -> Result<(), String> {
        if written.is_finite() && written >= self.min && written <= self.max {
            return Ok(());
        }
        let unit = match self.unit {
            "-" => String::new(),
            u => format!(" {u}"),
        };
        Err(format!(
            "must be within {} ..= {}{unit}, got {written}",
            self.min, self.max
        ))
    }

    /// Whether this spelling applies to a rotary (`true`) or linear axis.
    pub fn applies_to(&self, rotary: bool) -> bool {
        match self.applies {
            Applies::Any => true,
            Applies::Rotary => rotary,
            Applies::Linear => !rotary,
        }
    }
}

/// One parameter of the registry.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    /// The spelling on a linear axis (or on any, when `rotary` is `None`).
    pub linear: Form,
    /// The spelling on a rotary axis, when it differs.
    pub rotary: Option<Form>,
    /// Set while the axis runs (scenario events, the panel, the drive's 0x2000.. object).
    pub live: Option<AxisParam>,
    /// A key of the preset files and `--set` (a field of `presets::AxisConfig`).
    pub preset: bool,
    /// Offset of the drive's parameter object above its base (0x2000 by default).
    pub object_offset: Option<u16>,
    /// Lowest written value accepted where the parameter is set while running.
    pub min: f64,
    /// What it is, in one line.
    pub doc: &'static str,
}

impl ParamSpec {
    /// The spelling for an axis kind.
    pub fn form(&self, rotary: bool) -> &Form {
        match (&self.rotary, rotary) {
            (Some(r), true) => r,
            _ => &self.linear,
        }
    }

    /// Every spelling (one, or linear and rotary).
    pub fn forms(&self) -> impl Iterator<Item = &Form> {
        std::iter::once(&self.linear).chain(self.rotary.as_ref())
    }
}

const DEG: f64 = PI / 180.0;
const ARCSEC: f64 = DEG / 3600.0;
const NEG_INF: f64 = f64::NEG_INFINITY;

const fn f(key: &'static str, unit: &'static str, si: f64, applies: Applies) -> Form {
    Form {
        key,
        unit,
        si_per_unit: si,
        applies,
        min: NEG_INF,
        max: f64::INFINITY,
    }
}

const fn lin(key: &'static str, unit: &'static str, si: f64) -> Form {
    f(key, unit, si, Applies::Linear)
}

const fn rot(key: &'static str, unit: &'static str, si: f64) -> Option<Form> {
    Some(f(key, unit, si, Applies::Rotary))
}

/// A rotary spelling with its range.
const fn rot_within(
    key: &'static str,
    unit: &'static str,
    si: f64,
    min: f64,
    max: f64,
) -> Option<Form> {
    Some(f(key, unit, si, Applies::Rotary).within(min, max))
}

/// The largest encoder resolution the drive reports (0x608F is a U32), counts/rev.
const U32_MAX: f64 = u32::MAX as f64;

const fn any(key: &'static str, unit: &'static str, si: f64) -> Form {
    f(key, unit, si, Applies::Any)
}

/// A parameter of the preset files only (read once, when the axis is built): its spellings
/// carry the range (`Form::within`) every entry checks.
const fn preset(linear: Form, rotary: Option<Form>, doc: &'static str) -> ParamSpec {
    ParamSpec {
        linear,
        rotary,
        live: None,
        preset: true,
        object_offset: None,
        min: NEG_INF,
        doc,
    }
}

/// A parameter set while the axis runs, with its object, and a preset key if `preset`.
const fn live(
    linear: Form,
    rotary: Option<Form>,
    param: AxisParam,
    offset: u16,
    preset: bool,
    min: f64,
    doc: &'static str,
) -> ParamSpec {
    ParamSpec {
        linear,
        rotary,
        live: Some(param),
        preset,
        object_offset: Some(offset),
        min,
        doc,
    }
}

/// The registry. Object offsets (0x2000 + offset) are those the drive has always served.
#[rustfmt::skip]
pub const PARAMS: &[ParamSpec] = &[
    // ---- kinematics ----
    preset(lin("pitch_mm", "mm", 1e-3).within(0.1, 1000.0), None, "lead of the screw per revolution (lead screw)"),
    preset(lin("pinion_diameter_mm", "mm", 1e-3).within(1.0, 5000.0), None, "pitch diameter of the pinion (rack and pinion)"),
    preset(any("gear_ratio", "-", 1.0).within(0.01, 1e5), None, "motor revolutions per screw, pinion or table revolution"),
    // ---- load ----
    preset(lin("carriage_mass_kg", "kg", 1.0).within(0.1, 1e6), rot_within("table_inertia_kgm2", "kg m^2", 1.0, 1e-3, 1e7), "moving mass or table inertia at the load"),
    preset(any("counterbalance_fraction", "-", 1.0).within(0.0, 1.5), None, "counterbalanced share of a vertical axis' weight"),
    // ---- drive train ----
    live(lin("backlash_mm", "mm", 1e-3).within(0.0, MAX_BACKLASH_M / 1e-3), rot_within("backlash_deg", "deg", DEG, 0.0, MAX_BACKLASH_RAD / DEG), AxisParam::Backlash, 0x00, true, 0.0, "the gap in the drive train, at the load"),
    live(lin("stiffness_n_per_um", "N/µm", 1e6), rot("stiffness_nm_per_arcsec", "N m/arcsec", 1.0 / ARCSEC), AxisParam::Stiffness, 0x01, true, 1e-12, "drive-train stiffness at the load"),
    live(lin("damping_n_s_per_m", "N s/m", 1.0), rot("damping_nm_s_per_rad", "N m s/rad", 1.0), AxisParam::Damping, 0x02, false, 0.0, "drive-train damping at the load (the presets give `damping_ratio`)"),
    preset(any("damping_ratio", "-", 1.0).within(0.0, 2.0), None, "damping ratio of the drive train's resonance"),
    live(any("preload_pct", "%", 0.01), None, AxisParam::Preload, 0x0E, true, 0.0, "twin pinion's electrical preload: bias torque per motor, % of its rated torque"),
    // ---- load friction ----
    live(lin("load_coulomb_friction_n", "N", 1.0), rot("load_coulomb_friction_nm", "N m", 1.0), AxisParam::LoadCoulombFriction, 0x03, true, 0.0, "Coulomb friction at the load"),
    preset(any("load_static_friction_ratio", "-", 1.0).within(1.0, 10.0), None, "static over Coulomb friction at the load (Stribeck)"),
    preset(lin("stribeck_velocity_mm_per_s", "mm/s", 1e-3).within(1e-3, 1e4), rot_within("stribeck_velocity_deg_per_s", "deg/s", DEG, 1e-3, 1e4), "Stribeck velocity of the load friction"),
    live(lin("load_viscous_friction_n_per_m_per_s", "N/(m/s)", 1.0), rot("load_viscous_friction_nm_per_rad_per_s", "N m/(rad/s)", 1.0), AxisParam::LoadViscousFriction, 0x04, true, 0.0, "viscous friction at the load"),
    // ---- motor ----
    preset(any("motor_inertia_kgm2", "kg m^2", 1.0).within(1e-6, 100.0), None, "rotor inertia (with coupling, screw or pinion)"),
    preset(any("torque_constant_nm_per_a", "N m/A", 1.0).within(1e-3, 100.0), None, "motor torque constant"),
    preset(any("rated_torque_nm", "N m", 1.0).within(1e-3, 1e5), None, "rated motor torque (0x6076)"),
    preset(any("rated_current_a", "A", 1.0).within(1e-3, 1e4), None, "rated motor current (0x6075)"),
    preset(any("max_current_a", "A", 1.0).within(1e-3, 1e4), None, "peak current of the drive"),
    preset(any("max_speed_rpm", "rpm", PI / 30.0).within(1.0, 1e5), None, "maximum motor speed (0x6080)"),
    preset(any("motor_thermal_time_constant_s", "s", 1.0).within(1.0, 36_000.0), None, "winding's thermal time constant (I2t monitor)"),
    preset(any("current_bandwidth_hz", "Hz", 1.0).within(1.0, 1e5), None, "bandwidth of the current loop"),
    live(any("motor_coulomb_friction_nm", "N m", 1.0), None, AxisParam::MotorCoulombFriction, 0x05, true, 0.0, "Coulomb friction at the motor"),
    preset(any("motor_viscous_friction_nm_per_rad_per_s", "N m/(rad/s)", 1.0).within(0.0, 1e3), None, "viscous friction at the motor"),
    live(lin("load_force_n", "N", 1.0), rot("load_torque_nm", "N m", 1.0), AxisParam::ExternalLoad, 0x06, false, NEG_INF, "external load (cutting force) at the load"),
    // ---- encoders ----
    preset(any("motor_encoder_counts_per_rev", "counts/rev", 1.0).within(4.0, U32_MAX), None, "motor encoder resolution"),
    preset(lin("direct_encoder_resolution_nm", "nm", 1e-9).within(0.01, 1e6), None, "linear scale's resolution"),
    preset(f("direct_encoder_counts_per_rev", "counts/rev", 1.0, Applies::Rotary).within(4.0, U32_MAX), None, "rotary direct encoder's resolution"),
    live(any("motor_encoder_noise_counts", "counts", 1.0), None, AxisParam::MotorEncoderNoise, 0x0A, true, 0.0, "motor encoder noise, standard deviation"),
    preset(any("direct_encoder_noise_counts", "counts", 1.0).within(0.0, 1e6), None, "direct encoder noise, standard deviation (in files)"),
    live(lin("direct_encoder_noise_um", "µm", 1e-6), rot("direct_encoder_noise_mdeg", "mdeg", 1e-3 * DEG), AxisParam::DirectEncoderNoise, 0x0B, false, 0.0, "direct encoder noise, standard deviation (while running)"),
    live(lin("direct_encoder_offset_um", "µm", 1e-6), rot("direct_encoder_offset_mdeg", "mdeg", 1e-3 * DEG), AxisParam::DirectEncoderOffset, 0x0C, true, NEG_INF, "direct encoder offset (a scale's thermal drift)"),
    preset(any("noise_seed", "-", 1.0).within(0.0, u64::MAX as f64), None, "seed of the encoders' noise"),
    // ---- control ----
    live(any("kv_per_s", "1/s", 1.0), None, AxisParam::Kv, 0x07, true, 1e-9, "position-loop gain k_v"),
    live(any("speed_kp_nms_per_rad", "N m s/rad", 1.0), None, AxisParam::SpeedKp, 0x08, true, 1e-12, "speed-loop proportional gain"),
    live(any("speed_ti_ms", "ms", 1e-3), None, AxisParam::SpeedTi, 0x09, true, 1e-9, "speed-loop integral time"),
    preset(any("speed_filter_ms", "ms", 1e-3).within(0.0, 1000.0), None, "speed-feedback filter time constant"),
    live(any("position_from_direct", "0 or 1", 1.0), None, AxisParam::PositionFromDirect, 0x0D, true, 0.0, "the direct encoder closes the position loop (1) or the motor encoder (0)"),
    preset(any("physics_step_us", "us", 1e-6).within(1.0, 10_000.0), None, "physics integration step"),
    preset(any("speed_cycle_us", "us", 1e-6).within(1.0, 100_000.0), None, "speed-loop cycle"),
    preset(any("position_cycle_us", "us", 1e-6).within(1.0, 1_000_000.0), None, "position-loop cycle"),
];

/// Names that moved, with the one that replaced them: still read for one release, with a
/// warning. (The drive's parameter objects carried other spellings before the registry.)
pub const MOVED: &[(&str, &str)] = &[
    ("stiffness_N_per_um", "stiffness_n_per_um"),
    ("damping_Ns_per_m", "damping_n_s_per_m"),
    ("damping_Nms_per_rad", "damping_nm_s_per_rad"),
    ("load_coulomb_friction_N", "load_coulomb_friction_n"),
    ("load_coulomb_friction_Nm", "load_coulomb_friction_nm"),
    (
        "load_viscous_friction_Ns_per_m",
        "load_viscous_friction_n_per_m_per_s",
    ),
    (
        "load_viscous_friction_Nms_per_rad",
        "load_viscous_friction_nm_per_rad_per_s",
    ),
    ("motor_coulomb_friction_Nm", "motor_coulomb_friction_nm"),
    ("external_load_N", "load_force_n"),
    ("external_load_Nm", "load_torque_nm"),
    ("speed_kp_Nms_per_rad", "speed_kp_nms_per_rad"),
    ("motor_encoder_noise_inc", "motor_encoder_noise_counts"),
];

/// The parameter and spelling of `key`, if it is one.
pub fn find(key: &str) -> Option<(&'static ParamSpec, &'static Form)> {
    PARAMS
        .iter()
        .find_map(|p| p.forms().find(|f| f.key == key).map(|f| (p, f)))
}

/// The parameter of a live [`AxisParam`].
pub fn of_live(param: AxisParam) -> &'static ParamSpec {
    PARAMS
        .iter()
        .find(|p| p.live == Some(param))
        .expect("every AxisParam has a row in PARAMS (tested)")
}

/// Every key of every spelling.
pub fn keys() -> impl Iterator<Item = &'static str> {
    PARAMS.iter().flat_map(|p| p.forms().map(|f| f.key))
}

/// The new name of a moved one.
pub fn moved(key: &str) -> Option<&'static str> {
    MOVED
        .iter()
        .find(|(old, _)| *old == key)
        .map(|(_, new)| *new)
}

/// Edit distance (Damerau: a swap of two neighbours counts one), case-insensitive.
fn distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().flat_map(char::to_lowercase).collect();
    let b: Vec<char> = b.chars().flat_map(char::to_lowercase).collect();
    let (n, m) = (a.len(), b.len());
    let mut d = vec![vec![0usize; m + 1]; n + 1];
    for (i, row) in d.iter_mut().enumerate() {
        row[0] = i;
    }
    for (j, cell) in d[0].iter_mut().enumerate() {
        *cell = j;
    }
    for i in 1..=n {
        for j in 1..=m {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            let mut v = (d[i - 1][j] + 1)
                .min(d[i][j - 1] + 1)
                .min(d[i - 1][j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                v = v.min(d[i - 2][j - 2] + 1);
            }
            d[i][j] = v;
        }
    }
    d[n][m]
}

/// The candidate nearest to `name`, if it is near enough to be what was meant (at most a
/// third of its letters differ, and at least one of them, case aside).
pub fn suggest<'a>(name: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    let limit = (name.chars().count() / 3).max(2);
    candidates
        .into_iter()
        .map(|c| (distance(name, c), c))
        .filter(|(d, _)| *d <= limit)
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c)
}

/// " (did you mean `x`?)" for `name` among `candidates`, or "".
pub fn did_you_mean<'a>(name: &str, candidates: impl IntoIterator<Item = &'a str>) -> String {
    match suggest(name, candidates) {
        Some(c) => format!(" (did you mean `{c}`?)"),
        None => String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_key_is_spelled_once_in_lower_case_with_its_unit() {
        let all: Vec<&str> = keys().collect();
        for (i, k) in all.iter().enumerate() {
            assert!(!all[i + 1..].contains(k), "{k} twice");
            assert_eq!(k.to_lowercase(), *k, "{k} not lower case");
            assert!(find(k).is_some());
        }
        for p in PARAMS {
            assert!(p.linear.si_per_unit > 0.0 && p.linear.si_per_unit.is_finite());
            if let Some(r) = p.rotary {
                assert_eq!(r.applies, Applies::Rotary, "{}", r.key);
                assert_eq!(p.linear.applies, Applies::Linear, "{}", p.linear.key);
            }
        }
    }

    #[test]
    fn every_live_parameter_has_one_row_and_its_own_object() {
        use AxisParam::*;
        let all = [
            Backlash,
            Stiffness,
            Damping,
            LoadCoulombFriction,
            LoadViscousFriction,
            MotorCoulombFriction,
            ExternalLoad,
            Kv,
            SpeedKp,
            SpeedTi,
            MotorEncoderNoise,
            DirectEncoderNoise,
            DirectEncoderOffset,
            PositionFromDirect,
            Preload,
        ];
        for a in all {
            assert_eq!(
                PARAMS.iter().filter(|p| p.live == Some(a)).count(),
                1,
                "{a:?}"
            );
            assert!(of_live(a).object_offset.is_some());
        }
        let mut offsets: Vec<u16> = PARAMS.iter().filter_map(|p| p.object_offset).collect();
        offsets.sort();
        assert_eq!(offsets, (0..all.len() as u16).collect::<Vec<_>>());
    }

    #[test]
    fn moved_names_point_at_registry_keys_and_are_not_keys_themselves() {
        for (old, new) in MOVED {
            assert!(find(new).is_some(), "{new}");
            assert!(find(old).is_none(), "{old}");
            assert_eq!(moved(old), Some(*new));
        }
    }

    #[test]
    fn a_typo_gets_the_key_that_was_meant_and_nonsense_gets_none() {
        assert_eq!(suggest("backlsh_mm", keys()), Some("backlash_mm"));
        assert_eq!(suggest("backlash_um", keys()), Some("backlash_mm"));
        assert_eq!(suggest("kv_pers", keys()), Some("kv_per_s"));
        assert_eq!(suggest("BACKLASH_MM", keys()), Some("backlash_mm"));
        assert_eq!(
            suggest("stifness_n_per_um", keys()),
            Some("stiffness_n_per_um")
        );
        assert_eq!(suggest("colour", keys()), None);
        assert_eq!(suggest("x", keys()), None);
        assert_eq!(did_you_mean("nothing_like_it_at_all", keys()), "");
    }

    #[test]
    fn forms_convert_both_ways() {
        let (p, f) = find("backlash_mm").unwrap();
        assert_eq!(p.live, Some(AxisParam::Backlash));
        assert!((f.to_si(0.05) - 5e-5).abs() < 1e-18);
        assert!((f.from_si(5e-5) - 0.05).abs() < 1e-15);
        let (_, r) = find("backlash_deg").unwrap();
        assert!((r.to_si(1.0) - PI / 180.0).abs() < 1e-15);
        assert!(r.applies_to(true) && !r.applies_to(false));
    }
}
