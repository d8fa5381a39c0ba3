use super::*;
use crate::camera::test_scenes::{self, Coast, SEA, SIDE};
use std::path::Path;

/// FNV-1a over the bits of every number of the path, in order.
fn digest(p: &CameraPath) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |x: f64| {
        for b in x.to_bits().to_le_bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    for k in &p.keyframes {
        eat(k.time);
        k.eye.iter().for_each(|&v| eat(v));
        k.target.iter().for_each(|&v| eat(v));
        eat(k.fov);
    }
    p.up.iter().for_each(|&v| eat(v));
    eat(p.aspect);
    eat(p.near);
    eat(p.far);
    h
}

/// Bounds of the flat-ground regression: ordinary, UTM-size, flat, a point, a deep coastal box; each up
/// axis.
fn flat_scenes() -> Vec<(DVec3, DVec3, UpAxis)> {
    let mut v = Vec::new();
    for up in [UpAxis::X, UpAxis::Y, UpAxis::Z] {
        let swap = |p: DVec3| match up {
            UpAxis::X => DVec3::new(p.y, p.x, p.z),
            UpAxis::Y => p,
            UpAxis::Z => DVec3::new(p.x, p.z, p.y),
        };
        for (lo, hi) in [
            (
                DVec3::new(0.0, 34.0, 0.0),
                DVec3::new(10_000.0, 200.0, 10_000.0),
            ),
            (
                DVec3::new(4.5e6, 120.0, 5.5e6),
                DVec3::new(4.5e6 + 3000.0, 260.0, 5.5e6 + 1800.0),
            ),
            (DVec3::new(-50.0, 0.0, -20.0), DVec3::new(50.0, 0.0, 20.0)),
            (DVec3::ZERO, DVec3::ZERO),
            (
                DVec3::new(-3.25, -600.0, 7.5),
                DVec3::new(1200.0, 45.5, 900.0),
            ),
        ] {
            v.push((swap(lo), swap(hi), up));
        }
    }
    v
}

/// Digests of `[overview-dive, street, orbit]` per [`flat_scenes`] entry, recorded from the
/// bounds-only generator before the ground existed (commit 4db781c).
const BOUNDS_ONLY_DIGESTS: [[u64; 3]; 15] = [
    [0xe6043296f1f83d43, 0x158ec6128e4a5bf4, 0x0f8b79544f618c91],
    [0x866ca27f095ebf65, 0x591f92cc8cca9834, 0xbb2f85e0bc02e28c],
    [0xee1972b67b241401, 0x7a2fe79c74beff7f, 0xdd500cdf1df0c4aa],
    [0x762be17b75a2cff1, 0xb8a0549c53ea9ada, 0xe40d589865baaf18],
    [0x5299d0d3ad13b681, 0x19f57740bb23b2f7, 0x51e8c736ba21b93d],
    [0x2f0a81c50c34d4a3, 0x7ecf835ea97b3fa0, 0x9cdd246ece08a3a1],
    [0x4f6059c56f64fcdd, 0x5c1f160b36ec3b14, 0x2adf4a5feb18055c],
    [0x92e652fcfb9acb81, 0xd8e8d1aee2dfd1ff, 0x661113ecacbc872a],
    [0xa52765cdcf1cac51, 0x44abdd9882969f1a, 0xc762e10b066f64c8],
    [0xe8b8f7c9d30eae29, 0x420e688d44d19a27, 0xb69a6d59453a5225],
    [0xb6cfa6560b8051a3, 0xdacbfbe315c3635c, 0x97648e68b98bb209],
    [0x99c05167243702d5, 0xd09bdc8103e2f130, 0xbd67cdc271213cdc],
    [0x53bc1fefe6a96489, 0x999d238abf3c4647, 0xcba2c0fda28b7f4e],
    [0x8069822384c76db1, 0xa0518933a913da5a, 0x5dc9aaa54f6f5520],
    [0xe4695edc88578629, 0x6f9915e99502020f, 0xe11a2399971394a9],
];

/// The bounds-only dive over the deep coastal box, y-up, keyframe by keyframe (same recording).
const BOUNDS_ONLY_DIVE: &str = r#"[
    { "time":0.0, "eye":[586.3425,1393.8089846637529,444.825], "target":[598.375,-600.0,453.75], "fov":60.0},
    { "time":4.0, "eye":[685.009,-225.46972648229087,384.135], "target":[742.765,-600.0,337.725], "fov":60.0},
    { "time":7.0, "eye":[646.505,-570.0375781185833,266.32500000000005], "target":[742.765,-600.0,337.725], "fov":60.0},
    { "time":9.0, "eye":[718.6999999999999,-598.3,319.875], "target":[742.765,-590.0,337.725], "fov":75.0},
    { "time":11.0, "eye":[730.7325,-598.3,328.8], "target":[742.765,-590.0,337.725], "fov":75.0},
    { "time":13.0, "eye":[646.505,-570.0375781185833,266.32500000000005], "target":[742.765,-600.0,337.725], "fov":60.0},
    { "time":16.0, "eye":[685.009,-225.46972648229087,384.135], "target":[742.765,-600.0,337.725], "fov":60.0},
    { "time":20.0, "eye":[610.4075,1393.8089846637529,462.675], "target":[598.375,-600.0,453.75], "fov":60.0}
]"#;

#[test]
fn a_flat_ground_reproduces_the_bounds_only_paths_exactly() {
    for ((lo, hi, up), expect) in flat_scenes().into_iter().zip(BOUNDS_ONLY_DIGESTS) {
        let g = Ground::flat(lo, hi, up);
        let paths = [
            CameraPath::overview_dive_on(&g),
            CameraPath::street_on(&g),
            CameraPath::orbit_on(&g),
        ]
        .map(|p| p.unwrap_or_else(|e| panic!("{lo} {hi} {up:?}: {e}")));
        assert_eq!(paths.each_ref().map(digest), expect, "{lo} {hi} {up:?}");
        // The bounds-only forms are the same paths.
        assert_eq!(
            CameraPath::overview_dive(lo, hi, up).ok().as_ref(),
            Some(&paths[0])
        );
    }
    let old: Vec<Keyframe> =
        serde_json::from_str(BOUNDS_ONLY_DIVE).unwrap_or_else(|e| panic!("{e}"));
    let g = Ground::flat(
        DVec3::new(-3.25, -600.0, 7.5),
        DVec3::new(1200.0, 45.5, 900.0),
        UpAxis::Y,
    );
    let dive = CameraPath::overview_dive_on(&g).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(dive.keyframes, old);
}

/// Samples of a path, 2001 evenly over its duration.
fn samples(p: &CameraPath) -> Vec<crate::camera::Camera> {
    let (s, d) = (p.start(), p.duration());
    (0..=2000)
        .map(|i| p.sample(s + d * i as f64 / 2000.0))
        .collect()
}

fn coast_ground(coast: Coast) -> Ground {
    let tris = test_scenes::coast(coast, 10.0, 20.0, 4);
    let (lo, hi) = test_scenes::bounds(&tris);
    Ground::from_triangles(lo, hi, UpAxis::Y, tris).unwrap_or_else(|e| panic!("{e}"))
}

/// Checks the generated paths' bounds over `g` that hold for any ground: eye inside the footprint, at
/// least 1.7 m above the ground under it, at most `ceiling`; returns the lowest height above the ground.
fn check_above_ground(p: &CameraPath, g: &Ground, ceiling: f64, ctx: &str) -> f64 {
    p.validate(Path::new("generated"))
        .unwrap_or_else(|e| panic!("{ctx}: {e}"));
    let up = g.up();
    let (lo, hi) = g.bounds();
    let (plo, phi) = (up.plane(lo), up.plane(hi));
    let inside = |q: DVec2| q.cmpge(plo - 1e-6).all() && q.cmple(phi + 1e-6).all();
    let tol = 1e-6 * (1.0 + up.height(lo).abs() + up.height(hi).abs());
    let mut lowest = f64::INFINITY;
    for c in samples(p) {
        let e = up.plane(c.eye);
        assert!(inside(e), "{ctx}: eye {} leaves the footprint", c.eye);
        let above = up.height(c.eye) - g.height_at(e);
        assert!(
            above >= 1.7 - tol,
            "{ctx}: eye {} only {above} m above the ground",
            c.eye
        );
        assert!(
            up.height(c.eye) <= ceiling + tol,
            "{ctx}: eye {} above {ceiling}",
            c.eye
        );
        lowest = lowest.min(above);
    }
    lowest
}

#[test]
fn the_dive_over_a_coast_ends_on_the_plateau_not_the_sea_floor() {
    for coast in [Coast::West, Coast::North] {
        let g = coast_ground(coast);
        let ctx = format!("{coast:?}");
        let dive = CameraPath::overview_dive_on(&g).unwrap_or_else(|e| panic!("{ctx}: {e}"));
        let diag = SIDE * std::f64::consts::SQRT_2;
        let overview = (test_scenes::ROOF + 0.9 * diag).max(20.0);
        let lowest = check_above_ground(&dive, &g, overview, &ctx);
        assert!((lowest - 1.7).abs() < 1e-9, "{ctx}: street level {lowest}");
        let top = samples(&dive)
            .iter()
            .map(|c| c.eye.y)
            .fold(f64::MIN, f64::max);
        assert!((top - overview).abs() < 1e-9, "{ctx}: overview {top}");
        // The street part (9 s to 11 s): on the plateau, 1.7 m above it (≤ 2 m), looking at a building
        // on it; so are its keyframes.
        for k in &dive.keyframes[3..5] {
            let (eye, target) = (DVec3::from(k.eye), DVec3::from(k.target));
            let (pe, pt) = (DVec2::new(eye.x, eye.z), DVec2::new(target.x, target.z));
            assert!(
                coast.on_town(pe) && coast.on_town(pt),
                "{ctx}: {eye} → {target}"
            );
            assert_eq!(
                (eye.y, g.height_at(pe), g.height_at(pt)),
                (1.7, 0.0, 0.0),
                "{ctx}"
            );
        }
        for i in 0..=200 {
            let c = dive.sample(9.0 + 2.0 * i as f64 / 200.0);
            let p = DVec2::new(c.eye.x, c.eye.z);
            assert!(coast.on_town(p), "{ctx}: street eye {} over the sea", c.eye);
            assert!(
                (1.7 - 1e-9..=2.0).contains(&c.eye.y),
                "{ctx}: street eye {}",
                c.eye
            );
        }
        // Targets: inside the footprint, between the lowest ground and the top.
        for c in samples(&dive) {
            assert!(
                (SEA - 1e-9..=test_scenes::ROOF + 1e-9).contains(&c.target.y),
                "{ctx}"
            );
        }
        // Without the ground (bounds only) the same dive ends on the sea floor.
        let (lo, hi) = g.bounds();
        let old = CameraPath::overview_dive(lo, hi, UpAxis::Y).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(old.keyframes[3].eye[1], SEA + 1.7, "{ctx}");
    }
}

/// The street keeps to the content: each keyframe over the content nearest its point of the diagonal,
/// so across a coast it flies over the town on the plateau, never out over the empty sea (where its low
/// eye, looking ahead, saw only sky: 6–9 of 30 frames on several real tracks), at its listed height
/// above the plateau.
#[test]
fn the_street_keeps_to_the_content_across_a_coast() {
    let heights = [1.7, 10.0, 4.0, 1.7, 7.0, 2.5, 10.0, 1.7, 5.0];
    for coast in [Coast::West, Coast::North] {
        let g = coast_ground(coast);
        let ctx = format!("{coast:?}");
        let street = CameraPath::street_on(&g).unwrap_or_else(|e| panic!("{ctx}: {e}"));
        check_above_ground(&street, &g, 10.0, &ctx);
        assert_eq!(street.keyframes.len(), 9);
        for (k, h) in street.keyframes.iter().zip(heights) {
            let plane = g.up().plane(DVec3::from(k.eye));
            assert!(
                coast.on_town(plane),
                "{ctx}: keyframe at {} over the sea",
                k.time
            );
            assert_eq!(
                g.content_near(plane),
                plane,
                "{ctx}: keyframe at {}",
                k.time
            );
            assert_eq!(k.eye[1], h, "{ctx}: keyframe at {}", k.time);
        }
    }
}

/// Rolling hills (up to ±40 m, slopes under 60°) at UTM-size coordinates, z-up, with boxes on them.
fn hills() -> Vec<[DVec3; 3]> {
    let base = DVec3::new(4.5e6, 5.5e6, 300.0);
    let hill = |x: f64, y: f64| 40.0 * (x / 130.0).sin() * (y / 170.0).cos();
    let p = |x: f64, y: f64, dz: f64| base + DVec3::new(x, y, hill(x, y) + dz);
    let mut t = Vec::new();
    let n = 60;
    let step = 2000.0 / n as f64;
    for i in 0..n {
        for j in 0..n {
            let (x, y) = (i as f64 * step, j as f64 * step);
            let c = [
                p(x, y, 0.0),
                p(x + step, y, 0.0),
                p(x + step, y + step, 0.0),
                p(x, y + step, 0.0),
            ];
            t.push([c[0], c[1], c[2]]);
            t.push([c[0], c[2], c[3]]);
            if (i + j) % 3 == 0 {
                // A 20 m tower on the tile's low corner: its roof is ground too.
                let r = [
                    p(x, y, 20.0),
                    p(x + 8.0, y, 20.0),
                    p(x + 8.0, y + 8.0, 20.0),
                ];
                t.push(r);
            }
        }
    }
    t
}

#[test]
fn over_rough_ground_the_eye_never_comes_closer_than_street_level() {
    let tris = hills();
    let (lo, hi) = test_scenes::bounds(&tris);
    let g = Ground::from_triangles(lo, hi, UpAxis::Z, tris).unwrap_or_else(|e| panic!("{e}"));
    assert!(g.highest() - g.lowest() > 50.0, "the ground is not flat");
    let diag = (up_plane(hi) - up_plane(lo)).length();
    let overview = (hi.z + 0.9 * diag).max(g.highest() + 20.0);
    let dive = CameraPath::overview_dive_on(&g).unwrap_or_else(|e| panic!("{e}"));
    let lowest = check_above_ground(&dive, &g, overview, "dive");
    // It reaches the street: on these 17° slopes within 2.3 m of 1.7 m (2.19 m when recorded).
    assert!(lowest < 4.0, "the dive stays {lowest} m above the street");
    for c in samples(&dive) {
        assert!((g.lowest() - 1e-6..=hi.z + 1e-6).contains(&c.target.z));
    }
    let street = CameraPath::street_on(&g).unwrap_or_else(|e| panic!("{e}"));
    check_above_ground(&street, &g, g.highest() + 10.0, "street");
    let orbit = CameraPath::orbit_on(&g).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        orbit,
        CameraPath::orbit(lo, hi, UpAxis::Z).unwrap_or_else(|e| panic!("{e}"))
    );
}

fn up_plane(p: DVec3) -> DVec2 {
    UpAxis::Z.plane(p)
}

/// A scene of one large quad (a 1 km road, 20 m wide) has its content in the cells of its two
/// triangles' centroids: the street path's keyframes all snapped there and the eye stood still for the
/// whole path; it follows the diagonal, which the road covers, from 5 % to 95 % (fault hunt, session 38).
#[test]
fn the_street_path_moves_over_a_scene_of_one_large_quad() {
    let (w, l) = (1000.0, 20.0);
    let corners = [
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(w, 0.0, 0.0),
        DVec3::new(w, 0.0, l),
        DVec3::new(0.0, 0.0, l),
    ];
    let tris = vec![
        [corners[0], corners[2], corners[1]],
        [corners[0], corners[3], corners[2]],
    ];
    let (lo, hi) = test_scenes::bounds(&tris);
    let g = Ground::from_triangles(lo, hi, UpAxis::Y, tris).unwrap_or_else(|e| panic!("{e}"));
    let street = CameraPath::street_on(&g).unwrap_or_else(|e| panic!("{e}"));
    let (first, last) = (
        street.sample(street.start()),
        street.sample(street.start() + street.duration()),
    );
    let moved = (last.eye - first.eye).length();
    assert!(
        moved > 0.8 * w,
        "the eye moved {moved} m along a {w} m road"
    );
    check_above_ground(&street, &g, g.highest() + 10.0, "street");
}

/// A track whose bounds reach far beyond it (zengarden's skybox: a 100 m track in a 10 km box): every
/// keyframe snapped to the one content cell and the eye stood on one spot for the whole path; it flies
/// along the content's own extent instead (fault hunt, session 38).
#[test]
fn the_street_path_moves_over_a_small_track_in_wide_bounds() {
    let mut tris = Vec::new();
    for ix in 0..20 {
        for iz in 0..20 {
            // Off the footprint's diagonal, so no keyframe of it falls on the track.
            let (x, z) = (2000.0 + f64::from(ix) * 5.0, -3000.0 + f64::from(iz) * 5.0);
            let p = |dx: f64, dz: f64| DVec3::new(x + dx, 0.0, z + dz);
            tris.push([p(0.0, 0.0), p(5.0, 5.0), p(5.0, 0.0)]);
            tris.push([p(0.0, 0.0), p(0.0, 5.0), p(5.0, 5.0)]);
        }
    }
    // Two far specks (a sky dome's corners) stretch the bounds to 10 km.
    for c in [-5000.0, 5000.0] {
        tris.push([
            DVec3::new(c, 100.0, c),
            DVec3::new(c + 1.0, 100.0, c),
            DVec3::new(c, 101.0, c),
        ]);
    }
    let (lo, hi) = test_scenes::bounds(&tris);
    let g = Ground::from_triangles(lo, hi, UpAxis::Y, tris).unwrap_or_else(|e| panic!("{e}"));
    let street = CameraPath::street_on(&g).unwrap_or_else(|e| panic!("{e}"));
    let eyes: Vec<DVec3> = samples(&street).iter().map(|c| c.eye).collect();
    let travelled: f64 = eyes
        .windows(2)
        .map(|w| (w[1] - w[0]).with_y(0.0).length())
        .sum();
    // About 15 m/s, as documented: it crept between a few cell centres over the 10 km diagonal's time
    // (~0.5 m/s), standing still for tens of seconds.
    let speed = travelled / street.duration();
    assert!(
        travelled > 50.0 && speed > 5.0,
        "the eye travelled {travelled} m at {speed} m/s"
    );
    for e in &eyes {
        assert!(
            (1700.0..=2400.0).contains(&e.x) && (-3300.0..=-2600.0).contains(&e.z),
            "{e}"
        );
    }
}
