//! Chunk geometry on the GPU: where it comes from ([`GeometrySource`]) and the
//! pooled buffers it lives in ([`GeometryPool`]).

use bytemuck::{Pod, Zeroable};
use dmu_scene::{ChunkGeometry, ChunkId, MAX_LOD_LEVELS, Scene};

/// Where the renderer gets chunk geometry: "give me this chunk if it is resident".
///
/// The in-memory [`Scene`] has it when its meshes are loaded (a store's
/// skeleton has none); the store's residency manager answers
/// `None` for chunks not loaded yet, which the renderer skips for the frame (and
/// counts in [`crate::FrameStats::not_resident`]).
pub trait GeometrySource {
    /// The chunk's geometry, or `None` when it is not resident.
    fn chunk_geometry(&self, chunk: ChunkId) -> Option<ChunkGeometry<'_>>;

    /// Whether [`GeometrySource::chunk_geometry`] would give the chunk.
    fn has(&self, chunk: ChunkId) -> bool {
        self.chunk_geometry(chunk).is_some()
    }

    /// Whether it would give the chunk's own geometry, not a stand-in for it
    /// (a source of stand-ins answers a chunk it lacks with its box).
    fn has_own(&self, chunk: ChunkId) -> bool {
        self.has(chunk)
    }
}

impl GeometrySource for Scene {
    fn chunk_geometry(&self, chunk: ChunkId) -> Option<ChunkGeometry<'_>> {
        Scene::chunk_geometry(self, chunk)
    }
}

/// A vertex in the pool: position and a normal packed to snorm8, which is all a
/// headlight needs and keeps a vertex at 16 bytes.
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub(crate) struct PoolVertex {
    /// Part-local position.
    pub position: [f32; 3],
    /// Unit normal in snorm8 (w unused, 0).
    pub normal: [i8; 4],
}
const _: () = assert!(size_of::<PoolVertex>() == 16);

/// A unit normal as the vertex formats carry it: snorm8, w 0.
pub(crate) fn pack_normal(n: glam::Vec3) -> [i8; 4] {
    let snorm = |x: f32| (x.clamp(-1.0, 1.0) * 127.0).round() as i8;
    [snorm(n.x), snorm(n.y), snorm(n.z), 0]
}

/// Where a resident chunk lives in the pool.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ChunkSlot {
    /// Vertex page.
    pub vertex_page: u32,
    /// First vertex in the page (the draw's base vertex).
    pub first_vertex: u32,
    /// Vertices reserved.
    pub vertex_count: u32,
    /// Index page.
    pub index_page: u32,
    /// First index in the page, in units of the chunk's index format.
    pub first_index: u32,
    /// Indices (three per triangle).
    pub index_count: u32,
    /// Indices are u16 (chunks under 65 536 vertices), else u32.
    pub short_indices: bool,
    /// Indices reserved: the chunk's, then each simplified level's.
    reserved_indices: u32,
    /// The simplified levels, coarser each time, indexed after the chunk's
    /// own indices; the first `level_count` are used.
    levels: [LodRange; MAX_LOD_LEVELS],
    level_count: u8,
}

/// A simplified level of a resident chunk.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct LodRange {
    /// First index in the page.
    first_index: u32,
    index_count: u32,
    /// How far it may stray from the chunk, over the chunk's box diagonal.
    relative_error: f32,
}

/// What one draw of a resident chunk reads: a [`ChunkSlot`] at one level,
/// without the other levels (a frame keeps one per draw).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct SlotDraw {
    pub vertex_page: u32,
    pub first_vertex: u32,
    pub index_page: u32,
    pub first_index: u32,
    pub index_count: u32,
    pub short_indices: bool,
}

impl ChunkSlot {
    /// The draw of this slot's current range.
    pub(crate) fn draw_range(&self) -> SlotDraw {
        SlotDraw {
            vertex_page: self.vertex_page,
            first_vertex: self.first_vertex,
            index_page: self.index_page,
            first_index: self.first_index,
            index_count: self.index_count,
            short_indices: self.short_indices,
        }
    }

    /// Bytes reserved in the index page (padded to 4 for copy alignment).
    fn index_bytes(&self) -> u64 {
        let unit = if self.short_indices { 2 } else { 4 };
        (u64::from(self.reserved_indices) * unit).next_multiple_of(4)
    }

    /// The slot drawing the coarsest level whose error, on a box projected
    /// `size_px` pixels across, stays within `max_error_px` pixels (the
    /// chunk itself when none does).
    pub(crate) fn at_lod(mut self, size_px: f64, max_error_px: f64) -> Self {
        if let Some(level) = self.levels[..usize::from(self.level_count)]
            .iter()
            .rev()
            .find(|l| f64::from(l.relative_error) * size_px <= max_error_px)
        {
            self.first_index = level.first_index;
            self.index_count = level.index_count;
        }
        self
    }

    /// Byte offset of the first index.
    fn index_offset(&self) -> u64 {
        let unit = if self.short_indices { 2 } else { 4 };
        u64::from(self.first_index) * unit
    }
}

/// A page: one GPU buffer, its bytes handed out by [`Ranges`].
#[derive(Debug)]
struct Page {
    buffer: wgpu::Buffer,
    ranges: Ranges,
}

impl Page {
    /// The bytes handed out so far (at least 4, so the slice is never empty).
    fn written(&self) -> wgpu::BufferSlice<'_> {
        self.buffer.slice(..self.ranges.used.max(4))
    }
}

/// A page's bytes: bump-allocated from the start, freed ranges merged with
/// the free ranges beside them and reused first-fit. Unmerged, freed ranges
/// only ever split: in a soak of walks under a budget (issue 48) a larger
/// chunk fitted none of them, so the bump grew with every eviction wave
/// (the 2M plant's pool handed out 20.6 MB after one pass over its walks and
/// 51.0 MB after seven, 11.5 MB of it resident).
#[derive(Debug, Default, PartialEq, Eq)]
struct Ranges {
    /// Bytes handed out from the start: the high-water mark, freed ranges
    /// below it included (their memory stays touched).
    used: u64,
    /// Freed `(offset, bytes)` ranges below `used`, none touching another.
    free: Vec<(u64, u64)>,
}

impl Ranges {
    /// The offset of `bytes` more in a page of `capacity` bytes, if they fit.
    fn alloc(&mut self, bytes: u64, capacity: u64) -> Option<u64> {
        if let Some(i) = self.free.iter().position(|&(_, len)| len >= bytes) {
            let (offset, len) = self.free[i];
            if len == bytes {
                self.free.swap_remove(i);
            } else {
                self.free[i] = (offset + bytes, len - bytes);
            }
            return Some(offset);
        }
        (self.used + bytes <= capacity).then(|| {
            self.used += bytes;
            self.used - bytes
        })
    }

    /// Frees `bytes` at `offset`, merged with the free ranges that end where
    /// it starts and start where it ends (at most one each, since free
    /// ranges never touch).
    fn release(&mut self, offset: u64, bytes: u64) {
        if bytes == 0 {
            return;
        }
        let (mut start, mut end) = (offset, offset + bytes);
        self.free.retain(|&(o, len)| {
            if o + len == start {
                start = o;
                false
            } else if o == end {
                end = o + len;
                false
            } else {
                true
            }
        });
        self.free.push((start, end - start));
    }
}

/// Resident chunks in a few large vertex and index buffers, so a frame binds a
/// buffer per page rather than per chunk. Chunks are uploaded once and shared
/// by every part that instances them.
#[derive(Debug)]
pub struct GeometryPool {
    vertex_pages: Vec<Page>,
    index_pages: Vec<Page>,
    page_bytes: u64,
    /// Slot per chunk id, `None` when not resident.
    slots: Vec<Option<ChunkSlot>>,
    resident_bytes: u64,
    /// Reused staging for one chunk's packed data.
    scratch: Vec<u8>,
    /// Whether chunks are uploaded with their simplified levels (the ones
    /// the source lends, else computed).
    lods: bool,
    /// Time spent uploading (and simplifying) chunks so far.
    pub(crate) upload_time: std::time::Duration,
}

impl GeometryPool {
    /// An empty pool whose buffers are `page_bytes` each (chunks larger than a
    /// page get a page of their own size); with `lods`, chunks are uploaded
    /// with their simplified levels: those the source lends
    /// ([`dmu_scene::ChunkGeometry::levels`]), else [`dmu_scene::lod_levels`]
    /// computed then.
    pub(crate) fn new(chunk_count: usize, page_bytes: u64, lods: bool) -> Self {
        Self {
            vertex_pages: Vec::new(),
            index_pages: Vec::new(),
            page_bytes,
            slots: vec![None; chunk_count],
            resident_bytes: 0,
            scratch: Vec::new(),
            lods,
            upload_time: std::time::Duration::ZERO,
        }
    }

    /// Whether the chunk is on the GPU.
    pub fn is_resident(&self, chunk: ChunkId) -> bool {
        self.slots[chunk.index()].is_some()
    }

    /// Bytes of geometry resident on the GPU.
    pub fn resident_bytes(&self) -> u64 {
        self.resident_bytes
    }

    /// Chunks resident on the GPU.
    pub fn resident_chunks(&self) -> usize {
        self.slots.iter().filter(|s| s.is_some()).count()
    }

    /// Pages (GPU buffers, vertex and index) the pool has made. A page is
    /// never given back, so over a long run their number must level off.
    pub fn pages(&self) -> usize {
        self.vertex_pages.len() + self.index_pages.len()
    }

    /// Bytes of the pages handed out so far, freed ranges included: each
    /// page's high-water mark, what draws bind and so what lavapipe holds in
    /// memory for them. Above [`GeometryPool::resident_bytes`] by the freed
    /// ranges not reused yet (a chunk may not fit where a smaller one was).
    pub fn handed_out_bytes(&self) -> u64 {
        self.vertex_pages
            .iter()
            .chain(&self.index_pages)
            .map(|p| p.ranges.used)
            .sum()
    }

    fn vertex_buffer(&self, page: u32) -> &wgpu::Buffer {
        &self.vertex_pages[page as usize].buffer
    }

    fn index_buffer(&self, page: u32) -> &wgpu::Buffer {
        &self.index_pages[page as usize].buffer
    }

    /// What draws bind of a vertex page: the part handed out so far. Binding
    /// the whole page would have wgpu zero what was never written, and on
    /// lavapipe that makes a mostly empty page cost its full size in memory.
    pub(crate) fn vertex_slice(&self, page: u32) -> wgpu::BufferSlice<'_> {
        self.vertex_pages[page as usize].written()
    }

    /// What draws bind of an index page (see [`GeometryPool::vertex_slice`]).
    pub(crate) fn index_slice(&self, page: u32) -> wgpu::BufferSlice<'_> {
        self.index_pages[page as usize].written()
    }

    /// The chunk's slot, uploading it from `source` first if needed; `None` when
    /// the source does not have it.
    pub(crate) fn ensure(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        source: &dyn GeometrySource,
        chunk: ChunkId,
    ) -> Option<ChunkSlot> {
        if let Some(slot) = self.slots[chunk.index()] {
            return Some(slot);
        }
        let geometry = source.chunk_geometry(chunk)?;
        let start = std::time::Instant::now();
        // A store's chunks bring their levels; a scene's are simplified here.
        let lods = match (self.lods, geometry.levels) {
            (false, _) => std::borrow::Cow::Borrowed(&[][..]),
            (true, Some(levels)) => std::borrow::Cow::Borrowed(levels),
            (true, None) => std::borrow::Cow::Owned(dmu_scene::lod_levels(&geometry)),
        };
        let vertex_count = geometry.positions.len() as u32;
        let short_indices = vertex_count <= u32::from(u16::MAX) + 1;
        let vertex_bytes = u64::from(vertex_count) * size_of::<PoolVertex>() as u64;
        let mut slot = ChunkSlot {
            vertex_page: 0,
            first_vertex: 0,
            vertex_count,
            index_page: 0,
            first_index: 0,
            index_count: geometry.indices.len() as u32,
            short_indices,
            reserved_indices: (geometry.indices.len()
                + lods.iter().map(|l| l.indices.len()).sum::<usize>())
                as u32,
            levels: [LodRange::default(); MAX_LOD_LEVELS],
            level_count: lods.len() as u8,
        };
        let index_bytes = slot.index_bytes();
        let (vp, vo) = Self::alloc(
            device,
            &mut self.vertex_pages,
            self.page_bytes,
            vertex_bytes,
            wgpu::BufferUsages::VERTEX,
        );
        let (ip, io) = Self::alloc(
            device,
            &mut self.index_pages,
            self.page_bytes,
            index_bytes,
            wgpu::BufferUsages::INDEX,
        );
        slot.vertex_page = vp;
        slot.first_vertex = (vo / size_of::<PoolVertex>() as u64) as u32;
        slot.index_page = ip;
        slot.first_index = (io / if short_indices { 2 } else { 4 }) as u32;
        let diagonal = {
            let (lo, hi) = geometry.positions.iter().fold(
                (glam::Vec3::INFINITY, glam::Vec3::NEG_INFINITY),
                |(lo, hi), p| (lo.min(*p), hi.max(*p)),
            );
            (hi - lo).length()
        };
        let mut first = slot.first_index + slot.index_count;
        for (range, level) in slot.levels.iter_mut().zip(lods.iter()) {
            *range = LodRange {
                first_index: first,
                index_count: level.indices.len() as u32,
                relative_error: level.error / diagonal.max(f32::MIN_POSITIVE),
            };
            first += range.index_count;
        }

        self.scratch.clear();
        for (p, n) in geometry.positions.iter().zip(geometry.normals) {
            let v = PoolVertex {
                position: p.to_array(),
                normal: pack_normal(*n),
            };
            self.scratch.extend_from_slice(bytemuck::bytes_of(&v));
        }
        if vertex_bytes > 0 {
            queue.write_buffer(self.vertex_buffer(vp), vo, &self.scratch);
        }
        self.scratch.clear();
        let all_indices =
            std::iter::once(geometry.indices).chain(lods.iter().map(|l| &l.indices[..]));
        for indices in all_indices {
            if short_indices {
                for &i in indices {
                    self.scratch.extend_from_slice(&(i as u16).to_le_bytes());
                }
            } else {
                self.scratch
                    .extend_from_slice(bytemuck::cast_slice(indices));
            }
        }
        self.scratch.resize(index_bytes as usize, 0);
        if index_bytes > 0 {
            queue.write_buffer(self.index_buffer(ip), io, &self.scratch);
        }
        self.resident_bytes += vertex_bytes + index_bytes;
        self.slots[chunk.index()] = Some(slot);
        self.upload_time += start.elapsed();
        Some(slot)
    }

    /// Frees a chunk's ranges for reuse (the residency manager evicted it).
    pub fn evict(&mut self, chunk: ChunkId) {
        if let Some(slot) = self.slots[chunk.index()].take() {
            let vertex_bytes = u64::from(slot.vertex_count) * size_of::<PoolVertex>() as u64;
            let vertex_offset = u64::from(slot.first_vertex) * size_of::<PoolVertex>() as u64;
            self.vertex_pages[slot.vertex_page as usize]
                .ranges
                .release(vertex_offset, vertex_bytes);
            self.index_pages[slot.index_page as usize]
                .ranges
                .release(slot.index_offset(), slot.index_bytes());
            self.resident_bytes -= vertex_bytes + slot.index_bytes();
        }
    }

    /// `(page, byte offset)` of `bytes` in some page, adding a page when none fits.
    fn alloc(
        device: &wgpu::Device,
        pages: &mut Vec<Page>,
        page_bytes: u64,
        bytes: u64,
        usage: wgpu::BufferUsages,
    ) -> (u32, u64) {
        // Vertex offsets must be whole vertices: every size is a multiple of 16
        // (vertices) or 4 (indices), and pages hold one kind only.
        for (i, page) in pages.iter_mut().enumerate() {
            if let Some(offset) = page.ranges.alloc(bytes, page.buffer.size()) {
                return (i as u32, offset);
            }
        }
        let size = page_bytes.max(bytes).max(16);
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("dmu geometry page"),
            size,
            usage: usage | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut page = Page {
            buffer,
            ranges: Ranges::default(),
        };
        let offset = page.ranges.alloc(bytes, size).expect("a fresh page fits");
        pages.push(page);
        (pages.len() as u32 - 1, offset)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Freed ranges merge with their free neighbours, so a chunk larger than
    /// any one freed range still fits where several were, and the pages stop
    /// growing once what is resident stops growing.
    #[test]
    fn issue_48_freed_ranges_merge_and_are_reused() {
        let mut r = Ranges::default();
        let [a, b, c, d] = [16, 32, 48, 16].map(|n| r.alloc(n, 1 << 20).unwrap());
        assert_eq!((a, b, c, d, r.used), (0, 16, 48, 96, 112));
        // Freed in any order, the four merge into one range.
        r.release(b, 32);
        r.release(d, 16);
        r.release(a, 16);
        r.release(c, 48);
        assert_eq!(r.free, [(0, 112)]);
        assert_eq!(r.alloc(112, 1 << 20), Some(0));
        assert_eq!((r.used, r.free.len()), (112, 0));
        // A page full: nothing more fits, whatever is free elsewhere.
        let mut full = Ranges::default();
        assert_eq!(full.alloc(64, 64), Some(0));
        assert_eq!(full.alloc(16, 64), None);
        full.release(16, 16);
        full.release(32, 16);
        assert_eq!(full.free, [(16, 32)]);
        assert_eq!(full.alloc(32, 64), Some(16));
        full.release(0, 0);
        assert!(full.free.is_empty());

        // Chunks of random sizes come and go with at most 4 KiB resident:
        // the high-water mark stays within a few times that.
        let mut rng = 1u64;
        let mut next = || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            rng
        };
        let mut r = Ranges::default();
        let mut live: Vec<(u64, u64)> = Vec::new();
        for _ in 0..100_000 {
            let bytes = 16 * (1 + next() % 16);
            while live.iter().map(|l| l.1).sum::<u64>() + bytes > 4096 {
                let (o, n) = live.swap_remove((next() % live.len() as u64) as usize);
                r.release(o, n);
            }
            live.push((r.alloc(bytes, 1 << 30).unwrap(), bytes));
        }
        assert!(r.used <= 3 * 4096, "{} bytes handed out", r.used);
    }

    #[test]
    fn the_coarsest_level_within_the_pixel_error_is_drawn() {
        let mut slot = ChunkSlot {
            vertex_page: 0,
            first_vertex: 0,
            vertex_count: 100,
            index_page: 0,
            first_index: 10,
            index_count: 600,
            short_indices: true,
            reserved_indices: 600 + 300 + 150 + 60,
            levels: [LodRange::default(); MAX_LOD_LEVELS],
            level_count: 3,
        };
        let errors = [0.001, 0.01, 0.1];
        let counts = [300, 150, 60];
        let mut first = 610;
        for k in 0..3 {
            slot.levels[k] = LodRange {
                first_index: first,
                index_count: counts[k],
                relative_error: errors[k],
            };
            first += counts[k];
        }
        let drawn = |size_px: f64, tau: f64| {
            let s = slot.at_lod(size_px, tau);
            (s.first_index, s.index_count)
        };
        // Brute force: the coarsest level whose error times the size fits.
        for size_px in [0.5, 5.0, 50.0, 100.0, 500.0, 5000.0, f64::INFINITY] {
            for tau in [0.0, 0.5, 1.0, 2.0] {
                let want = (0..3)
                    .rev()
                    .find(|&k| f64::from(errors[k]) * size_px <= tau)
                    .map_or((10, 600), |k| (slot.levels[k].first_index, counts[k]));
                assert_eq!(drawn(size_px, tau), want, "{size_px} px, tau {tau}");
            }
        }
        assert_eq!(drawn(100.0, 1.0), (910, 150));
        assert_eq!(drawn(f64::INFINITY, 4.0), (10, 600), "an eye inside: whole");
        // Other fields are untouched.
        assert_eq!(slot.at_lod(5.0, 1.0).vertex_count, 100);
    }
}
