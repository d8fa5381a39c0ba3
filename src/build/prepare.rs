//! Per-triangle preparation shared by every node of a build: sizing (§5.2.1), the per-triangle UV period
//! shift, world area and plane midpoint (§5.3). Computed once, then only indexed.

use super::sizing::{SizeEstimate, SizeMethod, texels_per_uv};
use crate::ids::MaterialId;
use crate::scene::{Scene, UpAxis, Wrap};
use glam::{DVec2, DVec3};

/// What the builder knows about one triangle.
#[derive(Copy, Clone, Debug)]
pub struct TriInfo {
    /// Index of the triangle in `Scene::triangles`.
    pub scene_tri: u32,
    pub material: MaterialId,
    /// Midpoint in the distribution plane (the split sorts on it, §5.3).
    pub mid: DVec2,
    /// World-space area (the split balances it, §5.3).
    pub area: f64,
    /// Required texels per UV unit at d_min (already multiplied by f_proj).
    pub size: SizeEstimate,
    /// The UVs after the period shift (see [`period_shift`]).
    pub uv: [DVec2; 3],
    /// World bounds of the triangle.
    pub lo: DVec3,
    pub hi: DVec3,
}

/// The whole-period shift that moves a triangle's UVs next to the origin without changing what it shows:
/// by `floor(min)` on repeat axes, by an even integer on mirrored axes, not at all on clamped axes.
///
/// This bounds the atlas area A_tex of a texture in a node to `[0, 1 + max triangle span]` instead of the
/// union of all repetitions the scene happens to use (the paper copies the whole union, §5.2.2), and keeps
/// stored original UVs small enough for f32 (UV offsets of 1e5 or −2.9e9 occur in real data).
pub fn period_shift(uv: [DVec2; 3], wrap: [Wrap; 2]) -> DVec2 {
    let lo = uv[0].min(uv[1]).min(uv[2]);
    let axis = |v: f64, w: Wrap| -> f64 {
        if !v.is_finite() {
            return 0.0;
        }
        match w {
            Wrap::Repeat => v.floor(),
            Wrap::MirroredRepeat => 2.0 * (v * 0.5).floor(),
            Wrap::ClampToEdge => 0.0,
        }
    };
    DVec2::new(axis(lo.x, wrap[0]), axis(lo.y, wrap[1]))
}

/// Prepares the triangles `tris` (indices into `scene.triangles`) for a build with projection factor
/// `f_proj` (texels per world unit at d_min). Parallel over triangles.
pub fn prepare(scene: &Scene, tris: &[u32], f_proj: f64, up: UpAxis) -> Vec<TriInfo> {
    use rayon::prelude::*;
    tris.par_iter()
        .map(|&ti| {
            let t = &scene.triangles[ti as usize];
            let p = scene.tri_positions(t);
            let uv0 = scene.tri_uvs(t);
            let wrap = scene.materials[t.material.idx()].wrap;
            let shift = period_shift(uv0, wrap);
            let uv = uv0.map(|u| u - shift);
            let size = texels_per_uv(p, uv, f_proj);
            let area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
            let mid = up.plane((p[0] + p[1] + p[2]) / 3.0);
            TriInfo {
                scene_tri: ti,
                material: t.material,
                mid: if mid.is_finite() { mid } else { DVec2::ZERO },
                area: if area.is_finite() { area } else { 0.0 },
                size,
                uv,
                lo: p[0].min(p[1]).min(p[2]),
                hi: p[0].max(p[1]).max(p[2]),
            }
        })
        .collect()
}

/// Counts of sizing methods over prepared triangles (the report twin of [`prepare`]).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct PrepareReport {
    pub triangles: u64,
    pub exact: u64,
    pub edge_fallback: u64,
    pub all_uv_equal: u64,
    pub world_degenerate: u64,
}

pub fn analyze(infos: &[TriInfo]) -> PrepareReport {
    let mut r = PrepareReport {
        triangles: infos.len() as u64,
        ..Default::default()
    };
    for t in infos {
        match t.size.method {
            SizeMethod::Exact => r.exact += 1,
            SizeMethod::EdgeFallback => r.edge_fallback += 1,
            SizeMethod::AllUvEqual => r.all_uv_equal += 1,
            SizeMethod::WorldDegenerate => r.world_degenerate += 1,
        }
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn period_shift_per_wrap_mode() {
        let uv = [
            DVec2::new(1e5 + 0.25, -3.5),
            DVec2::new(1e5 + 1.5, -2.0),
            DVec2::new(1e5 + 0.75, -3.0),
        ];
        let s = period_shift(uv, [Wrap::Repeat, Wrap::MirroredRepeat]);
        assert_eq!(s, DVec2::new(1e5, -4.0));
        let s = period_shift(uv, [Wrap::ClampToEdge, Wrap::ClampToEdge]);
        assert_eq!(s, DVec2::ZERO);
        // A mirrored axis is only shifted by even periods: −3.5 → shift −4, leaving 0.5 (same mirror phase).
        let shifted = uv[0] - period_shift(uv, [Wrap::Repeat, Wrap::MirroredRepeat]);
        assert!((shifted.x - 0.25).abs() < 1e-9 && (shifted.y - 0.5).abs() < 1e-12);
    }
}
