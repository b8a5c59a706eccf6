//! Reading accessors into f32 vectors or u32 indices: strides, every component
//! type, normalized and quantized (KHR_mesh_quantization) data, sparse storage.
//! Every offset is bounds-checked; nothing here can panic on a broken file.

use gltf::json::accessor::{ComponentType, Type};
use gltf::json::validation::Checked;
use gltf::json::{self, Index};

use super::buffers::{Bytes, invalid};
use crate::error::ImportError;

/// Resolved file data that accessors read from.
pub(super) struct Data<'a> {
    pub root: &'a json::Root,
    pub views: &'a [Bytes<'a>],
}

fn component_size(c: ComponentType) -> usize {
    match c {
        ComponentType::I8 | ComponentType::U8 => 1,
        ComponentType::I16 | ComponentType::U16 => 2,
        ComponentType::U32 | ComponentType::F32 => 4,
    }
}

/// One component as f32; `normalized` maps integers to [0, 1] or [-1, 1].
fn read_component(bytes: &[u8], c: ComponentType, normalized: bool) -> f32 {
    let b = |i: usize| bytes[i];
    match (c, normalized) {
        (ComponentType::F32, _) => f32::from_le_bytes([b(0), b(1), b(2), b(3)]),
        (ComponentType::I8, false) => f32::from(b(0) as i8),
        (ComponentType::I8, true) => (f32::from(b(0) as i8) / 127.0).max(-1.0),
        (ComponentType::U8, false) => f32::from(b(0)),
        (ComponentType::U8, true) => f32::from(b(0)) / 255.0,
        (ComponentType::I16, false) => f32::from(i16::from_le_bytes([b(0), b(1)])),
        (ComponentType::I16, true) => {
            (f32::from(i16::from_le_bytes([b(0), b(1)])) / 32767.0).max(-1.0)
        }
        (ComponentType::U16, false) => f32::from(u16::from_le_bytes([b(0), b(1)])),
        (ComponentType::U16, true) => f32::from(u16::from_le_bytes([b(0), b(1)])) / 65535.0,
        (ComponentType::U32, false) => u32::from_le_bytes([b(0), b(1), b(2), b(3)]) as f32,
        (ComponentType::U32, true) => {
            u32::from_le_bytes([b(0), b(1), b(2), b(3)]) as f32 / u32::MAX as f32
        }
    }
}

fn read_index(bytes: &[u8], c: ComponentType) -> Option<u32> {
    match c {
        ComponentType::U8 => Some(u32::from(bytes[0])),
        ComponentType::U16 => Some(u32::from(u16::from_le_bytes([bytes[0], bytes[1]]))),
        ComponentType::U32 => Some(u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]])),
        _ => None,
    }
}

/// A strided run of `count` elements of `elem` bytes in a view, checked to fit.
struct Strided<'a> {
    bytes: &'a [u8],
    stride: usize,
}

impl<'a> Strided<'a> {
    fn new(
        data: &Data<'a>,
        view: Index<json::buffer::View>,
        offset: usize,
        count: usize,
        elem: usize,
        what: &dyn Fn() -> String,
    ) -> Result<Self, ImportError> {
        let v = view.value();
        let json_view = data
            .root
            .buffer_views
            .get(v)
            .ok_or_else(|| invalid(format!("{}: bufferView {v} does not exist", what())))?;
        let bytes: &'a [u8] = match &data.views[v] {
            Ok(bytes) => bytes,
            Err(e) => return Err(invalid(format!("{} reads {e}", what()))),
        };
        let stride = json_view.byte_stride.map_or(elem, |s| s.0);
        if stride < elem {
            return Err(invalid(format!(
                "{}: byteStride {stride} is smaller than the element ({elem} bytes)",
                what()
            )));
        }
        let end = match count {
            0 => Some(offset),
            n => (n - 1)
                .checked_mul(stride)
                .and_then(|s| s.checked_add(offset + elem)),
        };
        match end {
            Some(end) if end <= bytes.len() => Ok(Self {
                bytes: &bytes[offset.min(bytes.len())..],
                stride,
            }),
            _ => Err(invalid(format!(
                "{}: {count} elements of {elem} bytes at offset {offset} with stride {stride} overrun bufferView {v} ({} bytes)",
                what(),
                bytes.len()
            ))),
        }
    }

    fn element(&self, i: usize) -> &'a [u8] {
        &self.bytes[i * self.stride..]
    }
}

/// Decodes one element from its bytes, component type and `normalized` flag;
/// The most an accessor without a bufferView may decode to (zeros and its sparse
/// values), bytes; docs/limits.md.
const MAX_ZERO_FILLED_BYTES: usize = 256 << 20;

/// `None` when the component type is not allowed for the use.
type Decode<T> = dyn Fn(&[u8], ComponentType, bool) -> Option<T>;

/// Reads accessor `index` element by element with `decode`, which gets the bytes of
/// one element; `components` must match the accessor's type. Handles sparse data.
fn read_elements<T: Clone>(
    data: &Data<'_>,
    index: usize,
    components: usize,
    zero: T,
    decode: &Decode<T>,
) -> Result<Vec<T>, ImportError> {
    let what = || format!("accessors[{index}]");
    let acc = data
        .root
        .accessors
        .get(index)
        .ok_or_else(|| invalid(format!("{} does not exist", what())))?;
    let actual = match acc.type_ {
        Checked::Valid(Type::Scalar) => 1,
        Checked::Valid(Type::Vec2) => 2,
        Checked::Valid(Type::Vec3) => 3,
        Checked::Valid(Type::Vec4) => 4,
        _ => 0,
    };
    if actual != components {
        return Err(invalid(format!(
            "{}: expected {components} components per element, type is {:?}",
            what(),
            acc.type_
        )));
    }
    let Checked::Valid(json::accessor::GenericComponentType(ctype)) = acc.component_type else {
        return Err(invalid(format!("{}: invalid componentType", what())));
    };
    let wrong_type = || {
        invalid(format!(
            "{}: componentType {ctype:?} not allowed here",
            what()
        ))
    };
    let count = acc.count.0 as usize;
    let elem = component_size(ctype) * components;
    let mut out = match acc.buffer_view {
        Some(view) => {
            let run = Strided::new(
                data,
                view,
                acc.byte_offset.map_or(0, |o| o.0 as usize),
                count,
                elem,
                &what,
            )?;
            (0..count)
                .map(|i| decode(run.element(i), ctype, acc.normalized).ok_or_else(wrong_type))
                .collect::<Result<Vec<T>, _>>()?
        }
        None => {
            // No data behind it: zeros (then sparse values), bounded, since no
            // buffer's length limits what the count claims.
            if count.saturating_mul(elem) > MAX_ZERO_FILLED_BYTES {
                return Err(invalid(format!(
                    "{}: count {count} without a bufferView is more than {} MiB of zeros",
                    what(),
                    MAX_ZERO_FILLED_BYTES >> 20
                )));
            }
            vec![zero; count]
        }
    };
    if let Some(sparse) = &acc.sparse {
        let n = sparse.count.0 as usize;
        let sparse_what = || format!("{}.sparse", what());
        let Checked::Valid(ictype) = sparse.indices.component_type else {
            return Err(invalid(format!(
                "{}.indices: invalid componentType",
                sparse_what()
            )));
        };
        let ictype = ictype.0;
        let indices = Strided::new(
            data,
            sparse.indices.buffer_view,
            sparse.indices.byte_offset.0 as usize,
            n,
            component_size(ictype),
            &sparse_what,
        )?;
        let values = Strided::new(
            data,
            sparse.values.buffer_view,
            sparse.values.byte_offset.0 as usize,
            n,
            elem,
            &sparse_what,
        )?;
        for k in 0..n {
            let target = read_index(indices.element(k), ictype).ok_or_else(|| {
                invalid(format!(
                    "{}.indices: componentType must be unsigned",
                    sparse_what()
                ))
            })? as usize;
            let slot = out.get_mut(target).ok_or_else(|| {
                invalid(format!(
                    "{}: index {target} >= count {count}",
                    sparse_what()
                ))
            })?;
            *slot = decode(values.element(k), ctype, acc.normalized).ok_or_else(wrong_type)?;
        }
    }
    Ok(out)
}

/// Reads accessor `index` as `N`-component f32 vectors.
pub(super) fn read_vectors<const N: usize>(
    data: &Data<'_>,
    index: usize,
) -> Result<Vec<[f32; N]>, ImportError> {
    read_elements(data, index, N, [0.0; N], &|bytes, c, normalized| {
        let size = component_size(c);
        Some(std::array::from_fn(|k| {
            read_component(&bytes[k * size..], c, normalized)
        }))
    })
}

/// Reads an index accessor (unsigned scalar) as u32.
pub(super) fn read_indices(data: &Data<'_>, index: usize) -> Result<Vec<u32>, ImportError> {
    read_elements(data, index, 1, 0, &|bytes, c, _| read_index(bytes, c))
}
