//! The step from a wide node to its children: which of those the ray meets it visits next, and in
//! which order it postpones the others.

use super::lanes::Lanes;
use super::WideLayout;
use crate::bvh::layout::stack::TraversalStack;

impl<const W: usize> WideLayout<W> {
    /// The step from a node to its children: of the children whose boxes the ray meets (`mask`,
    /// entering at `entry`), returns the one to visit next and pushes the others, with their
    /// entry distances, onto `stack` (and asks for their memory early); `None` when none is met.
    ///
    /// Nearest first (closest hit): the nearest child is visited next and the others are pushed
    /// farthest first, so that they are popped in order of distance (Wald et al. 2008 order
    /// wide-node children the same way). Any hit (`NEAREST_FIRST = false`): every met child must
    /// be searched unless a hit ends the query, so they are taken in lane order, unsorted.
    #[inline(always)]
    pub(super) fn descend<const NEAREST_FIRST: bool>(
        &self,
        children: &[u32; W],
        mask: u32,
        entry: &[f32; W],
        stack: &mut TraversalStack<(u32, f32), 64>,
    ) -> Option<u32> {
        let mut hits = Lanes(mask);
        let first = hits.next()?;
        let rest = hits.0;
        if !NEAREST_FIRST {
            if rest & rest.wrapping_sub(1) == 0 {
                // One or two: as below, without a branch on which.
                let second = if rest == 0 {
                    first
                } else {
                    rest.trailing_zeros() as usize
                };
                self.prefetch(children[second]);
                stack.push_if((children[second], entry[second]), rest != 0);
                return Some(children[first]);
            }
            for lane in hits {
                self.prefetch(children[lane]);
                stack.push((children[lane], entry[lane]));
            }
            return Some(children[first]);
        }
        if rest & rest.wrapping_sub(1) == 0 {
            // One or two children met (most nodes): visit the nearer, postpone the other if
            // there is one. Selects, not branches, on which case it is: it is unpredictable.
            let second = if rest == 0 {
                first
            } else {
                rest.trailing_zeros() as usize
            };
            let (near, far) = if entry[second] < entry[first] {
                (second, first)
            } else {
                (first, second)
            };
            self.prefetch(children[far]);
            stack.push_if((children[far], entry[far]), rest != 0);
            return Some(children[near]);
        }
        let item = |lane: usize| (children[lane], entry[lane]);
        let exchange = |x: &mut (u32, f32), y: &mut (u32, f32)| {
            let swap = x.1 < y.1;
            let (p, q) = (*x, *y);
            *x = if swap { q } else { p };
            *y = if swap { p } else { q };
        };
        let rest2 = rest & (rest - 1);
        if rest2 & (rest2 - 1) == 0 {
            // Three: a sorting network of three compare-exchanges, as selects.
            let (mut a, mut b, mut c) = (
                item(first),
                item(rest.trailing_zeros() as usize),
                item(rest2.trailing_zeros() as usize),
            );
            exchange(&mut a, &mut b);
            exchange(&mut b, &mut c);
            exchange(&mut a, &mut b);
            // a ≥ b ≥ c by entry distance: the farthest goes deepest into the stack.
            self.prefetch(a.0);
            stack.push(a);
            self.prefetch(b.0);
            stack.push(b);
            return Some(c.0);
        }
        let rest3 = rest2 & (rest2 - 1);
        if rest3 & (rest3 - 1) == 0 {
            // Four: five compare-exchanges.
            let (mut a, mut b, mut c, mut d) = (
                item(first),
                item(rest.trailing_zeros() as usize),
                item(rest2.trailing_zeros() as usize),
                item(rest3.trailing_zeros() as usize),
            );
            exchange(&mut a, &mut b);
            exchange(&mut c, &mut d);
            exchange(&mut a, &mut c);
            exchange(&mut b, &mut d);
            exchange(&mut b, &mut c);
            for x in [a, b, c] {
                self.prefetch(x.0);
                stack.push(x);
            }
            return Some(d.0);
        }
        // Five or more: insertion sort by decreasing entry distance (at most 8 entries).
        let mut order = [(0u32, 0.0f32); W];
        let mut n = 0;
        for lane in Lanes(mask) {
            let item = (children[lane], entry[lane]);
            let mut k = n;
            while k > 0 && order[k - 1].1 < item.1 {
                order[k] = order[k - 1];
                k -= 1;
            }
            order[k] = item;
            n += 1;
        }
        for &item in &order[..n - 1] {
            self.prefetch(item.0);
            stack.push(item);
        }
        Some(order[n - 1].0)
    }
}
