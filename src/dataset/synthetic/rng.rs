//! A small seeded PRNG (SplitMix64) and stateless hashes of integer
//! coordinates, so every texture cell and every pixel's noise is a pure
//! function of the seed and its position (the same in any thread order).

/// SplitMix64's output mix: a bijective 64-bit hash with good avalanche.
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Hashes a seed with two signed cell coordinates and a layer index
/// (one multiply-xor per input, then one [`mix64`]).
pub fn hash_cell(seed: u64, layer: u64, ix: i64, iy: i64) -> u64 {
    let key = seed.wrapping_add(layer.wrapping_mul(0x9e37_79b9_7f4a_7c15))
        ^ (ix as u64).wrapping_mul(0xd6e8_feb8_6659_fd93)
        ^ (iy as u64)
            .wrapping_mul(0xa076_1d64_78bd_642f)
            .rotate_left(29);
    mix64(key)
}

/// The top 53 bits of a hash as a uniform number in `[0, 1)`.
pub fn unit_from_bits(bits: u64) -> f64 {
    (bits >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// The SplitMix64 generator: 64 bits of state, period 2⁶⁴.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    /// A generator started from `seed`.
    pub fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix64(self.state)
    }

    /// A uniform number in `[0, 1)`.
    pub fn next_unit(&mut self) -> f64 {
        unit_from_bits(self.next_u64())
    }

    /// A uniform number in `[low, high)`.
    pub fn uniform(&mut self, low: f64, high: f64) -> f64 {
        low + (high - low) * self.next_unit()
    }

    /// A standard normal number (Box–Muller, one of the pair).
    pub fn normal(&mut self) -> f64 {
        let u1 = 1.0 - self.next_unit(); // (0, 1]: the log stays finite
        let u2 = self.next_unit();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_stream_different_seed_different_stream() {
        let a: Vec<u64> = {
            let mut r = SplitMix64::new(42);
            (0..8).map(|_| r.next_u64()).collect()
        };
        let b: Vec<u64> = {
            let mut r = SplitMix64::new(42);
            (0..8).map(|_| r.next_u64()).collect()
        };
        let c: Vec<u64> = {
            let mut r = SplitMix64::new(43);
            (0..8).map(|_| r.next_u64()).collect()
        };
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn splitmix_matches_the_reference_values() {
        // Reference: Vigna's splitmix64.c seeded with 0.
        let mut r = SplitMix64::new(0);
        assert_eq!(r.next_u64(), 0xe220_a839_7b1d_cdaf);
        assert_eq!(r.next_u64(), 0x6e78_9e6a_a1b9_65f4);
    }

    #[test]
    fn units_lie_in_the_half_open_interval_and_average_one_half() {
        let mut r = SplitMix64::new(7);
        let n = 100_000;
        let mut sum = 0.0;
        for _ in 0..n {
            let u = r.next_unit();
            assert!((0.0..1.0).contains(&u));
            sum += u;
        }
        assert!((sum / n as f64 - 0.5).abs() < 0.01);
    }

    #[test]
    fn normals_have_unit_variance() {
        let mut r = SplitMix64::new(9);
        let n = 100_000;
        let xs: Vec<f64> = (0..n).map(|_| r.normal()).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.02, "mean {mean}");
        assert!((var - 1.0).abs() < 0.03, "variance {var}");
    }

    #[test]
    fn cell_hashes_differ_between_neighbours_and_layers() {
        let h = hash_cell(1, 0, 5, 5);
        assert_eq!(h, hash_cell(1, 0, 5, 5));
        assert_ne!(h, hash_cell(1, 0, 6, 5));
        assert_ne!(h, hash_cell(1, 0, 5, 6));
        assert_ne!(h, hash_cell(1, 1, 5, 5));
        assert_ne!(h, hash_cell(2, 0, 5, 5));
        assert_ne!(hash_cell(1, 0, -1, 0), hash_cell(1, 0, 0, -1));
    }
}
