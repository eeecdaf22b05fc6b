//! Deterministic noise for the unit tests (a 64-bit LCG, Knuth's MMIX constants): the same
//! sequence on every run and platform.

/// LCG state; `Noise(seed)`.
pub(crate) struct Noise(pub(crate) u64);

impl Noise {
    /// Uniform in [0, 1), 24 bits.
    pub(crate) fn unit(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }

    /// Sum of 12 uniforms in [0, 1) minus 6 (approximately normal, variance 1).
    pub(crate) fn normal12(&mut self) -> f32 {
        let mut s = 0.0f32;
        for _ in 0..12 {
            s += self.unit();
        }
        s - 6.0
    }
}
