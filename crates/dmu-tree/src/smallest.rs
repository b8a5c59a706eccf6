//! Min-heap entries: a `BinaryHeap` is a max-heap, so these compare reversed.

use std::cmp::Ordering;

/// An item in a `BinaryHeap` that pops the smallest `key` first (keys compare
/// by `total_cmp`; the item does not take part).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Smallest<T> {
    pub key: f64,
    pub item: T,
}

impl<T> PartialEq for Smallest<T> {
    fn eq(&self, other: &Self) -> bool {
        self.key.total_cmp(&other.key) == Ordering::Equal
    }
}
impl<T> Eq for Smallest<T> {}
impl<T> PartialOrd for Smallest<T> {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl<T> Ord for Smallest<T> {
    /// Reversed for the max-heap: the smallest key first.
    fn cmp(&self, other: &Self) -> Ordering {
        other.key.total_cmp(&self.key)
    }
}
