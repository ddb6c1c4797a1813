//! The sRGB transfer function (IEC 61966-2-1) on 8-bit values: what colours are averaged
//! through (drape mip levels, anti-aliasing's linear-light resolve and its tests).

/// The linear value (0..1) of 8-bit sRGB value `v`.
pub fn srgb_to_linear(v: u8) -> f64 {
    let c = f64::from(v) / 255.0;
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The 8-bit sRGB value of linear `c` (clamped to 0..1), rounded.
pub fn linear_to_srgb8(c: f64) -> u8 {
    let c = c.clamp(0.0, 1.0);
    let s = if c <= 0.0031308 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_value_comes_back() {
        for v in 0..=255u8 {
            assert_eq!(linear_to_srgb8(srgb_to_linear(v)), v);
        }
        assert_eq!(linear_to_srgb8(0.5), 188);
    }
}
