//! splitmix64: a tiny generator whose stream is a pure function of its seed, the same on
//! every machine. The procedural normal maps, dataset synthesis and the tests draw from it.

/// The generator; its state is the field.
#[derive(Clone, Debug)]
pub struct SplitMix(pub u64);

impl SplitMix {
    /// The next 64 bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1), 53 bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// `n` standard normal draws (Box-Muller, both of each pair).
    pub fn standard_normals(&mut self, n: usize) -> Vec<f64> {
        let mut out = Vec::with_capacity(n + 1);
        while out.len() < n {
            let u1 = 1.0 - self.uniform(); // in (0, 1]
            let u2 = std::f64::consts::TAU * self.uniform();
            let r = (-2.0 * u1.ln()).sqrt();
            out.push(r * u2.cos());
            out.push(r * u2.sin());
        }
        out.truncate(n);
        out
    }

    /// Uniform in 0..n (n > 0), by a 128-bit multiply.
    pub fn below(&mut self, n: usize) -> usize {
        ((u128::from(self.next_u64()) * n as u128) >> 64) as usize
    }
}
