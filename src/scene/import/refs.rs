//! Every index one glTF object gives to another, checked in the raw JSON before gltf-json sees it.
//!
//! gltf-json 1.4.1 deserialises an index into any u32 and its validation reads
//! `root.accessors[POSITION]` before it bounds-checks that index (`mesh.rs:151`), so a file with
//! `"POSITION": 2147483648` panics inside the dependency. [`check_indices`] walks the parsed
//! [`serde_json::Value`] first and turns every reference that is not a whole number, or that names an
//! object that does not exist, into a [`SceneError::BadIndex`] / [`SceneError::NotAnIndex`] carrying the
//! JSON path, e.g. `scene.gltf: meshes[5].primitives[0].attributes.POSITION = 2147483648: no accessor
//! 2147483648 (there are 348)`.
//!
//! Only references found where the schema puts them are checked; a container of the wrong JSON type
//! (an object where an array belongs) is left to gltf-json's schema errors. The rules cover glTF 2.0
//! core (scenes, nodes, meshes, primitives and morph targets, skins, animations, accessors and sparse
//! accessors, buffer views, images, textures, materials) and the extensions that hold indices:
//! `EXT_mesh_gpu_instancing`, `KHR_materials_variants`, `KHR_lights_punctual`, the texture-source
//! extensions (`KHR_texture_basisu`, `EXT_texture_webp`, …) and every material texture reference
//! (`*Texture.index`, core or extension, e.g. `KHR_materials_clearcoat`).

use crate::scene::error::SceneError;
use serde_json::Value;

/// One step of a rule's JSON path.
#[derive(Clone, Copy)]
enum Step {
    /// An object field.
    Field(&'static str),
    /// Every element of an array.
    Each,
    /// Every value of an object (attribute maps).
    Values,
}

use Step::{Each, Field, Values};

/// Where the referenced objects live.
#[derive(Clone, Copy)]
enum Target {
    /// A top-level array (`"accessors"`), named in the singular in messages (`"accessor"`).
    Root(&'static str, &'static str),
    /// An array under the top-level `extensions` object: (extension, array, singular).
    RootExt(&'static str, &'static str, &'static str),
    /// `samplers` of the animation the reference sits in (channel → sampler).
    AnimationSampler,
}

/// (path from the root, target). A path ending in [`Each`] or [`Values`] checks every element.
const RULES: &[(&[Step], Target)] = &[
    (&[Field("scene")], Target::Root("scenes", "scene")),
    (
        &[Field("scenes"), Each, Field("nodes"), Each],
        Target::Root("nodes", "node"),
    ),
    (
        &[Field("nodes"), Each, Field("children"), Each],
        Target::Root("nodes", "node"),
    ),
    (
        &[Field("nodes"), Each, Field("mesh")],
        Target::Root("meshes", "mesh"),
    ),
    (
        &[Field("nodes"), Each, Field("camera")],
        Target::Root("cameras", "camera"),
    ),
    (
        &[Field("nodes"), Each, Field("skin")],
        Target::Root("skins", "skin"),
    ),
    (
        &[
            Field("nodes"),
            Each,
            Field("extensions"),
            Field("EXT_mesh_gpu_instancing"),
            Field("attributes"),
            Values,
        ],
        Target::Root("accessors", "accessor"),
    ),
    (
        &[
            Field("nodes"),
            Each,
            Field("extensions"),
            Field("KHR_lights_punctual"),
            Field("light"),
        ],
        Target::RootExt("KHR_lights_punctual", "lights", "KHR_lights_punctual light"),
    ),
    (
        &[
            Field("meshes"),
            Each,
            Field("primitives"),
            Each,
            Field("attributes"),
            Values,
        ],
        Target::Root("accessors", "accessor"),
    ),
    (
        &[
            Field("meshes"),
            Each,
            Field("primitives"),
            Each,
            Field("indices"),
        ],
        Target::Root("accessors", "accessor"),
    ),
    (
        &[
            Field("meshes"),
            Each,
            Field("primitives"),
            Each,
            Field("material"),
        ],
        Target::Root("materials", "material"),
    ),
    (
        &[
            Field("meshes"),
            Each,
            Field("primitives"),
            Each,
            Field("targets"),
            Each,
            Values,
        ],
        Target::Root("accessors", "accessor"),
    ),
    (
        &[
            Field("meshes"),
            Each,
            Field("primitives"),
            Each,
            Field("extensions"),
            Field("KHR_materials_variants"),
            Field("mappings"),
            Each,
            Field("material"),
        ],
        Target::Root("materials", "material"),
    ),
    (
        &[
            Field("meshes"),
            Each,
            Field("primitives"),
            Each,
            Field("extensions"),
            Field("KHR_materials_variants"),
            Field("mappings"),
            Each,
            Field("variants"),
            Each,
        ],
        Target::RootExt(
            "KHR_materials_variants",
            "variants",
            "KHR_materials_variants variant",
        ),
    ),
    (
        &[Field("skins"), Each, Field("inverseBindMatrices")],
        Target::Root("accessors", "accessor"),
    ),
    (
        &[Field("skins"), Each, Field("joints"), Each],
        Target::Root("nodes", "node"),
    ),
    (
        &[Field("skins"), Each, Field("skeleton")],
        Target::Root("nodes", "node"),
    ),
    (
        &[
            Field("animations"),
            Each,
            Field("channels"),
            Each,
            Field("target"),
            Field("node"),
        ],
        Target::Root("nodes", "node"),
    ),
    (
        &[
            Field("animations"),
            Each,
            Field("channels"),
            Each,
            Field("sampler"),
        ],
        Target::AnimationSampler,
    ),
    (
        &[
            Field("animations"),
            Each,
            Field("samplers"),
            Each,
            Field("input"),
        ],
        Target::Root("accessors", "accessor"),
    ),
    (
        &[
            Field("animations"),
            Each,
            Field("samplers"),
            Each,
            Field("output"),
        ],
        Target::Root("accessors", "accessor"),
    ),
    (
        &[Field("accessors"), Each, Field("bufferView")],
        Target::Root("bufferViews", "buffer view"),
    ),
    (
        &[
            Field("accessors"),
            Each,
            Field("sparse"),
            Field("indices"),
            Field("bufferView"),
        ],
        Target::Root("bufferViews", "buffer view"),
    ),
    (
        &[
            Field("accessors"),
            Each,
            Field("sparse"),
            Field("values"),
            Field("bufferView"),
        ],
        Target::Root("bufferViews", "buffer view"),
    ),
    (
        &[Field("bufferViews"), Each, Field("buffer")],
        Target::Root("buffers", "buffer"),
    ),
    (
        &[Field("images"), Each, Field("bufferView")],
        Target::Root("bufferViews", "buffer view"),
    ),
    (
        &[Field("textures"), Each, Field("source")],
        Target::Root("images", "image"),
    ),
    (
        &[Field("textures"), Each, Field("sampler")],
        Target::Root("samplers", "sampler"),
    ),
    (
        &[
            Field("textures"),
            Each,
            Field("extensions"),
            Values,
            Field("source"),
        ],
        Target::Root("images", "image"),
    ),
];

/// A JSON path as glTF validators print it: `meshes[5].primitives[0].attributes.POSITION`.
#[derive(Clone, Default)]
struct JsonPath(String);

impl JsonPath {
    fn field(&self, name: &str) -> JsonPath {
        if self.0.is_empty() {
            JsonPath(name.to_string())
        } else {
            JsonPath(format!("{}.{name}", self.0))
        }
    }
    fn index(&self, i: usize) -> JsonPath {
        JsonPath(format!("{}[{i}]", self.0))
    }
}

/// Checks every index of the glTF JSON `root` (see the module docs); `file` names the file in errors.
/// The first bad reference is the error.
pub(super) fn check_indices(root: &Value, file: &str) -> Result<(), SceneError> {
    check_version(root, file)?;
    let mut check = Check { root, file };
    for (steps, target) in RULES {
        check.walk(root, steps, JsonPath::default(), None, *target)?;
    }
    if let Some(materials) = root.get("materials").and_then(Value::as_array) {
        let path = JsonPath::default().field("materials");
        for (i, m) in materials.iter().enumerate() {
            check.material_textures(m, path.index(i), 0)?;
        }
    }
    Ok(())
}

/// Refuses a document that is not glTF 2.0: `asset.version` of another major version (1.x keys its
/// scenes, meshes and materials by name, so every later check would report its references as "not an
/// index"; "3.0" was read as 2.0 silently), or an `asset.minVersion` above 2.0 (the asset says it needs a
/// newer reader). A missing version is left to the parser.
fn check_version(root: &Value, file: &str) -> Result<(), SceneError> {
    let asset = root.get("asset");
    let field = |name| asset.and_then(|a| a.get(name)).and_then(Value::as_str);
    let major_minor = |v: &str| {
        let mut parts = v.split('.').map(|p| p.parse::<u64>().ok());
        (parts.next().flatten(), parts.next().flatten().unwrap_or(0))
    };
    let refuse = |v: &str| {
        Err(SceneError::UnsupportedVersion {
            file: file.to_string(),
            version: v.to_string(),
        })
    };
    if let Some(v) = field("version")
        && major_minor(v).0.is_some_and(|major| major != 2)
    {
        return refuse(v);
    }
    if let Some(v) = field("minVersion")
        && let (Some(major), minor) = major_minor(v)
        && (major, minor) > (2, 0)
    {
        return refuse(&format!("{v} (asset.minVersion)"));
    }
    Ok(())
}

/// Material texture references are found by name (`baseColorTexture`, `KHR_materials_clearcoat`'s
/// `clearcoatTexture`, …) to this depth below a material.
const MATERIAL_DEPTH: usize = 4;

struct Check<'a> {
    root: &'a Value,
    file: &'a str,
}

impl Check<'_> {
    /// Follows `steps` from `v` (at `path`); `animation` is the index of the animation passed through.
    fn walk(
        &mut self,
        v: &Value,
        steps: &[Step],
        path: JsonPath,
        animation: Option<usize>,
        target: Target,
    ) -> Result<(), SceneError> {
        let Some((step, rest)) = steps.split_first() else {
            return self.reference(v, &path, animation, target);
        };
        match step {
            Field(name) => match v.as_object().and_then(|o| o.get(*name)) {
                Some(child) => self.walk(child, rest, path.field(name), animation, target),
                None => Ok(()),
            },
            Each => {
                let Some(items) = v.as_array() else {
                    return Ok(());
                };
                let is_animation = path.0 == "animations";
                for (i, item) in items.iter().enumerate() {
                    let a = if is_animation { Some(i) } else { animation };
                    self.walk(item, rest, path.index(i), a, target)?;
                }
                Ok(())
            }
            Values => {
                let Some(map) = v.as_object() else {
                    return Ok(());
                };
                for (key, item) in map {
                    self.walk(item, rest, path.field(key), animation, target)?;
                }
                Ok(())
            }
        }
    }

    /// Every `*Texture` object's `index` below material JSON `v`.
    fn material_textures(
        &mut self,
        v: &Value,
        path: JsonPath,
        depth: usize,
    ) -> Result<(), SceneError> {
        let Some(map) = v.as_object() else {
            return Ok(());
        };
        for (key, child) in map {
            // Application data and extensions the gltf crate does not read can name anything: only the
            // core material and the KHR extensions it parses are checked.
            if key == "extras" {
                continue;
            }
            let here = path.field(key);
            if key == "extensions" {
                if let (Some(exts), true) = (child.as_object(), depth < MATERIAL_DEPTH) {
                    for (name, ext) in exts.iter().filter(|(name, _)| name.starts_with("KHR_")) {
                        self.material_textures(ext, here.field(name), depth + 1)?;
                    }
                }
                continue;
            }
            if key.ends_with("Texture") && child.is_object() {
                if let Some(index) = child.get("index") {
                    self.reference(
                        index,
                        &here.field("index"),
                        None,
                        Target::Root("textures", "texture"),
                    )?;
                }
            } else if depth < MATERIAL_DEPTH && child.is_object() {
                self.material_textures(child, here, depth + 1)?;
            }
        }
        Ok(())
    }

    /// The number of objects `target` can name, and their singular noun.
    fn available(&self, animation: Option<usize>, target: Target) -> (usize, String) {
        let len = |v: Option<&Value>| v.and_then(Value::as_array).map_or(0, Vec::len);
        match target {
            Target::Root(array, noun) => (len(self.root.get(array)), noun.to_string()),
            Target::RootExt(ext, array, noun) => (
                len(self
                    .root
                    .get("extensions")
                    .and_then(|e| e.get(ext))
                    .and_then(|e| e.get(array))),
                noun.to_string(),
            ),
            Target::AnimationSampler => {
                let samplers = animation.and_then(|a| {
                    self.root
                        .get("animations")
                        .and_then(|v| v.get(a))
                        .and_then(|v| v.get("samplers"))
                });
                (len(samplers), "animation sampler".to_string())
            }
        }
    }

    /// Checks one reference `v` at `path`.
    fn reference(
        &mut self,
        v: &Value,
        path: &JsonPath,
        animation: Option<usize>,
        target: Target,
    ) -> Result<(), SceneError> {
        let Some(index) = v.as_u64() else {
            return Err(SceneError::NotAnIndex {
                file: self.file.to_string(),
                path: path.0.clone(),
                value: short(v),
            });
        };
        let (count, noun) = self.available(animation, target);
        if usize::try_from(index).is_ok_and(|i| i < count) {
            return Ok(());
        }
        Err(SceneError::BadIndex {
            file: self.file.to_string(),
            path: path.0.clone(),
            index,
            what: noun,
            count,
        })
    }
}

/// `v` as JSON text, cut to 40 characters.
fn short(v: &Value) -> String {
    let s = v.to_string();
    match s.char_indices().nth(40) {
        Some((cut, _)) => format!("{}…", &s[..cut]),
        None => s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn err(v: Value) -> String {
        match check_indices(&v, "f.gltf") {
            Err(e) => e.to_string(),
            Ok(()) => "ok".into(),
        }
    }

    #[test]
    fn versions_other_than_2_are_refused() {
        for v in ["1.0", "1.0.2", "1"] {
            let doc = json!({"asset": {"version": v}, "scene": "defaultScene"});
            match check_indices(&doc, "f.gltf") {
                Err(SceneError::UnsupportedVersion { version, .. }) => assert_eq!(version, v),
                other => panic!("version {v}: {other:?}"),
            }
        }
        for v in ["2.0", "2.1"] {
            let doc = json!({"asset": {"version": v}});
            assert!(check_indices(&doc, "f.gltf").is_ok(), "version {v}");
        }
        // Another major version is no 2.x either (it was read as 2.0).
        for v in ["10.0", "3.0"] {
            let doc = json!({"asset": {"version": v}});
            let e = check_indices(&doc, "f.gltf");
            assert!(
                matches!(e, Err(SceneError::UnsupportedVersion { .. })),
                "version {v}: {e:?}"
            );
        }
    }

    #[test]
    fn paths_and_counts() {
        assert_eq!(
            err(
                json!({"accessors": [{}], "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}]})
            ),
            "ok"
        );
        assert_eq!(
            err(
                json!({"accessors": [{}], "meshes": [{"primitives": [{"attributes": {"POSITION": 1}}]}]})
            ),
            "f.gltf: meshes[0].primitives[0].attributes.POSITION = 1: no accessor 1 (there are 1)"
        );
        assert_eq!(
            err(json!({"scene": -1})),
            "f.gltf: scene = -1: not an index (a whole number from 0)"
        );
        assert_eq!(
            err(
                json!({"animations": [{"samplers": [{"input": 0, "output": 0}], "channels": [{"sampler": 1}]}],
                       "accessors": [{}]})
            ),
            "f.gltf: animations[0].channels[0].sampler = 1: no animation sampler 1 (there are 1)"
        );
        assert_eq!(
            err(
                json!({"materials": [{"extensions": {"KHR_materials_clearcoat": {"clearcoatTexture": {"index": 2}}}}]})
            ),
            "f.gltf: materials[0].extensions.KHR_materials_clearcoat.clearcoatTexture.index = 2: no texture 2 \
             (there are 0)"
        );
    }
}
