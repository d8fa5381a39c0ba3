//! The UV range one atlas rect must hold along one texture axis (docs/DESIGN.md "Repeats: one period per rect,
//! wrapped in the shader"; the paper's future work §8.2).
//!
//! Input: the UV interval `[lo, hi]` of every triangle of one material in one node along one axis, each
//! already shifted by whole periods ([`super::prepare::period_shift`]: `lo ∈ [0, 1)` on REPEAT axes,
//! `lo ∈ [0, 2)` on MIRRORED_REPEAT axes, unshifted on CLAMP axes). Output: the range `[uv_min, uv_max]`
//! the rect's inner rectangle shows and its [`RectWrap`]:
//!
//! - [`RectWrap::Linear`] (baked, `--repeat bake`): the hull of the intervals, every period copied.
//! - [`RectWrap::Repeat`]: the shortest arc of the unit circle (UV mod 1) containing every interval;
//!   exactly one period `[0, 1]` when the intervals cover the circle (or one triangle alone spans a
//!   period). `uv_max − uv_min ≤ 1` always.
//! - [`RectWrap::Mirror`]: the hull of the intervals folded into `[0, 1]` (mirror period 2).
//! - [`RectWrap::Clamp`]: the hull of the intervals clamped to `[0, 1]`.
//!
//! Contract (checked by `inspect --verify`): for every input interval, every `u` in it lands inside
//! `[0, uv_max − uv_min]` under [`crate::model::transform::rect_t`], to within f64 rounding. Non-finite intervals
//! are ignored; no interval at all gives the point range `[0, 0]`.

use crate::model::RectWrap;
use crate::model::transform::mirror_image;

/// A gap of the circle shorter than this (UV) is not worth a partial arc: the rect holds a full period.
pub const MIN_GAP: f64 = 1e-6;

/// Accumulates the intervals of one axis of one rect.
#[derive(Clone, Debug, Default)]
pub struct AxisCover {
    wrap: RectWrap,
    lo: f64,
    hi: f64,
    /// Repeat only: the intervals on the circle unrolled onto `[0, 1]` ([`unroll`]), the first
    /// `merged` of them sorted disjoint components ([`merge_pieces`]), the rest as added.
    pieces: Vec<(f64, f64)>,
    merged: usize,
    /// Repeat only: some interval spans a whole period.
    full: bool,
    any: bool,
}

impl AxisCover {
    pub fn new(wrap: RectWrap) -> AxisCover {
        AxisCover {
            wrap,
            lo: f64::INFINITY,
            hi: f64::NEG_INFINITY,
            ..AxisCover::default()
        }
    }

    /// Adds one triangle's interval `[lo, hi]` (`lo ≤ hi`; non-finite values are ignored).
    pub fn add(&mut self, lo: f64, hi: f64) {
        if !(lo.is_finite() && hi.is_finite()) || hi < lo {
            return;
        }
        self.any = true;
        match self.wrap {
            RectWrap::Linear => self.hull(lo, hi),
            RectWrap::Clamp => self.hull(lo.clamp(0.0, 1.0), hi.clamp(0.0, 1.0)),
            RectWrap::Mirror => {
                let (a, b) = mirror_image(lo, hi);
                self.hull(a, b);
            }
            RectWrap::Repeat => {
                if self.full {
                    return;
                }
                if hi - lo >= 1.0 {
                    self.full = true;
                    self.pieces = Vec::new();
                    return;
                }
                let start = lo - lo.floor();
                let added = self.pieces.len();
                unroll((start, start + (hi - lo)), &mut self.pieces);
                // A piece inside a merged component changes neither a later merge nor the arc (the union
                // of the pieces is the same): most triangles of a repeated texture fall inside what their
                // neighbours already cover, and are dropped here instead of sorted at every merge.
                let mut k = added;
                while k < self.pieces.len() {
                    if covered(&self.pieces[..self.merged], self.pieces[k]) {
                        self.pieces.swap_remove(k);
                    } else {
                        k += 1;
                    }
                }
                // Many triangles of one texture overlap on the circle: merging them now and then keeps the
                // list (and the final sort) at the size of the union, not of the triangles.
                if self.pieces.len() >= (2 * self.merged).max(MERGE_MIN) {
                    merge_pieces(&mut self.pieces);
                    self.merged = self.pieces.len();
                }
            }
        }
    }

    /// Adds every interval `other` holds (same wrap): the cover of the union of both inputs, whichever
    /// way they were split. Hulls take min and max; repeat pieces are pooled (an arc of the same set of
    /// pieces is the same bit for bit in any order, [`shortest_arc`]), so covers of a node's triangles
    /// accumulated in pieces on several threads and absorbed give the one-pass cover exactly.
    pub fn absorb(&mut self, other: AxisCover) {
        debug_assert_eq!(self.wrap, other.wrap);
        self.any |= other.any;
        self.hull(other.lo, other.hi);
        if self.full || other.full {
            self.full = true;
            self.pieces = Vec::new();
            self.merged = 0;
            return;
        }
        self.pieces.extend(other.pieces);
        // The pooled list is no longer sorted: merge it now (the arc is unchanged) or leave it as added.
        if self.pieces.len() >= MERGE_MIN {
            merge_pieces(&mut self.pieces);
            self.merged = self.pieces.len();
        } else {
            self.merged = 0;
        }
    }

    fn hull(&mut self, lo: f64, hi: f64) {
        self.lo = self.lo.min(lo);
        self.hi = self.hi.max(hi);
    }

    /// `(uv_min, uv_max)` of the rect along this axis (see the module docs).
    pub fn range(&self) -> (f64, f64) {
        if !self.any {
            return (0.0, 0.0);
        }
        match self.wrap {
            RectWrap::Repeat if self.full => (0.0, 1.0),
            RectWrap::Repeat => {
                let (start, span) = arc_of_pieces(self.pieces.clone());
                (start, start + span)
            }
            _ => (self.lo, self.hi),
        }
    }

    pub fn wrap(&self) -> RectWrap {
        self.wrap
    }
}

/// Pieces an [`AxisCover`] holds before it first merges them.
const MERGE_MIN: usize = 64;

/// One arc `(start, end)` (`0 ≤ start ≤ 1`, `end < start + 1`) unrolled onto `[0, 1]`: an arc past 1
/// becomes two pieces; a start of exactly 1 (rounding of a period shift) is the same point as 0.
fn unroll((s, e): (f64, f64), pieces: &mut Vec<(f64, f64)>) {
    let (s, e) = if s >= 1.0 { (s - 1.0, e - 1.0) } else { (s, e) };
    if e > 1.0 {
        pieces.push((s, 1.0));
        pieces.push((0.0, e - 1.0));
    } else {
        pieces.push((s, e));
    }
}

/// Whether `piece` lies inside one of `merged` (sorted disjoint components, as [`merge_pieces`] leaves
/// them): the component with the last start at or before the piece's start ends at or after its end.
fn covered(merged: &[(f64, f64)], (s, e): (f64, f64)) -> bool {
    let i = merged.partition_point(|c| c.0 <= s);
    i > 0 && e <= merged[i - 1].1
}

fn sort_pieces(pieces: &mut [(f64, f64)]) {
    pieces.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
}

/// Sorts `pieces` and replaces each run that the sweep of [`arc_of_pieces`] would find no gap in (a piece
/// starting at or before the running end) by one piece from its first start to its largest end. Both are
/// endpoints of the input, and the gaps between runs are the sweep's gaps, so [`arc_of_pieces`] gives the
/// same arc, bit for bit, before and after.
fn merge_pieces(pieces: &mut Vec<(f64, f64)>) {
    sort_pieces(pieces);
    let mut out = 0;
    for i in 1..pieces.len() {
        let (s, e) = pieces[i];
        if s > pieces[out].1 {
            out += 1;
            pieces[out] = (s, e);
        } else {
            pieces[out].1 = pieces[out].1.max(e);
        }
    }
    pieces.truncate((out + 1).min(pieces.len()));
}

/// The shortest arc of the unit circle containing every arc `(start, end)` (`0 ≤ start < 1`,
/// `end < start + 1`): `(arc start in [0, 1), length in [0, 1])`. Length 1 (start 0) when the arcs leave
/// no gap of at least [`MIN_GAP`]. Deterministic for a given set of arcs, whatever their order.
pub fn shortest_arc(arcs: &[(f64, f64)]) -> (f64, f64) {
    let mut pieces: Vec<(f64, f64)> = Vec::with_capacity(arcs.len() + 4);
    for &a in arcs {
        unroll(a, &mut pieces);
    }
    arc_of_pieces(pieces)
}

/// [`shortest_arc`] of arcs already unrolled onto `[0, 1]` (in any order, merged or not).
fn arc_of_pieces(mut pieces: Vec<(f64, f64)>) -> (f64, f64) {
    if pieces.is_empty() {
        return (0.0, 0.0);
    }
    sort_pieces(&mut pieces);
    // Merge and find the largest gap; the gap across 1 → 0 wraps around.
    let mut best_gap = -1.0f64;
    let mut best_start = 0.0f64;
    let (first_start, _) = pieces[0];
    let mut end = pieces[0].1;
    for &(s, e) in &pieces[1..] {
        if s > end {
            let gap = s - end;
            if gap > best_gap {
                best_gap = gap;
                best_start = s;
            }
        }
        end = end.max(e);
    }
    let wrap_gap = 1.0 - end + first_start;
    if wrap_gap > best_gap {
        best_gap = wrap_gap;
        best_start = first_start;
    }
    if best_gap < MIN_GAP {
        return (0.0, 1.0);
    }
    (best_start, (1.0 - best_gap).max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::transform::rect_t;

    fn cover(wrap: RectWrap, ivs: &[(f64, f64)]) -> (f64, f64) {
        cover_of(wrap, ivs).range()
    }

    /// Every u of every interval lands in [0, span] (the module contract).
    fn assert_contract(wrap: RectWrap, ivs: &[(f64, f64)]) {
        let (lo, hi) = cover(wrap, ivs);
        let span = hi - lo;
        for &(a, b) in ivs {
            for k in 0..=64 {
                let u = a + (b - a) * f64::from(k) / 64.0;
                let t = rect_t(u, wrap, lo, hi);
                assert!(
                    (-1e-9..=span + 1e-9).contains(&t),
                    "{wrap:?} {ivs:?}: u {u} → t {t} outside [0, {span}] (range {lo}..{hi})"
                );
            }
        }
    }

    #[test]
    fn merging_pieces_keeps_the_arc_bit_for_bit() {
        // Sets of 1 to 3,000 arcs (merged several times past MERGE_MIN): the cover's range is exactly
        // shortest_arc of all the arcs unmerged, from a few wide arcs (gaps) to many narrow ones.
        let mut rng = crate::util::XorShift64::new(0x9e37_79b9_7f4a_7c15);
        let mut next = move || rng.next_f64();
        for (n, width) in [
            (1, 0.3),
            (40, 0.01),
            (65, 0.002),
            (500, 0.0005),
            (3000, 0.0001),
            (3000, 0.4),
        ] {
            let mut c = AxisCover::new(RectWrap::Repeat);
            let mut arcs = Vec::new();
            for _ in 0..n {
                let lo = next() * 3.0 - 1.0;
                let hi = lo + next() * width;
                c.add(lo, hi);
                let start = lo - lo.floor();
                arcs.push((start, start + (hi - lo)));
            }
            let (start, span) = shortest_arc(&arcs);
            let (a, b) = c.range();
            assert_eq!(
                (a.to_bits(), b.to_bits()),
                (start.to_bits(), (start + span).to_bits()),
                "n {n}"
            );
            assert!(n < MERGE_MIN || c.merged > 0, "n {n}: never merged");
        }
    }

    #[test]
    fn pieces_inside_a_merged_component_are_dropped_and_the_arc_is_unchanged() {
        // 20,000 overlapping arcs of one texture in two clusters (0.1–0.4 and 0.6–0.95 of the period): the
        // list holds the two merged clusters, and the range is shortest_arc of every arc.
        let mut rng = crate::util::XorShift64::new(0x51_7cc1_b727_220a);
        let mut next = move || rng.next_f64();
        let mut c = AxisCover::new(RectWrap::Repeat);
        let mut arcs = Vec::new();
        for i in 0..20_000 {
            let (base, room) = if i % 2 == 0 { (0.1, 0.3) } else { (0.6, 0.35) };
            let a = base + next() * room * 0.9;
            let b = (a + next() * 0.05).min(base + room);
            let shift = (next() * 7.0).floor() - 3.0;
            c.add(a + shift, b + shift);
            arcs.push((a, b));
            // Once the clusters are covered (well before half-way) every new piece is dropped: without
            // the check the list would grow back to MERGE_MIN between merges.
            if i >= 10_000 {
                assert!(c.pieces.len() <= 4, "{} pieces after {i}", c.pieces.len());
            }
        }
        let (start, span) = shortest_arc(&arcs);
        let (a, b) = c.range();
        assert_eq!(
            (a.to_bits(), b.to_bits()),
            (start.to_bits(), (start + span).to_bits())
        );
        // Containment is inclusive at both ends and never reaches across a gap.
        let merged = [(0.1, 0.2), (0.5, 0.7)];
        assert!(covered(&merged, (0.1, 0.2)));
        assert!(covered(&merged, (0.55, 0.7)));
        assert!(!covered(&merged, (0.15, 0.2000001)));
        assert!(!covered(&merged, (0.3, 0.31)));
        assert!(!covered(&merged, (0.05, 0.1)));
        assert!(!covered(&merged, (0.15, 0.6)));
        assert!(!covered(&[], (0.1, 0.1)));
    }

    #[test]
    fn absorbed_pieces_give_the_one_pass_cover_bit_for_bit() {
        // 1 to 3,000 intervals, split into 1–7 runs at arbitrary places, each run accumulated on its own and
        // absorbed in order: every wrap's range equals the one-pass cover exactly; a full period in one run
        // makes the whole cover full.
        let mut rng = crate::util::XorShift64::new(0x2545_f491_4f6c_dd1d);
        let mut next = move || rng.next_f64();
        let wraps = [
            RectWrap::Repeat,
            RectWrap::Mirror,
            RectWrap::Clamp,
            RectWrap::Linear,
        ];
        let mut checked = 0;
        for (n, width) in [
            (1, 0.3),
            (40, 0.01),
            (200, 0.002),
            (3000, 0.0001),
            (500, 1.2),
        ] {
            let ivs: Vec<(f64, f64)> = (0..n)
                .map(|_| {
                    let lo = next() * 3.0 - 1.0;
                    (lo, lo + next() * width)
                })
                .collect();
            for runs in 1..=7usize {
                let mut cuts: Vec<usize> =
                    (1..runs).map(|_| (next() * n as f64) as usize).collect();
                cuts.extend([0, n]);
                cuts.sort_unstable();
                for wrap in wraps {
                    let whole = cover_of(wrap, &ivs);
                    let mut pooled = AxisCover::new(wrap);
                    for w in cuts.windows(2) {
                        pooled.absorb(cover_of(wrap, &ivs[w[0]..w[1]]));
                    }
                    let (a, b) = whole.range();
                    let (c, d) = pooled.range();
                    assert_eq!(
                        (a.to_bits(), b.to_bits()),
                        (c.to_bits(), d.to_bits()),
                        "{wrap:?} n {n} runs {runs}"
                    );
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 5 * 7 * 4);
        let mut full = AxisCover::new(RectWrap::Repeat);
        full.absorb(cover_of(RectWrap::Repeat, &[(0.1, 0.2)]));
        full.absorb(cover_of(RectWrap::Repeat, &[(0.0, 1.5)]));
        assert_eq!(full.range(), (0.0, 1.0));
        let mut empty = AxisCover::new(RectWrap::Clamp);
        empty.absorb(AxisCover::new(RectWrap::Clamp));
        assert_eq!(empty.range(), (0.0, 0.0));
    }

    fn cover_of(wrap: RectWrap, ivs: &[(f64, f64)]) -> AxisCover {
        let mut c = AxisCover::new(wrap);
        for &(a, b) in ivs {
            c.add(a, b);
        }
        c
    }

    #[test]
    fn repeat_finds_the_shortest_arc_across_the_seam() {
        // [0.8, 0.95] and [0.05, 0.3] (as 1.05..1.3 shifted down): the arc 0.8 → 1.3, span 0.5.
        let ivs = [(0.8, 0.95), (0.05, 0.3)];
        let (lo, hi) = cover(RectWrap::Repeat, &ivs);
        assert!(
            (lo - 0.8).abs() < 1e-12 && (hi - 1.3).abs() < 1e-12,
            "{lo} {hi}"
        );
        assert_contract(RectWrap::Repeat, &ivs);
        // A triangle across the seam itself: gaps 0.2 → 0.4 and 0.5 → 0.9; the larger leaves 0.9 → 1.5.
        let ivs = [(0.9, 1.2), (0.4, 0.5)];
        let (lo, hi) = cover(RectWrap::Repeat, &ivs);
        assert!(
            (lo - 0.9).abs() < 1e-12 && (hi - 1.5).abs() < 1e-12,
            "{lo} {hi}"
        );
        assert_contract(RectWrap::Repeat, &ivs);
    }

    #[test]
    fn repeat_holds_one_period_when_the_circle_is_covered() {
        assert_eq!(cover(RectWrap::Repeat, &[(0.3, 1.3)]), (0.0, 1.0));
        assert_eq!(cover(RectWrap::Repeat, &[(0.0, 170.0)]), (0.0, 1.0));
        assert_eq!(
            cover(RectWrap::Repeat, &[(0.0, 0.6), (0.5, 1.1)]),
            (0.0, 1.0)
        );
        assert_contract(RectWrap::Repeat, &[(0.0, 0.6), (0.5, 1.1), (0.2, 5.0)]);
        // Inside one period: the hull.
        assert_eq!(
            cover(RectWrap::Repeat, &[(0.25, 0.5), (0.1, 0.2)]),
            (0.1, 0.5)
        );
    }

    #[test]
    fn mirror_folds_and_clamp_clamps() {
        // [0.5, 1.5] folds to [0.5, 1]; [1.2, 1.4] (backward) to [0.6, 0.8].
        assert_eq!(cover(RectWrap::Mirror, &[(0.5, 1.5)]), (0.5, 1.0));
        let (a, b) = cover(RectWrap::Mirror, &[(1.2, 1.4)]);
        assert!((a - 0.6).abs() < 1e-12 && (b - 0.8).abs() < 1e-12);
        assert_eq!(cover(RectWrap::Mirror, &[(0.1, 2.3)]), (0.0, 1.0));
        assert_contract(RectWrap::Mirror, &[(0.5, 1.5), (1.2, 1.4), (1.9, 2.1)]);
        assert_eq!(
            cover(RectWrap::Clamp, &[(-3.0, 0.4), (0.2, 0.7)]),
            (0.0, 0.7)
        );
        assert_contract(RectWrap::Clamp, &[(-3.0, 0.4), (0.2, 0.7), (2.0, 9.0)]);
        assert_eq!(
            cover(RectWrap::Linear, &[(-3.0, 0.4), (0.2, 7.5)]),
            (-3.0, 7.5)
        );
    }

    #[test]
    fn degenerate_and_non_finite_inputs() {
        assert_eq!(cover(RectWrap::Repeat, &[]), (0.0, 0.0));
        assert_eq!(cover(RectWrap::Repeat, &[(f64::NAN, 1.0)]), (0.0, 0.0));
        assert_eq!(cover(RectWrap::Repeat, &[(0.25, 0.25)]), (0.25, 0.25));
        // The order of the arcs does not matter.
        let a = [(0.1, 0.2), (0.7, 0.9), (0.4, 0.45)];
        let b = [(0.4, 0.45), (0.1, 0.2), (0.7, 0.9)];
        assert_eq!(shortest_arc(&a), shortest_arc(&b));
        // A start of exactly 1 (float rounding of a period shift) is the same as 0.
        assert_eq!(shortest_arc(&[(1.0, 1.25)]), (0.0, 0.25));
    }

    proptest::proptest! {
        #[test]
        fn contract_holds_for_random_intervals(
            ivs in proptest::collection::vec((0.0f64..1.0, 0.0f64..0.7), 1..12),
            mode in 0u32..4,
        ) {
            let wrap = RectWrap::from_code(mode).unwrap();
            let ivs: Vec<(f64, f64)> = ivs.iter().map(|&(a, l)| match wrap {
                RectWrap::Mirror => (a * 2.0, a * 2.0 + l),
                RectWrap::Clamp | RectWrap::Linear => (a * 4.0 - 2.0, a * 4.0 - 2.0 + l),
                RectWrap::Repeat => (a, a + l),
            }).collect();
            assert_contract(wrap, &ivs);
            let (lo, hi) = cover(wrap, &ivs);
            if wrap != RectWrap::Linear {
                proptest::prop_assert!(hi - lo <= 1.0 + 1e-12);
            }
        }
    }
}
