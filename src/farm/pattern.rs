//! File name patterns with a frame number: `explosion.####.vdb` (Nuke, OpenCue, Deadline),
//! `explosion.%04d.vdb` (printf, FFmpeg) and `explosion.$F4.vdb` (Houdini).
//!
//! Each token is replaced by the frame number zero-padded to the token's width: `#`
//! counts one digit per `#`, `%0Nd` and `$FN` pad to N, `%d` and `$F` do not pad. A number
//! wider than its padding is printed in full (frame 12345 in `####` is `12345`), and a
//! negative frame keeps its sign inside the width, as printf does (`-001` for −1 in
//! `%04d`). `%%` is a literal `%`; any other `%` or `$` is literal.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One piece of a pattern.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Piece {
    /// Text copied as is.
    Literal(String),
    /// The frame number, zero-padded to this many characters.
    Frame {
        /// Minimum width.
        width: usize,
    },
}

/// A path with zero or more frame-number tokens.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FramePattern {
    pieces: Vec<Piece>,
    /// The original text, for messages and non-UTF-8 paths without tokens.
    original: PathBuf,
}

impl FramePattern {
    /// Parse `path`. A path that is not valid UTF-8 is taken literally.
    #[must_use]
    pub fn parse(path: &Path) -> FramePattern {
        let Some(text) = path.to_str() else {
            return FramePattern { pieces: Vec::new(), original: path.to_path_buf() };
        };
        let chars: Vec<char> = text.chars().collect();
        let mut pieces = Vec::new();
        let mut literal = String::new();
        let mut i = 0;
        let frame = |literal: &mut String, pieces: &mut Vec<Piece>, width: usize| {
            if !literal.is_empty() {
                pieces.push(Piece::Literal(std::mem::take(literal)));
            }
            pieces.push(Piece::Frame { width });
        };
        while i < chars.len() {
            let c = chars[i];
            let digits_from =
                |j: usize| chars[j..].iter().take_while(|d| d.is_ascii_digit()).count();
            match c {
                '#' => {
                    let n = chars[i..].iter().take_while(|&&d| d == '#').count();
                    frame(&mut literal, &mut pieces, n);
                    i += n;
                }
                '%' if chars.get(i + 1) == Some(&'%') => {
                    literal.push('%');
                    i += 2;
                }
                '%' => {
                    // %d or %0Nd
                    let zero = chars.get(i + 1) == Some(&'0');
                    let n = digits_from(i + 1 + usize::from(zero));
                    let end = i + 1 + usize::from(zero) + n;
                    let valid = chars.get(end) == Some(&'d') && (n == 0) != zero;
                    if valid {
                        let width = if n == 0 {
                            1
                        } else {
                            chars[i + 2..end].iter().collect::<String>().parse().unwrap_or(1)
                        };
                        frame(&mut literal, &mut pieces, width);
                        i = end + 1;
                    } else {
                        literal.push(c);
                        i += 1;
                    }
                }
                '$' if chars.get(i + 1) == Some(&'F')
                    && !chars.get(i + 2).is_some_and(|c| c.is_ascii_alphabetic() || *c == '_') =>
                {
                    let n = digits_from(i + 2);
                    let width = if n == 0 {
                        1
                    } else {
                        chars[i + 2..i + 2 + n].iter().collect::<String>().parse().unwrap_or(1)
                    };
                    frame(&mut literal, &mut pieces, width);
                    i += 2 + n;
                }
                _ => {
                    literal.push(c);
                    i += 1;
                }
            }
        }
        if !literal.is_empty() {
            pieces.push(Piece::Literal(literal));
        }
        FramePattern { pieces, original: path.to_path_buf() }
    }

    /// True when the pattern has a frame token.
    #[must_use]
    pub fn has_frame(&self) -> bool {
        self.pieces.iter().any(|p| matches!(p, Piece::Frame { .. }))
    }

    /// The path of `frame` (the path itself when there is no token).
    #[must_use]
    pub fn path(&self, frame: i64) -> PathBuf {
        if !self.has_frame() {
            return self.original.clone();
        }
        let mut s = String::new();
        for p in &self.pieces {
            match p {
                Piece::Literal(t) => s.push_str(t),
                Piece::Frame { width } => {
                    let _ = write!(s, "{frame:0width$}");
                }
            }
        }
        PathBuf::from(s)
    }

    /// The path of `frame`, or the pattern taken literally without a frame (a run
    /// without `--frames`).
    #[must_use]
    pub fn resolve(&self, frame: Option<i64>) -> PathBuf {
        frame.map_or_else(|| self.original.clone(), |f| self.path(f))
    }

    /// The pattern as given.
    #[must_use]
    pub fn as_path(&self) -> &Path {
        &self.original
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(s: &str, f: i64) -> String {
        FramePattern::parse(Path::new(s)).path(f).to_string_lossy().into_owned()
    }

    #[test]
    fn hashes_printf_and_houdini_tokens() {
        assert_eq!(p("explosion.####.vdb", 7), "explosion.0007.vdb");
        assert_eq!(p("explosion.%04d.vdb", 7), "explosion.0007.vdb");
        assert_eq!(p("explosion.$F4.vdb", 7), "explosion.0007.vdb");
        assert_eq!(p("explosion.$F.vdb", 7), "explosion.7.vdb");
        assert_eq!(p("explosion.%d.vdb", 7), "explosion.7.vdb");
        assert_eq!(p("e.#.vdb", 7), "e.7.vdb");
        assert_eq!(p("shot/####/e.####.vdb", 1001), "shot/1001/e.1001.vdb");
    }

    #[test]
    fn film_starts_at_1001_and_overflowing_padding_prints_the_full_number() {
        assert_eq!(p("e.####.exr", 1001), "e.1001.exr");
        assert_eq!(p("e.####.exr", 12345), "e.12345.exr");
        assert_eq!(p("e.%03d.exr", 1001), "e.1001.exr");
        assert_eq!(p("e.$F2.exr", 100), "e.100.exr");
        assert_eq!(p("e.####.exr", -1), "e.-001.exr");
    }

    #[test]
    fn literal_percent_and_dollar_stay() {
        let plain = FramePattern::parse(Path::new("100%_$HOME_$Fx.vdb"));
        assert!(!plain.has_frame());
        assert_eq!(plain.path(3), Path::new("100%_$HOME_$Fx.vdb"));
        assert_eq!(p("a%%b.%02d", 3), "a%b.03");
        assert_eq!(p("a.%4d.vdb", 3), "a.%4d.vdb", "space padding is not a frame token");
        assert!(FramePattern::parse(Path::new("a.#.vdb")).has_frame());
    }
}
