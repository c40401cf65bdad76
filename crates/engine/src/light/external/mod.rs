//! Lights besides the volume's own emission: distant lights (suns), sphere and point
//! lights, and environments (constant, lat-long maps, the built-in sky). The integrator
//! samples them as one strategy, separate from the volume's (NEE/FNEE), and weighs each
//! against phase-function sampling (METHOD.md §8; pbrt-v4's light sampling is the model).
//!
//! **Light choice.** One light per scattering vertex, chosen with probability ∝ its power
//! `Φ` (luminance, Rec.709 Y), by an alias table (`sampling::alias`). With `R` the radius
//! of the volume's bounding sphere, light reaching it from infinity counts the flux
//! through its cross-section: `Φ = π R² E` for a distant light of irradiance `E`,
//! `Φ = π R² ∫ L dω` for an environment; a sphere light counts its emitted power.
//!
//! **Estimator at a vertex `x`** (incoming `ω_o`, phase `f`, throughput `β`): light `i`
//! with pmf `P_i`, direction `ω ~ p_i`, exact shadow transmittance `τ(x, ω, t_i)` from
//! regular tracking (no extra noise):
//!
//! ```text
//! β · f(ω_o, ω) · τ · L_i(ω) · w(P_i p_i(ω), f) / (P_i p_i(ω))
//! ```
//!
//! For a delta light (a point light, or a sun of zero diameter) `L_i/p_i` is replaced by
//! its irradiance and `w = 1`; forward paths cannot reach it.
//!
//! **Forward paths** that reach a light (escape to infinity or hit a sphere light) add
//! `β · τ̂ · L_i(ω) · w(f, P_i p_i(ω))`, `τ̂` the tracker's unbiased transmittance estimate;
//! camera rays (no partner technique) have `w = 1`. With the power heuristic the two
//! weights sum to one for every direction (tested in `tests/lights.rs`).
//!
//! Everything here is pure: randomness enters as `u` arguments.

pub mod distant;
pub mod environment;
pub mod sample;
pub mod settings;
pub mod sphere;

use glam::DVec3;

pub use distant::Distant;
pub use environment::{Environment, Radiance};
pub use sample::{frame, LightSample};
pub use sphere::Sphere;

use plume_core::color::Rgb;
use plume_core::sampling::alias::AliasTable;
use plume_scene::MisHeuristic;
use plume_volume::field::Ray;

/// One external light.
#[derive(Debug)]
pub enum Light {
    /// A sun: radiance from a cone of directions, or a delta direction.
    Distant(Distant),
    /// A sphere or point light.
    Sphere(Sphere),
    /// A constant or mapped environment.
    Environment(Environment),
}

/// A light sample with the light it came from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChosenLight {
    /// Index of the light.
    pub index: usize,
    /// Probability of choosing it.
    pub pmf: f64,
    /// The direction sample.
    pub sample: LightSample,
}

/// The scene's external lights with their choice table.
#[derive(Debug)]
pub struct ExternalLights {
    lights: Vec<Light>,
    choice: AliasTable,
    /// Lights at infinity that a ray can reach (environments, distant lights with a disc).
    at_infinity: Vec<usize>,
    /// Sphere lights with a radius (opaque, hit by rays).
    spheres: Vec<usize>,
    /// Each light's group (index into `groups`).
    group_of: Vec<usize>,
    /// Light groups (AOV layers), in order of first appearance.
    groups: Vec<String>,
}

impl Light {
    /// Power by which lights are chosen: luminance of `Φ` (see the module docs), for a
    /// volume of bounding radius `radius`.
    fn power(&self, radius: f64) -> f64 {
        let disc = std::f64::consts::PI * radius * radius;
        match self {
            Light::Distant(d) => disc * f64::from(d.irradiance().luminance()),
            Light::Sphere(s) => f64::from(s.power().luminance()),
            Light::Environment(e) => disc * e.luminance_integral(),
        }
    }

    /// The default group of a light of this kind.
    fn kind(&self) -> &'static str {
        match self {
            Light::Distant(_) => "sun",
            Light::Sphere(_) => "sphere",
            Light::Environment(_) => "environment",
        }
    }

    fn sample(&self, x: DVec3, u: [f64; 2]) -> Option<LightSample> {
        match self {
            Light::Distant(d) => Some(d.sample(u)),
            Light::Sphere(s) => s.sample(x, u),
            Light::Environment(e) => e.sample(u),
        }
    }

    fn pdf(&self, x: DVec3, direction: DVec3) -> f64 {
        match self {
            Light::Distant(d) => d.pdf(direction),
            Light::Sphere(s) => s.pdf(x, direction),
            Light::Environment(e) => e.pdf(direction),
        }
    }
}

impl ExternalLights {
    /// The lights of a scene whose volume has bounding-sphere radius `radius`; `None`
    /// when there are none, or none with power (the scene then pays nothing).
    #[must_use]
    pub fn new(lights: Vec<Light>, radius: f64) -> Option<ExternalLights> {
        let radius = if radius.is_finite() && radius > 0.0 { radius } else { 1.0 };
        let power: Vec<f64> = lights.iter().map(|l| l.power(radius)).collect();
        let choice = AliasTable::new(&power)?;
        let at_infinity = (0..lights.len())
            .filter(|&i| match &lights[i] {
                Light::Distant(d) => !d.is_delta(),
                Light::Environment(_) => true,
                Light::Sphere(_) => false,
            })
            .collect();
        let spheres = (0..lights.len())
            .filter(|&i| matches!(&lights[i], Light::Sphere(s) if !s.is_point()))
            .collect();
        let names: Vec<String> = lights.iter().map(|l| l.kind().to_string()).collect();
        let mut set = ExternalLights {
            lights,
            choice,
            at_infinity,
            spheres,
            group_of: Vec::new(),
            groups: Vec::new(),
        };
        set.set_groups(&names);
        Some(set)
    }

    /// Put light `i` in group `names[i]` (AOV layers; groups in order of first
    /// appearance).
    ///
    /// # Panics
    /// If there is not one name per light.
    pub fn set_groups(&mut self, names: &[String]) {
        assert_eq!(names.len(), self.lights.len(), "one group name per light");
        self.groups.clear();
        self.group_of = names
            .iter()
            .map(|n| {
                self.groups.iter().position(|g| g == n).unwrap_or_else(|| {
                    self.groups.push(n.clone());
                    self.groups.len() - 1
                })
            })
            .collect();
    }

    /// The light groups, in the order of their AOV layers.
    #[must_use]
    pub fn groups(&self) -> &[String] {
        &self.groups
    }

    /// The group of light `index`.
    #[inline]
    #[must_use]
    pub fn group(&self, index: usize) -> usize {
        self.group_of[index]
    }

    /// The lights.
    #[must_use]
    pub fn lights(&self) -> &[Light] {
        &self.lights
    }

    /// Probability of choosing light `index`.
    #[must_use]
    pub fn pmf(&self, index: usize) -> f64 {
        self.choice.pmf(index)
    }

    /// Choose a light with `u_choice` and sample a direction to it from `x` with `u`.
    #[must_use]
    pub fn sample(&self, x: DVec3, u_choice: f64, u: [f64; 2]) -> Option<ChosenLight> {
        let c = self.choice.sample(u_choice);
        let sample = self.lights[c.index].sample(x, u)?;
        Some(ChosenLight { index: c.index, pmf: c.pmf, sample })
    }

    /// The light technique's solid-angle density for light `index` at `x` in unit
    /// `direction`, choice included: `P_i p_i(ω)`.
    #[must_use]
    pub fn pdf(&self, index: usize, x: DVec3, direction: DVec3) -> f64 {
        self.pmf(index) * self.lights[index].pdf(x, direction)
    }

    /// The nearest sphere light hit by `ray`: its distance and index.
    #[must_use]
    pub fn hit(&self, ray: &Ray) -> Option<(f64, usize)> {
        let mut best: Option<(f64, usize)> = None;
        for &i in &self.spheres {
            if let Light::Sphere(s) = &self.lights[i] {
                if let Some(t) = s.intersect(ray) {
                    if best.is_none_or(|(b, _)| t < b) {
                        best = Some((t, i));
                    }
                }
            }
        }
        best
    }

    /// Whether any light can be hit by a ray (an environment, a disc or a sphere).
    #[must_use]
    pub fn reachable(&self) -> bool {
        !self.at_infinity.is_empty() || !self.spheres.is_empty()
    }

    /// The lights that `ray` ends on, each with its radiance and its weight against the
    /// light technique, handed to `each(light, weight, radiance)`: `hit` is the sphere
    /// light it hit (then nothing at infinity is seen), `phase_pdf` the pdf by which the
    /// phase function chose the direction (`None` for a camera ray: weight 1, and only
    /// what camera rays see).
    pub fn arriving(
        &self,
        ray: &Ray,
        hit: Option<usize>,
        phase_pdf: Option<f64>,
        mis: MisHeuristic,
        mut each: impl FnMut(usize, f64, [f64; 3]),
    ) {
        let mut add = |i: usize, radiance: [f64; 3]| {
            let w =
                phase_pdf.map_or(1.0, |p| mis.weight(p, self.pdf(i, ray.origin, ray.direction)));
            each(i, w, radiance);
        };
        if let Some(i) = hit {
            if let Light::Sphere(s) = &self.lights[i] {
                add(i, s.radiance());
            }
            return;
        }
        for &i in &self.at_infinity {
            match &self.lights[i] {
                Light::Distant(d) => {
                    if let Some(r) = d.radiance(ray.direction) {
                        add(i, r);
                    }
                }
                Light::Environment(e) if phase_pdf.is_some() || e.visible() => {
                    add(i, e.radiance(ray.direction))
                }
                _ => {}
            }
        }
    }
}

/// Irradiance colour from a colour or a temperature: `kelvin` gives the blackbody
/// chromaticity at luminance 1 (`color::blackbody`), times `scale`.
#[must_use]
pub fn tinted(color: Option<[f32; 3]>, kelvin: Option<f32>, scale: f64) -> Rgb {
    let c = match (color, kelvin) {
        (_, Some(t)) => plume_core::color::blackbody::blackbody_table().chromaticity(t),
        (Some(c), None) => Rgb(c),
        (None, None) => Rgb::ONE,
    };
    Rgb(c.0.map(|v| (f64::from(v) * scale) as f32))
}
