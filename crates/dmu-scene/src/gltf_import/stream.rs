//! Streaming import: the JSON is read as a stream (nodes straight into flat
//! arrays, never a document tree of them), and meshes are decoded, chunked and
//! handed to the caller a batch at a time, so peak memory is set by the
//! structure's flat arrays and the batch size, not by the model.
//!
//! The GLB file and external buffer files are memory-mapped rather than read, and
//! mapped anew for each batch: the file pages a batch touched leave the process's
//! resident set when its mapping is dropped. The JSON is read through a small
//! buffer, not the mapping, so its pages never count. Data-URI buffers are
//! decoded into memory once.

use std::borrow::Cow;
use std::fs::File;
use std::ops::Range;
use std::path::{Path, PathBuf};

use gltf::json::{self, mesh::Mode, mesh::Semantic, validation::Checked};
use memmap2::Mmap;
use rayon::prelude::*;

use super::accessor::Data;
use super::buffers::{Bytes, buffer_file, decode_data_uri, is_meshopt_fallback, resolve_views};
use super::{Document, ImportReport, decode_mesh};
use crate::chunking::ChunkedMesh;
use crate::error::ImportError;
use crate::ids::MeshId;
use crate::structure::{Structure, StructureBuilder};

/// Settings of [`import_gltf_streaming`].
#[derive(Clone, Copy)]
pub struct StreamOptions<'a> {
    /// Maximum triangles per chunk.
    pub chunk_triangles: u32,
    /// Peak memory to stay within. Once the JSON is read, what the structure
    /// holds (see [`Streamed::fixed_bytes`]) is taken off; decoding batches get
    /// half of the rest, the other half is headroom for the allocator and the
    /// caller's writer.
    pub memory_budget_bytes: u64,
    /// The smallest batch, whatever the budget leaves.
    pub min_batch_bytes: u64,
    /// Called with (meshes done, meshes total) after each mesh is handed over.
    pub progress: Option<&'a (dyn Fn(usize, usize) + Sync)>,
}

impl std::fmt::Debug for StreamOptions<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StreamOptions")
            .field("chunk_triangles", &self.chunk_triangles)
            .field("memory_budget_bytes", &self.memory_budget_bytes)
            .field("min_batch_bytes", &self.min_batch_bytes)
            .finish_non_exhaustive()
    }
}

/// What [`import_gltf_streaming`] made.
#[derive(Debug)]
pub struct Streamed {
    /// The scene's structure (nodes, parts, materials, transforms, chunk tables).
    pub structure: Structure,
    /// What the import skipped or repaired.
    pub report: ImportReport,
    /// Estimated bytes of decoding work each batch was allowed (see
    /// [`StreamOptions::memory_budget_bytes`]).
    pub batch_bytes: u64,
    /// Estimated bytes held beside the batches: the nodes' flat arrays (counted)
    /// and the typed JSON of everything else (meshes, accessors, materials;
    /// estimated at ten times its JSON).
    pub fixed_bytes: u64,
    /// The most bytes the structure's arrays held at once (counted from their
    /// capacities: the file's nodes and the structure made from them).
    pub structure_peak_bytes: u64,
}

/// Imports a .glb or .gltf file mesh by mesh. Each used mesh, chunked, goes to
/// `sink` with the id it has in the returned structure, in id order, and is
/// dropped after; the returned structure has the whole scene but its geometry.
/// Loading the sunk geometry into it gives what [`crate::import_gltf`] returns
/// for the same file.
///
/// Memory: the nodes as flat arrays (about 130 bytes a node and its name, then
/// as much again for the structure made from them), the other JSON members
/// typed, and one batch (see [`StreamOptions::memory_budget_bytes`]).
pub fn import_gltf_streaming<E: From<ImportError>>(
    path: &Path,
    options: &StreamOptions<'_>,
    sink: &mut dyn FnMut(MeshId, ChunkedMesh) -> Result<(), E>,
) -> Result<Streamed, E> {
    let io = |source| ImportError::Io {
        path: path.to_owned(),
        source,
    };
    let file = crate::atomic::open_regular_file(path).map_err(io)?;
    let (json, blob) = {
        let map = map_file(&file).map_err(io)?;
        let (json_bytes, blob) = super::buffers::split_container(&map)?;
        // Where the JSON and the BIN chunk sit, as ranges of the file.
        let range = |b: &[u8]| {
            let start = b.as_ptr() as usize - map.as_ptr() as usize;
            start..start + b.len()
        };
        (range(json_bytes), blob.map(range))
    };
    let at = std::cell::Cell::new(json.start as u64);
    let reader = std::io::BufReader::with_capacity(
        1 << 16,
        ReadRange {
            file: &file,
            at: &at,
            end: json.end as u64,
        },
    );
    let doc = Document::parse_stream(reader, &|| at.get())?;
    let root = &doc.root;
    let sources = buffer_sources(root, blob, path.parent());
    let name = path
        .file_stem()
        .map_or_else(|| "scene".into(), |s| s.to_string_lossy().into_owned());
    let mut materials = Vec::new();
    let (name, default_material) =
        doc.materials(&name, &mut |n, c| materials.push((n.to_owned(), c)));
    let mut builder = StructureBuilder::new(&name);
    for (n, c) in &materials {
        builder.structure.add_material(n, *c);
    }

    let nodes_bytes = doc.nodes.held_bytes();
    // The typed members other than the nodes: a value tree and typed structs
    // were measured near ten times their JSON.
    let rest_json = (json.len() as u64).saturating_sub(doc.nodes.json_bytes());
    let fixed = nodes_bytes + rest_json.saturating_mul(10);
    let batch_bytes =
        (options.memory_budget_bytes.saturating_sub(fixed) / 2).max(options.min_batch_bytes);

    let used = doc.used_meshes()?;
    let total = used.iter().filter(|&&u| u).count();
    let mut report = ImportReport {
        unused_meshes: used.len() - total,
        ..ImportReport::default()
    };
    let mut mesh_ids = vec![None; root.meshes.len()];
    let mut done = 0;
    for batch in batches(root, &used, batch_bytes) {
        let maps = map_sources(&file, &sources).map_err(io)?;
        let buffers = batch_buffers(&sources, &maps);
        let needed = needed_views(root, &batch);
        let views = resolve_views(root, &buffers, &|v| needed[v]);
        let data = Data {
            root,
            views: &views,
        };
        let decoded: Vec<(ChunkedMesh, ImportReport)> = batch
            .par_iter()
            .map(|&m| {
                decode_mesh(
                    &data,
                    m,
                    &root.meshes[m],
                    default_material,
                    options.chunk_triangles,
                )
            })
            .collect::<Result<_, ImportError>>()?;
        for (&m, (chunked, r)) in batch.iter().zip(decoded) {
            report.add(&r);
            let id = builder.add_mesh(&chunked);
            mesh_ids[m] = Some(id);
            sink(id, chunked)?;
            done += 1;
            if let Some(progress) = options.progress {
                progress(done, total);
            }
        }
    }
    doc.add_nodes(&mesh_ids, &mut builder, &mut report)?;
    let structure_peak_bytes = nodes_bytes + builder.structure.held_bytes();
    Ok(Streamed {
        structure: builder.structure,
        report,
        batch_bytes,
        fixed_bytes: fixed,
        structure_peak_bytes,
    })
}

/// A byte range of a file, read with positioned reads; `at` is where the next
/// read starts.
struct ReadRange<'a> {
    file: &'a File,
    at: &'a std::cell::Cell<u64>,
    end: u64,
}

impl std::io::Read for ReadRange<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let at = self.at.get();
        let want = buf.len().min((self.end - at) as usize);
        let n = std::os::unix::fs::FileExt::read_at(self.file, &mut buf[..want], at)?;
        self.at.set(at + n as u64);
        Ok(n)
    }
}

/// Maps a whole file read-only.
#[expect(
    unsafe_code,
    reason = "memmap2 cannot promise the file is not changed while mapped; dmu \
              never writes in place a file it reads (it writes a new file and renames)"
)]
fn map_file(file: &File) -> std::io::Result<Mmap> {
    // SAFETY: see the reason above; a file truncated by another process while
    // mapped would fault, as with any mapped reader.
    unsafe { Mmap::map(file) }
}

/// Where a buffer's bytes come from.
enum Source {
    /// A byte range of the GLB file itself (its BIN chunk).
    Blob(Range<usize>),
    /// A file next to the glTF, mapped per batch, and the length the buffer
    /// declares (what is read of it).
    File(PathBuf, usize),
    /// A data URI, decoded once.
    Owned(Vec<u8>),
    /// No bytes (an EXT_meshopt_compression fallback buffer).
    Empty,
    /// Why the buffer cannot be read; raised when an accessor reads it.
    Missing(String),
}

/// The source of every buffer, with the checks `load_buffers` makes.
fn buffer_sources(
    root: &json::Root,
    blob: Option<Range<usize>>,
    base_dir: Option<&Path>,
) -> Vec<Source> {
    root.buffers
        .iter()
        .enumerate()
        .map(|(i, buffer)| {
            let declared = buffer.byte_length.0 as usize;
            let short = |held: usize| {
                Source::Missing(format!(
                    "buffers[{i}] declares {declared} bytes but holds {held}"
                ))
            };
            match buffer.uri.as_deref() {
                None if i == 0 && blob.is_some() => {
                    let range = blob.clone().unwrap_or_default();
                    if range.len() < declared {
                        short(range.len())
                    } else {
                        // Views read at most the declared length (not the padding).
                        Source::Blob(range.start..range.start + declared)
                    }
                }
                None if is_meshopt_fallback(buffer) => Source::Empty,
                None => Source::Missing(format!(
                    "buffers[{i}] has no data (no uri, and no GLB BIN chunk)"
                )),
                Some(uri) if uri.starts_with("data:") => match decode_data_uri(i, uri) {
                    Ok(bytes) if bytes.len() < declared => short(bytes.len()),
                    Ok(mut bytes) => {
                        bytes.truncate(declared);
                        Source::Owned(bytes)
                    }
                    Err(e) => Source::Missing(e),
                },
                Some(uri) => match buffer_file(i, uri, base_dir, declared) {
                    Ok(path) => Source::File(path, declared),
                    Err(e) => Source::Missing(e),
                },
            }
        })
        .collect()
}

/// This batch's mappings: the GLB file (when a buffer is its BIN chunk) and each
/// external buffer file, by source index.
fn map_sources(file: &File, sources: &[Source]) -> std::io::Result<Vec<Option<Mmap>>> {
    sources
        .iter()
        .map(|s| match s {
            Source::Blob(_) => map_file(file).map(Some),
            Source::File(path, _) => map_file(&File::open(path)?).map(Some),
            _ => Ok(None),
        })
        .collect()
}

fn batch_buffers<'a>(sources: &'a [Source], maps: &'a [Option<Mmap>]) -> Vec<Bytes<'a>> {
    sources
        .iter()
        .zip(maps)
        .map(|(source, map)| match (source, map) {
            (Source::Blob(range), Some(map)) => map
                .get(range.clone())
                .map(Cow::Borrowed)
                .ok_or_else(|| "the GLB file changed while being imported".to_owned()),
            (Source::File(_, declared), Some(map)) => map
                .get(..*declared)
                .map(Cow::Borrowed)
                .ok_or_else(|| "a buffer file changed while being imported".to_owned()),
            (Source::Owned(bytes), _) => Ok(Cow::Borrowed(&bytes[..])),
            (Source::Missing(e), _) => Err(e.clone()),
            _ => Ok(Cow::Borrowed(&[][..])),
        })
        .collect()
}

/// The accessors a mesh's decoding reads: POSITION, NORMAL and indices of its
/// triangle primitives.
fn mesh_accessors(mesh: &json::Mesh) -> impl Iterator<Item = usize> + '_ {
    mesh.primitives
        .iter()
        .filter(|p| {
            matches!(
                p.mode,
                Checked::Valid(Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan)
            )
        })
        .flat_map(|p| {
            let attribute = |s| p.attributes.get(&Checked::Valid(s)).map(|a| a.value());
            [
                attribute(Semantic::Positions),
                attribute(Semantic::Normals),
                p.indices.map(|a| a.value()),
            ]
            .into_iter()
            .flatten()
        })
}

/// The buffer views a batch of meshes reads, sparse storage included.
fn needed_views(root: &json::Root, batch: &[usize]) -> Vec<bool> {
    let mut needed = vec![false; root.buffer_views.len()];
    let mut mark = |view: usize| {
        if let Some(n) = needed.get_mut(view) {
            *n = true;
        }
    };
    for &m in batch {
        for a in mesh_accessors(&root.meshes[m]) {
            let Some(acc) = root.accessors.get(a) else {
                continue;
            };
            if let Some(v) = acc.buffer_view {
                mark(v.value());
            }
            if let Some(sparse) = &acc.sparse {
                mark(sparse.indices.buffer_view.value());
                mark(sparse.values.buffer_view.value());
            }
        }
    }
    needed
}

/// Estimated peak bytes to decode and chunk a mesh, from its accessor counts:
/// per vertex its file bytes, the decoded, merged and chunked copies and the
/// chunker's remap tables; per index the same for indices and the chunker's
/// sort keys. Broken references count nothing (decoding reports them).
fn mesh_working_set(root: &json::Root, mesh: &json::Mesh) -> u64 {
    const PER_VERTEX: u64 = 128;
    const PER_INDEX: u64 = 24;
    const PER_MESH: u64 = 4096;
    let count = |a: usize| root.accessors.get(a).map_or(0, |acc| acc.count.0);
    let mut bytes = PER_MESH;
    for prim in &mesh.primitives {
        let positions = prim
            .attributes
            .get(&Checked::Valid(Semantic::Positions))
            .map_or(0, |a| count(a.value()));
        let indices = prim.indices.map_or(positions, |a| count(a.value()));
        // Saturating: a hostile count (up to 2^64 - 1) must not overflow here;
        // decoding refuses it with the accessor's name.
        bytes = bytes
            .saturating_add(PER_VERTEX.saturating_mul(positions))
            .saturating_add(PER_INDEX.saturating_mul(indices));
    }
    bytes
}

/// The used meshes in id order, cut into batches of at most `batch_bytes`
/// estimated working set (a larger mesh alone).
fn batches(root: &json::Root, used: &[bool], batch_bytes: u64) -> Vec<Vec<usize>> {
    let mut out: Vec<Vec<usize>> = Vec::new();
    let mut current = Vec::new();
    let mut bytes = 0u64;
    for (m, mesh) in root.meshes.iter().enumerate() {
        if !used[m] {
            continue;
        }
        let need = mesh_working_set(root, mesh);
        if !current.is_empty() && bytes.saturating_add(need) > batch_bytes {
            out.push(std::mem::take(&mut current));
            bytes = 0;
        }
        current.push(m);
        bytes = bytes.saturating_add(need);
    }
    if !current.is_empty() {
        out.push(current);
    }
    out
}
