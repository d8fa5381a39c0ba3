//! glTF 2.0 import into a flat world-space triangle soup.
//!
//! Buffers are loaded by this module (external files, data URIs, the GLB `BIN` chunk); images only have
//! their header read ([`super::image_source::read_header`]) and are decoded lazily. Node transforms are
//! taken from the raw JSON in f64 (gltf-json stores them as f32), multiplied in f64 ([`DMat4`]) and
//! applied to every instance, so every instance becomes distinct vertices and triangles.
//!
//! Policy on bad input: structural errors (unreadable/invalid JSON, schema failures, missing buffers,
//! accessors past their buffer, out-of-range indices, recursive node graphs, unsupported required
//! extensions) are a [`SceneError`]; data problems that affect single triangles (non-finite positions or
//! UVs) skip those triangles; unsupported primitive modes skip the primitive; missing images are
//! replaced by a fallback checker. Every skip is counted in [`ImportReport`].

use super::image_source::{self, ImageData, ImageSource};
use super::{AlphaMode, ImportReport, Material, Scene, Triangle, UpAxis, Vertex, Wrap};
use crate::ids::{ImageId, MaterialId};
use glam::{DMat4, DQuat, DVec2, DVec3};
use gltf::Semantic;
use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Mode;
use serde::Deserialize;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Required extensions this importer honours (others listed in `extensionsRequired` are an error).
pub const SUPPORTED_REQUIRED_EXTENSIONS: &[&str] = &[
    "KHR_texture_transform",
    "KHR_mesh_quantization",
    "EXT_mesh_gpu_instancing",
    "KHR_materials_unlit",
];
/// At most this many warning strings are kept; the rest are counted in `warnings_total`.
pub const MAX_WARNINGS: usize = 100;
/// UV components beyond ±this are kept but counted (`large_uv_triangles`).
pub const LARGE_UV: f64 = 1e6;
/// Cap on node visits during the hierarchy walk (guards against exponential DAG expansion).
pub const MAX_NODE_VISITS: u64 = 1 << 26;
/// Cap on accessors without a buffer view (sparse-only, zero-initialised), in elements.
const MAX_SPARSE_ONLY_COUNT: usize = 1 << 26;

/// Import failures. Every variant names the file and, where it applies, mesh, primitive and accessor.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{file}: cannot read: {source}")]
    Io {
        file: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: not a valid glTF/GLB file: {reason}")]
    Parse { file: String, reason: String },
    #[error("{file}: glTF validation failed: {reason}")]
    Invalid { file: String, reason: String },
    #[error("{file}: required extension {extension} is not supported")]
    UnsupportedExtension { file: String, extension: String },
    #[error("{file}: buffer {buffer} ({uri}): {reason}")]
    Buffer {
        file: String,
        buffer: usize,
        uri: String,
        reason: String,
    },
    #[error(
        "{file}: mesh {mesh} ({mesh_name}) primitive {primitive}: accessor {accessor}: {reason}"
    )]
    /// A bad accessor; `reason` starts with the attribute it was read as ("POSITION", "TEXCOORD_1",
    /// "indices").
    Accessor {
        file: String,
        mesh: usize,
        mesh_name: String,
        primitive: usize,
        accessor: usize,
        reason: String,
    },
    #[error(
        "{file}: mesh {mesh} ({mesh_name}) primitive {primitive}: index accessor {accessor} element {position} \
         is vertex {index}, but the primitive has {vertex_count} vertices"
    )]
    IndexOutOfRange {
        file: String,
        mesh: usize,
        mesh_name: String,
        primitive: usize,
        accessor: usize,
        position: usize,
        index: u32,
        vertex_count: usize,
    },
    #[error("{file}: node {node} ({node_name}) is its own ancestor (recursive node graph)")]
    RecursiveNodes {
        file: String,
        node: usize,
        node_name: String,
    },
    #[error("{file}: node {node} ({node_name}): EXT_mesh_gpu_instancing: {reason}")]
    Instancing {
        file: String,
        node: usize,
        node_name: String,
        reason: String,
    },
    #[error("{file}: scene too large: {what}")]
    TooLarge { file: String, what: String },
    #[error("image {image}: {reason}")]
    ImageDecode { image: String, reason: String },
    #[error("{0}")]
    Other(String),
}

/// Import options.
#[derive(Clone, Debug, Default)]
pub struct ImportOptions {
    /// `None` = auto (the axis of least extent of the world bounds; ties prefer Y, then Z).
    pub up: Option<UpAxis>,
}

/// Imports a `.gltf` (external files and/or data URIs) or `.glb` file into a world-space [`Scene`].
///
/// The default scene is walked (all root nodes if there is none); every mesh instance (node, and
/// `EXT_mesh_gpu_instancing` instance) becomes distinct vertices and triangles. See the module docs for
/// the error/warning policy.
pub fn import(path: &Path, opts: &ImportOptions) -> Result<Scene, SceneError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io {
        file: file.clone(),
        source,
    })?;
    let (json_bytes, blob) = split_glb(bytes, &file)?;
    let (doc, tolerated) = parse_document(&json_bytes, &file)?;
    let raw: RawRoot = serde_json::from_slice(&json_bytes).map_err(|e| SceneError::Parse {
        file: file.clone(),
        reason: format!("raw JSON: {e}"),
    })?;
    let base_dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let mut imp = Importer::new(file, base_dir, &doc, raw, blob);
    for w in tolerated {
        imp.warn(w);
    }
    let instances = imp.collect_instances()?;
    imp.reserve(&instances)?;
    for inst in &instances {
        imp.emit_instance(inst)?;
    }
    Ok(imp.finish(path, opts))
}

/// Splits a GLB into (JSON chunk, BIN chunk); a `.gltf` is all JSON.
fn split_glb(bytes: Vec<u8>, file: &str) -> Result<(Vec<u8>, Option<Vec<u8>>), SceneError> {
    if !bytes.starts_with(b"glTF") {
        return Ok((bytes, None));
    }
    let glb = gltf::Glb::from_slice(&bytes).map_err(|e| SceneError::Parse {
        file: file.to_string(),
        reason: format!("GLB: {e}"),
    })?;
    Ok((glb.json.into_owned(), glb.bin.map(|b| b.into_owned())))
}

/// Parses and validates the glTF JSON. `extensionsRequired` is checked against
/// [`SUPPORTED_REQUIRED_EXTENSIONS`] here (gltf-json does not know some of ours). Every schema failure
/// is an error except a missing POSITION `min`/`max` (required by the specification but omitted by many
/// exporters, and unused here): those are returned as warnings.
fn parse_document(json: &[u8], file: &str) -> Result<(gltf::Document, Vec<String>), SceneError> {
    use gltf::json::validation::{Error as VError, Validate};
    let mut root: gltf::json::Root =
        gltf::json::deserialize::from_slice(json).map_err(|e| SceneError::Parse {
            file: file.to_string(),
            reason: e.to_string(),
        })?;
    if let Some(ext) = root
        .extensions_required
        .iter()
        .find(|e| !SUPPORTED_REQUIRED_EXTENSIONS.contains(&e.as_str()))
    {
        return Err(SceneError::UnsupportedExtension {
            file: file.to_string(),
            extension: ext.clone(),
        });
    }
    root.extensions_required.clear();
    let mut errors = Vec::new();
    let mut tolerated = Vec::new();
    root.validate(&root, gltf::json::Path::new, &mut |path, error| {
        let p = path().to_string();
        let bounds =
            p.contains("attributes[\"POSITION\"]") && (p.ends_with(".min") || p.ends_with(".max"));
        if bounds && matches!(error, VError::Missing) {
            tolerated.push(format!(
                "{file}: {p} is missing (required by glTF; ignored)"
            ));
        } else {
            errors.push(format!("{p}: {error}"));
        }
    });
    if !errors.is_empty() {
        return Err(SceneError::Invalid {
            file: file.to_string(),
            reason: errors.join("; "),
        });
    }
    Ok((
        gltf::Document::from_json_without_validation(root),
        tolerated,
    ))
}

// ---------------------------------------------------------------------------------------------------
// Raw JSON read in f64 (gltf-json keeps transforms and KHR_texture_transform as f32).

#[derive(Deserialize, Default)]
struct RawRoot {
    #[serde(default)]
    nodes: Vec<RawNode>,
    #[serde(default)]
    materials: Vec<RawMaterial>,
}

#[derive(Deserialize, Default)]
struct RawNode {
    matrix: Option<[f64; 16]>,
    translation: Option<[f64; 3]>,
    rotation: Option<[f64; 4]>,
    scale: Option<[f64; 3]>,
}

#[derive(Deserialize, Default)]
#[serde(rename_all = "camelCase")]
struct RawMaterial {
    pbr_metallic_roughness: Option<RawPbr>,
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
pub struct UvTransform {
    pub offset: DVec2,
    /// Radians, counter-clockwise in UV space (the extension's convention).
    pub rotation: f64,
    pub scale: DVec2,
}

impl UvTransform {
    /// Applies the transform: `u' = cos·sx·u + sin·sy·v + ox`, `v' = −sin·sx·u + cos·sy·v + oy`
    /// (the matrix of the KHR_texture_transform specification).
    #[inline]
    pub fn apply(&self, uv: DVec2) -> DVec2 {
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

// ---------------------------------------------------------------------------------------------------
// Importer state.

/// One mesh instance in world space.
struct Instance {
    node: usize,
    mesh: usize,
    world: DMat4,
}

/// How a material's vertices get their UVs.
#[derive(Clone, Copy)]
enum UvSource {
    /// From `TEXCOORD_set`, then the optional transform.
    Set(u32, Option<UvTransform>),
    /// 1×1 solid image: every vertex gets the texel centre (0.5, 0.5).
    Solid,
}

/// Reused per-primitive buffers (no per-vertex allocation).
#[derive(Default)]
struct Scratch {
    floats: Vec<f64>,
    tmp: Vec<f64>,
    world: Vec<DVec3>,
    uvs: Vec<DVec2>,
    indices: Vec<u32>,
    remap: Vec<u32>,
}

/// Mesh/primitive identification for errors and warnings.
struct PrimCtx {
    mesh: usize,
    mesh_name: String,
    primitive: usize,
}

/// An accessor-level failure before the mesh context is attached.
struct AccErr {
    accessor: usize,
    reason: String,
}

struct Importer<'a> {
    file: String,
    base_dir: PathBuf,
    doc: &'a gltf::Document,
    raw: RawRoot,
    blob: Option<Vec<u8>>,
    buffers: Vec<Option<Vec<u8>>>,
    accessors: Vec<gltf::Accessor<'a>>,
    meshes: Vec<gltf::Mesh<'a>>,
    vertices: Vec<Vertex>,
    triangles: Vec<Triangle>,
    materials: Vec<Material>,
    material_uv: Vec<UvSource>,
    images: Vec<ImageSource>,
    report: ImportReport,
    image_ids: HashMap<usize, ImageId>,
    solid_ids: HashMap<[u8; 4], ImageId>,
    material_ids: HashMap<(Option<usize>, bool), MaterialId>,
    scratch: Scratch,
}

impl<'a> Importer<'a> {
    fn new(
        file: String,
        base_dir: PathBuf,
        doc: &'a gltf::Document,
        raw: RawRoot,
        blob: Option<Vec<u8>>,
    ) -> Self {
        Importer {
            file,
            base_dir,
            doc,
            raw,
            blob,
            buffers: vec![None; doc.buffers().len()],
            accessors: doc.accessors().collect(),
            meshes: doc.meshes().collect(),
            vertices: Vec::new(),
            triangles: Vec::new(),
            materials: Vec::new(),
            material_uv: Vec::new(),
            images: Vec::new(),
            report: ImportReport::default(),
            image_ids: HashMap::new(),
            solid_ids: HashMap::new(),
            material_ids: HashMap::new(),
            scratch: Scratch::default(),
        }
    }

    /// Records a warning: the string is kept while fewer than [`MAX_WARNINGS`] are, the total is exact.
    fn warn(&mut self, msg: String) {
        self.report.warnings_total += 1;
        if self.report.warnings.len() < MAX_WARNINGS {
            self.report.warnings.push(msg);
        }
    }

    fn finish(mut self, path: &Path, opts: &ImportOptions) -> Scene {
        let kept = self.report.warnings.len() as u64;
        if self.report.warnings_total > kept {
            let more = self.report.warnings_total - kept;
            self.report.warnings.push(format!("... and {more} more"));
        }
        let mut scene = Scene {
            source: path.to_path_buf(),
            up: UpAxis::Y,
            vertices: self.vertices,
            triangles: self.triangles,
            materials: self.materials,
            images: self.images,
            report: self.report,
        };
        scene.up = opts.up.unwrap_or_else(|| auto_up(scene.bounds()));
        scene
    }

    // ---- buffers ------------------------------------------------------------------------------

    /// Loads buffer `index` if not loaded yet (GLB BIN chunk, data URI or external file).
    fn load_buffer(&mut self, index: usize) -> Result<(), SceneError> {
        if self.buffers.get(index).is_some_and(Option::is_some) {
            return Ok(());
        }
        let buffer = self
            .doc
            .buffers()
            .nth(index)
            .ok_or_else(|| SceneError::Buffer {
                file: self.file.clone(),
                buffer: index,
                uri: String::new(),
                reason: "no such buffer".into(),
            })?;
        let (uri, data) = match buffer.source() {
            gltf::buffer::Source::Bin => {
                let data = self
                    .blob
                    .take()
                    .ok_or_else(|| "GLB BIN chunk missing or already used".to_string());
                ("<GLB BIN chunk>".to_string(), data)
            }
            gltf::buffer::Source::Uri(uri) => (uri.to_string(), self.read_uri(uri)),
        };
        let err = |reason: String| SceneError::Buffer {
            file: self.file.clone(),
            buffer: index,
            uri: uri.clone(),
            reason,
        };
        let data = data.map_err(err)?;
        if data.len() < buffer.length() {
            return Err(err(format!(
                "has {} bytes, byteLength says {}",
                data.len(),
                buffer.length()
            )));
        }
        if let Some(slot) = self.buffers.get_mut(index) {
            *slot = Some(data);
        }
        Ok(())
    }

    /// Reads a URI: `data:` (base64) or a path relative to the glTF file (percent-decoded).
    fn read_uri(&self, uri: &str) -> Result<Vec<u8>, String> {
        if uri.starts_with("data:") {
            return decode_data_uri(uri);
        }
        let path = self.base_dir.join(percent_decode(uri));
        std::fs::read(&path).map_err(|e| format!("{}: {e}", path.display()))
    }

    /// Loads every buffer accessor `index` reads from (its view and sparse views).
    fn load_accessor_buffers(&mut self, index: usize) -> Result<(), SceneError> {
        let Some(acc) = self.accessors.get(index) else {
            return Ok(());
        };
        let mut needed = Vec::with_capacity(3);
        if let Some(v) = acc.view() {
            needed.push(v.buffer().index());
        }
        if let Some(sp) = acc.sparse() {
            needed.push(sp.indices().view().buffer().index());
            needed.push(sp.values().view().buffer().index());
        }
        for b in needed {
            self.load_buffer(b)?;
        }
        Ok(())
    }

    // ---- node hierarchy -----------------------------------------------------------------------

    /// Walks the default scene (or all root nodes) iteratively and returns every mesh instance with its
    /// world matrix. A node met again while it is on the current path is a cycle: error.
    fn collect_instances(&mut self) -> Result<Vec<Instance>, SceneError> {
        let n = self.doc.nodes().len();
        let roots: Vec<usize> = match self.doc.default_scene() {
            Some(s) => s.nodes().map(|nd| nd.index()).collect(),
            None => {
                let mut is_child = vec![false; n];
                for node in self.doc.nodes() {
                    for c in node.children() {
                        if let Some(f) = is_child.get_mut(c.index()) {
                            *f = true;
                        }
                    }
                }
                (0..n)
                    .filter(|&i| !is_child.get(i).copied().unwrap_or(true))
                    .collect()
            }
        };
        let nodes: Vec<gltf::Node<'a>> = self.doc.nodes().collect();
        enum Step {
            Enter(usize, DMat4),
            Exit(usize),
        }
        let mut on_path = vec![false; n];
        let mut seen = vec![false; n];
        let mut stack: Vec<Step> = roots
            .iter()
            .rev()
            .map(|&r| Step::Enter(r, DMat4::IDENTITY))
            .collect();
        let mut instances = Vec::new();
        let mut visits: u64 = 0;
        while let Some(step) = stack.pop() {
            let (i, parent) = match step {
                Step::Exit(i) => {
                    if let Some(p) = on_path.get_mut(i) {
                        *p = false;
                    }
                    continue;
                }
                Step::Enter(i, parent) => (i, parent),
            };
            let Some(node) = nodes.get(i) else { continue };
            if on_path.get(i).copied().unwrap_or(false) {
                return Err(SceneError::RecursiveNodes {
                    file: self.file.clone(),
                    node: i,
                    node_name: node.name().unwrap_or("").to_string(),
                });
            }
            visits += 1;
            if visits > MAX_NODE_VISITS {
                return Err(SceneError::TooLarge {
                    file: self.file.clone(),
                    what: format!(
                        "more than {MAX_NODE_VISITS} node visits (nodes shared by many parents)"
                    ),
                });
            }
            if let Some(s) = seen.get_mut(i) {
                if *s {
                    self.warn(format!(
                        "{}: node {i} has more than one parent; it is instanced once per parent",
                        self.file
                    ));
                }
                *s = true;
            }
            if let Some(p) = on_path.get_mut(i) {
                *p = true;
            }
            stack.push(Step::Exit(i));
            let world = parent * self.local_matrix(i);
            if let Some(mesh) = node.mesh() {
                match self.gpu_instances(node)? {
                    Some(list) => instances.extend(list.into_iter().map(|m| Instance {
                        node: i,
                        mesh: mesh.index(),
                        world: world * m,
                    })),
                    None => instances.push(Instance {
                        node: i,
                        mesh: mesh.index(),
                        world,
                    }),
                }
            }
            for c in node.children().collect::<Vec<_>>().into_iter().rev() {
                stack.push(Step::Enter(c.index(), world));
            }
        }
        self.report.nodes = visits;
        self.report.instances = instances.len() as u64;
        Ok(instances)
    }

    /// The node's local matrix in f64 from the raw JSON (`matrix`, else T·R·S).
    fn local_matrix(&mut self, i: usize) -> DMat4 {
        let Some(raw) = self.raw.nodes.get(i) else {
            return DMat4::IDENTITY;
        };
        if let Some(m) = raw.matrix {
            return DMat4::from_cols_array(&m);
        }
        let t = raw.translation.map_or(DVec3::ZERO, DVec3::from);
        let s = raw.scale.map_or(DVec3::ONE, DVec3::from);
        let r = raw.rotation.unwrap_or([0.0, 0.0, 0.0, 1.0]);
        let (q, ok) = unit_quat(r);
        if !ok {
            self.warn(format!(
                "{}: node {i} has a zero or non-finite rotation {r:?}; using identity",
                self.file
            ));
        }
        DMat4::from_scale_rotation_translation(s, q, t)
    }

    /// `EXT_mesh_gpu_instancing` instance matrices (T·R·S per instance), read from the raw extension JSON.
    fn gpu_instances(&mut self, node: &gltf::Node<'a>) -> Result<Option<Vec<DMat4>>, SceneError> {
        let Some(ext) = node.extension_value("EXT_mesh_gpu_instancing") else {
            return Ok(None);
        };
        let file = self.file.clone();
        let err = |reason: String| SceneError::Instancing {
            file: file.clone(),
            node: node.index(),
            node_name: node.name().unwrap_or("").to_string(),
            reason,
        };
        let attrs = ext
            .get("attributes")
            .and_then(|a| a.as_object())
            .ok_or_else(|| err("no attributes".into()))?;
        let mut cols: [Option<Vec<f64>>; 3] = [None, None, None];
        let mut count: Option<usize> = None;
        for (k, (name, dims)) in [("TRANSLATION", 3), ("ROTATION", 4), ("SCALE", 3)]
            .into_iter()
            .enumerate()
        {
            let Some(v) = attrs.get(name) else { continue };
            let idx = v
                .as_u64()
                .and_then(|x| usize::try_from(x).ok())
                .filter(|&x| x < self.accessors.len())
                .ok_or_else(|| err(format!("{name} accessor {v} does not exist")))?;
            self.load_accessor_buffers(idx)?;
            let mut out = Vec::new();
            let acc = &self.accessors[idx];
            read_floats(&self.buffers, acc, dims, &mut out, &mut Vec::new())
                .map_err(|e| err(format!("{name} accessor {}: {}", e.accessor, e.reason)))?;
            let c = acc.count();
            if count.is_some_and(|n| n != c) {
                return Err(err(format!(
                    "{name} accessor {idx} has {c} elements, other attributes differ"
                )));
            }
            count = Some(c);
            if let Some(slot) = cols.get_mut(k) {
                *slot = Some(out);
            }
        }
        let Some(count) = count else {
            return Ok(Some(Vec::new()));
        };
        let [t, r, s] = cols;
        let mut out = Vec::with_capacity(count);
        let mut bad_rot = 0u64;
        for i in 0..count {
            let tr = t.as_ref().map_or(DVec3::ZERO, |v| {
                DVec3::new(v[3 * i], v[3 * i + 1], v[3 * i + 2])
            });
            let sc = s.as_ref().map_or(DVec3::ONE, |v| {
                DVec3::new(v[3 * i], v[3 * i + 1], v[3 * i + 2])
            });
            let q = match r.as_ref() {
                Some(v) => {
                    let (q, ok) = unit_quat([v[4 * i], v[4 * i + 1], v[4 * i + 2], v[4 * i + 3]]);
                    bad_rot += u64::from(!ok);
                    q
                }
                None => DQuat::IDENTITY,
            };
            out.push(DMat4::from_scale_rotation_translation(sc, q, tr));
        }
        if bad_rot > 0 {
            self.warn(format!(
                "{}: node {}: {bad_rot} EXT_mesh_gpu_instancing rotations are zero or non-finite; identity used",
                self.file,
                node.index()
            ));
        }
        Ok(Some(out))
    }

    /// Reserves the output vectors from the accessor counts (capped by the buffer view sizes). Allocation
    /// failure of the reservation is not an error: the vectors then grow as needed.
    fn reserve(&mut self, instances: &[Instance]) -> Result<(), SceneError> {
        let meshes = &self.meshes;
        let mut per_mesh: HashMap<usize, (u64, u64)> = HashMap::new();
        let (mut tris, mut verts) = (0u64, 0u64);
        for inst in instances {
            let (t, v) = *per_mesh.entry(inst.mesh).or_insert_with(|| {
                let Some(mesh) = meshes.get(inst.mesh) else {
                    return (0, 0);
                };
                mesh.primitives().fold((0, 0), |(t, v), p| {
                    let nv = p
                        .get(&Semantic::Positions)
                        .map_or(0, |a| plausible_count(&a)) as u64;
                    let ni = p.indices().map_or(nv, |a| plausible_count(&a) as u64);
                    (t + ni / 3, v + nv)
                })
            });
            tris = tris.saturating_add(t);
            verts = verts.saturating_add(v);
        }
        if verts > u64::from(u32::MAX) {
            return Err(SceneError::TooLarge {
                file: self.file.clone(),
                what: format!("{verts} vertices exceed the u32 vertex index range"),
            });
        }
        let _ = self
            .triangles
            .try_reserve(usize::try_from(tris).unwrap_or(0));
        let _ = self
            .vertices
            .try_reserve(usize::try_from(verts).unwrap_or(0));
        Ok(())
    }

    // ---- materials and images -----------------------------------------------------------------

    /// The material for primitive `prim` and its UV source. A textured material whose `texCoord` set is
    /// missing on this primitive becomes a solid-colour variant (counted warning).
    fn material_for(&mut self, prim: &gltf::Primitive<'a>, ctx: &PrimCtx) -> MaterialId {
        let gm = prim.material();
        let index = gm.index();
        let pbr = gm.pbr_metallic_roughness();
        let raw_tt = index
            .and_then(|i| self.raw.materials.get(i))
            .and_then(|m| m.pbr_metallic_roughness.as_ref())
            .and_then(|p| p.base_color_texture.as_ref())
            .and_then(|t| t.extensions.as_ref())
            .and_then(|e| e.texture_transform);
        let tex = pbr.base_color_texture();
        let set = tex
            .as_ref()
            .map(|info| raw_tt.and_then(|t| t.tex_coord).unwrap_or(info.tex_coord()));
        let has_uvs = set.is_some_and(|s| prim.get(&Semantic::TexCoords(s)).is_some());
        if let (Some(s), false) = (set, has_uvs) {
            self.report.missing_texcoords += 1;
            self.warn(format!(
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
            return id;
        }
        let factor = pbr.base_color_factor();
        let alpha = match gm.alpha_mode() {
            gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
            gltf::material::AlphaMode::Mask => AlphaMode::Mask {
                cutoff: gm.alpha_cutoff().unwrap_or(0.5),
            },
            gltf::material::AlphaMode::Blend => AlphaMode::Blend,
        };
        let name = match (gm.name(), index) {
            (Some(n), _) => n.to_string(),
            (None, Some(i)) => format!("material {i}"),
            (None, None) => "default material".to_string(),
        };
        let (material, uv) = match (tex, set) {
            (Some(info), Some(s)) if !solid => {
                let texture = info.texture();
                let sampler = texture.sampler();
                let image = self.image_for(texture.source());
                let xf = raw_tt.map(UvTransform::from);
                let m = Material {
                    name,
                    image,
                    tex_coord: s,
                    wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())],
                    alpha,
                    base_color_factor: factor,
                    texture_transform: xf.is_some(),
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
                };
                (m, UvSource::Solid)
            }
        };
        let id = MaterialId(self.materials.len() as u32);
        self.materials.push(material);
        self.material_uv.push(uv);
        self.material_ids.insert((index, solid), id);
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

    /// The image for glTF image `img` (header read once); missing/undecodable → fallback + warning.
    fn image_for(&mut self, img: gltf::Image<'a>) -> ImageId {
        if let Some(&id) = self.image_ids.get(&img.index()) {
            return id;
        }
        let (name, loaded) = self.load_image(&img);
        let source = match loaded {
            Ok(src) => src,
            Err(reason) => {
                self.report.missing_images += 1;
                self.warn(format!(
                    "{}: image {} ({name}): {reason}; using the magenta/black fallback checker",
                    self.file,
                    img.index()
                ));
                ImageSource::fallback(&name)
            }
        };
        let id = self.push_image(source);
        self.image_ids.insert(img.index(), id);
        id
    }

    /// Reads an image's header and keeps its path (external file) or encoded bytes.
    fn load_image(&mut self, img: &gltf::Image<'a>) -> (String, Result<ImageSource, String>) {
        // `gltf::Image::source` unwraps `mimeType`/`uri`, which validation does not guarantee: read
        // the JSON fields directly.
        let json = self.doc.as_json().images.get(img.index());
        let view = json
            .and_then(|j| j.buffer_view)
            .and_then(|v| self.doc.views().nth(v.value()));
        let uri = json.and_then(|j| j.uri.as_deref());
        let source = match (view, uri) {
            (Some(view), _) => ImgSrc::View(view),
            (None, Some(uri)) => ImgSrc::Uri(uri),
            (None, None) => {
                let name = img
                    .name()
                    .map_or_else(|| format!("image {}", img.index()), str::to_string);
                return (name, Err("neither uri nor bufferView".to_string()));
            }
        };
        match source {
            ImgSrc::Uri(uri) if uri.starts_with("data:") => {
                let name = img.name().map_or_else(
                    || format!("image {} (data URI)", img.index()),
                    str::to_string,
                );
                let res = decode_data_uri(uri).and_then(|b| from_bytes(&name, b.into()));
                (name, res)
            }
            ImgSrc::Uri(uri) => {
                let rel = percent_decode(uri);
                let path = self.base_dir.join(&rel);
                let name = img.name().map_or_else(|| rel.clone(), str::to_string);
                let res = std::fs::File::open(&path)
                    .map_err(|e| format!("{}: {e}", path.display()))
                    .and_then(|f| {
                        image_source::read_header(std::io::BufReader::new(f))
                            .map_err(|e| format!("{}: {e}", path.display()))
                    })
                    .map(|h| ImageSource {
                        name: name.clone(),
                        width: h.width,
                        height: h.height,
                        has_alpha: h.has_alpha,
                        color: h.color,
                        data: ImageData::File(path.clone()),
                    });
                (name, res)
            }
            ImgSrc::View(view) => {
                let name = img.name().map_or_else(
                    || format!("image {} (buffer view {})", img.index(), view.index()),
                    str::to_string,
                );
                let res = self
                    .load_buffer(view.buffer().index())
                    .map_err(|e| e.to_string())
                    .and_then(|()| view_slice(&self.buffers, &view))
                    .and_then(|bytes| from_bytes(&name, Arc::from(bytes)));
                (name, res)
            }
        }
    }

    // ---- geometry -----------------------------------------------------------------------------

    fn emit_instance(&mut self, inst: &Instance) -> Result<(), SceneError> {
        let Some(mesh) = self.meshes.get(inst.mesh).cloned() else {
            return Ok(());
        };
        let mesh_name = mesh.name().unwrap_or("").to_string();
        for prim in mesh.primitives() {
            let ctx = PrimCtx {
                mesh: inst.mesh,
                mesh_name: mesh_name.clone(),
                primitive: prim.index(),
            };
            self.emit_primitive(inst, &prim, &ctx)?;
        }
        Ok(())
    }

    fn acc_error(&self, ctx: &PrimCtx, semantic: &str, e: AccErr) -> SceneError {
        SceneError::Accessor {
            file: self.file.clone(),
            mesh: ctx.mesh,
            mesh_name: ctx.mesh_name.clone(),
            primitive: ctx.primitive,
            accessor: e.accessor,
            reason: format!("{semantic}: {}", e.reason),
        }
    }

    /// Emits one primitive of one instance: world-space vertices (only those used by kept triangles)
    /// and triangles. See the module docs for what is skipped and counted.
    fn emit_primitive(
        &mut self,
        inst: &Instance,
        prim: &gltf::Primitive<'a>,
        ctx: &PrimCtx,
    ) -> Result<(), SceneError> {
        let mode = prim.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            self.report.skipped_primitives += 1;
            self.warn(format!(
                "{}: mesh {} ({}) primitive {}: mode {mode:?} is not triangles; skipped (node {})",
                self.file, ctx.mesh, ctx.mesh_name, ctx.primitive, inst.node
            ));
            return Ok(());
        }
        let Some(pos_acc) = prim.get(&Semantic::Positions) else {
            self.report.skipped_primitives += 1;
            self.warn(format!(
                "{}: mesh {} ({}) primitive {}: no POSITION attribute; skipped",
                self.file, ctx.mesh, ctx.mesh_name, ctx.primitive
            ));
            return Ok(());
        };
        let material = self.material_for(prim, ctx);
        let uv_source = self
            .material_uv
            .get(material.idx())
            .copied()
            .unwrap_or(UvSource::Solid);

        // Positions → world space.
        self.load_accessor_buffers(pos_acc.index())?;
        let s = &mut self.scratch;
        read_floats(&self.buffers, &pos_acc, 3, &mut s.floats, &mut s.tmp)
            .map_err(|e| self.acc_error(ctx, "POSITION", e))?;
        let n = pos_acc.count();
        let s = &mut self.scratch;
        s.world.clear();
        s.world.extend(
            s.floats
                .chunks_exact(3)
                .map(|p| inst.world.transform_point3(DVec3::new(p[0], p[1], p[2]))),
        );

        // UVs (transform baked in f64).
        s.uvs.clear();
        if let UvSource::Set(set, xf) = uv_source {
            let semantic = format!("TEXCOORD_{set}");
            let Some(uv_acc) = prim.get(&Semantic::TexCoords(set)) else {
                return Err(SceneError::Other(format!(
                    "{}: internal: {semantic} vanished",
                    self.file
                )));
            };
            if uv_acc.count() != n {
                return Err(SceneError::Accessor {
                    file: self.file.clone(),
                    mesh: ctx.mesh,
                    mesh_name: ctx.mesh_name.clone(),
                    primitive: ctx.primitive,
                    accessor: uv_acc.index(),
                    reason: format!(
                        "{semantic} has {} elements but POSITION (accessor {}) has {n}",
                        uv_acc.count(),
                        pos_acc.index()
                    ),
                });
            }
            self.load_accessor_buffers(uv_acc.index())?;
            let s = &mut self.scratch;
            read_floats(&self.buffers, &uv_acc, 2, &mut s.floats, &mut s.tmp)
                .map_err(|e| self.acc_error(ctx, &semantic, e))?;
            let s = &mut self.scratch;
            match xf {
                Some(t) => s.uvs.extend(
                    s.floats
                        .chunks_exact(2)
                        .map(|c| t.apply(DVec2::new(c[0], c[1]))),
                ),
                None => s
                    .uvs
                    .extend(s.floats.chunks_exact(2).map(|c| DVec2::new(c[0], c[1]))),
            }
        }

        // Indices (or 0..n), checked against the vertex count.
        match prim.indices() {
            Some(idx_acc) => {
                self.load_accessor_buffers(idx_acc.index())?;
                let s = &mut self.scratch;
                read_indices(&self.buffers, &idx_acc, &mut s.indices, &mut s.tmp)
                    .map_err(|e| self.acc_error(ctx, "indices", e))?;
                if let Some((position, &index)) = self
                    .scratch
                    .indices
                    .iter()
                    .enumerate()
                    .find(|(_, i)| **i as usize >= n)
                {
                    return Err(SceneError::IndexOutOfRange {
                        file: self.file.clone(),
                        mesh: ctx.mesh,
                        mesh_name: ctx.mesh_name.clone(),
                        primitive: ctx.primitive,
                        accessor: idx_acc.index(),
                        position,
                        index,
                        vertex_count: n,
                    });
                }
            }
            None => {
                let count = u32::try_from(n).map_err(|_| SceneError::TooLarge {
                    file: self.file.clone(),
                    what: format!(
                        "mesh {} primitive {}: {n} vertices",
                        ctx.mesh, ctx.primitive
                    ),
                })?;
                self.scratch.indices.clear();
                self.scratch.indices.extend(0..count);
            }
        }
        let leftover = match mode {
            Mode::Triangles => self.scratch.indices.len() % 3,
            _ => 0,
        };
        if leftover != 0 {
            self.warn(format!(
                "{}: mesh {} ({}) primitive {}: {} indices is not a multiple of 3; the last {leftover} ignored",
                self.file,
                ctx.mesh,
                ctx.mesh_name,
                ctx.primitive,
                self.scratch.indices.len()
            ));
        }
        let counts = self.assemble(mode, material, n)?;
        self.report_counts(ctx, &counts);
        Ok(())
    }

    /// Builds the triangles of the current primitive from `scratch` (world positions, UVs, indices).
    fn assemble(
        &mut self,
        mode: Mode,
        material: MaterialId,
        n: usize,
    ) -> Result<TriCounts, SceneError> {
        let Scratch {
            world,
            uvs,
            indices,
            remap,
            ..
        } = &mut self.scratch;
        remap.clear();
        remap.resize(n, u32::MAX);
        let ntri = match mode {
            Mode::Triangles => indices.len() / 3,
            _ => indices.len().saturating_sub(2),
        };
        let solid_uv = DVec2::splat(0.5);
        let mut counts = TriCounts::default();
        for t in 0..ntri {
            let tri = match mode {
                Mode::Triangles => [3 * t, 3 * t + 1, 3 * t + 2],
                Mode::TriangleStrip if t % 2 == 0 => [t, t + 1, t + 2],
                Mode::TriangleStrip => [t, t + 2, t + 1],
                _ => [t + 1, t + 2, 0],
            };
            let (Some(&a), Some(&b), Some(&c)) = (
                indices.get(tri[0]),
                indices.get(tri[1]),
                indices.get(tri[2]),
            ) else {
                continue;
            };
            let l = [a as usize, b as usize, c as usize];
            let (Some(&p0), Some(&p1), Some(&p2)) =
                (world.get(l[0]), world.get(l[1]), world.get(l[2]))
            else {
                continue;
            };
            let p = [p0, p1, p2];
            if !p.iter().all(|q| q.is_finite()) {
                counts.bad_pos += 1;
                continue;
            }
            let uv = if uvs.is_empty() {
                [solid_uv; 3]
            } else {
                let (Some(&u0), Some(&u1), Some(&u2)) =
                    (uvs.get(l[0]), uvs.get(l[1]), uvs.get(l[2]))
                else {
                    continue;
                };
                [u0, u1, u2]
            };
            if !uv.iter().all(|u| u.is_finite()) {
                counts.bad_uv += 1;
                continue;
            }
            if uv
                .iter()
                .any(|u| u.x.abs() > LARGE_UV || u.y.abs() > LARGE_UV)
            {
                counts.large_uv += 1;
            }
            let mut v = [0u32; 3];
            for k in 0..3 {
                let slot = remap
                    .get_mut(l[k])
                    .ok_or_else(|| SceneError::Other("internal: remap".into()))?;
                if *slot == u32::MAX {
                    *slot = u32::try_from(self.vertices.len())
                        .ok()
                        .filter(|&x| x != u32::MAX)
                        .ok_or_else(|| SceneError::TooLarge {
                            file: self.file.clone(),
                            what: "more than 2^32-1 vertices".into(),
                        })?;
                    self.vertices.push(Vertex {
                        pos: p[k],
                        uv: uv[k],
                    });
                }
                v[k] = *slot;
            }
            self.triangles.push(Triangle { v, material });
        }
        Ok(counts)
    }

    fn report_counts(&mut self, ctx: &PrimCtx, c: &TriCounts) {
        let where_ = format!(
            "{}: mesh {} ({}) primitive {}",
            self.file, ctx.mesh, ctx.mesh_name, ctx.primitive
        );
        if c.bad_pos > 0 {
            self.report.skipped_triangles += c.bad_pos;
            self.warn(format!(
                "{where_}: {} triangles with NaN/Inf positions skipped",
                c.bad_pos
            ));
        }
        if c.bad_uv > 0 {
            self.report.skipped_triangles += c.bad_uv;
            self.warn(format!(
                "{where_}: {} triangles with NaN/Inf UVs skipped",
                c.bad_uv
            ));
        }
        if c.large_uv > 0 {
            self.report.large_uv_triangles += c.large_uv;
            self.warn(format!(
                "{where_}: {} triangles with |uv| > {LARGE_UV:e} kept",
                c.large_uv
            ));
        }
    }
}

/// Where an image's bytes are.
enum ImgSrc<'a> {
    View(gltf::buffer::View<'a>),
    Uri(&'a str),
}

/// Per-primitive triangle counts.
#[derive(Default)]
struct TriCounts {
    bad_pos: u64,
    bad_uv: u64,
    large_uv: u64,
}

// ---------------------------------------------------------------------------------------------------
// Helpers.

/// Header of encoded bytes → an `ImageSource` keeping the bytes.
fn from_bytes(name: &str, bytes: Arc<[u8]>) -> Result<ImageSource, String> {
    let h = image_source::read_header(std::io::Cursor::new(&bytes[..]))?;
    Ok(ImageSource {
        name: name.to_string(),
        width: h.width,
        height: h.height,
        has_alpha: h.has_alpha,
        color: h.color,
        data: ImageData::Bytes(bytes),
    })
}

fn wrap(w: gltf::texture::WrappingMode) -> Wrap {
    match w {
        gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
    }
}

/// Linear RGBA factor → sRGB-encoded RGBA8 (alpha stays linear), each clamped to [0, 1] and rounded.
pub fn srgb8(linear: [f32; 4]) -> [u8; 4] {
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

/// Normalised quaternion from `[x, y, z, w]`; identity (and `false`) when zero-length or non-finite.
fn unit_quat(r: [f64; 4]) -> (DQuat, bool) {
    let q = DQuat::from_xyzw(r[0], r[1], r[2], r[3]);
    let len = q.length();
    if len.is_finite() && len > 1e-12 {
        (q / len, true)
    } else {
        (DQuat::IDENTITY, false)
    }
}

/// Auto up axis: the axis of least extent of `bounds`; ties prefer Y, then Z, then X. Y for no bounds.
pub fn auto_up(bounds: Option<(DVec3, DVec3)>) -> UpAxis {
    let Some((lo, hi)) = bounds else {
        return UpAxis::Y;
    };
    let e = hi - lo;
    let mut best = (UpAxis::Y, e.y);
    for (axis, ext) in [(UpAxis::Z, e.z), (UpAxis::X, e.x)] {
        if ext < best.1 {
            best = (axis, ext);
        }
    }
    best.0
}

/// Decodes `%XX` escapes of a relative URI (invalid escapes are kept literally).
pub fn percent_decode(uri: &str) -> String {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |k: usize| b.get(k).and_then(|c| (*c as char).to_digit(16));
        match (b[i], hex(i + 1), hex(i + 2)) {
            (b'%', Some(h), Some(l)) => {
                out.push((h * 16 + l) as u8);
                i += 3;
            }
            (c, _, _) => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Decodes a base64 `data:` URI (padding optional).
fn decode_data_uri(uri: &str) -> Result<Vec<u8>, String> {
    use base64::Engine;
    let (head, payload) = uri.split_once(',').ok_or("data URI without ','")?;
    if !head.ends_with(";base64") {
        return Err(format!("data URI '{head}' is not base64"));
    }
    let engine = base64::engine::GeneralPurpose::new(
        &base64::alphabet::STANDARD,
        base64::engine::GeneralPurposeConfig::new()
            .with_decode_padding_mode(base64::engine::DecodePaddingMode::Indifferent),
    );
    engine
        .decode(payload.trim())
        .map_err(|e| format!("data URI base64: {e}"))
}

// ---------------------------------------------------------------------------------------------------
// Accessor reading with checked ranges.

fn component_size(t: DataType) -> usize {
    match t {
        DataType::I8 | DataType::U8 => 1,
        DataType::I16 | DataType::U16 => 2,
        DataType::U32 | DataType::F32 => 4,
    }
}

fn dimension_count(d: Dimensions) -> usize {
    match d {
        Dimensions::Scalar => 1,
        Dimensions::Vec2 => 2,
        Dimensions::Vec3 => 3,
        Dimensions::Vec4 | Dimensions::Mat2 => 4,
        Dimensions::Mat3 => 9,
        Dimensions::Mat4 => 16,
    }
}

/// One component as f64 (`b` holds exactly `component_size(t)` bytes). Normalised integers map to
/// [0, 1] (unsigned) or [-1, 1] (signed, `max(v / MAX, -1)`), per the glTF specification.
#[inline]
fn decode_component(t: DataType, normalized: bool, b: &[u8]) -> f64 {
    let (v, max) = match t {
        DataType::F32 => return f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        DataType::I8 => (f64::from(b[0] as i8), 127.0),
        DataType::U8 => (f64::from(b[0]), 255.0),
        DataType::I16 => (f64::from(i16::from_le_bytes([b[0], b[1]])), 32767.0),
        DataType::U16 => (f64::from(u16::from_le_bytes([b[0], b[1]])), 65535.0),
        DataType::U32 => (
            f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            4_294_967_295.0,
        ),
    };
    if normalized { (v / max).max(-1.0) } else { v }
}

/// The bytes of buffer view `view`, checked against the loaded buffer.
fn view_slice<'b>(
    buffers: &'b [Option<Vec<u8>>],
    view: &gltf::buffer::View,
) -> Result<&'b [u8], String> {
    let b = view.buffer().index();
    let buf = buffers
        .get(b)
        .and_then(|x| x.as_deref())
        .ok_or_else(|| format!("buffer {b} not loaded"))?;
    let end = view
        .offset()
        .checked_add(view.length())
        .ok_or("buffer view range overflows")?;
    buf.get(view.offset()..end).ok_or_else(|| {
        format!(
            "buffer view {} (bytes {}..{end}) exceeds buffer {b} of {} bytes",
            view.index(),
            view.offset(),
            buf.len()
        )
    })
}

/// Dense element layout inside a view: `count` elements of `elem` bytes, `stride` apart, from `offset`.
struct Dense<'b> {
    data: &'b [u8],
    stride: usize,
    elem: usize,
    count: usize,
}

fn dense<'b>(
    buffers: &'b [Option<Vec<u8>>],
    view: &gltf::buffer::View,
    offset: usize,
    count: usize,
    elem: usize,
    use_view_stride: bool,
) -> Result<Dense<'b>, String> {
    let vs = view_slice(buffers, view)?;
    let stride = if use_view_stride {
        view.stride().unwrap_or(elem)
    } else {
        elem
    };
    if stride < elem {
        return Err(format!(
            "byteStride {stride} is smaller than the element size {elem}"
        ));
    }
    if count == 0 {
        return Ok(Dense {
            data: &[],
            stride,
            elem,
            count,
        });
    }
    let end = (count - 1)
        .checked_mul(stride)
        .and_then(|x| x.checked_add(offset))
        .and_then(|x| x.checked_add(elem))
        .ok_or("accessor byte range overflows")?;
    let data = vs.get(offset..end).ok_or_else(|| {
        format!(
            "{count} elements of {elem} bytes (stride {stride}) from byte {offset} end at byte {end}, past the end \
             of buffer view {} ({} bytes)",
            view.index(),
            vs.len()
        )
    })?;
    Ok(Dense {
        data,
        stride,
        elem,
        count,
    })
}

impl Dense<'_> {
    /// The element slices (each exactly `elem` bytes).
    fn elements(&self) -> impl Iterator<Item = &[u8]> {
        self.data
            .chunks(self.stride)
            .take(self.count)
            .filter_map(|c| c.get(..self.elem))
    }
}

/// Reads accessor `acc` as `count × dims` f64 into `out` (sparse substitution applied). The accessor
/// must have exactly `dims` components per element.
fn read_floats(
    buffers: &[Option<Vec<u8>>],
    acc: &gltf::Accessor,
    dims: usize,
    out: &mut Vec<f64>,
    tmp: &mut Vec<f64>,
) -> Result<(), AccErr> {
    let err = |reason: String| AccErr {
        accessor: acc.index(),
        reason,
    };
    let got = dimension_count(acc.dimensions());
    if got != dims {
        return Err(err(format!(
            "has {:?} elements, expected {dims} components",
            acc.dimensions()
        )));
    }
    let t = acc.data_type();
    let cs = component_size(t);
    let norm = acc.normalized();
    let count = acc.count();
    out.clear();
    match acc.view() {
        Some(view) => {
            let d = dense(buffers, &view, acc.offset(), count, cs * dims, true).map_err(err)?;
            out.reserve(count * dims);
            for e in d.elements() {
                out.extend(e.chunks_exact(cs).map(|b| decode_component(t, norm, b)));
            }
        }
        None => {
            if count > MAX_SPARSE_ONLY_COUNT {
                return Err(err(format!("{count} elements without a buffer view")));
            }
            out.resize(count * dims, 0.0);
        }
    }
    if out.len() != count * dims {
        return Err(err("short read".into()));
    }
    if let Some(sp) = acc.sparse() {
        let mut idx = Vec::new();
        let iv = sp.indices();
        let it = match iv.index_type() {
            gltf::accessor::sparse::IndexType::U8 => DataType::U8,
            gltf::accessor::sparse::IndexType::U16 => DataType::U16,
            gltf::accessor::sparse::IndexType::U32 => DataType::U32,
        };
        let n = sp.count();
        let d = dense(
            buffers,
            &iv.view(),
            iv.offset(),
            n,
            component_size(it),
            false,
        )
        .map_err(|r| err(format!("sparse indices: {r}")))?;
        idx.extend(
            d.elements()
                .map(|b| decode_component(it, false, b) as usize),
        );
        let vv = sp.values();
        let d = dense(buffers, &vv.view(), vv.offset(), n, cs * dims, false)
            .map_err(|r| err(format!("sparse values: {r}")))?;
        tmp.clear();
        for e in d.elements() {
            tmp.extend(e.chunks_exact(cs).map(|b| decode_component(t, norm, b)));
        }
        for (k, &i) in idx.iter().enumerate() {
            let dst = i
                .checked_mul(dims)
                .and_then(|s| out.get_mut(s..s + dims))
                .ok_or_else(|| err(format!("sparse index {i} out of range ({count} elements)")))?;
            let src = tmp
                .get(k * dims..(k + 1) * dims)
                .ok_or_else(|| err("sparse values short".into()))?;
            dst.copy_from_slice(src);
        }
    }
    Ok(())
}

/// Reads an index accessor (SCALAR of u8/u16/u32) into `out`.
fn read_indices(
    buffers: &[Option<Vec<u8>>],
    acc: &gltf::Accessor,
    out: &mut Vec<u32>,
    tmp: &mut Vec<f64>,
) -> Result<(), AccErr> {
    let err = |reason: String| AccErr {
        accessor: acc.index(),
        reason,
    };
    let t = acc.data_type();
    if acc.dimensions() != Dimensions::Scalar
        || !matches!(t, DataType::U8 | DataType::U16 | DataType::U32)
    {
        return Err(err(format!(
            "indices must be SCALAR of unsigned byte/short/int, found {:?} of {t:?}",
            acc.dimensions()
        )));
    }
    out.clear();
    if acc.sparse().is_some() || acc.view().is_none() {
        let mut vals = Vec::new();
        read_floats(buffers, acc, 1, &mut vals, tmp)?;
        out.extend(vals.iter().map(|&v| v as u32));
        return Ok(());
    }
    let Some(view) = acc.view() else {
        return Ok(());
    };
    let cs = component_size(t);
    let d = dense(buffers, &view, acc.offset(), acc.count(), cs, true).map_err(err)?;
    out.reserve(acc.count());
    match t {
        DataType::U8 => out.extend(d.elements().map(|b| u32::from(b[0]))),
        DataType::U16 => out.extend(
            d.elements()
                .map(|b| u32::from(u16::from_le_bytes([b[0], b[1]]))),
        ),
        _ => out.extend(
            d.elements()
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
        ),
    }
    Ok(())
}

/// An accessor's count if its dense range fits its view's declared length, else 0 (used for
/// reservations only; the real check happens when reading).
fn plausible_count(acc: &gltf::Accessor) -> usize {
    let Some(view) = acc.view() else { return 0 };
    let elem = component_size(acc.data_type()) * dimension_count(acc.dimensions());
    let stride = view.stride().unwrap_or(elem).max(elem);
    let fits = acc
        .count()
        .checked_sub(1)
        .and_then(|c| c.checked_mul(stride))
        .and_then(|x| x.checked_add(acc.offset() + elem))
        .is_some_and(|end| end <= view.length());
    if fits { acc.count() } else { 0 }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_decoding() {
        assert_eq!(percent_decode("a%20b%2Fc.png"), "a b/c.png");
        assert_eq!(percent_decode("100%"), "100%");
        assert_eq!(percent_decode("%zz%4"), "%zz%4");
    }

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

    #[test]
    fn auto_up_picks_least_extent() {
        assert_eq!(auto_up(None), UpAxis::Y);
        assert_eq!(
            auto_up(Some((DVec3::ZERO, DVec3::new(10.0, 10.0, 1.0)))),
            UpAxis::Z
        );
        assert_eq!(
            auto_up(Some((DVec3::ZERO, DVec3::new(10.0, 1.0, 10.0)))),
            UpAxis::Y
        );
        assert_eq!(
            auto_up(Some((DVec3::ZERO, DVec3::new(0.5, 1.0, 10.0)))),
            UpAxis::X
        );
        assert_eq!(auto_up(Some((DVec3::ZERO, DVec3::ONE))), UpAxis::Y);
    }

    #[test]
    fn error_stays_small() {
        // clippy::result_large_err: keep `Result<_, SceneError>` cheap to return.
        assert!(
            std::mem::size_of::<SceneError>() < 128,
            "{}",
            std::mem::size_of::<SceneError>()
        );
    }

    #[test]
    fn normalized_components() {
        assert_eq!(decode_component(DataType::U8, true, &[255]), 1.0);
        assert_eq!(decode_component(DataType::I8, true, &[0x80]), -1.0);
        assert_eq!(decode_component(DataType::U16, true, &[0xff, 0xff]), 1.0);
        assert_eq!(decode_component(DataType::U16, false, &[2, 1]), 258.0);
    }
}
