//! The file layout: a header, segments, and the table of contents, and the
//! checks that make any byte string either a valid layout or an error.
//!
//! ```text
//! 0        header (64 bytes)
//! 64       segment, segment, ...  each at a 16-byte boundary, zero padded to
//!          the next one; a chunk's geometry, one skeleton, and optionally
//!          blob sets (`BlobSet`): one far-field index with a blob per
//!          far-field cell, one level-of-detail index with a blob per node;
//!          the nodes' properties when some node has one
//! toc      table of contents: one 32-byte entry per segment (last in the file,
//!          so a streaming writer needs no second pass)
//! ```
//!
//! Every byte is covered by a checksum: the header by its own, the table by the
//! one in the header, each segment (with its padding) by the one in its entry.
//! Segments must tile the space between header and table exactly, so no byte is
//! outside all of them.

use std::path::Path;

use bytemuck::{Pod, Zeroable};
use xxhash_rust::xxh3::xxh3_64;

use crate::error::StoreError;

#[cfg(target_endian = "big")]
compile_error!(
    "dmu stores are little-endian and read by casting; big-endian hosts are not supported"
);

/// The first eight bytes of every store.
pub(crate) const MAGIC: [u8; 8] = *b"DMUSTORE";
/// The format version this build writes and reads.
///
/// Version 2 (issue 14) holds the skeleton as flat arrays (see `skeleton.rs`);
/// version 1 stores (a bincode skeleton) are refused with a request to
/// re-import the model. Version 3 adds to each mesh record whether the mesh
/// bounds solids with outward windings (the renderer culls their back faces);
/// version 2 stores are refused the same way, since that is known only from
/// the geometry.
///
/// Far-field segments (an index and one blob per cell, kinds 3 and 4) were
/// added within version 2 rather than as version 3: a store without them is
/// byte for byte what it was, and a version-2 reader from before them refuses
/// a store that has them with "segment N has unknown kind 3" (or 4) rather
/// than misreading it, which is acceptable for an optional addition. The
/// level-of-detail hierarchy's segments (kinds 5 and 6) are such a set too,
/// and so are the nodes' properties (kind 7, issue 44).
///
/// Version 4 (issue 42) stores each chunk's simplified levels after its
/// indices (`geometry.rs`), made at import rather than on every upload.
/// Version 3 stores are still read, with the version-3 chunk layout: their
/// chunks have no levels (the renderer computes them on upload, as it did),
/// and rewriting one (saving edits, far fields) adds them.
pub const FORMAT_VERSION: u32 = 4;
/// The oldest format version this build reads.
pub const OLDEST_READABLE_VERSION: u32 = 3;
/// Written as a native `u32` by a little-endian writer: reads back swapped on a
/// big-endian one.
const BYTE_ORDER_MARK: u32 = 0x0102_0304;
/// Segment alignment: enough for any array cast from the mapping.
pub(crate) const ALIGN: u64 = 16;
pub(crate) const HEADER_LEN: u64 = size_of::<Header>() as u64;
const ENTRY_LEN: u64 = size_of::<TocEntry>() as u64;

/// Segment kinds.
pub(crate) const KIND_SKELETON: u32 = 1;
pub(crate) const KIND_CHUNK: u32 = 2;
/// The far-field index: opaque bytes (the caller's encoding), id 0, at most one.
pub(crate) const KIND_FAR_INDEX: u32 = 3;
/// One far-field cell's blob: opaque bytes, id the cell number (exactly `0..n`,
/// once each, like chunks); only in a store with a far-field index.
pub(crate) const KIND_FAR_CELL: u32 = 4;
/// The level-of-detail hierarchy's index ([`BlobSet::Lod`]): like kind 3.
pub(crate) const KIND_LOD_INDEX: u32 = 5;
/// One level-of-detail node's blob: like kind 4.
pub(crate) const KIND_LOD_NODE: u32 = 6;
/// The nodes' properties ([`dmu_scene::Properties`]'s encoding), id 0, at
/// most one; absent when no node has a property.
pub(crate) const KIND_PROPERTIES: u32 = 7;

/// The sets of opaque blobs a store keeps beside its geometry, each an index
/// (id 0, at most one) and blobs numbered `0..n` (only beside an index), in
/// the caller's encoding: the store checks their bytes, not their meaning.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BlobSet {
    /// Far fields: one blob per viewpoint cell (`dmu_app::farfield`).
    FarField,
    /// The level-of-detail hierarchy: one blob per tree node's merged,
    /// simplified proxy (`dmu_app::lod`).
    Lod,
}

impl BlobSet {
    /// Every set, in the order a rewrite copies them.
    pub const ALL: [BlobSet; 2] = [BlobSet::FarField, BlobSet::Lod];

    /// The segment kinds of its index and of its blobs.
    pub(crate) fn kinds(self) -> (u32, u32) {
        match self {
            BlobSet::FarField => (KIND_FAR_INDEX, KIND_FAR_CELL),
            BlobSet::Lod => (KIND_LOD_INDEX, KIND_LOD_NODE),
        }
    }

    /// What its index is called in errors ("far-field index").
    pub fn index_name(self) -> &'static str {
        match self {
            BlobSet::FarField => "far-field index",
            BlobSet::Lod => "level-of-detail index",
        }
    }

    /// What one blob is called in errors ("far-field cell").
    pub fn blob_name(self) -> &'static str {
        match self {
            BlobSet::FarField => "far-field cell",
            BlobSet::Lod => "level-of-detail node",
        }
    }
}

/// One blob set's segments in a store.
#[derive(Debug, Default)]
pub(crate) struct BlobSegments {
    /// The index; `None` when the store has none of this set.
    pub index: Option<TocEntry>,
    /// Indexed by blob number (the ids are exactly `0..n`); empty without an
    /// index.
    pub blobs: Vec<TocEntry>,
}

/// The file header. Little-endian like everything in the file.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct Header {
    /// [`MAGIC`].
    pub magic: [u8; 8],
    /// [`FORMAT_VERSION`]; checked before anything else after the magic, so a
    /// later version may change all that follows.
    pub version: u32,
    /// [`BYTE_ORDER_MARK`].
    pub byte_order: u32,
    /// Size of this header (64).
    pub header_len: u32,
    /// Segment alignment ([`ALIGN`]).
    pub align: u32,
    /// Where the table of contents starts (aligned; the table ends the file).
    pub toc_offset: u64,
    /// Entries in the table.
    pub toc_entries: u64,
    /// xxh3-64 of the table's bytes.
    pub toc_checksum: u64,
    /// Zero.
    pub reserved: u64,
    /// xxh3-64 of the 56 bytes before it.
    pub header_checksum: u64,
}
const _: () = assert!(size_of::<Header>() == 64);

/// One segment's entry in the table of contents.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable, PartialEq, Eq)]
pub(crate) struct TocEntry {
    /// The chunk id for chunk geometry, the cell number for a far-field cell; 0
    /// for the skeleton and the far-field index.
    pub id: u32,
    /// [`KIND_SKELETON`], [`KIND_CHUNK`], [`KIND_FAR_INDEX`] or [`KIND_FAR_CELL`].
    pub kind: u32,
    /// Start in the file, a multiple of [`ALIGN`].
    pub offset: u64,
    /// Payload bytes (the zero padding after it is not counted).
    pub length: u64,
    /// xxh3-64 of the payload and its padding.
    pub checksum: u64,
}
const _: () = assert!(size_of::<TocEntry>() == 32);

impl TocEntry {
    /// The payload with its padding: what the checksum covers. For an entry
    /// that [`parse`] validated (its segment lies within the file); a length
    /// within 15 of `u64::MAX` overflows.
    pub fn padded_len(&self) -> u64 {
        self.length.next_multiple_of(ALIGN)
    }
}

impl Header {
    pub fn new(toc_offset: u64, toc: &[TocEntry]) -> Self {
        let mut header = Header {
            magic: MAGIC,
            version: FORMAT_VERSION,
            byte_order: BYTE_ORDER_MARK,
            header_len: HEADER_LEN as u32,
            align: ALIGN as u32,
            toc_offset,
            toc_entries: toc.len() as u64,
            toc_checksum: xxh3_64(bytemuck::cast_slice(toc)),
            reserved: 0,
            header_checksum: 0,
        };
        header.header_checksum = header_checksum(bytemuck::bytes_of(&header));
        header
    }
}

fn header_checksum(header: &[u8]) -> u64 {
    xxh3_64(&header[..HEADER_LEN as usize - 8])
}

/// A validated layout: where the skeleton, each chunk's geometry and the far
/// fields are.
#[derive(Debug)]
pub(crate) struct Layout {
    /// The file's format version, [`OLDEST_READABLE_VERSION`] to
    /// [`FORMAT_VERSION`].
    pub version: u32,
    pub skeleton: TocEntry,
    /// The nodes' properties, when some node has one.
    pub properties: Option<TocEntry>,
    /// Indexed by chunk id (the ids are exactly `0..n`).
    pub chunks: Vec<TocEntry>,
    /// Each [`BlobSet`]'s segments, in [`BlobSet::ALL`]'s order.
    pub blobs: [BlobSegments; 2],
}

impl Layout {
    /// The segments of `set`.
    pub fn blob_set(&self, set: BlobSet) -> &BlobSegments {
        &self.blobs[set as usize]
    }
}

/// What a file that is not a store looks like, for the error message.
fn describe(bytes: &[u8]) -> String {
    let start = &bytes[..bytes.len().min(8)];
    if bytes.is_empty() {
        "an empty file".into()
    } else if start.starts_with(b"glTF") {
        "binary glTF (.glb); make a store from it with `dmu import`".into()
    } else if start.trim_ascii_start().starts_with(b"{") {
        "JSON (a .gltf file? make a store from it with `dmu import`)".into()
    } else {
        format!("something else (it starts with {start:02x?})")
    }
}

/// Checks the header and the table of contents of `bytes` (a whole file) and
/// returns the layout; every offset and length is validated before use.
pub(crate) fn parse(file: &impl ReadAt, path: &Path) -> Result<Layout, StoreError> {
    let len = file.len().map_err(|source| io_error(path, source))?;
    let bytes = &file
        .read_at_most(0, HEADER_LEN)
        .map_err(|source| io_error(path, source))?[..];
    let corrupt = |what: String| StoreError::Corrupt {
        path: path.to_owned(),
        what,
    };
    if !bytes.is_empty() && bytes.len() < MAGIC.len() && MAGIC.starts_with(bytes) {
        return Err(StoreError::Truncated {
            path: path.to_owned(),
            what: "the header".into(),
            expected: HEADER_LEN,
            actual: len,
        });
    }
    if bytes.len() < MAGIC.len() || bytes[..MAGIC.len()] != MAGIC {
        return Err(StoreError::NotAStore {
            path: path.to_owned(),
            found: describe(bytes),
        });
    }
    let Some(head) = bytes.get(..HEADER_LEN as usize) else {
        return Err(StoreError::Truncated {
            path: path.to_owned(),
            what: "the header".into(),
            expected: HEADER_LEN,
            actual: len,
        });
    };
    let header: Header = bytemuck::pod_read_unaligned(head);
    if !(OLDEST_READABLE_VERSION..=FORMAT_VERSION).contains(&header.version) {
        return Err(StoreError::UnsupportedVersion {
            path: path.to_owned(),
            found: header.version,
            supported: FORMAT_VERSION,
        });
    }
    if header.byte_order != BYTE_ORDER_MARK {
        return Err(if header.byte_order == BYTE_ORDER_MARK.swap_bytes() {
            StoreError::ByteOrder {
                path: path.to_owned(),
            }
        } else {
            corrupt(format!(
                "byte order mark {:#010x} is neither order",
                header.byte_order
            ))
        });
    }
    let computed = header_checksum(head);
    if computed != header.header_checksum {
        return Err(StoreError::Checksum {
            path: path.to_owned(),
            segment: "the header".into(),
            stored: header.header_checksum,
            computed,
        });
    }
    if u64::from(header.header_len) != HEADER_LEN || u64::from(header.align) != ALIGN {
        return Err(corrupt(format!(
            "header length {} or alignment {} is not this version's",
            header.header_len, header.align
        )));
    }
    let toc_end = header
        .toc_entries
        .checked_mul(ENTRY_LEN)
        .and_then(|l| l.checked_add(header.toc_offset))
        .ok_or_else(|| corrupt("table of contents size overflows".into()))?;
    if toc_end > len {
        return Err(StoreError::Truncated {
            path: path.to_owned(),
            what: "the table of contents".into(),
            expected: toc_end,
            actual: len,
        });
    }
    if toc_end < len {
        return Err(corrupt(format!(
            "{} bytes after the table of contents",
            len - toc_end
        )));
    }
    if header.toc_offset < HEADER_LEN || !header.toc_offset.is_multiple_of(ALIGN) {
        return Err(corrupt(format!(
            "table of contents at {} is misplaced",
            header.toc_offset
        )));
    }
    let toc_bytes = &file
        .read_exact_at(header.toc_offset, toc_end - header.toc_offset)
        .map_err(|source| read_error(path, source, "the table of contents", toc_end, len))?[..];
    let computed = xxh3_64(toc_bytes);
    if computed != header.toc_checksum {
        return Err(StoreError::Checksum {
            path: path.to_owned(),
            segment: "the table of contents".into(),
            stored: header.toc_checksum,
            computed,
        });
    }
    let entries: Vec<TocEntry> = toc_bytes
        .chunks_exact(ENTRY_LEN as usize)
        .map(bytemuck::pod_read_unaligned)
        .collect();
    let mut layout = validate_entries(&entries, header.toc_offset).map_err(corrupt)?;
    layout.version = header.version;
    Ok(layout)
}

/// Entries must tile `[HEADER_LEN, toc_offset)` in order, name one skeleton,
/// chunk ids `0..n` once each, and per blob set at most one index (id 0) and
/// blob ids `0..m` once each, only beside an index.
fn validate_entries(entries: &[TocEntry], toc_offset: u64) -> Result<Layout, String> {
    let mut by_offset: Vec<&TocEntry> = entries.iter().collect();
    by_offset.sort_by_key(|e| e.offset);
    let mut at = HEADER_LEN;
    for e in &by_offset {
        if e.offset != at {
            return Err(format!(
                "segment {} of kind {} starts at {}, expected {at}",
                e.id, e.kind, e.offset
            ));
        }
        // Checked: a length within 15 of `u64::MAX` overflows when padded
        // (`padded_len` is for validated entries only).
        at = e
            .length
            .checked_next_multiple_of(ALIGN)
            .and_then(|padded| e.offset.checked_add(padded))
            .filter(|&end| end <= toc_offset)
            .ok_or_else(|| {
                format!(
                    "segment {} of kind {} ({} bytes at {}) runs into the table of contents",
                    e.id, e.kind, e.length, e.offset
                )
            })?;
    }
    if at != toc_offset {
        return Err(format!("bytes {at}..{toc_offset} belong to no segment"));
    }
    let mut skeleton = None;
    let mut properties = None;
    let mut chunks = Dense::new(entries, KIND_CHUNK, "chunk");
    let mut sets = BlobSet::ALL.map(|set| {
        let (_, blob_kind) = set.kinds();
        (None, Dense::new(entries, blob_kind, set.blob_name()))
    });
    // Blobs after everything else, so that a table's error does not depend
    // on the order its writer put the segments in.
    let is_blob = |kind: u32| BlobSet::ALL.iter().any(|s| s.kinds().1 == kind);
    let (blob_entries, others): (Vec<&TocEntry>, Vec<&TocEntry>) =
        entries.iter().partition(|e| is_blob(e.kind));
    for e in others.into_iter().chain(blob_entries) {
        match e.kind {
            KIND_SKELETON if skeleton.is_none() => skeleton = Some(*e),
            KIND_SKELETON => return Err("two skeleton segments".into()),
            KIND_PROPERTIES if e.id != 0 => {
                return Err(format!("the properties segment has id {}, not 0", e.id));
            }
            KIND_PROPERTIES if properties.is_none() => properties = Some(*e),
            KIND_PROPERTIES => return Err("two properties segments".into()),
            KIND_CHUNK => chunks.insert(e)?,
            kind => {
                let Some(set) = BlobSet::ALL.into_iter().find(|s| {
                    let (index, blob) = s.kinds();
                    kind == index || kind == blob
                }) else {
                    return Err(format!("segment {} has unknown kind {kind}", e.id));
                };
                let (index, blobs) = &mut sets[set as usize];
                match e.kind == set.kinds().0 {
                    true if e.id != 0 => {
                        return Err(format!("the {} has id {}, not 0", set.index_name(), e.id));
                    }
                    true if index.is_none() => *index = Some(*e),
                    true => return Err(format!("two {} segments", set.index_name())),
                    false => blobs.insert(e)?,
                }
            }
        }
    }
    for (set, (index, blobs)) in BlobSet::ALL.iter().zip(&sets) {
        if index.is_none() && !blobs.slots.is_empty() {
            return Err(format!(
                "{} {} segments but no {}",
                blobs.slots.len(),
                set.blob_name(),
                set.index_name()
            ));
        }
    }
    Ok(Layout {
        version: FORMAT_VERSION,
        skeleton: skeleton.ok_or("no skeleton segment")?,
        properties,
        chunks: chunks.into_entries(),
        blobs: sets.map(|(index, blobs)| BlobSegments {
            index,
            blobs: blobs.into_entries(),
        }),
    })
}

/// Segments of one kind whose ids must be exactly `0..n`, once each.
struct Dense {
    slots: Vec<Option<TocEntry>>,
    /// What one is called in errors ("chunk", "far-field cell").
    name: &'static str,
}

impl Dense {
    /// Room for every entry of `kind` in `entries`.
    fn new(entries: &[TocEntry], kind: u32, name: &'static str) -> Self {
        let count = entries.iter().filter(|e| e.kind == kind).count();
        Self {
            slots: vec![None; count],
            name,
        }
    }

    /// Puts `e` at its id; an id out of range or seen before is an error.
    fn insert(&mut self, e: &TocEntry) -> Result<(), String> {
        let count = self.slots.len();
        match self.slots.get_mut(e.id as usize) {
            Some(slot @ None) => {
                *slot = Some(*e);
                Ok(())
            }
            Some(Some(_)) => Err(format!("{} #{} has two segments", self.name, e.id)),
            None => Err(format!(
                "{} #{} is out of range ({count} {} segments)",
                self.name, e.id, self.name
            )),
        }
    }

    /// The entries by id: with as many slots as entries, each one filled once,
    /// so none is missing.
    fn into_entries(self) -> Vec<TocEntry> {
        self.slots.into_iter().flatten().collect()
    }
}

/// A segment's bytes (payload only), read from the file and checked against
/// its checksum. Read, not mapped: a file truncated or rewritten by another
/// process gives an error here, never a `SIGBUS`.
pub(crate) fn verified(
    file: &impl ReadAt,
    entry: &TocEntry,
    name: impl FnOnce() -> String,
    path: &Path,
) -> Result<Vec<u8>, StoreError> {
    let end = entry.offset + entry.padded_len();
    let segment = name();
    let mut padded = file
        .read_exact_at(entry.offset, entry.padded_len())
        .map_err(|source| {
            let actual = file.len().unwrap_or(0);
            read_error(path, source, &segment, end, actual)
        })?;
    let computed = xxh3_64(&padded);
    if computed != entry.checksum {
        return Err(StoreError::Checksum {
            path: path.to_owned(),
            segment,
            stored: entry.checksum,
            computed,
        });
    }
    padded.truncate(entry.length as usize);
    Ok(padded)
}

/// Recomputes every checksum in `bytes`, a whole store file however damaged
/// or crafted, so that only the checks behind the checksums can refuse it:
/// first each segment's (in its table-of-contents entry), then the table's
/// and the header's (in the header). A checksum whose bytes lie outside
/// `bytes` (a short file, a table or segment past the end, an offset or length
/// that overflows) is left as it is; no input makes it panic.
///
/// For fuzzing and for tests that craft stores: a fuzzer's mutated bytes
/// resealed reach the table's and the skeleton's checks and the geometry
/// decoder, where unsealed they would nearly all fail a checksum first.
/// A store written by dmu comes back byte for byte the same.
///
/// ```
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("grid.dmu");
/// dmu_store::write_scene(&dmu_samples::grid(1, 10.0, 4.0, 8), &path, Default::default()).unwrap();
/// let written = std::fs::read(&path).unwrap();
/// let mut bytes = written.clone();
/// dmu_store::reseal(&mut bytes);
/// assert_eq!(bytes, written);
/// bytes[64] ^= 0xff; // the first chunk's geometry
/// let chunk = dmu_scene::ChunkId::from_index(0);
/// let read = |bytes: &[u8]| {
///     std::fs::write(&path, bytes).unwrap();
///     dmu_store::Store::open(&path).unwrap().chunk_geometry(chunk)
/// };
/// assert!(matches!(read(&bytes), Err(dmu_store::StoreError::Checksum { .. })));
/// dmu_store::reseal(&mut bytes);
/// // The checksum holds: the decoder sees the byte.
/// assert!(!matches!(read(&bytes), Err(dmu_store::StoreError::Checksum { .. })));
/// ```
pub fn reseal(bytes: &mut [u8]) {
    let Some(head) = bytes.get(..HEADER_LEN as usize) else {
        return;
    };
    let mut header: Header = bytemuck::pod_read_unaligned(head);
    let file_len = bytes.len() as u64;
    let within = |start: u64, len: Option<u64>| {
        let end = start.checked_add(len?)?;
        (end <= file_len).then_some(start as usize..end as usize)
    };
    if let Some(toc) = within(header.toc_offset, header.toc_entries.checked_mul(ENTRY_LEN)) {
        for at in toc.clone().step_by(ENTRY_LEN as usize) {
            let slot = at..at + ENTRY_LEN as usize;
            let mut entry: TocEntry = bytemuck::pod_read_unaligned(&bytes[slot.clone()]);
            let padded = entry.length.checked_next_multiple_of(ALIGN);
            if let Some(segment) = within(entry.offset, padded) {
                entry.checksum = xxh3_64(&bytes[segment]);
                bytes[slot].copy_from_slice(bytemuck::bytes_of(&entry));
            }
        }
        header.toc_checksum = xxh3_64(&bytes[toc]);
    }
    bytes[..HEADER_LEN as usize].copy_from_slice(bytemuck::bytes_of(&header));
    header.header_checksum = header_checksum(bytes);
    bytes[..HEADER_LEN as usize].copy_from_slice(bytemuck::bytes_of(&header));
}

/// Positioned reads of a file (`pread`), so concurrent readers share one handle.
pub(crate) trait ReadAt {
    /// The file's current length.
    fn len(&self) -> std::io::Result<u64>;
    /// Exactly `len` bytes at `offset`; `UnexpectedEof` when the file is shorter.
    fn read_exact_at(&self, offset: u64, len: u64) -> std::io::Result<Vec<u8>>;
    /// Up to `len` bytes at `offset` (fewer at the end of the file).
    fn read_at_most(&self, offset: u64, len: u64) -> std::io::Result<Vec<u8>>;
    /// Fills `buf` from `offset`; `UnexpectedEof` when the file is shorter.
    fn read_into(&self, offset: u64, buf: &mut [u8]) -> std::io::Result<()>;
}

impl ReadAt for std::fs::File {
    fn len(&self) -> std::io::Result<u64> {
        Ok(self.metadata()?.len())
    }

    fn read_exact_at(&self, offset: u64, len: u64) -> std::io::Result<Vec<u8>> {
        let mut buf = vec![0; usize::try_from(len).map_err(std::io::Error::other)?];
        self.read_into(offset, &mut buf)?;
        Ok(buf)
    }

    fn read_into(&self, offset: u64, buf: &mut [u8]) -> std::io::Result<()> {
        std::os::unix::fs::FileExt::read_exact_at(self, buf, offset)
    }

    fn read_at_most(&self, offset: u64, len: u64) -> std::io::Result<Vec<u8>> {
        let mut buf = vec![0; usize::try_from(len).map_err(std::io::Error::other)?];
        let mut filled = 0;
        while filled < buf.len() {
            match std::os::unix::fs::FileExt::read_at(
                self,
                &mut buf[filled..],
                offset + filled as u64,
            ) {
                Ok(0) => break,
                Ok(n) => filled += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        buf.truncate(filled);
        Ok(buf)
    }
}

fn io_error(path: &Path, source: std::io::Error) -> StoreError {
    StoreError::Io {
        path: path.to_owned(),
        source,
    }
}

/// A failed read of `what`, which ends at byte `end`: a file that became shorter
/// than its table of contents says (truncated while open) is `Truncated`.
pub(crate) fn read_error(
    path: &Path,
    source: std::io::Error,
    what: &str,
    end: u64,
    actual: u64,
) -> StoreError {
    if source.kind() == std::io::ErrorKind::UnexpectedEof {
        StoreError::Truncated {
            path: path.to_owned(),
            what: what.to_owned(),
            expected: end,
            actual,
        }
    } else {
        io_error(path, source)
    }
}
