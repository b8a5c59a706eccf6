//! The glTF nodes as flat arrays in file order (children in one index list,
//! names in one string table, local transforms as f64), read straight from the
//! JSON one node at a time: never a document tree of them. The `gltf` crate's
//! typed nodes hold transforms as f32, which cannot hold a millimetre offset
//! of 1e7; these are read as f64 from the JSON's numbers.

use std::fmt;

use glam::DAffine3;
use serde::Deserialize;
use serde::de::{self, DeserializeSeed, Deserializer, IgnoredAny, MapAccess, SeqAccess, Visitor};

use super::RawNode;
use super::buffers::invalid;
use crate::error::ImportError;
use crate::ids::NodeId;
use crate::properties::{MAX_KEY_BYTES, MAX_PER_NODE, MAX_VALUE_BYTES, Properties};
use crate::structure::Names;

/// No mesh, in [`FileNodes::mesh`].
const NO_MESH: u32 = u32::MAX;

/// The file's nodes, flat.
#[derive(Default)]
pub(super) struct FileNodes {
    /// Each node's mesh index, or [`NO_MESH`].
    mesh: Vec<u32>,
    /// Where each node's children end in `children`.
    child_ends: Vec<u64>,
    /// Children, node after node, in file order.
    children: Vec<u32>,
    /// Local transforms, column-major 3x4 (identity where invalid).
    local: Vec<[f64; 12]>,
    /// Names (empty where unnamed).
    names: Names,
    /// Nodes without a name.
    unnamed: Vec<bool>,
    /// The nodes' `extras` members with a string, number or boolean value,
    /// by file node index.
    properties: Properties,
    /// `extras` members not kept (see [`FileNodes::properties_dropped`]).
    properties_dropped: usize,
    /// Nodes whose transform is invalid, with the error, by node index: raised
    /// only when the import reaches the node, as for any other broken element.
    bad: Vec<(u32, String)>,
    /// Bytes of JSON the nodes were read from (to within the read buffer), when
    /// streamed.
    json_bytes: u64,
}

impl FileNodes {
    fn push(
        &mut self,
        i: usize,
        name: Option<&str>,
        mesh: Option<u64>,
        children: &[u64],
        raw: &RawNode,
        extras: Option<Extras>,
    ) -> Result<(), String> {
        let index = |what: &str, v: u64| {
            u32::try_from(v)
                .ok()
                .filter(|&v| v != u32::MAX)
                .ok_or_else(|| format!("nodes[{i}].{what} {v} is out of range"))
        };
        self.mesh
            .push(mesh.map_or(Ok(NO_MESH), |m| index("mesh", m))?);
        for &c in children {
            self.children.push(index("children", c)?);
        }
        self.child_ends.push(self.children.len() as u64);
        let local = raw.local(i).unwrap_or_else(|e| {
            let what = match e {
                ImportError::Invalid { what } => what,
                e => e.to_string(),
            };
            self.bad.push((i as u32, what));
            DAffine3::IDENTITY
        });
        self.local.push(local.to_cols_array());
        self.names.push(name.unwrap_or_default());
        self.unnamed.push(name.is_none());
        if let Some(extras) = extras {
            self.add_properties(i, extras);
        }
        Ok(())
    }

    /// Keeps node `i`'s `extras` members whose value is a string, number
    /// or boolean as its properties, within the limits of
    /// [`crate::properties`]; counts the rest as dropped.
    fn add_properties(&mut self, i: usize, extras: Extras) {
        let Extras::Members(members) = extras else {
            self.properties_dropped += 1;
            return;
        };
        let mut kept = 0;
        for (key, value) in members {
            match value {
                Some(v)
                    if kept < MAX_PER_NODE
                        && key.len() <= MAX_KEY_BYTES
                        && v.len() <= MAX_VALUE_BYTES =>
                {
                    self.properties.push(NodeId(i as u32), &key, &v);
                    kept += 1;
                }
                _ => self.properties_dropped += 1,
            }
        }
    }

    /// Node `n`'s properties.
    pub fn properties(&self, n: usize) -> impl Iterator<Item = (&str, &str)> + '_ {
        self.properties.of(NodeId(n as u32))
    }

    /// `extras` that were not an object, and members whose value is null,
    /// an array or an object, or beyond the limits of
    /// [`crate::properties`]: not kept.
    pub fn properties_dropped(&self) -> usize {
        self.properties_dropped
    }

    pub fn len(&self) -> usize {
        self.mesh.len()
    }

    pub fn mesh(&self, n: usize) -> Option<usize> {
        (self.mesh[n] != NO_MESH).then_some(self.mesh[n] as usize)
    }

    pub fn children(&self, n: usize) -> &[u32] {
        let start = if n == 0 { 0 } else { self.child_ends[n - 1] };
        &self.children[start as usize..self.child_ends[n] as usize]
    }

    pub fn name(&self, n: usize) -> Option<&str> {
        (!self.unnamed[n]).then(|| self.names.get(n))
    }

    /// The node's local transform, or the error of an invalid one.
    pub fn local(&self, n: usize) -> Result<DAffine3, ImportError> {
        if let Ok(k) = self.bad.binary_search_by_key(&(n as u32), |b| b.0) {
            return Err(invalid(self.bad[k].1.clone()));
        }
        Ok(DAffine3::from_cols_array(&self.local[n]))
    }

    /// Bytes of JSON the nodes were read from, when streamed (0 otherwise).
    pub fn json_bytes(&self) -> u64 {
        self.json_bytes
    }

    /// Bytes its arrays hold.
    pub fn held_bytes(&self) -> u64 {
        (self.mesh.capacity() * 4
            + self.child_ends.capacity() * 8
            + self.children.capacity() * 4
            + self.local.capacity() * 96
            + self.names.ends.capacity() * 8
            + self.names.bytes.capacity()
            + self.unnamed.capacity()) as u64
            + self.properties.held_bytes()
    }
}

/// A node as it is streamed: only what the import reads; every other member
/// (extensions, camera, skin, weights) is skipped unread.
#[derive(Deserialize)]
#[serde(expecting = "a node (an object)")]
struct StreamNode {
    name: Option<String>,
    mesh: Option<JsonIndex>,
    #[serde(default)]
    children: Vec<JsonIndex>,
    matrix: Option<[f64; 16]>,
    translation: Option<[f64; 3]>,
    rotation: Option<[f64; 4]>,
    scale: Option<[f64; 3]>,
    extras: Option<Extras>,
}

/// A node's `extras` as the import keeps it: each member's value when it is
/// a string, number or boolean, `None` for any other, whose contents are
/// skipped unread (however deep, as when `extras` was not read at all).
enum Extras {
    Members(Vec<(String, Option<String>)>),
    NotAnObject,
}

impl<'de> Deserialize<'de> for Extras {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Extras;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("any JSON value")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Extras, A::Error> {
                let mut members = Vec::new();
                while let Some(key) = map.next_key::<String>()? {
                    members.push((key, map.next_value::<Scalar>()?.0));
                }
                Ok(Extras::Members(members))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<Extras, A::Error> {
                IgnoredAny.visit_seq(seq).map(|_| Extras::NotAnObject)
            }
            fn visit_str<E: de::Error>(self, _: &str) -> Result<Extras, E> {
                Ok(Extras::NotAnObject)
            }
            fn visit_bool<E: de::Error>(self, _: bool) -> Result<Extras, E> {
                Ok(Extras::NotAnObject)
            }
            fn visit_i64<E: de::Error>(self, _: i64) -> Result<Extras, E> {
                Ok(Extras::NotAnObject)
            }
            fn visit_u64<E: de::Error>(self, _: u64) -> Result<Extras, E> {
                Ok(Extras::NotAnObject)
            }
            fn visit_f64<E: de::Error>(self, _: f64) -> Result<Extras, E> {
                Ok(Extras::NotAnObject)
            }
            fn visit_unit<E: de::Error>(self) -> Result<Extras, E> {
                Ok(Extras::NotAnObject)
            }
        }
        d.deserialize_any(V)
    }
}

/// A member's value as a property: a string, number or boolean as text;
/// `None` for null, an array or an object (skipped unread).
struct Scalar(Option<String>);

impl<'de> Deserialize<'de> for Scalar {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> Visitor<'de> for V {
            type Value = Scalar;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("any JSON value")
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<Scalar, E> {
                Ok(Scalar(Some(v.to_owned())))
            }
            fn visit_bool<E: de::Error>(self, v: bool) -> Result<Scalar, E> {
                Ok(Scalar(Some(v.to_string())))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Scalar, E> {
                Ok(Scalar(Some(v.to_string())))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Scalar, E> {
                Ok(Scalar(Some(v.to_string())))
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Scalar, E> {
                // As JSON writes it (`1e300`, not 300 zeros).
                Ok(Scalar(
                    serde_json::Number::from_f64(v).map(|n| n.to_string()),
                ))
            }
            fn visit_unit<E: de::Error>(self) -> Result<Scalar, E> {
                Ok(Scalar(None))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> Result<Scalar, A::Error> {
                IgnoredAny.visit_seq(seq).map(|_| Scalar(None))
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<Scalar, A::Error> {
                IgnoredAny.visit_map(map).map(|_| Scalar(None))
            }
        }
        d.deserialize_any(V)
    }
}

/// A glTF index: a non-negative integer, also written as an integral float
/// (`1.0`), as the whole-document reader accepts it.
struct JsonIndex(u64);

impl<'de> Deserialize<'de> for JsonIndex {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl Visitor<'_> for V {
            type Value = JsonIndex;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("an index (a non-negative integer)")
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<JsonIndex, E> {
                Ok(JsonIndex(v))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<JsonIndex, E> {
                u64::try_from(v)
                    .map(JsonIndex)
                    .map_err(|_| E::invalid_value(de::Unexpected::Signed(v), &self))
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<JsonIndex, E> {
                if v.fract() == 0.0 && (0.0..9.0e15).contains(&v) {
                    Ok(JsonIndex(v as u64))
                } else {
                    Err(E::invalid_value(de::Unexpected::Float(v), &self))
                }
            }
        }
        d.deserialize_any(V)
    }
}

/// The top-level members the import never reads, skipped unread (the
/// whole-document reader drops them too).
pub(super) const UNUSED_MEMBERS: [&str; 6] = [
    "animations",
    "skins",
    "cameras",
    "images",
    "textures",
    "samplers",
];

/// Reads a glTF document's top-level object from `de`: `nodes` streamed into
/// [`FileNodes`], the unused members skipped, every other member kept as a
/// JSON value (meshes, accessors, materials: a few per mesh, not per node).
/// `position` tells how far the input has been read, to measure the nodes'
/// JSON ([`FileNodes::json_bytes`]).
pub(super) fn read_document<'de, D: Deserializer<'de>>(
    de: D,
    position: &dyn Fn() -> u64,
) -> Result<(serde_json::Map<String, serde_json::Value>, FileNodes), D::Error> {
    de.deserialize_map(TopLevel { position })
}

struct TopLevel<'a> {
    position: &'a dyn Fn() -> u64,
}

impl<'de> Visitor<'de> for TopLevel<'_> {
    type Value = (serde_json::Map<String, serde_json::Value>, FileNodes);

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("an object with \"asset\" (the JSON is not a glTF document)")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Self::Value, A::Error> {
        let mut rest = serde_json::Map::new();
        let mut nodes = None;
        while let Some(key) = map.next_key::<String>()? {
            if key == "nodes" {
                if nodes.is_some() {
                    return Err(de::Error::duplicate_field("nodes"));
                }
                let start = (self.position)();
                let mut read = map.next_value_seed(NodesSeed)?;
                read.json_bytes = (self.position)().saturating_sub(start);
                nodes = Some(read);
            } else if UNUSED_MEMBERS.contains(&key.as_str()) {
                map.next_value::<IgnoredAny>()?;
            } else {
                let value = map.next_value()?;
                rest.insert(key, value);
            }
        }
        Ok((rest, nodes.unwrap_or_default()))
    }
}

struct NodesSeed;

impl<'de> DeserializeSeed<'de> for NodesSeed {
    type Value = FileNodes;
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<FileNodes, D::Error> {
        d.deserialize_seq(self)
    }
}

impl<'de> Visitor<'de> for NodesSeed {
    type Value = FileNodes;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("an array of nodes")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<FileNodes, A::Error> {
        let mut nodes = FileNodes::default();
        loop {
            let i = nodes.len();
            let node = seq
                .next_element::<StreamNode>()
                .map_err(|e| <A::Error as de::Error>::custom(format_args!("nodes[{i}]: {e}")))?;
            let Some(n) = node else { break };
            let raw = RawNode {
                matrix: n.matrix,
                translation: n.translation,
                rotation: n.rotation,
                scale: n.scale,
            };
            let children: Vec<u64> = n.children.iter().map(|c| c.0).collect();
            nodes
                .push(
                    i,
                    n.name.as_deref(),
                    n.mesh.map(|m| m.0),
                    &children,
                    &raw,
                    n.extras,
                )
                .map_err(<A::Error as de::Error>::custom)?;
        }
        Ok(nodes)
    }
}
