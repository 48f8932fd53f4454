//! Colour maps for pictures of samplers and their tests (the `brdf test` images, the
//! viewer): sequential viridis for densities and counts, diverging RdBu for differences.

/// Viridis at nine evenly spaced stops (sequential, perceptually uniform, colour-blind safe).
const VIRIDIS: [[f32; 3]; 9] = [
    [68.0, 1.0, 84.0],
    [71.0, 44.0, 122.0],
    [59.0, 81.0, 139.0],
    [44.0, 113.0, 142.0],
    [33.0, 144.0, 141.0],
    [39.0, 173.0, 129.0],
    [92.0, 200.0, 99.0],
    [170.0, 220.0, 50.0],
    [253.0, 231.0, 37.0],
];

/// ColorBrewer's RdBu, blue through white to red.
const RDBU: [[f32; 3]; 7] = [
    [33.0, 102.0, 172.0],
    [67.0, 147.0, 195.0],
    [209.0, 229.0, 240.0],
    [247.0, 247.0, 247.0],
    [253.0, 219.0, 199.0],
    [214.0, 96.0, 77.0],
    [178.0, 24.0, 43.0],
];

/// Piecewise-linear lookup of `t` ∈ [0, 1] (clamped; NaN reads 0) in evenly spaced stops.
fn lookup(stops: &[[f32; 3]], t: f32) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (stops.len() - 1) as f32;
    let k = (x as usize).min(stops.len() - 2);
    let u = x - k as f32;
    let c = |i: usize| (stops[k][i] + u * (stops[k + 1][i] - stops[k][i]) + 0.5) as u8;
    [c(0), c(1), c(2)]
}

/// Viridis (dark violet at 0, yellow at 1) as sRGB bytes.
#[must_use]
pub fn viridis(t: f32) -> [u8; 3] {
    lookup(&VIRIDIS, t)
}

/// RdBu (blue at 0, white at ½, red at 1) as sRGB bytes.
#[must_use]
pub fn rdbu(t: f32) -> [u8; 3] {
    lookup(&RDBU, t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ends_and_middle() {
        assert_eq!(viridis(0.0), [68, 1, 84]);
        assert_eq!(viridis(1.0), [253, 231, 37]);
        assert_eq!(viridis(f32::NAN), [68, 1, 84]);
        assert_eq!(viridis(2.0), [253, 231, 37]);
        assert_eq!(rdbu(0.5), [247, 247, 247]);
        assert_eq!(rdbu(0.0), [33, 102, 172]);
        assert_eq!(rdbu(1.0), [178, 24, 43]);
    }
}
