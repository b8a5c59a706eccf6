//! The residency manager against simple oracles: the budget is never passed
//! over random request streams, a pinned chunk is never evicted, loads follow
//! the priority order, and walks are deterministic and complete when memory
//! allows.

use std::sync::Arc;

use dmu_scene::ChunkId;
use dmu_store::{
    CameraFrame, Class, LoadOrder, Pacing, Request, Residency, ResidencyOptions, Store, Viewport,
    WalkOptions, WriteOptions, walk,
};
use glam::DVec3;
use proptest::prelude::*;

use crate::support::{small_plant, stored};

fn plant_store() -> (tempfile::TempDir, Arc<Store>) {
    let (dir, path) = stored(&small_plant(60_000), WriteOptions::default());
    (dir, Arc::new(Store::open(&path).unwrap()))
}

fn residency(store: &Arc<Store>, budget: u64, order: LoadOrder) -> Residency {
    Residency::new(
        Arc::clone(store),
        ResidencyOptions {
            budget_bytes: budget,
            loader_threads: 2,
            order,
            pacing: Pacing::Granted,
        },
    )
}

const CLASSES: [Class; 5] = [
    Class::Visible,
    Class::Recent,
    Class::InFrustum,
    Class::OutsideFrustum,
    Class::Subpixel,
];

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    /// Random frames of random requests with random grants, some chunks held
    /// (pinned) across a frame: the accounting stays exact, resident plus
    /// in-flight bytes never pass the budget, and a held chunk stays resident.
    #[test]
    fn budget_and_pins_hold_over_random_frames(
        budget_percent in 1u64..40,
        frames in prop::collection::vec(
            (prop::collection::vec((0usize..10_000, 0usize..5, 0f32..1e5), 0..60), 0u64..400_000),
            1..25,
        ),
    ) {
        let (_dir, store) = plant_store();
        let total = store.info().geometry_resident_bytes;
        let chunks = store.skeleton().chunks().len();
        let r = residency(&store, total * budget_percent / 100, LoadOrder::Visibility);
        let mut held = Vec::new();
        for (requests, grant) in frames {
            let requests: Vec<Request> = requests
                .into_iter()
                .map(|(c, k, area_px)| Request {
                    chunk: ChunkId::from_index(c % chunks),
                    class: CLASSES[k],
                    area_px,
                })
                .collect();
            r.request(&requests);
            r.load_granted(grant);
            prop_assert_eq!(r.validate(), Ok(()));
            for (c, _) in &held {
                prop_assert!(r.is_resident(*c), "held chunk {} was evicted", c);
            }
            held.clear();
            for q in requests.iter().take(3) {
                if let Some(g) = r.get(q.chunk) {
                    held.push((q.chunk, g));
                }
            }
        }
        prop_assert!(r.stats().peak_bytes <= r.budget_bytes());
        prop_assert_eq!(r.stats().failures, 0);
    }
}

/// With room for everything but a grant for one chunk at a time, chunks load
/// in the order's priority: by class then area (visibility), by area alone
/// (area), or as first requested (fifo).
#[test]
fn loads_follow_the_priority_order() {
    let (_dir, store) = plant_store();
    let chunks: Vec<ChunkId> = (0..10).map(ChunkId::from_index).collect();
    // Chunk i: class i % 5, area growing with i.
    let requests: Vec<Request> = chunks
        .iter()
        .enumerate()
        .map(|(i, &chunk)| Request {
            chunk,
            class: CLASSES[i % 5],
            area_px: i as f32 * 10.0,
        })
        .collect();
    let expected = |order: LoadOrder| -> Vec<usize> {
        match order {
            LoadOrder::Visibility => vec![5, 0, 6, 1, 7, 2, 8, 3, 9, 4],
            LoadOrder::Area => (0..10).rev().collect(),
            LoadOrder::Fifo => (0..10).collect(),
        }
    };
    for order in [LoadOrder::Visibility, LoadOrder::Area, LoadOrder::Fifo] {
        let r = Residency::new(
            Arc::clone(&store),
            ResidencyOptions {
                budget_bytes: u64::MAX,
                loader_threads: 1,
                order,
                pacing: Pacing::Granted,
            },
        );
        r.request(&requests);
        let mut loaded = Vec::new();
        for _ in 0..10 {
            // One byte more than the last load overdrew lets exactly one start.
            let debt = loaded
                .last()
                .map_or(0, |&i| store.chunk_file_bytes(chunks[i]) - 1);
            r.load_granted(debt + 1);
            let now: Vec<usize> = (0..10)
                .filter(|&i| r.is_resident(chunks[i]) && !loaded.contains(&i))
                .collect();
            assert_eq!(now.len(), 1, "{order:?}: one load per grant, got {now:?}");
            loaded.extend(now);
        }
        assert_eq!(loaded, expected(order), "{order:?}");
    }
}

/// Under a budget that holds two chunks, requesting a third evicts the least
/// recently used one that is not held.
#[test]
fn eviction_is_least_recently_used_and_spares_held_chunks() {
    let (_dir, store) = plant_store();
    let same_size: Vec<ChunkId> = {
        let first = store.chunk_resident_bytes(ChunkId(0));
        (0..store.skeleton().chunks().len())
            .map(ChunkId::from_index)
            .filter(|&c| store.chunk_resident_bytes(c) == first)
            .take(4)
            .collect()
    };
    assert_eq!(same_size.len(), 4, "the plant has chunks of equal size");
    let bytes = store.chunk_resident_bytes(same_size[0]);
    let r = residency(&store, 2 * bytes, LoadOrder::Visibility);
    let want = |c: ChunkId| Request {
        chunk: c,
        class: Class::Visible,
        area_px: 1.0,
    };
    let [a, b, c, d] = same_size[..] else {
        unreachable!()
    };
    r.request(&[want(a)]);
    r.load_granted(u64::MAX / 4);
    r.request(&[want(b)]);
    r.load_granted(u64::MAX / 4);
    assert!(r.is_resident(a) && r.is_resident(b));
    // a is older; c evicts it.
    assert_eq!(r.take_evicted(), []);
    r.request(&[want(c)]);
    r.load_granted(u64::MAX / 4);
    assert!(!r.is_resident(a) && r.is_resident(b) && r.is_resident(c));
    assert_eq!(r.take_evicted(), [a], "evictions are reported once");
    assert_eq!(r.take_evicted(), []);
    // Hold b (older than c): d must evict c instead.
    let pin = r.get(b).unwrap();
    r.request(&[want(d)]);
    r.load_granted(u64::MAX / 4);
    assert!(r.is_resident(b) && !r.is_resident(c) && r.is_resident(d));
    drop(pin);
    assert_eq!(r.validate(), Ok(()));
}

/// A straight walk down the plant, 200 frames.
fn path(store: &Store) -> Vec<CameraFrame> {
    let b = store.skeleton().world_bounds();
    let (lo, hi) = (b.min, b.max);
    let z = lo.z + 1_700.0;
    let y = (lo.y + hi.y) / 2.0;
    (0..200)
        .map(|i| {
            let x = lo.x + (hi.x - lo.x) * f64::from(i) / 200.0;
            CameraFrame {
                eye: DVec3::new(x, y, z),
                target: DVec3::new(x + 1_000.0, y + 300.0 * (f64::from(i) * 0.1).sin(), z),
                up: DVec3::Z,
                fov_y_deg: 60.0,
            }
        })
        .collect()
}

fn options(budget: u64, order: LoadOrder) -> WalkOptions {
    WalkOptions {
        order,
        budget_bytes: budget,
        loader_threads: 2,
        disk_bytes_per_frame: Some(4 << 20),
        frame_rate_hz: 60.0,
        viewport: Viewport {
            width: 640,
            height: 360,
        },
        min_pixels: 1.0,
        prefetch: None,
        warmup_frames: 10,
    }
}

#[test]
fn walks_are_deterministic_and_within_budget() {
    let (_dir, store) = plant_store();
    let tree = dmu_tree::Tree::build(store.skeleton(), Default::default());
    let frames = path(&store);
    let budget = store.info().geometry_resident_bytes / 10;
    for order in [LoadOrder::Visibility, LoadOrder::Area, LoadOrder::Fifo] {
        let a = walk(&store, &tree, &frames, &options(budget, order)).unwrap();
        let b = walk(&store, &tree, &frames, &options(budget, order)).unwrap();
        let first = a.frames.iter().zip(&b.frames).position(|(x, y)| x != y);
        assert!(
            first.is_none(),
            "{order:?}: frame {first:?} differs: {:?} vs {:?}",
            first.map(|i| &a.frames[i]),
            first.map(|i| &b.frames[i])
        );
        assert!(a.total.peak_resident_bytes <= budget);
        assert!(a.frames.iter().all(|f| f.resident_bytes <= budget));
        assert!(a.total.loads > 0);
    }
}

/// With memory for the whole model and ample bandwidth, a frame misses only
/// what came into view since the last frame; a view that stays still misses
/// nothing after its first frame.
#[test]
fn a_walk_with_room_for_everything_misses_only_new_chunks() {
    let (_dir, store) = plant_store();
    let tree = dmu_tree::Tree::build(store.skeleton(), Default::default());
    let mut still = path(&store)[100..101].to_vec();
    still.extend(std::iter::repeat_n(still[0], 9));
    let mut o = options(u64::MAX, LoadOrder::Visibility);
    o.disk_bytes_per_frame = Some(u64::MAX / 4);
    let report = walk(&store, &tree, &still, &o).unwrap();
    assert!(report.frames[0].missing_chunks == report.frames[0].wanted_chunks);
    assert!(report.frames[0].wanted_chunks > 0);
    assert!(report.frames[1..].iter().all(|f| f.missing_chunks == 0));
    let moving = walk(&store, &tree, &path(&store), &o).unwrap();
    assert!(moving.total.evictions == 0);
}

/// A renderer's occlusion culling (here: a fixed set, the three wanted
/// chunks of least area, which the frustum's priorities load last) decides
/// what is visible, under a budget of that set and a little more, while the
/// frustum wants more: what the first frame found visible is loaded before the second
/// (queued as soon as the frame reports it), and a chunk hidden for nine
/// frames, though culling keeps wanting bigger ones, is still resident when
/// it shows again (requested as recent, above what culling merely wants).
#[test]
fn found_visible_loads_at_once_and_stays_while_recent() {
    let (_dir, store) = plant_store();
    let tree = dmu_tree::Tree::build(store.skeleton(), Default::default());
    let still = vec![path(&store)[100]; 12];
    let mut o = options(u64::MAX, LoadOrder::Visibility);
    o.disk_bytes_per_frame = Some(u64::MAX / 4);
    // The wanted chunks, smallest on screen first.
    let mut wanted: Vec<(ChunkId, f32)> = Vec::new();
    dmu_store::walk_with(&store, &tree, &still[..1], &o, &mut |_, set, _| {
        wanted = set.drawn.clone();
        Ok(dmu_store::Drawn::default())
    })
    .unwrap();
    wanted.sort_by(|a, b| a.1.total_cmp(&b.1));
    let visible: Vec<ChunkId> = wanted.iter().take(3).map(|w| w.0).collect();
    let bytes = |cs: &mut dyn Iterator<Item = ChunkId>| -> u64 {
        cs.map(|c| store.chunk_resident_bytes(c)).sum()
    };
    // The hidden one: the least on screen. The budget leaves room for the
    // largest on screen (the head of culling's queue) only in its place.
    let hidden = visible[0];
    let head = wanted.last().unwrap().0;
    let size = |c: ChunkId| store.chunk_resident_bytes(c);
    o.budget_bytes = bytes(&mut visible.iter().copied()) + size(head).saturating_sub(size(hidden));
    let mut missing = Vec::new();
    dmu_store::walk_with(&store, &tree, &still, &o, &mut |i, _, residency| {
        let shown: Vec<ChunkId> = visible
            .iter()
            .copied()
            .filter(|&c| c != hidden || !(2..11).contains(&i))
            .collect();
        let absent: Vec<ChunkId> = shown
            .iter()
            .copied()
            .filter(|&c| !residency.is_resident(c))
            .collect();
        missing.push(absent);
        Ok(dmu_store::Drawn {
            missing_chunks: 0,
            visible: shown,
            pins: Vec::new(),
        })
    })
    .unwrap();
    assert_eq!(missing[0].len(), visible.len(), "nothing resident at first");
    for (i, m) in missing.iter().enumerate().skip(1) {
        assert!(m.is_empty(), "frame {i}: {m:?} not resident");
    }
}
