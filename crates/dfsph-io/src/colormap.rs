//! Perceptually uniform colour map for scalar fields (viridis, van der Walt & Smith 2015, as
//! in matplotlib): dark purple for low values through teal to yellow for high ones. Readable
//! by colour-blind viewers and in greyscale print.
//!
//! And the rigid bodies' colours ([`body_fill`], [`BODY_EDGE`]), shared by the CPU
//! rasteriser and the interactive viewer so that a body looks the same in both.

use dfsph::rigid::spec::BODY_DENSITY_RANGE;

/// Viridis at nine evenly spaced values (0, 1/8, …, 1), sRGB.
const VIRIDIS: [[u8; 3]; 9] = [
    [0x44, 0x01, 0x54],
    [0x47, 0x2d, 0x7b],
    [0x3b, 0x52, 0x8b],
    [0x2c, 0x72, 0x8e],
    [0x21, 0x90, 0x8c],
    [0x27, 0xad, 0x81],
    [0x5d, 0xc8, 0x63],
    [0xaa, 0xdc, 0x32],
    [0xfd, 0xe7, 0x25],
];

/// The viridis colour of `t` in [0, 1] (clamped; NaN maps to 0), as sRGB bytes.
pub fn viridis(t: f32) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (VIRIDIS.len() - 1) as f32;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f32;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    std::array::from_fn(|c| (a[c] as f32 + f * (b[c] as f32 - a[c] as f32)).round() as u8)
}

/// Fill of the lightest bodies: pale wood.
pub const BODY_LIGHT: [u8; 3] = [236, 196, 128];
/// Fill of the heaviest bodies: dark bronze.
pub const BODY_DARK: [u8; 3] = [112, 62, 30];
/// Outline of every body: darker than any fill.
pub const BODY_EDGE: [u8; 3] = [60, 34, 14];

/// Fill of a body of `density` (kg/m³): pale wood for the lightest, through wood at about
/// water's density, to dark bronze for the heaviest (log scale over
/// [`BODY_DENSITY_RANGE`]), so floaters and sinkers look apart. Distinct from the water's
/// colour maps and the walls' greys.
pub fn body_fill(density: f64) -> [u8; 3] {
    let (lo, hi) = BODY_DENSITY_RANGE;
    let t = ((density.max(lo).ln() - lo.ln()) / (hi.ln() - lo.ln())).clamp(0.0, 1.0);
    // NaN density: `max` gives `lo`, t = 0.
    body_ramp(if t.is_nan() { 0.0 } else { t as f32 })
}

/// The bodies' fills from the lightest (`t` = 0) to the heaviest (`t` = 1), sRGB bytes.
pub fn body_ramp(t: f32) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    std::array::from_fn(|i| {
        let (a, b) = (f32::from(BODY_LIGHT[i]), f32::from(BODY_DARK[i]));
        (a + t * (b - a)).round() as u8
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_and_middle() {
        assert_eq!(viridis(0.0), [0x44, 0x01, 0x54]);
        assert_eq!(viridis(1.0), [0xfd, 0xe7, 0x25]);
        assert_eq!(viridis(0.5), [0x21, 0x90, 0x8c]);
        assert_eq!(viridis(-3.0), viridis(0.0));
        assert_eq!(viridis(7.0), viridis(1.0));
        assert_eq!(viridis(f32::NAN), viridis(0.0));
    }

    #[test]
    fn lightness_increases_monotonically() {
        let luma = |c: [u8; 3]| 0.2126 * c[0] as f32 + 0.7152 * c[1] as f32 + 0.0722 * c[2] as f32;
        let mut last = -1.0;
        for k in 0..=100 {
            let l = luma(viridis(k as f32 / 100.0));
            assert!(l >= last, "luma drops at {k}");
            last = l;
        }
    }

    #[test]
    fn light_bodies_are_paler_than_heavy_ones_and_edges_darker_still() {
        let (lo, hi) = BODY_DENSITY_RANGE;
        assert_eq!(body_fill(lo), BODY_LIGHT);
        assert_eq!(body_fill(hi), BODY_DARK);
        assert_eq!(body_fill(0.0), BODY_LIGHT);
        assert_eq!(body_fill(f64::NAN), BODY_LIGHT);
        assert_eq!(body_fill(f64::INFINITY), BODY_DARK);
        let (light, water, heavy) = (body_fill(100.0), body_fill(1000.0), body_fill(8000.0));
        for c in 0..3 {
            assert!(light[c] > water[c] && water[c] > heavy[c] && heavy[c] > BODY_EDGE[c]);
        }
    }
}
