//! Per-node properties: what the source file says of a node beside its name
//! (an IFC element's GlobalId and class, a STEP product's name, a glTF
//! node's `extras`), as key–value strings. Sparse: most nodes of a large
//! model have none, so the table holds rows, not a slot per node.
//!
//! Encoded ([`Properties::to_bytes`]) as little-endian arrays:
//!
//! ```text
//! rows u64, key bytes u64, value bytes u64
//! node u32 x rows (zero padded to 8 bytes)
//! key ends u64 x rows, then the keys' UTF-8 bytes
//! value ends u64 x rows, then the values' UTF-8 bytes
//! ```

use crate::ids::NodeId;
use crate::structure::Names;

/// The most properties an importer keeps of one node; the rest are dropped
/// and counted ([`crate::ImportReport::properties_dropped`]).
pub const MAX_PER_NODE: usize = 64;
/// The longest key an importer keeps, bytes.
pub const MAX_KEY_BYTES: usize = 256;
/// The longest value an importer keeps, bytes.
pub const MAX_VALUE_BYTES: usize = 4096;
/// The property that holds an IFC element's GlobalId: what BCF's `IfcGuid`
/// names, and what a part can be found by ([`crate::Scene::find_part`]).
pub const GLOBAL_ID: &str = "GlobalId";
/// The property naming the file a part came from: the same on every part of
/// a file, so searches leave it out.
pub const SOURCE_FILE: &str = "SourceFile";

/// Key–value strings of nodes, rows in node order.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Properties {
    /// Each row's node, non-decreasing: a node's rows follow each other.
    nodes: Vec<u32>,
    keys: Names,
    values: Names,
}

impl Properties {
    /// Appends a property of `node`.
    ///
    /// # Panics
    /// When `node` comes before the last row's node (rows are added in node
    /// order, as importers make nodes).
    pub fn push(&mut self, node: NodeId, key: &str, value: &str) {
        assert!(
            self.nodes.last().is_none_or(|&last| last <= node.0),
            "properties are added in node order"
        );
        self.nodes.push(node.0);
        self.keys.push(key);
        self.values.push(value);
    }

    /// Rows held.
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// Whether no node has a property.
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// `node`'s properties, in the order they were added.
    pub fn of(&self, node: NodeId) -> impl Iterator<Item = (&str, &str)> + '_ {
        let start = self.nodes.partition_point(|&n| n < node.0);
        let end = start + self.nodes[start..].partition_point(|&n| n == node.0);
        (start..end).map(|r| (self.keys.get(r), self.values.get(r)))
    }

    /// The value of `node`'s property `key`, if it has one.
    pub fn get(&self, node: NodeId, key: &str) -> Option<&str> {
        self.of(node).find(|&(k, _)| k == key).map(|(_, v)| v)
    }

    /// Every row: node, key, value.
    pub fn iter(&self) -> impl Iterator<Item = (NodeId, &str, &str)> + '_ {
        (0..self.len()).map(|r| (NodeId(self.nodes[r]), self.keys.get(r), self.values.get(r)))
    }

    /// Checks that the rows are in node order, below `nodes`, and UTF-8.
    pub fn check(&self, nodes: usize) -> Result<(), String> {
        if self.keys.len() != self.len() || self.values.len() != self.len() {
            return Err(format!(
                "{} keys and {} values for {} properties",
                self.keys.len(),
                self.values.len(),
                self.len()
            ));
        }
        if let Some(r) = self.nodes.windows(2).position(|w| w[0] > w[1]) {
            return Err(format!("property {}: not in node order", r + 1));
        }
        if let Some(&n) = self.nodes.last().filter(|&&n| n as usize >= nodes) {
            return Err(format!("a property of node {n}, of {nodes} nodes"));
        }
        self.keys.check("property key")?;
        self.values.check("property value")
    }

    /// The encoding (see the module's documentation).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        for v in [
            self.len() as u64,
            self.keys.bytes.len() as u64,
            self.values.bytes.len() as u64,
        ] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        for n in &self.nodes {
            out.extend_from_slice(&n.to_le_bytes());
        }
        out.resize(out.len().next_multiple_of(8), 0);
        for names in [&self.keys, &self.values] {
            for e in &names.ends {
                out.extend_from_slice(&e.to_le_bytes());
            }
            out.extend_from_slice(&names.bytes);
        }
        out
    }

    /// Decodes [`Properties::to_bytes`] of a scene of `nodes` nodes, checked
    /// ([`Properties::check`]): anything else is an error saying what is wrong.
    pub fn from_bytes(bytes: &[u8], nodes: usize) -> Result<Self, String> {
        let mut rest = bytes;
        let mut take = |n: u64| -> Result<&[u8], String> {
            let n = usize::try_from(n)
                .ok()
                .filter(|&n| n <= rest.len())
                .ok_or_else(|| format!("{} bytes, shorter than its counts say", bytes.len()))?;
            let (head, tail) = rest.split_at(n);
            rest = tail;
            Ok(head)
        };
        let u64s = |b: &[u8]| -> Vec<u64> {
            b.chunks_exact(8)
                .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")))
                .collect()
        };
        let counts = u64s(take(24)?);
        let (rows, key_bytes, value_bytes) = (counts[0], counts[1], counts[2]);
        let node_bytes = rows.checked_mul(4).ok_or("row count overflows")?;
        let padded = node_bytes
            .checked_next_multiple_of(8)
            .ok_or("row count overflows")?;
        let nodes_read = take(padded)?[..node_bytes as usize]
            .chunks_exact(4)
            .map(|c| u32::from_le_bytes(c.try_into().expect("4 bytes")))
            .collect();
        let mut names = |bytes: u64| -> Result<Names, String> {
            Ok(Names {
                ends: u64s(take(rows.checked_mul(8).ok_or("row count overflows")?)?),
                bytes: take(bytes)?.to_vec(),
            })
        };
        let keys = names(key_bytes)?;
        let values = names(value_bytes)?;
        if !rest.is_empty() {
            return Err(format!("{} bytes after the values", rest.len()));
        }
        let p = Properties {
            nodes: nodes_read,
            keys,
            values,
        };
        p.check(nodes)?;
        Ok(p)
    }

    /// Bytes its arrays hold.
    pub fn held_bytes(&self) -> u64 {
        (self.nodes.capacity() * 4) as u64 + self.keys.held_bytes() + self.values.held_bytes()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Properties {
        let mut p = Properties::default();
        p.push(NodeId(1), "GlobalId", "2O2Fr$t4X7Zf8NOew3FLOH");
        p.push(NodeId(1), "IfcClass", "IfcWall");
        p.push(NodeId(4), "Name", "Wand-Ext-ERG-1 ünd");
        p.push(NodeId(4), "", "");
        p
    }

    #[test]
    fn rows_are_found_by_node_and_key() {
        let p = sample();
        assert_eq!(p.get(NodeId(1), "IfcClass"), Some("IfcWall"));
        assert_eq!(p.get(NodeId(4), "GlobalId"), None);
        assert_eq!(p.of(NodeId(2)).count(), 0);
        assert_eq!(p.of(NodeId(4)).count(), 2);
        assert_eq!(p.of(NodeId(9)).count(), 0);
    }

    #[test]
    fn the_encoding_reads_back_and_refuses_every_damage() {
        let p = sample();
        let bytes = p.to_bytes();
        assert_eq!(Properties::from_bytes(&bytes, 5), Ok(p.clone()));
        assert_eq!(
            Properties::from_bytes(&Properties::default().to_bytes(), 1),
            Ok(Properties::default())
        );
        // A node beyond the scene, every truncation and a trailing byte are
        // errors, never a panic.
        assert!(Properties::from_bytes(&bytes, 4).is_err());
        for n in 0..bytes.len() {
            assert!(
                Properties::from_bytes(&bytes[..n], 5).is_err(),
                "cut at {n}"
            );
        }
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(Properties::from_bytes(&longer, 5).is_err());
        // Row counts whose arrays overflow (the review's crafted store
        // panicked sizing the node array).
        for rows in [
            u64::MAX,
            u64::MAX / 4,
            0x3fff_ffff_ffff_ffff,
            u64::MAX / 8 + 1,
        ] {
            let mut huge = bytes.clone();
            huge[..8].copy_from_slice(&rows.to_le_bytes());
            assert!(Properties::from_bytes(&huge, 5).is_err(), "{rows:#x} rows");
        }
        // Every single-byte change is refused or reads as a valid table.
        for i in 0..bytes.len() {
            let mut bad = bytes.clone();
            bad[i] ^= 0xff;
            if let Ok(q) = Properties::from_bytes(&bad, 5) {
                assert_eq!(q.check(5), Ok(()));
            }
        }
    }

    #[test]
    #[should_panic(expected = "node order")]
    fn rows_out_of_node_order_are_refused() {
        let mut p = sample();
        p.push(NodeId(2), "k", "v");
    }
}
