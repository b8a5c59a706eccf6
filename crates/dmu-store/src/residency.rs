//! The residency manager: which chunks' geometry is in memory, within a byte
//! budget; named loader threads fetch what is wanted most first; the least
//! recently used chunks are evicted, never one in use.
//!
//! Each frame the renderer says what it wants ([`Residency::request`]): the
//! request list replaces the load queue (MMDr's residency request manager, with
//! MMR's prefetch requests in the same queue at a lower class). Memory is
//! reserved when a loader takes a request, so resident plus in-flight bytes never
//! pass the budget; to make room, chunks are evicted oldest first, skipping those
//! in use (an `Arc` of their geometry is held outside) and those wanted this
//! frame at a priority at least the new request's (so a frame's wants cannot
//! evict each other in a loop). When the head of the queue does not fit, loading
//! stops until the next request list.
//!
//! All decisions (which request, which victim, the LRU stamp) are taken under
//! one lock in queue order, so with [`Pacing::Granted`] the result of a frame is
//! the same whatever the threads' timing.

use std::collections::BTreeSet;
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use dmu_scene::ChunkId;

use crate::error::{ResidencyError, StoreError, one_line};
use crate::geometry::OwnedChunkGeometry;
use crate::priority::{LoadOrder, Request};
use crate::read::Store;

/// When loader threads may read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pacing {
    /// Whenever there is work: real time.
    Free,
    /// Only the disk bytes granted by [`Residency::load_granted`]: a fixed
    /// disk bandwidth per frame, so results do not depend on the machine.
    Granted,
}

/// Settings of a [`Residency`].
#[derive(Clone, Copy, Debug)]
pub struct ResidencyOptions {
    /// Decoded geometry bytes that may be resident or loading at once.
    pub budget_bytes: u64,
    /// Loader threads (at least one), named `dmu-loader-N`.
    pub loader_threads: usize,
    /// How the queue is ordered.
    pub order: LoadOrder,
    /// When loaders may read.
    pub pacing: Pacing,
}

/// Counters and levels of a [`Residency`].
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ResidencyStats {
    /// Request lists received.
    pub frames: u64,
    /// Bytes resident now.
    pub resident_bytes: u64,
    /// Chunks resident now.
    pub resident_chunks: u64,
    /// Bytes reserved by loads in flight.
    pub reserved_bytes: u64,
    /// Highest resident plus reserved bytes ever: never above the budget.
    pub peak_bytes: u64,
    /// Requests of this frame still waiting for a loader.
    pub queue_len: u64,
    /// Chunks loaded.
    pub loads: u64,
    /// File bytes read by those loads.
    pub loaded_file_bytes: u64,
    /// Decoded bytes of those loads.
    pub loaded_resident_bytes: u64,
    /// Chunks evicted.
    pub evictions: u64,
    /// Times the head of the queue did not fit the budget (loading then waits for
    /// the next request list).
    pub budget_stalls: u64,
    /// Loads that failed (corrupt segments); such chunks are not retried.
    pub failures: u64,
    /// Loads that failed for I/O (a server gone, a network down): the chunk
    /// stays absent and is loaded again later ([`Residency::outage`]).
    pub fetch_errors: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum SlotState {
    Absent,
    Loading,
    Resident,
    Failed,
}

#[derive(Debug)]
struct Slot {
    state: SlotState,
    geometry: Option<Arc<OwnedChunkGeometry>>,
    /// LRU stamp (larger is more recent); the LRU set holds `(last_use, chunk)`
    /// for every resident chunk.
    last_use: u64,
    /// The frame that last requested it (0: never).
    want_frame: u64,
    /// Its priority key in `want_frame`.
    key: u64,
    /// When the current run of frames requesting it began (for FIFO order).
    arrival: u64,
}

#[derive(Debug)]
struct State {
    slots: Vec<Slot>,
    lru: BTreeSet<(u64, u32)>,
    /// This frame's wanted absent chunks, most urgent first; `cursor` is the next.
    queue: Vec<u32>,
    cursor: usize,
    frame: u64,
    tick: u64,
    arrivals: u64,
    /// Disk bytes loaders may still read ([`Pacing::Granted`]); may go below 0
    /// by the last load, and the debt is paid from the next grant.
    grant: i64,
    /// The head of the queue did not fit: wait for the next request list.
    blocked: bool,
    in_flight: usize,
    shutdown: bool,
    stats: ResidencyStats,
    first_error: Option<String>,
    /// While loads fail for I/O: the last such error, and when loading may
    /// be tried again (after [`RETRY_FIRST`], doubling to [`RETRY_MOST`]).
    outage: Option<Outage>,
    /// Chunks evicted since [`Residency::take_evicted`] last ran.
    evicted: Vec<ChunkId>,
}

#[derive(Debug)]
struct Shared {
    store: Arc<Store>,
    options: ResidencyOptions,
    state: Mutex<State>,
    /// Loaders wait here for work.
    work: Condvar,
    /// [`Residency::load_granted`] waits here for the loaders to go idle.
    idle: Condvar,
}

/// Loads failing for I/O (see [`State::outage`]).
#[derive(Debug)]
struct Outage {
    error: String,
    retry_at: Instant,
    wait: Duration,
}

/// How long loading pauses after the first load that failed for I/O.
pub const RETRY_FIRST: Duration = Duration::from_millis(250);
/// The longest pause between tries while loads keep failing for I/O.
pub const RETRY_MOST: Duration = Duration::from_secs(4);

/// A load taken by a loader: memory reserved, disk grant spent.
struct Job {
    chunk: u32,
    bytes: u64,
    file_bytes: u64,
}

/// Keeps chunk geometry of a [`Store`] in memory within a byte budget.
#[derive(Debug)]
pub struct Residency {
    shared: Arc<Shared>,
    threads: Vec<JoinHandle<()>>,
}

fn lock(m: &Mutex<State>) -> MutexGuard<'_, State> {
    // A loader that panicked left the state consistent (all changes are made
    // before anything that can panic), so keep going.
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

impl Residency {
    /// Starts the loader threads.
    ///
    /// # Panics
    /// When `loader_threads` is 0 or a thread cannot be spawned.
    pub fn new(store: Arc<Store>, options: ResidencyOptions) -> Residency {
        assert!(
            options.loader_threads > 0,
            "a residency needs a loader thread"
        );
        let chunks = store.skeleton().chunks().len();
        let slots = (0..chunks)
            .map(|_| Slot {
                state: SlotState::Absent,
                geometry: None,
                last_use: 0,
                want_frame: 0,
                key: 0,
                arrival: 0,
            })
            .collect();
        let shared = Arc::new(Shared {
            store,
            options,
            state: Mutex::new(State {
                slots,
                lru: BTreeSet::new(),
                queue: Vec::new(),
                cursor: 0,
                frame: 0,
                tick: 0,
                arrivals: 0,
                grant: 0,
                blocked: false,
                in_flight: 0,
                shutdown: false,
                stats: ResidencyStats::default(),
                first_error: None,
                outage: None,
                evicted: Vec::new(),
            }),
            work: Condvar::new(),
            idle: Condvar::new(),
        });
        let threads = (0..options.loader_threads)
            .map(|i| {
                let shared = Arc::clone(&shared);
                std::thread::Builder::new()
                    .name(format!("dmu-loader-{i}"))
                    .spawn(move || loader(&shared))
                    .expect("spawn a loader thread")
            })
            .collect();
        Residency { shared, threads }
    }

    /// The budget.
    pub fn budget_bytes(&self) -> u64 {
        self.shared.options.budget_bytes
    }

    /// Starts a frame: `requests` (any order, duplicates allowed: the highest
    /// priority counts) replace the load queue. Resident chunks requested are
    /// marked used now, the least urgent first, so that among them the LRU order
    /// is the priority order.
    ///
    /// # Panics
    /// When a request names a chunk the store does not have.
    pub fn request(&self, requests: &[Request]) {
        let order = self.shared.options.order;
        let mut guard = lock(&self.shared.state);
        let st = &mut *guard;
        st.frame += 1;
        st.stats.frames += 1;
        let frame = st.frame;
        let mut unique: Vec<u32> = Vec::new();
        for r in requests {
            let c = r.chunk.0;
            let slot = &mut st.slots[c as usize];
            if slot.want_frame == frame {
                slot.key = slot.key.max(order.key(r, slot.arrival));
                continue;
            }
            if slot.want_frame == 0 || slot.want_frame + 1 != frame {
                slot.arrival = st.arrivals;
                st.arrivals += 1;
            }
            slot.want_frame = frame;
            slot.key = order.key(r, slot.arrival);
            unique.push(c);
        }
        let by_urgency = |slots: &[Slot], a: &u32, b: &u32| {
            slots[*b as usize]
                .key
                .cmp(&slots[*a as usize].key)
                .then(a.cmp(b))
        };
        let (mut absent, mut resident): (Vec<u32>, Vec<u32>) = unique
            .into_iter()
            .filter(|&c| {
                matches!(
                    st.slots[c as usize].state,
                    SlotState::Absent | SlotState::Resident
                )
            })
            .partition(|&c| st.slots[c as usize].state == SlotState::Absent);
        absent.sort_unstable_by(|a, b| by_urgency(&st.slots, a, b));
        resident.sort_unstable_by(|a, b| by_urgency(&st.slots, b, a));
        for c in resident {
            st.touch(c);
        }
        st.queue = absent;
        st.cursor = 0;
        st.blocked = false;
        drop(guard);
        self.shared.work.notify_all();
    }

    /// The chunk's geometry if resident, marking it used. Holding the returned
    /// `Arc` pins the chunk: it is not evicted while any clone lives.
    pub fn get(&self, chunk: ChunkId) -> Option<Arc<OwnedChunkGeometry>> {
        let mut st = lock(&self.shared.state);
        let frame = st.frame;
        let slot = &st.slots[chunk.index()];
        let geometry = Arc::clone(slot.geometry.as_ref()?);
        // Chunks requested this frame were ordered by priority in `request`.
        if slot.want_frame != frame {
            st.touch(chunk.0);
        }
        Some(geometry)
    }

    /// Whether the chunk's geometry is resident.
    pub fn is_resident(&self, chunk: ChunkId) -> bool {
        lock(&self.shared.state).slots[chunk.index()].state == SlotState::Resident
    }

    /// With [`Pacing::Granted`]: lets the loaders read `disk_bytes` more (less
    /// any overdraw of the last grant) and waits until they are done: queue
    /// empty, grant spent, or the head of the queue not fitting the budget. An
    /// unspent grant is dropped on return (an idle disk saves no bandwidth), so
    /// loaders only ever run inside this call.
    pub fn load_granted(&self, disk_bytes: u64) {
        let shared = &self.shared;
        let mut st = lock(&shared.state);
        st.grant = st.grant.min(0) + i64::try_from(disk_bytes).unwrap_or(i64::MAX);
        shared.work.notify_all();
        while st.in_flight > 0 || st.has_work(&shared.options) {
            // The work may have appeared by the clock (an outage's pause
            // ending) after every loader went to sleep: wake them each time.
            shared.work.notify_all();
            st = shared.idle.wait(st).unwrap_or_else(PoisonError::into_inner);
        }
        // What is left is not kept: loaders stay idle until the next grant, so
        // nothing loads while the caller draws, whatever the threads' timing.
        st.grant = st.grant.min(0);
    }

    /// Counters and levels.
    pub fn stats(&self) -> ResidencyStats {
        let st = lock(&self.shared.state);
        let mut stats = st.stats.clone();
        stats.queue_len = st.pending() as u64;
        stats
    }

    /// The chunks evicted since the last call, so that copies made of their
    /// geometry (e.g. on the GPU) can be dropped with them.
    pub fn take_evicted(&self) -> Vec<ChunkId> {
        std::mem::take(&mut lock(&self.shared.state).evicted)
    }

    /// While loads fail for I/O (an object store gone away): the last such
    /// error. Chunks that failed so stay absent (drawn as stand-ins) and are
    /// loaded again when tries succeed; `None` once one does.
    pub fn outage(&self) -> Option<String> {
        lock(&self.shared.state)
            .outage
            .as_ref()
            .map(|o| o.error.clone())
    }

    /// The first load error (a corrupt chunk segment), if any.
    pub fn first_error(&self) -> Option<String> {
        lock(&self.shared.state).first_error.clone()
    }

    /// Checks the accounting: resident bytes and the LRU set match the resident
    /// chunks, and resident plus reserved bytes are within the budget.
    pub fn validate(&self) -> Result<(), ResidencyError> {
        self.check_accounting()
            .map_err(|what| ResidencyError { what })
    }

    /// [`Residency::validate`]'s checks, failing with what is wrong.
    fn check_accounting(&self) -> Result<(), String> {
        let st = lock(&self.shared.state);
        let store = &self.shared.store;
        let mut bytes = 0;
        let mut count = 0;
        for (c, slot) in st.slots.iter().enumerate() {
            let resident = slot.state == SlotState::Resident;
            if resident != slot.geometry.is_some() {
                return Err(format!(
                    "chunk {c}: state {:?} disagrees with its geometry",
                    slot.state
                ));
            }
            if resident {
                bytes += store.chunk_resident_bytes(ChunkId::from_index(c));
                count += 1;
                if !st.lru.contains(&(slot.last_use, c as u32)) {
                    return Err(format!("chunk {c}: resident but not in the LRU set"));
                }
            }
        }
        if st.lru.len() != count || bytes != st.stats.resident_bytes {
            return Err(format!(
                "{count} chunks of {bytes} bytes resident, accounted {} of {}",
                st.lru.len(),
                st.stats.resident_bytes
            ));
        }
        let budget = self.shared.options.budget_bytes;
        if st.stats.resident_bytes + st.stats.reserved_bytes > budget
            || st.stats.peak_bytes > budget
        {
            return Err(format!("over the budget of {budget} bytes: {:?}", st.stats));
        }
        Ok(())
    }
}

impl Drop for Residency {
    fn drop(&mut self) {
        lock(&self.shared.state).shutdown = true;
        self.shared.work.notify_all();
        for t in self.threads.drain(..) {
            // A loader that panicked has nothing left to clean up.
            let _ = t.join();
        }
    }
}

fn loader(shared: &Shared) {
    let mut st = lock(&shared.state);
    loop {
        if st.shutdown {
            return;
        }
        let Some(job) = st.next_job(shared) else {
            shared.idle.notify_all();
            // While loads pause for an outage, wake when the pause ends:
            // loading resumes even when nothing else calls.
            st = match st.outage.as_ref().map(|o| o.retry_at) {
                Some(at) => {
                    let wait = at.saturating_duration_since(Instant::now());
                    shared
                        .work
                        .wait_timeout(st, wait.max(Duration::from_millis(1)))
                        .unwrap_or_else(PoisonError::into_inner)
                        .0
                }
                None => shared.work.wait(st).unwrap_or_else(PoisonError::into_inner),
            };
            continue;
        };
        drop(st);
        let result = shared.store.chunk_geometry(ChunkId(job.chunk));
        st = lock(&shared.state);
        let was_out = st.outage.is_some();
        st.complete(&job, result);
        if was_out && st.outage.is_none() {
            // Back: every loader may take work again.
            shared.work.notify_all();
        }
        shared.idle.notify_all();
    }
}

impl State {
    fn touch(&mut self, c: u32) {
        let tick = self.next_tick();
        let slot = &mut self.slots[c as usize];
        if slot.state == SlotState::Resident {
            self.lru.remove(&(slot.last_use, c));
            self.lru.insert((tick, c));
        }
        slot.last_use = tick;
    }

    fn next_tick(&mut self) -> u64 {
        self.tick += 1;
        self.tick
    }

    /// Requests of this frame still waiting, from the cursor on.
    fn pending(&self) -> usize {
        self.queue[self.cursor.min(self.queue.len())..]
            .iter()
            .filter(|&&c| self.waiting(c))
            .count()
    }

    fn waiting(&self, c: u32) -> bool {
        let slot = &self.slots[c as usize];
        slot.state == SlotState::Absent && slot.want_frame == self.frame
    }

    fn has_work(&self, options: &ResidencyOptions) -> bool {
        let allowed = (options.pacing == Pacing::Free || self.grant > 0)
            && self
                .outage
                .as_ref()
                .is_none_or(|o| Instant::now() >= o.retry_at);
        let pending = || {
            self.queue[self.cursor.min(self.queue.len())..]
                .iter()
                .any(|&c| self.waiting(c))
        };
        !self.shutdown && !self.blocked && allowed && pending()
    }

    /// Takes the next request that is still wanted, reserving its memory (evicting
    /// as needed) and its disk grant.
    fn next_job(&mut self, shared: &Shared) -> Option<Job> {
        if !self.has_work(&shared.options) {
            return None;
        }
        while let Some(&c) = self.queue.get(self.cursor) {
            if !self.waiting(c) {
                self.cursor += 1;
                continue;
            }
            let chunk = ChunkId(c);
            let bytes = shared.store.chunk_resident_bytes(chunk);
            let key = self.slots[c as usize].key;
            if !self.make_room(bytes, key, &shared.store, shared.options.budget_bytes) {
                self.blocked = true;
                self.stats.budget_stalls += 1;
                return None;
            }
            self.cursor += 1;
            let file_bytes = shared.store.chunk_file_bytes(chunk);
            if shared.options.pacing == Pacing::Granted {
                self.grant -= i64::try_from(file_bytes).unwrap_or(i64::MAX);
            }
            self.stats.reserved_bytes += bytes;
            let used = self.stats.resident_bytes + self.stats.reserved_bytes;
            self.stats.peak_bytes = self.stats.peak_bytes.max(used);
            // Stamped now, not when the load ends, so the LRU order does not
            // depend on which loader finishes first.
            let tick = self.next_tick();
            let slot = &mut self.slots[c as usize];
            slot.state = SlotState::Loading;
            slot.last_use = tick;
            self.in_flight += 1;
            return Some(Job {
                chunk: c,
                bytes,
                file_bytes,
            });
        }
        None
    }

    /// Evicts until `bytes` more fit, oldest first; when even evicting every
    /// candidate would not make room, evicts nothing and returns false.
    fn make_room(&mut self, bytes: u64, key: u64, store: &Store, budget: u64) -> bool {
        if bytes > budget {
            return false;
        }
        let used = self.stats.resident_bytes + self.stats.reserved_bytes;
        let mut excess = (used + bytes).saturating_sub(budget);
        if excess == 0 {
            return true;
        }
        let frame = self.frame;
        let mut victims = Vec::new();
        for &(tick, c) in &self.lru {
            let slot = &self.slots[c as usize];
            let in_use = slot
                .geometry
                .as_ref()
                .is_some_and(|g| Arc::strong_count(g) > 1);
            let protected = slot.want_frame == frame && slot.key >= key;
            if in_use || protected {
                continue;
            }
            victims.push((tick, c));
            excess = excess.saturating_sub(store.chunk_resident_bytes(ChunkId(c)));
            if excess == 0 {
                break;
            }
        }
        if excess > 0 {
            return false;
        }
        for (tick, c) in victims {
            self.lru.remove(&(tick, c));
            let slot = &mut self.slots[c as usize];
            slot.geometry = None;
            slot.state = SlotState::Absent;
            self.stats.resident_bytes -= store.chunk_resident_bytes(ChunkId(c));
            self.stats.resident_chunks -= 1;
            self.stats.evictions += 1;
            self.evicted.push(ChunkId(c));
        }
        true
    }

    fn complete(&mut self, job: &Job, result: Result<OwnedChunkGeometry, StoreError>) {
        self.in_flight -= 1;
        self.stats.reserved_bytes -= job.bytes;
        let slot = &mut self.slots[job.chunk as usize];
        match result {
            Ok(geometry) => {
                debug_assert!(geometry.resident_bytes() <= job.bytes);
                slot.geometry = Some(Arc::new(geometry));
                slot.state = SlotState::Resident;
                self.lru.insert((slot.last_use, job.chunk));
                self.stats.resident_bytes += job.bytes;
                self.stats.resident_chunks += 1;
                self.stats.loads += 1;
                self.stats.loaded_file_bytes += job.file_bytes;
                self.stats.loaded_resident_bytes += job.bytes;
                self.outage = None;
            }
            Err(e @ StoreError::Io { .. }) => {
                slot.state = SlotState::Absent;
                self.stats.fetch_errors += 1;
                let wait = self
                    .outage
                    .as_ref()
                    .map_or(RETRY_FIRST, |o| (o.wait * 2).min(RETRY_MOST));
                self.outage = Some(Outage {
                    error: one_line(&e),
                    retry_at: Instant::now() + wait,
                    wait,
                });
            }
            Err(e) => {
                slot.state = SlotState::Failed;
                self.stats.failures += 1;
                self.first_error.get_or_insert(one_line(&e));
            }
        }
    }
}
