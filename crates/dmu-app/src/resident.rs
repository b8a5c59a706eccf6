//! The bridge from a store's residency manager to the renderer: chunk geometry
//! streamed from disk, drawn as it arrives.

use std::sync::{Arc, Mutex, OnceLock, PoisonError};

use dmu_geom::Aabb3f;
use dmu_render::{GeometryPool, GeometrySource};
use dmu_scene::{ChunkGeometry, ChunkId, Scene};
use dmu_store::Residency;
use glam::Vec3;

/// Chunk geometry for one frame from a residency manager: each chunk the
/// renderer asks for is looked up once (resident or not) and pinned until
/// this source is dropped, so a chunk evicted while the frame is drawn stays
/// valid for it.
///
/// Make one per frame, after handing the renderer's geometry pool the chunks
/// the residency evicted (`Residency::take_evicted`, then
/// `GeometryPool::evict`); chunks not resident are `None`, which the renderer
/// skips for the frame and counts as not resident.
#[derive(Debug)]
pub struct ResidentSource<'a> {
    residency: &'a Residency,
    pins: Vec<OnceLock<Option<Arc<dmu_store::OwnedChunkGeometry>>>>,
}

impl<'a> ResidentSource<'a> {
    /// A source over `residency` for a scene of `chunks` chunks (the store's
    /// `skeleton().chunks().len()`).
    pub(crate) fn new(residency: &'a Residency, chunks: usize) -> Self {
        Self {
            residency,
            pins: (0..chunks).map(|_| OnceLock::new()).collect(),
        }
    }
}

impl GeometrySource for ResidentSource<'_> {
    fn chunk_geometry(&self, chunk: ChunkId) -> Option<ChunkGeometry<'_>> {
        let g = self
            .pins
            .get(chunk.index())?
            .get_or_init(|| self.residency.get(chunk))
            .as_ref()?;
        Some(g.geometry())
    }
}

/// A [`ResidentSource`] that answers for a chunk not resident with a stand-in:
/// its box (the skeleton's chunk bounds, which the geometry fills exactly),
/// flat-shaded (a face normal per side), drawn with the chunk's material by
/// whatever instances it. The renderer uploads it as the chunk, so the
/// caller keeps the chunks given a stand-in ([`StandInSource::stood_in`])
/// and hands them to `geometry_pool().evict` once they are resident, for
/// the real geometry to replace the box.
#[derive(Debug)]
pub struct StandInSource<'a> {
    resident: ResidentSource<'a>,
    scene: &'a Scene,
    boxes: Vec<OnceLock<BoxGeometry>>,
    stood_in: Mutex<Vec<ChunkId>>,
}

/// A box as chunk geometry: 24 vertices (four per face, each face its own
/// normal) and 12 triangles.
#[derive(Debug)]
struct BoxGeometry {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    indices: Vec<u32>,
}

impl BoxGeometry {
    fn new(b: &Aabb3f) -> Self {
        let corner = |x: bool, y: bool, z: bool| {
            Vec3::new(
                if x { b.max.x } else { b.min.x },
                if y { b.max.y } else { b.min.y },
                if z { b.max.z } else { b.min.z },
            )
        };
        let mut g = Self {
            positions: Vec::with_capacity(24),
            normals: Vec::with_capacity(24),
            indices: Vec::with_capacity(36),
        };
        for axis in 0..3 {
            for high in [false, true] {
                // The face's four corners counter-clockwise seen from outside.
                let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                let mut quad = [(false, false), (true, false), (true, true), (false, true)];
                if !high {
                    quad.reverse();
                }
                let base = g.positions.len() as u32;
                for (a, c) in quad {
                    let mut bits = [false; 3];
                    bits[axis] = high;
                    bits[u] = a;
                    bits[v] = c;
                    g.positions.push(corner(bits[0], bits[1], bits[2]));
                    let mut n = Vec3::ZERO;
                    n[axis] = if high { 1.0 } else { -1.0 };
                    g.normals.push(n);
                }
                g.indices
                    .extend([0, 1, 2, 0, 2, 3].into_iter().map(|i| base + i));
            }
        }
        g
    }
}

impl<'a> StandInSource<'a> {
    /// Stand-ins from `scene`'s chunk boxes (the store's skeleton, or a scene
    /// of the same structure) for what `residency` lacks.
    pub(crate) fn new(residency: &'a Residency, scene: &'a Scene) -> Self {
        let chunks = scene.chunks().len();
        Self {
            resident: ResidentSource::new(residency, chunks),
            scene,
            boxes: (0..chunks).map(|_| OnceLock::new()).collect(),
            stood_in: Mutex::new(Vec::new()),
        }
    }

    /// The chunks given a stand-in through this source (each once).
    pub fn stood_in(self) -> Vec<ChunkId> {
        let mut v = self
            .stood_in
            .into_inner()
            .unwrap_or_else(PoisonError::into_inner);
        v.sort_unstable();
        v.dedup();
        v
    }
}

impl GeometrySource for StandInSource<'_> {
    fn chunk_geometry(&self, chunk: ChunkId) -> Option<ChunkGeometry<'_>> {
        if let Some(g) = self.resident.chunk_geometry(chunk) {
            return Some(g);
        }
        let slot = self.boxes.get(chunk.index())?;
        let g = slot.get_or_init(|| {
            self.stood_in
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .push(chunk);
            BoxGeometry::new(&self.scene.chunk(chunk).bounds)
        });
        Some(ChunkGeometry {
            positions: &g.positions,
            normals: &g.normals,
            indices: &g.indices,
            // Twelve triangles: too few for levels.
            levels: Some(&[]),
        })
    }

    fn has(&self, chunk: ChunkId) -> bool {
        chunk.index() < self.boxes.len()
    }

    fn has_own(&self, chunk: ChunkId) -> bool {
        self.resident.has(chunk)
    }
}

/// Which chunks the GPU pool holds as stand-ins (their boxes, uploaded through
/// a [`StandInSource`]) rather than as their geometry, across frames: once such
/// a chunk is resident its box is dropped from the pool, for the geometry to
/// be uploaded in its place; and which drawn chunk instances were stand-ins.
#[derive(Debug)]
pub(crate) struct StandIns {
    /// Per chunk: the GPU pool holds its stand-in.
    standing: Vec<bool>,
    /// The chunks set in `standing`.
    list: Vec<ChunkId>,
}

impl StandIns {
    /// None yet, for a scene of `chunks` chunks.
    pub fn new(chunks: usize) -> Self {
        Self {
            standing: vec![false; chunks],
            list: Vec::new(),
        }
    }

    /// Before a frame: drops from `pool` the stand-ins of chunks `residency`
    /// now holds.
    pub fn release(&mut self, residency: &Residency, pool: &mut GeometryPool) {
        let standing = &mut self.standing;
        self.list.retain(|&c| {
            let resident = residency.is_resident(c);
            if resident {
                pool.evict(c);
                standing[c.index()] = false;
            }
            !resident
        });
    }

    /// After a frame: `stood_in` got stand-ins in the pool
    /// ([`StandInSource::stood_in`]).
    pub fn note(&mut self, stood_in: Vec<ChunkId>) {
        for c in stood_in {
            if !self.standing[c.index()] {
                self.standing[c.index()] = true;
                self.list.push(c);
            }
        }
    }

    /// How many stand-ins the pool holds (a box each, kept until its chunk
    /// is resident).
    pub fn count(&self) -> usize {
        self.list.len()
    }

    /// Whether the pool holds `chunk`'s stand-in.
    pub fn is_standing(&self, chunk: ChunkId) -> bool {
        self.standing.get(chunk.index()).copied().unwrap_or(false)
    }
}

/// The per-frame streaming work between a residency manager and a renderer,
/// written once for every program that draws a store within a budget (the
/// viewer, `dmu walk --render`, and the XR session when it streams): before
/// a frame the GPU pool drops what the residency evicted and the stand-ins
/// of chunks now resident ([`StreamedFrames::begin`]); the frame draws
/// through one [`FrameSource`] ([`StreamedFrames::source`]), boxes or holes
/// for what is missing as the program chose; after it the new stand-ins are
/// kept and the frame's misses counted ([`StreamedFrames::end`]).
#[derive(Debug)]
pub struct StreamedFrames {
    /// A chunk not resident is drawn as its box (else it is a hole).
    stand_ins: bool,
    standing: StandIns,
}

/// What a streamed frame's views lacked.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameMisses {
    /// Chunk instances not drawn for want of geometry.
    pub holes: u64,
    /// Chunk instances drawn as their boxes.
    pub stand_ins: u64,
}

/// One streamed frame's geometry: a [`StandInSource`] with stand-ins, else a
/// [`ResidentSource`] (a table per chunk, made per frame).
#[derive(Debug)]
pub enum FrameSource<'a> {
    /// Chunks not resident answer with their boxes.
    StandIns(StandInSource<'a>),
    /// Chunks not resident are holes.
    Resident(ResidentSource<'a>),
}

impl FrameSource<'_> {
    /// The chunks given a stand-in in this frame (none without stand-ins),
    /// for [`StreamedFrames::end`].
    pub fn stood_in(self) -> Vec<ChunkId> {
        match self {
            Self::StandIns(s) => s.stood_in(),
            Self::Resident(_) => Vec::new(),
        }
    }
}

impl GeometrySource for FrameSource<'_> {
    fn chunk_geometry(&self, chunk: ChunkId) -> Option<ChunkGeometry<'_>> {
        match self {
            Self::StandIns(s) => s.chunk_geometry(chunk),
            Self::Resident(r) => r.chunk_geometry(chunk),
        }
    }

    fn has(&self, chunk: ChunkId) -> bool {
        match self {
            Self::StandIns(s) => s.has(chunk),
            Self::Resident(r) => r.has(chunk),
        }
    }

    fn has_own(&self, chunk: ChunkId) -> bool {
        match self {
            Self::StandIns(s) => s.has_own(chunk),
            Self::Resident(r) => r.has_own(chunk),
        }
    }
}

impl StreamedFrames {
    /// Nothing streamed yet into a pool for a scene of `chunks` chunks;
    /// `stand_ins`: draw a chunk not resident as its box.
    pub fn new(chunks: usize, stand_ins: bool) -> Self {
        Self {
            stand_ins,
            standing: StandIns::new(chunks),
        }
    }

    /// Whether chunks not resident are drawn as their boxes.
    pub fn stand_ins(&self) -> bool {
        self.stand_ins
    }

    /// Before a frame: drops from `pool` the chunks `residency` evicted and
    /// the stand-ins of chunks it now holds (the invariant a residency's
    /// callers keep, ARCHITECTURE.md).
    pub fn begin(&mut self, residency: &Residency, pool: &mut GeometryPool) {
        for c in residency.take_evicted() {
            pool.evict(c);
        }
        self.standing.release(residency, pool);
    }

    /// The frame's geometry from `residency`, stand-ins made from `scene`'s
    /// chunk boxes; every view of the frame draws through it.
    pub fn source<'a>(&self, residency: &'a Residency, scene: &'a Scene) -> FrameSource<'a> {
        if self.stand_ins {
            FrameSource::StandIns(StandInSource::new(residency, scene))
        } else {
            FrameSource::Resident(ResidentSource::new(residency, scene.chunks().len()))
        }
    }

    /// After a frame: `stood_in` got stand-ins in the pool
    /// ([`FrameSource::stood_in`]), `drawn` are the chunks of the drawn
    /// chunk instances the misses are counted over and `not_resident` the
    /// draws that had nothing to draw.
    pub fn end(
        &mut self,
        stood_in: Vec<ChunkId>,
        drawn: impl IntoIterator<Item = ChunkId>,
        not_resident: u64,
    ) -> FrameMisses {
        self.standing.note(stood_in);
        FrameMisses {
            holes: not_resident,
            stand_ins: drawn
                .into_iter()
                .filter(|&c| self.standing.is_standing(c))
                .count() as u64,
        }
    }

    /// How many stand-ins the pool holds.
    pub fn stand_ins_held(&self) -> usize {
        self.standing.count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stand_in_is_its_box_with_outward_faces() {
        let b = Aabb3f {
            min: Vec3::new(-2.0, 1.0, 10.0),
            max: Vec3::new(3.5, 1.25, 40.0),
        };
        let g = BoxGeometry::new(&b);
        assert_eq!((g.positions.len(), g.indices.len()), (24, 36));
        // It fills the chunk's box exactly (the renderer's tree boxes stay true).
        assert_eq!(Aabb3f::from_points(g.positions.iter().copied()), b);
        let centre = (b.min + b.max) * 0.5;
        for t in g.indices.chunks_exact(3) {
            let [p, q, r] = [0, 1, 2].map(|k| g.positions[t[k] as usize]);
            let n = g.normals[t[0] as usize];
            assert!(t.iter().all(|&i| g.normals[i as usize] == n), "flat faces");
            // Counter-clockwise seen from outside: the winding's normal is the
            // face normal, and it points away from the box's centre.
            let winding = (q - p).cross(r - p);
            assert!(winding.dot(n) > 0.0, "{t:?}");
            assert!((p - centre).dot(n) > 0.0, "{t:?}");
        }
    }
}
