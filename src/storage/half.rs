//! IEEE 754 half precision (binary16) conversions, for descriptor storage:
//! round to nearest, ties to even; overflow to ±∞; NaN stays NaN.

/// The binary16 bits nearest to `value`.
pub fn f32_to_f16_bits(value: f32) -> u16 {
    let bits = value.to_bits();
    let sign = ((bits >> 16) & 0x8000) as u16;
    let exponent = ((bits >> 23) & 0xff) as i32;
    let mantissa = bits & 0x007f_ffff;
    if exponent == 0xff {
        // Infinity or NaN (a NaN keeps a payload bit so it stays NaN).
        let nan = if mantissa != 0 { 0x0200 } else { 0 };
        return sign | 0x7c00 | nan;
    }
    let half_exponent = exponent - 127 + 15;
    if half_exponent >= 0x1f {
        return sign | 0x7c00;
    }
    if half_exponent <= 0 {
        // Subnormal half (or zero): shift the full mantissa into place.
        if half_exponent < -10 {
            return sign;
        }
        let full = mantissa | 0x0080_0000;
        let shift = (14 - half_exponent) as u32;
        let half_mantissa = full >> shift;
        let remainder = full & ((1 << shift) - 1);
        let halfway = 1 << (shift - 1);
        let round_up = remainder > halfway || (remainder == halfway && half_mantissa & 1 == 1);
        return sign | (half_mantissa as u16 + u16::from(round_up));
    }
    let half_mantissa = (mantissa >> 13) as u16;
    let remainder = mantissa & 0x1fff;
    let round_up = remainder > 0x1000 || (remainder == 0x1000 && half_mantissa & 1 == 1);
    // A carry out of the mantissa correctly bumps the exponent (up to ∞).
    (sign | ((half_exponent as u16) << 10) | half_mantissa) + u16::from(round_up)
}

/// The value of binary16 bits.
pub fn f16_bits_to_f32(bits: u16) -> f32 {
    let sign = u32::from(bits & 0x8000) << 16;
    let exponent = u32::from((bits >> 10) & 0x1f);
    let mantissa = u32::from(bits & 0x03ff);
    let out = match (exponent, mantissa) {
        (0, 0) => sign,
        (0, m) => {
            // Subnormal: value = m · 2⁻²⁴.
            let value = m as f32 * f32::from_bits(0x3380_0000);
            return if sign != 0 { -value } else { value };
        }
        (0x1f, 0) => sign | 0x7f80_0000,
        (0x1f, m) => sign | 0x7f80_0000 | (m << 13),
        (e, m) => sign | ((e + 127 - 15) << 23) | (m << 13),
    };
    f32::from_bits(out)
}

#[cfg(test)]
mod tests {
    use super::{f16_bits_to_f32, f32_to_f16_bits};

    #[test]
    fn known_values_convert_exactly() {
        for (value, bits) in [
            (0.0f32, 0x0000u16),
            (-0.0, 0x8000),
            (1.0, 0x3c00),
            (-2.0, 0xc000),
            (0.5, 0x3800),
            (65504.0, 0x7bff),
            (6.103_515_6e-5, 0x0400),
            (5.960_464_5e-8, 0x0001),
            (f32::INFINITY, 0x7c00),
            (1e6, 0x7c00),
            (0.333_251_95, 0x3555),
        ] {
            assert_eq!(f32_to_f16_bits(value), bits, "{value}");
            if value.abs() < 1e5 {
                assert_eq!(f16_bits_to_f32(bits), value, "{bits:#06x}");
            }
        }
        assert!(f16_bits_to_f32(f32_to_f16_bits(f32::NAN)).is_nan());
    }

    #[test]
    fn every_half_round_trips_and_rounding_is_nearest() {
        for bits in 0..=u16::MAX {
            let value = f16_bits_to_f32(bits);
            if value.is_nan() {
                continue;
            }
            assert_eq!(f32_to_f16_bits(value), bits, "{bits:#06x}");
        }
        // Unit-range values (SuperPoint descriptors): error at most half an ulp.
        let mut x = -1.0f32;
        while x <= 1.0 {
            let back = f16_bits_to_f32(f32_to_f16_bits(x));
            let ulp = if x.abs() < 6.1e-5 {
                5.96e-8
            } else {
                x.abs() / 1024.0 * 2.0
            };
            assert!((back - x).abs() <= ulp / 2.0 + 1e-12, "{x} -> {back}");
            x += 0.000_731;
        }
    }
}
