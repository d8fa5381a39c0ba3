//! Texture size estimation per triangle (paper §5.2.1).
//!
//! For a triangle `T = (v0, v1, v2, t0, t1, t2)` the required texture size is the number of texels one
//! repetition of the texture (one unit of UV) needs so that, seen from any distance `≥ d_min`, no texel is
//! magnified: `w = |s_world| · f_proj`, `h = |t_world| · f_proj`, where `s_world = P_T(Tex_T⁻¹((1, 0)))` and
//! `t_world = P_T(Tex_T⁻¹((0, 1)))` are the world-space images of the UV unit vectors,
//! `P_T(a, b) = a·e1 + b·e2` with `e_i = v_i − v0`, and `Tex_T(a, b) = a·d1 + b·d2` with `d_i = t_i − t0`.
//! `f_proj` is [`crate::model::BuildParams::f_proj`] (texels per world unit at `d_min`).
//!
//! Units: `w`, `h` are texels per unit of UV ("texels per repetition"), `f_proj` texels per world unit.
//!
//! # Degenerate cases ([`SizeMethod`])
//! - [`SizeMethod::WorldDegenerate`]: zero-area world triangle (twice its area `≤ 1e-12 ×` its longest
//!   edge squared), or any NaN/±∞ position or UV. Never rasterised, so ignored for sizing: `w = h = 0`.
//! - [`SizeMethod::AllUvEqual`]: `t0 = t1 = t2` (to within the precision of the UVs, see below). The paper
//!   fixes a 1×1 texture. Per unit of UV that is no finite size, so we return `w = h = 0` and flag it;
//!   [`crate::preprocess::area`] clamps every inner area to at least 1×1 texel, which gives the paper's 1×1.
//! - [`SizeMethod::EdgeFallback`]: the UV triangle is collinear or too ill-conditioned to invert (2×2
//!   condition number `> 1e6`, or its smallest singular value below `1e4 ×` the UV precision). The paper's
//!   estimate `|v_i − v_j| / |t_i − t_j|` on the longest UV edge `(i, j)` is used for both `w` and `h`.
//! - [`SizeMethod::Exact`]: the formula above.
//!
//! # Precision
//! Everything is computed from differences (`v_i − v0`, `t_i − t0`), and a difference of two f64 values is
//! correct to half an ulp *of the difference*, so large offsets (UTM positions, UVs at `−2.9e9`) cost nothing
//! here. What they do cost is upstream: an input UV of magnitude `M` can carry no more precision than
//! `M · ε` (ε = 2⁻⁵² ≈ 2.2e-16; at `M = 2.9e9` that is 6.4e-7 UV, and far worse if the source stored it in
//! f32). We call `uv_noise = max(M, 1) · ε`. The relative error of the exact estimate is about
//! `uv_noise / σ_min(D)`; requiring `σ_min ≥ 1e4 · uv_noise` keeps it below 1e-4, else the edge fallback
//! (whose relative error is `uv_noise / |t_i − t_j|`) is used. UV triangles whose longest edge is
//! `≤ 4 · uv_noise` cannot be told from a point and count as [`SizeMethod::AllUvEqual`].
//! Intermediate products are normalised by the largest component, so nothing overflows before the final
//! multiplication; a result beyond `f64::MAX` is returned as `f64::MAX` (the area stage then rejects it).
//! The output is always finite and `≥ 0`. A non-finite or negative `f_proj` yields `w = h = 0`.

use glam::{DVec2, DVec3};
use serde::Serialize;

/// How a [`SizeEstimate`] was obtained (paper §5.2.1 and its degenerate cases).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum SizeMethod {
    /// `|P_T(Tex_T⁻¹(e_k))| · f_proj` with a well-conditioned UV triangle.
    Exact,
    /// All three UVs are equal: `w = h = 0` per UV; the area stage makes that a 1×1 texel area.
    AllUvEqual,
    /// Collinear or ill-conditioned UVs: `|v_i − v_j| / |t_i − t_j| · f_proj` on the longest UV edge, for
    /// both `w` and `h`.
    EdgeFallback,
    /// Zero-area world triangle, or a NaN/±∞ input: ignored for sizing, `w = h = 0`.
    WorldDegenerate,
}

/// Minimum texture size of one triangle: texels per unit of UV so that no texel is magnified at `d_min`.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct SizeEstimate {
    /// Texels per unit of U (always finite, `≥ 0`).
    pub w: f64,
    /// Texels per unit of V (always finite, `≥ 0`).
    pub h: f64,
    pub method: SizeMethod,
}

/// Largest condition number (2-norm) of the UV matrix `[d1 d2]` that is inverted.
pub const MAX_UV_COND: f64 = 1e6;
/// The UV matrix's smallest singular value must be at least this many times `uv_noise`.
pub const MIN_UV_SIGMA_OVER_NOISE: f64 = 1e4;
/// A world triangle is degenerate when `2·area ≤ this × (longest edge)²`.
pub const WORLD_DEGENERATE_RATIO: f64 = 1e-12;

/// Required texels per unit of UV for one triangle (paper §5.2.1). See the module docs for the
/// degenerate cases and the precision contract.
pub fn texels_per_uv(pos: [DVec3; 3], uv: [DVec2; 3], f_proj: f64) -> SizeEstimate {
    let f = if f_proj.is_finite() && f_proj >= 0.0 {
        f_proj
    } else {
        0.0
    };
    let finite = pos.iter().all(|p| p.is_finite()) && uv.iter().all(|t| t.is_finite());
    let e1 = pos[1] - pos[0];
    let e2 = pos[2] - pos[0];
    if !finite || !e1.is_finite() || !e2.is_finite() || world_degenerate(e1, e2) {
        return SizeEstimate {
            w: 0.0,
            h: 0.0,
            method: SizeMethod::WorldDegenerate,
        };
    }
    let uv_noise = uv.iter().map(|t| t.abs().max_element()).fold(1.0, f64::max) * f64::EPSILON;
    let d1 = uv[1] - uv[0];
    let d2 = uv[2] - uv[0];
    let d3 = uv[2] - uv[1];
    let longest = robust_len2(d1).max(robust_len2(d2)).max(robust_len2(d3));
    if longest <= 4.0 * uv_noise {
        return SizeEstimate {
            w: 0.0,
            h: 0.0,
            method: SizeMethod::AllUvEqual,
        };
    }
    match exact(e1, e2, d1, d2, uv_noise) {
        Some((s_len, t_len)) => SizeEstimate {
            w: sanitize(s_len * f),
            h: sanitize(t_len * f),
            method: SizeMethod::Exact,
        },
        None => {
            let len = edge_fallback(pos, uv);
            SizeEstimate {
                w: sanitize(len * f),
                h: sanitize(len * f),
                method: SizeMethod::EdgeFallback,
            }
        }
    }
}

/// True when the world triangle spanned by `e1`, `e2` has (numerically) zero area.
fn world_degenerate(e1: DVec3, e2: DVec3) -> bool {
    let m = e1.abs().max_element().max(e2.abs().max_element());
    if m == 0.0 || !m.is_finite() {
        return true;
    }
    let (n1, n2) = (e1 / m, e2 / m);
    let twice_area = n1.cross(n2).length();
    let longest_sq = n1
        .length_squared()
        .max(n2.length_squared())
        .max((n2 - n1).length_squared());
    twice_area <= WORLD_DEGENERATE_RATIO * longest_sq
}

/// `(|s_world|, |t_world|)` when the UV matrix `[d1 d2]` is well-conditioned, else `None`.
fn exact(e1: DVec3, e2: DVec3, d1: DVec2, d2: DVec2, uv_noise: f64) -> Option<(f64, f64)> {
    let k = d1.abs().max_element().max(d2.abs().max_element());
    let (n1, n2) = (d1 / k, d2 / k);
    let (sigma_max_n, sigma_min_n) = singular_values(n1, n2);
    if sigma_min_n <= 0.0 || sigma_max_n / sigma_min_n > MAX_UV_COND {
        return None;
    }
    if sigma_min_n * k < MIN_UV_SIGMA_OVER_NOISE * uv_noise {
        return None;
    }
    let det_n = n1.perp_dot(n2);
    let m = e1.abs().max_element().max(e2.abs().max_element());
    let (w1, w2) = (e1 / m, e2 / m);
    // Tex⁻¹((1,0)) = (n2.y, −n1.y) / (det_n · k);  Tex⁻¹((0,1)) = (−n2.x, n1.x) / (det_n · k).
    let s = (w1 * n2.y - w2 * n1.y).length() / det_n.abs();
    let t = (w2 * n1.x - w1 * n2.x).length() / det_n.abs();
    let ratio = m / k;
    Some((s * ratio, t * ratio))
}

/// Singular values `(σ_max, σ_min)` of the 2×2 matrix with columns `a`, `b` (entries of order 1).
fn singular_values(a: DVec2, b: DVec2) -> (f64, f64) {
    let (p, q) = (a.length_squared(), b.length_squared());
    let c = a.dot(b);
    // σ² = (p + q ± sqrt((p − q)² + 4c²)) / 2, written without cancellation for σ_max; σ_min = |det| / σ_max.
    let root = ((p - q) * (p - q) + 4.0 * c * c).sqrt();
    let sigma_max = ((p + q + root) * 0.5).sqrt();
    if sigma_max == 0.0 {
        return (0.0, 0.0);
    }
    (sigma_max, a.perp_dot(b).abs() / sigma_max)
}

/// The paper's fallback: world length over UV length of the longest UV edge (world units per UV).
fn edge_fallback(pos: [DVec3; 3], uv: [DVec2; 3]) -> f64 {
    let edges = [(0usize, 1usize), (0, 2), (1, 2)];
    let (mut best_uv, mut best_world) = (0.0f64, 0.0f64);
    for (i, j) in edges {
        let l = robust_len2(uv[j] - uv[i]);
        if l > best_uv {
            best_uv = l;
            best_world = robust_len3(pos[j] - pos[i]);
        }
    }
    if best_uv > 0.0 {
        best_world / best_uv
    } else {
        0.0
    }
}

/// `|v|` without intermediate overflow or underflow.
fn robust_len2(v: DVec2) -> f64 {
    let m = v.abs().max_element();
    if m == 0.0 || !m.is_finite() {
        m
    } else {
        (v / m).length() * m
    }
}

/// `|v|` without intermediate overflow or underflow.
fn robust_len3(v: DVec3) -> f64 {
    let m = v.abs().max_element();
    if m == 0.0 || !m.is_finite() {
        m
    } else {
        (v / m).length() * m
    }
}

/// Finite and non-negative: NaN → 0, +∞ → `f64::MAX`.
fn sanitize(x: f64) -> f64 {
    if x.is_nan() || x <= 0.0 {
        0.0
    } else if x.is_infinite() {
        f64::MAX
    } else {
        x
    }
}
