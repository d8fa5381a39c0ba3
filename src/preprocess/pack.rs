//! All-or-fail packing of texture areas into one square atlas (paper §5.2.3).
//!
//! MaxRects (Jylänki, "A Thousand Ways to Pack the Bin", 2010) with the best-short-side-fit score. The first
//! attempt is **global** best fit: at each step the (rectangle, free rectangle) pair with the best score
//! among *all* remaining rectangles is placed. Further attempts place the rectangles one by one in a sort
//! order (area, longest side, perimeter, height, width, all descending), each at its best free rectangle.
//! The first attempt that places every rectangle wins; otherwise the node fails ([`PackFailure::NoFit`]) and
//! the caller splits it (paper §5.1).
//!
//! No rotation: a rotated area would need a rotated UV mapping in the rasteriser and in the per-vertex atlas
//! UVs, for a small gain. All sizes and positions are multiples of 4 texels (BC blocks never straddle two
//! textures); internally everything is in 4-texel units.
//!
//! Cost: free rectangles contained in another are pruned after every placement. Only the rectangles created
//! by that placement can be contained in another one (an older free rectangle contained in a new one was
//! already contained in the split rectangle it came from, and so pruned before), so the pruning is
//! `O(new · free)` rather than `O(free²)`. Global best fit keeps, per distinct rectangle size, its best free
//! rectangle and rescans only when that free rectangle disappears; new free rectangles are scored
//! incrementally.

use serde::Serialize;

/// Order in which rectangles are placed; [`SortOrder::GlobalBestFit`] picks the best pair at each step.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum SortOrder {
    GlobalBestFit,
    AreaDesc,
    MaxSideDesc,
    PerimeterDesc,
    HeightDesc,
    WidthDesc,
}

impl SortOrder {
    /// Every order, global best fit first (the default attempt sequence).
    pub const ALL: [SortOrder; 6] = [
        SortOrder::GlobalBestFit,
        SortOrder::AreaDesc,
        SortOrder::MaxSideDesc,
        SortOrder::PerimeterDesc,
        SortOrder::HeightDesc,
        SortOrder::WidthDesc,
    ];

    /// Sort key (larger first) of a `w × h` rectangle; ties keep input order.
    fn key(self, w: u32, h: u32) -> (u64, u64) {
        let (w, h) = (u64::from(w), u64::from(h));
        match self {
            SortOrder::GlobalBestFit | SortOrder::AreaDesc => (w * h, w.max(h)),
            SortOrder::MaxSideDesc => (w.max(h), w * h),
            SortOrder::PerimeterDesc => (w + h, w * h),
            SortOrder::HeightDesc => (h, w),
            SortOrder::WidthDesc => (w, h),
        }
    }
}

/// Parameters of [`pack`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PackOptions {
    /// Atlas width = height, texels (power of two, `≥ 4`).
    pub atlas_size: u32,
    /// Attempts, in order; the first that places everything wins. Empty means `[GlobalBestFit]`.
    pub orders: Vec<SortOrder>,
}

impl Default for PackOptions {
    fn default() -> Self {
        Self {
            atlas_size: 1024,
            orders: SortOrder::ALL.to_vec(),
        }
    }
}

/// A successful packing: every rectangle placed.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Packing {
    /// Top-left corner of each input rectangle, texels, multiples of 4 (same order as the input).
    pub positions: Vec<[u32; 2]>,
    /// Summed rectangle area over the atlas area, in `[0, 1]`.
    pub occupancy: f64,
    /// The attempt that succeeded.
    pub order_used: SortOrder,
}

/// Why a set of rectangles does not pack. No partial result is ever returned.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum PackFailure {
    #[error("atlas side {side} is not a power of two ≥ 4")]
    InvalidAtlas { side: u32 },
    #[error("rectangle {index} has zero size {w}×{h}")]
    ZeroSize { index: usize, w: u32, h: u32 },
    #[error("rectangle {index} size {w}×{h} is not a multiple of 4")]
    Unaligned { index: usize, w: u32, h: u32 },
    #[error("rectangle {index} ({w}×{h}) exceeds the atlas side {side}")]
    RectTooLarge {
        index: usize,
        w: u32,
        h: u32,
        side: u32,
    },
    #[error("summed area {area} texels² exceeds the atlas capacity {capacity}")]
    SummedAreaExceeds { area: u64, capacity: u64 },
    #[error("no attempt placed all rectangles: best placed {placed} of {total}")]
    NoFit { placed: usize, total: usize },
}

/// Pack all `sizes` (`[w, h]` texels, multiples of 4) into one `atlas_size²` atlas, or fail.
pub fn pack(sizes: &[[u32; 2]], opts: &PackOptions) -> Result<Packing, PackFailure> {
    let side = opts.atlas_size;
    if side < 4 || !side.is_power_of_two() {
        return Err(PackFailure::InvalidAtlas { side });
    }
    let area = validate(sizes, side)?;
    let capacity = u64::from(side) * u64::from(side);
    if area > capacity {
        return Err(PackFailure::SummedAreaExceeds { area, capacity });
    }
    let occupancy = area as f64 / capacity as f64;
    let units: Vec<[u32; 2]> = sizes.iter().map(|s| [s[0] / 4, s[1] / 4]).collect();
    let orders: &[SortOrder] = if opts.orders.is_empty() {
        &[SortOrder::GlobalBestFit]
    } else {
        &opts.orders
    };
    let mut best_placed = 0;
    for &order in orders {
        let attempt = match order {
            SortOrder::GlobalBestFit => pack_global(&units, side / 4),
            _ => pack_sorted(&units, side / 4, order),
        };
        match attempt {
            Ok(pos) => {
                let positions = pos.into_iter().map(|p| [p[0] * 4, p[1] * 4]).collect();
                return Ok(Packing {
                    positions,
                    occupancy,
                    order_used: order,
                });
            }
            Err(placed) => best_placed = best_placed.max(placed),
        }
    }
    Err(PackFailure::NoFit {
        placed: best_placed,
        total: sizes.len(),
    })
}

/// Per-rectangle checks; returns the summed area in texels².
fn validate(sizes: &[[u32; 2]], side: u32) -> Result<u64, PackFailure> {
    let mut area = 0u64;
    for (index, &[w, h]) in sizes.iter().enumerate() {
        if w == 0 || h == 0 {
            return Err(PackFailure::ZeroSize { index, w, h });
        }
        if w % 4 != 0 || h % 4 != 0 {
            return Err(PackFailure::Unaligned { index, w, h });
        }
        if w > side || h > side {
            return Err(PackFailure::RectTooLarge { index, w, h, side });
        }
        area = area.saturating_add(u64::from(w) * u64::from(h));
    }
    Ok(area)
}

/// A rectangle in 4-texel units.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
struct R {
    x: u32,
    y: u32,
    w: u32,
    h: u32,
}

impl R {
    fn right(self) -> u32 {
        self.x + self.w
    }
    fn bottom(self) -> u32 {
        self.y + self.h
    }
    fn contains(self, o: R) -> bool {
        o.x >= self.x && o.y >= self.y && o.right() <= self.right() && o.bottom() <= self.bottom()
    }
    fn intersects(self, o: R) -> bool {
        o.x < self.right() && self.x < o.right() && o.y < self.bottom() && self.y < o.bottom()
    }
}

/// Best-short-side-fit score (smaller is better): `(short leftover, long leftover, y, x)`, the position
/// terms making ties deterministic (prefer top-left). `None` if `w × h` does not fit `f`.
type Score = (u32, u32, u32, u32);

fn score(f: R, w: u32, h: u32) -> Option<Score> {
    if w > f.w || h > f.h {
        return None;
    }
    let (dw, dh) = (f.w - w, f.h - h);
    Some((dw.min(dh), dw.max(dh), f.y, f.x))
}

/// A free rectangle with a unique id (ids are never reused, so a stale id means "gone").
#[derive(Copy, Clone, Debug)]
struct Free {
    r: R,
    id: u32,
}

/// The MaxRects free list.
struct FreeSet {
    rects: Vec<Free>,
    alive: Vec<bool>,
    scratch: Vec<R>,
}

impl FreeSet {
    fn new(side: u32) -> Self {
        Self {
            rects: vec![Free {
                r: R {
                    x: 0,
                    y: 0,
                    w: side,
                    h: side,
                },
                id: 0,
            }],
            alive: vec![true],
            scratch: Vec::new(),
        }
    }

    fn is_alive(&self, id: u32) -> bool {
        self.alive.get(id as usize).copied().unwrap_or(false)
    }

    /// Best free rectangle for `w × h`: `(score, id, x, y)`.
    fn best(&self, w: u32, h: u32) -> Option<(Score, u32, u32, u32)> {
        best_in(&self.rects, w, h)
    }

    /// Occupy `p`: split every free rectangle it overlaps (MaxRects split), prune contained ones.
    /// Returns the index in `rects` from which the new free rectangles start.
    fn place(&mut self, p: R) -> usize {
        let mut split = std::mem::take(&mut self.scratch);
        split.clear();
        let alive = &mut self.alive;
        self.rects.retain(|f| {
            if !f.r.intersects(p) {
                return true;
            }
            split_free(f.r, p, &mut split);
            if let Some(a) = alive.get_mut(f.id as usize) {
                *a = false;
            }
            false
        });
        let old = self.rects.len();
        for (i, &c) in split.iter().enumerate() {
            let in_old = self.rects[..old].iter().any(|f| f.r.contains(c));
            // Among the new ones: drop c if another contains it (of two equal ones, keep the first).
            let in_new = split
                .iter()
                .enumerate()
                .any(|(j, &o)| j != i && o.contains(c) && (o != c || j < i));
            if !in_old && !in_new {
                let id = self.alive.len() as u32;
                self.alive.push(true);
                self.rects.push(Free { r: c, id });
            }
        }
        self.scratch = split;
        old
    }
}

fn best_in(rects: &[Free], w: u32, h: u32) -> Option<(Score, u32, u32, u32)> {
    let mut best: Option<(Score, u32, u32, u32)> = None;
    for f in rects {
        if let Some(s) = score(f.r, w, h)
            && best.is_none_or(|b| s < b.0)
        {
            best = Some((s, f.id, f.r.x, f.r.y));
        }
    }
    best
}

/// The up to four maximal free rectangles left of `f` after removing `p` (which overlaps `f`).
fn split_free(f: R, p: R, out: &mut Vec<R>) {
    if p.x > f.x {
        out.push(R {
            x: f.x,
            y: f.y,
            w: p.x - f.x,
            h: f.h,
        });
    }
    if p.right() < f.right() {
        out.push(R {
            x: p.right(),
            y: f.y,
            w: f.right() - p.right(),
            h: f.h,
        });
    }
    if p.y > f.y {
        out.push(R {
            x: f.x,
            y: f.y,
            w: f.w,
            h: p.y - f.y,
        });
    }
    if p.bottom() < f.bottom() {
        out.push(R {
            x: f.x,
            y: p.bottom(),
            w: f.w,
            h: f.bottom() - p.bottom(),
        });
    }
}

/// Rectangles in `order`, each at its best free rectangle. `Err(placed)` on the first that fits nowhere.
fn pack_sorted(units: &[[u32; 2]], side: u32, order: SortOrder) -> Result<Vec<[u32; 2]>, usize> {
    let mut idx: Vec<usize> = (0..units.len()).collect();
    idx.sort_by_key(|&i| std::cmp::Reverse(units.get(i).map_or((0, 0), |s| order.key(s[0], s[1]))));
    let mut free = FreeSet::new(side);
    let mut pos = vec![[0u32; 2]; units.len()];
    for (placed, &i) in idx.iter().enumerate() {
        let [w, h] = units[i];
        let (_, _, x, y) = free.best(w, h).ok_or(placed)?;
        free.place(R { x, y, w, h });
        pos[i] = [x, y];
    }
    Ok(pos)
}

/// One distinct size and the rectangles of that size still to place.
struct Class {
    w: u32,
    h: u32,
    members: Vec<usize>,
    best: Option<(Score, u32, u32, u32)>,
}

/// Global best fit: at each step place the (size, free rectangle) pair with the best score.
/// `Err(placed)` as soon as some remaining size fits nowhere (free space only shrinks, so it never will).
fn pack_global(units: &[[u32; 2]], side: u32) -> Result<Vec<[u32; 2]>, usize> {
    let mut classes = size_classes(units);
    let mut free = FreeSet::new(side);
    for c in &mut classes {
        c.best = free.best(c.w, c.h);
    }
    let mut pos = vec![[0u32; 2]; units.len()];
    for placed in 0..units.len() {
        let ci = pick_class(&classes).ok_or(placed)?;
        let c = &mut classes[ci];
        let (_, _, x, y) = c.best.ok_or(placed)?;
        let i = c.members.pop().ok_or(placed)?;
        pos[i] = [x, y];
        let first_new = free.place(R {
            x,
            y,
            w: c.w,
            h: c.h,
        });
        for c in classes.iter_mut().filter(|c| !c.members.is_empty()) {
            let stale = c.best.is_none_or(|b| !free.is_alive(b.1));
            c.best = if stale {
                free.best(c.w, c.h)
            } else {
                let fresh = best_in(&free.rects[first_new..], c.w, c.h);
                match (c.best, fresh) {
                    (Some(b), Some(n)) if n.0 < b.0 => Some(n),
                    (b, _) => b,
                }
            };
        }
    }
    Ok(pos)
}

/// Distinct sizes, largest area first; members in reverse input order so `pop` yields input order.
fn size_classes(units: &[[u32; 2]]) -> Vec<Class> {
    let mut idx: Vec<usize> = (0..units.len()).collect();
    idx.sort_by_key(|&i| {
        let [w, h] = units[i];
        (
            std::cmp::Reverse(u64::from(w) * u64::from(h)),
            w,
            h,
            std::cmp::Reverse(i),
        )
    });
    let mut classes: Vec<Class> = Vec::new();
    for i in idx {
        let [w, h] = units[i];
        match classes.last_mut() {
            Some(c) if c.w == w && c.h == h => c.members.push(i),
            _ => classes.push(Class {
                w,
                h,
                members: vec![i],
                best: None,
            }),
        }
    }
    classes
}

/// The non-empty class with the best score (ties: earlier class, i.e. larger area). `None` if a non-empty
/// class fits nowhere, or none is left.
fn pick_class(classes: &[Class]) -> Option<usize> {
    let mut best: Option<(Score, usize)> = None;
    for (ci, c) in classes
        .iter()
        .enumerate()
        .filter(|(_, c)| !c.members.is_empty())
    {
        let (s, ..) = c.best?;
        if best.is_none_or(|b| s < b.0) {
            best = Some((s, ci));
        }
    }
    best.map(|b| b.1)
}

/// Check a packing: every rectangle inside the atlas, 4-aligned, no two overlapping (sweep over x).
/// Returns a description of the first violation. Public for the integration tests.
pub fn verify_packing(
    sizes: &[[u32; 2]],
    positions: &[[u32; 2]],
    atlas_size: u32,
) -> Result<(), String> {
    if sizes.len() != positions.len() {
        return Err(format!(
            "{} sizes but {} positions",
            sizes.len(),
            positions.len()
        ));
    }
    let rects: Vec<[u64; 4]> = sizes
        .iter()
        .zip(positions)
        .map(|(s, p)| {
            [
                u64::from(p[0]),
                u64::from(p[1]),
                u64::from(s[0]),
                u64::from(s[1]),
            ]
        })
        .collect();
    for (i, r) in rects.iter().enumerate() {
        if r.iter().any(|v| v % 4 != 0) {
            return Err(format!("rect {i} {r:?} not 4-aligned"));
        }
        if r[0] + r[2] > u64::from(atlas_size) || r[1] + r[3] > u64::from(atlas_size) {
            return Err(format!("rect {i} {r:?} outside the {atlas_size}² atlas"));
        }
    }
    let mut by_x: Vec<usize> = (0..rects.len()).collect();
    by_x.sort_by_key(|&i| rects[i][0]);
    for (k, &i) in by_x.iter().enumerate() {
        let a = rects[i];
        for &j in &by_x[k + 1..] {
            let b = rects[j];
            if b[0] >= a[0] + a[2] {
                break;
            }
            if b[1] < a[1] + a[3] && a[1] < b[1] + b[3] {
                return Err(format!("rects {i} {a:?} and {j} {b:?} overlap"));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn opts(atlas_size: u32) -> PackOptions {
        PackOptions {
            atlas_size,
            ..Default::default()
        }
    }

    #[test]
    fn empty_list_succeeds_with_zero_occupancy() {
        let p = pack(&[], &opts(512)).unwrap();
        assert!(p.positions.is_empty());
        assert_eq!(p.occupancy, 0.0);
        assert_eq!(p.order_used, SortOrder::GlobalBestFit);
    }

    #[test]
    fn invalid_inputs_are_named() {
        for side in [0, 2, 100, 1000] {
            assert_eq!(
                pack(&[[4, 4]], &opts(side)),
                Err(PackFailure::InvalidAtlas { side })
            );
        }
        assert_eq!(
            pack(&[[4, 4], [0, 8]], &opts(64)),
            Err(PackFailure::ZeroSize {
                index: 1,
                w: 0,
                h: 8
            })
        );
        assert_eq!(
            pack(&[[4, 4], [8, 6]], &opts(64)),
            Err(PackFailure::Unaligned {
                index: 1,
                w: 8,
                h: 6
            })
        );
        assert_eq!(
            pack(&[[4, 4], [8, 68]], &opts(64)),
            Err(PackFailure::RectTooLarge {
                index: 1,
                w: 8,
                h: 68,
                side: 64
            })
        );
        assert_eq!(
            pack(&[[64, 64], [4, 4]], &opts(64)),
            Err(PackFailure::SummedAreaExceeds {
                area: 4112,
                capacity: 4096
            })
        );
    }

    #[test]
    fn exact_fills_succeed() {
        let quads = [[512, 512]; 4];
        let p = pack(&quads, &opts(1024)).unwrap();
        assert_eq!(p.occupancy, 1.0);
        verify_packing(&quads, &p.positions, 1024).unwrap();
        // 512×1024 + 512×512 + 256×512 + 32 × (64×64) = 1024², shuffled small-first.
        let mut mix = vec![[64, 64]; 32];
        mix.extend([[256, 512], [512, 512], [512, 1024]]);
        let p = pack(&mix, &opts(1024)).unwrap();
        assert_eq!(p.occupancy, 1.0);
        verify_packing(&mix, &p.positions, 1024).unwrap();
        // 256 equal squares of 32 in a 512 atlas.
        let grid = vec![[32, 32]; 256];
        let p = pack(&grid, &opts(512)).unwrap();
        assert_eq!(p.occupancy, 1.0);
        verify_packing(&grid, &p.positions, 512).unwrap();
    }

    #[test]
    fn impossible_set_fails_without_partial_result() {
        // Three 516² squares: 76 % of the area, but no two fit side by side in 1024.
        let r = pack(&[[516, 516]; 3], &opts(1024));
        assert_eq!(
            r,
            Err(PackFailure::NoFit {
                placed: 1,
                total: 3
            })
        );
    }

    #[test]
    fn sort_orders_are_tried_in_turn() {
        let sizes = [[8, 8]];
        let p = pack(
            &sizes,
            &PackOptions {
                atlas_size: 16,
                orders: vec![SortOrder::WidthDesc],
            },
        )
        .unwrap();
        assert_eq!(p.order_used, SortOrder::WidthDesc);
        assert_eq!(p.positions, vec![[0, 0]]);
        let p = pack(
            &sizes,
            &PackOptions {
                atlas_size: 16,
                orders: vec![],
            },
        )
        .unwrap();
        assert_eq!(p.order_used, SortOrder::GlobalBestFit);
    }

    /// Split + prune keep the MaxRects invariants: free rectangles avoid every placed one, none contains
    /// another, and together with the placed ones they cover every cell.
    fn check_free_set(free: &FreeSet, placed: &[R], side: u32) -> Result<(), String> {
        for (i, f) in free.rects.iter().enumerate() {
            if !free.is_alive(f.id) {
                return Err(format!("dead id {} listed", f.id));
            }
            if let Some(p) = placed.iter().find(|p| p.intersects(f.r)) {
                return Err(format!("free {:?} overlaps placed {p:?}", f.r));
            }
            if let Some(g) = free
                .rects
                .iter()
                .enumerate()
                .find(|(j, g)| *j != i && g.r.contains(f.r))
            {
                return Err(format!("free {:?} contained in {:?}", f.r, g.1.r));
            }
        }
        for y in 0..side {
            for x in 0..side {
                let cell = R { x, y, w: 1, h: 1 };
                let covered = placed.iter().any(|p| p.contains(cell))
                    || free.rects.iter().any(|f| f.r.contains(cell));
                if !covered {
                    return Err(format!("cell ({x},{y}) neither placed nor free"));
                }
            }
        }
        Ok(())
    }

    proptest! {
        #[test]
        fn free_set_invariants(rects in prop::collection::vec((1u32..8, 1u32..8), 1..40)) {
            let side = 16;
            let mut free = FreeSet::new(side);
            let mut placed = Vec::new();
            for (w, h) in rects {
                if let Some((_, _, x, y)) = free.best(w, h) {
                    let p = R { x, y, w, h };
                    free.place(p);
                    placed.push(p);
                    prop_assert_eq!(check_free_set(&free, &placed, side), Ok(()));
                }
            }
        }

        #[test]
        fn packing_is_valid_or_fails_whole(
            units in prop::collection::vec((1u32..=64, 1u32..=64), 0..80),
            log_side in 6u32..=10,
        ) {
            let side = 1u32 << log_side;
            let sizes: Vec<[u32; 2]> = units.iter().map(|&(w, h)| [w * 4, h * 4]).collect();
            let area: u64 = sizes.iter().map(|s| u64::from(s[0]) * u64::from(s[1])).sum();
            match pack(&sizes, &opts(side)) {
                Ok(p) => {
                    prop_assert_eq!(p.positions.len(), sizes.len());
                    prop_assert_eq!(verify_packing(&sizes, &p.positions, side), Ok(()));
                    prop_assert!((p.occupancy - area as f64 / f64::from(side).powi(2)).abs() < 1e-12);
                }
                Err(PackFailure::SummedAreaExceeds { area: a, capacity }) => {
                    prop_assert_eq!(a, area);
                    prop_assert!(a > capacity);
                }
                Err(PackFailure::RectTooLarge { index, w, h, side: s }) => {
                    prop_assert_eq!(s, side);
                    prop_assert_eq!(sizes[index], [w, h]);
                    prop_assert!(w > side || h > side);
                }
                Err(PackFailure::NoFit { placed, total }) => {
                    prop_assert!(placed < total);
                    prop_assert_eq!(total, sizes.len());
                }
                Err(e) => prop_assert!(false, "unexpected {e}"),
            }
        }

        #[test]
        fn every_order_alone_is_valid(units in prop::collection::vec((1u32..=32, 1u32..=32), 1..60), o in 0usize..6) {
            let order = SortOrder::ALL[o];
            let sizes: Vec<[u32; 2]> = units.iter().map(|&(w, h)| [w * 4, h * 4]).collect();
            if let Ok(p) = pack(&sizes, &PackOptions { atlas_size: 512, orders: vec![order] }) {
                prop_assert_eq!(p.order_used, order);
                prop_assert_eq!(verify_packing(&sizes, &p.positions, 512), Ok(()));
            }
        }

        #[test]
        fn one_rect_within_the_side_always_fits(w in 1u32..=256, h in 1u32..=256) {
            let p = pack(&[[w * 4, h * 4]], &opts(1024)).unwrap();
            prop_assert_eq!(p.positions, vec![[0, 0]]);
        }
    }
}
