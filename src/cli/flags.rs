//! Value parsers shared by the commands: `x,y,z` vectors, byte sizes, and the library's
//! named choices ([`Choice`]) with their help texts.

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use glam::DVec3;
use plume_scene::Choice;

/// A value parser for a library [`Choice`]: its names as possible values, with help.
pub fn choice<T: Choice + Clone + Send + Sync>() -> impl TypedValueParser<Value = T> {
    PossibleValuesParser::new(
        T::CHOICES.iter().map(|&(name, _, help)| PossibleValue::new(name).help(help)),
    )
    .map(|s| T::from_name(&s).expect("invariant: clap checked the possible values"))
}

/// Parse `x,y,z`.
///
/// # Errors
/// A message for clap when the text is not three finite numbers.
pub fn parse_vec3(s: &str) -> Result<DVec3, String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        return Err(format!("expected x,y,z, got {s:?}"));
    }
    let mut v = [0.0; 3];
    for (d, p) in v.iter_mut().zip(&parts) {
        *d = p.parse::<f64>().map_err(|_| format!("{p:?} is not a number"))?;
        if !d.is_finite() {
            return Err(format!("{p:?} is not finite"));
        }
    }
    Ok(DVec3::from_array(v))
}

/// Parse a 4×4 matrix: sixteen numbers, row by row.
///
/// # Errors
/// A message for clap when the text is not sixteen numbers.
pub fn parse_matrix(s: &str) -> Result<[[f64; 4]; 4], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    if parts.len() != 16 {
        return Err(format!("expected 16 numbers, row by row, got {}", parts.len()));
    }
    let mut m = [[0.0; 4]; 4];
    for (k, p) in parts.iter().enumerate() {
        m[k / 4][k % 4] = p.parse::<f64>().map_err(|_| format!("{p:?} is not a number"))?;
    }
    Ok(m)
}

/// Parse a light's keys as written in a scene file's table, comma-separated (a TOML
/// inline table's body): `direction = [0, 0, -1], irradiance = 3`. Empty: all defaults.
///
/// # Errors
/// A one-line message for clap naming the key that does not parse or is unknown.
pub fn parse_keys<T: serde::de::DeserializeOwned>(s: &str) -> Result<T, String> {
    parse_keys_like(s, "direction = [0, 0, -1], irradiance = 3")
}

/// Parse a volume's keys as written in a `[[volumes]]` entry, comma-separated:
/// `file = "smoke.vdb", translate = [1, 0, 0], medium = { g = 0.3 }`.
///
/// # Errors
/// As [`parse_keys`].
pub fn parse_volume_keys(s: &str) -> Result<plume_scene::VolumeEntryKeys, String> {
    parse_keys_like(s, r#"file = "smoke.vdb", translate = [1, 0, 0], medium = { g = 0.3 }"#)
}

/// [`parse_keys`], its message ending with `example`.
fn parse_keys_like<T: serde::de::DeserializeOwned>(s: &str, example: &str) -> Result<T, String> {
    #[derive(serde::Deserialize)]
    struct Wrapper<T> {
        v: T,
    }
    toml::from_str::<Wrapper<T>>(&format!("v = {{ {s} }}")).map(|w| w.v).map_err(|e| {
        let message = e.message().trim().lines().map(str::trim).collect::<Vec<_>>().join("; ");
        format!("{message} (expected keys like `{example}`)")
    })
}

/// Parse an environment map: a file, or its keys (`file = "sky.exr", intensity = 2`).
///
/// # Errors
/// As [`parse_keys`].
pub fn parse_environment_map(s: &str) -> Result<plume_scene::EnvironmentMapSettings, String> {
    if s.contains('=') {
        parse_keys(s)
    } else {
        Ok(plume_scene::EnvironmentMapSettings {
            file: s.into(),
            intensity: 1.0,
            rotation: 0.0,
            visible: true,
            group: None,
        })
    }
}

/// Parse `a,b` (two finite numbers).
///
/// # Errors
/// A message for clap when the text is not two finite numbers.
pub fn parse_pair(s: &str) -> Result<[f64; 2], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let [a, b] = parts.as_slice() else { return Err(format!("expected OPEN,CLOSE, got {s:?}")) };
    let num = |p: &str| {
        p.parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("{p:?} is not a finite number"))
    };
    Ok([num(a)?, num(b)?])
}

/// Parse a byte size (`512MiB`, `8GiB`).
///
/// # Errors
/// A message for clap on a malformed size.
pub fn parse_size(s: &str) -> Result<plume_scene::ByteSize, String> {
    s.parse()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_vectors() {
        assert_eq!(parse_vec3("1, -2,3.5").unwrap(), DVec3::new(1.0, -2.0, 3.5));
        assert!(parse_vec3("1,2").is_err());
        assert!(parse_vec3("1,2,nan").is_err());
        assert_eq!(parse_size("512MiB").unwrap().0, 512 << 20);
    }
}
