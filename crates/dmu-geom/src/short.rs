//! Numbers in messages: at most six significant digits, so an error about
//! `1e300` says `1e300`, not a 301-digit integer.

use std::fmt;

use glam::DVec3;

/// A number or vector shown with at most six significant digits: plainly
/// between 1e-4 and 1e6, in scientific notation outside, trailing zeros
/// dropped (`0.1`, `123457`, `1.5e300`, `[1, 2.5, -3e-7]`). For messages
/// only: it rounds.
#[derive(Clone, Copy, Debug)]
pub struct Short<T>(pub T);

fn write_short(f: &mut fmt::Formatter<'_>, x: f64) -> fmt::Result {
    if !x.is_finite() || x == 0.0 {
        return write!(f, "{x}");
    }
    let scientific = format!("{x:.5e}");
    let (mantissa, exponent) = scientific
        .split_once('e')
        .expect("`{:e}` always writes an exponent");
    let exponent: i32 = exponent.parse().expect("an integer exponent");
    if (-4..6).contains(&exponent) {
        // Six significant digits: `5 - exponent` after the point.
        let decimals = (5 - exponent) as usize;
        let plain = format!("{x:.decimals$}");
        let plain = if plain.contains('.') {
            plain.trim_end_matches('0').trim_end_matches('.')
        } else {
            &plain
        };
        f.write_str(plain)
    } else {
        let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
        write!(f, "{mantissa}e{exponent}")
    }
}

impl fmt::Display for Short<f64> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_short(f, self.0)
    }
}

impl fmt::Display for Short<f32> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write_short(f, f64::from(self.0))
    }
}

impl fmt::Display for Short<DVec3> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        Short(self.0.to_array()).fmt(f)
    }
}

impl fmt::Display for Short<[f64; 3]> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        Short(&self.0[..]).fmt(f)
    }
}

impl fmt::Display for Short<&[f64]> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("[")?;
        for (i, x) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            write_short(f, *x)?;
        }
        f.write_str("]")
    }
}
