//! Texel demand of a set of triangles: the summed outer atlas area (texels², borders included) that its
//! materials' rects need at `d_min`, after the source cap and the wrap. The split of paper §5.3 balances
//! it — the paper's condition (b) itself, "the summed number of texels for all required texture areas",
//! which the paper approximates by equal world areas; with repeats wrapped in the shader and textures
//! shared between triangles, world area and demand no longer agree (a 4 km ground with a 28 m tile needs one
//! period, not 140²).
//!
//! The demand of a set is computed per material from running maxima, so the demand of every prefix of a
//! sorted sequence costs one pass ([`prefix_demands`]). Per axis the UV range is the hull of the
//! triangles' (period-shifted) intervals, at most one period where the sampler repeats, mirrors or
//! clamps — an upper bound of the exact cover the layout computes ([`super::cover`]), equal to it when the
//! range does not straddle a seam. Units: texels².

use super::area::{AreaInput, AreaOptions, required_area};
use super::prepare::TriInfo;
use crate::model::sizing::SizeMethod;
use crate::scene::Wrap;
use glam::DVec2;

/// What the demand of a triangle depends on beyond the triangle itself.
#[derive(Clone, Debug)]
pub struct DemandModel {
    /// Per material: source image size `[w, h]`, texels.
    pub sources: Vec<[u32; 2]>,
    /// Per material: sampler wrap modes.
    pub wraps: Vec<[Wrap; 2]>,
    /// Repeats wrapped in the shader (else baked: the whole UV hull is stored).
    pub wrap: bool,
    pub border: u32,
    pub cap_to_source: bool,
}

/// Running per-material maxima of a set of triangles.
#[derive(Copy, Clone, Debug, PartialEq)]
struct Acc {
    w: f64,
    h: f64,
    lo: DVec2,
    hi: DVec2,
    point_uvs: bool,
    used: bool,
}

impl Default for Acc {
    fn default() -> Acc {
        Acc {
            w: 0.0,
            h: 0.0,
            lo: DVec2::splat(f64::INFINITY),
            hi: DVec2::splat(f64::NEG_INFINITY),
            point_uvs: false,
            used: false,
        }
    }
}

impl Acc {
    fn add(&mut self, t: &TriInfo) {
        self.used = true;
        for uv in t.uv {
            if uv.is_finite() {
                self.lo = self.lo.min(uv);
                self.hi = self.hi.max(uv);
            }
        }
        match t.size.method {
            SizeMethod::Exact | SizeMethod::EdgeFallback => {
                self.w = self.w.max(t.size.w);
                self.h = self.h.max(t.size.h);
            }
            SizeMethod::AllUvEqual => self.point_uvs = true,
            SizeMethod::WorldDegenerate => {}
        }
    }
}

impl DemandModel {
    /// The stored UV span along one axis of a material whose triangles' hull is `[lo, hi]`.
    fn span(&self, lo: f64, hi: f64, wrap: Wrap) -> f64 {
        if !(lo.is_finite() && hi.is_finite()) || hi < lo {
            return 0.0;
        }
        if !self.wrap {
            return hi - lo;
        }
        match wrap {
            Wrap::Repeat | Wrap::MirroredRepeat => (hi - lo).min(1.0),
            Wrap::ClampToEdge => hi.clamp(0.0, 1.0) - lo.clamp(0.0, 1.0),
        }
    }

    /// Outer area of material `m`'s rect for the running maxima `a` (0 when unused). Computed by the
    /// area stage's own [`required_area`], so rounding, border and cap are the layout's.
    fn area(&self, m: usize, a: &Acc) -> u64 {
        if !a.used {
            return 0;
        }
        let src = self.sources.get(m).copied().unwrap_or([1, 1]);
        let wrap = self.wraps.get(m).copied().unwrap_or([Wrap::Repeat; 2]);
        let span = [
            self.span(a.lo.x, a.hi.x, wrap[0]),
            self.span(a.lo.y, a.hi.y, wrap[1]),
        ];
        let (mut w, mut h) = (a.w, a.h);
        if a.point_uvs && span.iter().any(|&s| s > 0.0) {
            w = w.max(f64::from(src[0]));
            h = h.max(f64::from(src[1]));
        }
        let input = AreaInput {
            w,
            h,
            uv_min: [0.0; 2],
            uv_max: span,
            source: src,
        };
        let opts = AreaOptions {
            border: self.border,
            scale: 1.0,
            cap_to_source: self.cap_to_source,
            max_side: u32::MAX,
            cap_floor: true,
        };
        // Beyond u32 sides: saturate (such a set never fits; only the order of demands matters). An area
        // within u32 sides can exceed the saturated value (both sides past 2³¹): it saturates too, so a
        // material's area never falls as its maxima grow (what the split's early stop relies on).
        match required_area(&input, &opts) {
            Ok(r) => r.outer_texels().min(SATURATED_AREA),
            Err(_) => SATURATED_AREA,
        }
    }
}

/// A material's demand where its rect is beyond any atlas (texels²).
const SATURATED_AREA: u64 = u64::MAX / 4;

/// The demand of every prefix of `items` (indices into `infos`): `out[k]` is the demand of `items[..k]`,
/// `k = 0..=items.len()` (so `out[0] = 0`). `O(n)` after one map of the materials in `items`.
pub fn prefix_demands(model: &DemandModel, infos: &[TriInfo], items: &[u32]) -> Vec<u64> {
    prefix_demands_exact(model, infos, items).0
}

/// [`prefix_demands`], and whether the running sum never saturated. Then the last entry is the sum of the
/// materials' final areas, and the demand of these items, or of any subset, is the same in every order: a
/// material's area only grows as its running maxima grow, and those do not depend on the order, so no
/// other order's running sum saturates either. (Saturation needs areas near `u64::MAX`: sides beyond
/// 2³² texels.)
pub fn prefix_demands_exact(
    model: &DemandModel,
    infos: &[TriInfo],
    items: &[u32],
) -> (Vec<u64>, bool) {
    SCRATCH.with(|scratch| {
        let mut scratch = scratch.borrow_mut();
        scratch.prefix_demands(model, infos, items)
    })
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// Per-thread accumulators of [`prefix_demands`], sparse over the materials a call meets: a call costs
/// O(items), not O(materials of the scene) (which dominated the layout of scenes with thousands of
/// materials, where most nodes hold a few).
#[derive(Default)]
struct Scratch {
    /// Per scene material: the call that last used it, and its slot in `accs` for that call.
    stamp: Vec<u64>,
    slot: Vec<u32>,
    call: u64,
    accs: Vec<(Acc, u64)>,
}

impl Scratch {
    fn prefix_demands(
        &mut self,
        model: &DemandModel,
        infos: &[TriInfo],
        items: &[u32],
    ) -> (Vec<u64>, bool) {
        let mut out = Vec::with_capacity(items.len() + 1);
        out.push(0);
        let exact = self.walk(model, infos, items, |total| {
            out.push(total);
            true
        });
        (out, exact)
    }

    /// Walks `items` in order, handing `visit` the demand of every prefix after its last item (the
    /// entries 1.. of [`prefix_demands`]) until `visit` returns false. Returns whether the running sum
    /// never saturated over the items walked.
    fn walk(
        &mut self,
        model: &DemandModel,
        infos: &[TriInfo],
        items: &[u32],
        mut visit: impl FnMut(u64) -> bool,
    ) -> bool {
        let materials = model.sources.len();
        if self.stamp.len() < materials {
            self.stamp.resize(materials, 0);
            self.slot.resize(materials, 0);
        }
        self.call += 1;
        self.accs.clear();
        let mut total: u64 = 0;
        let mut exact = true;
        for t in super::prepare::walk_prefix(infos, items, TriInfo::SPLIT_BYTES) {
            let m = t.material.idx();
            if m < materials {
                if self.stamp[m] != self.call {
                    self.stamp[m] = self.call;
                    self.slot[m] = self.accs.len() as u32;
                    self.accs.push((Acc::default(), 0));
                }
                let (acc, area) = &mut self.accs[self.slot[m] as usize];
                let before = *acc;
                acc.add(t);
                // Unchanged maxima give the same area: skip recomputing it.
                if *acc != before {
                    let new = model.area(m, acc);
                    let rest = total.saturating_sub(*area);
                    exact &= rest.checked_add(new).is_some();
                    total = rest.saturating_add(new);
                    *area = new;
                }
            }
            if !visit(total) {
                break;
            }
        }
        exact
    }
}

/// Walks the prefixes of `items` in order with their demands, as [`prefix_demands`] gives them, while
/// `visit(k, demand of items[..k])` (k = 1, 2, …) returns true: the demand of a prefix without the
/// longer ones. The demand of a prefix never falls as it grows (a material's area only grows with its
/// maxima; saturation keeps it at `u64::MAX`), so a caller looking for a balance can stop once it is past.
/// Returns whether the running sum never saturated over the prefixes walked. `visit` runs while this
/// thread's demand scratch is borrowed: it must not compute demands itself.
pub fn walk_prefix_demands(
    model: &DemandModel,
    infos: &[TriInfo],
    items: &[u32],
    mut visit: impl FnMut(usize, u64) -> bool,
) -> bool {
    SCRATCH.with(|scratch| {
        let mut k = 0;
        scratch.borrow_mut().walk(model, infos, items, |total| {
            k += 1;
            visit(k, total)
        })
    })
}

/// The demand of a whole set (analyzer twin of [`prefix_demands`]: its last entry).
pub fn demand(model: &DemandModel, infos: &[TriInfo], items: &[u32]) -> u64 {
    prefix_demands(model, infos, items)
        .last()
        .copied()
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ids::MaterialId;
    use crate::model::sizing::SizeEstimate;

    fn tri(material: u32, w: f64, uv0: [f64; 2], uv1: [f64; 2]) -> TriInfo {
        TriInfo {
            scene_tri: 0,
            piece: crate::preprocess::prepare::WHOLE,
            material: MaterialId(material),
            mid: DVec2::ZERO,
            area: 1.0,
            size: SizeEstimate {
                w,
                h: w,
                method: SizeMethod::Exact,
            },
            class: 0,
            uv: [DVec2::from(uv0), DVec2::from(uv1), DVec2::from(uv0)],
        }
    }

    fn model(wrap: bool) -> DemandModel {
        DemandModel {
            sources: vec![[512, 512], [64, 64]],
            wraps: vec![[Wrap::Repeat; 2]; 2],
            wrap,
            border: 2,
            cap_to_source: true,
        }
    }

    #[test]
    fn a_shared_texture_counts_once_and_wrap_caps_one_period() {
        // Two triangles of material 0 over 40 periods at 100 texels/period: wrapped, one period
        // (100 + 4 → 104²); baked, 40 periods (4000 + 4 → 4004 × 104).
        let infos = vec![
            tri(0, 100.0, [0.0, 0.0], [40.0, 1.0]),
            tri(0, 100.0, [0.0, 0.0], [40.0, 1.0]),
        ];
        let p = prefix_demands(&model(true), &infos, &[0, 1]);
        assert_eq!(p, vec![0, 104 * 104, 104 * 104]);
        assert_eq!(demand(&model(false), &infos, &[0, 1]), 4004 * 104);
    }

    #[test]
    fn a_demand_never_falls_as_its_set_grows_even_past_any_atlas() {
        // Baked, uncapped, 3·10⁹ texels a UV unit: [0, 1]² has u32 sides and an area past the saturated
        // value, [0, 2]² sides past u32. Both saturate; the second must not fall below the first.
        let model = DemandModel {
            cap_to_source: false,
            ..model(false)
        };
        let infos = vec![
            tri(0, 3e9, [0.0, 0.0], [1.0, 1.0]),
            tri(0, 3e9, [0.0, 0.0], [2.0, 2.0]),
        ];
        let p = prefix_demands(&model, &infos, &[0, 1]);
        assert_eq!(p, vec![0, SATURATED_AREA, SATURATED_AREA]);
    }

    #[test]
    fn the_source_cap_bounds_the_demand() {
        // 1000 texels/period of a 64² source: capped at 64 (+4 → 68²).
        let infos = vec![tri(1, 1000.0, [0.0, 0.0], [1.0, 1.0])];
        assert_eq!(demand(&model(true), &infos, &[0]), 68 * 68);
        let uncapped = DemandModel {
            cap_to_source: false,
            ..model(true)
        };
        assert_eq!(demand(&uncapped, &infos, &[0]), 1004 * 1004);
    }
}
