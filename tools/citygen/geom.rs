//! Mesh builders in mesh-local metres, y up. Footprints are polygons in the x–z plane, ordered so that the
//! outward wall normal of edge `a → b` is `(b − a) × ŷ` (clockwise in (x, z) coordinates, i.e.
//! counter-clockwise seen from above); [`orient`] enforces it.

use crate::gltf_out::{MeshData, Vtx};

/// Signed shoelace area in (x, z) coordinates.
pub fn signed_area(poly: &[[f64; 2]]) -> f64 {
    let n = poly.len();
    (0..n)
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % n]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum::<f64>()
        * 0.5
}

/// Reorders `poly` so that wall normals point outwards and roof fans face up (negative signed area).
pub fn orient(mut poly: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    if signed_area(&poly) > 0.0 {
        poly.reverse();
    }
    poly
}

fn vtx(p: [f64; 3], n: [f64; 3], uv: [f64; 2]) -> Vtx {
    Vtx {
        p: p.map(|c| c as f32),
        n: n.map(|c| c as f32),
        uv: uv.map(|c| c as f32),
    }
}

/// How a prism's walls and roof are textured.
#[derive(Copy, Clone, Debug)]
pub struct PrismUv {
    /// Metres of wall per texture repetition horizontally (u runs continuously around the facade).
    pub rep_u: f64,
    /// Metres of wall per repetition vertically; v = 0 (image top) is at the eaves.
    pub rep_v: f64,
    /// Metres of roof per repetition (planar x–z mapping).
    pub rep_roof: f64,
    /// Split walls into storeys of this height (more, smaller triangles), or one quad per wall.
    pub storey: Option<f64>,
}

/// A flat-roofed prism over the star-shaped footprint `poly` (oriented by [`orient`]) of height `h`,
/// with its roof triangulated as a fan from `center` (which must see every vertex). Returns
/// `(walls, roof)`.
pub fn prism(poly: &[[f64; 2]], center: [f64; 2], h: f64, uv: PrismUv) -> (MeshData, MeshData) {
    let mut walls = MeshData::default();
    let mut roof = MeshData::default();
    let n = poly.len();
    let mut u0 = 0.0;
    let cuts: Vec<f64> = match uv.storey {
        Some(s) if s > 0.0 => {
            let k = (h / s).ceil().max(1.0) as usize;
            (0..=k).map(|i| (i as f64 * s).min(h)).collect()
        }
        _ => vec![0.0, h],
    };
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        let (dx, dz) = (b[0] - a[0], b[1] - a[1]);
        let len = dx.hypot(dz);
        if len <= 1e-9 {
            continue;
        }
        let nrm = [-dz / len, 0.0, dx / len];
        let u1 = u0 + len / uv.rep_u;
        for w in cuts.windows(2) {
            let (y0, y1) = (w[0], w[1]);
            if y1 - y0 <= 1e-9 {
                continue;
            }
            let (v0, v1) = ((h - y0) / uv.rep_v, (h - y1) / uv.rep_v);
            walls.quad([
                vtx([a[0], y0, a[1]], nrm, [u0, v0]),
                vtx([b[0], y0, b[1]], nrm, [u1, v0]),
                vtx([b[0], y1, b[1]], nrm, [u1, v1]),
                vtx([a[0], y1, a[1]], nrm, [u0, v1]),
            ]);
        }
        u0 = u1;
    }
    let up = [0.0, 1.0, 0.0];
    let ruv = |p: [f64; 2]| [p[0] / uv.rep_roof, p[1] / uv.rep_roof];
    for i in 0..n {
        let (a, b) = (poly[i], poly[(i + 1) % n]);
        roof.tri([
            vtx([center[0], h, center[1]], up, ruv(center)),
            vtx([a[0], h, a[1]], up, ruv(a)),
            vtx([b[0], h, b[1]], up, ruv(b)),
        ]);
    }
    (walls, roof)
}

/// An upward-facing axis-aligned ground rectangle `[x0,x1] × [z0,z1]` at height `y`, split into a grid of
/// quads no larger than `cell` metres, with UV = (position − `uv_origin`) / `rep` (so hundreds of
/// repetitions on a large ground).
pub fn ground_grid(
    x: [f64; 2],
    z: [f64; 2],
    y: f64,
    cell: f64,
    uv_origin: [f64; 2],
    rep: f64,
) -> MeshData {
    let mut m = MeshData::default();
    let nx = ((x[1] - x[0]) / cell).ceil().max(1.0) as usize;
    let nz = ((z[1] - z[0]) / cell).ceil().max(1.0) as usize;
    let up = [0.0, 1.0, 0.0];
    let at = |i: usize, j: usize| {
        let px = x[0] + (x[1] - x[0]) * i as f64 / nx as f64;
        let pz = z[0] + (z[1] - z[0]) * j as f64 / nz as f64;
        vtx(
            [px, y, pz],
            up,
            [(px - uv_origin[0]) / rep, (pz - uv_origin[1]) / rep],
        )
    };
    for j in 0..nz {
        for i in 0..nx {
            // (x0,z0) → (x0,z1) → (x1,z1) → (x1,z0): negative area in (x, z), so it faces +y.
            m.quad([at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j)]);
        }
    }
    m
}

/// A vertical quad from `a` to `b` (x–z), `y0..y1`, UV u = 0..`u_max`, v = 0 (top) .. 1 (bottom).
pub fn wall_quad(a: [f64; 2], b: [f64; 2], y0: f64, y1: f64, u_max: f64) -> MeshData {
    let mut m = MeshData::default();
    let (dx, dz) = (b[0] - a[0], b[1] - a[1]);
    let len = dx.hypot(dz).max(1e-9);
    let n = [-dz / len, 0.0, dx / len];
    m.quad([
        vtx([a[0], y0, a[1]], n, [0.0, 1.0]),
        vtx([b[0], y0, b[1]], n, [u_max, 1.0]),
        vtx([b[0], y1, b[1]], n, [u_max, 0.0]),
        vtx([a[0], y1, a[1]], n, [0.0, 0.0]),
    ]);
    m
}

/// Two unit quads crossing at the origin (x–y and z–y planes), 1 m wide and 1 m high: a billboard tree
/// to be scaled by its node.
pub fn crossed_quads() -> MeshData {
    let mut m = wall_quad([-0.5, 0.0], [0.5, 0.0], 0.0, 1.0, 1.0);
    let b = wall_quad([0.0, 0.5], [0.0, -0.5], 0.0, 1.0, 1.0);
    m.quad([b.v[0], b.v[1], b.v[2], b.v[3]]);
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cross_y(m: &MeshData, t: usize) -> [f32; 3] {
        let [a, b, c] = [0, 1, 2].map(|k| m.v[m.idx[t * 3 + k] as usize].p);
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ]
    }

    #[test]
    fn prism_faces_outward_and_up_with_repeated_uvs() {
        let poly = orient(vec![[-10.0, -5.0], [10.0, -5.0], [10.0, 5.0], [-10.0, 5.0]]);
        let uv = PrismUv {
            rep_u: 10.0,
            rep_v: 12.0,
            rep_roof: 8.0,
            storey: None,
        };
        let (walls, roof) = prism(&poly, [0.0, 0.0], 24.0, uv);
        assert_eq!(walls.triangles(), 8);
        assert_eq!(roof.triangles(), 4);
        for t in 0..walls.triangles() as usize {
            let g = cross_y(&walls, t);
            let n = walls.v[walls.idx[t * 3] as usize].n;
            assert!(
                g[0] * n[0] + g[1] * n[1] + g[2] * n[2] > 0.0,
                "wall {t} winding disagrees with normal"
            );
            // Outward: the normal points away from the centre.
            let p = walls.v[walls.idx[t * 3] as usize].p;
            assert!(p[0] * n[0] + p[2] * n[2] > 0.0);
        }
        for t in 0..4 {
            assert!(cross_y(&roof, t)[1] > 0.0, "roof triangle {t} faces down");
        }
        // Perimeter 60 m / 10 m = 6 repetitions around; 24 m / 12 m = 2 vertically.
        let umax = walls.v.iter().map(|v| v.uv[0]).fold(0.0, f32::max);
        let vmax = walls.v.iter().map(|v| v.uv[1]).fold(0.0, f32::max);
        assert!((umax - 6.0).abs() < 1e-5 && (vmax - 2.0).abs() < 1e-5);
        assert!((walls.uv_area() - 12.0).abs() < 1e-4);
    }

    #[test]
    fn storeys_split_walls() {
        let poly = orient(vec![[0.0, 0.0], [4.0, 0.0], [4.0, 4.0]]);
        let uv = PrismUv {
            rep_u: 3.0,
            rep_v: 3.0,
            rep_roof: 5.0,
            storey: Some(3.0),
        };
        let (walls, _) = prism(&poly, [2.5, 1.0], 10.0, uv);
        // 3 edges × ceil(10/3) = 4 storeys × 2 triangles.
        assert_eq!(walls.triangles(), 24);
    }

    #[test]
    fn ground_faces_up() {
        let g = ground_grid([0.0, 100.0], [0.0, 50.0], 0.0, 30.0, [0.0, 0.0], 4.0);
        assert_eq!(g.triangles(), 4 * 2 * 2);
        assert!((0..g.triangles() as usize).all(|t| cross_y(&g, t)[1] > 0.0));
        assert!((g.uv_area() - 100.0 * 50.0 / 16.0).abs() < 1e-3);
    }
}
