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

/// A byte size: `2GiB`, `256MiB`, `512KiB` (powers of 1024; `K`, `M`, `G`, `T`
/// alone too), `100MB`, `1.5GB` (powers of 1000), or a plain number of bytes.
pub fn parse_bytes(s: &str) -> anyhow::Result<u64> {
    let t = s.trim();
    let split = t.find(|c: char| c.is_ascii_alphabetic()).unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let mult: f64 = match unit.to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "k" | "kib" => 1024.0,
        "m" | "mib" => 1024.0 * 1024.0,
        "g" | "gib" => 1024.0 * 1024.0 * 1024.0,
        "t" | "tib" => 1024.0 * 1024.0 * 1024.0 * 1024.0,
        "kb" => 1e3,
        "mb" => 1e6,
        "gb" => 1e9,
        "tb" => 1e12,
        _ => bail!("{s:?}: unknown unit {unit:?} (use KiB, MiB, GiB, or kB, MB, GB)"),
    };
    let v: f64 = num
        .trim()
        .parse()
        .with_context(|| format!("{s:?} is not a size (e.g. 256MiB, 2GiB, 1.5GB)"))?;
    let v = v * mult;
    if !(0.0..1e18).contains(&v) {
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
    fn byte_sizes() {
        assert_eq!(parse_bytes("2GiB").unwrap(), 2 << 30);
        assert_eq!(parse_bytes("256MiB").unwrap(), 256 << 20);
        assert_eq!(parse_bytes("256m").unwrap(), 256 << 20);
        assert_eq!(parse_bytes("1.5GB").unwrap(), 1_500_000_000);
        assert_eq!(parse_bytes("100 MB").unwrap(), 100_000_000);
        assert_eq!(parse_bytes("4096").unwrap(), 4096);
        assert!(parse_bytes("2 parsecs").is_err());
        assert!(parse_bytes("-1GiB").is_err());
        assert!(parse_bytes("GiB").is_err());
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
