//! [`SceneError`]: why a scene could not be imported or an image not decoded.
//!
//! Its own file so that the importer ([`mod@super::import`]) and the lazy image decoder
//! ([`super::image_source`]) both depend on it instead of on each other. Every variant names the file
//! (or image) and, where it applies, mesh, primitive, accessor or node; the text is the user-facing
//! message.

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
    /// A reference to an object that does not exist (`path` is the JSON path of the reference).
    #[error("{file}: {path} = {index}: no {what} {index} (there are {count})")]
    BadIndex {
        file: String,
        path: String,
        index: u64,
        /// The kind of object referenced, singular ("accessor", "buffer view").
        what: String,
        count: usize,
    },
    /// A reference that is not a whole number (`value` is its JSON text, cut to 40 characters).
    #[error("{file}: {path} = {value}: not an index (a whole number from 0)")]
    NotAnIndex {
        file: String,
        path: String,
        value: String,
    },
    /// A panic inside a dependency, contained at the import boundary (`stage`: what was running).
    #[error("{file}: internal error in the gltf crate ({stage}): {message}")]
    Internal {
        file: String,
        stage: &'static str,
        message: String,
    },
    /// Not glTF 2.0: a 1.x file (`asset.version`, or the GLB header's version: its JSON layout differs
    /// from 2.0's), another major version, or an `asset.minVersion` above 2.0.
    #[error(
        "{file}: glTF {version} is not supported, only glTF 2.0: convert it or re-export it as glTF 2.0 \
         (`npx gltf-pipeline -i IN -o OUT.gltf` upgrades 1.0 files)"
    )]
    UnsupportedVersion { file: String, version: String },
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
    /// More triangles than `ImportOptions::max_triangles` (the memory budget's plan): all of them
    /// counted (the node walk goes on counting, keeping nothing), so the caller can say what is needed.
    #[error(
        "{file}: {triangles} triangles over {instances} mesh instances, more than the memory budget's plan \
         holds (room for {max} beside the process's fixed base and the {json_bytes} bytes of JSON parsed)"
    )]
    OverTriangleBudget {
        file: String,
        triangles: u64,
        /// The vertices those triangles use (at most three a triangle; an instanced mesh's per instance).
        vertices: u64,
        instances: u64,
        max: u64,
        /// The glTF JSON's length, bytes: parsing it takes its share of the budget too.
        json_bytes: u64,
    },
    /// Scene input (the file and the buffers it names) past `ImportOptions::max_input_bytes`, refused
    /// before it is read.
    #[error(
        "{file}: {bytes} bytes of scene input ({what}: each read whole), more than the memory budget \
         lets it read ({max} bytes, the budget less the process's base)"
    )]
    OverInputBudget {
        file: String,
        bytes: u64,
        max: u64,
        what: &'static str,
    },
    /// A glTF JSON larger than `ImportOptions::max_json_bytes` (the memory budget's share for parsing
    /// it), refused before it is parsed.
    #[error(
        "{file}: {json_bytes} bytes of glTF JSON (data: URIs counted at a quarter), more than the memory \
         budget lets the import parse ({max} bytes: its parsed forms take ~16 bytes a byte)"
    )]
    OverJsonBudget {
        file: String,
        json_bytes: u64,
        max: u64,
    },
    #[error("image {image}: {reason}")]
    ImageDecode { image: String, reason: String },
    /// An image file that could not be opened for the open-files limit (`EMFILE`, `ENFILE`): a limit of
    /// this machine, not a fault of the image, so the build stops instead of drawing the fallback
    /// (`util::is_out_of_descriptors`; fault hunt, session 38).
    #[error(
        "{file}: {source}: the open-files limit is too low for this build (the image is fine); raise it \
         (ulimit -n) and run again"
    )]
    OutOfDescriptors {
        file: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{0}")]
    Other(String),
}

impl SceneError {
    /// `e`, from opening or reading `path`, back for the caller's own fallback or message, unless the
    /// open-files limit caused it: then [`SceneError::OutOfDescriptors`], to stop the import or build.
    pub fn unless_out_of_descriptors(
        path: &std::path::Path,
        e: std::io::Error,
    ) -> Result<std::io::Error, SceneError> {
        if crate::util::is_out_of_descriptors(&e) {
            return Err(SceneError::OutOfDescriptors {
                file: path.display().to_string(),
                source: e,
            });
        }
        Ok(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_stays_small() {
        // clippy::result_large_err: keep `Result<_, SceneError>` cheap to return.
        assert!(
            std::mem::size_of::<SceneError>() < 128,
            "{}",
            std::mem::size_of::<SceneError>()
        );
    }
}
