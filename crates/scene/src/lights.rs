//! `[lights]`: lights besides the volume's own emission, as data, with their validation
//! (the engine turns them into the lights it samples: `plume_engine::light::external::settings`).
//!
//! ```toml
//! [lights]
//! environment = [0.1, 0.1, 0.1]        # constant radiance, W·m⁻²·sr⁻¹ per channel
//!
//! [lights.environment_map]             # a lat-long EXR (Cycles' equirectangular, +Z up)
//! file = "plate.exr"
//! intensity = 1.0                      # Cycles' Background Strength
//! rotation = 0.0                       # degrees about the up axis, counter-clockwise
//! visible = true                       # seen by camera rays
//!
//! [lights.sky]                         # Preetham et al. 1999 sky with its sun
//! elevation = 30.0                     # sun, degrees
//! azimuth = 0.0                        # sun, degrees from +x towards +y (+z up)
//! turbidity = 3.0
//!
//! [[lights.distant]]                   # a sun
//! direction = [0.0, 0.0, -1.0]         # the direction the light travels
//! irradiance = 3.0                     # W·m⁻² facing the light (Cycles' Sun Strength)
//! kelvin = 5800.0                      # or color = [r, g, b]
//! angle = 0.53                         # angular diameter, degrees
//!
//! [[lights.sphere]]                    # a sphere light; radius 0 is a point light
//! position = [0.0, 0.0, 3.0]
//! radius = 0.1
//! power = 1000.0                       # W (Cycles' Power, soft falloff off)
//! group = "key"                        # AOV layer (default: sun, sphere, environment, sky)
//! ```
//!
//! The up axis of maps and sky is the scene's (`camera.up_axis`).

use std::path::PathBuf;

use glam::DVec3;
use serde::{Deserialize, Serialize};

use plume_core::error::{Error, Result};

/// Lights besides the volume's own emission.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LightSettings {
    /// Constant environment radiance (r, g, b) seen by escaping paths.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub environment: Option<DVec3>,
    /// A lat-long environment map.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub environment_map: Option<EnvironmentMapSettings>,
    /// The built-in physical sky and its sun.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sky: Option<SkySettings>,
    /// Distant lights (suns).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub distant: Vec<DistantSettings>,
    /// Sphere and point lights.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub sphere: Vec<SphereSettings>,
}

/// A lat-long environment map (`[lights.environment_map]`, `--environment-map`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentMapSettings {
    /// The EXR.
    pub file: PathBuf,
    /// Radiance multiplier (Cycles' Background Strength).
    #[serde(default = "one")]
    pub intensity: f64,
    /// Degrees about the up axis, counter-clockwise seen from above.
    #[serde(default)]
    pub rotation: f64,
    /// Seen by camera rays.
    #[serde(default = "yes")]
    pub visible: bool,
    /// AOV light group (default `environment`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
}

/// The built-in sky (`[lights.sky]`, `--sky`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SkySettings {
    /// Sun elevation above the horizon, degrees.
    pub elevation: f64,
    /// Sun azimuth, degrees from +x towards +y (in the sky's frame, +z up).
    pub azimuth: f64,
    /// Atmospheric turbidity (Preetham's fitted range 1.7 … 10).
    pub turbidity: f64,
    /// Multiplies sky and sun.
    pub intensity: f64,
    /// Add the sun as a distant light of 0.53°.
    pub sun: bool,
    /// Seen by camera rays (the sky; the sun disc always is).
    pub visible: bool,
    /// AOV light group of sky and sun (default `sky`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
}

impl Default for SkySettings {
    fn default() -> Self {
        SkySettings {
            elevation: 30.0,
            azimuth: 0.0,
            turbidity: 3.0,
            intensity: 1.0,
            sun: true,
            visible: true,
            group: None,
        }
    }
}

/// A distant light (`[[lights.distant]]`, `--distant-light`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DistantSettings {
    /// The direction the light travels (from the light into the scene).
    pub direction: DVec3,
    /// Irradiance on a surface facing the light, W·m⁻² (Cycles' Sun Strength); default 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub irradiance: Option<f64>,
    /// Illuminance on a surface facing the light, lux (irradiance × 683).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub illuminance: Option<f64>,
    /// Colour, linear Rec.709 (default white).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub color: Option<[f32; 3]>,
    /// Colour of a blackbody at this temperature, luminance 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kelvin: Option<f32>,
    /// Angular diameter, degrees (the sun's 0.53 by default; 0: a delta light).
    #[serde(default = "sun_angle")]
    pub angle: f64,
    /// AOV light group (default `sun`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
}

/// A sphere or point light (`[[lights.sphere]]`, `--sphere-light`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereSettings {
    /// Centre, world.
    pub position: DVec3,
    /// Radius, world units (0: a point light).
    #[serde(default)]
    pub radius: f64,
    /// Emitted power, W (Cycles' Power); default 1000 unless `intensity` is given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub power: Option<f64>,
    /// Radiant intensity, W·sr⁻¹ (power / 4π).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub intensity: Option<f64>,
    /// Colour, linear Rec.709 (default white).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub color: Option<[f32; 3]>,
    /// Colour of a blackbody at this temperature, luminance 1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kelvin: Option<f32>,
    /// AOV light group (default `sphere`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
}

fn one() -> f64 {
    1.0
}
fn yes() -> bool {
    true
}
fn sun_angle() -> f64 {
    SUN_ANGULAR_DIAMETER
}

/// Photometric luminous efficacy of plume's luminance unit: lux = 683 × W·m⁻² (Y).
pub const LUMENS_PER_WATT: f64 = 683.0;

fn check(ok: bool, key: &str, message: impl FnOnce() -> String) -> Result<()> {
    if ok {
        Ok(())
    } else {
        Err(Error::invalid(key, message()))
    }
}

fn finite_nonneg(v: f64) -> bool {
    v.is_finite() && v >= 0.0
}

fn colour(key: &str, what: &str, color: Option<[f32; 3]>, kelvin: Option<f32>) -> Result<()> {
    if let Some(c) = color {
        check(c.iter().all(|v| v.is_finite() && *v >= 0.0), key, || {
            format!("{what}: color components must be finite and ≥ 0")
        })?;
        check(kelvin.is_none(), key, || format!("{what}: give color or kelvin, not both"))?;
    }
    if let Some(t) = kelvin {
        check(t.is_finite() && (800.0..=1.0e6).contains(&t), key, || {
            format!("{what}: kelvin {t} is not in [800, 1e6]")
        })?;
    }
    Ok(())
}

/// A light group's name: a layer name of the EXR, so letters, digits, `_` and `-`, and
/// not one of the fixed layers.
pub(crate) fn group_name(key: &str, group: Option<&String>) -> Result<()> {
    let Some(g) = group else { return Ok(()) };
    check(
        !g.is_empty() && g.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-'),
        key,
        || format!("group {g:?} must be letters, digits, '_' or '-' (it names an EXR layer)"),
    )?;
    check(!RESERVED.contains(&g.as_str()), key, || {
        format!("group {g:?} is the name of a fixed layer")
    })
}

impl DistantSettings {
    /// Irradiance (W·m⁻², luminance of the colour times this).
    #[must_use]
    pub fn irradiance(&self) -> f64 {
        self.irradiance.or(self.illuminance.map(|lx| lx / LUMENS_PER_WATT)).unwrap_or(1.0)
    }
}

impl SphereSettings {
    /// Power, W.
    #[must_use]
    pub fn power(&self) -> f64 {
        self.power.or(self.intensity.map(|i| 4.0 * std::f64::consts::PI * i)).unwrap_or(1000.0)
    }
}

impl LightSettings {
    /// Whether any light besides the volume is given.
    #[must_use]
    pub fn any(&self) -> bool {
        self.environment.is_some()
            || self.environment_map.is_some()
            || self.sky.is_some()
            || !self.distant.is_empty()
            || !self.sphere.is_empty()
    }

    /// The group of every light given, by where it is given (defaults: `environment`,
    /// `sky`, `sun`, `sphere`): the one place the defaults live.
    pub fn entry_groups(&self) -> EntryGroups {
        let name =
            |g: &Option<String>, default: &str| g.clone().unwrap_or_else(|| default.to_string());
        EntryGroups {
            environment: self.environment.map(|_| "environment".to_string()),
            environment_map: self.environment_map.as_ref().map(|m| name(&m.group, "environment")),
            sky: self.sky.as_ref().map(|s| name(&s.group, "sky")),
            distant: self.distant.iter().map(|d| name(&d.group, "sun")).collect(),
            sphere: self.sphere.iter().map(|s| name(&s.group, "sphere")).collect(),
        }
    }

    /// The light groups (AOV layers), in order of first appearance: what
    /// `ExternalLights::groups` of the built lights holds, known before loading.
    #[must_use]
    pub fn groups(&self) -> Vec<String> {
        let e = self.entry_groups();
        let all = e
            .environment
            .into_iter()
            .chain(e.environment_map)
            .chain(e.sky)
            .chain(e.distant)
            .chain(e.sphere);
        let mut groups: Vec<String> = Vec::new();
        for g in all {
            if !groups.contains(&g) {
                groups.push(g);
            }
        }
        groups
    }

    /// Check every value that needs no file.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the key (`lights.distant`) and which light.
    pub fn validate(&self) -> Result<()> {
        if let Some(env) = self.environment {
            check(env.is_finite() && env.min_element() >= 0.0, "lights.environment", || {
                "components must be finite and ≥ 0".into()
            })?;
        }
        if let Some(m) = &self.environment_map {
            let key = "lights.environment_map";
            check(!m.file.as_os_str().is_empty(), key, || "file: required".into())?;
            check(finite_nonneg(m.intensity), key, || {
                format!("intensity {} must be a finite number ≥ 0", m.intensity)
            })?;
            check(m.rotation.is_finite(), key, || {
                format!("rotation {} must be finite", m.rotation)
            })?;
            group_name(key, m.group.as_ref())?;
        }
        if let Some(s) = &self.sky {
            check(finite_nonneg(s.intensity), "lights.sky", || {
                format!("intensity {} must be a finite number ≥ 0", s.intensity)
            })?;
            s.params().validate()?;
            group_name("lights.sky", s.group.as_ref())?;
        }
        for (i, d) in self.distant.iter().enumerate() {
            let key = "lights.distant";
            let what = format!("distant light {}", i + 1);
            check(d.direction.is_finite() && d.direction.length() > 0.0, key, || {
                format!("{what}: direction {} must be finite and not zero", d.direction)
            })?;
            check(d.irradiance.is_none() || d.illuminance.is_none(), key, || {
                format!("{what}: give irradiance or illuminance, not both")
            })?;
            check(finite_nonneg(d.irradiance()), key, || {
                format!("{what}: irradiance {} must be a finite number ≥ 0", d.irradiance())
            })?;
            check(d.angle.is_finite() && (0.0..180.0).contains(&d.angle), key, || {
                format!("{what}: angle {} is not in [0, 180) degrees", d.angle)
            })?;
            colour(key, &what, d.color, d.kelvin)?;
            group_name(key, d.group.as_ref())?;
        }
        for (i, s) in self.sphere.iter().enumerate() {
            let key = "lights.sphere";
            let what = format!("sphere light {}", i + 1);
            check(s.position.is_finite(), key, || format!("{what}: position must be finite"))?;
            check(finite_nonneg(s.radius), key, || {
                format!("{what}: radius {} must be a finite number ≥ 0", s.radius)
            })?;
            check(s.power.is_none() || s.intensity.is_none(), key, || {
                format!("{what}: give power or intensity, not both")
            })?;
            check(finite_nonneg(s.power()), key, || {
                format!("{what}: power {} must be a finite number ≥ 0", s.power())
            })?;
            colour(key, &what, s.color, s.kelvin)?;
            group_name(key, s.group.as_ref())?;
        }
        Ok(())
    }
}

impl SkySettings {
    /// The sky model's parameters.
    #[must_use]
    pub fn params(&self) -> SkyParams {
        SkyParams { elevation: self.elevation, azimuth: self.azimuth, turbidity: self.turbidity }
    }
}

/// Angular diameter of the sun disc, degrees (the default `angle` of a distant light).
pub const SUN_ANGULAR_DIAMETER: f64 = 0.53;

/// Layers no light group may be named (the fixed ones, the beauty's, and `--denoise`'s
/// half sums and noisy beauty).
pub const RESERVED: [&str; 7] = ["emission", "scattered", "alpha", "depth", "sum", "half", "noisy"];

/// The AOV group of each light as given in `[lights]` (`LightSettings::entry_groups`).
pub struct EntryGroups {
    /// The constant environment's group.
    pub environment: Option<String>,
    /// The environment map's group.
    pub environment_map: Option<String>,
    /// The sky's (and its sun's) group.
    pub sky: Option<String>,
    /// Each distant light's group, in order.
    pub distant: Vec<String>,
    /// Each sphere light's group, in order.
    pub sphere: Vec<String>,
}

/// Turbidity range of Preetham's fit, [1.7, 10].
pub const TURBIDITY_RANGE: (f64, f64) = (1.7, 10.0);

/// Sky parameters. Angles in degrees.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SkyParams {
    /// Sun elevation above the horizon, degrees, in [−90, 90].
    pub elevation: f64,
    /// Sun azimuth, degrees, from +X towards +Y (any finite value).
    pub azimuth: f64,
    /// Atmospheric turbidity T, in [1.7, 10]: 2 very clear, 3 clear, 6 hazy.
    pub turbidity: f64,
}

impl Default for SkyParams {
    /// `plume synth sky`'s defaults: elevation 30°, azimuth 0°, turbidity 3.
    fn default() -> SkyParams {
        SkyParams { elevation: 30.0, azimuth: 0.0, turbidity: 3.0 }
    }
}

impl SkyParams {
    /// Check the parameters against the model's range.
    ///
    /// # Errors
    /// [`Error::InvalidArgument`] naming the key (`lights.sky.turbidity`, …).
    pub fn validate(&self) -> Result<()> {
        let (t_min, t_max) = TURBIDITY_RANGE;
        if !self.turbidity.is_finite() || !(t_min..=t_max).contains(&self.turbidity) {
            return Err(Error::invalid(
                "lights.sky.turbidity",
                format!(
                    "{} is outside [{t_min}, {t_max}], the range of Preetham's fit",
                    self.turbidity
                ),
            ));
        }
        if !self.elevation.is_finite() || !(-90.0..=90.0).contains(&self.elevation) {
            return Err(Error::invalid(
                "lights.sky.elevation",
                format!("{} degrees is outside [-90, 90]", self.elevation),
            ));
        }
        if !self.azimuth.is_finite() {
            return Err(Error::invalid(
                "lights.sky.azimuth",
                format!("{} is not a finite number of degrees", self.azimuth),
            ));
        }
        Ok(())
    }
}
