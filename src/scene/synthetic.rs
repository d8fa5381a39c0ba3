//! Scenes built in code, for tests, benchmarks and the hard-case suite: no files, images encoded as PNG in
//! memory (so the real lazy-decode path runs).

use super::image_source::ImageData;
use super::{
    AlphaMode, ImageSource, ImportReport, Material, Scene, Triangle, UpAxis, Vertex, Wrap,
};
use crate::ids::{ImageId, MaterialId};
use glam::{DVec2, DVec3};
use std::sync::Arc;

/// Builds a [`Scene`] triangle by triangle.
pub struct SceneBuilder {
    scene: Scene,
}

impl SceneBuilder {
    pub fn new(up: UpAxis) -> Self {
        SceneBuilder {
            scene: Scene {
                source: "synthetic".into(),
                up,
                vertices: Vec::new(),
                triangles: Vec::new(),
                materials: Vec::new(),
                images: Vec::new(),
                report: ImportReport::default(),
            },
        }
    }

    /// Adds an RGBA8 image given by `texel(x, y) -> [r, g, b, a]` (sRGB, straight alpha), PNG-encoded.
    pub fn image(
        &mut self,
        name: &str,
        w: u32,
        h: u32,
        texel: impl Fn(u32, u32) -> [u8; 4],
    ) -> ImageId {
        let img = image::RgbaImage::from_fn(w, h, |x, y| image::Rgba(texel(x, y)));
        let mut bytes = Vec::new();
        let has_alpha = img.pixels().any(|p| p.0[3] < 255);
        // Encoding an in-memory RGBA8 buffer cannot fail except on allocation.
        if img
            .write_to(
                &mut std::io::Cursor::new(&mut bytes),
                image::ImageFormat::Png,
            )
            .is_err()
        {
            bytes.clear();
        }
        self.scene.images.push(ImageSource {
            name: name.to_string(),
            width: w,
            height: h,
            has_alpha,
            color: "Rgba8".into(),
            data: ImageData::Bytes(Arc::from(bytes.into_boxed_slice())),
            gltf_image: None,
        });
        ImageId(self.scene.images.len() as u32 - 1)
    }

    /// A test pattern: a colour gradient with a checker and an id-dependent hue, so every texel differs.
    pub fn pattern_image(&mut self, name: &str, size: u32, id: u32) -> ImageId {
        let hue = id.wrapping_mul(2654435761);
        self.image(name, size, size, move |x, y| {
            let c = ((x / 8 + y / 8) % 2) as u8 * 60;
            [
                ((x * 255 / size.max(1)) as u8).wrapping_add((hue & 0xff) as u8) / 2 + c,
                ((y * 255 / size.max(1)) as u8).wrapping_add(((hue >> 8) & 0xff) as u8) / 2 + c,
                (((hue >> 16) & 0xff) as u8) / 2 + c,
                255,
            ]
        })
    }

    pub fn material(&mut self, image: ImageId, wrap: [Wrap; 2], alpha: AlphaMode) -> MaterialId {
        self.scene.materials.push(Material {
            name: format!("material {}", self.scene.materials.len()),
            image,
            tex_coord: 0,
            wrap,
            alpha,
            base_color_factor: [1.0; 4],
            texture_transform: false,
            gltf_material: None,
        });
        MaterialId(self.scene.materials.len() as u32 - 1)
    }

    pub fn triangle(&mut self, pos: [DVec3; 3], uv: [DVec2; 3], material: MaterialId) {
        let base = self.scene.vertices.len() as u32;
        for k in 0..3 {
            self.scene.vertices.push(Vertex {
                pos: pos[k],
                uv: uv[k],
            });
        }
        self.scene.triangles.push(Triangle {
            v: [base, base + 1, base + 2],
            material,
        });
    }

    /// A quad `a b c d` (counter-clockwise) with UVs spanning `[uv0, uv1]` (a → uv0, c → uv1).
    pub fn quad(&mut self, c: [DVec3; 4], uv0: DVec2, uv1: DVec2, material: MaterialId) {
        let uv = [uv0, DVec2::new(uv1.x, uv0.y), uv1, DVec2::new(uv0.x, uv1.y)];
        self.triangle([c[0], c[1], c[2]], [uv[0], uv[1], uv[2]], material);
        self.triangle([c[0], c[2], c[3]], [uv[0], uv[2], uv[3]], material);
    }

    /// A y-up box building: four walls with `facade` repeated every `repeat_m` metres, and a roof.
    pub fn building(
        &mut self,
        min: DVec3,
        max: DVec3,
        facade: MaterialId,
        roof: MaterialId,
        repeat_m: f64,
    ) {
        let (x0, y0, z0) = (min.x, min.y, min.z);
        let (x1, y1, z1) = (max.x, max.y, max.z);
        let h = (y1 - y0) / repeat_m;
        let walls = [
            (DVec3::new(x0, y0, z0), DVec3::new(x1, y0, z0)),
            (DVec3::new(x1, y0, z0), DVec3::new(x1, y0, z1)),
            (DVec3::new(x1, y0, z1), DVec3::new(x0, y0, z1)),
            (DVec3::new(x0, y0, z1), DVec3::new(x0, y0, z0)),
        ];
        for (a, b) in walls {
            let len = (b - a).length() / repeat_m;
            let up = DVec3::new(0.0, y1 - y0, 0.0);
            self.quad(
                [a, b, b + up, a + up],
                DVec2::new(0.0, h),
                DVec2::new(len, 0.0),
                facade,
            );
        }
        self.quad(
            [
                DVec3::new(x0, y1, z0),
                DVec3::new(x1, y1, z0),
                DVec3::new(x1, y1, z1),
                DVec3::new(x0, y1, z1),
            ],
            DVec2::ZERO,
            DVec2::ONE,
            roof,
        );
    }

    /// Translates every vertex (for the huge-coordinates cases).
    pub fn translate(&mut self, by: DVec3) {
        for v in &mut self.scene.vertices {
            v.pos += by;
        }
    }

    pub fn build(self) -> Scene {
        self.scene
    }
}

/// A small city: `n × n` box buildings, each with its own facade texture of `facade` texels, on a ground
/// plane with a repeated tile. Deterministic.
pub fn small_city(n: u32, facade: u32) -> Scene {
    let mut b = SceneBuilder::new(UpAxis::Y);
    let tile = b.pattern_image("ground tile", 64, 9999);
    let ground = b.material(tile, [Wrap::Repeat; 2], AlphaMode::Opaque);
    let roof_img = b.pattern_image("roof", 32, 7777);
    let roof = b.material(roof_img, [Wrap::Repeat; 2], AlphaMode::Opaque);
    let span = 40.0 * n as f64;
    b.quad(
        [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(span, 0.0, 0.0),
            DVec3::new(span, 0.0, span),
            DVec3::new(0.0, 0.0, span),
        ],
        DVec2::ZERO,
        DVec2::splat(span / 10.0),
        ground,
    );
    for i in 0..n {
        for j in 0..n {
            let id = i * n + j;
            let img = b.pattern_image(&format!("facade {id}"), facade, id);
            let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
            let x = 40.0 * i as f64 + 8.0;
            let z = 40.0 * j as f64 + 8.0;
            let hgt = 10.0 + ((id * 7) % 5) as f64 * 6.0;
            b.building(
                DVec3::new(x, 0.0, z),
                DVec3::new(x + 20.0 + (id % 3) as f64 * 4.0, hgt, z + 22.0),
                m,
                roof,
                10.0,
            );
        }
    }
    b.build()
}
