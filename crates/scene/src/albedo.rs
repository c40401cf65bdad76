//! A medium's albedo as the scene holds it: grey or a scattering colour.

use serde::{Deserialize, Serialize};

/// A medium's single-scattering albedo: grey (`albedo = 0.8`), or a scattering colour
/// (`albedo = [0.9, 0.6, 0.3]`), each channel in [0, 1]. Without an absorption colour
/// extinction stays grey: the colour is what scatters, the rest of each channel is
/// absorbed (Cycles' Principled Volume *Color* with a black *Absorption Color*). The same
/// type holds the absorption colour (`medium.absorption_color`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Albedo {
    /// The same in every channel.
    Grey(f32),
    /// Red, green, blue.
    Color([f32; 3]),
}

impl<'de> Deserialize<'de> for Albedo {
    /// A number or three; anything else is refused with what is expected.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Albedo, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Grey(f32),
            Color([f32; 3]),
        }
        match Raw::deserialize(d) {
            Ok(Raw::Grey(a)) => Ok(Albedo::Grey(a)),
            Ok(Raw::Color(c)) => Ok(Albedo::Color(c)),
            Err(_) => {
                Err(serde::de::Error::custom("expected a number or [r, g, b], each in [0, 1]"))
            }
        }
    }
}

impl Albedo {
    /// Per channel.
    #[must_use]
    pub fn rgb(self) -> [f32; 3] {
        match self {
            Albedo::Grey(a) => [a; 3],
            Albedo::Color(c) => c,
        }
    }

    /// The largest channel.
    #[must_use]
    pub fn max(self) -> f32 {
        let [r, g, b] = self.rgb();
        r.max(g).max(b)
    }
}

impl From<f32> for Albedo {
    fn from(a: f32) -> Albedo {
        Albedo::Grey(a)
    }
}

impl std::str::FromStr for Albedo {
    type Err = String;

    /// `0.8` or `0.9,0.6,0.3`.
    fn from_str(s: &str) -> std::result::Result<Albedo, String> {
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        let num =
            |t: &str| t.parse::<f32>().map_err(|_| format!("{s:?}: expected a number or r,g,b"));
        match parts.as_slice() {
            [a] => Ok(Albedo::Grey(num(a)?)),
            [r, g, b] => Ok(Albedo::Color([num(r)?, num(g)?, num(b)?])),
            _ => Err(format!("{s:?}: expected a number or r,g,b")),
        }
    }
}
