//! A minimal glTF 2.0 writer: one external `.bin` buffer with five buffer views (positions, normals, UVs,
//! u16 indices, u32 indices), accessors that address into them with byte offsets, and the JSON document.
//!
//! It also keeps the statistics `citygen.json` reports: triangles after instancing and the texel count a
//! naive per-triangle atlas would need when repetitions are unrolled (paper §7, "considering repetitions on
//! single triangles, the summed texture size of the scene expanded to multiple billion texels").

use serde_json::{Value, json};

/// glTF sampler wrap modes (the numeric constants of the spec).
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum WrapMode {
    Repeat = 10497,
    MirroredRepeat = 33648,
    ClampToEdge = 33071,
}

/// glTF `alphaMode` with the cutoff for MASK.
#[derive(Copy, Clone, Debug, PartialEq)]
pub enum Alpha {
    Opaque,
    Mask(f32),
    Blend,
}

/// One vertex as written: position in metres (mesh-local), unit normal, UV (glTF: v = 0 is the image top).
#[derive(Copy, Clone, Debug)]
pub struct Vtx {
    pub p: [f32; 3],
    pub n: [f32; 3],
    pub uv: [f32; 2],
}

/// Triangle-list geometry of one primitive.
#[derive(Clone, Debug, Default)]
pub struct MeshData {
    pub v: Vec<Vtx>,
    pub idx: Vec<u32>,
}

impl MeshData {
    /// Appends a quad `a b c d` (counter-clockwise seen from the front) as two triangles.
    pub fn quad(&mut self, q: [Vtx; 4]) {
        let b = self.v.len() as u32;
        self.v.extend_from_slice(&q);
        self.idx
            .extend_from_slice(&[b, b + 1, b + 2, b, b + 2, b + 3]);
    }

    /// Appends one triangle (counter-clockwise seen from the front).
    pub fn tri(&mut self, t: [Vtx; 3]) {
        let b = self.v.len() as u32;
        self.v.extend_from_slice(&t);
        self.idx.extend_from_slice(&[b, b + 1, b + 2]);
    }

    pub fn triangles(&self) -> u64 {
        self.idx.len() as u64 / 3
    }

    /// Summed absolute triangle area in UV space (1.0 = one full copy of the texture).
    pub fn uv_area(&self) -> f64 {
        self.idx
            .chunks_exact(3)
            .map(|t| {
                let [a, b, c] = [t[0], t[1], t[2]].map(|i| self.v[i as usize].uv.map(f64::from));
                ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])).abs() * 0.5
            })
            .sum()
    }
}

/// A material to write: either textured (image index, sampler) or a plain `baseColorFactor`.
#[derive(Clone, Debug)]
pub struct MaterialDef {
    pub name: String,
    /// `(image index, [wrap_s, wrap_t])`; `None` for untextured materials.
    pub texture: Option<(usize, [WrapMode; 2])>,
    pub factor: [f32; 4],
    pub alpha: Alpha,
    pub double_sided: bool,
}

/// A node to write. `children` are node indices.
#[derive(Clone, Debug, Default)]
pub struct NodeDef {
    pub name: String,
    pub mesh: Option<usize>,
    pub translation: Option<[f32; 3]>,
    /// Unit quaternion `[x, y, z, w]`.
    pub rotation: Option<[f32; 4]>,
    pub scale: Option<[f32; 3]>,
    pub children: Vec<usize>,
}

#[derive(Copy, Clone, Debug)]
enum View {
    Pos = 0,
    Nrm = 1,
    Uv = 2,
    Idx16 = 3,
    Idx32 = 4,
}

struct Accessor {
    view: View,
    offset: usize,
    count: usize,
    kind: &'static str,
    component: u32,
    minmax: Option<([f32; 3], [f32; 3])>,
}

/// Per-mesh numbers for the statistics: triangles and `Σ uv_area × texels` over its primitives.
#[derive(Copy, Clone, Debug, Default)]
struct MeshStats {
    triangles: u64,
    repeated_texels: f64,
}

/// Accumulates a glTF document and its binary buffer.
#[derive(Default)]
pub struct GltfBuilder {
    /// `(uri, mime type, texels)` per image.
    images: Vec<(String, &'static str, u64)>,
    samplers: Vec<[WrapMode; 2]>,
    /// `(image, sampler)` per texture.
    textures: Vec<(usize, usize)>,
    materials: Vec<Value>,
    material_texels: Vec<Option<u64>>,
    meshes: Vec<Value>,
    mesh_stats: Vec<MeshStats>,
    nodes: Vec<NodeDef>,
    roots: Vec<usize>,
    accessors: Vec<Accessor>,
    views: [Vec<u8>; 5],
}

/// Totals over the scene after instancing (every node that references a mesh counts it again).
#[derive(Copy, Clone, Debug, Default, serde::Serialize)]
pub struct SceneStats {
    pub nodes: u64,
    pub mesh_nodes: u64,
    pub meshes: u64,
    pub primitives: u64,
    pub materials: u64,
    pub textures: u64,
    pub samplers: u64,
    /// Triangles in the scene after instancing.
    pub triangles: u64,
    /// Triangles stored in meshes (before instancing).
    pub mesh_triangles: u64,
    /// `Σ over instanced triangles of uv_area × texture texels` (textured materials only); reported
    /// rounded as `texels_with_repetition` in citygen.json.
    #[serde(skip)]
    pub texels_with_repetition: f64,
}

fn push_f32s(buf: &mut Vec<u8>, vals: impl IntoIterator<Item = f32>) -> usize {
    let off = buf.len();
    for v in vals {
        buf.extend_from_slice(&v.to_le_bytes());
    }
    off
}

impl GltfBuilder {
    /// Registers an image file (relative URI) with its texel count; returns the image index.
    pub fn add_image(&mut self, uri: &str, mime: &'static str, texels: u64) -> usize {
        self.images.push((uri.to_string(), mime, texels));
        self.images.len() - 1
    }

    fn sampler(&mut self, wrap: [WrapMode; 2]) -> usize {
        if let Some(i) = self.samplers.iter().position(|s| *s == wrap) {
            return i;
        }
        self.samplers.push(wrap);
        self.samplers.len() - 1
    }

    fn texture(&mut self, image: usize, wrap: [WrapMode; 2]) -> usize {
        let s = self.sampler(wrap);
        if let Some(i) = self.textures.iter().position(|t| *t == (image, s)) {
            return i;
        }
        self.textures.push((image, s));
        self.textures.len() - 1
    }

    /// Adds a material; returns its index.
    pub fn add_material(&mut self, m: &MaterialDef) -> usize {
        let mut pbr = json!({
            "baseColorFactor": m.factor,
            "metallicFactor": 0.0,
            "roughnessFactor": 0.9,
        });
        let mut texels = None;
        if let Some((image, wrap)) = m.texture {
            let t = self.texture(image, wrap);
            pbr["baseColorTexture"] = json!({ "index": t });
            texels = self.images.get(image).map(|i| i.2);
        }
        let mut mat = json!({ "name": m.name, "pbrMetallicRoughness": pbr });
        match m.alpha {
            Alpha::Opaque => {}
            Alpha::Mask(c) => {
                mat["alphaMode"] = json!("MASK");
                mat["alphaCutoff"] = json!(c);
            }
            Alpha::Blend => mat["alphaMode"] = json!("BLEND"),
        }
        if m.double_sided {
            mat["doubleSided"] = json!(true);
        }
        self.materials.push(mat);
        self.material_texels.push(texels);
        self.materials.len() - 1
    }

    fn accessor(&mut self, a: Accessor) -> usize {
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    /// Adds a mesh of `(geometry, material)` primitives; empty primitives are dropped. Returns its index.
    pub fn add_mesh(&mut self, name: &str, prims: &[(MeshData, usize)]) -> usize {
        let mut out = Vec::new();
        let mut stats = MeshStats::default();
        for (g, mat) in prims.iter().filter(|(g, _)| !g.idx.is_empty()) {
            let count = g.v.len();
            let mut lo = [f32::INFINITY; 3];
            let mut hi = [f32::NEG_INFINITY; 3];
            for v in &g.v {
                for k in 0..3 {
                    lo[k] = lo[k].min(v.p[k]);
                    hi[k] = hi[k].max(v.p[k]);
                }
            }
            let off = push_f32s(
                &mut self.views[View::Pos as usize],
                g.v.iter().flat_map(|v| v.p),
            );
            let pos = self.accessor(Accessor {
                view: View::Pos,
                offset: off,
                count,
                kind: "VEC3",
                component: 5126,
                minmax: Some((lo, hi)),
            });
            let off = push_f32s(
                &mut self.views[View::Nrm as usize],
                g.v.iter().flat_map(|v| v.n),
            );
            let nrm = self.accessor(Accessor {
                view: View::Nrm,
                offset: off,
                count,
                kind: "VEC3",
                component: 5126,
                minmax: None,
            });
            let off = push_f32s(
                &mut self.views[View::Uv as usize],
                g.v.iter().flat_map(|v| v.uv),
            );
            let uv = self.accessor(Accessor {
                view: View::Uv,
                offset: off,
                count,
                kind: "VEC2",
                component: 5126,
                minmax: None,
            });
            // Small primitives use u16 indices, large ones u32, so importers see both component types.
            let idx = if count <= usize::from(u16::MAX) {
                let buf = &mut self.views[View::Idx16 as usize];
                let off = buf.len();
                for i in &g.idx {
                    buf.extend_from_slice(&(*i as u16).to_le_bytes());
                }
                self.accessor(Accessor {
                    view: View::Idx16,
                    offset: off,
                    count: g.idx.len(),
                    kind: "SCALAR",
                    component: 5123,
                    minmax: None,
                })
            } else {
                let buf = &mut self.views[View::Idx32 as usize];
                let off = buf.len();
                for i in &g.idx {
                    buf.extend_from_slice(&i.to_le_bytes());
                }
                self.accessor(Accessor {
                    view: View::Idx32,
                    offset: off,
                    count: g.idx.len(),
                    kind: "SCALAR",
                    component: 5125,
                    minmax: None,
                })
            };
            out.push(json!({
                "attributes": { "POSITION": pos, "NORMAL": nrm, "TEXCOORD_0": uv },
                "indices": idx,
                "material": mat,
            }));
            stats.triangles += g.triangles();
            if let Some(Some(t)) = self.material_texels.get(*mat) {
                stats.repeated_texels += g.uv_area() * *t as f64;
            }
        }
        self.meshes.push(json!({ "name": name, "primitives": out }));
        self.mesh_stats.push(stats);
        self.meshes.len() - 1
    }

    /// Adds a node; `root` makes it a child of the scene. Returns its index.
    pub fn add_node(&mut self, node: NodeDef, root: bool) -> usize {
        self.nodes.push(node);
        let i = self.nodes.len() - 1;
        if root {
            self.roots.push(i);
        }
        i
    }

    /// Appends `child` to the children of `parent`.
    pub fn add_child(&mut self, parent: usize, child: usize) {
        if let Some(p) = self.nodes.get_mut(parent) {
            p.children.push(child);
        }
    }

    /// Scene totals; instancing is counted per mesh-referencing node.
    pub fn stats(&self) -> SceneStats {
        let mut s = SceneStats {
            nodes: self.nodes.len() as u64,
            meshes: self.meshes.len() as u64,
            primitives: self
                .meshes
                .iter()
                .map(|m| m["primitives"].as_array().map_or(0, |p| p.len() as u64))
                .sum(),
            materials: self.materials.len() as u64,
            textures: self.textures.len() as u64,
            samplers: self.samplers.len() as u64,
            mesh_triangles: self.mesh_stats.iter().map(|m| m.triangles).sum(),
            ..Default::default()
        };
        for n in &self.nodes {
            if let Some(st) = n.mesh.and_then(|m| self.mesh_stats.get(m)) {
                s.mesh_nodes += 1;
                s.triangles += st.triangles;
                s.texels_with_repetition += st.repeated_texels;
            }
        }
        s
    }

    /// The JSON document (pretty-printed, deterministic) and the binary buffer for `bin_uri`.
    pub fn finish(
        self,
        bin_uri: &str,
        generator: &str,
    ) -> Result<(Vec<u8>, Vec<u8>), serde_json::Error> {
        let mut bin = Vec::new();
        let mut view_index = [usize::MAX; 5];
        let mut views = Vec::new();
        for (k, data) in self.views.iter().enumerate() {
            if data.is_empty() {
                continue;
            }
            while bin.len() % 4 != 0 {
                bin.push(0);
            }
            let target = if k >= View::Idx16 as usize {
                34963
            } else {
                34962
            };
            view_index[k] = views.len();
            views.push(json!({ "buffer": 0, "byteOffset": bin.len(), "byteLength": data.len(), "target": target }));
            bin.extend_from_slice(data);
        }
        while bin.len() % 4 != 0 {
            bin.push(0);
        }
        let accessors: Vec<Value> = self
            .accessors
            .iter()
            .map(|a| {
                let mut v = json!({
                    "bufferView": view_index[a.view as usize],
                    "byteOffset": a.offset,
                    "componentType": a.component,
                    "count": a.count,
                    "type": a.kind,
                });
                if let Some((lo, hi)) = a.minmax {
                    v["min"] = json!(lo);
                    v["max"] = json!(hi);
                }
                v
            })
            .collect();
        let nodes: Vec<Value> = self
            .nodes
            .iter()
            .map(|n| {
                let mut v = json!({ "name": n.name });
                if let Some(m) = n.mesh {
                    v["mesh"] = json!(m);
                }
                if let Some(t) = n.translation {
                    v["translation"] = json!(t);
                }
                if let Some(r) = n.rotation {
                    v["rotation"] = json!(r);
                }
                if let Some(s) = n.scale {
                    v["scale"] = json!(s);
                }
                if !n.children.is_empty() {
                    v["children"] = json!(n.children);
                }
                v
            })
            .collect();
        let doc = json!({
            "asset": { "version": "2.0", "generator": generator },
            "scene": 0,
            "scenes": [{ "name": "city", "nodes": self.roots }],
            "nodes": nodes,
            "meshes": self.meshes,
            "materials": self.materials,
            "textures": self.textures.iter().map(|(i, s)| json!({ "source": i, "sampler": s })).collect::<Vec<_>>(),
            "samplers": self.samplers.iter().map(|w| json!({
                "magFilter": 9729, "minFilter": 9987, "wrapS": w[0] as u32, "wrapT": w[1] as u32,
            })).collect::<Vec<_>>(),
            "images": self.images.iter().map(|(u, m, _)| json!({ "uri": u, "mimeType": m })).collect::<Vec<_>>(),
            "accessors": accessors,
            "bufferViews": views,
            "buffers": [{ "uri": bin_uri, "byteLength": bin.len() }],
        });
        let mut text = serde_json::to_vec_pretty(&doc)?;
        text.push(b'\n');
        Ok((text, bin))
    }
}
