//! The split of §5.3: a node's triangles → four groups, in place in the permutation array.
//!
//! Triangles are sorted by their plane midpoints quantised to about `2^−MIDPOINT_BITS` of the node's
//! extent ([`midpoint_keys`]), first along x, then each half along y, and cut where the two sides
//! balance what [`SplitRule`] says: the summed texel demand ([`crate::preprocess::demand`], condition
//! (b) itself), or the summed world area (the paper's approximation). A cut never separates equal keys
//! and is kept inside `1..n`, so every group of a node with ≥ 2 triangles is smaller than the node.

use crate::preprocess::demand::{DemandModel, prefix_demands_exact, walk_prefix_demands};
use crate::preprocess::prepare::{TriInfo, walk, walk_prefix};
use serde::Serialize;

/// What the split of §5.3 balances.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Hash, Serialize)]
pub enum SplitRule {
    /// The summed texel demand of the halves, condition (b) itself ([`crate::preprocess::demand`]).
    #[default]
    Demand,
    /// The summed world area of the halves: the paper's approximation of (b), which assumes every texture
    /// point maps to one world point (no repeats, no shared textures).
    Area,
}

impl std::str::FromStr for SplitRule {
    type Err = String;
    fn from_str(s: &str) -> Result<SplitRule, String> {
        match s.to_ascii_lowercase().as_str() {
            "demand" => Ok(SplitRule::Demand),
            "area" => Ok(SplitRule::Area),
            _ => Err(format!("unknown split rule {s:?} (demand or area)")),
        }
    }
}

/// Midpoints are compared in units of `2^(ceil(log2 extent) − MIDPOINT_BITS)` of the node's extent along
/// the sorted axis.
pub const MIDPOINT_BITS: i32 = 24;

/// Quantised plane midpoints of `items` along `axis` (0: x, 1: y of the plane): `floor((mid − min) / q)`
/// with `q = 2^(ceil(log2 extent) − MIDPOINT_BITS)`, the extent that of the items' midpoints. A translation
/// of the scene that perturbs every midpoint by rounding (≪ q) leaves the keys unchanged except for
/// midpoints within that rounding of a bucket edge; the quantum follows the node, so deep nodes of tiny
/// triangles still separate them.
pub fn midpoint_keys(infos: &[TriInfo], items: &[u32], axis: usize) -> Vec<i64> {
    use rayon::prelude::*;
    let big = items.len() >= PAR_ITEMS;
    // One walk over the records (random in memory) gathers the midpoints, kept as their bits in the
    // vector whose entries then become the keys in place; min, max and the keys read it in order.
    let mut keys = vec![0i64; items.len()];
    let gather = |(out, run): (&mut [i64], &[u32])| {
        for (key, t) in out
            .iter_mut()
            .zip(walk_prefix(infos, run, TriInfo::MID_BYTES))
        {
            *key = t.mid[axis].to_bits() as i64;
        }
    };
    let mid = |key: i64| f64::from_bits(key as u64);
    let range = |(a, b): (f64, f64), &key: &i64| (a.min(mid(key)), b.max(mid(key)));
    let empty = (f64::INFINITY, f64::NEG_INFINITY);
    // Min and max are exact in any order.
    let (lo, hi) = if big {
        keys.par_chunks_mut(PAR_CHUNK)
            .zip(items.par_chunks(PAR_CHUNK))
            .for_each(gather);
        keys.par_chunks(PAR_CHUNK)
            .map(|run| run.iter().fold(empty, range))
            .reduce(|| empty, |(a, b), (c, d)| (a.min(c), b.max(d)))
    } else {
        gather((&mut keys, items));
        keys.iter().fold(empty, range)
    };
    let q = key_quantum(hi - lo);
    let to_key = |key: &mut i64| *key = ((mid(*key) - lo) / q).floor() as i64;
    if big {
        keys.par_iter_mut().for_each(to_key);
    } else {
        keys.iter_mut().for_each(to_key);
    }
    keys
}

/// The key quantum of [`midpoint_keys`] for midpoints spanning `extent`.
fn key_quantum(extent: f64) -> f64 {
    if extent.is_finite() && extent > 0.0 {
        (extent.log2().ceil() - f64::from(MIDPOINT_BITS)).exp2()
    } else {
        1.0
    }
}

/// Items from which a demand cut walks every suffix beside the prefixes, on the rayon pool; below it
/// ([`Splitter::demand_cut_serial`]) the suffixes are walked after the prefixes, and only as far as they
/// can matter: about 1.5 walks of the node where two ran side by side, which is less work once the
/// recursion below the top has several nodes in flight.
const PAR_DEMAND_ITEMS: usize = 1 << 20;

/// Items from which a cut sorts and walks its demand passes on the rayon pool (the results are the same
/// either way; below this the tasks cost more than they save).
const PAR_ITEMS: usize = 1 << 15;

/// Items per task of the parallel passes over a big node.
const PAR_CHUNK: usize = 1 << 14;

/// Splits triangle sets in four by texel demand (paper §5.3 with condition (b) itself).
pub struct Splitter<'a> {
    pub infos: &'a [TriInfo],
    pub model: &'a DemandModel,
    pub rule: SplitRule,
}

impl Splitter<'_> {
    /// Splits `items` in place into four groups: sort by quantised plane-midpoint x and cut where the texel
    /// demand of the two halves is balanced, then each half likewise by y. Returns the group lengths in
    /// array order (low-x/low-y, low-x/high-y, high-x/low-y, high-x/high-y). Every group is shorter than
    /// `items` when `items.len() ≥ 2`: the cut is kept inside `1..n`, so thousands of triangles with one
    /// midpoint still split.
    pub fn split4(&self, items: &mut [u32]) -> [usize; 4] {
        self.split4_demands(items).0
    }

    /// [`Splitter::split4`], with the texel demands of the four groups and of all `items` where the
    /// demand rule's passes give them exactly ([`SplitDemands`]).
    pub fn split4_demands(&self, items: &mut [u32]) -> ([usize; 4], Option<SplitDemands>) {
        // The x cut's ties may come in any order: each half is then sorted by (y key, index), an order
        // that does not depend on the one it arrives in, and the x cut itself depends only on which items
        // lie before each key boundary (demands are of sets, and a cut never separates equal keys).
        let (k, x) = self.cut(items, 0, Ties::Any);
        let (lo, hi) = items.split_at_mut(k);
        // The halves are independent: on big nodes (the top of a city) they run side by side.
        let y_cut = |half: &mut [u32]| self.cut(half, 1, Ties::ByIndex);
        let ((k0, y0), (k1, y1)) = if lo.len().min(hi.len()) >= PAR_ITEMS {
            rayon::join(|| y_cut(lo), || y_cut(hi))
        } else {
            (y_cut(lo), y_cut(hi))
        };
        let groups = [k0, lo.len() - k0, k1, hi.len() - k1];
        let demands = match (x, y0, y1) {
            (Some(x), Some(y0), Some(y1)) if x.exact && y0.exact && y1.exact => {
                Some(SplitDemands {
                    groups: [y0.before, y0.after, y1.before, y1.after],
                    total: x.total,
                })
            }
            _ => None,
        };
        (groups, demands)
    }

    /// Sorts `items` by key `axis` (ties by index, deterministic) and returns the cut index: among the
    /// positions between different keys, the one where `max(demand(before), demand(after))` is smallest
    /// ([`SplitRule::Demand`]; with [`SplitRule::Area`], where the world area before is closest to half),
    /// ties nearest the middle, then the lower. Without such a position (all keys equal) the middle; for
    /// n ≤ 1 it returns n (everything in the low group).
    pub fn cut_sorted(&self, items: &mut [u32], axis: usize) -> usize {
        self.cut(items, axis, Ties::ByIndex).0
    }

    /// [`Splitter::cut_sorted`], with the demands of both sides under [`SplitRule::Demand`]; with
    /// [`Ties::Any`] items of equal keys may stay in any order (the cut and the demands are the same).
    fn cut(&self, items: &mut [u32], axis: usize, ties: Ties) -> (usize, Option<CutDemands>) {
        self.cut_walking_both_from(items, axis, ties, PAR_DEMAND_ITEMS)
    }

    /// [`Splitter::cut`], walking every suffix beside the prefixes from `both_from` items (else
    /// [`Splitter::demand_cut_serial`]); the same cut and demands either way (unit test).
    fn cut_walking_both_from(
        &self,
        items: &mut [u32],
        axis: usize,
        ties: Ties,
        both_from: usize,
    ) -> (usize, Option<CutDemands>) {
        let n = items.len();
        let big = n >= PAR_ITEMS;
        let order = if n > 1 {
            let keys = midpoint_keys(self.infos, items, axis);
            let order = SortedKeys::sort(keys, items, big, ties);
            order.write_items(items);
            order
        } else {
            SortedKeys::Packed(Vec::new())
        };
        if self.rule == SplitRule::Demand && n < both_from {
            let (k, demands) = self.demand_cut_serial(items, &order);
            return (k, Some(demands));
        }
        // Demand rule on the biggest nodes (the top of a city, where the rest of the pool has little to
        // do): the demand of every prefix walked forwards and of every suffix walked backwards, two
        // independent passes side by side.
        let sides = (self.rule == SplitRule::Demand).then(|| {
            let forwards = || prefix_demands_exact(self.model, self.infos, items);
            let backwards = || {
                let rev: Vec<u32> = items.iter().rev().copied().collect();
                prefix_demands_exact(self.model, self.infos, &rev)
            };
            let ((before, exact_before), (after, exact_after)) = rayon::join(forwards, backwards);
            (before, after, exact_before && exact_after)
        });
        // Area rule: the world area of every prefix.
        let mut areas = Vec::new();
        if sides.is_none() {
            areas.push(0.0f64);
            for t in walk(self.infos, items) {
                areas.push(areas[areas.len() - 1] + t.area);
            }
        }
        let half = 0.5 * areas.last().copied().unwrap_or(0.0);
        let cost_of = |k: usize| match &sides {
            Some((before, after, _)) => before[k].max(after[n - k]) as f64,
            None => (areas[k] - half).abs(),
        };
        let mut best = BestCut::new(n);
        for k in (1..n).filter(|&k| !order.same_key(k)) {
            best.offer(k, cost_of(k));
        }
        // n ≤ 1: everything in the low group.
        let k = if n <= 1 { n } else { best.k().unwrap_or(n / 2) };
        let demands = sides.map(|(before, after, exact)| CutDemands {
            before: before[k],
            after: after[n - k],
            total: before[n],
            exact,
        });
        (k, demands)
    }

    /// The demand rule's cut of sorted `items` on one thread: the demand of every prefix, then the
    /// suffixes walked backwards only while they can still give the cut. The cost `max(before,
    /// after)` of a cut at `k` is at least the demand after it, which only grows as `k` falls: once that
    /// exceeds the best cost so far, no lower `k` can match it. The same cut and demands as walking
    /// every suffix (the big-node branch of [`Splitter::cut`], the same [`BestCut`]), in about half the
    /// second walk.
    fn demand_cut_serial(&self, items: &[u32], order: &SortedKeys) -> (usize, CutDemands) {
        let n = items.len();
        let (before, exact_before) = prefix_demands_exact(self.model, self.infos, items);
        if n <= 1 {
            // Everything in the low group: the demand after the cut is that of nothing.
            let demands = CutDemands {
                before: before[n],
                after: 0,
                total: before[n],
                exact: exact_before,
            };
            return (n, demands);
        }
        let rev: Vec<u32> = items.iter().rev().copied().collect();
        let mut best = BestCut::new(n);
        // The demand after the best cut so far, and after the middle.
        let (mut after_best, mut after_middle) = (0, 0);
        let middle = n / 2;
        let exact_after = walk_prefix_demands(self.model, self.infos, &rev, |j, after| {
            if j >= n {
                return false;
            }
            let k = n - j;
            if k == middle {
                after_middle = after;
            }
            if best.cost().is_some_and(|c| after as f64 > c) {
                return false;
            }
            if !order.same_key(k) && best.offer(k, before[k].max(after) as f64) {
                after_best = after;
            }
            true
        });
        // No position between different keys (all keys equal): the middle, walked past since nothing
        // stopped the walk.
        let (k, after) = best.k().map_or((middle, after_middle), |k| (k, after_best));
        let demands = CutDemands {
            before: before[k],
            after,
            total: before[n],
            exact: exact_before && exact_after,
        };
        (k, demands)
    }
}

/// The cut a split takes among the positions offered: the lowest cost, then the nearest the middle of
/// `n` items, then the lowest `k`, in whatever order they are offered (the big-node walk offers them
/// upwards, the serial demand cut downwards).
struct BestCut {
    n: usize,
    /// (cost, distance from the middle, k)
    best: Option<(f64, usize, usize)>,
}

impl BestCut {
    fn new(n: usize) -> Self {
        BestCut { n, best: None }
    }

    /// Offers the cut at `k` of cost `cost`; true where it is now the best.
    fn offer(&mut self, k: usize, cost: f64) -> bool {
        let candidate = (cost, (2 * k).abs_diff(self.n), k);
        let better = self.best.is_none_or(|b| candidate < b);
        if better {
            self.best = Some(candidate);
        }
        better
    }

    fn cost(&self) -> Option<f64> {
        self.best.map(|(c, ..)| c)
    }

    fn k(&self) -> Option<usize> {
        self.best.map(|(.., k)| k)
    }
}

/// How a sort orders items of equal keys.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
enum Ties {
    /// By index: the pairs are distinct, so every sort gives the one order.
    ByIndex,
    /// In any order (deterministic for a given input): the radix sort then passes over the key's bytes
    /// only, 3 of the packed value's 6 varying bytes.
    Any,
}

/// A node's items sorted by (midpoint key, index): the pairs are distinct, so every sort gives the one
/// order (with [`Ties::Any`], by key alone). Keys in `0..2³²` (always, but for midpoint extents near the
/// smallest f64, see [`key_quantum`]) are sorted packed with their index into one `u64` (`key << 32 |
/// index`: the same order, half the bytes to move; from [`RADIX_ITEMS`] by the `radsort` crate's LSD
/// radix sort, which skips the bytes every value shares: packed keys vary in about 6 of their 8, and a
/// pass costs ~2 ns a value where a comparison sort of the same keys took ~24 ns); other keys as
/// `(i64, u32)` pairs (on the rayon pool for big nodes).
enum SortedKeys {
    Packed(Vec<u64>),
    Wide(Vec<(i64, u32)>),
}

impl SortedKeys {
    fn sort(keys: Vec<i64>, items: &[u32], big: bool, ties: Ties) -> SortedKeys {
        if keys.iter().all(|&k| u32::try_from(k).is_ok()) {
            let mut packed: Vec<u64> = keys
                .iter()
                .zip(items)
                .map(|(&k, &i)| ((k as u64) << 32) | u64::from(i))
                .collect();
            if packed.len() >= RADIX_ITEMS && ties == Ties::Any {
                radsort::sort_by_key(&mut packed, |&v| (v >> 32) as u32);
            } else if packed.len() >= RADIX_ITEMS {
                radsort::sort(&mut packed);
            } else {
                packed.sort_unstable();
            }
            return SortedKeys::Packed(packed);
        }
        SortedKeys::wide(keys, items, big)
    }

    fn wide(keys: Vec<i64>, items: &[u32], big: bool) -> SortedKeys {
        use rayon::prelude::*;
        let mut pairs: Vec<(i64, u32)> = keys.into_iter().zip(items.iter().copied()).collect();
        if big {
            pairs.par_sort_unstable();
        } else {
            pairs.sort_unstable();
        }
        SortedKeys::Wide(pairs)
    }

    /// Writes the items in sorted order.
    fn write_items(&self, items: &mut [u32]) {
        match self {
            SortedKeys::Packed(p) => {
                for (slot, &v) in items.iter_mut().zip(p) {
                    *slot = v as u32;
                }
            }
            SortedKeys::Wide(p) => {
                for (slot, &(_, i)) in items.iter_mut().zip(p) {
                    *slot = i;
                }
            }
        }
    }

    /// Whether sorted positions `k − 1` and `k` share their key (`1 ≤ k < n`).
    fn same_key(&self, k: usize) -> bool {
        match self {
            SortedKeys::Packed(p) => p[k - 1] >> 32 == p[k] >> 32,
            SortedKeys::Wide(p) => p[k - 1].0 == p[k].0,
        }
    }
}

/// Items from which packed keys are radix-sorted ([`SortedKeys`]).
const RADIX_ITEMS: usize = 1 << 12;

/// The texel demands a demand-rule split computed anyway ([`Splitter::split4_demands`]), when both passes
/// of every cut were exact ([`prefix_demands_exact`]): `groups[i]` is the demand of group `i` (array
/// order), `total` that of all items. Each equals the demand of the same triangles in any order, so the
/// layout need not walk them again.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct SplitDemands {
    pub groups: [u64; 4],
    pub total: u64,
}

/// One cut's demands: of the items before the cut, after it (walked backwards), and of all of them.
#[derive(Copy, Clone, Debug)]
struct CutDemands {
    before: u64,
    after: u64,
    total: u64,
    exact: bool,
}

#[cfg(test)]
mod tests;
