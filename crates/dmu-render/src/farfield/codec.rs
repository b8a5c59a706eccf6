//! A far field's bytes: a head, the meshes and part lists, and the colour
//! and part ids as PNG images; read back with every count, index, number
//! and image checked.

use dmu_geom::Aabb3d;
use glam::DVec3;

use super::{FAR_FIELD_RESOLUTIONS, FarField};

/// Why bytes are not a far field ([`FarField::decode`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FarFieldDecodeError {
    #[error("{len} bytes: shorter than its head")]
    ShortHead { len: usize },
    #[error("not a far field (wrong magic)")]
    Magic,
    #[error("resolution {resolution} outside {FAR_FIELD_RESOLUTIONS:?}")]
    Resolution { resolution: u32 },
    #[error("{what}: {len} bytes past the end")]
    PastEnd { what: &'static str, len: usize },
    #[error("{extra} bytes after its end")]
    Trailing { extra: usize },
    #[error("a centre, box, angle or bound is not a finite number in range")]
    NotFinite,
    #[error("an empty cell or cull box")]
    EmptyBox,
    #[error("face starts {face_starts:?} do not split {indices} indices in triangles")]
    FaceStarts { face_starts: [u32; 7], indices: u32 },
    #[error("index {index} past {vertices} vertices")]
    Index { index: u32, vertices: usize },
    #[error("vertex {index} of face {face} is not a finite point of that face")]
    Vertex { index: u32, face: usize },
    #[error("{what} parts are not sorted part ids below {parts}")]
    PartList { what: &'static str, parts: usize },
    #[error("{what}: {reason}")]
    Image {
        what: &'static str,
        reason: image::ImageError,
    },
    #[error("{what} is {width}x{height}, not {resolution}x{}", 6 * resolution)]
    ImageSize {
        what: &'static str,
        width: u32,
        height: u32,
        resolution: u32,
    },
    #[error("a texel's part id is not below {parts}")]
    TexelPart { parts: usize },
}

/// The first bytes of an encoded far field.
const MAGIC: [u8; 8] = *b"DMUFAR01";

/// Fixed-size head of an encoded far field, little-endian.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Head {
    magic: [u8; 8],
    center: [f64; 3],
    cell: [f64; 6],
    near_box: [f64; 6],
    build_ms: f64,
    resolution: u32,
    tan_half: f32,
    mesh_error_px: f32,
    vertices: u32,
    indices: u32,
    seen: u32,
    excluded: u32,
    color_png: u32,
    parts_png: u32,
    face_starts: [u32; 7],
}

impl FarField {
    /// Its bytes: a head, the meshes and part lists, and the colour and part
    /// ids as PNG images (a column of the six faces).
    pub fn encode(&self) -> Vec<u8> {
        let r = self.resolution;
        let png = |bytes: Vec<u8>| {
            let image = image::RgbaImage::from_raw(r, 6 * r, bytes).expect("six faces");
            crate::encode_png(&image).expect("PNG encoding in memory")
        };
        let color = png(self.color.clone());
        let parts = png(bytemuck::cast_slice(&self.parts).to_vec());
        let b = |b: &Aabb3d| [b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z];
        let head = Head {
            magic: MAGIC,
            center: self.center.to_array(),
            cell: b(&self.cell),
            near_box: b(&self.near_box),
            build_ms: self.build_ms,
            resolution: r,
            tan_half: self.tan_half,
            mesh_error_px: self.mesh_error_px,
            vertices: self.vertices.len() as u32,
            indices: self.indices.len() as u32,
            seen: self.seen.len() as u32,
            excluded: self.excluded.len() as u32,
            color_png: color.len() as u32,
            parts_png: parts.len() as u32,
            face_starts: self.face_starts,
        };
        let mut out = bytemuck::bytes_of(&head).to_vec();
        out.extend_from_slice(bytemuck::cast_slice(&self.vertices));
        out.extend_from_slice(bytemuck::cast_slice(&self.indices));
        out.extend_from_slice(bytemuck::cast_slice(&self.seen));
        out.extend_from_slice(bytemuck::cast_slice(&self.excluded));
        out.extend_from_slice(&color);
        out.extend_from_slice(&parts);
        out
    }

    /// Reads [`FarField::encode`]'s bytes, checking every count, index,
    /// number and image against the others and part ids against `parts`
    /// (the model's part count): what does not fit when they do not.
    pub fn decode(bytes: &[u8], parts: usize) -> Result<FarField, FarFieldDecodeError> {
        let head_len = size_of::<Head>();
        let head: Head = bytemuck::pod_read_unaligned(
            bytes
                .get(..head_len)
                .ok_or(FarFieldDecodeError::ShortHead { len: bytes.len() })?,
        );
        if head.magic != MAGIC {
            return Err(FarFieldDecodeError::Magic);
        }
        let r = head.resolution;
        if !FAR_FIELD_RESOLUTIONS.contains(&r) {
            return Err(FarFieldDecodeError::Resolution { resolution: r });
        }
        let mut at = head_len;
        let mut take = |len: usize, what: &'static str| -> Result<&[u8], FarFieldDecodeError> {
            let piece = at
                .checked_add(len)
                .and_then(|end| bytes.get(at..end))
                .ok_or(FarFieldDecodeError::PastEnd { what, len })?;
            at += len;
            Ok(piece)
        };
        let vertices: Vec<[f32; 4]> =
            bytemuck::pod_collect_to_vec(take(16 * head.vertices as usize, "vertices")?);
        let indices: Vec<u32> =
            bytemuck::pod_collect_to_vec(take(4 * head.indices as usize, "indices")?);
        let seen: Vec<u32> = bytemuck::pod_collect_to_vec(take(4 * head.seen as usize, "seen")?);
        let excluded: Vec<u32> =
            bytemuck::pod_collect_to_vec(take(4 * head.excluded as usize, "excluded")?);
        let color = take(head.color_png as usize, "colour image")?.to_vec();
        let parts_png = take(head.parts_png as usize, "part image")?.to_vec();
        if at != bytes.len() {
            return Err(FarFieldDecodeError::Trailing {
                extra: bytes.len() - at,
            });
        }
        let finite = head
            .center
            .iter()
            .chain(&head.cell)
            .chain(&head.near_box)
            .all(|x| x.is_finite())
            && head.tan_half.is_finite()
            && head.tan_half >= 1.0
            && head.tan_half < 2.0
            && head.mesh_error_px.is_finite();
        if !finite {
            return Err(FarFieldDecodeError::NotFinite);
        }
        let b =
            |a: [f64; 6]| Aabb3d::new(DVec3::new(a[0], a[1], a[2]), DVec3::new(a[3], a[4], a[5]));
        let (cell, near_box) = (b(head.cell), b(head.near_box));
        if cell.is_empty() || near_box.is_empty() {
            return Err(FarFieldDecodeError::EmptyBox);
        }
        let fs = head.face_starts;
        if fs[0] != 0
            || fs[6] != head.indices
            || fs.windows(2).any(|w| w[0] > w[1] || w[1] % 3 != 0)
        {
            return Err(FarFieldDecodeError::FaceStarts {
                face_starts: fs,
                indices: head.indices,
            });
        }
        for (f, w) in fs.windows(2).enumerate() {
            for &i in &indices[w[0] as usize..w[1] as usize] {
                let v = vertices.get(i as usize).ok_or(FarFieldDecodeError::Index {
                    index: i,
                    vertices: vertices.len(),
                })?;
                if v[3] != f as f32 || !v.iter().all(|x| x.is_finite()) {
                    return Err(FarFieldDecodeError::Vertex { index: i, face: f });
                }
            }
        }
        let sorted_parts = |list: &[u32], what: &'static str| {
            if list.windows(2).any(|w| w[0] >= w[1])
                || list.last().is_some_and(|&p| p as usize >= parts)
            {
                Err(FarFieldDecodeError::PartList { what, parts })
            } else {
                Ok(())
            }
        };
        sorted_parts(&seen, "seen")?;
        sorted_parts(&excluded, "excluded")?;
        let image = |png: &[u8], what: &'static str| -> Result<Vec<u8>, FarFieldDecodeError> {
            let image = image::load_from_memory_with_format(png, image::ImageFormat::Png)
                .map_err(|reason| FarFieldDecodeError::Image { what, reason })?;
            if (image.width(), image.height()) != (r, 6 * r) {
                return Err(FarFieldDecodeError::ImageSize {
                    what,
                    width: image.width(),
                    height: image.height(),
                    resolution: r,
                });
            }
            Ok(image.into_rgba8().into_raw())
        };
        let color = image(&color, "colour image")?;
        let part_ids: Vec<u32> = bytemuck::pod_collect_to_vec(&image(&parts_png, "part image")?);
        if part_ids.iter().any(|&p| p as usize > parts) {
            return Err(FarFieldDecodeError::TexelPart { parts });
        }
        Ok(FarField {
            center: DVec3::from_array(head.center),
            cell,
            near_box,
            resolution: r,
            tan_half: head.tan_half,
            vertices,
            indices,
            face_starts: fs,
            color,
            parts: part_ids,
            seen,
            excluded,
            mesh_error_px: head.mesh_error_px,
            build_ms: head.build_ms,
        })
    }
}
