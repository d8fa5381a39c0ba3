//! glTF 2.0 import into a flat world-space triangle soup: the entry point [`import`] and what it
//! hands from one stage to the next.
//!
//! The data change form in this order, one file each:
//! - `uri.rs`: the file's bytes → JSON and the GLB `BIN` chunk; buffers (external files, data URIs, the
//!   `BIN` chunk) loaded on first use; images only have their header read
//!   ([`crate::scene::image_source::read_header`]) and are decoded lazily;
//! - `refs.rs`: every index one object gives to another, checked in the raw JSON ([`serde_json::Value`])
//!   with its JSON path, before gltf-json (whose validation indexes before it bounds-checks) sees it;
//! - here: the JSON → a validated [`gltf::Document`] plus the raw JSON fields gltf-json keeps as f32;
//! - `nodes.rs`: the node graph → mesh instances with f64 world matrices ([`glam::DMat4`] products,
//!   taken from the raw JSON), `EXT_mesh_gpu_instancing` expanded;
//! - `mesh.rs`: each instance's primitives → distinct world-space vertices and triangles, reading
//!   attributes through `accessors.rs` (bytes → f64 / u32, ranges checked) and materials through
//!   `materials.rs` (glTF material → [`crate::scene::Material`] and how its vertices get UVs).
//!
//! Every stage counts what it skips in the [`ImportReport`] and warns through `warnings.rs` (at most
//! [`MAX_WARNINGS`] messages kept).
//!
//! Policy on bad input: structural errors (unreadable/invalid JSON, schema failures, missing buffers,
//! accessors past their buffer, out-of-range indices, recursive node graphs, unsupported required
//! extensions) are a [`SceneError`]; data problems that affect single triangles (non-finite positions or
//! UVs) skip those triangles; unsupported primitive modes skip the primitive; missing images are
//! replaced by a fallback checker. Every skip is counted in [`ImportReport`]. A panic left in a
//! dependency is caught at this boundary and returned as [`SceneError::Internal`] naming the file.

mod accessors;
mod images_only;
mod materials;
mod mesh;
mod nodes;
mod refs;
mod uri;
mod warnings;

pub(super) use crate::scene::error::SceneError;
pub use images_only::{import_images, input_digest};
pub use uri::looks_like_json;

use crate::scene::{ImportReport, Scene, UpAxis};
use crate::util::panic_message;
use glam::DVec3;
use materials::{Materials, RawMaterial, RawTexture};
use mesh::Geometry;
use nodes::{RawNode, Walk};
use serde::Deserialize;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;
use uri::{Buffers, split_glb};

/// Required extensions this importer honours (others listed in `extensionsRequired` are an error).
pub(super) const SUPPORTED_REQUIRED_EXTENSIONS: &[&str] = &[
    "KHR_texture_transform",
    "KHR_mesh_quantization",
    "EXT_mesh_gpu_instancing",
    "KHR_materials_unlit",
    "EXT_texture_webp",
    "KHR_materials_pbrSpecularGlossiness",
];

/// Import options.
#[derive(Clone, Debug, Default)]
pub struct ImportOptions {
    /// `None` = auto (the axis of least extent of the world bounds where under half the next least,
    /// else Y: [`auto_up`]).
    pub up: Option<UpAxis>,
    /// The most triangles the caller's memory budget holds (`build --max-memory`: the plan keeps ~250
    /// bytes a triangle). The node walk counts triangles as it meets mesh instances and refuses the scene
    /// ([`SceneError::OverTriangleBudget`], with the whole scene's count: past the budget the walk keeps
    /// no instance) before any vertex is read: a few KB of JSON sharing nodes can instance millions of
    /// triangles. `None`: only the importer's own cap.
    pub max_triangles: Option<u64>,
    /// The largest glTF JSON the same budget lets the import parse (its parsed forms take ~16 bytes a
    /// byte: `preprocess::memory::max_json_bytes`): a larger one is refused before it is parsed
    /// ([`SceneError::OverJsonBudget`]), and a smaller one leaves `max_triangles` its share (the two
    /// limits are of one budget, so JSON of half the largest leaves half the triangles). 40,000 one-quad
    /// primitives (21.5 MB of JSON, 80,000 triangles) peaked at 357 MiB where the model said 84 (fault
    /// hunt, session 32). `None`: no limit.
    pub max_json_bytes: Option<u64>,
    /// The most bytes of scene input the budget lets the import read: the glTF or GLB file and the
    /// buffers its JSON names, each held whole while the geometry is read (a one-quad scene naming a
    /// 1.5 GiB buffer was accepted at 300 MiB and peaked at 1.5 GiB: fault hunt, session 35). Checked
    /// on the file's length before it is read and on the buffers' `byteLength` before they are.
    /// `None`: no limit.
    pub max_input_bytes: Option<u64>,
}

/// The bytes of the external buffers (not `data:` URIs, which are in the JSON, nor a GLB's BIN chunk, in
/// the file) that some buffer view names, by their `byteLength`: what the import may read besides the
/// file (`Buffers` loads a buffer when a view of it is read; one no view names is never read).
fn read_buffer_bytes(value: &serde_json::Value) -> u64 {
    let viewed: std::collections::BTreeSet<u64> = (value.get("bufferViews"))
        .and_then(|v| v.as_array())
        .into_iter()
        .flatten()
        .filter_map(|v| v.get("buffer").and_then(serde_json::Value::as_u64))
        .collect();
    (value
        .get("buffers")
        .and_then(|b| b.as_array())
        .into_iter()
        .flatten())
    .enumerate()
    .filter(|(i, _)| viewed.contains(&(*i as u64)))
    .filter(|(_, b)| {
        (b.get("uri").and_then(|u| u.as_str())).is_some_and(|u| !u.starts_with("data:"))
    })
    .filter_map(|(_, b)| b.get("byteLength").and_then(serde_json::Value::as_u64))
    .fold(0u64, u64::saturating_add)
}

/// The length of the scene file at `path`, refused ([`SceneError::OverInputBudget`]) where it passes
/// `max` before a byte is read: the import and a planned shard's image import each read it whole.
pub(super) fn check_file_len(path: &Path, file: &str, max: Option<u64>) -> Result<u64, SceneError> {
    // A directory or device is not counted (its length is no input): the read that follows names it
    // (a directory was refused as "reading 4.00 KiB of scene input" under a small budget).
    let len = (std::fs::metadata(path).ok())
        .filter(|m| m.is_file())
        .map_or(0, |m| m.len());
    check_input_bytes(file, len, max, "the file")?;
    Ok(len)
}

/// [`SceneError::OverInputBudget`] where `bytes` of input pass `max`.
fn check_input_bytes(
    file: &str,
    bytes: u64,
    max: Option<u64>,
    what: &'static str,
) -> Result<(), SceneError> {
    match max {
        Some(max) if bytes > max => Err(SceneError::OverInputBudget {
            file: file.to_string(),
            bytes,
            max,
            what,
        }),
        _ => Ok(()),
    }
}

/// The bytes of `json` as the memory budget weighs them: a byte inside a `data:` URI (an embedded
/// buffer or image, base64: its text, one string and the decoded bytes) costs about a quarter of a byte
/// of JSON structure (its parsed forms), so it counts a quarter (the review of session 32: embedded
/// buffers were refused at 16 bytes a byte).
fn json_weight(json: &[u8]) -> u64 {
    const OPEN: &[u8] = b"\"data:";
    let mut data = 0u64;
    let mut at = 0;
    while let Some(start) = json[at..].windows(OPEN.len()).position(|w| w == OPEN) {
        let from = at + start + 1;
        let len = json[from..]
            .iter()
            .position(|&b| b == b'"')
            .unwrap_or(json.len() - from);
        data += len as u64;
        at = from + len;
    }
    json.len() as u64 - data * 3 / 4
}

/// `max_triangles` less the share of the budget `json_bytes` of JSON take, where both limits are given
/// ([`ImportOptions::max_json_bytes`]).
fn triangles_beside_json(
    max_triangles: Option<u64>,
    max_json_bytes: Option<u64>,
    json_bytes: u64,
) -> Option<u64> {
    match (max_triangles, max_json_bytes) {
        (Some(t), Some(j)) if j > 0 => {
            let left = u128::from(j.saturating_sub(json_bytes));
            Some((u128::from(t) * left / u128::from(j)) as u64)
        }
        (t, _) => t,
    }
}

/// Imports a `.gltf` (external files and/or data URIs) or `.glb` file into a world-space [`Scene`].
///
/// The default scene is walked (all root nodes if there is none); every mesh instance (node, and
/// `EXT_mesh_gpu_instancing` instance) becomes distinct vertices and triangles. See the module docs for
/// the error/warning policy.
pub fn import(path: &Path, opts: &ImportOptions) -> Result<Scene, SceneError> {
    let file = path.display().to_string();
    // The JSON is checked before gltf sees it (`refs`), so no known input panics in it; a panic that
    // is left (in gltf, gltf-json or the importer itself) becomes an error naming the file.
    catch_unwind(AssertUnwindSafe(|| import_unguarded(path, opts, &file))).unwrap_or_else(
        |payload| {
            Err(SceneError::Internal {
                file: file.clone(),
                stage: "reading the document",
                message: panic_message(payload.as_ref()),
            })
        },
    )
}

/// [`import`] without the panic guard.
fn import_unguarded(path: &Path, opts: &ImportOptions, file: &str) -> Result<Scene, SceneError> {
    let file = file.to_string();
    let file_len = check_file_len(path, &file, opts.max_input_bytes)?;
    let bytes = crate::util::read_regular(path, None).map_err(|source| SceneError::Io {
        file: file.clone(),
        source,
    })?;
    let (json_bytes, blob) = split_glb(bytes, &file)?;
    let json_len = json_weight(&json_bytes);
    if let Some(max) = opts.max_json_bytes.filter(|&max| json_len > max) {
        return Err(SceneError::OverJsonBudget {
            file,
            json_bytes: json_len,
            max,
        });
    }
    let value: serde_json::Value =
        serde_json::from_slice(&json_bytes).map_err(|e| SceneError::Parse {
            file: file.clone(),
            reason: with_json_context(&e, &json_bytes),
        })?;
    refs::check_indices(&value, &file)?;
    let named = read_buffer_bytes(&value);
    let what = "the file and the buffers it names";
    check_input_bytes(
        &file,
        file_len.saturating_add(named),
        opts.max_input_bytes,
        what,
    )?;
    let (doc, tolerated) =
        catch_unwind(|| parse_document(&json_bytes, &file)).unwrap_or_else(|payload| {
            Err(SceneError::Internal {
                file: file.clone(),
                stage: "parsing and validating the JSON",
                message: panic_message(payload.as_ref()),
            })
        })?;
    let raw: RawRoot = serde_json::from_value(value).map_err(|e| SceneError::Parse {
        file: file.clone(),
        reason: format!("raw JSON: {e}"),
    })?;
    let base_dirs = uri::scene_dirs(path);
    let mut report = ImportReport::default();
    for w in tolerated {
        report.warn(w);
    }
    warnings::warn_undrawn_features(&file, &doc, &mut report);
    let accessors: Vec<gltf::Accessor> = doc.accessors().collect();
    let mut buffers = Buffers::new(&file, base_dirs, &doc, blob);
    let mut walk = Walk {
        file: &file,
        doc: &doc,
        raw: &raw.nodes,
        accessors: &accessors,
        buffers: &mut buffers,
        report: &mut report,
        max_triangles: triangles_beside_json(opts.max_triangles, opts.max_json_bytes, json_len),
        json_bytes: json_len,
    };
    walk.warn_invalid_matrices();
    let instances = walk.instances()?;
    let mut geometry = Geometry::new(&file, &doc, &accessors, raw.meshes);
    geometry.reserve(&instances)?;
    let mut materials = Materials::new(&file, &doc, raw.materials, raw.textures);
    for inst in &instances {
        geometry.emit_instance(inst, &mut materials, &mut buffers, &mut report)?;
    }
    Ok(finish(path, opts, geometry, materials, report))
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
            reason: typed_json_error(&e, json),
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
        // glTF 2.0 §3.6.2.1: an accessor without a buffer view (and without sparse) is all zeros — an
        // exporter's zero morph-target deltas; the schema check reported it missing and the whole file
        // was refused (fault hunt, session 32). The readers zero-fill it.
        let zeros = p.starts_with("accessors[") && p.ends_with("].bufferView");
        if zeros && matches!(error, VError::Missing) {
            return;
        }
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

/// `e` with the JSON text where it was found: serde's messages name a line and column only, and
/// some say little on their own ("trailing characters" for a KHR_texture_transform `scale` of three
/// numbers: fault hunt, session 35), where the text shows the field.
pub(super) fn with_json_context(e: &serde_json::Error, json: &[u8]) -> String {
    let line_start = (json.split_inclusive(|&b| b == b'\n'))
        .take(e.line().saturating_sub(1))
        .map(<[u8]>::len)
        .sum::<usize>();
    let at = (line_start + e.column().saturating_sub(1)).min(json.len());
    let (mut from, mut to) = (at.saturating_sub(48), (at + 16).min(json.len()));
    // Whole characters: not from or to the middle of a multi-byte one.
    let continuation = |i: usize| json.get(i).is_some_and(|&b| b & 0xc0 == 0x80);
    while from < at && continuation(from) {
        from += 1;
    }
    while to > at && continuation(to) {
        to -= 1;
    }
    let text = String::from_utf8_lossy(&json[from..to]);
    let text: String = (text.chars())
        .map(|c| if c.is_control() { ' ' } else { c })
        .collect();
    if text.trim().is_empty() {
        return e.to_string();
    }
    format!("{e}, in `{}`", text.trim())
}

/// [`with_json_context`] for the typed parse, which runs on JSON the untyped parse read whole: serde's
/// "trailing characters" there is an array longer than its field takes (a `scale` of three numbers),
/// not text after the JSON.
fn typed_json_error(e: &serde_json::Error, json: &[u8]) -> String {
    let context = with_json_context(e, json);
    if e.to_string().starts_with("trailing characters") {
        format!("more items than the field takes ({context})")
    } else {
        context
    }
}

/// The raw JSON fields read in f64 (gltf-json keeps transforms and KHR_texture_transform as f32).
#[derive(Deserialize, Default)]
struct RawRoot {
    #[serde(default)]
    nodes: Vec<RawNode>,
    #[serde(default)]
    materials: Vec<RawMaterial>,
    #[serde(default)]
    textures: Vec<RawTexture>,
    #[serde(default)]
    meshes: Vec<mesh::RawMesh>,
}

/// The scene of the built geometry and materials: closes the warning list ("... and N more") and picks
/// the up axis.
fn finish(
    path: &Path,
    opts: &ImportOptions,
    geometry: Geometry,
    materials: Materials,
    mut report: ImportReport,
) -> Scene {
    report.close_warnings();
    let mut scene = Scene {
        source: path.to_path_buf(),
        up: UpAxis::Y,
        vertices: geometry.vertices,
        triangles: geometry.triangles,
        materials: materials.materials,
        images: materials.images,
        report,
    };
    scene.up = opts.up.unwrap_or_else(|| auto_up(scene.bounds()));
    scene
}

/// Auto up axis: the axis of least extent of `bounds` where it is clearly the least (under half of
/// the next least: a Z-up city, a landscape), else Y, glTF's own convention (a tower on a square plot,
/// whose two ground axes tie, was laid on its side: fault hunt, session 33). Y for no bounds.
pub(super) fn auto_up(bounds: Option<(DVec3, DVec3)>) -> UpAxis {
    let Some((lo, hi)) = bounds else {
        return UpAxis::Y;
    };
    let e = hi - lo;
    let mut axes = [(UpAxis::Y, e.y), (UpAxis::Z, e.z), (UpAxis::X, e.x)];
    // Stable: equal extents keep the order Y, Z, X.
    axes.sort_by(|a, b| a.1.total_cmp(&b.1));
    let [(least, extent), (_, next), _] = axes;
    if least == UpAxis::Y || extent < 0.5 * next {
        least
    } else {
        UpAxis::Y
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn data_uris_weigh_a_quarter_in_the_json_budget() {
        let plain = br#"{"buffers":[{"uri":"a.bin"}]}"#;
        assert_eq!(json_weight(plain), plain.len() as u64);
        let data = format!(r#"{{"uri":"data:{}"}}"#, "A".repeat(995));
        // 1000 bytes inside the URI (from `data:`), 3/4 of them taken off.
        assert_eq!(json_weight(data.as_bytes()), data.len() as u64 - 750);
        // An unterminated URI counts to the end: 9 bytes from `data:`, 6 of them taken off.
        let open = br#"{"uri":"data:AAAA"#;
        assert_eq!(json_weight(open), open.len() as u64 - 6);
        assert_eq!(triangles_beside_json(Some(100), Some(1000), 500), Some(50));
        assert_eq!(triangles_beside_json(Some(100), Some(1000), 5000), Some(0));
        assert_eq!(triangles_beside_json(Some(100), None, 5000), Some(100));
        assert_eq!(triangles_beside_json(None, Some(1000), 5), None);
    }

    /// A typed parse error shows the JSON around its line and column (the second line here), so a
    /// `scale` of three numbers is named where serde says only "trailing characters".
    #[test]
    fn a_parse_error_shows_the_json_where_it_was_found() {
        let json =
            b"{\"asset\": {\"version\": \"2.0\"},\n \"materials\": [{\"pbrMetallicRoughness\": \
            {\"baseColorTexture\": {\"index\": 0, \"extensions\": {\"KHR_texture_transform\": \
            {\"scale\": [1, 2, 3]}}}}}]}";
        let e = parse_document(json, "s.gltf").err().unwrap().to_string();
        assert!(
            e.contains("more items than the field takes (trailing characters at line 2 column")
                && e.contains(r#"{"scale": [1, 2, 3]"#),
            "{e}"
        );
    }

    /// The text shown keeps whole characters: a window edge inside a multi-byte one moves off it.
    #[test]
    fn the_json_context_keeps_whole_characters() {
        // Keys of two lengths: the window's start falls on each byte of a two-byte `é`.
        for key in ["x", "xy"] {
            let json = format!("{{\"name\": \"{}\", \"{key}\": tru}}", "é".repeat(40));
            let e = serde_json::from_slice::<serde_json::Value>(json.as_bytes()).unwrap_err();
            let shown = with_json_context(&e, json.as_bytes());
            assert!(shown.contains("tru") && shown.contains("éé"), "{shown}");
            assert!(!shown.contains('\u{fffd}'), "{shown}");
        }
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
            auto_up(Some((DVec3::ZERO, DVec3::new(0.4, 1.0, 10.0)))),
            UpAxis::X
        );
        assert_eq!(auto_up(Some((DVec3::ZERO, DVec3::ONE))), UpAxis::Y);
        // Not clearly least (at least half the next least): glTF's Y. A 300 m tower on a 50 × 50 m
        // plot was laid on its side (Z); a 60 × 50 m plot too.
        let up = |x: f64, y: f64, z: f64| auto_up(Some((DVec3::ZERO, DVec3::new(x, y, z))));
        assert_eq!(up(0.5, 1.0, 10.0), UpAxis::Y);
        assert_eq!(up(50.0, 300.0, 50.0), UpAxis::Y);
        assert_eq!(up(60.0, 300.0, 50.0), UpAxis::Y);
        assert_eq!(up(1000.0, 1000.0, 50.0), UpAxis::Z);
    }
}
