//! `spatial_runs` against brute force: a partition of the items into runs
//! within the bounds it promises, and on a line, runs that are intervals.

use dmu_scene::spatial_runs;
use glam::Vec3;
use proptest::prelude::*;

fn items(points: &[(f32, f32, f32)]) -> Vec<(u32, Vec3)> {
    (0..)
        .zip(points)
        .map(|(k, &(x, y, z))| (k, Vec3::new(x, y, z)))
        .collect()
}

proptest! {
    /// The runs cover the items in order with no gap, each item once; none
    /// holds more than `max`; past `max` items each holds at least half of
    /// it (rounded up), so there are at most `n / max.div_ceil(2)`.
    #[test]
    fn runs_partition_the_items_within_their_bounds(
        points in prop::collection::vec((-1e3f32..1e3, -1e3f32..1e3, -1e3f32..1e3), 0..600),
        max in 1usize..200,
    ) {
        let mut items = items(&points);
        let runs = spatial_runs(&mut items, max);
        let mut next = 0;
        for run in &runs {
            prop_assert_eq!(run.start, next);
            prop_assert!(!run.is_empty() && run.len() <= max);
            if points.len() > max {
                prop_assert!(run.len() >= max.div_ceil(2));
            }
            next = run.end;
        }
        prop_assert_eq!(next, points.len());
        if points.len() > max {
            prop_assert!(runs.len() <= points.len() / max.div_ceil(2));
        }
        let mut ids: Vec<u32> = items.iter().map(|&(k, _)| k).collect();
        ids.sort_unstable();
        prop_assert!(ids.iter().copied().eq(0..points.len() as u32));
        for &(k, p) in &items {
            let (x, y, z) = points[k as usize];
            prop_assert_eq!(p, Vec3::new(x, y, z));
        }
    }

    /// Points along a line, all distinct: median splits cut it into
    /// intervals, so the runs, in order, are the sorted points in order.
    #[test]
    fn runs_of_points_on_a_line_are_intervals(
        xs in prop::collection::btree_set(-100_000i32..100_000, 1..400),
        max in 1usize..64,
        shuffle in any::<u64>(),
    ) {
        let mut xs: Vec<i32> = xs.into_iter().collect();
        let sorted = xs.clone();
        // A deterministic shuffle, so the input order says nothing.
        let mut state = shuffle | 1;
        for i in (1..xs.len()).rev() {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            xs.swap(i, (state % (i as u64 + 1)) as usize);
        }
        let points: Vec<(f32, f32, f32)> = xs.iter().map(|&x| (x as f32, 2.0 * x as f32, -(x as f32))).collect();
        let mut items = items(&points);
        let runs = spatial_runs(&mut items, max);
        let mut in_order = Vec::with_capacity(xs.len());
        for run in runs {
            let mut run: Vec<i32> = items[run].iter().map(|&(k, _)| xs[k as usize]).collect();
            run.sort_unstable();
            in_order.extend(run);
        }
        prop_assert_eq!(in_order, sorted);
    }
}
