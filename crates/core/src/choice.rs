//! Closed sets of named values: the [`Choice`] trait and the [`choice!`](crate::choice!)
//! macro that gives an `enum` its names once, for `FromStr`, `Display`, serde and the
//! command line's list of possible values with their help.

/// A closed set of named values.
pub trait Choice: Copy + PartialEq + Sized + 'static {
    /// Every value: its name (kebab-case), the value and a one-line help text.
    const CHOICES: &'static [(&'static str, Self, &'static str)];

    /// The value's name.
    #[must_use]
    fn name(self) -> &'static str {
        Self::CHOICES.iter().find(|c| c.1 == self).map_or("?", |c| c.0)
    }

    /// The value called `name`.
    ///
    /// # Errors
    /// A message listing the names when `name` is none of them.
    fn from_name(name: &str) -> Result<Self, String> {
        Self::CHOICES.iter().find(|c| c.0 == name).map(|c| c.1).ok_or_else(|| {
            let names: Vec<&str> = Self::CHOICES.iter().map(|c| c.0).collect();
            format!("{name:?} is not one of {}", names.join(", "))
        })
    }
}

/// `Choice`, `FromStr`, `Display` and serde (as the name) for an enum.
#[macro_export]
macro_rules! choice {
    ($t:ty { $($name:literal => $v:expr, $help:literal;)* }) => {
        impl $crate::choice::Choice for $t {
            const CHOICES: &'static [(&'static str, Self, &'static str)] = &[$(($name, $v, $help)),*];
        }
        impl std::str::FromStr for $t {
            type Err = String;
            fn from_str(s: &str) -> Result<Self, String> {
                <$t as $crate::choice::Choice>::from_name(s)
            }
        }
        impl std::fmt::Display for $t {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str($crate::choice::Choice::name(*self))
            }
        }
        impl serde::Serialize for $t {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_str($crate::choice::Choice::name(*self))
            }
        }
        impl<'de> serde::Deserialize<'de> for $t {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                let s = <std::borrow::Cow<'de, str> as serde::Deserialize>::deserialize(d)?;
                <$t as $crate::choice::Choice>::from_name(&s).map_err(serde::de::Error::custom)
            }
        }
    };
}

choice!(crate::sampling::SamplerKind {
    "sobol" => crate::sampling::SamplerKind::Sobol, "Owen-scrambled Sobol points (Burley 2020), padded per path segment: lower error at equal spp";
    "random" => crate::sampling::SamplerKind::Random, "Independent hashed random numbers (SplitMix64), kept to reproduce the sampler comparison";
});
