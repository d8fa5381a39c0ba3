//! The `chemnitz` layout (paper §7): irregular footprints, a pool of ~2,000 textures of mixed sizes,
//! massively repeated ground tiles, alpha-tested fences and blended trees.

use super::*;

fn pool_size(kind: PoolKind, rng: &mut Rng, max: u32) -> (u32, u32) {
    let pick = |rng: &mut Rng, w: &[f64]| SIZES[rng.weighted(w)];
    let (w, h) = match kind {
        PoolKind::Facade | PoolKind::Concrete => {
            let s = pick(rng, &FACADE_SIZE_WEIGHTS);
            match rng.below(8) {
                0 => (s, (s / 2).max(16)),
                1 => ((s / 2).max(16), s),
                _ => (s, s),
            }
        }
        PoolKind::Photo => (
            pick(rng, &[0.0, 0.0, 0.0, 0.0, 2.0, 2.0, 1.0]),
            pick(rng, &[0.0, 0.0, 0.0, 0.0, 2.0, 2.0, 1.0]),
        ),
        PoolKind::Roof => (pick(rng, &[0.0, 2.0, 3.0, 3.0, 2.0, 1.0]), 0),
        PoolKind::Paving => (pick(rng, &[3.0, 4.0, 3.0, 1.0, 0.3]), 0),
        PoolKind::Fence => {
            let s = pick(rng, &[0.0, 0.0, 1.0, 2.0, 1.0]);
            (s, s / 2)
        }
        PoolKind::Tree => (pick(rng, &[0.0, 0.0, 0.0, 1.0, 2.0, 1.0]), 0),
        PoolKind::Sign => {
            let s = pick(rng, &[0.0, 0.0, 1.0, 2.0, 1.0]);
            (s, s / 2)
        }
    };
    let h = if h == 0 { w } else { h };
    (w.min(max).max(16), h.min(max).max(16))
}

struct PoolMat {
    kind: PoolKind,
    material: usize,
    /// Metres per repetition (u, v) on walls, or per repetition on roofs and pavings.
    rep: [f64; 2],
}

fn chemnitz_pool(city: &mut City, p: &ChemnitzParams, rng: &mut Rng) -> Vec<PoolMat> {
    use PoolKind::*;
    let fixed = [
        Photo, Photo, Fence, Tree, Sign, Concrete, Paving, Roof, Facade, Fence, Tree,
    ];
    let kinds = [Facade, Concrete, Photo, Roof, Paving, Fence, Tree, Sign];
    let weights = [40.0, 8.0, 0.5, 15.0, 12.0, 7.0, 8.0, 8.0];
    let total = p.textures.max(fixed.len() as u32);
    let mut pool = Vec::with_capacity(total as usize);
    for i in 0..total {
        let kind = fixed
            .get(i as usize)
            .copied()
            .unwrap_or_else(|| kinds[rng.weighted(&weights)]);
        let (w, h) = pool_size(kind, rng, p.max_size);
        let name = format!("c{i:05}_{}", format!("{kind:?}").to_lowercase());
        let (tex, enc) = match kind {
            Facade => (
                TexKind::Facade(crate::texgen::Facade {
                    id: None,
                    floors: rng.int(1, 2),
                    cols: rng.int(1, 3),
                    wall: colour(rng, 90, 240),
                    frame: colour(rng, 30, 250),
                    glass: colour(rng, 40, 160),
                }),
                Encoding::PngRgb,
            ),
            Concrete => (
                TexKind::Concrete {
                    panels: rng.int(1, 3),
                },
                Encoding::PngGrey,
            ),
            Photo => (TexKind::Photo, Encoding::Jpeg),
            Roof => (TexKind::Roof(rng.below(3) as u8), Encoding::PngRgb),
            Paving => (
                TexKind::Paving {
                    n: rng.int(1, 4),
                    base: colour(rng, 110, 220),
                },
                Encoding::PngRgb,
            ),
            Fence => (
                TexKind::Fence {
                    cells: rng.int(4, 10),
                    wire: colour(rng, 100, 200),
                },
                Encoding::PngRgba,
            ),
            Tree => (
                TexKind::Tree {
                    leaf: [
                        rng.int(30, 90) as u8,
                        rng.int(80, 150) as u8,
                        rng.int(20, 60) as u8,
                    ],
                },
                Encoding::PngRgba,
            ),
            Sign => (TexKind::Sign { number: i }, Encoding::PngPalette),
        };
        let img = city.texture(format!("{name}.{}", enc.ext()), w, h, tex, enc);
        let (wrap, alpha, two_sided) = match kind {
            Facade | Concrete if rng.chance(0.15) => ([M, M], Alpha::Opaque, false),
            Paving if rng.chance(0.3) => ([M, M], Alpha::Opaque, false),
            Fence => ([R, C], Alpha::Mask(0.5), true),
            Tree => ([C, C], Alpha::Blend, true),
            Sign => ([C, C], Alpha::Opaque, true),
            _ => ([R, R], Alpha::Opaque, false),
        };
        let material = city.material(name, Some((img, wrap)), [1.0; 4], alpha, two_sided);
        let rep = match kind {
            Facade | Concrete => [rng.range(3.0, 8.0), rng.range(3.0, 6.0)],
            Photo => [rng.range(10.0, 20.0), rng.range(10.0, 20.0)],
            Roof => [rng.range(4.0, 10.0); 2],
            _ => [1.0, 1.0],
        };
        pool.push(PoolMat {
            kind,
            material,
            rep,
        });
    }
    pool
}

/// A star-shaped footprint (rotated rectangle, irregular star polygon or L shape) of radius about `r`
/// metres, oriented by [`geom::orient`], and a fan centre that sees every vertex.
fn footprint(rng: &mut Rng, r: f64) -> (Vec<[f64; 2]>, [f64; 2]) {
    let rot = rng.range(0.0, std::f64::consts::PI);
    let (s, c) = rot.sin_cos();
    let turn = |p: [f64; 2]| [p[0] * c - p[1] * s, p[0] * s + p[1] * c];
    let (poly, center) = match rng.below(20) {
        0..=6 => {
            let (a, b) = (r * rng.range(0.5, 1.0), r * rng.range(0.4, 1.0));
            (vec![[-a, -b], [a, -b], [a, b], [-a, b]], [0.0, 0.0])
        }
        7..=15 => {
            let n = rng.int(5, 9);
            let phase = rng.range(0.0, 1.0);
            let pts = (0..n)
                .map(|i| {
                    let t = (i as f64 + phase + rng.range(-0.3, 0.3)) / n as f64
                        * std::f64::consts::TAU;
                    let rr = r * rng.range(0.55, 1.0);
                    [rr * t.cos(), rr * t.sin()]
                })
                .collect();
            (pts, [0.0, 0.0])
        }
        _ => {
            // L: [0,a]×[0,b] minus [ca,a]×[db,b]; its kernel contains (ca/2, db/2).
            let (a, b) = (2.0 * r * rng.range(0.6, 1.0), 2.0 * r * rng.range(0.6, 1.0));
            let (ca, db) = (a * rng.range(0.35, 0.65), b * rng.range(0.35, 0.65));
            let o = [-a / 2.0, -b / 2.0];
            let pts = [[0.0, 0.0], [a, 0.0], [a, db], [ca, db], [ca, b], [0.0, b]]
                .map(|q| [q[0] + o[0], q[1] + o[1]]);
            (pts.to_vec(), [ca / 2.0 + o[0], db / 2.0 + o[1]])
        }
    };
    (
        geom::orient(poly.into_iter().map(turn).collect()),
        turn(center),
    )
}

#[derive(Copy, Clone, Debug, PartialEq, Eq)]
enum Cell {
    Building,
    Plaza,
    Park,
}

/// An irregular district after the Chemnitz model: a pool of `p.textures` textures, every one used at
/// least once. Returns the district extent `(x, z)` in metres.
pub fn chemnitz(city: &mut City, p: &ChemnitzParams) -> [f64; 2] {
    let mut rng = Rng::derive(city.seed, Stream::Pool, 0);
    let pool = chemnitz_pool(city, p, &mut rng);
    let of =
        |k: PoolKind| -> Vec<usize> { (0..pool.len()).filter(|i| pool[*i].kind == k).collect() };
    let facades: Vec<usize> = (0..pool.len())
        .filter(|i| {
            matches!(
                pool[*i].kind,
                PoolKind::Facade | PoolKind::Concrete | PoolKind::Photo
            )
        })
        .collect();
    let (roofs, pavings, fences, trees, signs) = (
        of(PoolKind::Roof),
        of(PoolKind::Paving),
        of(PoolKind::Fence),
        of(PoolKind::Tree),
        of(PoolKind::Sign),
    );
    let plain_roofs: Vec<usize> = [
        [0.55f32, 0.25, 0.2, 1.0],
        [0.35, 0.35, 0.38, 1.0],
        [0.2, 0.45, 0.3, 1.0],
    ]
    .iter()
    .enumerate()
    .map(|(i, f)| city.material(format!("plain_roof_{i}"), None, *f, Alpha::Opaque, false))
    .collect();

    let img = city.texture(
        "c_grass.png".into(),
        128,
        128,
        TexKind::Grass,
        Encoding::PngRgb,
    );
    let grass = city.material(
        "grass".into(),
        Some((img, [R, R])),
        [1.0; 4],
        Alpha::Opaque,
        false,
    );
    let buildings = p
        .buildings
        .max(facades.len() as u32)
        .max(roofs.len() as u32);
    let fence_objs = 2 * fences.len();
    let tree_objs = 3 * trees.len();
    let parks = fence_objs
        .div_ceil(2)
        .max(tree_objs.div_ceil(4))
        .max(signs.len().div_ceil(2))
        .max(1);
    let mut cells: Vec<Cell> = std::iter::repeat_n(Cell::Building, buildings as usize)
        .chain(std::iter::repeat_n(
            Cell::Plaza,
            pavings.len().saturating_sub(1),
        ))
        .chain(std::iter::repeat_n(Cell::Park, parks))
        .collect();
    let mut layout = Rng::derive(city.seed, Stream::Layout, 0);
    layout.shuffle(&mut cells);
    let cols = ((cells.len() as f64).sqrt().ceil() as usize).max(1);
    let rows = cells.len().div_ceil(cols);
    let extent = [cols as f64 * CELL, rows as f64 * CELL];

    let group = city.group("chemnitz", p.origin);
    // Ground: two single triangles-pairs over the whole district with u, v reaching ±300 (paper Fig. 2a).
    let half = [extent[0] / 2.0 + CELL, extent[1] / 2.0 + CELL];
    let centre = [extent[0] / 2.0, extent[1] / 2.0];
    let tile = half[0].max(half[1]) / 300.0;
    let g = geom::ground_grid(
        [centre[0] - half[0], centre[0] + half[0]],
        [centre[1] - half[1], centre[1] + half[1]],
        -0.02,
        f64::INFINITY,
        centre,
        tile,
    );
    let base = pavings
        .first()
        .map_or(plain_roofs[1], |i| pool[*i].material);
    let mesh = city.gltf.add_mesh("chemnitz_ground", &[(g, base)]);
    city.child(
        group,
        NodeDef {
            name: "chemnitz_ground".into(),
            mesh: Some(mesh),
            ..Default::default()
        },
    );

    // Tree meshes: one crossed-quad mesh per tree texture, instanced by scaled nodes.
    let tree_meshes: Vec<usize> = trees
        .iter()
        .map(|t| {
            city.gltf.add_mesh(
                &format!("tree_{t:05}"),
                &[(geom::crossed_quads(), pool[*t].material)],
            )
        })
        .collect();

    let (mut b, mut plaza, mut park) = (0usize, 1usize, 0usize);
    for (k, cell) in cells.iter().enumerate() {
        let origin = [
            (k % cols) as f64 * CELL + CELL / 2.0,
            (k / cols) as f64 * CELL + CELL / 2.0,
        ];
        let mut rng = Rng::derive(city.seed, Stream::Building, (1 << 32) + k as u64);
        match cell {
            Cell::Building => {
                let radius = rng.range(6.0, 15.0);
                let (poly, center) = footprint(&mut rng, radius);
                let h = rng.range(6.0, 30.0);
                let fi = facades
                    .get(b)
                    .copied()
                    .unwrap_or_else(|| facades[rng.below(facades.len() as u32) as usize]);
                let (roof, rep_roof) = match roofs.get(b) {
                    Some(r) => (pool[*r].material, pool[*r].rep[0]),
                    None if rng.chance(0.1) || roofs.is_empty() => {
                        (plain_roofs[rng.below(3) as usize], 6.0)
                    }
                    None => {
                        let r = &pool[roofs[rng.below(roofs.len() as u32) as usize]];
                        (r.material, r.rep[0])
                    }
                };
                let uv = PrismUv {
                    rep_u: pool[fi].rep[0],
                    rep_v: pool[fi].rep[1],
                    rep_roof,
                    storey: Some(3.0),
                };
                let (walls, top) = geom::prism(&poly, center, h, uv);
                let name = format!("irregular_{b:05}");
                let mesh = city
                    .gltf
                    .add_mesh(&name, &[(walls, pool[fi].material), (top, roof)]);
                let t = [
                    origin[0] + rng.range(-3.0, 3.0),
                    0.0,
                    origin[1] + rng.range(-3.0, 3.0),
                ]
                .map(|c| c as f32);
                city.child(
                    group,
                    NodeDef {
                        name,
                        mesh: Some(mesh),
                        translation: Some(t),
                        ..Default::default()
                    },
                );
                city.counts.irregular_buildings += 1;
                b += 1;
            }
            Cell::Plaza => {
                // One large paved triangle per plaza; 0.12 m pavers → u, v up to about ±150.
                let mi = pool[pavings[plaza]].material;
                let r = CELL * 0.5;
                let mut m = MeshData::default();
                let tri =
                    geom::ground_grid([-r, r], [-r, r], 0.02, f64::INFINITY, [0.0, 0.0], 0.12);
                m.tri([tri.v[0], tri.v[1], tri.v[2]]);
                let name = format!("plaza_{plaza:05}");
                let mesh = city.gltf.add_mesh(&name, &[(m, mi)]);
                let t = [origin[0] as f32, 0.0, origin[1] as f32];
                city.child(
                    group,
                    NodeDef {
                        name,
                        mesh: Some(mesh),
                        translation: Some(t),
                        ..Default::default()
                    },
                );
                city.counts.plazas += 1;
                plaza += 1;
            }
            Cell::Park => {
                let half = CELL * 0.45;
                // A lawn of 2 m grass tiles.
                let lawn = geom::ground_grid(
                    [-half, half],
                    [-half, half],
                    0.01,
                    f64::INFINITY,
                    [0.0, 0.0],
                    2.0,
                );
                let name = format!("park_{park:05}");
                let mesh = city.gltf.add_mesh(&name, &[(lawn, grass)]);
                let t = [origin[0] as f32, 0.0, origin[1] as f32];
                city.child(
                    group,
                    NodeDef {
                        name,
                        mesh: Some(mesh),
                        translation: Some(t),
                        ..Default::default()
                    },
                );
                for f in [2 * park, 2 * park + 1] {
                    if f >= fence_objs {
                        continue;
                    }
                    let pm = &pool[fences[f % fences.len()]];
                    let (a, bb) = if f % 2 == 0 {
                        ([-half, -half], [half, -half])
                    } else {
                        ([-half, half], [-half, -half])
                    };
                    let len = 2.0 * half;
                    let m = geom::wall_quad(a, bb, 0.0, 2.0, len / 2.0);
                    let name = format!("fence_{f:05}");
                    let mesh = city.gltf.add_mesh(&name, &[(m, pm.material)]);
                    let t = [origin[0] as f32, 0.0, origin[1] as f32];
                    city.child(
                        group,
                        NodeDef {
                            name,
                            mesh: Some(mesh),
                            translation: Some(t),
                            ..Default::default()
                        },
                    );
                    city.counts.fences += 1;
                }
                for t in 4 * park..4 * park + 4 {
                    if t >= tree_objs {
                        continue;
                    }
                    let s = rng.range(5.0, 12.0) as f32;
                    let angle = rng.range(0.0, std::f64::consts::PI) as f32 * 0.5;
                    let pos = [
                        origin[0] + rng.range(-half, half) * 0.8,
                        0.0,
                        origin[1] + rng.range(-half, half) * 0.8,
                    ]
                    .map(|c| c as f32);
                    let node = NodeDef {
                        name: format!("tree_{t:05}"),
                        mesh: Some(tree_meshes[t % tree_meshes.len()]),
                        translation: Some(pos),
                        rotation: Some([0.0, angle.sin(), 0.0, angle.cos()]),
                        scale: Some([s, s, s]),
                        ..Default::default()
                    };
                    city.child(group, node);
                    city.counts.tree_instances += 1;
                }
                for si in [2 * park, 2 * park + 1] {
                    let Some(sign) = signs.get(si) else { continue };
                    let z = if si % 2 == 0 { half } else { 0.0 };
                    let m = geom::wall_quad([-2.0, z], [2.0, z], 2.0, 4.0, 1.0);
                    let name = format!("sign_{si:05}");
                    let mesh = city.gltf.add_mesh(&name, &[(m, pool[*sign].material)]);
                    let t = [origin[0] as f32, 0.0, origin[1] as f32];
                    city.child(
                        group,
                        NodeDef {
                            name,
                            mesh: Some(mesh),
                            translation: Some(t),
                            ..Default::default()
                        },
                    );
                    city.counts.signs += 1;
                }
                city.counts.parks += 1;
                park += 1;
            }
        }
    }
    extent
}
