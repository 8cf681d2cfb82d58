//! The traversal stack: a fixed array on the machine stack, spilling to the heap only for trees
//! deeper than any sane builder makes.

use std::mem::MaybeUninit;

/// A LIFO of `T` with `INLINE` entries stored inline; pushes beyond that go to a `Vec`.
///
/// The inline array is left uninitialized (a traversal starts one per ray, and zeroing 64
/// entries would cost more than most rays' pushes). `len` counts every entry, inline and
/// spilled: entries `0..INLINE` are inline, the rest in `spill`, so a pop asks one length
/// whether the stack is empty and (a branch that is always predicted) where its top is.
pub(crate) struct TraversalStack<T: Copy, const INLINE: usize> {
    inline: [MaybeUninit<T>; INLINE],
    len: usize,
    spill: Vec<T>,
}

impl<T: Copy, const INLINE: usize> TraversalStack<T, INLINE> {
    #[inline]
    pub fn new() -> Self {
        Self {
            inline: [const { MaybeUninit::uninit() }; INLINE],
            len: 0,
            spill: Vec::new(),
        }
    }

    #[inline]
    pub fn push(&mut self, value: T) {
        if self.len < INLINE {
            self.inline[self.len] = MaybeUninit::new(value);
        } else {
            self.spill.push(value);
        }
        self.len += 1;
    }

    /// Pushes `value` if `keep`, without branching on `keep` while the inline array has room
    /// (the value is written in any case, and counted only if kept).
    #[inline]
    pub fn push_if(&mut self, value: T, keep: bool) {
        if self.len < INLINE {
            self.inline[self.len] = MaybeUninit::new(value);
            self.len += usize::from(keep);
        } else if keep {
            self.spill.push(value);
            self.len += 1;
        }
    }

    /// Empties the stack (keeping the spill's allocation).
    #[inline]
    pub fn clear(&mut self) {
        self.len = 0;
        self.spill.clear();
    }

    #[inline]
    pub fn pop(&mut self) -> Option<T> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        if self.len < INLINE {
            // SAFETY: inline entries below `len` were written by `push`.
            Some(unsafe { self.inline[self.len].assume_init() })
        } else {
            self.spill.pop()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spills_and_keeps_lifo_order() {
        let mut s: TraversalStack<u32, 4> = TraversalStack::new();
        for i in 0..10 {
            s.push(i);
        }
        for i in (0..10).rev() {
            assert_eq!(s.pop(), Some(i));
        }
        assert_eq!(s.pop(), None);
    }

    #[test]
    fn push_if_keeps_only_what_it_is_told_to_inline_and_spilled() {
        let mut s: TraversalStack<u32, 4> = TraversalStack::new();
        for i in 0..12 {
            s.push_if(i, i % 2 == 0);
        }
        for i in (0..12).rev().filter(|i| i % 2 == 0) {
            assert_eq!(s.pop(), Some(i));
        }
        assert_eq!(s.pop(), None);
    }
}
