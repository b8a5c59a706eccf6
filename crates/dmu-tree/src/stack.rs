//! The traversal stack of ray searches: nodes still to see, each with the
//! distance at which the ray enters it.

/// A traversal stack that lives on the call stack up to 64 deep and spills
/// to the heap beyond (a BVH of a degenerate chunk can be deeper).
pub(crate) struct Stack {
    inline: [(u32, f64); 64],
    len: usize,
    spill: Vec<(u32, f64)>,
}

impl Stack {
    pub(crate) fn new() -> Self {
        Self {
            inline: [(0, 0.0); 64],
            len: 0,
            spill: Vec::new(),
        }
    }

    pub(crate) fn push(&mut self, item: (u32, f64)) {
        if self.len < self.inline.len() {
            self.inline[self.len] = item;
            self.len += 1;
        } else {
            self.spill.push(item);
        }
    }

    pub(crate) fn pop(&mut self) -> Option<(u32, f64)> {
        if let Some(item) = self.spill.pop() {
            return Some(item);
        }
        self.len = self.len.checked_sub(1)?;
        Some(self.inline[self.len])
    }
}

/// How far a ray search looks past its nearest hit so far: a box's computed
/// entry distance may lie a few ulps beyond the computed distance of a
/// triangle on its face, and such a box must still be searched (the
/// triangle test then decides exactly). One part in 10⁹ is far above those
/// ulps and costs a few extra box visits at most.
pub(crate) fn reach(t_max: f64) -> f64 {
    t_max * (1.0 + 1e-9)
}
