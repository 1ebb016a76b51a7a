//! Permanent-magnet servo motor with its current loop.
//!
//! The closed current loop is modelled as a first-order lag with the configured bandwidth
//! (500-1000 Hz on real drives), discretised exactly for the physics step. The torque demand is
//! clipped to the motor's torque limit, which is the lower of the peak torque and the torque at
//! the current limit (`k_t * i_max`). Torque and current are proportional (`tau = k_t * i`).

/// Motor data (SI).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorParams {
    /// Rotor inertia including coupling / first gear, kg m^2.
    pub inertia: f64,
    /// Torque constant, N m/A.
    pub torque_constant: f64,
    /// Rated (continuous) torque, N m.
    pub rated_torque: f64,
    /// Rated current, A.
    pub rated_current: f64,
    /// Current limit of the power stage, A.
    pub max_current: f64,
    /// Maximum motor speed, rad/s.
    pub max_speed: f64,
    /// Closed current-loop bandwidth, Hz.
    pub current_bandwidth_hz: f64,
}

/// Motor with the current-loop state.
#[derive(Clone, Debug)]
pub struct Motor {
    pub params: MotorParams,
    /// Lag coefficient for one physics step: `1 - exp(-h * 2 pi f_c)`.
    alpha: f64,
    torque_limit: f64,
    demand: f64,
    torque: f64,
    /// False while the power stage is off ([`Motor::disable`] until the next demand).
    enabled: bool,
}

impl Motor {
    pub fn new(params: MotorParams, step: f64) -> Self {
        let mut m = Motor {
            params,
            alpha: 0.0,
            torque_limit: 0.0,
            demand: 0.0,
            torque: 0.0,
            enabled: false,
        };
        m.set_params(params, step);
        m
    }

    /// Replace the motor data (the current-loop state is kept).
    pub fn set_params(&mut self, params: MotorParams, step: f64) {
        self.params = params;
        self.alpha = 1.0 - (-step * 2.0 * std::f64::consts::PI * params.current_bandwidth_hz).exp();
        self.torque_limit = params.torque_constant * params.max_current;
    }

    /// Highest torque the power stage can deliver, N m.
    pub fn torque_limit(&self) -> f64 {
        self.torque_limit
    }

    /// Set the torque demand for the current loop (clipped to the motor's limit).
    #[inline(always)]
    pub fn set_demand(&mut self, torque: f64) {
        self.demand = torque.clamp(-self.torque_limit, self.torque_limit);
        self.enabled = true;
    }

    /// True once a demand has been set, false after [`Motor::disable`] (power stage off).
    pub fn enabled(&self) -> bool {
        self.enabled
    }

    /// Torque demand after clipping, N m.
    pub fn demand(&self) -> f64 {
        self.demand
    }

    /// Power stage off: demand and actual torque drop to zero at once.
    pub fn disable(&mut self) {
        self.demand = 0.0;
        self.torque = 0.0;
        self.enabled = false;
    }

    /// Advance the current loop by one physics step; returns the air-gap torque.
    #[inline(always)]
    pub fn step(&mut self) -> f64 {
        self.torque += (self.demand - self.torque) * self.alpha;
        self.torque
    }

    /// Actual torque, N m.
    pub fn torque(&self) -> f64 {
        self.torque
    }

    /// Actual current, A.
    pub fn current(&self) -> f64 {
        self.torque / self.params.torque_constant
    }
}
