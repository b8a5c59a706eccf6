//! The one normaliser and range check for vectors from outside, and numbers
//! in messages.

use dmu_geom::glam::DVec3;
use dmu_geom::{Plane, Short, is_within, unit_vector};
use proptest::prelude::*;

/// Issue 48: a section plane or BCF direction of `[1e300, 0, 0]` passed a
/// "squared length > 0" check (its square is infinite) and then panicked in
/// `Plane::from_point_normal`; `[1e-320, 0, 0]` normalised to NaN.
#[test]
fn issue_48_extreme_lengths_normalise() {
    for (v, expected) in [
        (DVec3::new(1e300, 0.0, 0.0), DVec3::X),
        (DVec3::new(0.0, -f64::MAX, 0.0), -DVec3::Y),
        (DVec3::new(0.0, 0.0, 1e-320), DVec3::Z),
        (
            DVec3::new(5e-324, 5e-324, 0.0),
            DVec3::new(1.0, 1.0, 0.0).normalize(),
        ),
        (DVec3::splat(f64::MAX), DVec3::ONE.normalize()),
    ] {
        let u = unit_vector(v).unwrap_or_else(|| panic!("{v} has a direction"));
        assert!(
            (u - expected).length() < 1e-15,
            "{v} -> {u}, not {expected}"
        );
    }
    let plane = Plane::from_point_normal(DVec3::new(1.0, 2.0, 3.0), DVec3::new(1e300, 0.0, 0.0));
    assert_eq!(plane.normal, DVec3::X);
    assert_eq!(plane.signed_distance(DVec3::new(4.0, 0.0, 0.0)), 3.0);
    for bad in [
        DVec3::ZERO,
        DVec3::new(f64::NAN, 1.0, 0.0),
        DVec3::new(f64::INFINITY, 0.0, 0.0),
    ] {
        assert_eq!(unit_vector(bad), None, "{bad}");
        assert_eq!(
            Plane::try_from_point_normal(DVec3::ZERO, bad),
            None,
            "{bad}"
        );
    }
    // A finite normal and point whose offset overflows is no plane either.
    assert_eq!(
        Plane::try_from_point_normal(
            DVec3::new(f64::MAX, f64::MAX, 0.0),
            DVec3::new(1.0, 1.0, 0.0)
        ),
        None
    );
}

proptest! {
    /// Any finite non-zero vector, of any scale, normalises to unit length
    /// along itself (the oracle: the same vector scaled into [1, 2) by an
    /// exact power of two, where glam's normalize is safe).
    #[test]
    fn unit_vector_is_unit_and_parallel_at_every_scale(
        x in -1.0f64..1.0, y in -1.0f64..1.0, z in -1.0f64..1.0, exponent in -1074i32..1023,
    ) {
        let base = DVec3::new(x, y, z);
        prop_assume!(base.abs().max_element() > 1e-3);
        let v = base * 2f64.powi(exponent / 2) * 2f64.powi(exponent - exponent / 2);
        prop_assume!(v.is_finite() && v != DVec3::ZERO);
        let u = unit_vector(v).unwrap();
        prop_assert!((u.length() - 1.0).abs() < 1e-12, "{v}: |{u}| != 1");
        // Subnormal scales lose low bits of the components: compare with the
        // vector as it was stored.
        let stored = v / v.abs().max_element();
        prop_assert!((u - stored.normalize()).length() < 1e-12);
    }
}

#[test]
fn is_within_checks_finite_and_range() {
    assert!(is_within(DVec3::splat(1e15), 1e15));
    assert!(!is_within(DVec3::new(0.0, -1.0000001e15, 0.0), 1e15));
    assert!(!is_within(DVec3::new(f64::NAN, 0.0, 0.0), 1e15));
    assert!(!is_within(
        DVec3::new(f64::INFINITY, 0.0, 0.0),
        f64::INFINITY
    ));
}

/// Issue 48: errors printed 300-digit numbers (Rust's `{}` for `1e300`).
#[test]
fn issue_48_numbers_in_messages_have_six_significant_digits() {
    for (x, shown) in [
        (1e300, "1e300"),
        (-2.5e-310, "-2.5e-310"),
        (123456.7, "123457"),
        (1234567.0, "1.23457e6"),
        (0.1, "0.1"),
        (0.000123, "0.000123"),
        (0.0000123, "1.23e-5"),
        (2.5, "2.5"),
        (0.0, "0"),
        (-7.0, "-7"),
        (f64::NAN, "NaN"),
        (f64::NEG_INFINITY, "-inf"),
        (999999.7, "1e6"),
    ] {
        assert_eq!(Short(x).to_string(), shown, "{x:e}");
    }
    assert_eq!(
        Short(DVec3::new(1e300, 0.5, -3e-7)).to_string(),
        "[1e300, 0.5, -3e-7]"
    );
    assert_eq!(Short(f64::MAX).to_string(), "1.79769e308");
}
