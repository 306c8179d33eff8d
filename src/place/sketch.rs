//! A count sketch of long global descriptors (feature hashing, Weinberger
//! et al. 2009): value `i` of the descriptor is added, with sign `s(i)`, to
//! bucket `h(i)` of [`SKETCH_DIM`]. Dot products of sketches estimate dot
//! products of the descriptors without bias, with a standard deviation
//! of about `√(1 + cos²) / √SKETCH_DIM` (0.06 for unit vectors).
//!
//! The keyframe database ranks every keyframe by its sketch and computes
//! the exact similarity for a shortlist only, so that a query over
//! thousands of 16,384-value VLADs reads 32× less memory. `h` and `s` come
//! from a fixed hash of the index: the same on every machine and run.

/// Values of a sketch.
pub const SKETCH_DIM: usize = 512;

/// The bucket and sign of every index of a descriptor.
#[derive(Debug, Clone)]
pub(crate) struct CountSketch {
    bucket: Vec<u32>,
    sign: Vec<f32>,
}

/// SplitMix64's finaliser: a fixed, well-mixed hash of `x`.
fn mix(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

impl CountSketch {
    /// The sketch of descriptors of `dim` values.
    pub(crate) fn new(dim: usize) -> Self {
        let (mut bucket, mut sign) = (Vec::with_capacity(dim), Vec::with_capacity(dim));
        for i in 0..dim {
            let h = mix(i as u64);
            bucket.push((h % SKETCH_DIM as u64) as u32);
            sign.push(if h >> 63 == 0 { 1.0 } else { -1.0 });
        }
        Self { bucket, sign }
    }

    /// Appends the sketch of `descriptor` (of the length given to
    /// [`Self::new`]) to `out`.
    pub(crate) fn push(&self, descriptor: &[f32], out: &mut Vec<f32>) {
        let start = out.len();
        out.resize(start + SKETCH_DIM, 0.0);
        let row = &mut out[start..];
        for ((x, b), s) in descriptor.iter().zip(&self.bucket).zip(&self.sign) {
            row[*b as usize] += s * x;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{CountSketch, SKETCH_DIM};
    use crate::place::global_descriptor::{dot, l2_normalise};
    use crate::place::SeededRng;

    #[test]
    fn sketch_dot_products_estimate_the_true_ones() {
        let dim = 16_384;
        let sketch = CountSketch::new(dim);
        let mut rng = SeededRng::new(7);
        let mut unit = || {
            let mut v: Vec<f32> = (0..dim).map(|_| rng.next_unit() as f32 - 0.5).collect();
            l2_normalise(&mut v);
            v
        };
        let mut worst = 0.0f32;
        for _ in 0..20 {
            let (a, noise) = (unit(), unit());
            // b has cosine about 0.6 with a.
            let mut b: Vec<f32> = a
                .iter()
                .zip(&noise)
                .map(|(x, n)| 0.6 * x + 0.8 * n)
                .collect();
            l2_normalise(&mut b);
            let (mut sa, mut sb) = (Vec::new(), Vec::new());
            sketch.push(&a, &mut sa);
            sketch.push(&b, &mut sb);
            assert_eq!(sa.len(), SKETCH_DIM);
            worst = worst.max((dot(&sa, &sb) - dot(&a, &b)).abs());
        }
        // 20 draws, standard deviation about 0.05: 0.25 is 5 sigma.
        assert!(worst < 0.25, "sketch error {worst}");
        assert!(worst > 0.0, "a sketch that is exact is not a sketch");
    }
}
