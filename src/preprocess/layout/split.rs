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
        let mut best: Option<(f64, usize, usize)> = None;
        for k in 1..n {
            if order.same_key(k) {
                continue;
            }
            let cost = cost_of(k);
            let off_centre = (2 * k).abs_diff(n);
            if best.is_none_or(|(c, o, _)| (cost, off_centre) < (c, o)) {
                best = Some((cost, off_centre, k));
            }
        }
        // n ≤ 1: everything in the low group.
        let k = if n <= 1 {
            n
        } else {
            best.map_or(n / 2, |(_, _, k)| k)
        };
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
    /// every suffix (the big-node branch of [`Splitter::cut`], the same order of preference: lowest
    /// cost, then nearest the middle, then the lower `k`), in about half the second walk.
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
        // (cost, distance from the middle, k, demand after k)
        let mut best: Option<(f64, usize, usize, u64)> = None;
        let middle = n / 2;
        let mut after_middle = 0;
        let exact_after = walk_prefix_demands(self.model, self.infos, &rev, |j, after| {
            if j >= n {
                return false;
            }
            let k = n - j;
            if k == middle {
                after_middle = after;
            }
            if best.is_some_and(|(c, ..)| after as f64 > c) {
                return false;
            }
            if !order.same_key(k) {
                let cost = before[k].max(after) as f64;
                let off_centre = (2 * k).abs_diff(n);
                // `k` falls: an equal cost and distance replaces the best, so the lowest `k` stays.
                if best.is_none_or(|(c, o, ..)| (cost, off_centre) <= (c, o)) {
                    best = Some((cost, off_centre, k, after));
                }
            }
            true
        });
        // No position between different keys (all keys equal): the middle, walked past since nothing
        // stopped the walk.
        let (k, after) = best.map_or((middle, after_middle), |(_, _, k, after)| (k, after));
        let demands = CutDemands {
            before: before[k],
            after,
            total: before[n],
            exact: exact_before && exact_after,
        };
        (k, demands)
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
mod tests {
    use super::*;
    use crate::ids::MaterialId;
    use crate::model::sizing::{SizeEstimate, SizeMethod};
    use crate::scene::Wrap;
    use glam::DVec2;

    /// A triangle of `material` at plane midpoint `mid` needing `w` texels per period over UV `[0, 1]²`.
    fn tri(mid: DVec2, material: u32, w: f64, area: f64) -> TriInfo {
        TriInfo {
            scene_tri: 0,
            piece: crate::preprocess::prepare::WHOLE,
            material: MaterialId(material),
            mid,
            area,
            size: SizeEstimate {
                w,
                h: w,
                method: SizeMethod::Exact,
            },
            class: 0,
            uv: [DVec2::ZERO, DVec2::X, DVec2::Y],
        }
    }

    fn model(materials: usize) -> DemandModel {
        DemandModel {
            sources: vec![[1024, 1024]; materials],
            wraps: vec![[Wrap::Repeat; 2]; materials],
            wrap: true,
            border: 2,
            cap_to_source: true,
        }
    }

    fn split(infos: &[TriInfo], model: &DemandModel, items: &mut [u32]) -> [usize; 4] {
        Splitter {
            infos,
            model,
            rule: SplitRule::Demand,
        }
        .split4(items)
    }

    #[test]
    fn packed_and_wide_sorts_give_one_order() {
        let mut rng = crate::util::XorShift64::new(7);
        for n in [2usize, 17, 1000, RADIX_ITEMS + 1, PAR_ITEMS + 3] {
            let keys: Vec<i64> = (0..n).map(|_| (rng.next_u64() % 300) as i64).collect();
            let items: Vec<u32> = (0..n as u32)
                .map(|i| i.wrapping_mul(2_654_435_761) % 1_000_003)
                .collect();
            let packed = SortedKeys::sort(keys.clone(), &items, n >= PAR_ITEMS, Ties::ByIndex);
            assert!(matches!(packed, SortedKeys::Packed(_)));
            let any = SortedKeys::sort(keys.clone(), &items, n >= PAR_ITEMS, Ties::Any);
            let wide = SortedKeys::wide(keys, &items, false);
            let (mut a, mut b) = (items.clone(), items.clone());
            packed.write_items(&mut a);
            wide.write_items(&mut b);
            assert_eq!(a, b, "n = {n}");
            for k in 1..n {
                assert_eq!(packed.same_key(k), wide.same_key(k), "n = {n}, k = {k}");
                assert_eq!(any.same_key(k), wide.same_key(k), "n = {n}, k = {k}");
            }
            // Ties in any order: the same runs of equal keys, each holding the same items.
            let mut c = items.clone();
            any.write_items(&mut c);
            let mut start = 0;
            for k in 1..=n {
                if k == n || !any.same_key(k) {
                    c[start..k].sort_unstable();
                    start = k;
                }
            }
            assert_eq!(c, a, "n = {n}");
        }
        // A key beyond u32 (an underflowed quantum) takes the wide path, in (key, index) order.
        let order = SortedKeys::sort(vec![5, i64::MAX, 5, 0], &[3, 2, 1, 0], false, Ties::ByIndex);
        assert!(matches!(order, SortedKeys::Wide(_)));
        let mut items = [3, 2, 1, 0];
        order.write_items(&mut items);
        assert_eq!(items, [0, 1, 3, 2]);
        assert!(order.same_key(2) && !order.same_key(1) && !order.same_key(3));
    }

    #[test]
    fn split_balances_demand_in_x_then_y() {
        // A 4×4 grid of triangles with a material each, equal demand: four 2×2 quadrants.
        let infos: Vec<TriInfo> = (0..16)
            .map(|i| tri(DVec2::new((i % 4) as f64, (i / 4) as f64), i, 60.0, 1.0))
            .collect();
        let mut items: Vec<u32> = (0..16).rev().collect();
        let g = split(&infos, &model(16), &mut items);
        assert_eq!(g, [4, 4, 4, 4]);
        let groups: Vec<&[u32]> = {
            let (a, r) = items.split_at(4);
            let (b, r) = r.split_at(4);
            let (c, d) = r.split_at(4);
            vec![a, b, c, d]
        };
        // Array order: low-x/low-y, low-x/high-y, high-x/low-y, high-x/high-y.
        let want = [(false, false), (false, true), (true, false), (true, true)];
        for (grp, (hx, hy)) in groups.iter().zip(want) {
            for &i in *grp {
                let m = infos[i as usize].mid;
                assert_eq!((m.x >= 2.0, m.y >= 2.0), (hx, hy), "triangle {i} at {m}");
            }
        }
    }

    #[test]
    fn split_demands_are_the_groups_demands_in_their_own_order() {
        use crate::preprocess::demand::demand;
        // 200 triangles of 7 shared materials, scattered midpoints, UV ranges and densities.
        let infos: Vec<TriInfo> = (0..200u32)
            .map(|i| {
                let h = i.wrapping_mul(2654435761);
                let mut t = tri(
                    DVec2::new(f64::from(h % 97), f64::from((h >> 8) % 89)),
                    h % 7,
                    f64::from(8 + (h >> 16) % 300),
                    1.0,
                );
                t.uv[1] = DVec2::new(f64::from((h >> 4) % 5) + 0.25, 0.5);
                t
            })
            .collect();
        let model = model(7);
        let s = Splitter {
            infos: &infos,
            model: &model,
            rule: SplitRule::Demand,
        };
        for n in [0usize, 1, 2, 3, 17, 200] {
            let mut items: Vec<u32> = (0..n as u32).collect();
            let (g, d) = s.split4_demands(&mut items);
            let d = d.expect("no saturation here");
            let mut start = 0;
            for (i, len) in g.into_iter().enumerate() {
                let want = demand(&model, &infos, &items[start..start + len]);
                assert_eq!(d.groups[i], want, "n {n} group {i}");
                start += len;
            }
            assert_eq!(d.total, demand(&model, &infos, &items), "n {n}");
            assert_eq!(s.split4(&mut items.clone()), g);
        }
        // The area rule computes no demands.
        let area = Splitter {
            rule: SplitRule::Area,
            ..s
        };
        assert_eq!(
            area.split4_demands(&mut (0..50).collect::<Vec<u32>>()).1,
            None
        );
    }

    #[test]
    fn a_big_node_splits_exactly_as_a_serial_twin_does() {
        use crate::preprocess::demand::prefix_demands;
        // 3 · PAR_ITEMS triangles of 40 materials (keys, sort, demand passes and y cuts on the rayon
        // pool): the order and the group sizes are those of a serial twin that sorts (key, index) and
        // picks each cut by the documented rule from serially walked demands.
        let n = 3 * PAR_ITEMS as u32;
        let mut rng = crate::util::XorShift64::new(0x517c_c1b7_2722_0a95);
        let mut next = move || rng.next_u64();
        let infos: Vec<TriInfo> = (0..n)
            .map(|_| {
                let h = next();
                let mut t = tri(
                    DVec2::new(
                        (h % 10_007) as f64 * 0.37,
                        ((h >> 16) % 9_973) as f64 * 0.41,
                    ),
                    ((h >> 32) % 40) as u32,
                    (8 + (h >> 40) % 300) as f64,
                    1.0,
                );
                t.uv[1] = DVec2::new(((h >> 48) % 5) as f64 + 0.25, 0.5);
                t
            })
            .collect();
        let model = model(40);
        let s = Splitter {
            infos: &infos,
            model: &model,
            rule: SplitRule::Demand,
        };
        // The twin: keys by the formula of `midpoint_keys`, a serial sort, the cut rule walked serially.
        let twin_cut = |items: &mut [u32], axis: usize| -> usize {
            let m = |i: u32| infos[i as usize].mid[axis];
            let lo = items.iter().map(|&i| m(i)).fold(f64::INFINITY, f64::min);
            let hi = items
                .iter()
                .map(|&i| m(i))
                .fold(f64::NEG_INFINITY, f64::max);
            let q = ((hi - lo).log2().ceil() - f64::from(MIDPOINT_BITS)).exp2();
            let mut keyed: Vec<(i64, u32)> = items
                .iter()
                .map(|&i| (((m(i) - lo) / q).floor() as i64, i))
                .collect();
            keyed.sort();
            for (slot, &(_, i)) in items.iter_mut().zip(&keyed) {
                *slot = i;
            }
            let before = prefix_demands(&model, &infos, items);
            let rev: Vec<u32> = items.iter().rev().copied().collect();
            let after = prefix_demands(&model, &infos, &rev);
            let len = items.len();
            let mut best: Option<(u64, usize, usize)> = None;
            for k in 1..len {
                if keyed[k - 1].0 == keyed[k].0 {
                    continue;
                }
                let cand = (before[k].max(after[len - k]), (2 * k).abs_diff(len), k);
                if best.is_none_or(|b| (cand.0, cand.1) < (b.0, b.1)) {
                    best = Some(cand);
                }
            }
            best.map_or(len / 2, |b| b.2)
        };
        let mut want: Vec<u32> = (0..n).rev().collect();
        let k = twin_cut(&mut want, 0);
        let (lo, hi) = want.split_at_mut(k);
        let (k0, k1) = (twin_cut(lo, 1), twin_cut(hi, 1));
        let want_groups = [k0, lo.len() - k0, k1, hi.len() - k1];
        assert!(
            lo.len().min(hi.len()) >= PAR_ITEMS,
            "both y cuts run side by side"
        );

        let mut items: Vec<u32> = (0..n).rev().collect();
        let (groups, demands) = s.split4_demands(&mut items);
        assert_eq!(groups, want_groups);
        assert!(items == want, "the split's order is the twin's");
        let d = demands.expect("no saturation here");
        assert_eq!(d.total, prefix_demands(&model, &infos, &items)[n as usize]);
    }

    #[test]
    fn the_serial_cut_stops_its_backward_walk_without_changing_the_cut() {
        use crate::preprocess::demand::prefix_demands;
        // Small nodes with few keys and materials, so costs, distances and keys tie often: the cut and
        // its demands, with the suffixes walked only as far as they matter, equal those of the branch
        // that walks both passes whole side by side, and those of the full search over every suffix.
        let mut rng = crate::util::XorShift64::new(0x2f1e_77a9_c3d4_0b15);
        let mut next = move || rng.next_u64();
        let model = model(6);
        let mut stopped_early = 0;
        for case in 0..400 {
            // The first cases are the smallest nodes: nothing, one item, two.
            let n = if case < 3 {
                case as u32
            } else {
                1 + (next() % 120) as u32
            };
            let keys = 1 + next() % 12;
            let infos: Vec<TriInfo> = (0..n)
                .map(|_| {
                    let h = next();
                    let mut t = tri(
                        DVec2::new((h % keys) as f64, ((h >> 8) % keys) as f64),
                        ((h >> 16) % 6) as u32,
                        (4 + (h >> 24) % (4 + case % 200)) as f64,
                        1.0,
                    );
                    t.uv[1] = DVec2::new(((h >> 40) % 3) as f64 + 0.5, 0.5);
                    t
                })
                .collect();
            let s = Splitter {
                infos: &infos,
                model: &model,
                rule: SplitRule::Demand,
            };
            let mut items: Vec<u32> = (0..n).collect();
            let mut both: Vec<u32> = items.clone();
            let (k, demands) = s.cut_walking_both_from(&mut items, 0, Ties::ByIndex, usize::MAX);
            let d = demands.expect("the demand rule reports its demands");
            let (k_both, d_both) = s.cut_walking_both_from(&mut both, 0, Ties::ByIndex, 0);
            assert_eq!((k, items.clone()), (k_both, both), "case {case}");
            let d_both = d_both.expect("the demand rule reports its demands");
            assert_eq!(
                (d.before, d.after, d.total, d.exact),
                (d_both.before, d_both.after, d_both.total, d_both.exact),
                "case {case}"
            );
            // The full search over the order the cut left.
            let n = n as usize;
            let keys = midpoint_keys(&infos, &items, 0);
            let before = prefix_demands(&model, &infos, &items);
            let rev: Vec<u32> = items.iter().rev().copied().collect();
            let after = prefix_demands(&model, &infos, &rev);
            let mut best: Option<(u64, usize, usize)> = None;
            for k in 1..n {
                if keys[k - 1] == keys[k] {
                    continue;
                }
                let cand = (before[k].max(after[n - k]), (2 * k).abs_diff(n), k);
                if best.is_none_or(|b| (cand.0, cand.1) < (b.0, b.1)) {
                    best = Some(cand);
                }
            }
            let want = if n <= 1 {
                n
            } else {
                best.map_or(n / 2, |b| b.2)
            };
            assert_eq!(k, want, "case {case}: n {n}");
            assert_eq!(
                (d.before, d.after, d.total),
                (before[k], after[n - k], before[n]),
                "case {case}"
            );
            // The data give the stop something to skip: a suffix longer than the cut's costs more.
            if (1..k).any(|j| after[n - j] > before[k].max(after[n - k])) {
                stopped_early += 1;
            }
        }
        assert!(
            stopped_early > 100,
            "{stopped_early} of 400 cases can stop early"
        );
    }

    #[test]
    fn split_follows_texel_demand_not_world_area() {
        // Left (x = 0..9): ten big triangles (area 100 each) sharing one texture, one period of 60 texels:
        // demand 64² however many there are. Right (x = 10..19): ten small triangles (area 1) with a
        // texture each: 10 · 64². Equal world areas would cut inside the left group (x ≈ 5); equal demand
        // cuts inside the right group, so the low half holds the shared texture and about half the small
        // ones (64² · 5.5 per side).
        let mut infos: Vec<TriInfo> = (0..10)
            .map(|i| tri(DVec2::new(f64::from(i), 0.0), 0, 60.0, 100.0))
            .collect();
        infos.extend((0..10).map(|i| tri(DVec2::new(f64::from(10 + i), 0.0), 1 + i, 60.0, 1.0)));
        let mut items: Vec<u32> = (0..20).collect();
        let m = model(11);
        let s = Splitter {
            infos: &infos,
            model: &m,
            rule: SplitRule::Demand,
        };
        let k = s.cut_sorted(&mut items, 0);
        // At a cut k ≥ 10 the low half needs 64² · (1 + k − 10), the high half 64² · (20 − k): the larger is
        // smallest (6 · 64²) at k = 14 and 15, and the tie goes to the cut nearer the middle.
        assert_eq!(k, 14, "cut at {k}");
        let area_left: f64 = items[..k].iter().map(|&i| infos[i as usize].area).sum();
        assert!(
            area_left > 900.0,
            "the low half holds the big shared triangles"
        );
    }

    #[test]
    fn split_terminates_on_identical_midpoints_and_never_separates_equal_keys() {
        let infos: Vec<TriInfo> = (0..1000)
            .map(|i| tri(DVec2::new(5.0, 5.0), i % 7, 10.0, 0.0))
            .collect();
        let mut items: Vec<u32> = (0..1000).collect();
        let g = split(&infos, &model(7), &mut items);
        assert_eq!(g.iter().sum::<usize>(), 1000);
        assert!(
            g.iter().all(|&n| n < 1000),
            "every child must shrink: {g:?}"
        );
        // Two triangles: each goes to its own child; one triangle: everything in the first group.
        let mut two = vec![0u32, 1];
        assert_eq!(
            split(&infos, &model(7), &mut two)
                .iter()
                .filter(|&&n| n == 1)
                .count(),
            2
        );
        let mut one = vec![0u32];
        assert_eq!(split(&infos, &model(7), &mut one), [1, 0, 0, 0]);
        // Midpoints 1e-9 apart are one key: the cut falls between x = 0 and x = 1, never inside the pair.
        let infos = vec![
            tri(DVec2::new(0.0, 0.0), 0, 10.0, 1.0),
            tri(DVec2::new(1e-9, 0.0), 1, 10.0, 1.0),
            tri(DVec2::new(1.0, 0.0), 2, 10.0, 1.0),
            tri(DVec2::new(1000.0, 0.0), 3, 10.0, 1.0),
        ];
        let keys = midpoint_keys(&infos, &[0, 1, 2, 3], 0);
        assert_eq!(keys[0], keys[1]);
        assert_ne!(keys[1], keys[2]);
        let m = model(4);
        let s = Splitter {
            infos: &infos,
            model: &m,
            rule: SplitRule::Demand,
        };
        let mut items = vec![0, 1, 2, 3];
        let k = s.cut_sorted(&mut items, 0);
        assert!(
            k == 2 || k == 3,
            "cut {k} must not separate triangles 0 and 1"
        );
    }
}
