//! The simulated CNC axis behind a CiA 402 drive, and everything that runs it.
