//! Order statistics of measured figures (frame times, cell sizes).

/// The `q` quantile of `values` (`q` in `[0, 1]`): the element at rank
/// `round((n - 1) q)`, an element of the data, never an interpolation; NaN
/// when there are none. Reorders `values` (a selection, not a sort: O(n)).
/// Takes a `Vec` or a mutable slice.
pub fn percentile(mut values: impl AsMut<[f64]>, q: f64) -> f64 {
    let values = values.as_mut();
    if values.is_empty() {
        return f64::NAN;
    }
    let rank = ((values.len() - 1) as f64 * q).round() as usize;
    *values.select_nth_unstable_by(rank, f64::total_cmp).1
}

/// The median of `values`, as [`percentile`] at 0.5 (the upper middle of an
/// even count).
pub fn median(values: impl AsMut<[f64]>) -> f64 {
    percentile(values, 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against a sort: the rank rounds half up, and every quantile is data.
    #[test]
    fn quantiles_are_the_sorted_elements_at_their_rank() {
        let data = [5.0, -1.0, 3.0, 9.0, 0.5, 7.0, 3.0, 2.0];
        let mut sorted = data;
        sorted.sort_by(f64::total_cmp);
        for (q, rank) in [(0.0, 0), (0.5, 4), (0.9, 6), (0.95, 7), (1.0, 7)] {
            assert_eq!(percentile(data.to_vec(), q), sorted[rank], "q {q}");
        }
        assert_eq!(median(&mut [4.0, 1.0, 2.0][..]), 2.0);
        assert!(median(Vec::new()).is_nan());
    }
}
