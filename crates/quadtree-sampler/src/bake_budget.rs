//! How a bake meets [`crate::BakeConfig::max_bytes`]: which of its trees give up which
//! nodes.
//!
//! A tree pruned by a prefix of its [`Quadtree::collapse_order`] is still exact: each
//! collapsed node samples with the proposal and bound its own evaluation found, so rejection
//! mode's density is unchanged and only its expected trials E\[T\] grow (by the collapse's
//! added live box volume over the tree's volume, which pruning keeps), and the warp proxy
//! grows coarser with it. So the bake spends its bytes where they save the most trials:
//! every collapse of every tree it may prune is ranked by the E\[T\] it adds, and the bake
//! takes the shortest run of that ranking that fits its limit (greedily, the least total
//! E\[T\] over the trees for the bytes given up: each collapse frees four nodes, about the
//! same bytes in any tree). A tree whose lobe is resolved far past the acceptance it needs
//! gives up many nodes; one whose nodes each save many trials keeps them. (Cutting every
//! large tree to one size instead, the water level of the bytes, gave Ward αx = 0.5,
//! αy = 0.003 at the default grid and 16 MiB a mean E\[T\] over its trees of 1.505 and a
//! largest of 2.18, where this gives 1.456 and 1.73; αx = 1, αy = 0.001: mean 3.19 → 2.90,
//! 90th percentile 5.29 → 3.71, and with a first build of 8 shares instead of 4, its
//! largest 9.76 → 4.72.)
//!
//! The ranking is fixed by the trees alone (ties by tree, then by the tree's own order), so
//! serial and parallel bakes prune alike. A tree is never pruned past
//! [`crate::MAX_USABLE_EXPECTED_TRIALS`].

use crate::tree::{HeapKey, Quadtree};
use alloc::collections::BinaryHeap;
use alloc::vec::Vec;
use core::cmp::Reverse;

/// A tree a bake may prune: its collapses in order, as far as E\[T\] stays usable, and its
/// volume (the live leaves' v1, which E\[T\] divides by).
#[derive(Clone, Debug)]
pub(crate) struct Prunable {
    /// [`Quadtree::collapse_order`], cut before the first collapse that would take E\[T\]
    /// past [`crate::MAX_USABLE_EXPECTED_TRIALS`].
    pub(crate) order: Vec<(u32, f64)>,
    volume: f64,
}

impl Prunable {
    /// The collapses of `q` that keep it usable.
    pub(crate) fn new(q: &Quadtree) -> Self {
        let mut order = q.collapse_order();
        let (mut boxes, mut volume) = (0.0, 0.0);
        for (_, leaf) in q.leaves() {
            if leaf.v1 > 0.0 {
                boxes += leaf.box_volume();
                volume += leaf.v1;
            }
        }
        // (A tree with no volume samples nothing: E[T] is 0 however far it is pruned.)
        if volume > 0.0 {
            let most = crate::MAX_USABLE_EXPECTED_TRIALS * volume;
            let keep = order
                .iter()
                .take_while(|s| {
                    boxes += s.1;
                    boxes <= most
                })
                .count();
            order.truncate(keep);
        }
        Self { order, volume }
    }

    /// The E\[T\] that collapse `step` of the order adds.
    fn cost(&self, step: usize) -> f64 {
        if self.volume > 0.0 {
            self.order[step].1 / self.volume
        } else {
            0.0
        }
    }
}

/// Every collapse of `trees`, as the tree it belongs to, in the bake's ranking: at each
/// step the cheapest next collapse of any tree (a tree's own collapses stay in its order,
/// which pruning needs: a prefix of it is a tree).
pub(crate) fn ranking(trees: &[Prunable]) -> Vec<u32> {
    // Each tree's next collapse: (the E[T] it adds, tree, step), least first (ties by tree).
    let mut heap: BinaryHeap<Reverse<(HeapKey, u32, u32)>> = trees
        .iter()
        .enumerate()
        .filter(|(_, t)| !t.order.is_empty())
        .map(|(k, t)| Reverse((HeapKey(t.cost(0)), k as u32, 0)))
        .collect();
    let mut ranked = Vec::with_capacity(trees.iter().map(|t| t.order.len()).sum());
    while let Some(Reverse((_, tree, step))) = heap.pop() {
        ranked.push(tree);
        let t = &trees[tree as usize];
        let next = step as usize + 1;
        if next < t.order.len() {
            heap.push(Reverse((HeapKey(t.cost(next)), tree, next as u32)));
        }
    }
    ranked
}

/// How many collapses each tree takes (in `trees`' order): the counts of the shortest
/// prefix of [`ranking`] for which `fits` holds (a bisection: `fits` is asked of about
/// log₂ of the collapses' number of prefixes, and must hold for longer ones where it holds
/// for a prefix), or `None` where even the whole ranking does not fit.
pub(crate) fn plan(
    trees: &[Prunable],
    mut fits: impl FnMut(&[usize]) -> bool,
) -> Option<Vec<usize>> {
    let ranked = ranking(trees);
    let counts = |t: usize| {
        let mut c = alloc::vec![0usize; trees.len()];
        for &k in &ranked[..t] {
            c[k as usize] += 1;
        }
        c
    };
    if fits(&counts(0)) {
        return Some(counts(0));
    }
    if !fits(&counts(ranked.len())) {
        return None;
    }
    // fits(lo) fails, fits(hi) holds.
    let (mut lo, mut hi) = (0, ranked.len());
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if fits(&counts(mid)) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(counts(hi))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tree(costs: &[f64], volume: f64) -> Prunable {
        Prunable {
            order: costs
                .iter()
                .enumerate()
                .map(|(i, &c)| (i as u32, c * volume))
                .collect(),
            volume,
        }
    }

    /// The ranking interleaves the trees by the E[T] each collapse adds (a collapse's volume
    /// over its own tree's volume), keeps each tree's own order even where it is not rising,
    /// and breaks ties by tree.
    #[test]
    fn the_ranking_takes_the_cheapest_next_collapse() {
        let trees = [
            tree(&[0.1, 0.5, 0.2], 2.0),
            tree(&[0.3, 0.3], 10.0),
            tree(&[], 1.0),
        ];
        assert_eq!(ranking(&trees), [0, 1, 1, 0, 0]);
        let tied = [tree(&[0.2], 1.0), tree(&[0.2], 3.0)];
        assert_eq!(ranking(&tied), [0, 1]);
    }

    /// The plan is the shortest prefix that fits: one collapse fewer does not. Nothing to
    /// do where nothing is over; `None` where even everything does not fit.
    #[test]
    fn the_plan_is_the_shortest_prefix_that_fits() {
        let trees = [
            tree(&[0.1, 0.5, 0.2, 0.9], 2.0),
            tree(&[0.3, 0.3, 0.4], 10.0),
        ];
        let ranked = ranking(&trees);
        assert_eq!(ranked, [0, 1, 1, 1, 0, 0, 0]);
        let nodes = [17usize, 13];
        let held = |c: &[usize]| nodes.iter().zip(c).map(|(n, c)| n - 4 * c).sum::<usize>();
        for room in 0..=30 {
            let plan = plan(&trees, |c| held(c) <= room);
            match plan {
                None => assert!(room < held(&[4, 3]), "{room}"),
                Some(c) => {
                    assert!(held(&c) <= room, "{room}: {c:?}");
                    let taken: usize = c.iter().sum();
                    if taken > 0 {
                        // One fewer of the ranking does not fit.
                        let mut less = c.clone();
                        less[ranked[taken - 1] as usize] -= 1;
                        assert!(held(&less) > room, "{room}: {c:?}");
                    }
                }
            }
        }
    }

    /// A tree is never pruned past the usable E[T]: its order stops before the collapse
    /// that would pass it.
    #[test]
    fn a_tree_stops_where_e_t_would_pass_the_usable_limit() {
        let brdf = brdf_core::registry::create("phong", ["n=1000", "kd=0"]).unwrap();
        let q = Quadtree::new(
            &*brdf,
            glam::Vec3::new(0.6, 0.0, 0.8),
            crate::BuildConfig::default(),
        )
        .unwrap();
        let all = q.collapse_order();
        let p = Prunable::new(&q);
        assert!(
            !p.order.is_empty() && p.order.len() < all.len(),
            "{} of {}",
            p.order.len(),
            all.len()
        );
        assert_eq!(p.order[..], all[..p.order.len()]);
        let e = |steps: usize| {
            let mut t = q.clone();
            t.collapse(&all[..steps]);
            t.stats().expected_trials
        };
        let limit = crate::MAX_USABLE_EXPECTED_TRIALS;
        assert!(e(p.order.len()) <= limit * (1.0 + 1e-9));
        assert!(e(p.order.len() + 1) > limit * (1.0 - 1e-9));
    }
}
