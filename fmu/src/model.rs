//! The FMU's model: its variables (from the parameter registry) and one instance of the axis
//! behind them, stepped by communication steps. Plain Rust: the C API ([`crate::capi`]) is a
//! thin shell around [`Instance`].

use std::f64::consts::PI;

use drive_physics::control::cascade::{Command, Servo, Setpoint};
use drive_physics::params::PARAMS;
use drive_physics::presets::{AxisConfig, AxisKind};

/// What a variable is to the importer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Causality {
    /// Set by the importer before each step.
    Input,
    /// Computed by the FMU.
    Output,
    /// Set before initialisation, fixed afterwards.
    Parameter,
}

/// FMI base type of a variable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// fmi2Real.
    Real,
    /// fmi2Boolean.
    Boolean,
}

/// One scalar variable of the model description.
#[derive(Clone, Debug, PartialEq)]
pub struct Variable {
    /// Its value reference.
    pub vr: u32,
    /// Its name (unit in the name, as the registry's keys).
    pub name: String,
    /// Its unit, for people and the model description.
    pub unit: &'static str,
    /// Input, output or parameter.
    pub causality: Causality,
    /// Real or Boolean.
    pub kind: Kind,
    /// Start value (inputs and parameters).
    pub start: f64,
    /// One line for the model description.
    pub description: String,
}

/// Value references of the fixed variables; parameters start at [`VR_PARAM`].
pub const VR_POSITION_SETPOINT: u32 = 0;
/// Velocity input: feed-forward in position control, the set-point in velocity control.
pub const VR_VELOCITY_SETPOINT: u32 = 1;
/// External load at the load (cutting force, a knock), N or N m: the registry's
/// `load_force_n` / `load_torque_nm`.
pub const VR_LOAD_FORCE: u32 = 2;
/// First output.
pub const VR_MOTOR_POSITION: u32 = 10;
/// Direct (linear scale or table) encoder at the load.
pub const VR_DIRECT_POSITION: u32 = 11;
/// Load velocity.
pub const VR_LOAD_VELOCITY: u32 = 12;
/// Motor speed.
pub const VR_MOTOR_SPEED: u32 = 13;
/// Motor current.
pub const VR_CURRENT: u32 = 14;
/// Motor torque.
pub const VR_TORQUE: u32 = 15;
/// Following error of the position loop.
pub const VR_FOLLOWING_ERROR: u32 = 16;
/// Boolean parameter: velocity control (the velocity input is the set-point).
pub const VR_VELOCITY_CONTROL: u32 = 99;
/// First registry parameter.
pub const VR_PARAM: u32 = 100;

/// The axis unit of a configuration: (name, SI per unit).
pub fn axis_unit(cfg: &AxisConfig) -> (&'static str, f64) {
    match cfg.kind {
        AxisKind::Linear => ("mm", 1e-3),
        AxisKind::Rotary => ("deg", PI / 180.0),
    }
}

/// The model's variables for an axis configuration: inputs, outputs, then every numeric
/// preset key of the registry that this kind of axis takes, with its value as start.
pub fn variables(cfg: &AxisConfig) -> Vec<Variable> {
    let mut v = io_variables(cfg);
    push_parameters(cfg, &mut v);
    v
}

/// The inputs, the outputs and the `velocity_control` switch, in value-reference order.
fn io_variables(cfg: &AxisConfig) -> Vec<Variable> {
    let (u, _) = axis_unit(cfg);
    let speed_unit: &'static str = if u == "mm" { "mm/s" } else { "deg/s" };
    let var = |vr, name: String, unit, causality, description: &str| Variable {
        vr,
        name,
        unit,
        causality,
        kind: Kind::Real,
        start: 0.0,
        description: description.to_string(),
    };
    vec![
        var(
            VR_POSITION_SETPOINT,
            format!("position_setpoint_{u}"),
            u,
            Causality::Input,
            "position set-point at the load (interpolated linearly over each communication step)",
        ),
        var(
            VR_VELOCITY_SETPOINT,
            format!("velocity_setpoint_{}", speed_unit.replace('/', "_per_")),
            speed_unit,
            Causality::Input,
            "velocity feed-forward (position control) or set-point (velocity_control)",
        ),
        {
            let spec =
                drive_physics::params::of_live(drive_physics::params::AxisParam::ExternalLoad);
            let form = spec.form(cfg.kind == AxisKind::Rotary);
            var(
                VR_LOAD_FORCE,
                form.key.to_string(),
                form.unit,
                Causality::Input,
                "external load at the load: a cutting force, or a knock that starts the limit cycle",
            )
        },
        var(
            VR_MOTOR_POSITION,
            format!("motor_encoder_position_{u}"),
            u,
            Causality::Output,
            "motor encoder, expressed at the load",
        ),
        var(
            VR_DIRECT_POSITION,
            format!("direct_encoder_position_{u}"),
            u,
            Causality::Output,
            "direct encoder (linear scale or table encoder) at the load",
        ),
        var(
            VR_LOAD_VELOCITY,
            format!("load_velocity_{}", speed_unit.replace('/', "_per_")),
            speed_unit,
            Causality::Output,
            "velocity of the load",
        ),
        var(
            VR_MOTOR_SPEED,
            "motor_speed_rpm".into(),
            "rpm",
            Causality::Output,
            "measured motor speed",
        ),
        var(
            VR_CURRENT,
            "motor_current_a".into(),
            "A",
            Causality::Output,
            "motor current",
        ),
        var(
            VR_TORQUE,
            "motor_torque_nm".into(),
            "N m",
            Causality::Output,
            "motor torque",
        ),
        var(
            VR_FOLLOWING_ERROR,
            format!("following_error_{u}"),
            u,
            Causality::Output,
            "following error of the position loop",
        ),
        Variable {
            vr: VR_VELOCITY_CONTROL,
            name: "velocity_control".into(),
            unit: "",
            causality: Causality::Parameter,
            kind: Kind::Boolean,
            start: 0.0,
            description: "true: the velocity input is the set-point (speed loop only)".into(),
        },
    ]
}

/// Every real-valued preset key of the registry that `cfg` has and its kind of axis takes, a
/// parameter with the configuration's value as start.
fn push_parameters(cfg: &AxisConfig, v: &mut Vec<Variable>) {
    let table = toml::Table::try_from(cfg).unwrap_or_default();
    let rotary = cfg.kind == AxisKind::Rotary;
    let mut vr = VR_PARAM;
    for p in PARAMS.iter().filter(|p| p.preset) {
        let form = p.form(rotary);
        if !form.applies_to(rotary) {
            continue;
        }
        // Real-valued keys this configuration has; counts, seeds and switches stay the file's.
        let Some(toml::Value::Float(x)) = table.get(form.key) else {
            continue;
        };
        v.push(Variable {
            vr,
            name: form.key.to_string(),
            unit: form.unit,
            causality: Causality::Parameter,
            kind: Kind::Real,
            start: *x,
            description: p.doc.to_string(),
        });
        vr += 1;
    }
}

/// Where an instance is in the FMI 2.0 co-simulation state machine.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// After instantiation: parameters may be set.
    Instantiated,
    /// Between enter and exit of initialisation mode.
    Initialization,
    /// Stepping.
    StepMode,
    /// After terminate.
    Terminated,
    /// A call failed: only reset or free.
    Error,
}

/// Why a call was refused.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelError(pub String);

impl std::fmt::Display for ModelError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// One instance of the axis.
pub struct Instance {
    base: AxisConfig,
    vars: Vec<Variable>,
    values: Vec<f64>,
    servo: Option<Servo>,
    unit_si: f64,
    /// The position set-point reached at the end of the last step, SI.
    last_setpoint: f64,
    time_s: f64,
    /// Which phase the instance is in.
    pub phase: Phase,
}

impl Instance {
    /// An instance of `cfg` (the FMU's `resources/axis.toml`).
    pub fn new(cfg: AxisConfig) -> Instance {
        let vars = variables(&cfg);
        let values = vars.iter().map(|v| v.start).collect();
        let (_, unit_si) = axis_unit(&cfg);
        Instance {
            base: cfg,
            vars,
            values,
            servo: None,
            unit_si,
            last_setpoint: 0.0,
            time_s: 0.0,
            phase: Phase::Instantiated,
        }
    }

    /// The model's variables.
    pub fn variables(&self) -> &[Variable] {
        &self.vars
    }

    fn index(&self, vr: u32) -> Result<usize, ModelError> {
        self.vars
            .iter()
            .position(|v| v.vr == vr)
            .ok_or_else(|| ModelError(format!("no variable with value reference {vr}")))
    }

    /// Set a variable: an input any time before a step, a parameter only before
    /// initialisation ends.
    pub fn set(&mut self, vr: u32, value: f64) -> Result<(), ModelError> {
        let i = self.index(vr)?;
        let v = &self.vars[i];
        match v.causality {
            Causality::Output => {
                return Err(ModelError(format!("`{}` is an output", v.name)));
            }
            Causality::Parameter
                if !matches!(self.phase, Phase::Instantiated | Phase::Initialization) =>
            {
                return Err(ModelError(format!(
                    "`{}` is a fixed parameter: set it before initialisation ends",
                    v.name
                )));
            }
            _ => {}
        }
        if !value.is_finite() {
            return Err(ModelError(format!("`{}`: {value} is not a number", v.name)));
        }
        self.values[i] = value;
        Ok(())
    }

    /// A variable's value (outputs as of the last step).
    pub fn get(&self, vr: u32) -> Result<f64, ModelError> {
        let i = self.index(vr)?;
        if self.vars[i].causality != Causality::Output {
            return Ok(self.values[i]);
        }
        let Some(s) = &self.servo else {
            return Ok(0.0);
        };
        let u = self.unit_si;
        Ok(match vr {
            VR_MOTOR_POSITION => s.motor_encoder_position() / u,
            VR_DIRECT_POSITION => s.direct_encoder_position() / u,
            VR_LOAD_VELOCITY => s.axis.load_velocity() / u,
            VR_MOTOR_SPEED => s.motor_velocity() * 30.0 / PI,
            VR_CURRENT => s.current(),
            VR_TORQUE => s.torque(),
            VR_FOLLOWING_ERROR => s.following_error() / u,
            _ => 0.0,
        })
    }

    /// The configuration with the parameters as set (validated by the preset loader: a
    /// value the axis cannot take is refused with its key and why).
    pub fn configuration(&self) -> Result<AxisConfig, ModelError> {
        let mut cfg = self.base.clone();
        for (v, x) in self.vars.iter().zip(&self.values) {
            if v.causality == Causality::Parameter && v.vr >= VR_PARAM && *x != v.start {
                cfg = cfg
                    .with_override(&v.name, &format!("{x:?}"))
                    .map_err(|e| ModelError(e.to_string()))?;
            }
        }
        Ok(cfg)
    }

    /// Leave initialisation: build the axis at rest at the position set-point.
    pub fn initialize(&mut self) -> Result<(), ModelError> {
        let cfg = self.configuration()?;
        let built = cfg.build().map_err(|e| ModelError(e.to_string()))?;
        let mut servo =
            Servo::new(built.axis, built.control).map_err(|e| ModelError(format!("{e:?}")))?;
        let x0 = self.values[self.index(VR_POSITION_SETPOINT)?] * self.unit_si;
        servo.reset_at_rest(x0);
        self.last_setpoint = x0;
        self.servo = Some(servo);
        self.phase = Phase::StepMode;
        Ok(())
    }

    /// Advance one communication step of `h_s` seconds: a whole number of the axis' position
    /// cycles, the position set-point interpolated linearly from the last step's to the input.
    pub fn do_step(&mut self, h_s: f64) -> Result<(), ModelError> {
        let velocity_control = self.values[self.index(VR_VELOCITY_CONTROL)?] != 0.0;
        let target = self.values[self.index(VR_POSITION_SETPOINT)?] * self.unit_si;
        let velocity = self.values[self.index(VR_VELOCITY_SETPOINT)?] * self.unit_si;
        // N or N m: the registry's SI scale of the spelling (1).
        let load = self.values[self.index(VR_LOAD_FORCE)?];
        let servo = self
            .servo
            .as_mut()
            .ok_or_else(|| ModelError("not initialised".into()))?;
        let cycle = servo.cycle_time();
        let n = (h_s / cycle).round();
        if !h_s.is_finite()
            || h_s <= 0.0
            || n < 1.0
            || (n * cycle - h_s).abs() > 1e-9 * h_s.max(1.0)
        {
            return Err(ModelError(format!(
                "communication step {h_s} s is not a whole number of the axis' position \
                 cycles ({cycle} s)"
            )));
        }
        if n > 1e7 {
            return Err(ModelError(format!(
                "communication step {h_s} s is over 10^7 position cycles"
            )));
        }
        let n = n as u64;
        let from = self.last_setpoint;
        servo.axis.set_external_load(load);
        for k in 1..=n {
            let setpoint = if velocity_control {
                Setpoint::Velocity {
                    velocity,
                    torque_ff: 0.0,
                }
            } else {
                Setpoint::Position {
                    position: from + (target - from) * (k as f64 / n as f64),
                    velocity_ff: velocity,
                    torque_ff: 0.0,
                }
            };
            servo.set_command(Command::new(setpoint));
            servo.step();
        }
        self.last_setpoint = target;
        self.time_s += h_s;
        let finite = [
            servo.direct_encoder_position(),
            servo.motor_encoder_position(),
            servo.torque(),
        ]
        .iter()
        .all(|x| x.is_finite());
        if !finite {
            self.phase = Phase::Error;
            return Err(ModelError("the axis' state is no longer finite".into()));
        }
        Ok(())
    }

    /// Simulated time, s.
    pub fn time_s(&self) -> f64 {
        self.time_s
    }

    /// Back to the state after instantiation (parameters back to their start values).
    pub fn reset(&mut self) {
        *self = Instance::new(self.base.clone());
    }
}
