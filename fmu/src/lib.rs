//! The simulated CNC axis as an FMI 2.0 co-simulation FMU, for HIL tool chains (Simulink, NI
//! VeriStand, dSPACE, OpenModelica, Dymola, FMPy): `drive-emu fmu --preset P -o axis.fmu`.
//!
//! - [`model`]: the variables (inputs: the position set-point and a velocity input; outputs:
//!   both encoders, speeds, current, torque, following error; parameters: every real-valued
//!   preset key of the parameter registry, with its unit) and one instance of the axis and its
//!   servo cascade (`drive_physics::control::cascade::Servo`), stepped a communication step at
//!   a time, the axis' own position cycles and physics substeps inside;
//! - [`capi`]: the fmi2 C functions over it (this crate built as a cdylib is the FMU's
//!   `binaries/linux64/drive_emu_axis.so`);
//! - [`package`]: `modelDescription.xml` and the `.fmu` zip.

pub mod model;

pub mod capi;

pub mod package;
