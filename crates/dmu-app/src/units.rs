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

pub use dmu_scene::limits::{
    MAX_CHUNK_TRIANGLES, MAX_LENGTH, MAX_STEPS, MAX_TRIANGLES, MIN_PLANT_TRIANGLES,
};

/// A clap value parser for a count ([`parse_count`]: `10M`, `2.5k`) in
/// `min..=max`, saying the range when refused.
pub fn count_in(
    min: u64,
    max: u64,
) -> impl Fn(&str) -> anyhow::Result<u64> + Clone + Send + Sync + 'static {
    move |s| {
        let v = parse_count(s)?;
        if !(min..=max).contains(&v) {
            bail!("{s:?} is out of range: give {min} to {max}");
        }
        Ok(v)
    }
}

/// A clap value parser for a finite number in `min..=max`.
pub fn number_in(
    min: f64,
    max: f64,
) -> impl Fn(&str) -> anyhow::Result<f64> + Clone + Send + Sync + 'static {
    move |s| {
        let v: f64 = s
            .trim()
            .parse()
            .with_context(|| format!("{s:?} is not a number"))?;
        if !(v.is_finite() && (min..=max).contains(&v)) {
            bail!(
                "{s:?} is out of range: give a number from {} to {}",
                dmu_geom::Short(min),
                dmu_geom::Short(max)
            );
        }
        Ok(v)
    }
}

/// A clap value parser for an output file whose extension is `ext` (any case):
/// the extension names the format written, so `-o model.glb` on a command that
/// writes PNG is refused instead of replacing a model with an image.
pub fn output_with(
    ext: &'static str,
) -> impl Fn(&str) -> anyhow::Result<std::path::PathBuf> + Clone + Send + Sync + 'static {
    move |s| {
        let path = std::path::PathBuf::from(s);
        if !path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case(ext))
        {
            bail!("{s:?}: this command writes .{ext} files; give a name ending in .{ext}");
        }
        Ok(path)
    }
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

    proptest::proptest! {
        /// Whatever is typed, the parsers answer (never panic), and what they
        /// accept is within the range they were given.
        #[test]
        fn typed_values_are_parsed_or_refused_never_out_of_range(s in "\\PC{0,24}", n in proptest::num::f64::ANY) {
            if let Ok(v) = count_in(3, 5_000)(&s) {
                proptest::prop_assert!((3..=5_000).contains(&v));
            }
            if let Ok(v) = number_in(-1.0, 1e3)(&s) {
                proptest::prop_assert!(v.is_finite() && (-1.0..=1e3).contains(&v));
            }
            let typed = format!("{n}");
            match number_in(-1.0, 1e3)(&typed) {
                Ok(v) => proptest::prop_assert_eq!(v, n),
                Err(_) => proptest::prop_assert!(!(n.is_finite() && (-1.0..=1e3).contains(&n))),
            }
            let _ = (parse_count(&s), parse_bytes(&s), parse_dvec3(&s));
        }
    }

    #[test]
    fn bounded_counts_and_numbers() {
        let count = count_in(1, 1000);
        assert_eq!(count("1k").unwrap(), 1000);
        assert!(count("0").is_err());
        assert!(count("1001").is_err());
        let number = number_in(1e-6, 10.0);
        assert_eq!(number("2.5").unwrap(), 2.5);
        for bad in ["0", "-1", "10.5", "nan", "inf", "x"] {
            assert!(number(bad).is_err(), "{bad}");
        }
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

/// The length one model unit stands for, where a file has its own unit (BCF
/// is in metres): `--unit mm` for the plant and most CAD exports.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum LengthUnit {
    /// Millimetres.
    Mm,
    /// Centimetres.
    Cm,
    /// Metres (glTF's own unit).
    M,
    /// Inches.
    In,
    /// Feet.
    Ft,
}

impl LengthUnit {
    /// Model units in a metre.
    pub fn per_metre(self) -> f64 {
        match self {
            Self::Mm => 1000.0,
            Self::Cm => 100.0,
            Self::M => 1.0,
            Self::In => 1.0 / 0.0254,
            Self::Ft => 1.0 / 0.3048,
        }
    }

    /// `mm`, `cm`, `m`, `in` or `ft`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Mm => "mm",
            Self::Cm => "cm",
            Self::M => "m",
            Self::In => "in",
            Self::Ft => "ft",
        }
    }
}
