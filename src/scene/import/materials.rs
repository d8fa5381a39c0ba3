//! Materials: glTF materials, samplers and textures → [`Material`]s with one base-colour image each,
//! and how their vertices get UVs ([`UvSource`]).
//!
//! Per (glTF material, solid) pair one [`Material`] is made, on first use by a primitive. A textured
//! material keeps its base-colour texture's sampler wraps ([`Wrap`]), `alphaMode`/`alphaCutoff`
//! ([`AlphaMode`]) and `baseColorFactor` (linear RGBA); its `KHR_texture_transform`, read in f64 from the
//! raw JSON, is returned as a [`UvTransform`] for the geometry to bake into the UVs. A material without a
//! texture, or whose `texCoord` set the primitive lacks, gets a deduplicated 1×1 image of its factor
//! encoded as sRGB8 ([`srgb8`]) and the UV (0.5, 0.5). A `KHR_materials_pbrSpecularGlossiness` material
//! without a metal-rough base colour texture uses its diffuse texture and factor instead (with a base
//! colour texture, or with a metal-rough block and no diffuse texture, the metal-rough values are its own
//! fallback and are used). A texture draws the image its `EXT_texture_webp`
//! names where it names one (PNG, JPEG and WebP all decode), else its core `source`. glTF images are
//! deduplicated by index; one that cannot be read, or a texture that names none, is replaced by the
//! fallback checker and counted.

use super::accessors::PrimCtx;
use super::uri::Buffers;
use crate::ids::{ImageId, MaterialId};
use crate::scene::image_source::ImageSource;
use crate::scene::{AlphaMode, ImportReport, Material, Wrap};
use glam::DVec2;
use gltf::Semantic;
use serde::Deserialize;
use std::collections::HashMap;

// Raw JSON read in f64 (gltf-json keeps KHR_texture_transform as f32).

#[derive(Deserialize, Default)]
#[serde(rename_all = "camelCase")]
pub(super) struct RawMaterial {
    pbr_metallic_roughness: Option<RawPbr>,
    extensions: Option<RawMaterialExt>,
}

#[derive(Deserialize, Default)]
struct RawMaterialExt {
    #[serde(rename = "KHR_materials_pbrSpecularGlossiness")]
    spec_gloss: Option<RawSpecGloss>,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "camelCase")]
struct RawSpecGloss {
    diffuse_texture: Option<RawTexInfo>,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "camelCase")]
struct RawPbr {
    base_color_texture: Option<RawTexInfo>,
}

#[derive(Deserialize, Default)]
struct RawTexInfo {
    extensions: Option<RawTexExt>,
}

#[derive(Deserialize, Default)]
struct RawTexExt {
    #[serde(rename = "KHR_texture_transform")]
    texture_transform: Option<RawTexTransform>,
}

/// A texture's raw JSON: the image its `EXT_texture_webp` names (the core `source` is gltf-json's).
#[derive(Deserialize, Default)]
pub(super) struct RawTexture {
    extensions: Option<RawTextureExt>,
}

#[derive(Deserialize, Default)]
struct RawTextureExt {
    #[serde(rename = "EXT_texture_webp")]
    webp: Option<RawImageSource>,
}

#[derive(Deserialize, Default)]
struct RawImageSource {
    source: Option<u32>,
}

#[derive(Deserialize, Default, Clone, Copy)]
struct RawTexTransform {
    offset: Option<[f64; 2]>,
    rotation: Option<f64>,
    scale: Option<[f64; 2]>,
    #[serde(rename = "texCoord")]
    tex_coord: Option<u32>,
}

/// `KHR_texture_transform` in f64: `uv' = T(offset) · R(rotation) · S(scale) · uv`.
#[derive(Copy, Clone, Debug, PartialEq)]
pub(super) struct UvTransform {
    pub offset: DVec2,
    /// Radians, counter-clockwise in UV space (the extension's convention).
    pub rotation: f64,
    pub scale: DVec2,
}

impl UvTransform {
    /// Applies the transform: `u' = cos·sx·u + sin·sy·v + ox`, `v' = −sin·sx·u + cos·sy·v + oy`
    /// (the matrix of the KHR_texture_transform specification).
    #[inline]
    pub(super) fn apply(&self, uv: DVec2) -> DVec2 {
        let (s, c) = self.rotation.sin_cos();
        let su = uv.x * self.scale.x;
        let sv = uv.y * self.scale.y;
        DVec2::new(
            c * su + s * sv + self.offset.x,
            -s * su + c * sv + self.offset.y,
        )
    }
}

impl From<RawTexTransform> for UvTransform {
    fn from(r: RawTexTransform) -> Self {
        UvTransform {
            offset: r.offset.map_or(DVec2::ZERO, DVec2::from),
            rotation: r.rotation.unwrap_or(0.0),
            scale: r.scale.map_or(DVec2::ONE, DVec2::from),
        }
    }
}

/// How a material's vertices get their UVs.
#[derive(Clone, Copy)]
pub(super) enum UvSource {
    /// From `TEXCOORD_set`, then the optional transform.
    Set(u32, Option<UvTransform>),
    /// 1×1 solid image: every vertex gets the texel centre (0.5, 0.5).
    Solid,
}

/// The materials and images made so far, and what deduplicates them.
pub(super) struct Materials<'a> {
    /// The glTF file (for warnings).
    file: &'a str,
    /// Its images (a texture's `EXT_texture_webp` source is found by index).
    doc: &'a gltf::Document,
    /// Per glTF material: its raw JSON (for `KHR_texture_transform` in f64).
    raw: Vec<RawMaterial>,
    /// Per glTF texture: its raw JSON (for `EXT_texture_webp`).
    raw_textures: Vec<RawTexture>,
    pub(super) materials: Vec<Material>,
    /// Per material: how its vertices get their UVs.
    uv: Vec<UvSource>,
    pub(super) images: Vec<ImageSource>,
    /// Per glTF image and whether OPAQUE materials draw it: its image. An image drawn by OPAQUE and by
    /// alpha materials is two images, one decoded with its alpha dropped (`image_cache::opaque_only_images`),
    /// one premultiplied and bled: the bleed would otherwise colour the OPAQUE material's alpha-0 texels.
    image_ids: HashMap<(usize, bool), ImageId>,
    solid_ids: HashMap<[u8; 4], ImageId>,
    /// Per glTF texture that names no image: its fallback checker.
    sourceless_ids: HashMap<usize, ImageId>,
    material_ids: HashMap<(Option<usize>, bool), MaterialId>,
}

impl<'a> Materials<'a> {
    pub(super) fn new(
        file: &'a str,
        doc: &'a gltf::Document,
        raw: Vec<RawMaterial>,
        raw_textures: Vec<RawTexture>,
    ) -> Self {
        Materials {
            file,
            doc,
            raw,
            raw_textures,
            materials: Vec::new(),
            uv: Vec::new(),
            images: Vec::new(),
            image_ids: HashMap::new(),
            solid_ids: HashMap::new(),
            sourceless_ids: HashMap::new(),
            material_ids: HashMap::new(),
        }
    }

    /// The material for primitive `prim` and its UV source. A textured material whose `texCoord` set is
    /// missing on this primitive becomes a solid-colour variant (counted warning). `Err` only where the
    /// open-files limit stopped an image from being read ([`image_or_fallback`]).
    pub(super) fn material_for(
        &mut self,
        prim: &gltf::Primitive,
        ctx: &PrimCtx,
        buffers: &mut Buffers,
        report: &mut ImportReport,
    ) -> Result<(MaterialId, UvSource), crate::scene::SceneError> {
        let gm = prim.material();
        let index = gm.index();
        let pbr = gm.pbr_metallic_roughness();
        let raw = index.and_then(|i| self.raw.get(i));
        // A material of the (archived, still common) specular-glossiness workflow without a metal-rough
        // base colour texture draws its diffuse texture and factor, not the default white: the colour
        // its author saw. Where it has both, the metal-rough one is its own fallback and is used.
        let diffuse = gm.pbr_specular_glossiness().filter(|sg| {
            pbr.base_color_texture().is_none()
                && (sg.diffuse_texture().is_some()
                    || raw.is_some_and(|m| m.pbr_metallic_roughness.is_none()))
        });
        let raw_info = match diffuse {
            Some(_) => raw
                .and_then(|m| m.extensions.as_ref())
                .and_then(|e| e.spec_gloss.as_ref())
                .and_then(|sg| sg.diffuse_texture.as_ref()),
            None => raw
                .and_then(|m| m.pbr_metallic_roughness.as_ref())
                .and_then(|p| p.base_color_texture.as_ref()),
        };
        let raw_tt = raw_info
            .and_then(|t| t.extensions.as_ref())
            .and_then(|e| e.texture_transform);
        let tex = match &diffuse {
            Some(sg) => sg.diffuse_texture(),
            None => pbr.base_color_texture(),
        };
        let set = tex
            .as_ref()
            .map(|info| raw_tt.and_then(|t| t.tex_coord).unwrap_or(info.tex_coord()));
        let has_uvs = set.is_some_and(|s| prim.get(&Semantic::TexCoords(s)).is_some());
        if let (Some(s), false) = (set, has_uvs) {
            report.missing_texcoords += 1;
            report.warn(format!(
                "{}: mesh {} ({}) primitive {}: material {} has a base colour texture on TEXCOORD_{s}, which the \
                 primitive lacks; using a solid image of its baseColorFactor",
                self.file,
                ctx.mesh,
                ctx.mesh_name,
                ctx.primitive,
                index.map_or("default".to_string(), |i| i.to_string())
            ));
        }
        let solid = !has_uvs;
        if let Some(&id) = self.material_ids.get(&(index, solid)) {
            let uv = self.uv.get(id.idx()).copied().unwrap_or(UvSource::Solid);
            return Ok((id, uv));
        }
        // Clamped into glTF's [0, 1] (warned about: `warn_undrawn_features`), so the atlas, which applies
        // it before filtering and stores 8 bits, and the originals, which apply it after, agree.
        let mut factor = diffuse
            .map_or(pbr.base_color_factor(), |sg| sg.diffuse_factor())
            .map(|c| if c.is_nan() { 1.0 } else { c.clamp(0.0, 1.0) });
        let alpha = match gm.alpha_mode() {
            gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
            // glTF 2.0 §3.9.4 draws a texel whose alpha is ≥ the cutoff opaque, in its own colour: with a
            // cutoff ≤ 0 every texel passes, which is OPAQUE (a MASK material's texels below alpha 1 are
            // premultiplied and those at 0 bled over, losing the colour this cutoff keeps).
            gltf::material::AlphaMode::Mask => match gm.alpha_cutoff().unwrap_or(0.5) {
                c if c <= 0.0 => AlphaMode::Opaque,
                cutoff => AlphaMode::Mask { cutoff },
            },
            gltf::material::AlphaMode::Blend => AlphaMode::Blend,
        };
        // glTF 2.0 §3.9.4: an OPAQUE material's alpha is ignored, its factor's included. Kept, a factor
        // alpha of 0 would premultiply the atlas texels (and a solid colour) to black.
        if alpha == AlphaMode::Opaque {
            factor[3] = 1.0;
        }
        let name = match (gm.name(), index) {
            (Some(n), _) => n.to_string(),
            (None, Some(i)) => format!("material {i}"),
            (None, None) => "default material".to_string(),
        };
        let (material, uv) = match (tex, set) {
            (Some(info), Some(s)) if !solid => {
                let texture = info.texture();
                let sampler = texture.sampler();
                let image = match self.texture_image(&texture) {
                    Some(img) => {
                        self.image_for(img, alpha == AlphaMode::Opaque, buffers, report)?
                    }
                    None => self.sourceless_texture_image(&texture, report),
                };
                let xf = raw_tt.map(UvTransform::from);
                let m = Material {
                    name,
                    image,
                    tex_coord: s,
                    wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())],
                    alpha,
                    base_color_factor: factor,
                    texture_transform: xf.is_some(),
                    gltf_material: index.and_then(|i| u32::try_from(i).ok()),
                };
                (m, UvSource::Set(s, xf))
            }
            _ => {
                let image = self.solid_image(srgb8(factor));
                let m = Material {
                    name,
                    image,
                    tex_coord: 0,
                    wrap: [Wrap::ClampToEdge; 2],
                    alpha,
                    base_color_factor: [1.0; 4],
                    texture_transform: false,
                    gltf_material: index.and_then(|i| u32::try_from(i).ok()),
                };
                (m, UvSource::Solid)
            }
        };
        let id = MaterialId(self.materials.len() as u32);
        self.materials.push(material);
        self.uv.push(uv);
        self.material_ids.insert((index, solid), id);
        Ok((id, uv))
    }

    /// The fallback checker of glTF texture `texture`, which names no image: made, counted and warned
    /// about once per texture, however many materials use it.
    /// Its other extensions (`KHR_texture_basisu`, `MSFT_texture_dds`, …) name image kinds atlastree
    /// does not decode: the warning names them.
    fn sourceless_texture_image(
        &mut self,
        texture: &gltf::Texture<'_>,
        report: &mut ImportReport,
    ) -> ImageId {
        let index = texture.index();
        if let Some(&id) = self.sourceless_ids.get(&index) {
            return id;
        }
        let unread: Vec<&str> = texture
            .extensions()
            .into_iter()
            .flat_map(|e| e.keys())
            .map(String::as_str)
            .filter(|&name| name != "EXT_texture_webp")
            .collect();
        let unread = match unread.as_slice() {
            [] => String::new(),
            names => format!(
                "; its {} source is not read (images: PNG, JPEG, WebP)",
                names.join(", ")
            ),
        };
        report.missing_images += 1;
        report.warn(format!(
            "{}: texture {index} names no image (no source, no EXT_texture_webp source{unread}); using \
             the magenta/black fallback checker",
            self.file
        ));
        let id = self.push_image(ImageSource::fallback(&format!("texture {index}")));
        self.sourceless_ids.insert(index, id);
        id
    }

    /// The deduplicated 1×1 image of an sRGB RGBA8 colour.
    fn solid_image(&mut self, rgba: [u8; 4]) -> ImageId {
        if let Some(&id) = self.solid_ids.get(&rgba) {
            return id;
        }
        let id = self.push_image(ImageSource::solid(rgba));
        self.solid_ids.insert(rgba, id);
        id
    }

    fn push_image(&mut self, img: ImageSource) -> ImageId {
        let id = ImageId(self.images.len() as u32);
        self.images.push(img);
        id
    }

    /// The image texture `t` draws: the one its `EXT_texture_webp` names where it names one (this
    /// importer decodes WebP, and that image is the one the author meant for clients that do; the core
    /// `source` is then a PNG/JPEG fallback or absent), else its core `source`; `None` with neither.
    /// Indices were checked by the reference pass (`refs`).
    fn texture_image(&self, t: &gltf::Texture<'a>) -> Option<gltf::Image<'a>> {
        let webp = (self.raw_textures.get(t.index()))
            .and_then(|r| r.extensions.as_ref())
            .and_then(|e| e.webp.as_ref())
            .and_then(|w| w.source);
        match webp.and_then(|i| self.doc.images().nth(i as usize)) {
            Some(img) => Some(img),
            None => t.source(),
        }
    }

    /// The image for glTF image `img` as OPAQUE materials (`opaque`) or alpha materials draw it (header
    /// read once for both); missing/undecodable → fallback + warning.
    fn image_for(
        &mut self,
        img: gltf::Image,
        opaque: bool,
        buffers: &mut Buffers,
        report: &mut ImportReport,
    ) -> Result<ImageId, crate::scene::SceneError> {
        if let Some(&id) = self.image_ids.get(&(img.index(), opaque)) {
            return Ok(id);
        }
        let known = (self.image_ids.get(&(img.index(), !opaque)))
            .and_then(|other| self.images.get(other.idx()))
            .cloned();
        let source = match known {
            Some(source) => source,
            None => image_or_fallback(self.file, &img, buffers, report)?,
        };
        let id = self.push_image(source);
        self.image_ids.insert((img.index(), opaque), id);
        Ok(id)
    }
}

/// glTF image `img` by its header, or the fallback checker (counted, with a warning naming the file and
/// the image) when it cannot be read; either way tagged with its glTF index.
pub(super) fn image_or_fallback(
    file: &str,
    img: &gltf::Image,
    buffers: &mut Buffers,
    report: &mut ImportReport,
) -> Result<ImageSource, crate::scene::SceneError> {
    let (name, loaded) = buffers.load_image(img)?;
    let mut source = match loaded {
        Ok(super::uri::LoadedImage { source, truncated }) => {
            if truncated {
                report.truncated_images += 1;
                report.warn(format!(
                    "{file}: image {} ({name}): the data ends without its end marker (a JPEG's \
                     end-of-image, a PNG's IEND) or holds fewer bytes than its JPEG frame header's size \
                     needs: a truncated or patched file?; a JPEG is drawn as far as it decodes, a PNG as \
                     the magenta fallback",
                    img.index()
                ));
            }
            source
        }
        Err(reason) => {
            report.missing_images += 1;
            // One line: decoders' messages may span several.
            let reason = reason.split_whitespace().collect::<Vec<_>>().join(" ");
            report.warn(format!(
                "{file}: image {} ({name}): {reason}; using the magenta/black fallback checker",
                img.index()
            ));
            ImageSource::fallback(&name)
        }
    };
    source.gltf_image = u32::try_from(img.index()).ok();
    // Its name (its `name`, else its URI) reaches terminals: control characters escaped (the warnings
    // above are escaped by `ImportReport::warn`).
    source.name = crate::util::printable(&source.name).into_owned();
    Ok(source)
}

fn wrap(w: gltf::texture::WrappingMode) -> Wrap {
    match w {
        gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
    }
}

/// Linear RGBA factor → sRGB-encoded RGBA8 (alpha stays linear), each clamped to [0, 1] and rounded.
pub(super) fn srgb8(linear: [f32; 4]) -> [u8; 4] {
    let enc = |c: f32| {
        let c = f64::from(c);
        let c = if c.is_nan() { 0.0 } else { c.clamp(0.0, 1.0) };
        let s = if c <= 0.003_130_8 {
            12.92 * c
        } else {
            1.055 * c.powf(1.0 / 2.4) - 0.055
        };
        (s * 255.0).round() as u8
    };
    let a = f64::from(linear[3]);
    let a = if a.is_nan() { 1.0 } else { a.clamp(0.0, 1.0) };
    [
        enc(linear[0]),
        enc(linear[1]),
        enc(linear[2]),
        (a * 255.0).round() as u8,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_encoding() {
        assert_eq!(srgb8([0.0, 1.0, 0.5, 0.5]), [0, 255, 188, 128]);
        assert_eq!(srgb8([f32::NAN, 2.0, -1.0, 1.0]), [0, 255, 0, 255]);
    }

    #[test]
    fn texture_transform_matrix() {
        // Rotation by 90°: (1, 0) → (0, -1) scaled by 2 in u, then offset (0.5, 0.25).
        let t = UvTransform {
            offset: DVec2::new(0.5, 0.25),
            rotation: std::f64::consts::FRAC_PI_2,
            scale: DVec2::new(2.0, 3.0),
        };
        let r = t.apply(DVec2::new(1.0, 0.0));
        assert!((r - DVec2::new(0.5, -1.75)).length() < 1e-12, "{r}");
        let r = t.apply(DVec2::new(0.0, 1.0));
        assert!((r - DVec2::new(3.5, 0.25)).length() < 1e-12, "{r}");
    }
}
