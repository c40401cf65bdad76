//! The sun disc's spectral radiance at the ground: an extraterrestrial spectrum times the
//! atmosphere's direct transmittance along the sun's path (Preetham et al. 1999,
//! appendix A.1, after Iqbal 1983, *An Introduction to Solar Radiation*, ch. 6).
//!
//! # Maths and units
//!
//! Extraterrestrial spectrum: a 5778 K blackbody scaled to the solar constant,
//!
//! ```text
//! L₀(λ) = k · B(λ, 5778 K),   k = E_sc / (Ω_sun · σ T⁴/π),   E_sc = 1361 W m⁻²
//! Ω_sun = 2π (1 − cos(0.53°/2)) ≈ 6.72e-5 sr
//! ```
//!
//! so that `∫ L₀ dλ · Ω_sun = E_sc` over the whole spectrum (k ≈ 1.006: the blackbody's
//! own radiance nearly gives the solar constant already). Direct transmittance, λ in µm,
//! m the relative optical air mass:
//!
//! ```text
//! τ(λ) = τ_R · τ_a · τ_o · τ_g · τ_wa
//! τ_R  = exp(−0.008735 λ^−4.08 m)                                   Rayleigh
//! τ_a  = exp(−β λ^−α m),  α = 1.3,  β = 0.04608 T − 0.04586          Ångström aerosol
//! τ_o  = exp(−k_o(λ) l m),  l = 0.35 cm                               ozone
//! τ_g  = exp(−1.41 k_g(λ) m / (1 + 118.93 k_g(λ) m)^0.45)             mixed gases (O₂)
//! τ_wa = exp(−0.2385 k_wa(λ) w m / (1 + 20.07 k_wa(λ) w m)^0.45),  w = 2 cm   water vapour
//! m    = 1 / (cos θs + 0.15 (93.885 − θs[°])^−1.253)                  Kasten (1966)
//! ```
//!
//! `k_o`, `k_g`, `k_wa` (cm⁻¹) are the tables of Preetham's appendix (Iqbal's tables),
//! interpolated linearly in λ and zero outside them. Then on the 1 nm CIE 1931 grid,
//!
//! ```text
//! (X, Y, Z) = Σ_{λ=360}^{830} L₀(λ) τ(λ) (x̄, ȳ, z̄)(λ) · 1 nm       [W m⁻² sr⁻¹]
//! ```
//!
//! which is in plume's units directly: `683 · Y` is the luminance in cd m⁻².
//!
//! # Approximations
//!
//! The blackbody stands in for the measured extraterrestrial spectrum (it is within a few
//! per cent in the visible; its luminous efficacy is 92 lm/W, so the sun gives 125 klux
//! above the atmosphere against the commonly quoted 127.5–133.8 klux). The disc is
//! uniform (no limb darkening) and its whole area has the transmittance of its centre.
//! Ozone, water vapour and aerosol amounts are the paper's fixed values.

use plume_core::color::blackbody::{planck, STEFAN_BOLTZMANN};
use plume_core::color::cie1931::{CIE1931_2DEG, CIE1931_LAMBDA_MAX_NM, CIE1931_LAMBDA_MIN_NM};

/// Solar constant (total solar irradiance at 1 AU), W m⁻².
pub const SOLAR_CONSTANT: f64 = 1361.0;

/// Temperature of the blackbody that stands in for the extraterrestrial spectrum, K.
pub const SUN_TEMPERATURE: f64 = 5778.0;

/// Ozone column, cm at NTP (Preetham's `l`).
pub const OZONE_CM: f64 = 0.35;

/// Precipitable water vapour, cm (Preetham's `w`).
pub const WATER_VAPOUR_CM: f64 = 2.0;

/// Ångström wavelength exponent α for the aerosol (Preetham's recommended value).
pub const ANGSTROM_ALPHA: f64 = 1.3;

/// Ozone absorption coefficient k_o, (λ nm, cm⁻¹).
const OZONE: [(f64, f64); 64] = [
    (300.0, 10.0),
    (305.0, 4.8),
    (310.0, 2.7),
    (315.0, 1.35),
    (320.0, 0.8),
    (325.0, 0.38),
    (330.0, 0.16),
    (335.0, 0.075),
    (340.0, 0.04),
    (345.0, 0.019),
    (350.0, 0.007),
    (355.0, 0.0),
    (445.0, 0.003),
    (450.0, 0.003),
    (455.0, 0.004),
    (460.0, 0.006),
    (465.0, 0.008),
    (470.0, 0.009),
    (475.0, 0.012),
    (480.0, 0.014),
    (485.0, 0.017),
    (490.0, 0.021),
    (495.0, 0.025),
    (500.0, 0.03),
    (505.0, 0.035),
    (510.0, 0.04),
    (515.0, 0.045),
    (520.0, 0.048),
    (525.0, 0.057),
    (530.0, 0.063),
    (535.0, 0.07),
    (540.0, 0.075),
    (545.0, 0.08),
    (550.0, 0.085),
    (555.0, 0.095),
    (560.0, 0.103),
    (565.0, 0.11),
    (570.0, 0.12),
    (575.0, 0.122),
    (580.0, 0.12),
    (585.0, 0.118),
    (590.0, 0.115),
    (595.0, 0.12),
    (600.0, 0.125),
    (605.0, 0.13),
    (610.0, 0.12),
    (620.0, 0.105),
    (630.0, 0.09),
    (640.0, 0.079),
    (650.0, 0.067),
    (660.0, 0.057),
    (670.0, 0.048),
    (680.0, 0.036),
    (690.0, 0.028),
    (700.0, 0.023),
    (710.0, 0.018),
    (720.0, 0.014),
    (730.0, 0.011),
    (740.0, 0.01),
    (750.0, 0.009),
    (760.0, 0.007),
    (770.0, 0.004),
    (780.0, 0.0),
    (790.0, 0.0),
];

/// Uniformly mixed gases (the O₂ A band) k_g, (λ nm, cm⁻¹).
const MIXED_GASES: [(f64, f64); 4] = [(759.0, 0.0), (760.0, 3.0), (770.0, 0.21), (771.0, 0.0)];

/// Water vapour k_wa, (λ nm, cm⁻¹).
const WATER_VAPOUR: [(f64, f64); 13] = [
    (689.0, 0.0),
    (690.0, 0.016),
    (700.0, 0.024),
    (710.0, 0.0125),
    (720.0, 1.0),
    (730.0, 0.87),
    (740.0, 0.061),
    (750.0, 0.001),
    (760.0, 1e-5),
    (770.0, 1e-5),
    (780.0, 6e-4),
    (790.0, 0.0175),
    (800.0, 0.036),
];

/// Linear interpolation in a table of (λ, k) sorted by λ; 0 outside it.
fn table(points: &[(f64, f64)], lambda_nm: f64) -> f64 {
    let (first, last) = (points[0], points[points.len() - 1]);
    if !(first.0..=last.0).contains(&lambda_nm) {
        return 0.0;
    }
    let i = points.partition_point(|p| p.0 <= lambda_nm).clamp(1, points.len() - 1);
    let ((l0, k0), (l1, k1)) = (points[i - 1], points[i]);
    k0 + (k1 - k0) * (lambda_nm - l0) / (l1 - l0)
}

/// Solid angle of the sun disc (angular diameter `diameter_degrees`), sr.
#[must_use]
pub fn disc_solid_angle(diameter_degrees: f64) -> f64 {
    2.0 * std::f64::consts::PI * (1.0 - (0.5 * diameter_degrees).to_radians().cos())
}

/// Relative optical air mass towards a sun `theta_s` radians from the zenith (Kasten
/// 1966): 1 at the zenith, ≈ 36.5 at the horizon (finite there, unlike 1/cos θs).
#[must_use]
pub fn relative_optical_mass(theta_s: f64) -> f64 {
    let degrees = theta_s.to_degrees().min(90.0);
    1.0 / (theta_s.cos().max(0.0) + 0.15 * (93.885 - degrees).powf(-1.253))
}

/// Ångström turbidity coefficient β for Preetham's turbidity `turbidity` (his fit).
#[must_use]
pub fn angstrom_beta(turbidity: f64) -> f64 {
    0.04608 * turbidity - 0.04586
}

/// Direct transmittance τ(λ) of the atmosphere at `lambda_nm` along an air mass `m`, for
/// turbidity `turbidity` (the product in the module docs); in [0, 1].
#[must_use]
pub fn transmittance(lambda_nm: f64, m: f64, turbidity: f64) -> f64 {
    let lambda_um = lambda_nm * 1e-3;
    let rayleigh = -0.008735 * lambda_um.powf(-4.08) * m;
    let aerosol = -angstrom_beta(turbidity) * lambda_um.powf(-ANGSTROM_ALPHA) * m;
    let ozone = -table(&OZONE, lambda_nm) * OZONE_CM * m;
    let k_g = table(&MIXED_GASES, lambda_nm) * m;
    let gases = -1.41 * k_g / (1.0 + 118.93 * k_g).powf(0.45);
    let k_wa = table(&WATER_VAPOUR, lambda_nm) * WATER_VAPOUR_CM * m;
    let water = -0.2385 * k_wa / (1.0 + 20.07 * k_wa).powf(0.45);
    (rayleigh + aerosol + ozone + gases + water).exp()
}

/// Extraterrestrial spectral radiance of the sun disc L₀(λ), W m⁻² sr⁻¹ nm⁻¹: the
/// 5778 K blackbody scaled so that the disc (angular diameter `diameter_degrees`) gives
/// the solar constant.
#[must_use]
pub fn extraterrestrial_radiance(lambda_nm: f64, diameter_degrees: f64) -> f64 {
    let blackbody_radiance = STEFAN_BOLTZMANN * SUN_TEMPERATURE.powi(4) / std::f64::consts::PI;
    let k = SOLAR_CONSTANT / (disc_solid_angle(diameter_degrees) * blackbody_radiance);
    k * planck(lambda_nm, SUN_TEMPERATURE)
}

/// CIE 1931 XYZ of the sun disc's radiance (W m⁻² sr⁻¹; `683 · Y` in cd m⁻²) through an
/// air mass `m` (0: above the atmosphere).
#[must_use]
pub fn disc_xyz(m: f64, turbidity: f64, diameter_degrees: f64) -> [f64; 3] {
    let mut xyz = [0.0; 3];
    for (lambda_nm, cmf) in (CIE1931_LAMBDA_MIN_NM..=CIE1931_LAMBDA_MAX_NM).zip(&CIE1931_2DEG) {
        let lambda_nm = f64::from(lambda_nm);
        // Δλ = 1 nm.
        let l = extraterrestrial_radiance(lambda_nm, diameter_degrees)
            * transmittance(lambda_nm, m, turbidity);
        for (sum, weight) in xyz.iter_mut().zip(cmf) {
            *sum += l * weight;
        }
    }
    xyz
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_interpolate_and_vanish_outside() {
        assert_eq!(table(&OZONE, 605.0), 0.13);
        assert!((table(&OZONE, 602.5) - 0.1275).abs() < 1e-12);
        assert_eq!(table(&OZONE, 299.0), 0.0);
        assert_eq!(table(&OZONE, 800.0), 0.0);
        assert_eq!(table(&MIXED_GASES, 760.0), 3.0);
        assert_eq!(table(&WATER_VAPOUR, 720.0), 1.0);
        assert_eq!(table(&WATER_VAPOUR, 500.0), 0.0);
    }

    #[test]
    fn air_mass_is_one_at_the_zenith_and_finite_at_the_horizon() {
        // Kasten's fit leaves ≈ 0.1 % at the zenith (0.15 · 93.885^−1.253 ≈ 5e-4).
        assert!((relative_optical_mass(0.0) - 1.0).abs() < 1e-3);
        assert!((relative_optical_mass(60f64.to_radians()) - 2.0).abs() < 0.01);
        let horizon = relative_optical_mass(std::f64::consts::FRAC_PI_2);
        assert!((36.0..37.0).contains(&horizon), "{horizon}");
    }

    #[test]
    fn transmittance_falls_towards_blue_and_with_turbidity() {
        let m = 1.0;
        assert!(transmittance(450.0, m, 2.0) < transmittance(650.0, m, 2.0));
        assert!(transmittance(550.0, m, 6.0) < transmittance(550.0, m, 2.0));
        // At 550 nm, T = 2, m = 1: Rayleigh 0.905, aerosol 0.904, ozone 0.971 → 0.794.
        let t = transmittance(550.0, m, 2.0);
        assert!((t - 0.794).abs() < 0.003, "{t}");
        assert_eq!(transmittance(550.0, 0.0, 3.0), 1.0);
    }

    #[test]
    fn extraterrestrial_disc_gives_the_solar_constant() {
        // Integrate far beyond the CIE range, where the whole blackbody lies.
        let d = 0.53;
        let total: f64 =
            (1..200_000).map(|i| extraterrestrial_radiance(f64::from(i) * 0.5, d) * 0.5).sum();
        assert!((total * disc_solid_angle(d) / SOLAR_CONSTANT - 1.0).abs() < 1e-4, "{total}");
        // Above the atmosphere: 125 klux (quoted: 127.5–133.8 klux).
        let lux = 683.0 * disc_xyz(0.0, 2.0, d)[1] * disc_solid_angle(d);
        eprintln!("above the atmosphere: {lux:.0} lx, {:.1} lm/W", lux / SOLAR_CONSTANT);
        assert!((120e3..135e3).contains(&lux), "{lux}");
    }
}
