//! Parsing numbers people type: `10M`, `2.5k`, `1e6`; vectors as `x,y,z`.

use anyhow::{Context as _, bail};

/// A count with an optional k/M/G suffix (powers of 1000).
pub fn parse_count(s: &str) -> anyhow::Result<u64> {
    let t = s.trim();
    let (num, mult) = match t.char_indices().last() {
        Some((i, 'k' | 'K')) => (&t[..i], 1e3),
        Some((i, 'm' | 'M')) => (&t[..i], 1e6),
        Some((i, 'g' | 'G')) => (&t[..i], 1e9),
        _ => (t, 1.0),
    };
    let v: f64 = num
        .parse()
        .with_context(|| format!("{s:?} is not a count (e.g. 500k, 10M, 2000000)"))?;
    let v = v * mult;
    if !(0.0..1e15).contains(&v) {
        bail!("{s:?} is out of range");
    }
    Ok(v.round() as u64)
}

/// `x,y,z` as f64.
pub fn parse_dvec3(s: &str) -> anyhow::Result<glam::DVec3> {
    let parts: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("{s:?} is not x,y,z"))?;
    match parts.as_slice() {
        [x, y, z] if parts.iter().all(|v| v.is_finite()) => Ok(glam::DVec3::new(*x, *y, *z)),
        _ => bail!("{s:?} is not three finite numbers x,y,z"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_with_suffixes() {
        assert_eq!(parse_count("10M").unwrap(), 10_000_000);
        assert_eq!(parse_count("2.5k").unwrap(), 2_500);
        assert_eq!(parse_count("1e6").unwrap(), 1_000_000);
        assert_eq!(parse_count("500").unwrap(), 500);
        assert!(parse_count("ten").is_err());
        assert!(parse_count("-5").is_err());
        assert!(parse_count("1e300").is_err());
    }

    #[test]
    fn vectors() {
        assert_eq!(
            parse_dvec3("1, 2.5,-3").unwrap(),
            glam::DVec3::new(1.0, 2.5, -3.0)
        );
        assert!(parse_dvec3("1,2").is_err());
        assert!(parse_dvec3("1,2,NaN").is_err());
    }
}
