//! Drive control: the SINUMERIK-style cascade of the paper (position P on the direct encoder,
//! speed PI on the motor encoder, current loop in the motor model) and built-in motion.
//! Knows nothing of CANopen.

pub mod cascade;
pub mod motion;
pub mod params;
pub mod position;
pub mod speed;

pub use cascade::{Cascade, CascadeOutputs, CascadeParams, Command, Servo, ServoError, Setpoint};
pub use motion::{MotionSample, Segment, Trapezoid, VelocityProfile};
