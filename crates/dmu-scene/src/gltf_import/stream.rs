//! Streaming import: meshes are decoded, chunked and handed to the caller a batch
//! at a time, so peak memory is set by the batch size, not by the model.
//!
//! The GLB file and external buffer files are memory-mapped rather than read, and
//! mapped anew for each batch: the file pages a batch touched leave the process's
//! resident set when its mapping is dropped. Data-URI buffers are decoded into
//! memory once (they live inside the JSON, which is parsed whole anyway).

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
use crate::scene::Scene;

/// Settings of [`import_gltf_streaming`].
#[derive(Clone, Copy)]
pub struct StreamOptions<'a> {
    /// Maximum triangles per chunk.
    pub chunk_triangles: u32,
    /// Estimated bytes of decoding work in flight at once: meshes are decoded in
    /// parallel batches whose estimated working sets (file pages, decoded arrays,
    /// chunking scratch, chunked copy) add up to at most this. A mesh larger than
    /// the whole budget is still decoded, alone.
    pub batch_bytes: u64,
    /// Called with (meshes done, meshes total) after each mesh is handed over.
    pub progress: Option<&'a (dyn Fn(usize, usize) + Sync)>,
}

impl std::fmt::Debug for StreamOptions<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StreamOptions")
            .field("chunk_triangles", &self.chunk_triangles)
            .field("batch_bytes", &self.batch_bytes)
            .finish_non_exhaustive()
    }
}

/// Imports a .glb or .gltf file mesh by mesh. Each used mesh, chunked, goes to
/// `sink` with the id it has in the returned scene, in id order, and is dropped
/// after; the returned scene has the whole structure (nodes, parts, materials,
/// transforms, chunk tables) with the geometry not loaded (see [`crate::Mesh`]).
/// Loading the sunk geometry back into it gives what [`crate::import_gltf`]
/// returns for the same file.
///
/// Memory: the parsed JSON, the scene's structure, and one batch (see
/// [`StreamOptions::batch_bytes`]).
pub fn import_gltf_streaming<E: From<ImportError>>(
    path: &Path,
    options: &StreamOptions<'_>,
    sink: &mut dyn FnMut(MeshId, ChunkedMesh) -> Result<(), E>,
) -> Result<(Scene, ImportReport), E> {
    let io = |source| ImportError::Io {
        path: path.to_owned(),
        source,
    };
    let file = crate::atomic::open_regular_file(path).map_err(io)?;
    let (doc, blob) = {
        let map = map_file(&file).map_err(io)?;
        let (json_bytes, blob) = super::buffers::split_container(&map)?;
        // Where the BIN chunk sits, to slice it out of each batch's mapping.
        let blob = blob.map(|b| {
            let start = b.as_ptr() as usize - map.as_ptr() as usize;
            start..start + b.len()
        });
        (Document::parse(json_bytes)?, blob)
    };
    let root = &doc.root;
    let sources = buffer_sources(root, blob, path.parent());
    let name = path
        .file_stem()
        .map_or_else(|| "scene".into(), |s| s.to_string_lossy().into_owned());
    let (mut builder, default_material) = doc.start(&name, options.chunk_triangles);

    let used = doc.used_meshes()?;
    let total = used.iter().filter(|&&u| u).count();
    let mut report = ImportReport {
        unused_meshes: used.len() - total,
        ..ImportReport::default()
    };
    let mut mesh_ids = vec![None; root.meshes.len()];
    let mut done = 0;
    for batch in batches(root, &used, options.batch_bytes) {
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
            let id = builder.add_unloaded_mesh(
                chunked.name.clone(),
                chunked.chunks.clone(),
                chunked.degenerate_triangles,
            );
            mesh_ids[m] = Some(id);
            sink(id, chunked)?;
            done += 1;
            if let Some(progress) = options.progress {
                progress(done, total);
            }
        }
    }
    doc.add_nodes(&mesh_ids, &mut builder)?;
    Ok((builder.finish(), report))
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
        bytes += PER_VERTEX * positions + PER_INDEX * indices;
    }
    bytes
}

/// The used meshes in id order, cut into batches of at most `batch_bytes`
/// estimated working set (a larger mesh alone).
fn batches(root: &json::Root, used: &[bool], batch_bytes: u64) -> Vec<Vec<usize>> {
    let mut out: Vec<Vec<usize>> = Vec::new();
    let mut current = Vec::new();
    let mut bytes = 0;
    for (m, mesh) in root.meshes.iter().enumerate() {
        if !used[m] {
            continue;
        }
        let need = mesh_working_set(root, mesh);
        if !current.is_empty() && bytes + need > batch_bytes {
            out.push(std::mem::take(&mut current));
            bytes = 0;
        }
        current.push(m);
        bytes += need;
    }
    if !current.is_empty() {
        out.push(current);
    }
    out
}
