//! Position encoders as a drive reads them: quantised counts, optional offset and noise, and
//! fault injection (signal loss, count glitch).
//!
//! An encoder maps a true position (rad for the motor encoder, m or rad for the direct encoder)
//! to integer counts: `floor(x * counts_per_unit + offset_counts + noise) + glitch`. Noise is
//! approximately Gaussian (sum of four uniforms) from a seeded xorshift64* generator, so runs
//! are reproducible.

/// Static encoder data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EncoderParams {
    /// Counts per SI unit (counts/rad, counts/m).
    pub counts_per_unit: f64,
    /// Zero offset in SI units (added to the true position), e.g. thermal drift of a scale.
    pub offset: f64,
    /// Noise standard deviation, counts (0 = none).
    pub noise_counts: f64,
    /// PRNG seed for the noise.
    pub seed: u64,
}

/// Tiny deterministic PRNG (xorshift64*), seeded via splitmix64.
#[derive(Clone, Debug)]
pub struct XorShift64 {
    state: u64,
}

impl XorShift64 {
    pub fn new(seed: u64) -> Self {
        // splitmix64 of the seed, never zero.
        let mut z = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        XorShift64 { state: z | 1 }
    }

    #[inline(always)]
    pub fn next_u64(&mut self) -> u64 {
        let mut x = self.state;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.state = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    /// Uniform in [0, 1).
    #[inline(always)]
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Approximately standard normal (Irwin-Hall, four uniforms; |x| <= 2 sqrt 3).
    #[inline(always)]
    pub fn normal(&mut self) -> f64 {
        let s = self.uniform() + self.uniform() + self.uniform() + self.uniform();
        (s - 2.0) * 3.0f64.sqrt()
    }
}

/// One encoder channel with its fault state.
#[derive(Clone, Debug)]
pub struct Encoder {
    pub params: EncoderParams,
    rng: XorShift64,
    glitch: i64,
    signal_lost: bool,
    last: i64,
}

impl Encoder {
    pub fn new(params: EncoderParams) -> Self {
        Encoder {
            params,
            rng: XorShift64::new(params.seed),
            glitch: 0,
            signal_lost: false,
            last: 0,
        }
    }

    /// Read the encoder at true position `x` (SI). Frozen while the signal is lost.
    #[inline]
    pub fn read(&mut self, x: f64) -> i64 {
        if self.signal_lost {
            return self.last;
        }
        let mut c = (x + self.params.offset) * self.params.counts_per_unit;
        if self.params.noise_counts > 0.0 {
            c += self.params.noise_counts * self.rng.normal();
        }
        // floor without a libm call (no SSE4.1 on the baseline target). The cast saturates
        // (NaN gives 0); an absurd position saturates the count instead of overflowing, and
        // the drive's supervision faults on it.
        let t = c as i64;
        let floor = if (t as f64) > c {
            t.saturating_sub(1)
        } else {
            t
        };
        self.last = floor.saturating_add(self.glitch);
        self.last
    }

    /// The last reading, counts.
    pub fn counts(&self) -> i64 {
        self.last
    }

    /// The last reading converted back to SI (rad or m).
    pub fn position(&self) -> f64 {
        self.last as f64 / self.params.counts_per_unit
    }

    /// SI units per count.
    pub fn resolution(&self) -> f64 {
        1.0 / self.params.counts_per_unit
    }

    /// Signal loss: the reading freezes and [`Encoder::fault`] reports it until cleared.
    pub fn set_signal_lost(&mut self, lost: bool) {
        self.signal_lost = lost;
    }

    /// A count glitch: the reading jumps by `counts` from now on (as a missed/extra count
    /// burst on an incremental track does).
    pub fn inject_glitch(&mut self, counts: i64) {
        self.glitch = self.glitch.saturating_add(counts);
    }

    /// Clear accumulated glitches (e.g. on re-homing).
    pub fn clear_glitch(&mut self) {
        self.glitch = 0;
    }

    /// True while the signal is lost.
    pub fn fault(&self) -> bool {
        self.signal_lost
    }

    pub fn set_noise(&mut self, noise_counts: f64) {
        self.params.noise_counts = noise_counts;
    }

    pub fn set_offset(&mut self, offset: f64) {
        self.params.offset = offset;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantises_freezes_and_glitches() {
        let mut e = Encoder::new(EncoderParams {
            counts_per_unit: 1e6,
            offset: 0.0,
            noise_counts: 0.0,
            seed: 1,
        });
        assert_eq!(e.read(1.0000015e-3), 1000);
        assert_eq!(e.read(-0.5e-6), -1);
        e.set_signal_lost(true);
        assert_eq!(e.read(5.0), -1);
        assert!(e.fault());
        e.set_signal_lost(false);
        e.inject_glitch(7);
        assert_eq!(e.read(1e-3), 1007);
    }

    #[test]
    fn absurd_positions_saturate_instead_of_overflowing() {
        // Overflow-checked arithmetic (debug build): no panic for any position.
        let mut e = Encoder::new(EncoderParams {
            counts_per_unit: 1e6,
            offset: 0.0,
            noise_counts: 0.0,
            seed: 1,
        });
        assert_eq!(e.read(-1e300), i64::MIN);
        assert_eq!(e.read(1e300), i64::MAX);
        assert_eq!(e.read(f64::NEG_INFINITY), i64::MIN);
        assert_eq!(e.read(f64::NAN), 0);
        e.inject_glitch(5);
        assert_eq!(e.read(1e300), i64::MAX);
        e.inject_glitch(-10);
        assert_eq!(e.read(-1e300), i64::MIN);
    }

    #[test]
    fn noise_has_the_requested_spread() {
        let mut r = XorShift64::new(42);
        let n = 100_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            let x = r.normal();
            s += x;
            s2 += x * x;
        }
        let mean = s / n as f64;
        let var = s2 / n as f64 - mean * mean;
        assert!(mean.abs() < 0.02);
        assert!((var - 1.0).abs() < 0.03);
    }
}
