//! Mailboxes: a ray never tests the same triangle twice while walking a grid.

/// A small hashed mailbox, one per query on the stack (Amanatides & Woo 1987 keep a ray number
/// in each object; Kirk & Arvo 1991 give the hashed form).
///
/// A triangle that overlaps several cells is listed in each of them; the walk meets it again in
/// every cell it crosses. Slot `id mod 64` remembers the last triangle tested there: a repeat
/// that finds itself in its slot is skipped. Two triangles that share a slot only evict each
/// other, which costs a repeated test, never a wrong answer: skipping is safe because a test's
/// answer can only get worse for a triangle later in the same query (the ray's `tmax` only
/// shrinks). Being local to one query, it needs no locks and no per-thread state.
#[derive(Clone, Debug)]
pub struct Mailbox {
    slots: [u32; Self::SLOTS],
}

impl Default for Mailbox {
    fn default() -> Self {
        Self::new()
    }
}

impl Mailbox {
    /// Slots: 256 bytes, enough for the triangles of a few dozen cells.
    pub const SLOTS: usize = 64;

    /// An empty mailbox (no id is `u32::MAX`: grids hold fewer triangles).
    pub fn new() -> Self {
        Self {
            slots: [u32::MAX; Self::SLOTS],
        }
    }

    /// Whether `id` was the last triangle posted to its slot; posts it if not.
    #[inline]
    pub fn seen_or_post(&mut self, id: u32) -> bool {
        let slot = &mut self.slots[id as usize % Self::SLOTS];
        if *slot == id {
            true
        } else {
            *slot = id;
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn repeats_are_seen_collisions_only_evict() {
        let mut m = Mailbox::new();
        assert!(!m.seen_or_post(3));
        assert!(m.seen_or_post(3));
        assert!(!m.seen_or_post(3 + Mailbox::SLOTS as u32));
        // 3 was evicted: tested again, never wrongly skipped.
        assert!(!m.seen_or_post(3));
        assert!(!m.seen_or_post(u32::MAX - 1));
    }
}
