//! The lights of a description (`[lights]`, [`LightSettings`]) turned into the lights the
//! integrator samples ([`ExternalLights`]): the one conversion, which also reads the
//! environment map and tabulates the sky.

use glam::DVec3;

use plume_core::color::Rgb;
use plume_core::error::Result;
use plume_scene::LightSettings;

use super::environment::world_to_map;
use super::{tinted, Distant, Environment, ExternalLights, Light, Radiance, Sphere};

/// Size of the lat-long table the sky is sampled from (0.35° per pixel).
pub const SKY_MAP_SIZE: (u32, u32) = (1024, 512);

/// The lights, for a scene whose up axis is `up` and whose volume has bounding-sphere
/// radius `radius`; `None` without lights (the integrator then does exactly what it
/// did before lights existed). Reads the environment map.
///
/// # Errors
/// As [`LightSettings::validate`]; a missing, unreadable or not lat-long map.
pub fn build(settings: &LightSettings, up: DVec3, radius: f64) -> Result<Option<ExternalLights>> {
    settings.validate()?;
    let up = up.normalize();
    let mut lights = Vec::new();
    let mut groups: Vec<String> = Vec::new();
    let entry = settings.entry_groups();
    if let Some(env) = settings.environment {
        let c = Rgb([env.x as f32, env.y as f32, env.z as f32]);
        lights.push(Light::Environment(Environment::new(
            Radiance::Constant(c),
            1.0,
            up,
            0.0,
            true,
        )));
        groups.extend(entry.environment.clone());
    }
    if let Some(m) = &settings.environment_map {
        let map = crate::light::envmap::EnvironmentMap::load(&m.file)?;
        lights.push(Light::Environment(Environment::new(
            Radiance::Map(Box::new(map)),
            m.intensity,
            up,
            m.rotation.to_radians(),
            m.visible,
        )));
        groups.extend(entry.environment_map.clone());
    }
    if let Some(s) = &settings.sky {
        let sky = crate::light::sky::Sky::new(&s.params())?;
        let (w, h) = SKY_MAP_SIZE;
        let map = crate::light::envmap::EnvironmentMap::from_pixels(
            w,
            h,
            sky.image(w, h, false),
            "the sky",
        )?;
        lights.push(Light::Environment(Environment::new(
            Radiance::Map(Box::new(map)),
            s.intensity,
            up,
            0.0,
            s.visible,
        )));
        groups.extend(entry.sky.clone());
        if s.sun {
            let sun = sky.sun_radiance();
            if !sun.is_black() {
                // The sun's direction in the world: the sky's frame is the maps' frame
                let to_sun = world_to_map(up, 0.0).transpose() * sky.sun_direction();
                let alpha = 0.5 * crate::light::sky::Sky::SUN_ANGULAR_DIAMETER.to_radians();
                let e = std::f64::consts::PI * alpha.sin().powi(2) * s.intensity;
                let irradiance = Rgb(sun.0.map(|c| (f64::from(c) * e) as f32));
                lights.push(Light::Distant(Distant::new(-to_sun, irradiance, 2.0 * alpha)));
                groups.extend(entry.sky.clone());
            }
        }
    }
    for d in &settings.distant {
        lights.push(Light::Distant(Distant::new(
            d.direction.normalize(),
            tinted(d.color, d.kelvin, d.irradiance()),
            d.angle.to_radians(),
        )));
    }
    groups.extend(entry.distant);
    for s in &settings.sphere {
        lights.push(Light::Sphere(Sphere::new(
            s.position,
            s.radius,
            tinted(s.color, s.kelvin, s.power()),
        )));
    }
    groups.extend(entry.sphere);
    let mut set = ExternalLights::new(lights, radius);
    if let Some(set) = &mut set {
        set.set_groups(&groups);
    }
    Ok(set)
}
