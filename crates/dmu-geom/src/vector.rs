//! Vectors entering from outside (files, flags, scripts, other participants):
//! one check that they are finite and in range, and one normaliser that works
//! for any finite length.

use glam::DVec3;

/// The unit vector along `v`, for any finite non-zero `v`: it is scaled by
/// its largest component first, so lengths from the smallest subnormal to
/// `f64::MAX` normalise (`v.length()` overflows to infinity past about
/// 1.3e154 and underflows to zero below about 1e-162, where glam's
/// `normalize` gives zero or NaN). `None` when `v` is zero or not finite.
pub fn unit_vector(v: DVec3) -> Option<DVec3> {
    if !v.is_finite() {
        return None;
    }
    let largest = v.abs().max_element();
    if largest == 0.0 {
        return None;
    }
    // In [1, sqrt(3)] after the division: its length neither overflows nor
    // underflows.
    Some((v / largest).normalize())
}

/// Whether every component of `v` is finite and within `±limit`.
pub fn is_within(v: DVec3, limit: f64) -> bool {
    v.is_finite() && v.abs().max_element() <= limit
}
