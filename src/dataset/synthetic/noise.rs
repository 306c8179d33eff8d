//! Value noise: smooth random shading in surface coordinates, with octaves
//! that fade out once they are finer than the pixel footprint.

use super::rng::{hash_cell, unit_from_bits};

/// Lattice value noise in `[-1, 1]`, smooth (smoothstep-interpolated)
/// between integer lattice points.
pub fn value_noise(seed: u64, x: f64, y: f64) -> f64 {
    let (fx, fy) = (x.floor(), y.floor());
    let (ix, iy) = (fx as i64, fy as i64);
    let (tx, ty) = (smoothstep(x - fx), smoothstep(y - fy));
    let corner =
        |dx: i64, dy: i64| 2.0 * unit_from_bits(hash_cell(seed, 97, ix + dx, iy + dy)) - 1.0;
    let bottom = lerp(corner(0, 0), corner(1, 0), tx);
    let top = lerp(corner(0, 1), corner(1, 1), tx);
    lerp(bottom, top, ty)
}

/// Three octaves of value noise (wavelengths λ, λ/3, λ/9; amplitudes 1, ½, ¼)
/// at `(u, v)` metres. An octave fades out as `footprint` (metres per
/// pixel) grows past a quarter of its wavelength, which keeps far surfaces
/// from shimmering. Result roughly in `[-1.75, 1.75]`.
pub fn fractal_noise(seed: u64, u: f64, v: f64, wavelength: f64, footprint: f64) -> f64 {
    let mut sum = 0.0;
    let mut lambda = wavelength;
    let mut amplitude = 1.0;
    for octave in 0..3u64 {
        let visibility = fade(footprint / lambda, 0.08, 0.25);
        if visibility <= 0.0 {
            break;
        }
        let n = value_noise(seed.wrapping_add(octave), u / lambda, v / lambda);
        sum += amplitude * visibility * n;
        lambda /= 3.0;
        amplitude *= 0.5;
    }
    sum
}

/// 1 below `full`, 0 above `gone`, linear in between.
pub fn fade(ratio: f64, full: f64, gone: f64) -> f64 {
    ((gone - ratio) / (gone - full)).clamp(0.0, 1.0)
}

fn smoothstep(t: f64) -> f64 {
    t * t * (3.0 - 2.0 * t)
}

fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a + (b - a) * t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn value_noise_is_continuous_and_bounded() {
        let mut previous = value_noise(3, 0.0, 0.37);
        for i in 1..2000 {
            let x = i as f64 * 0.005;
            let n = value_noise(3, x, 0.37);
            assert!((-1.0..=1.0).contains(&n));
            assert!((n - previous).abs() < 0.05, "jump at x = {x}");
            previous = n;
        }
    }

    #[test]
    fn octaves_finer_than_the_footprint_are_dropped() {
        // With a footprint of a whole wavelength nothing is left.
        assert_eq!(fractal_noise(1, 0.3, 0.7, 1.0, 1.0), 0.0);
        assert!(fractal_noise(1, 0.3, 0.7, 1.0, 0.001) != 0.0);
    }
}
