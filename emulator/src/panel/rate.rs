//! The stream's rates: how often the collector sends, and how many samples a second and axis
//! it carries (the recording has every tick). Named by the collector ([`super::stream`]), the
//! routes and the history alike.

/// The collector's period, ms: 25 `samples` messages a second.
pub const PERIOD_MS: u64 = 40;
/// Most samples per second and axis in the stream (the recording has every tick).
pub const MAX_STREAM_HZ: u32 = 500;

/// Samples per second and axis the stream carries at `tick_hz`.
pub fn stream_rate_hz(tick_hz: u32) -> f64 {
    f64::from(tick_hz) / f64::from(decimation(tick_hz))
}

/// Every how many ticks the stream takes one.
pub fn decimation(tick_hz: u32) -> u32 {
    tick_hz.div_ceil(MAX_STREAM_HZ).max(1)
}
