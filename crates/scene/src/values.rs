//! Values written as text on the command line and in scene files: byte sizes (`4GiB`),
//! tiles (`i/n`), crops (`x0,y0,x1,y1`), sample ranges (`a..b`) and debug pixels
//! (`x,y,s`, a [`crate::pixels::SampleId`]). Each parses and prints one syntax, both places.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

/// A number of bytes; in a scene file an integer or a size like `"512MiB"`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ByteSize(pub u64);

/// Parse a byte size: `1234`, `512MiB`, `8GiB`, `2GB`, `100K`.
///
/// # Errors
/// A message on a malformed size or one below a byte.
pub fn parse_bytes(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t.find(|c: char| !(c.is_ascii_digit() || c == '.')).unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let n: f64 = num.parse().map_err(|_| format!("{s:?} is not a size like 512MiB or 8GiB"))?;
    let mult: f64 = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kb" => 1e3,
        "kib" => 1024.0,
        "m" | "mb" => 1e6,
        "mib" => 1024.0 * 1024.0,
        "g" | "gb" => 1e9,
        "gib" => 1024.0 * 1024.0 * 1024.0,
        "t" | "tb" => 1e12,
        "tib" => 1024.0f64.powi(4),
        _ => {
            return Err(format!(
                "unknown unit in {s:?} (use B, KiB, MiB, GiB, TiB, KB, MB, GB, TB)"
            ))
        }
    };
    let v = n * mult;
    if !(v.is_finite() && v >= 1.0) {
        return Err(format!("{s:?} must be at least 1 byte"));
    }
    Ok(v as u64)
}

impl FromStr for ByteSize {
    type Err = String;
    fn from_str(s: &str) -> Result<ByteSize, String> {
        parse_bytes(s).map(ByteSize)
    }
}

impl Serialize for ByteSize {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        // Exact in any case; TOML integers stop at 2^63 − 1
        s.serialize_str(&self.0.to_string())
    }
}

impl<'de> Deserialize<'de> for ByteSize {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Int(u64),
            Text(String),
        }
        match Raw::deserialize(d)? {
            Raw::Int(0) => Err(serde::de::Error::custom("must be at least 1 byte")),
            Raw::Int(n) => Ok(ByteSize(n)),
            Raw::Text(s) => s.parse().map_err(serde::de::Error::custom),
        }
    }
}

/// Tile `index` of `count` (`i/n`, 0-based).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileIndex {
    /// Which tile, from 0.
    pub index: u32,
    /// How many tiles.
    pub count: u32,
}

impl FromStr for TileIndex {
    type Err = String;
    fn from_str(s: &str) -> Result<TileIndex, String> {
        crate::split::parse_tile(s).map(|(index, count)| TileIndex { index, count })
    }
}

impl fmt::Display for TileIndex {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// serde for an `Option<T>` written as `T`'s text (`FromStr` + `Display`).
pub(super) mod opt_text {
    use std::fmt::Display;
    use std::str::FromStr;

    use serde::{Deserialize, Deserializer, Serializer};

    pub(crate) fn serialize<T: Display, S: Serializer>(
        v: &Option<T>,
        s: S,
    ) -> Result<S::Ok, S::Error> {
        match v {
            Some(v) => s.collect_str(v),
            None => s.serialize_none(),
        }
    }

    pub(crate) fn deserialize<'de, T, D>(d: D) -> Result<Option<T>, D::Error>
    where
        T: FromStr,
        T::Err: Display,
        D: Deserializer<'de>,
    {
        let s = String::deserialize(d)?;
        s.parse().map(Some).map_err(serde::de::Error::custom)
    }
}

/// serde for an `Option<Range<u64>>` written as `a..b`.
pub(super) mod sample_range_text {
    use std::ops::Range;

    use serde::{Deserialize, Deserializer, Serializer};

    pub(crate) fn serialize<S: Serializer>(
        v: &Option<Range<u64>>,
        s: S,
    ) -> Result<S::Ok, S::Error> {
        match v {
            Some(r) => s.serialize_str(&crate::split::format_range(r)),
            None => s.serialize_none(),
        }
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(
        d: D,
    ) -> Result<Option<Range<u64>>, D::Error> {
        let s = String::deserialize(d)?;
        crate::split::parse_sample_range(&s).map(Some).map_err(serde::de::Error::custom)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_sizes_tiles_and_pixels() {
        assert_eq!(parse_bytes("512MiB").unwrap(), 512 << 20);
        assert_eq!(parse_bytes("8GiB").unwrap(), 8 << 30);
        assert_eq!(parse_bytes("2GB").unwrap(), 2_000_000_000);
        assert!(parse_bytes("12 parsecs").is_err());
        assert!(parse_bytes("0").is_err());
        assert_eq!("1/4".parse::<TileIndex>().unwrap(), TileIndex { index: 1, count: 4 });
        assert!("4/4".parse::<TileIndex>().is_err());
        let d: crate::pixels::SampleId = "3, 4,5".parse().unwrap();
        assert_eq!((d.x, d.y, d.sample), (3, 4, 5));
        assert_eq!(d.to_string(), "3,4,5");
        assert!("1,2".parse::<crate::pixels::SampleId>().is_err());
    }
}
