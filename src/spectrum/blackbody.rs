//! Blackbody radiance as linear RGB (docs/references.md §15.3): Planck's law integrated against
//! the CIE 1931 2° colour matching functions, then XYZ → linear Rec.709 (D65).
//!
//! The colour matching functions are the multi-lobe piecewise-Gaussian fits of Wyman, Sloan
//! and Shirley 2013 ("Simple Analytic Approximations to the CIE XYZ Color Matching
//! Functions"), within a few percent of the tabulated CIE 1931 functions. The result is
//! *radiometric*: X = ∫ B_λ(T) x̄(λ) dλ over 360–830 nm in W·m⁻²·sr⁻¹ (no 683 lm/W factor), so
//! Y at 1000 K is about 4·10⁻³, at 1500 K about 11 and at 3000 K about 4.4·10⁴; scenes scale
//! it to their units (`emission_scale`).

use super::Rgb;

/// Planck's constant (J·s).
const H: f64 = 6.626_070_15e-34;
/// Speed of light (m/s).
const C: f64 = 299_792_458.0;
/// Boltzmann's constant (J/K).
const K: f64 = 1.380_649e-23;

/// The piecewise Gaussian of Wyman et al. 2013: width `s1` below the mean, `s2` above.
fn lobe(lambda: f64, mu: f64, s1: f64, s2: f64) -> f64 {
    let s = if lambda < mu { s1 } else { s2 };
    let x = (lambda - mu) / s;
    (-0.5 * x * x).exp()
}

/// The CIE 1931 2° colour matching functions (x̄, ȳ, z̄) at wavelength `lambda` (nm), by the
/// multi-lobe fit of Wyman, Sloan and Shirley 2013.
#[must_use]
pub fn cie_xyz(lambda: f64) -> [f64; 3] {
    let x = 1.056 * lobe(lambda, 599.8, 37.9, 31.0) + 0.362 * lobe(lambda, 442.0, 16.0, 26.7)
        - 0.065 * lobe(lambda, 501.1, 20.4, 26.2);
    let y = 0.821 * lobe(lambda, 568.8, 46.9, 40.5) + 0.286 * lobe(lambda, 530.9, 16.3, 31.1);
    let z = 1.217 * lobe(lambda, 437.0, 11.8, 36.0) + 0.681 * lobe(lambda, 459.0, 26.0, 13.8);
    [x, y, z]
}

/// Planck's spectral radiance B_λ(T) at wavelength `lambda_nm` (nm) and temperature `kelvin`,
/// in W·m⁻²·sr⁻¹·nm⁻¹ (0 for T ≤ 0).
#[must_use]
pub fn planck(lambda_nm: f64, kelvin: f64) -> f64 {
    if !(kelvin > 0.0) {
        return 0.0;
    }
    let l = lambda_nm * 1e-9;
    let e = H * C / (l * K * kelvin);
    if e > 700.0 {
        return 0.0;
    }
    2.0 * H * C * C / (l.powi(5) * e.exp_m1()) * 1e-9
}

/// CIE XYZ of the blackbody at `kelvin` (radiometric, W·m⁻²·sr⁻¹), by the midpoint rule over
/// 360–830 nm in 1 nm steps.
#[must_use]
pub fn blackbody_xyz(kelvin: f64) -> [f64; 3] {
    let mut xyz = [0.0f64; 3];
    for i in 0..470 {
        let lambda = 360.5 + f64::from(i);
        let b = planck(lambda, kelvin);
        let cmf = cie_xyz(lambda);
        for c in 0..3 {
            xyz[c] += b * cmf[c];
        }
    }
    xyz
}

/// CIE XYZ → linear Rec.709 RGB (D65 white).
#[must_use]
pub fn xyz_to_linear_rgb(xyz: [f64; 3]) -> [f64; 3] {
    let [x, y, z] = xyz;
    [
        3.240_454_2 * x - 1.537_138_5 * y - 0.498_531_4 * z,
        -0.969_266_0 * x + 1.876_010_8 * y + 0.041_556_0 * z,
        0.055_643_4 * x - 0.204_025_9 * y + 1.057_225_2 * z,
    ]
}

/// Blackbody radiance at `kelvin` as linear Rec.709 RGB (W·m⁻²·sr⁻¹ per channel), with the
/// out-of-gamut negative channels of low temperatures clamped to zero.
#[must_use]
pub fn blackbody_rgb(kelvin: f64) -> Rgb {
    let rgb = xyz_to_linear_rgb(blackbody_xyz(kelvin));
    Rgb(rgb.map(|v| v.max(0.0) as f32))
}

/// [`blackbody_rgb`] tabulated over `[0, t_max]` for per-lookup use (linear interpolation
/// between 1024 entries; temperatures outside the range are clamped to it).
#[derive(Clone, Debug)]
pub struct BlackbodyTable {
    t_max: f32,
    rgb: Vec<Rgb>,
}

impl BlackbodyTable {
    /// Entries of the table.
    const ENTRIES: usize = 1024;

    /// The table over `[0, t_max]` kelvin (`t_max` is clamped to at least 1 K).
    #[must_use]
    pub fn new(t_max: f32) -> Self {
        let t_max = if t_max.is_finite() {
            t_max.max(1.0)
        } else {
            1.0
        };
        let rgb = (0..Self::ENTRIES)
            .map(|i| blackbody_rgb(f64::from(t_max) * i as f64 / (Self::ENTRIES - 1) as f64))
            .collect();
        BlackbodyTable { t_max, rgb }
    }

    /// Radiance at `kelvin` (linear interpolation in the table).
    #[must_use]
    pub fn at(&self, kelvin: f32) -> Rgb {
        let x = (kelvin / self.t_max).clamp(0.0, 1.0) * (Self::ENTRIES - 1) as f32;
        let i = (x as usize).min(Self::ENTRIES - 2);
        let f = x - i as f32;
        match (self.rgb.get(i), self.rgb.get(i + 1)) {
            (Some(&a), Some(&b)) => a * (1.0 - f) + b * f,
            _ => Rgb::ZERO,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fitted_colour_matching_functions_have_the_cie_peaks() {
        // CIE 1931: ȳ(555) ≈ 1.0, x̄(600) ≈ 1.06, z̄(445) ≈ 1.78 (tabulated values).
        assert!((cie_xyz(555.0)[1] - 1.0).abs() < 0.03);
        assert!((cie_xyz(600.0)[0] - 1.062).abs() < 0.04);
        assert!((cie_xyz(445.0)[2] - 1.78).abs() < 0.08);
    }

    #[test]
    fn a_6500_kelvin_blackbody_is_nearly_white_and_fire_is_red() {
        let w = blackbody_rgb(6504.0);
        let m = w.max_component();
        assert!(w.min_component() > 0.85 * m, "{w:?}");
        let fire = blackbody_rgb(1500.0);
        assert!(fire[0] > 5.0 * fire[1] && fire[1] >= fire[2], "{fire:?}");
        assert_eq!(blackbody_rgb(0.0), Rgb::ZERO);
        assert_eq!(blackbody_rgb(-5.0), Rgb::ZERO);
    }

    #[test]
    fn stefan_boltzmann_scaling_of_the_visible_band_is_steep() {
        // Y grows much faster than T⁴ in the visible at fire temperatures (Wien's tail).
        let y1 = blackbody_xyz(1000.0)[1];
        let y3 = blackbody_xyz(3000.0)[1];
        assert!(y3 / y1 > 81.0 * 100.0, "{y1} {y3}");
    }

    #[test]
    fn the_table_interpolates_the_curve() {
        let table = BlackbodyTable::new(4000.0);
        for t in [800.0f32, 1500.0, 2500.0, 3999.0] {
            let a = table.at(t);
            let b = blackbody_rgb(f64::from(t));
            for c in 0..3 {
                assert!(
                    (a[c] - b[c]).abs() <= 0.01 * b.max_component() + 1e-9,
                    "{t}: {a:?} {b:?}"
                );
            }
        }
        assert_eq!(table.at(-3.0), Rgb::ZERO);
    }
}
