//! The residency manager against simple oracles: the budget is never passed
//! over random request streams, a pinned chunk is never evicted, loads follow
//! the priority order, and walks are deterministic and complete when memory
//! allows.

use std::sync::Arc;

use dmu_scene::ChunkId;
use dmu_store::{
    CameraFrame, Class, LoadOrder, Opening, Pacing, Request, Residency, ResidencyOptions, Store,
    Viewport, WalkOptions, WriteOptions, walk,
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
pub(crate) fn path(store: &Store) -> Vec<CameraFrame> {
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

pub(crate) fn options(budget: u64, order: LoadOrder) -> WalkOptions {
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
        opening_frames: 0,
        lod_cut: None,
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

/// Twelve frames at one camera of the plant, with room for everything and
/// an unbounded disk, and the chunks that camera wants, least on screen first.
struct Still(
    tempfile::TempDir,
    Arc<Store>,
    dmu_tree::Tree,
    Vec<CameraFrame>,
    WalkOptions,
    Vec<(ChunkId, f32)>,
);

impl Still {
    fn new() -> Self {
        let (dir, store) = plant_store();
        let tree = dmu_tree::Tree::build(store.skeleton(), Default::default());
        let still = vec![path(&store)[100]; 12];
        let mut o = options(u64::MAX, LoadOrder::Visibility);
        o.disk_bytes_per_frame = Some(u64::MAX / 4);
        let mut wanted: Vec<(ChunkId, f32)> = Vec::new();
        dmu_store::walk_with(&store, &tree, &still[..1], &o, &mut |_, set, _| {
            wanted = set.drawn.clone();
            Ok(dmu_store::Drawn::default())
        })
        .unwrap();
        wanted.sort_by(|a, b| a.1.total_cmp(&b.1));
        Self(dir, store, tree, still, o, wanted)
    }
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
    let Still(_dir, store, tree, still, mut o, wanted) = Still::new();
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
        let i = i.expect("no opening frames");
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

/// A cold first frame draws everything in view as stand-ins (boxes). Those
/// chunks are recent, but not resident: they are not loaded for being recent,
/// or they would evict, as recent chunks with more on screen, a chunk the
/// next frame found visible and loaded. Here the cold frame is followed by a
/// frame drawing only one chunk little on screen, then by frames drawing
/// nothing: that chunk stays resident while it is recent.
#[test]
fn a_cold_frame_of_stand_ins_does_not_evict_what_was_found_visible() {
    let Still(_dir, store, tree, still, mut o, wanted) = Still::new();
    let size = |c: ChunkId| store.chunk_resident_bytes(c);
    // Found: the largest in bytes of the half least on screen, so that every
    // chunk more on screen that does not fit would fit in its place.
    let found = wanted[..wanted.len() / 2]
        .iter()
        .map(|w| w.0)
        .max_by_key(|&c| size(c))
        .unwrap();
    let largest = wanted.iter().map(|w| size(w.0)).max().unwrap();
    // Room for the found chunk and for the largest of the others.
    o.budget_bytes = size(found) + largest;
    assert!(wanted.len() > 3 && wanted.iter().map(|w| size(w.0)).sum::<u64>() > o.budget_bytes);
    let mut resident = Vec::new();
    dmu_store::walk_with(&store, &tree, &still, &o, &mut |i, _, residency| {
        let i = i.expect("no opening frames");
        resident.push(residency.is_resident(found));
        let visible = match i {
            0 => wanted.iter().map(|w| w.0).collect(),
            1 => vec![found],
            _ => Vec::new(),
        };
        Ok(dmu_store::Drawn {
            missing_chunks: 0,
            visible,
            pins: Vec::new(),
        })
    })
    .unwrap();
    // Loaded before frame 3 (a Visible request after frame 2), then kept.
    assert_eq!(
        &resident[3..],
        &[true; 9],
        "resident per frame: {resident:?}"
    );
}

/// The opening frames draw the path's first view until one misses nothing
/// (the loads between them bring what it wants), are not counted among the
/// walk's frames, and leave its first frame missing nothing; without them the
/// first frame misses what it wants.
#[test]
fn opening_frames_load_the_first_view_before_the_walk() {
    let (_dir, store) = plant_store();
    let tree = dmu_tree::Tree::build(store.skeleton(), Default::default());
    let frames = &path(&store)[100..110];
    let mut o = options(u64::MAX, LoadOrder::Visibility);
    let cold = walk(&store, &tree, frames, &o).unwrap();
    assert_eq!(cold.opening, Opening::default());
    assert!(cold.frames[0].missing_chunks > 0);
    // A grant of a few kilobytes a frame: the opening takes several frames.
    o.disk_bytes_per_frame = Some(16 << 10);
    o.opening_frames = 1_000;
    let mut opening_draws = 0;
    let opened = dmu_store::walk_with(&store, &tree, frames, &o, &mut |index, set, residency| {
        opening_draws += u32::from(index.is_none());
        let missing = set
            .drawn
            .iter()
            .filter(|&&(c, _)| !residency.is_resident(c))
            .count();
        Ok(dmu_store::Drawn {
            missing_chunks: missing as u64,
            visible: set.drawn.iter().map(|w| w.0).collect(),
            pins: Vec::new(),
        })
    })
    .unwrap();
    assert_eq!(opened.frames.len(), frames.len());
    assert_eq!(u64::from(opening_draws), opened.opening.frames);
    assert!(opened.opening.frames > 2, "{:?}", opened.opening);
    assert_eq!(opened.opening.missing_chunks, 0);
    assert_eq!(opened.frames[0].missing_chunks, 0);
    assert!(opened.opening.loaded_bytes > 0);
    assert!(opened.total.loaded_bytes >= opened.opening.loaded_bytes);
    // Capped: at most that many frames, and the walk goes on regardless.
    o.opening_frames = 2;
    let capped = walk(&store, &tree, frames, &o).unwrap();
    assert_eq!(capped.opening.frames, 2);
    assert!(capped.opening.missing_chunks > 0);
    assert_eq!(capped.frames.len(), frames.len());
    // A first view larger than the budget: the opening ends once it stops
    // missing fewer chunks, not after a thousand frames.
    o.opening_frames = 1_000;
    o.disk_bytes_per_frame = Some(u64::MAX / 4);
    o.budget_bytes = cold.frames[0].wanted_bytes / 2;
    let stalled = walk(&store, &tree, frames, &o).unwrap();
    assert!(stalled.opening.missing_chunks > 0, "{:?}", stalled.opening);
    assert!(stalled.opening.frames < 20, "{:?}", stalled.opening);
    assert!(stalled.opening.frames > u64::from(dmu_store::OPENING_STALL_FRAMES));
}
