//! Scene layouts after paper §7: `berlin` (block buildings on a street grid, one labelled facade texture
//! per building, repeated around it), `chemnitz` (irregular footprints, ~2,000 textures of mixed sizes,
//! massively repeated ground tiles, alpha-tested fences and blended trees) and their blend `mixed`.

use crate::geom::{self, PrismUv};
use crate::gltf_out::{Alpha, GltfBuilder, MaterialDef, MeshData, NodeDef, WrapMode};
use crate::rng::{Rng, Stream};
use crate::texgen::{Encoding, Facade, TexKind, TexSpec};
use serde::Serialize;

mod chemnitz;

pub use chemnitz::chemnitz;

/// Object counts reported in `citygen.json`.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Counts {
    /// Distinct block buildings (each with its own facade texture and printed id).
    pub block_buildings: u64,
    /// Extra nodes that instance a block building's mesh (rotated 90°).
    pub block_instances: u64,
    pub irregular_buildings: u64,
    pub plazas: u64,
    pub parks: u64,
    pub fences: u64,
    pub tree_instances: u64,
    pub signs: u64,
    pub untextured_materials: u64,
    pub mask_materials: u64,
    pub blend_materials: u64,
}

/// The scene under construction: glTF document plus the textures still to be generated.
pub struct City {
    pub gltf: GltfBuilder,
    pub textures: Vec<TexSpec>,
    pub counts: Counts,
    seed: u64,
    root: usize,
}

/// Berlin-style block buildings.
#[derive(Clone, Debug, Serialize)]
pub struct BerlinParams {
    pub buildings: u32,
    /// Facade texture edge in texels (square).
    pub facade_size: u32,
    pub roof_size: u32,
    pub ground_size: u32,
    /// District origin in the x–z plane, metres.
    pub origin: [f64; 2],
}

/// Chemnitz-style irregular district.
#[derive(Clone, Debug, Serialize)]
pub struct ChemnitzParams {
    /// Minimum number of buildings (raised if the texture pool needs more to use every texture).
    pub buildings: u32,
    /// Size of the texture pool (at least 11: every kind occurs, fences and trees twice).
    pub textures: u32,
    /// Largest texture edge in texels (the pool goes up to 2048).
    pub max_size: u32,
    pub origin: [f64; 2],
}

const LOT: f64 = 40.0;
const LOT_COLS: u32 = 4;
const LOT_ROWS: u32 = 2;
const STREET: f64 = 20.0;
/// One in this many block buildings gets a second, instancing node: buildings 7, 47, 87, …
const TWIN_EVERY: u32 = 40;
const TWIN_PHASE: u32 = 7;
/// Metres of wall per facade repetition (paper §7: the texture is repeated around the facade).
const FACADE_REP_U: f64 = 10.0;
const FACADE_REP_V: f64 = 12.0;
const CELL: f64 = 36.0;

const R: WrapMode = WrapMode::Repeat;
const M: WrapMode = WrapMode::MirroredRepeat;
const C: WrapMode = WrapMode::ClampToEdge;

impl City {
    pub fn new(seed: u64) -> Self {
        let mut gltf = GltfBuilder::default();
        let root = gltf.add_node(
            NodeDef {
                name: "city".into(),
                ..Default::default()
            },
            true,
        );
        City {
            gltf,
            textures: Vec::new(),
            counts: Counts::default(),
            seed,
            root,
        }
    }

    /// Registers a texture to generate; returns its glTF image index. Its seed depends only on the global
    /// seed and the image index.
    fn texture(
        &mut self,
        file: String,
        w: u32,
        h: u32,
        kind: TexKind,
        encoding: Encoding,
    ) -> usize {
        let image = self.gltf.add_image(
            &format!("textures/{file}"),
            encoding.mime(),
            u64::from(w) * u64::from(h),
        );
        let seed = Rng::derive(self.seed, Stream::Texture, image as u64).next_u64();
        self.textures.push(TexSpec {
            file,
            width: w,
            height: h,
            kind,
            encoding,
            seed,
        });
        image
    }

    fn material(
        &mut self,
        name: String,
        texture: Option<(usize, [WrapMode; 2])>,
        factor: [f32; 4],
        alpha: Alpha,
        double_sided: bool,
    ) -> usize {
        match alpha {
            Alpha::Mask(_) => self.counts.mask_materials += 1,
            Alpha::Blend => self.counts.blend_materials += 1,
            Alpha::Opaque => {}
        }
        if texture.is_none() {
            self.counts.untextured_materials += 1;
        }
        self.gltf.add_material(&MaterialDef {
            name,
            texture,
            factor,
            alpha,
            double_sided,
        })
    }

    fn group(&mut self, name: &str, origin: [f64; 2]) -> usize {
        let n = self.gltf.add_node(
            NodeDef {
                name: name.into(),
                translation: Some([origin[0] as f32, 0.0, origin[1] as f32]),
                ..Default::default()
            },
            false,
        );
        self.gltf.add_child(self.root, n);
        n
    }

    fn child(&mut self, parent: usize, node: NodeDef) -> usize {
        let n = self.gltf.add_node(node, false);
        self.gltf.add_child(parent, n);
        n
    }
}

fn colour(rng: &mut Rng, lo: u32, hi: u32) -> [u8; 3] {
    [
        rng.int(lo, hi) as u8,
        rng.int(lo, hi) as u8,
        rng.int(lo, hi) as u8,
    ]
}

/// Places `p.buildings` box buildings on a street grid: blocks of `4 × 2` lots of 40 m, streets of 20 m,
/// footprints 10–40 m, heights 8–60 m (skewed low). Returns the district extent `(x, z)` in metres.
pub fn berlin(city: &mut City, p: &BerlinParams) -> [f64; 2] {
    let n = p.buildings.max(1);
    let twins = (n + TWIN_EVERY - 1 - TWIN_PHASE) / TWIN_EVERY;
    let lots = n + twins;
    let per_block = LOT_COLS * LOT_ROWS;
    let blocks = lots.div_ceil(per_block);
    let pitch = [
        LOT_COLS as f64 * LOT + STREET,
        LOT_ROWS as f64 * LOT + STREET,
    ];
    let cols = ((blocks as f64 * pitch[1] / pitch[0]).sqrt().ceil() as u32).max(1);
    let rows = blocks.div_ceil(cols);
    let extent = [cols as f64 * pitch[0], rows as f64 * pitch[1]];

    let roof_mats: Vec<usize> = (0..3u8)
        .map(|k| {
            let img = city.texture(
                format!("roof_{k}.png"),
                p.roof_size,
                p.roof_size,
                TexKind::Roof(k),
                Encoding::PngRgb,
            );
            city.material(
                format!("roof_{k}"),
                Some((img, [R, R])),
                [1.0; 4],
                Alpha::Opaque,
                false,
            )
        })
        .collect();
    let img = city.texture(
        "asphalt.png".into(),
        p.ground_size,
        p.ground_size,
        TexKind::Asphalt,
        Encoding::PngGrey,
    );
    let asphalt = city.material(
        "asphalt".into(),
        Some((img, [R, R])),
        [1.0; 4],
        Alpha::Opaque,
        false,
    );

    let group = city.group("berlin", p.origin);
    // Ground: 4 m asphalt tiles over the district plus a street-wide margin; hundreds of repetitions.
    let g = geom::ground_grid(
        [-STREET, extent[0]],
        [-STREET, extent[1]],
        0.0,
        400.0,
        [0.0, 0.0],
        4.0,
    );
    let mesh = city.gltf.add_mesh("berlin_ground", &[(g, asphalt)]);
    city.child(
        group,
        NodeDef {
            name: "berlin_ground".into(),
            mesh: Some(mesh),
            ..Default::default()
        },
    );

    let block_nodes: Vec<usize> = (0..blocks)
        .map(|b| {
            let o = [(b % cols) as f64 * pitch[0], (b / cols) as f64 * pitch[1]];
            city.child(
                group,
                NodeDef {
                    name: format!("block_{b:05}"),
                    translation: Some([o[0] as f32, 0.0, o[1] as f32]),
                    ..Default::default()
                },
            )
        })
        .collect();

    let mut lot = 0u32;
    for id in 0..n {
        let mut rng = Rng::derive(city.seed, Stream::Building, u64::from(id));
        let (w, d) = (rng.range(10.0, 40.0), rng.range(10.0, 40.0));
        let h = 8.0 + 52.0 * rng.f64().powi(2);
        let fac = Facade {
            id: Some(id),
            floors: rng.int(3, 5),
            cols: rng.int(2, 5),
            wall: colour(&mut rng, 110, 230),
            frame: colour(&mut rng, 40, 250),
            glass: colour(&mut rng, 50, 150),
        };
        let img = city.texture(
            format!("facade_{id:05}.png"),
            p.facade_size,
            p.facade_size,
            TexKind::Facade(fac),
            Encoding::PngRgb,
        );
        let facade = city.material(
            format!("facade_{id:05}"),
            Some((img, [R, R])),
            [1.0; 4],
            Alpha::Opaque,
            false,
        );
        let roof = roof_mats[rng.below(3) as usize];
        let poly = geom::orient(vec![
            [-w / 2.0, -d / 2.0],
            [w / 2.0, -d / 2.0],
            [w / 2.0, d / 2.0],
            [-w / 2.0, d / 2.0],
        ]);
        let uv = PrismUv {
            rep_u: FACADE_REP_U,
            rep_v: FACADE_REP_V,
            rep_roof: 8.0,
            storey: None,
        };
        let (walls, top) = geom::prism(&poly, [0.0, 0.0], h, uv);
        let mesh = city.gltf.add_mesh(
            &format!("building_{id:05}"),
            &[(walls, facade), (top, roof)],
        );
        let jitter = rng.f64();
        let mut place =
            |city: &mut City, name: String, fw: f64, fd: f64, rotation: Option<[f32; 4]>| {
                let (block, j) = (lot / per_block, lot % per_block);
                let (col, row) = (j % LOT_COLS, j / LOT_COLS);
                let x = col as f64 * LOT + fw / 2.0 + jitter * (LOT - fw);
                // Front faces the street: row 0 flush with the block's near edge, row 1 with the far edge.
                let z = if row == 0 {
                    fd / 2.0
                } else {
                    LOT_ROWS as f64 * LOT - fd / 2.0
                };
                let parent = block_nodes[block as usize];
                city.child(
                    parent,
                    NodeDef {
                        name,
                        mesh: Some(mesh),
                        translation: Some([x as f32, 0.0, z as f32]),
                        rotation,
                        ..Default::default()
                    },
                );
                lot += 1;
            };
        place(city, format!("building_{id:05}"), w, d, None);
        city.counts.block_buildings += 1;
        if id % TWIN_EVERY == TWIN_PHASE {
            let s = std::f32::consts::FRAC_1_SQRT_2;
            place(
                city,
                format!("building_{id:05}_twin"),
                d,
                w,
                Some([0.0, s, 0.0, s]),
            );
            city.counts.block_instances += 1;
        }
    }
    extent
}

/// Texture kinds of the Chemnitz pool.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
enum PoolKind {
    Facade,
    Concrete,
    Photo,
    Roof,
    Paving,
    Fence,
    Tree,
    Sign,
}

/// Edge lengths `[16 … 2048]` and their weights for facade-like pool textures: mostly small, a few large.
const SIZES: [u32; 8] = [16, 32, 64, 128, 256, 512, 1024, 2048];
const FACADE_SIZE_WEIGHTS: [f64; 8] = [30.0, 30.0, 20.0, 12.0, 5.0, 2.0, 0.6, 0.2];
