//! Colour for the procedural lights: CIE xyY and XYZ to linear sRGB (Rec. 709 primaries,
//! D65 white), and the colour of a black body of a given temperature.

/// Luminance Y of a linear sRGB colour.
pub fn luminance(rgb: [f64; 3]) -> f64 {
    0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
}

/// CIE XYZ to linear sRGB (IEC 61966-2-1). Out-of-gamut colours can have negative
/// channels; callers clamp.
pub fn xyz_to_rgb(xyz: [f64; 3]) -> [f64; 3] {
    let [x, y, z] = xyz;
    [
        3.2406 * x - 1.5372 * y - 0.4986 * z,
        -0.9689 * x + 1.8758 * y + 0.0415 * z,
        0.0557 * x - 0.2040 * y + 1.0570 * z,
    ]
}

/// Chromaticity (x, y) at luminance `big_y` to linear sRGB, negative channels clamped to 0.
pub fn xyy_to_rgb(x: f64, y: f64, big_y: f64) -> [f64; 3] {
    if y <= 0.0 || big_y <= 0.0 {
        return [0.0; 3];
    }
    let xyz = [x * big_y / y, big_y, (1.0 - x - y) * big_y / y];
    xyz_to_rgb(xyz).map(|v| v.max(0.0))
}

/// Lowest and highest colour temperature accepted, kelvin (the range of the Planckian
/// locus fit below).
pub const TEMPERATURE_RANGE: (f64, f64) = (1667.0, 25000.0);

/// Chromaticity (x, y) of a black body at `kelvin` (clamped to [`TEMPERATURE_RANGE`]), by
/// the cubic fit of Kim et al. (US patent 7024034, 2006) to the Planckian locus.
pub fn planck_xy(kelvin: f64) -> (f64, f64) {
    let t = kelvin.clamp(TEMPERATURE_RANGE.0, TEMPERATURE_RANGE.1);
    let (t1, t2, t3) = (1e3 / t, 1e6 / (t * t), 1e9 / (t * t * t));
    let x = if t <= 4000.0 {
        -0.266_123_9 * t3 - 0.234_358_9 * t2 + 0.877_695_6 * t1 + 0.179_910
    } else {
        -3.025_846_9 * t3 + 2.107_037_9 * t2 + 0.222_634_7 * t1 + 0.240_390
    };
    let (x2, x3) = (x * x, x * x * x);
    let y = if t <= 2222.0 {
        -1.106_381_4 * x3 - 1.348_110_20 * x2 + 2.185_558_32 * x - 0.202_196_83
    } else if t <= 4000.0 {
        -0.954_947_6 * x3 - 1.374_185_93 * x2 + 2.091_370_15 * x - 0.167_488_67
    } else {
        3.081_758_0 * x3 - 5.873_386_70 * x2 + 3.751_129_97 * x - 0.370_014_83
    };
    (x, y)
}

/// Linear sRGB colour of a black body at `kelvin`, scaled to luminance 1 (its gamut's
/// negative channels clamped to 0 first).
pub fn temperature_rgb(kelvin: f64) -> [f64; 3] {
    let (x, y) = planck_xy(kelvin);
    let rgb = xyy_to_rgb(x, y, 1.0);
    let l = luminance(rgb);
    rgb.map(|v| v / l)
}

/// `rgb` scaled to luminance 1 (unchanged if its luminance is 0).
pub fn unit_luminance(rgb: [f64; 3]) -> [f64; 3] {
    let l = luminance(rgb);
    if l > 0.0 { rgb.map(|v| v / l) } else { rgb }
}

/// `a` times `b`, channel by channel.
pub fn mul(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] * b[0], a[1] * b[1], a[2] * b[2]]
}

/// `a` times the scalar `s`.
pub fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    a.map(|v| v * s)
}

/// `a + b`.
pub fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

/// `a + t (b - a)`.
pub fn mix(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn daylight_is_near_white_and_candles_are_red() {
        // 6500 K is close to the sRGB white point D65
        let d = temperature_rgb(6500.0);
        for v in d {
            assert!((v - 1.0).abs() < 0.1, "{d:?}");
        }
        let warm = temperature_rgb(2000.0);
        assert!(warm[0] > 1.5 * warm[1] && warm[1] > warm[2], "{warm:?}");
        let cool = temperature_rgb(15000.0);
        assert!(cool[2] > cool[0], "{cool:?}");
        assert!((luminance(warm) - 1.0).abs() < 1e-12);
    }
}
