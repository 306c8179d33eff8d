//! Value noise: smooth random shading in surface coordinates, with octaves
//! that fade out once they are finer than the pixel footprint.

/// Lattice value noise in `[-1, 1]`, smooth (smoothstep-interpolated)
/// between integer lattice points.
pub fn value_noise(seed: u64, x: f64, y: f64) -> f64 {
    let (fx, fy) = (floor(x), floor(y));
    let (ix, iy) = (fx as i64, fy as i64);
    let (tx, ty) = (smoothstep(x - fx), smoothstep(y - fy));
    let corner = |dx: i64, dy: i64| lattice_value(seed, ix + dx, iy + dy);
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
        let inverse = 1.0 / lambda;
        let n = value_noise(seed.wrapping_add(octave), u * inverse, v * inverse);
        sum += amplitude * visibility * n;
        lambda /= 3.0;
        amplitude *= 0.5;
    }
    sum
}

/// A random value in `[-1, 1]` for a lattice point: one multiply-xorshift
/// round, cheaper than a full hash and plenty for smooth shading.
fn lattice_value(seed: u64, ix: i64, iy: i64) -> f64 {
    let mut h = seed
        ^ (ix as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15)
        ^ (iy as u64).wrapping_mul(0xc2b2_ae3d_27d4_eb4f);
    h = (h ^ (h >> 29)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h ^= h >> 32;
    (h & 0xffff_ffff) as f64 * (2.0 / 4_294_967_295.0) - 1.0
}

/// `x.floor()` without the libm call (the baseline x86-64 target has no
/// rounding instruction); exact for |x| < 2⁶³.
pub fn floor(x: f64) -> f64 {
    let truncated = x as i64 as f64;
    if truncated > x {
        truncated - 1.0
    } else {
        truncated
    }
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
    fn fast_floor_equals_floor() {
        for x in [
            -2.5,
            -2.0,
            -0.1,
            -0.0,
            0.0,
            0.3,
            1.0,
            7.9,
            -1e9 - 0.5,
            123456.75,
        ] {
            assert_eq!(floor(x), x.floor(), "{x}");
        }
    }

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
