//! The simulated CNC axis behind the drive, as pipeline stages (rapier's style): the two-mass
//! mechanics with backlash contact, friction, motor and encoders ([`axis`]), the servo cascade
//! on it ([`control`]), the axis presets and their loader ([`presets`]), and the one registry
//! of their parameters ([`params`]: key, unit, SI scale, where each may be set).
//!
//! SI units inside; no fieldbus, no threads, no clocks: a step takes the state and a time step
//! and returns the next state. The emulator's drive adapter (crate `drive-emu`) puts a CiA 402
//! drive in front of it (docs/decisions/0012-crate-split.md).
//!
//! Modules, bottom layer first: a module imports only modules before it.

pub mod params;

pub mod axis;

pub mod control;

pub mod presets;
