//! A chunk's geometry segment: encoding, optional quantization, and decoding
//! with every count checked against the skeleton's chunk table.
//!
//! ```text
//! GeometryHeader (16 bytes)
//! positions   f32 x3 per vertex, or u16 x3 quantized in the chunk's box
//! normals     f32 x3 per vertex, or i16 x2 octahedral
//! indices     u16 x3 per triangle when the chunk has at most 65,536 vertices
//!             (always, at the default chunk size), else u32 x3
//! levels      (version 4) per level, coarser each time: u32 index count and
//!             f32 error (`dmu_scene::LodLevel`); then each level's indices,
//!             as wide as the chunk's
//! ```
//!
//! A version-3 chunk is the same up to its indices, with no levels (its
//! header's level count is zero): the renderer computes them on upload.

use bytemuck::{Pod, Zeroable};
use dmu_geom::Aabb3f;
use dmu_scene::{LodLevel, MAX_LOD_LEVELS};
use glam::{Vec2, Vec3};

/// Flag: positions and normals are quantized.
const QUANTIZED: u32 = 1;
/// Flag: indices are u16.
const SHORT_INDICES: u32 = 2;
const HEADER_LEN: usize = size_of::<GeometryHeader>();

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct GeometryHeader {
    /// Vertices: must equal the chunk's vertex range in the skeleton.
    vertices: u32,
    /// Triangles: must equal the chunk's triangle range in the skeleton.
    triangles: u32,
    /// [`QUANTIZED`] | [`SHORT_INDICES`].
    flags: u32,
    /// Simplified levels after the indices, at most [`MAX_LOD_LEVELS`]; zero
    /// in version 3 (reserved there).
    levels: u32,
}
/// A level's entry in the segment's level table.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct LevelHeader {
    /// Its indices: a multiple of three.
    indices: u32,
    /// [`LodLevel::error`]: finite, not negative, not below the finer level's.
    error: f32,
}
const _: () = assert!(size_of::<LevelHeader>() == 8);
const _: () = assert!(size_of::<GeometryHeader>() == 16);

/// One chunk's geometry, decoded and owned (what the residency manager holds):
/// part-local f32 vertices and chunk-local indices; it lends
/// [`dmu_scene::ChunkGeometry`], which the renderer uploads and picking reads.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct OwnedChunkGeometry {
    /// Part-local positions.
    pub positions: Vec<Vec3>,
    /// Unit normals, one per position.
    pub normals: Vec<Vec3>,
    /// Three per triangle, each below `positions.len()`.
    pub indices: Vec<u32>,
    /// The chunk's simplified levels as the store holds them
    /// ([`dmu_scene::lod_levels`] at import); `None` from a version-3 store,
    /// which has none (whoever draws the chunk computes them).
    pub levels: Option<Vec<LodLevel>>,
}

impl OwnedChunkGeometry {
    /// The borrowed geometry.
    pub fn geometry(&self) -> dmu_scene::ChunkGeometry<'_> {
        dmu_scene::ChunkGeometry {
            positions: &self.positions,
            normals: &self.normals,
            indices: &self.indices,
            levels: self.levels.as_deref(),
        }
    }

    /// Bytes this geometry holds in memory: at most what the residency
    /// budget counts for it (`resident_bytes`).
    pub fn resident_bytes(&self) -> u64 {
        let level_indices = self.levels.iter().flatten().map(|l| l.indices.len());
        let indices = self.indices.len() + level_indices.sum::<usize>();
        (self.positions.len() * 2 * size_of::<Vec3>() + indices * size_of::<u32>()) as u64
    }
}

/// Bytes of a decoded chunk of `vertices` and `triangles`, with room for its
/// levels when it has them (`levels`): their indices are at most the chunk's
/// own ([`dmu_scene::lod_levels`] stops there, the decoder checks it), so this
/// bounds what reading the chunk can hold before it is read.
pub(crate) fn resident_bytes(vertices: u64, triangles: u64, levels: bool) -> u64 {
    let index_bytes = triangles * 3 * size_of::<u32>() as u64;
    vertices * 2 * size_of::<Vec3>() as u64 + index_bytes * if levels { 2 } else { 1 }
}

/// Encodes one chunk with its levels; `bounds` is its box (the quantization
/// grid).
pub(crate) fn encode(
    g: &dmu_scene::ChunkGeometry<'_>,
    levels: &[LodLevel],
    bounds: &Aabb3f,
    quantize: bool,
) -> Vec<u8> {
    let (positions, normals, indices) = (g.positions, g.normals, g.indices);
    let short = positions.len() <= 1 << 16;
    let header = GeometryHeader {
        vertices: positions.len() as u32,
        triangles: (indices.len() / 3) as u32,
        flags: if quantize { QUANTIZED } else { 0 } | if short { SHORT_INDICES } else { 0 },
        levels: 0,
    };
    let mut out = Vec::with_capacity(HEADER_LEN + positions.len() * 24 + indices.len() * 8);
    out.extend_from_slice(bytemuck::bytes_of(&header));
    if quantize {
        for p in positions {
            let q = quantize_position(*p, bounds);
            out.extend_from_slice(bytemuck::cast_slice(&q));
        }
        for n in normals {
            out.extend_from_slice(bytemuck::cast_slice(&octahedral_encode(*n)));
        }
    } else {
        out.extend_from_slice(bytemuck::cast_slice(positions));
        out.extend_from_slice(bytemuck::cast_slice(normals));
    }
    put_indices(&mut out, indices, short);
    add_levels(&mut out, levels);
    out
}

/// Appends `levels` to an encoded chunk that has none (one just encoded, or a
/// version-3 segment being copied into a version-4 store) and counts them in
/// its header.
///
/// # Panics
/// When the chunk has levels already, or more than [`MAX_LOD_LEVELS`] are
/// given.
pub(crate) fn add_levels(segment: &mut Vec<u8>, levels: &[LodLevel]) {
    let mut header: GeometryHeader = bytemuck::pod_read_unaligned(&segment[..HEADER_LEN]);
    assert_eq!(header.levels, 0, "the chunk has levels already");
    assert!(levels.len() <= MAX_LOD_LEVELS, "{} levels", levels.len());
    header.levels = levels.len() as u32;
    segment[..HEADER_LEN].copy_from_slice(bytemuck::bytes_of(&header));
    for level in levels {
        let entry = LevelHeader {
            indices: level.indices.len() as u32,
            error: level.error,
        };
        segment.extend_from_slice(bytemuck::bytes_of(&entry));
    }
    for level in levels {
        put_indices(segment, &level.indices, header.flags & SHORT_INDICES != 0);
    }
}

fn put_indices(out: &mut Vec<u8>, indices: &[u32], short: bool) {
    if short {
        for &i in indices {
            out.extend_from_slice(&(i as u16).to_le_bytes());
        }
    } else {
        out.extend_from_slice(bytemuck::cast_slice(indices));
    }
}

fn get_indices(bytes: &[u8], index_size: usize) -> Vec<u32> {
    if index_size == 2 {
        bytes
            .chunks_exact(2)
            .map(|b| u32::from(u16::from_le_bytes([b[0], b[1]])))
            .collect()
    } else {
        bytemuck::pod_collect_to_vec(bytes)
    }
}

/// Decodes a chunk segment of a store of format `version` (3 or 4), checking
/// it against the skeleton's chunk table: counts, exact length, indices in
/// range (the levels' too), and that the decoded positions fill `bounds`
/// exactly (so a loaded scene validates).
pub(crate) fn decode(
    bytes: &[u8],
    version: u32,
    vertices: u32,
    triangles: u32,
    bounds: &Aabb3f,
) -> Result<OwnedChunkGeometry, String> {
    let head = bytes
        .get(..HEADER_LEN)
        .ok_or_else(|| format!("{} bytes, shorter than its header", bytes.len()))?;
    let h: GeometryHeader = bytemuck::pod_read_unaligned(head);
    if (h.vertices, h.triangles) != (vertices, triangles) {
        return Err(format!(
            "holds {} vertices and {} triangles, the skeleton says {vertices} and {triangles}",
            h.vertices, h.triangles
        ));
    }
    if h.flags & !(QUANTIZED | SHORT_INDICES) != 0 {
        return Err(format!("unknown flags {:#x}", h.flags));
    }
    let stores_levels = version >= 4;
    if !stores_levels && h.levels != 0 {
        return Err(format!("reserved word {:#x} is not zero", h.levels));
    }
    if h.levels as usize > MAX_LOD_LEVELS {
        return Err(format!("{} levels, more than {MAX_LOD_LEVELS}", h.levels));
    }
    let (v, t) = (vertices as usize, triangles as usize);
    let quantized = h.flags & QUANTIZED != 0;
    let index_size = if h.flags & SHORT_INDICES != 0 { 2 } else { 4 };
    let (pos_size, nrm_size) = if quantized { (6, 4) } else { (12, 12) };
    let table_at = HEADER_LEN + v * (pos_size + nrm_size) + 3 * t * index_size;
    let level_table = bytes
        .get(table_at..table_at + h.levels as usize * size_of::<LevelHeader>())
        .ok_or_else(|| format!("{} bytes, shorter than its counts make", bytes.len()))?;
    let level_headers: Vec<LevelHeader> = level_table
        .chunks_exact(size_of::<LevelHeader>())
        .map(bytemuck::pod_read_unaligned)
        .collect();
    let level_indices: usize = level_headers.iter().map(|l| l.indices as usize).sum();
    let expected = table_at + level_table.len() + level_indices * index_size;
    if bytes.len() != expected {
        return Err(format!(
            "{} bytes where its counts make {expected}",
            bytes.len()
        ));
    }
    let (pos, rest) = bytes[HEADER_LEN..table_at].split_at(v * pos_size);
    let (nrm, idx) = rest.split_at(v * nrm_size);
    let (positions, normals) = if quantized {
        let positions = pos
            .chunks_exact(6)
            .map(|q| dequantize_position(bytemuck::pod_read_unaligned(q), bounds))
            .collect();
        let normals = nrm
            .chunks_exact(4)
            .map(|q| octahedral_decode(bytemuck::pod_read_unaligned(q)))
            .collect();
        (positions, normals)
    } else {
        (
            bytemuck::pod_collect_to_vec(pos),
            bytemuck::pod_collect_to_vec(nrm),
        )
    };
    let indices = get_indices(idx, index_size);
    if let Some(bad) = indices.iter().find(|&&i| i >= vertices) {
        return Err(format!("index {bad} >= {vertices} vertices"));
    }
    if Aabb3f::from_points(positions.iter().copied()) != *bounds {
        return Err("its vertices do not fill the chunk's box".into());
    }
    let levels = stores_levels
        .then(|| {
            decode_levels(
                &level_headers,
                &bytes[table_at + level_table.len()..],
                index_size,
                vertices,
                indices.len(),
            )
        })
        .transpose()?;
    Ok(OwnedChunkGeometry {
        positions,
        normals,
        indices,
        levels,
    })
}

/// The levels of `headers` from `bytes` (their indices, back to back), each
/// checked: whole triangles, indices below `vertices`, errors finite and
/// growing, and together no more indices than the chunk's `chunk_indices`.
fn decode_levels(
    headers: &[LevelHeader],
    mut bytes: &[u8],
    index_size: usize,
    vertices: u32,
    chunk_indices: usize,
) -> Result<Vec<LodLevel>, String> {
    let total: usize = headers.iter().map(|l| l.indices as usize).sum();
    if total > chunk_indices {
        return Err(format!(
            "its levels hold {total} indices, more than its own {chunk_indices}"
        ));
    }
    let mut levels: Vec<LodLevel> = Vec::with_capacity(headers.len());
    for (k, h) in headers.iter().enumerate() {
        let finer = levels.last().map_or(0.0, |l| l.error);
        if !h.indices.is_multiple_of(3) {
            return Err(format!(
                "level {k} has {} indices, not whole triangles",
                h.indices
            ));
        }
        if !(h.error.is_finite() && h.error >= finer) {
            return Err(format!(
                "level {k} claims error {}, below {finer} or not finite",
                h.error
            ));
        }
        let (mine, rest) = bytes.split_at(h.indices as usize * index_size);
        bytes = rest;
        let indices = get_indices(mine, index_size);
        if let Some(bad) = indices.iter().find(|&&i| i >= vertices) {
            return Err(format!("level {k}: index {bad} >= {vertices} vertices"));
        }
        levels.push(LodLevel {
            indices,
            error: h.error,
        });
    }
    Ok(levels)
}

/// 16 bits per axis across the chunk's box: the error is at most half a step,
/// 1/131070 of the box's extent on that axis (0.08 mm on a 10 m chunk).
fn quantize_position(p: Vec3, bounds: &Aabb3f) -> [u16; 3] {
    let extent = bounds.max - bounds.min;
    std::array::from_fn(|k| {
        if extent[k] > 0.0 {
            ((p[k] - bounds.min[k]) / extent[k] * 65535.0)
                .round()
                .clamp(0.0, 65535.0) as u16
        } else {
            0
        }
    })
}

/// The inverse of [`quantize_position`]. Written as a blend of the box's ends so
/// that 0 and 65535 give `min` and `max` exactly: the decoded vertices keep the
/// chunk's box bit for bit, and the tree's boxes stay true.
fn dequantize_position(q: [u16; 3], bounds: &Aabb3f) -> Vec3 {
    Vec3::from_array(std::array::from_fn(|k| {
        let f = f32::from(q[k]) / 65535.0;
        (bounds.min[k] * (1.0 - f) + bounds.max[k] * f).clamp(bounds.min[k], bounds.max[k])
    }))
}

/// Octahedral unit-vector encoding in two snorm16 (Cigolle et al. 2014): under
/// 0.01 degrees of error.
fn octahedral_encode(n: Vec3) -> [i16; 2] {
    let n = n / (n.x.abs() + n.y.abs() + n.z.abs()).max(f32::MIN_POSITIVE);
    let mut p = Vec2::new(n.x, n.y);
    if n.z < 0.0 {
        p = (Vec2::ONE - Vec2::new(p.y.abs(), p.x.abs())) * sign_not_zero(p);
    }
    [p.x, p.y].map(|v| (v.clamp(-1.0, 1.0) * 32767.0).round() as i16)
}

fn octahedral_decode(q: [i16; 2]) -> Vec3 {
    let p = Vec2::new(f32::from(q[0]), f32::from(q[1])) / 32767.0;
    let z = 1.0 - p.x.abs() - p.y.abs();
    let xy = if z < 0.0 {
        (Vec2::ONE - Vec2::new(p.y.abs(), p.x.abs())) * sign_not_zero(p)
    } else {
        p
    };
    Vec3::new(xy.x, xy.y, z).normalize_or(Vec3::Z)
}

fn sign_not_zero(p: Vec2) -> Vec2 {
    Vec2::new(
        if p.x >= 0.0 { 1.0 } else { -1.0 },
        if p.y >= 0.0 { 1.0 } else { -1.0 },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn octahedral_round_trip_is_within_a_hundredth_of_a_degree() {
        // The angle in f64 from the chord: an f32 dot product cannot resolve it.
        let angle_deg = |n: Vec3| {
            let d = octahedral_decode(octahedral_encode(n)).as_dvec3() - n.as_dvec3().normalize();
            2.0 * (d.length() / 2.0).asin().to_degrees()
        };
        let mut worst = 0.0f64;
        for i in 0..2000 {
            let a = i as f32 * 0.7;
            let b = (i as f32 * 0.37).sin() * 1.5;
            let n = Vec3::new(a.cos() * b.cos(), a.sin() * b.cos(), b.sin()).normalize();
            worst = worst.max(angle_deg(n));
        }
        for n in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z] {
            worst = worst.max(angle_deg(n));
        }
        assert!(worst <= 0.01, "{worst} degrees");
    }

    #[test]
    fn quantized_positions_keep_the_box_exactly() {
        let bounds = Aabb3f {
            min: Vec3::new(-1234.5, 0.25, 7.0),
            max: Vec3::new(9876.125, 0.25, 7.5),
        };
        let corners = [bounds.min, bounds.max];
        for p in corners {
            assert_eq!(
                dequantize_position(quantize_position(p, &bounds), &bounds),
                p
            );
        }
        let p = Vec3::new(100.0, 0.25, 7.2);
        let d = dequantize_position(quantize_position(p, &bounds), &bounds) - p;
        let step = (bounds.max - bounds.min) / 65535.0;
        assert!(d.abs().cmple(step * 0.5 + 1e-3).all(), "{d}");
    }
}
