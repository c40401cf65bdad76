//! Frame lists: `--frames 1-100`, `1-100x2`, `1,5,10-20`, `1001-1100:4`.
//!
//! A list is comma-separated items; an item is a frame `N`, a range `A-B` (inclusive), or
//! a stepped range `A-BxS` / `A-B:S` (Nuke's and OpenJD's spellings; OpenJD's
//! `CHUNK[INT]` task parameters hand over exactly such text). Frames may be negative
//! (`-5--1`). Order is kept and repeats are dropped, so a chunk renders in the order the
//! farm gave.

/// More frames than this in one list is taken for a typo.
pub const MAX_FRAMES: usize = 1_000_000;

/// Parse a frame list.
///
/// # Errors
/// A message naming the bad item: not a number, end before start, step 0, too many frames.
pub fn parse_frames(s: &str) -> Result<Vec<i64>, String> {
    let mut frames = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for item in s.split(',').map(str::trim) {
        if item.is_empty() {
            return Err(format!("empty item in frame list {s:?}"));
        }
        let bad = |why: &str| {
            format!("{item:?} in {s:?}: {why} (use N, A-B, A-BxS or A-B:S, comma-separated)")
        };
        let (range, step) = match item.find(['x', ':']) {
            Some(k) => (&item[..k], Some(&item[k + 1..])),
            None => (item, None),
        };
        let (first, rest) = split_number(range).ok_or_else(|| bad("not a frame number"))?;
        let first: i64 = first.parse().map_err(|_| bad("not a frame number"))?;
        let last: i64 = match rest {
            "" => first,
            r => {
                let r = r.strip_prefix('-').ok_or_else(|| bad("not a frame number"))?;
                let (n, tail) = split_number(r).ok_or_else(|| bad("not a frame number"))?;
                if !tail.is_empty() {
                    return Err(bad("not a frame number"));
                }
                n.parse().map_err(|_| bad("not a frame number"))?
            }
        };
        let step: i64 = match step {
            None => 1,
            Some(t) => t.trim().parse().map_err(|_| bad("the step is not a positive integer"))?,
        };
        if step < 1 {
            return Err(bad("the step must be at least 1"));
        }
        if last < first {
            return Err(bad("the range ends before it starts"));
        }
        if rest.is_empty() && step != 1 {
            return Err(bad("a step needs a range"));
        }
        let count = (last - first) / step + 1;
        if count as u128 + frames.len() as u128 > MAX_FRAMES as u128 {
            return Err(bad(&format!("more than {MAX_FRAMES} frames")));
        }
        let mut f = first;
        while f <= last {
            if seen.insert(f) {
                frames.push(f);
            }
            match f.checked_add(step) {
                Some(n) => f = n,
                None => break,
            }
        }
    }
    Ok(frames)
}

/// Split a leading optionally negative integer from `s`: ("-12", "-20") from "-12--20".
fn split_number(s: &str) -> Option<(&str, &str)> {
    let sign = usize::from(s.starts_with('-'));
    let digits = s[sign..].bytes().take_while(u8::is_ascii_digit).count();
    (digits > 0).then(|| s.split_at(sign + digits))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_steps_and_lists() {
        assert_eq!(parse_frames("1-5").unwrap(), vec![1, 2, 3, 4, 5]);
        assert_eq!(parse_frames("1-10x3").unwrap(), vec![1, 4, 7, 10]);
        assert_eq!(parse_frames("1-10:4").unwrap(), vec![1, 5, 9]);
        assert_eq!(parse_frames("1,5,10-12").unwrap(), vec![1, 5, 10, 11, 12]);
        assert_eq!(parse_frames(" 7 ").unwrap(), vec![7]);
        assert_eq!(
            parse_frames("3,1,3,2-3").unwrap(),
            vec![3, 1, 2],
            "order kept, repeats dropped"
        );
    }

    #[test]
    fn film_style_starts_and_negative_frames() {
        let f = parse_frames("1001-1100").unwrap();
        assert_eq!((f.len(), f[0], f[99]), (100, 1001, 1100));
        assert_eq!(parse_frames("9998-10001").unwrap(), vec![9998, 9999, 10000, 10001]);
        assert_eq!(parse_frames("-2-1").unwrap(), vec![-2, -1, 0, 1]);
        assert_eq!(parse_frames("-5--4").unwrap(), vec![-5, -4]);
    }

    #[test]
    fn bad_lists_name_the_item() {
        for bad in
            ["", "1-", "a-3", "5-1", "1-10x0", "1-10x-2", "1,,2", "3x2", "1-2-3", "0-2000000"]
        {
            let e = parse_frames(bad).unwrap_err();
            assert!(
                e.contains("frame")
                    || e.contains("step")
                    || e.contains("range")
                    || e.contains("empty"),
                "{bad}: {e}"
            );
        }
        assert!(parse_frames("5-1").unwrap_err().contains("\"5-1\""));
    }
}
