//! What a shard of a planned build reads of the scene (issue 22): its images, named by the plan, without
//! a single vertex; and the digest of the scene input that keys a plan to the files it was made from.

use super::materials::image_or_fallback;
use super::uri::{Buffers, local_path_in, split_glb};
use super::{SceneError, parse_document, refs};
use crate::scene::{ImageRef, ImageSource, ImportReport};
use crate::util::panic_message;
use std::io::Read;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

/// The images `refs` of the glTF scene at `path`, in order, read exactly as [`super::import`] reads them
/// (headers only; a glTF image that cannot be read becomes the fallback checker, counted in the report),
/// without reading any geometry: a `.gltf` loads only the buffers that hold images, a `.glb` is read
/// whole (its BIN chunk holds them). The file is refused before it is read where its length passes
/// `max_input_bytes` (`ImportOptions::max_input_bytes`: a planned shard of a GLB with a 1.5 GiB BIN chunk
/// was accepted at 300 MiB; fault hunt, session 35).
pub fn import_images(
    path: &Path,
    refs: &[ImageRef],
    max_input_bytes: Option<u64>,
) -> Result<(Vec<ImageSource>, ImportReport), SceneError> {
    let file = path.display().to_string();
    super::check_file_len(path, &file, max_input_bytes)?;
    catch_unwind(AssertUnwindSafe(|| images_unguarded(path, refs, &file))).unwrap_or_else(
        |payload| {
            Err(SceneError::Internal {
                file: file.clone(),
                stage: "reading the images",
                message: panic_message(payload.as_ref()),
            })
        },
    )
}

fn images_unguarded(
    path: &Path,
    wanted: &[ImageRef],
    file: &str,
) -> Result<(Vec<ImageSource>, ImportReport), SceneError> {
    let bytes = crate::util::read_regular(path, None).map_err(|source| SceneError::Io {
        file: file.to_string(),
        source,
    })?;
    let (json_bytes, blob) = split_glb(bytes, file)?;
    let value: serde_json::Value =
        serde_json::from_slice(&json_bytes).map_err(|e| SceneError::Parse {
            file: file.to_string(),
            reason: super::with_json_context(&e, &json_bytes),
        })?;
    refs::check_indices(&value, file)?;
    let (doc, _) = parse_document(&json_bytes, file)?;
    let base_dirs = super::uri::scene_dirs(path);
    let mut buffers = Buffers::new(file, base_dirs, &doc, blob);
    let mut report = ImportReport::default();
    let mut images = Vec::with_capacity(wanted.len());
    // A glTF image drawn by OPAQUE and alpha materials is named twice (`Materials::image_for`): read once.
    let mut read: std::collections::HashMap<u32, ImageSource> = std::collections::HashMap::new();
    for r in wanted {
        let image = match *r {
            ImageRef::Solid(rgba) => ImageSource::solid(rgba),
            ImageRef::Gltf(i) => match read.get(&i) {
                Some(known) => known.clone(),
                None => {
                    let img = doc.images().nth(i as usize).ok_or_else(|| SceneError::Parse {
                        file: file.to_string(),
                        reason: format!(
                            "the plan names glTF image {i}, the file has {}: was the scene changed after the plan?",
                            doc.images().len()
                        ),
                    })?;
                    let image = image_or_fallback(file, &img, &mut buffers, &mut report)?;
                    read.insert(i, image.clone());
                    image
                }
            },
        };
        images.push(image);
    }
    report.close_warnings();
    Ok((images, report))
}

/// `xxh3_128` of the scene input a plan is made from: the glTF file's bytes and, in order, those of every
/// buffer it names by a relative URI (data URIs are inside the file). Image files are not read here (a
/// shard checks their identities, as a merge does). Files are streamed, never held.
pub fn input_digest(path: &Path) -> Result<[u64; 2], SceneError> {
    let file = path.display().to_string();
    let io = |source| SceneError::Io {
        file: file.clone(),
        source,
    };
    let mut hasher = xxhash_rust::xxh3::Xxh3::new();
    stream_into(&mut hasher, path).map_err(io)?;
    let json = json_chunk(path).map_err(io)?;
    let value: serde_json::Value =
        serde_json::from_slice(&json).map_err(|e| SceneError::Parse {
            file: file.clone(),
            reason: super::with_json_context(&e, &json),
        })?;
    let base_dirs = super::uri::scene_dirs(path);
    let uris = (value
        .get("buffers")
        .and_then(|b| b.as_array())
        .into_iter()
        .flatten())
    .filter_map(|b| b.get("uri").and_then(|u| u.as_str()))
    .filter(|u| !u.starts_with("data:"));
    for (i, uri) in uris.enumerate() {
        let buffer_err = |reason| SceneError::Buffer {
            file: file.clone(),
            buffer: i,
            uri: uri.to_string(),
            reason,
        };
        let buffer = local_path_in(&base_dirs, uri).map_err(buffer_err)?;
        hasher.update(format!("|buffer {i}|").as_bytes());
        stream_into(&mut hasher, &buffer)
            .map_err(|source| buffer_err(format!("{}: {source}", buffer.display())))?;
    }
    Ok(crate::util::digest_words(hasher.digest128()))
}

/// Feeds the file at `path` to `hasher` in 1 MiB reads.
fn stream_into(hasher: &mut xxhash_rust::xxh3::Xxh3, path: &Path) -> std::io::Result<()> {
    let mut f = crate::util::open_regular(path)?;
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            return Ok(());
        }
        hasher.update(&buf[..n]);
    }
}

/// The JSON of a `.gltf`, or the JSON chunk of a `.glb` (read by its header, not the whole file).
fn json_chunk(path: &Path) -> std::io::Result<Vec<u8>> {
    let mut f = crate::util::open_regular(path)?;
    let mut head = [0u8; 20];
    let n = read_up_to(&mut f, &mut head)?;
    if n < 20 || &head[..4] != b"glTF" {
        // As the import reads it (`uri::split_glb`): a byte-order mark before the JSON is no error.
        let mut bytes = crate::util::read_regular(path, None)?;
        super::uri::strip_bom(&mut bytes);
        return Ok(bytes);
    }
    let len = u64::from(u32::from_le_bytes([head[12], head[13], head[14], head[15]]));
    if len > f.metadata()?.len() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("GLB JSON chunk of {len} bytes is longer than the file"),
        ));
    }
    let mut json = vec![0u8; len as usize];
    f.read_exact(&mut json)?;
    let text = super::uri::glb_json_text(&json)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e))?;
    Ok(text.to_vec())
}

fn read_up_to(f: &mut std::fs::File, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match f.read(&mut buf[n..])? {
            0 => break,
            k => n += k,
        }
    }
    Ok(n)
}
