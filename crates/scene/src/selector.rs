//! [`GridSelector`]: which grid of a file to read, by name and occurrence.
//!
//! A file may hold several grids with the same name (Houdini writes them freely). The
//! selector `density` binds the first grid named `density` in file order, `density[1]` the
//! second, `density[2]` the third. This matches the `name[N]` strings OpenVDB's own
//! `io::File::readGrid` accepts for files written by OpenVDB, which numbers duplicates in
//! file order.
//!
//! Round trip: `selector.to_string().parse() == Ok(selector)` for every selector, including
//! odd names. The bare form is used only when it cannot be misread: an empty name, or a
//! name that itself ends in `[digits]`, always carries its occurrence (`[0]`, `a[1][0]`).

use std::fmt;
use std::str::FromStr;

use plume_core::error::Error;

/// Names one grid of a file: the `occurrence`-th (0-based, file order) grid called `name`.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct GridSelector {
    /// Grid name as stored in the file (may be empty).
    pub name: String,
    /// Which of the grids with that name, counting from 0 in file order.
    pub occurrence: usize,
}

impl GridSelector {
    /// The first grid called `name`.
    #[must_use]
    pub fn first(name: impl Into<String>) -> GridSelector {
        GridSelector { name: name.into(), occurrence: 0 }
    }
}

/// Splits `name[digits]` into `(name, digits)`.
fn split_occurrence(text: &str) -> Option<(&str, usize)> {
    let inner = text.strip_suffix(']')?;
    let open = inner.rfind('[')?;
    let digits = &inner[open + 1..];
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    Some((&inner[..open], digits.parse().ok()?))
}

impl FromStr for GridSelector {
    type Err = Error;

    /// Parses `name` or `name[N]`. A bracketed suffix that is not a decimal number is part
    /// of the name. `[N]` alone selects an unnamed grid.
    fn from_str(text: &str) -> Result<GridSelector, Error> {
        if text.is_empty() {
            return Err(Error::invalid("grid selector", "empty; expected NAME or NAME[N]"));
        }
        Ok(match split_occurrence(text) {
            Some((name, occurrence)) => GridSelector { name: name.to_string(), occurrence },
            None => GridSelector::first(text),
        })
    }
}

impl fmt::Display for GridSelector {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let bare_is_unambiguous = !self.name.is_empty() && split_occurrence(&self.name).is_none();
        if self.occurrence == 0 && bare_is_unambiguous {
            write!(f, "{}", self.name)
        } else {
            write!(f, "{}[{}]", self.name, self.occurrence)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> GridSelector {
        text.parse().expect("valid selector")
    }

    #[test]
    fn parses_plain_and_indexed_names() {
        assert_eq!(parse("density"), GridSelector::first("density"));
        assert_eq!(parse("density[1]"), GridSelector { name: "density".into(), occurrence: 1 });
        assert_eq!(parse("density[0]"), GridSelector::first("density"));
        assert_eq!(parse("[0]"), GridSelector::first(""));
        assert_eq!(parse("a[1][2]"), GridSelector { name: "a[1]".into(), occurrence: 2 });
    }

    #[test]
    fn non_numeric_brackets_belong_to_the_name() {
        assert_eq!(parse("density[x]"), GridSelector::first("density[x]"));
        assert_eq!(parse("density[]"), GridSelector::first("density[]"));
        assert_eq!(parse("density[-1]"), GridSelector::first("density[-1]"));
        assert_eq!(parse("vel]"), GridSelector::first("vel]"));
    }

    #[test]
    fn rejects_empty_and_overflowing_selectors() {
        assert!("".parse::<GridSelector>().is_err());
        // An occurrence that does not fit in usize is not a number we can honour: it
        // stays part of the name, and will simply not be found.
        let huge = parse("d[99999999999999999999999]");
        assert_eq!(huge.occurrence, 0);
    }

    #[test]
    fn display_round_trips() {
        for selector in [
            GridSelector::first("density"),
            GridSelector { name: "density".into(), occurrence: 2 },
            GridSelector::first(""),
            GridSelector::first("a[1]"),
            GridSelector { name: "a[1]".into(), occurrence: 3 },
            GridSelector::first("odd name [x]"),
        ] {
            let text = selector.to_string();
            assert_eq!(parse(&text), selector, "{text:?}");
        }
        assert_eq!(GridSelector::first("density").to_string(), "density");
        assert_eq!(
            GridSelector { name: "density".into(), occurrence: 1 }.to_string(),
            "density[1]"
        );
        assert_eq!(GridSelector::first("").to_string(), "[0]");
        assert_eq!(GridSelector::first("a[1]").to_string(), "a[1][0]");
    }
}
