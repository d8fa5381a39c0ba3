//! One tile's content as a glTF 2.0 JSON document (`.gltf`) whose buffers are the leaves' shared `.bin`
//! files ([`super::geometry`]) and whose images are files beside it. Built incrementally: buffers, views
//! and accessors are created the first time a primitive needs them, so the document holds nothing unused
//! (gltf-validator reports unused objects).

use super::geometry::{IndexGroup, LeafMesh};
use serde_json::{Value, json};
use std::collections::HashMap;

/// glTF sampler wrap codes.
pub(super) const REPEAT: u32 = 10497;
pub(super) const CLAMP_TO_EDGE: u32 = 33071;
pub(super) const MIRRORED_REPEAT: u32 = 33648;
const NEAREST: u32 = 9728;
const LINEAR: u32 = 9729;
const LINEAR_MIPMAP_LINEAR: u32 = 9987;
const FLOAT: u32 = 5126;
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// The glTF wrap code of a scene wrap mode.
pub(super) fn wrap_code(w: crate::scene::Wrap) -> u32 {
    match w {
        crate::scene::Wrap::Repeat => REPEAT,
        crate::scene::Wrap::MirroredRepeat => MIRRORED_REPEAT,
        crate::scene::Wrap::ClampToEdge => CLAMP_TO_EDGE,
    }
}

/// Where a leaf's node puts the leaf's positions in its tile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct LeafPlacement {
    /// The leaf origin relative to the tile's (tree's) origin, in glTF's frame.
    pub translation: [f32; 3],
    /// The turn from the scene's frame to glTF's (`tileset::gltf_rotation`), `None` for y-up.
    pub rotation: Option<[f32; 4]>,
}

/// A material: one texture, the UV set it reads, an optional `KHR_texture_transform` (offset, scale),
/// the base colour factor (linear) and the alpha mode (0 opaque, 1 mask with cutoff, 2 blend).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct MaterialSpec {
    pub(super) texture: usize,
    pub(super) tex_coord: u32,
    pub(super) transform: Option<([f64; 2], [f64; 2])>,
    pub(super) factor: [f32; 4],
    pub(super) alpha: u8,
    pub(super) cutoff: f32,
}

/// Which vertex sections of a leaf a view covers.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
enum Section {
    Positions,
    Uv0,
    Uv1,
    Indices,
}

/// The document under construction.
#[derive(Default)]
pub(super) struct GltfDoc {
    buffers: Vec<Value>,
    views: Vec<Value>,
    accessors: Vec<Value>,
    images: Vec<Value>,
    samplers: Vec<Value>,
    textures: Vec<Value>,
    materials: Vec<Value>,
    meshes: Vec<Value>,
    nodes: Vec<Value>,
    buffer_of: HashMap<usize, usize>,
    view_of: HashMap<(usize, Section), usize>,
    accessor_of: HashMap<(usize, Section, u64, u32), usize>,
    texture_of: HashMap<(String, [u32; 2], bool), usize>,
    sampler_of: HashMap<([u32; 2], bool), usize>,
    material_of: Vec<MaterialSpec>,
    transform_used: bool,
    /// Primitives (draw calls) so far.
    pub(super) primitives: usize,
}

impl GltfDoc {
    fn buffer(&mut self, leaf: usize, mesh: &LeafMesh, uri: &str) -> usize {
        *self.buffer_of.entry(leaf).or_insert_with(|| {
            self.buffers
                .push(json!({ "uri": uri, "byteLength": mesh.bin_len }));
            self.buffers.len() - 1
        })
    }

    fn view(&mut self, leaf: usize, mesh: &LeafMesh, uri: &str, s: Section) -> usize {
        if let Some(&v) = self.view_of.get(&(leaf, s)) {
            return v;
        }
        let buffer = self.buffer(leaf, mesh, uri);
        let n = u64::from(mesh.vertices);
        let (offset, len, target) = match s {
            Section::Positions => (mesh.positions_offset(), 12 * n, ARRAY_BUFFER),
            Section::Uv0 => (mesh.uv0_offset(), 8 * n, ARRAY_BUFFER),
            Section::Uv1 => (mesh.uv1_offset(), 8 * n, ARRAY_BUFFER),
            Section::Indices => (
                mesh.index_offset(),
                mesh.index_bytes(),
                ELEMENT_ARRAY_BUFFER,
            ),
        };
        self.views.push(json!({
            "buffer": buffer, "byteOffset": offset, "byteLength": len, "target": target,
        }));
        self.view_of.insert((leaf, s), self.views.len() - 1);
        self.views.len() - 1
    }

    /// The accessor of a vertex section (`Positions`, `Uv0`, `Uv1`) of `leaf`.
    fn vertex_accessor(&mut self, leaf: usize, mesh: &LeafMesh, uri: &str, s: Section) -> usize {
        if let Some(&a) = self.accessor_of.get(&(leaf, s, 0, 0)) {
            return a;
        }
        let view = self.view(leaf, mesh, uri, s);
        let acc = if s == Section::Positions {
            json!({
                "bufferView": view, "componentType": FLOAT, "count": mesh.vertices, "type": "VEC3",
                "min": mesh.pos_min, "max": mesh.pos_max,
            })
        } else {
            json!({ "bufferView": view, "componentType": FLOAT, "count": mesh.vertices, "type": "VEC2" })
        };
        self.accessors.push(acc);
        self.accessor_of
            .insert((leaf, s, 0, 0), self.accessors.len() - 1);
        self.accessors.len() - 1
    }

    fn index_accessor(&mut self, leaf: usize, mesh: &LeafMesh, uri: &str, g: &IndexGroup) -> usize {
        if let Some(&a) = self
            .accessor_of
            .get(&(leaf, Section::Indices, g.offset, g.count))
        {
            return a;
        }
        let view = self.view(leaf, mesh, uri, Section::Indices);
        let ty = if mesh.index_size == 2 {
            UNSIGNED_SHORT
        } else {
            UNSIGNED_INT
        };
        self.accessors.push(json!({
            "bufferView": view, "byteOffset": g.offset, "componentType": ty, "count": g.count,
            "type": "SCALAR",
        }));
        self.accessor_of.insert(
            (leaf, Section::Indices, g.offset, g.count),
            self.accessors.len() - 1,
        );
        self.accessors.len() - 1
    }

    /// A texture of the image named `name` (its file path, also for an image embedded as a data URI) at
    /// `uri`, with wrap modes `[s, t]` (glTF codes), trilinear (or `nearest`, no mips: an image of single
    /// texels read at their centres); shared by equal triples.
    pub(super) fn texture(
        &mut self,
        (uri, name): (&str, &str),
        wrap: [u32; 2],
        nearest: bool,
    ) -> usize {
        if let Some(&t) = self.texture_of.get(&(name.to_string(), wrap, nearest)) {
            return t;
        }
        let image = match self.images.iter().position(|i| i["name"] == name) {
            Some(i) => i,
            None => {
                self.images.push(json!({ "uri": uri, "name": name }));
                self.images.len() - 1
            }
        };
        let sampler = *self.sampler_of.entry((wrap, nearest)).or_insert_with(|| {
            let (mag, min) = if nearest {
                (NEAREST, NEAREST)
            } else {
                (LINEAR, LINEAR_MIPMAP_LINEAR)
            };
            self.samplers.push(json!({
                "magFilter": mag, "minFilter": min, "wrapS": wrap[0], "wrapT": wrap[1],
            }));
            self.samplers.len() - 1
        });
        self.textures
            .push(json!({ "source": image, "sampler": sampler }));
        self.texture_of
            .insert((name.to_string(), wrap, nearest), self.textures.len() - 1);
        self.textures.len() - 1
    }

    /// Sets the URI of the image named `name` (made before its texels were final).
    pub(super) fn set_image_uri(&mut self, name: &str, uri: &str) {
        for i in &mut self.images {
            if i["name"] == name {
                i["uri"] = json!(uri);
            }
        }
    }

    /// An unlit material (`KHR_materials_unlit`, double-sided as atlastree draws); equal specs shared.
    pub(super) fn material(&mut self, spec: MaterialSpec) -> usize {
        if let Some(i) = self.material_of.iter().position(|m| *m == spec) {
            return i;
        }
        let mut tex = json!({ "index": spec.texture, "texCoord": spec.tex_coord });
        if let Some((offset, scale)) = spec.transform {
            self.transform_used = true;
            tex["extensions"] = json!({ "KHR_texture_transform": {
                "offset": offset, "scale": scale, "texCoord": spec.tex_coord,
            }});
        }
        let mut m = json!({
            "pbrMetallicRoughness": {
                "baseColorTexture": tex, "baseColorFactor": spec.factor,
                "metallicFactor": 0.0, "roughnessFactor": 1.0,
            },
            "doubleSided": true,
            "extensions": { "KHR_materials_unlit": {} },
        });
        match spec.alpha {
            1 => {
                m["alphaMode"] = json!("MASK");
                m["alphaCutoff"] = json!(spec.cutoff);
            }
            2 => m["alphaMode"] = json!("BLEND"),
            _ => {}
        }
        self.materials.push(m);
        self.material_of.push(spec);
        self.materials.len() - 1
    }

    /// One leaf as a glTF node placed by `placement` (relative to the tile's origin, in glTF's y-up frame,
    /// turned from the scene's where its up axis is another), its mesh one
    /// primitive per `(group, material)`; `uv1` selects `TEXCOORD_1` (leaf-atlas UV) over the original UV.
    pub(super) fn leaf_node(
        &mut self,
        leaf: usize,
        mesh: &LeafMesh,
        uri: &str,
        placement: LeafPlacement,
        prims: &[(IndexGroup, usize, bool)],
    ) {
        if prims.is_empty() {
            return;
        }
        let pos = self.vertex_accessor(leaf, mesh, uri, Section::Positions);
        let mut out = Vec::with_capacity(prims.len());
        for (g, material, uv1) in prims {
            let (material, uv1) = (*material, *uv1);
            let uv_section = if uv1 { Section::Uv1 } else { Section::Uv0 };
            let uv = self.vertex_accessor(leaf, mesh, uri, uv_section);
            let indices = self.index_accessor(leaf, mesh, uri, g);
            let texcoord = if uv1 { "TEXCOORD_1" } else { "TEXCOORD_0" };
            let mut attributes = serde_json::Map::new();
            attributes.insert("POSITION".into(), json!(pos));
            attributes.insert(texcoord.into(), json!(uv));
            if uv1 {
                // glTF requires TEXCOORD_n to be preceded by TEXCOORD_0..n-1.
                let uv0 = self.vertex_accessor(leaf, mesh, uri, Section::Uv0);
                attributes.insert("TEXCOORD_0".into(), json!(uv0));
            }
            out.push(json!({ "attributes": attributes, "indices": indices, "material": material, "mode": 4 }));
        }
        self.primitives += out.len();
        self.meshes.push(json!({ "primitives": out }));
        let mut node =
            json!({ "mesh": self.meshes.len() - 1, "translation": placement.translation });
        if let Some(rotation) = placement.rotation {
            node["rotation"] = json!(rotation);
        }
        self.nodes.push(node);
    }

    /// The document as JSON text.
    pub(super) fn finish(self) -> String {
        let mut ext = vec!["KHR_materials_unlit"];
        let mut required: Vec<&str> = Vec::new();
        if self.transform_used {
            ext.push("KHR_texture_transform");
            required.push("KHR_texture_transform");
        }
        let node_ids: Vec<usize> = (0..self.nodes.len()).collect();
        let mut doc = json!({
            "asset": { "version": "2.0", "generator": concat!("atlastree ", env!("CARGO_PKG_VERSION")) },
            "extensionsUsed": ext,
            "scene": 0,
            "scenes": [ { "nodes": node_ids } ],
            "nodes": self.nodes,
            "meshes": self.meshes,
            "materials": self.materials,
            "textures": self.textures,
            "samplers": self.samplers,
            "images": self.images,
            "accessors": self.accessors,
            "bufferViews": self.views,
            "buffers": self.buffers,
        });
        if !required.is_empty() {
            doc["extensionsRequired"] = json!(required);
        }
        // Empty arrays are not allowed by the schema (minItems 1).
        if let Some(obj) = doc.as_object_mut() {
            obj.retain(|_, v| !matches!(v, Value::Array(a) if a.is_empty()));
        }
        serde_json::to_string(&doc).unwrap_or_default()
    }
}
