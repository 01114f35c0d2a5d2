//! The one seeds grammar of every command (and of `models/train`).
//!
//! A comma-separated list of items, each a seed `a`, a range `a..b` (end exclusive) or
//! `a..=b` (end inclusive): `12345..12355`, `0..100,105`, `7,3,9..=11`. Seeds keep the
//! order given; an empty range, a seed listed twice, or more than [`MAX_SEEDS`] seeds is an
//! error.

use crate::ExperimentError;

/// The most seeds one list may name.
pub const MAX_SEEDS: usize = 1_000_000;

/// Parses a seed list (see the [module](self) docs).
///
/// ```
/// use deepcontact_experiments::seeds::parse_seeds;
/// assert_eq!(parse_seeds("3..5,9,10..=11").unwrap(), vec![3, 4, 9, 10, 11]);
/// assert!(parse_seeds("5..5").is_err());
/// assert!(parse_seeds("1,1").is_err());
/// ```
pub fn parse_seeds(text: &str) -> Result<Vec<u64>, ExperimentError> {
    let bad = |why: String| ExperimentError::Invalid(format!("seeds `{text}`: {why}"));
    let num = |s: &str| {
        s.trim()
            .parse::<u64>()
            .map_err(|e| bad(format!("`{}`: {e}", s.trim())))
    };
    let mut seeds = Vec::new();
    for item in text.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let past = |b: u64| {
            b.checked_add(1)
                .ok_or_else(|| bad(format!("`{item}` ends too high")))
        };
        let (a, b) = if let Some((a, b)) = item.split_once("..=") {
            (num(a)?, past(num(b)?)?)
        } else if let Some((a, b)) = item.split_once("..") {
            (num(a)?, num(b)?)
        } else {
            let a = num(item)?;
            (a, past(a)?)
        };
        if b <= a {
            return Err(bad(format!("`{item}` is an empty range")));
        }
        if (b - a) as usize > MAX_SEEDS - seeds.len().min(MAX_SEEDS) {
            return Err(bad(format!("more than {MAX_SEEDS} seeds")));
        }
        seeds.extend(a..b);
    }
    if seeds.is_empty() {
        return Err(bad("no seed".into()));
    }
    let mut sorted = seeds.clone();
    sorted.sort_unstable();
    if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
        return Err(bad(format!("seed {} is listed twice", w[0])));
    }
    Ok(seeds)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_lists_and_errors() {
        assert_eq!(
            parse_seeds("12345..12348").unwrap(),
            vec![12345, 12346, 12347]
        );
        assert_eq!(parse_seeds("0..=2").unwrap(), vec![0, 1, 2]);
        assert_eq!(parse_seeds(" 7, 3 ,").unwrap(), vec![7, 3]);
        assert_eq!(parse_seeds("0..3,7").unwrap(), vec![0, 1, 2, 7]);
        for bad in [
            "",
            "x",
            "3..3",
            "0..3,2",
            "1..x",
            "0..2000000",
            &format!("{}..=", u64::MAX),
        ] {
            assert!(parse_seeds(bad).is_err(), "{bad}");
        }
        assert!(parse_seeds(&format!("{0}..={0}", u64::MAX)).is_err());
    }
}
