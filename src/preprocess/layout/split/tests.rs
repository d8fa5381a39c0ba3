//! Tests of the split (§5.3): sorts, cuts, the demand rule's two branches and the serial twin.

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

/// A splitter by the demand rule.
fn demand_splitter<'a>(infos: &'a [TriInfo], model: &'a DemandModel) -> Splitter<'a> {
    Splitter {
        infos,
        model,
        rule: SplitRule::Demand,
    }
}

fn split(infos: &[TriInfo], model: &DemandModel, items: &mut [u32]) -> [usize; 4] {
    demand_splitter(infos, model).split4(items)
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
    let s = demand_splitter(&infos, &model);
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
    let s = demand_splitter(&infos, &model);
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
        let s = demand_splitter(&infos, &model);
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
    let s = demand_splitter(&infos, &m);
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
    let s = demand_splitter(&infos, &m);
    let mut items = vec![0, 1, 2, 3];
    let k = s.cut_sorted(&mut items, 0);
    assert!(
        k == 2 || k == 3,
        "cut {k} must not separate triangles 0 and 1"
    );
}
