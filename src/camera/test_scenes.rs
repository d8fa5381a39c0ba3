//! Hand-made scenes for the ground and generated-path tests: a coastal town, y-up, over the footprint
//! `[0, 1000]²` (x, z). The town is a plateau at height 0 tiled with quads and covered with box
//! buildings (12 m tall, walls split into storeys, so most triangles are there); the rest is a sea floor
//! at −600 m of two large triangles, with a vertical cliff between them.

use crate::scene::synthetic::SceneBuilder;
use crate::scene::{AlphaMode, Scene, UpAxis, Wrap};
use glam::{DVec2, DVec3};

/// Footprint side, metres.
pub(super) const SIDE: f64 = 1000.0;
/// Sea floor height, metres.
pub(super) const SEA: f64 = -600.0;
/// Building height, metres.
pub(super) const ROOF: f64 = 12.0;

/// Which half is the town.
#[derive(Copy, Clone, Debug, PartialEq)]
pub(super) enum Coast {
    /// Town at `x < 500`, sea at `x > 500`.
    West,
    /// Town at `z > 500`, sea at `z < 500`.
    North,
}

impl Coast {
    /// True if plane point `p` (x, z) lies on the town's side.
    pub(super) fn on_town(self, p: DVec2) -> bool {
        match self {
            Coast::West => p.x < SIDE / 2.0,
            Coast::North => p.y > SIDE / 2.0,
        }
    }

    /// Distance of `p` from the coastline, metres.
    pub(super) fn distance_to_coast(self, p: DVec2) -> f64 {
        match self {
            Coast::West => (p.x - SIDE / 2.0).abs(),
            Coast::North => (p.y - SIDE / 2.0).abs(),
        }
    }

    /// World point of plane coordinates `(a, b)` in the town's frame: `a` across the coast (0 at the
    /// far edge of the town, 500 at the coast), `b` along it.
    fn point(self, a: f64, b: f64, h: f64) -> DVec3 {
        match self {
            Coast::West => DVec3::new(a, h, b),
            Coast::North => DVec3::new(b, h, SIDE - a),
        }
    }
}

/// A quad as two triangles, corners in order.
fn quad(out: &mut Vec<[DVec3; 3]>, c: [DVec3; 4]) {
    out.push([c[0], c[1], c[2]]);
    out.push([c[0], c[2], c[3]]);
}

/// The coastal town's triangles: `tile`-metre plateau tiles, a building every `spacing` metres
/// (footprint `spacing · 0.4`, walls in `storeys` rows of quads per side), the cliff and the sea floor.
pub(super) fn coast(coast: Coast, tile: f64, spacing: f64, storeys: usize) -> Vec<[DVec3; 3]> {
    let half = SIDE / 2.0;
    let p = |a: f64, b: f64, h: f64| coast.point(a, b, h);
    let mut t = Vec::new();
    let tiles = (half / tile) as usize;
    let rows = (SIDE / tile) as usize;
    for i in 0..tiles {
        for j in 0..rows {
            let (a, b) = (i as f64 * tile, j as f64 * tile);
            quad(
                &mut t,
                [
                    p(a, b, 0.0),
                    p(a + tile, b, 0.0),
                    p(a + tile, b + tile, 0.0),
                    p(a, b + tile, 0.0),
                ],
            );
        }
    }
    let n = (half / spacing) as usize;
    let m = (SIDE / spacing) as usize;
    let w = spacing * 0.4;
    for i in 0..n {
        for j in 0..m {
            let (a, b) = (
                i as f64 * spacing + spacing * 0.3,
                j as f64 * spacing + spacing * 0.3,
            );
            building(&mut t, &p, (a, b), w, storeys);
        }
    }
    // The cliff and the sea floor.
    quad(
        &mut t,
        [
            p(half, 0.0, SEA),
            p(half, SIDE, SEA),
            p(half, SIDE, 0.0),
            p(half, 0.0, 0.0),
        ],
    );
    quad(
        &mut t,
        [
            p(half, 0.0, SEA),
            p(SIDE, 0.0, SEA),
            p(SIDE, SIDE, SEA),
            p(half, SIDE, SEA),
        ],
    );
    t
}

/// A box building with its low corner at `(a, b)`, side `w`, walls in `storeys` rows, a flat roof.
fn building(
    t: &mut Vec<[DVec3; 3]>,
    p: &impl Fn(f64, f64, f64) -> DVec3,
    (a, b): (f64, f64),
    w: f64,
    storeys: usize,
) {
    let corners = [(a, b), (a + w, b), (a + w, b + w), (a, b + w)];
    let storey = ROOF / storeys as f64;
    for k in 0..4 {
        let (c0, c1) = (corners[k], corners[(k + 1) % 4]);
        for s in 0..storeys {
            let (h0, h1) = (s as f64 * storey, (s + 1) as f64 * storey);
            quad(
                t,
                [
                    p(c0.0, c0.1, h0),
                    p(c1.0, c1.1, h0),
                    p(c1.0, c1.1, h1),
                    p(c0.0, c0.1, h1),
                ],
            );
        }
    }
    quad(t, corners.map(|(x, y)| p(x, y, ROOF)));
}

/// A box of side `w` with its low corner at `corner` (world), walls in `storeys` rows of quads: a dense
/// cluster of triangles away from the ground (an airplane prop over the sea).
pub(super) fn prop(t: &mut Vec<[DVec3; 3]>, corner: DVec3, w: f64, storeys: usize) {
    let p =
        |a: f64, b: f64, h: f64| DVec3::new(corner.x + a, corner.y + h * w / ROOF, corner.z + b);
    building(t, &p, (0.0, 0.0), w, storeys);
}

/// The bounds of triangles.
pub(super) fn bounds(tris: &[[DVec3; 3]]) -> (DVec3, DVec3) {
    tris.iter()
        .flatten()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        })
}

/// The triangles as an imported scene with one textured material (for [`Ground::from_scene`] and the
/// paging-file build).
///
/// [`Ground::from_scene`]: super::Ground::from_scene
pub(super) fn scene(tris: &[[DVec3; 3]]) -> Scene {
    let mut b = SceneBuilder::new(UpAxis::Y);
    let img = b.pattern_image("tile", 16, 1);
    let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
    for &t in tris {
        let uv = t.map(|p| DVec2::new(p.x, p.z) / 10.0);
        b.triangle(t, uv, m);
    }
    b.build()
}
