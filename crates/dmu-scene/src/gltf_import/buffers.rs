//! Buffer loading: the GLB container, data URIs, external files, and buffer views
//! compressed with EXT_meshopt_compression.

use std::borrow::Cow;
use std::path::{Path, PathBuf};

use base64::Engine as _;
use gltf::json;

use crate::error::ImportError;

/// An `Invalid` error with its description.
pub(super) fn invalid(what: impl Into<String>) -> ImportError {
    ImportError::Invalid { what: what.into() }
}

/// The JSON and the BIN chunk of a file: GLB is split, anything else is JSON.
pub(super) fn split_container(bytes: &[u8]) -> Result<(&[u8], Option<&[u8]>), ImportError> {
    if !bytes.starts_with(b"glTF") {
        return Ok((bytes, None));
    }
    let malformed = |m: &str| ImportError::Malformed {
        message: format!("GLB container: {m}"),
    };
    let word = |at: usize| -> Option<u32> {
        bytes
            .get(at..at + 4)
            .map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]]))
    };
    let version = word(4).ok_or_else(|| malformed("truncated header"))?;
    if version != 2 {
        return Err(malformed(&format!("version {version}, only 2 is glTF 2.0")));
    }
    let length = word(8).ok_or_else(|| malformed("truncated header"))? as usize;
    if length > bytes.len() {
        return Err(malformed(&format!(
            "header says {length} bytes, file has {}",
            bytes.len()
        )));
    }
    let (mut json, mut bin) = (None, None);
    let mut at = 12;
    while at + 8 <= length {
        let (len, kind) = (word(at).unwrap_or(0) as usize, word(at + 4).unwrap_or(0));
        let body = bytes
            .get(at + 8..at + 8 + len)
            .filter(|_| at + 8 + len <= length)
            .ok_or_else(|| malformed(&format!("chunk at byte {at} runs past the end")))?;
        match kind {
            0x4E4F_534A if json.is_none() => json = Some(body),
            0x004E_4942 if bin.is_none() => bin = Some(body),
            _ => {} // Unknown chunks must be ignored (spec 4.4.3.1).
        }
        at += 8 + len.next_multiple_of(4);
    }
    Ok((json.ok_or_else(|| malformed("no JSON chunk"))?, bin))
}

/// A buffer or buffer view's bytes, or why they cannot be had. Errors wait until
/// an accessor the import needs reads them: a file may carry unused broken parts.
pub(super) type Bytes<'a> = Result<Cow<'a, [u8]>, String>;

/// Loads every buffer: the GLB BIN chunk, data URIs and files next to the glTF.
/// Buffers that exist only as an EXT_meshopt_compression fallback are left empty.
pub(super) fn load_buffers<'a>(
    root: &json::Root,
    blob: Option<&'a [u8]>,
    base_dir: Option<&Path>,
) -> Vec<Bytes<'a>> {
    root.buffers
        .iter()
        .enumerate()
        .map(|(i, buffer)| {
            let declared = buffer.byte_length.0 as usize;
            let data: Cow<'a, [u8]> = match buffer.uri.as_deref() {
                None if i == 0 && blob.is_some() => Cow::Borrowed(blob.unwrap_or_default()),
                None if is_meshopt_fallback(buffer) => return Ok(Cow::Borrowed(&[][..])),
                None => {
                    return Err(format!(
                        "buffers[{i}] has no data (no uri, and no GLB BIN chunk)"
                    ));
                }
                Some(uri) if uri.starts_with("data:") => Cow::Owned(decode_data_uri(i, uri)?),
                Some(uri) => {
                    let path = buffer_file(i, uri, base_dir, declared)?;
                    Cow::Owned(read_prefix(&path, declared).map_err(|e| {
                        format!("buffers[{i}]: cannot read {}: {e}", path.display())
                    })?)
                }
            };
            if data.len() < declared {
                return Err(format!(
                    "buffers[{i}] declares {declared} bytes but holds {}",
                    data.len()
                ));
            }
            // What views may read is the declared length, whatever the source
            // holds beyond it (a GLB chunk's padding, a longer data URI).
            Ok(match data {
                Cow::Borrowed(b) => Cow::Borrowed(&b[..declared]),
                Cow::Owned(mut v) => {
                    v.truncate(declared);
                    Cow::Owned(v)
                }
            })
        })
        .collect()
}

/// A base64 data URI's bytes.
pub(super) fn decode_data_uri(i: usize, uri: &str) -> Result<Vec<u8>, String> {
    let (_, payload) = uri
        .split_once(";base64,")
        .ok_or_else(|| format!("buffers[{i}].uri is a data URI without base64"))?;
    base64::engine::general_purpose::STANDARD
        .decode(payload)
        .map_err(|e| format!("buffers[{i}].uri: bad base64: {e}"))
}

/// The file a buffer's URI names, checked before anything is opened: a relative
/// path that stays inside the model's folder (after `..` and symbolic links are
/// resolved), naming a regular file (never a device, pipe or directory) of at
/// least the `byteLength` the buffer declares. A glTF file must not make dmu
/// read, or embed in what it writes, anything outside its own folder.
pub(super) fn buffer_file(
    i: usize,
    uri: &str,
    base_dir: Option<&Path>,
    declared: usize,
) -> Result<PathBuf, String> {
    let dir = base_dir.ok_or_else(|| {
        format!("buffers[{i}] refers to file {uri:?} but the glTF was not read from a file")
    })?;
    // `model.gltf` has the parent "": the current folder.
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let decoded = percent_decode(uri);
    let relative = Path::new(&decoded);
    let outside = || {
        format!(
            "buffers[{i}].uri {uri:?} is outside the model's folder {} (dmu reads only files inside it)",
            dir.display()
        )
    };
    // A first segment with a colon is a scheme (`file:`, `http:`), not a file name
    // (RFC 3986 4.2): dmu reads data URIs and relative file names only.
    let scheme = uri
        .split('/')
        .next()
        .is_some_and(|first| first.contains(':'));
    if scheme || relative.is_absolute() {
        return Err(outside());
    }
    let joined = dir.join(relative);
    let folder = dir.canonicalize().map_err(|e| {
        format!(
            "buffers[{i}]: cannot resolve the folder {}: {e}",
            dir.display()
        )
    })?;
    let path = joined
        .canonicalize()
        .map_err(|e| format!("buffers[{i}]: cannot read {}: {e}", joined.display()))?;
    if !path.starts_with(&folder) {
        return Err(outside());
    }
    let meta = std::fs::metadata(&path)
        .map_err(|e| format!("buffers[{i}]: cannot read {}: {e}", path.display()))?;
    if !meta.is_file() {
        return Err(format!(
            "buffers[{i}].uri {uri:?} names {}, which is not a regular file",
            path.display()
        ));
    }
    if (meta.len() as usize) < declared {
        return Err(format!(
            "buffers[{i}] declares {declared} bytes but holds {}",
            meta.len()
        ));
    }
    Ok(path)
}

/// The first `len` bytes of a file: a buffer's declared length bounds what is
/// read, however large the file is.
fn read_prefix(path: &Path, len: usize) -> std::io::Result<Vec<u8>> {
    use std::io::Read as _;
    let mut bytes = Vec::with_capacity(len);
    std::fs::File::open(path)?
        .take(len as u64)
        .read_to_end(&mut bytes)?;
    Ok(bytes)
}

pub(super) fn is_meshopt_fallback(buffer: &json::Buffer) -> bool {
    buffer
        .extensions
        .as_ref()
        .and_then(|e| e.others.get("EXT_meshopt_compression"))
        .and_then(|m| m.get("fallback"))
        .and_then(serde_json::Value::as_bool)
        .unwrap_or(false)
}

fn percent_decode(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = bytes
            .get(i + 1..i + 3)
            .and_then(|h| std::str::from_utf8(h).ok());
        match (bytes[i], hex.and_then(|h| u8::from_str_radix(h, 16).ok())) {
            (b'%', Some(b)) => {
                out.push(b);
                i += 3;
            }
            (b, _) => {
                out.push(b);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// The bytes of the buffer views that `needed` selects, bounds-checked, with
/// meshopt views decoded; the others are left as an error naming them.
pub(super) fn resolve_views<'a>(
    root: &json::Root,
    buffers: &'a [Bytes<'a>],
    needed: &dyn Fn(usize) -> bool,
) -> Vec<Bytes<'a>> {
    root.buffer_views
        .iter()
        .enumerate()
        .map(|(i, view)| {
            if !needed(i) {
                return Err(format!("bufferViews[{i}] was not loaded (importer bug)"));
            }
            let meshopt = view
                .extensions
                .as_ref()
                .and_then(|e| e.others.get("EXT_meshopt_compression"));
            if let Some(ext) = meshopt {
                return decode_meshopt(i, ext, buffers, view.byte_length.0 as usize)
                    .map(Cow::Owned);
            }
            let offset = view.byte_offset.map_or(0, |o| o.0 as usize);
            slice(
                buffers,
                view.buffer.value(),
                offset,
                view.byte_length.0 as usize,
            )
            .map(Cow::Borrowed)
            .map_err(|e| format!("bufferViews[{i}]: {e}"))
        })
        .collect()
}

fn slice<'a>(
    buffers: &'a [Bytes<'a>],
    buffer: usize,
    offset: usize,
    len: usize,
) -> Result<&'a [u8], String> {
    let data = match buffers.get(buffer) {
        Some(Ok(data)) => data,
        Some(Err(e)) => return Err(e.clone()),
        None => return Err(format!("buffer {buffer} does not exist")),
    };
    offset
        .checked_add(len)
        .and_then(|end| data.get(offset..end))
        .ok_or_else(|| {
            format!(
                "bytes {offset}..{offset}+{len} outside buffer {buffer} of {} bytes",
                data.len()
            )
        })
}

/// Decodes one EXT_meshopt_compression buffer view (modes ATTRIBUTES, TRIANGLES,
/// INDICES; filters OCTAHEDRAL, QUATERNION, EXPONENTIAL).
fn decode_meshopt(
    view: usize,
    ext: &serde_json::Value,
    buffers: &[Bytes<'_>],
    view_length: usize,
) -> Result<Vec<u8>, String> {
    let bad = |m: &str| format!("bufferViews[{view}].extensions.EXT_meshopt_compression: {m}");
    let field = |k: &str| {
        ext.get(k)
            .and_then(serde_json::Value::as_u64)
            .map(|v| v as usize)
    };
    let buffer = field("buffer").ok_or_else(|| bad("missing buffer"))?;
    let offset = field("byteOffset").unwrap_or(0);
    let length = field("byteLength").ok_or_else(|| bad("missing byteLength"))?;
    let stride = field("byteStride").ok_or_else(|| bad("missing byteStride"))?;
    let count = field("count").ok_or_else(|| bad("missing count"))?;
    // The decoded view is `count` elements of `byteStride` bytes, which the spec
    // says is the view's own byteLength: it bounds what decoding allocates.
    if count.checked_mul(stride) != Some(view_length) {
        return Err(bad(&format!(
            "count {count} x byteStride {stride} is not the view's byteLength {view_length}"
        )));
    }
    let mode = ext
        .get("mode")
        .and_then(serde_json::Value::as_str)
        .unwrap_or("");
    let filter = ext
        .get("filter")
        .and_then(serde_json::Value::as_str)
        .unwrap_or("NONE");
    let src = slice(buffers, buffer, offset, length).map_err(|e| bad(&e))?;
    let err = |e: meshopt::Error| bad(&format!("corrupt {mode} stream ({e})"));
    match (mode, stride) {
        ("TRIANGLES" | "INDICES", 2) => {
            let idx: Vec<u16> = if mode == "TRIANGLES" {
                meshopt::encoding::decode_index_buffer(src, count).map_err(err)?
            } else {
                meshopt::encoding::decode_index_sequence(src, count).map_err(err)?
            };
            Ok(idx.iter().flat_map(|i| i.to_le_bytes()).collect())
        }
        ("TRIANGLES" | "INDICES", 4) => {
            let idx: Vec<u32> = if mode == "TRIANGLES" {
                meshopt::encoding::decode_index_buffer(src, count).map_err(err)?
            } else {
                meshopt::encoding::decode_index_sequence(src, count).map_err(err)?
            };
            Ok(idx.iter().flat_map(|i| i.to_le_bytes()).collect())
        }
        ("ATTRIBUTES", s) if s % 4 == 0 && (4..=128).contains(&s) => {
            let mut words = decode_attributes(src, count, s).map_err(err)?;
            apply_filter(&mut words, filter, stride).map_err(|m| bad(&m))?;
            Ok(words.iter().flat_map(|w| w.to_le_bytes()).collect())
        }
        _ => Err(bad(&format!(
            "unsupported mode {mode:?} with byteStride {stride}"
        ))),
    }
}

/// The meshopt vertex codec needs the vertex size as a type; strides are multiples
/// of four, so dispatch on a 4-byte word count. The extension allows up to 256
/// bytes; dmu reads up to 128 (32 floats a vertex) and names the stride otherwise.
/// Returns little-endian 4-byte words, which keeps the data aligned for the filters.
fn decode_attributes(src: &[u8], count: usize, stride: usize) -> Result<Vec<u32>, meshopt::Error> {
    macro_rules! by_words {
        ($($n:literal)*) => {
            match stride / 4 {
                $($n => Ok(meshopt::encoding::decode_vertex_buffer::<[u32; $n]>(src, count)?
                    .into_iter().flatten().map(u32::from_le).collect()),)*
                _ => unreachable!("stride checked by the caller"),
            }
        };
    }
    by_words!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 24 25 26 27 28 29 30 31 32)
}

fn apply_filter(words: &mut [u32], filter: &str, stride: usize) -> Result<(), String> {
    match (filter, stride) {
        ("NONE", _) => {}
        ("OCTAHEDRAL", 4) => {
            meshopt::encoding::decode_filter_oct::<i8>(bytemuck::cast_slice_mut(words))
        }
        ("OCTAHEDRAL", 8) => {
            meshopt::encoding::decode_filter_oct::<i16>(bytemuck::cast_slice_mut(words))
        }
        ("QUATERNION", 8) => meshopt::encoding::decode_filter_quat(bytemuck::cast_slice_mut(words)),
        ("EXPONENTIAL", s) if s % 4 == 0 => match s / 4 {
            1 => meshopt::encoding::decode_filter_exp::<1>(bytemuck::cast_slice_mut(words)),
            2 => meshopt::encoding::decode_filter_exp::<2>(bytemuck::cast_slice_mut(words)),
            3 => meshopt::encoding::decode_filter_exp::<3>(bytemuck::cast_slice_mut(words)),
            4 => meshopt::encoding::decode_filter_exp::<4>(bytemuck::cast_slice_mut(words)),
            _ => return Err(format!("EXPONENTIAL filter with byteStride {s}")),
        },
        _ => {
            return Err(format!(
                "unsupported filter {filter:?} with byteStride {stride}"
            ));
        }
    }
    Ok(())
}
