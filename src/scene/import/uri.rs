//! Where the bytes come from: the GLB container, buffers (GLB `BIN` chunk, data URIs, external files)
//! and image headers.
//!
//! [`Buffers`] loads each glTF buffer once, on first use, and checks it holds `byteLength` bytes; an
//! unreadable or short buffer is a [`SceneError::Buffer`]. Relative URIs are percent-decoded and
//! resolved against the glTF file's directory; `data:` URIs must be base64. Images are not decoded
//! here: [`Buffers::load_image`] reads only their header ([`image_source::read_header`]) and keeps the
//! path (external file) or the encoded bytes (data URI, buffer view) for the lazy decode.

use super::accessors::view_slice;
use crate::scene::error::SceneError;
use crate::scene::image_source::{self, ImageData, ImageSource};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Splits a GLB into (JSON chunk, BIN chunk); a `.gltf` is all JSON.
pub(super) fn split_glb(
    bytes: Vec<u8>,
    file: &str,
) -> Result<(Vec<u8>, Option<Vec<u8>>), SceneError> {
    if bytes.is_empty() {
        // Said as such: "starts with '', not the magic" and a JSON "EOF while parsing" read as damage.
        return Err(SceneError::Parse {
            file: file.to_string(),
            reason: "the file is empty (0 bytes): an interrupted download or copy?".to_string(),
        });
    }
    let named_glb = std::path::Path::new(file)
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"));
    if !bytes.starts_with(b"glTF") && named_glb && !looks_like_json(&bytes) {
        let magic: String = (bytes.iter().take(4))
            .map(|&b| {
                if b.is_ascii_graphic() {
                    char::from(b)
                } else {
                    '.'
                }
            })
            .collect();
        return Err(SceneError::Parse {
            file: file.to_string(),
            reason: format!(
                "GLB: the file starts with '{magic}', not the magic 'glTF' (not a GLB, or a damaged one)"
            ),
        });
    }
    if !bytes.starts_with(b"glTF") {
        let mut bytes = bytes;
        strip_bom(&mut bytes);
        return Ok((bytes, None));
    }
    // gltf 1.4.1 computes `length - 12` before comparing (an overflow, a panic in debug builds).
    let length = bytes
        .get(8..12)
        .and_then(|b| <[u8; 4]>::try_from(b).ok())
        .map(u32::from_le_bytes);
    let version = bytes
        .get(4..8)
        .and_then(|b| <[u8; 4]>::try_from(b).ok())
        .map(u32::from_le_bytes);
    if let Some(version) = version.filter(|&v| v < 2) {
        return Err(SceneError::UnsupportedVersion {
            file: file.to_string(),
            version: format!("{version}.x (GLB header version {version})"),
        });
    }
    if let Some(length) = length.filter(|&n| n < 12) {
        return Err(SceneError::Parse {
            file: file.to_string(),
            reason: format!(
                "GLB: header says the file has {length} bytes, fewer than its 12-byte header"
            ),
        });
    }
    if let Some(length) = length.filter(|&n| n as usize != bytes.len()) {
        let why = if length as usize > bytes.len() {
            "truncated?"
        } else {
            "bytes appended after it, or a corrupt header"
        };
        return Err(SceneError::Parse {
            file: file.to_string(),
            reason: format!(
                "GLB: header says the file has {length} bytes, it has {} ({why})",
                bytes.len()
            ),
        });
    }
    let glb = gltf::Glb::from_slice(&bytes).map_err(|e| SceneError::Parse {
        file: file.to_string(),
        reason: format!("GLB ({} bytes): {e}", bytes.len()),
    })?;
    let json = (glb_json_text(&glb.json))
        .map_err(|reason| SceneError::Parse {
            file: file.to_string(),
            reason,
        })?
        .to_vec();
    // The BIN chunk is most of a GLB: it stays in the file's own vector (moved to its front), not copied
    // into a second one, which doubled the import's peak (a 512 MiB chunk peaked at 1 GiB).
    let range = glb.bin.as_deref().and_then(|b| {
        let start = (b.as_ptr() as usize).checked_sub(bytes.as_ptr() as usize)?;
        (start + b.len() <= bytes.len()).then_some(start..start + b.len())
    });
    let bin = match (glb.bin, range) {
        (None, _) => None,
        (Some(_), Some(range)) => {
            let mut bin = bytes;
            bin.truncate(range.end);
            bin.drain(..range.start);
            Some(bin)
        }
        (Some(b), None) => Some(b.into_owned()),
    };
    Ok((json, bin))
}

/// The UTF-8 byte-order mark.
const BOM: &[u8] = b"\xef\xbb\xbf";

/// The JSON of a `.gltf` file: without a UTF-8 byte-order mark before it (glTF 2.0 §3.2 lets readers
/// ignore one; JSON parsers refuse it at "line 1 column 1").
pub(crate) fn json_text(bytes: &[u8]) -> &[u8] {
    bytes.strip_prefix(BOM).unwrap_or(bytes)
}

/// [`json_text`] of `bytes` in place.
pub(crate) fn strip_bom(bytes: &mut Vec<u8>) {
    let mark = bytes.len() - json_text(bytes).len();
    bytes.drain(..mark);
}

/// The JSON of a GLB's JSON chunk: [`json_text`], and the chunk's padding, which glTF 2.0 §4.4.3.2 makes
/// spaces, taken as padding where an exporter wrote NULs (were "trailing characters": fault hunt,
/// session 35); an error where nothing but padding is left. The one rule of the import, the plan key's
/// digest and the CLI's sniffing.
pub(crate) fn glb_json_text(chunk: &[u8]) -> Result<&[u8], String> {
    let json = json_text(chunk);
    let end = json
        .iter()
        .rposition(|&b| b != 0)
        .map_or(0, |last| last + 1);
    let json = &json[..end];
    if json.trim_ascii().is_empty() {
        return Err(format!(
            "GLB: its JSON chunk ({} bytes) holds no JSON, only padding",
            chunk.len()
        ));
    }
    Ok(json)
}

/// Whether `head` (a file's first bytes) starts like JSON: `{` or `[` after an optional byte-order mark
/// and white space.
pub fn looks_like_json(head: &[u8]) -> bool {
    let text = json_text(head).trim_ascii_start();
    text.starts_with(b"{") || text.starts_with(b"[")
}

/// The buffers of one glTF file, loaded lazily.
pub(super) struct Buffers<'a> {
    /// The glTF file (for error messages).
    file: &'a str,
    /// Relative URIs are resolved against these directories, the first that holds the file
    /// ([`scene_dirs`], [`local_path_in`]).
    base_dirs: Vec<PathBuf>,
    doc: &'a gltf::Document,
    /// The GLB `BIN` chunk until the buffer that uses it is loaded.
    blob: Option<Vec<u8>>,
    /// Per glTF buffer: its bytes once loaded.
    data: Vec<Option<Vec<u8>>>,
}

impl<'a> Buffers<'a> {
    pub(super) fn new(
        file: &'a str,
        base_dirs: Vec<PathBuf>,
        doc: &'a gltf::Document,
        blob: Option<Vec<u8>>,
    ) -> Self {
        Buffers {
            file,
            base_dirs,
            doc,
            blob,
            data: vec![None; doc.buffers().len()],
        }
    }

    /// The loaded buffers by glTF index (`None`: not loaded yet), as the accessor readers take them.
    pub(super) fn data(&self) -> &[Option<Vec<u8>>] {
        &self.data
    }

    /// Loads buffer `index` if not loaded yet (GLB BIN chunk, data URI or external file).
    fn load_buffer(&mut self, index: usize) -> Result<(), SceneError> {
        if self.data.get(index).is_some_and(Option::is_some) {
            return Ok(());
        }
        let buffer = self
            .doc
            .buffers()
            .nth(index)
            .ok_or_else(|| SceneError::Buffer {
                file: self.file.to_string(),
                buffer: index,
                uri: String::new(),
                reason: "no such buffer".into(),
            })?;
        let (uri, data) = match buffer.source() {
            gltf::buffer::Source::Bin => {
                // glTF 2.0 §4.4 (GLB-stored buffer): only the first buffer may use the BIN chunk.
                // Buffer 0 is loaded once, so the chunk is taken at most once.
                // EXT_meshopt_compression's placeholder: the bytes its compressed views decode into
                // (a fallback buffer without a uri). Its message was "only buffer 0 may use the GLB
                // BIN chunk" in a `.gltf` text file (fault hunt, session 37).
                let meshopt = buffer.extension_value("EXT_meshopt_compression").is_some();
                let data = match index {
                    _ if meshopt => Err(
                        "has no uri: it is EXT_meshopt_compression's placeholder for decompressed data, \
                         and atlastree does not decode EXT_meshopt_compression; write the file without \
                         mesh compression (gltfpack without -c), or with an uncompressed fallback buffer \
                         (gltfpack -cf)"
                            .into(),
                    ),
                    // Said for both forms: a `.gltf` text buffer without a uri read as a truncated GLB
                    // (fault hunt, session 32).
                    0 => self.blob.take().ok_or_else(|| {
                        "has no uri: a .gltf buffer needs one, and a GLB's first buffer its BIN chunk, \
                         which this file lacks (a GLB truncated after its JSON chunk?)"
                            .to_string()
                    }),
                    _ => Err("has no uri, and only buffer 0 may use the GLB BIN chunk".into()),
                };
                let label = if index == 0 && !meshopt {
                    "<GLB BIN chunk>"
                } else {
                    "<no uri>"
                };
                (label.to_string(), data)
            }
            gltf::buffer::Source::Uri(uri) => (
                uri_for_messages(uri),
                self.read_uri(uri, buffer.length() as u64)?,
            ),
        };
        let err = |file: &str, reason: String| SceneError::Buffer {
            file: file.to_string(),
            buffer: index,
            uri: uri.clone(),
            reason,
        };
        let data = data.map_err(|reason| err(self.file, reason))?;
        if data.len() < buffer.length() {
            let reason = format!(
                "has {} bytes, byteLength says {}",
                data.len(),
                buffer.length()
            );
            // The BIN chunk goes back: a later reader of buffer 0 (an image's view failed first, and
            // fell back) gets this error again, not "no BIN chunk".
            if index == 0 && matches!(buffer.source(), gltf::buffer::Source::Bin) {
                self.blob = Some(data);
            }
            return Err(err(self.file, reason));
        }
        if let Some(slot) = self.data.get_mut(index) {
            *slot = Some(data);
        }
        Ok(())
    }

    /// Reads a URI: `data:` (base64), or the local file [`local_path`] names (relative to the glTF file,
    /// or a `file:` URI; other schemes refused): a regular file, of which the first `length` bytes (the
    /// buffer's `byteLength`; a longer file's tail is not read).
    ///
    /// `Err` only where the open-files limit stopped it ([`SceneError::OutOfDescriptors`]): an image in a
    /// buffer of its own was drawn as the fallback (review, session 38); else its bytes or why not.
    fn read_uri(&self, uri: &str, length: u64) -> Result<Result<Vec<u8>, String>, SceneError> {
        if uri.starts_with("data:") {
            return Ok(decode_data_uri(uri));
        }
        let path = match local_path_in(&self.base_dirs, uri) {
            Ok(path) => path,
            Err(e) => return Ok(Err(e)),
        };
        match crate::util::read_regular(&path, Some(length)) {
            Ok(bytes) => Ok(Ok(bytes)),
            Err(e) => Ok(Err(format!(
                "{}: {}",
                path.display(),
                SceneError::unless_out_of_descriptors(&path, e)?
            ))),
        }
    }

    /// Loads every buffer accessor `acc` reads from (its view and sparse views).
    pub(super) fn load_accessor(&mut self, acc: &gltf::Accessor) -> Result<(), SceneError> {
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

    /// Image `img` by its header: its name and the image, or why it cannot be read (the caller draws
    /// the fallback); `Err` only where the open-files limit stopped it ([`SceneError::OutOfDescriptors`]).
    pub(super) fn load_image(
        &mut self,
        img: &gltf::Image,
    ) -> Result<(String, Result<LoadedImage, String>), SceneError> {
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
                return Ok((name, Err("neither uri nor bufferView".to_string())));
            }
        };
        match source {
            ImgSrc::Uri(uri) if uri.starts_with("data:") => {
                let name = img
                    .name()
                    .map_or_else(|| "data URI".to_string(), str::to_string);
                let res = decode_data_uri(uri).and_then(|b| from_bytes(&name, b.into()));
                Ok((name, res))
            }
            ImgSrc::Uri(uri) => {
                let rel = percent_decode(uri);
                let name = img.name().map_or_else(|| rel.clone(), str::to_string);
                let res = match local_path_in(&self.base_dirs, uri) {
                    Err(e) => Err(e),
                    Ok(path) => match crate::util::open_regular(&path) {
                        Err(e) => Err(format!(
                            "{}: {}",
                            path.display(),
                            SceneError::unless_out_of_descriptors(&path, e)?
                        )),
                        Ok(f) => image_source::read_header(std::io::BufReader::new(f))
                            .map_err(|e| format!("{}: {e}", path.display()))
                            .map(|h| from_header(&name, h, ImageData::File(path.clone()))),
                    },
                };
                Ok((name, res))
            }
            ImgSrc::View(view) => {
                let name = img
                    .name()
                    .map_or_else(|| format!("buffer view {}", view.index()), str::to_string);
                let res = match self.load_buffer(view.buffer().index()) {
                    Err(e @ SceneError::OutOfDescriptors { .. }) => return Err(e),
                    loaded => loaded,
                };
                let res = res
                    .map_err(|e| e.to_string())
                    .and_then(|()| view_slice(&self.data, &view))
                    .and_then(|bytes| from_bytes(&name, Arc::from(bytes)));
                Ok((name, res))
            }
        }
    }
}

/// An image read by its header.
pub(super) struct LoadedImage {
    pub(super) source: ImageSource,
    /// Its data look cut short ([`image_source::ImageHeader::truncated`]).
    pub(super) truncated: bool,
}

/// Where an image's bytes are.
enum ImgSrc<'a> {
    View(gltf::buffer::View<'a>),
    Uri(&'a str),
}

/// Header of encoded bytes → an `ImageSource` keeping the bytes ([`from_header`]).
fn from_bytes(name: &str, bytes: Arc<[u8]>) -> Result<LoadedImage, String> {
    let h = image_source::read_header(std::io::Cursor::new(&bytes[..]))?;
    Ok(from_header(name, h, ImageData::Bytes(bytes)))
}

/// The `ImageSource` named `name` that header `h` describes, its pixels in `data`.
fn from_header(name: &str, h: image_source::ImageHeader, data: ImageData) -> LoadedImage {
    let source = ImageSource {
        name: name.to_string(),
        width: h.width,
        height: h.height,
        has_alpha: h.has_alpha,
        color: h.color,
        data,
        gltf_image: None,
    };
    LoadedImage {
        source,
        truncated: h.truncated,
    }
}

/// The local file a (non-`data:`) URI names: a relative reference against the glTF file's folder
/// (percent-decoded), or a `file:` URI's path. Any other scheme is refused by name (`http://…` was joined
/// to the folder and reported as a missing local file).
///
/// A relative reference that names no file as written is tried as a browser reads it: without its
/// `?query` or `#fragment`, and with a Windows exporter's `\` as `/` (`tex.png?v=2` and
/// `textures\tex.png` drew the fallback; fault hunt, session 28). As written first, so a file named
/// with a `#` (`Material #25.png`) is still found.
pub(super) fn local_path(base_dir: &Path, uri: &str) -> Result<PathBuf, String> {
    let scheme = uri.split_once(':').map(|(s, _)| s).filter(|s| {
        let mut c = s.chars();
        c.next().is_some_and(|c| c.is_ascii_alphabetic())
            && c.all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
    });
    let relative = relative_file(base_dir, uri);
    match scheme {
        None => Ok(relative),
        // A one-letter "scheme" is a Windows drive; a name with an unencoded colon that exists
        // (`Material:Base.png`, as exporters write) is read as it always was.
        Some(s) if s.len() == 1 => Err(format!(
            "'{uri}' looks like a Windows path: glTF URIs are relative to the glTF file (or file:///…)"
        )),
        Some(_) if relative.is_file() => Ok(relative),
        Some(s) if s.eq_ignore_ascii_case("file") => {
            let rest = &uri[s.len() + 1..];
            // file:///abs, file://localhost/abs, file:/abs
            let path = match rest.strip_prefix("//") {
                Some(r) => r.strip_prefix("localhost").unwrap_or(r),
                None => rest,
            };
            if !path.starts_with('/') {
                return Err(format!(
                    "{uri}: a file: URI needs an absolute path (file:///…)"
                ));
            }
            Ok(decoded_path(path))
        }
        Some(s) => Err(format!(
            "the URI scheme '{s}:' is not read (local files and data: URIs are; fetch the \
             file next to the glTF and name it by a relative path)"
        )),
    }
}

/// The folders a scene's relative URIs are resolved in, in order: the scene file's, then, where the scene
/// path is a symbolic link, its target's (`ln -s city/scene.gltf link.gltf` read `link.gltf: buffer 0
/// (scene.bin): No such file or directory`; fault hunt, session 34). The link's own folder first: a
/// folder of links into a content-addressed store (a Hugging Face cache, git-annex) holds its files
/// only beside the links (review of session 34).
pub(super) fn scene_dirs(path: &Path) -> Vec<PathBuf> {
    let own = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let is_link = std::fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink());
    let target = is_link
        .then(|| std::fs::canonicalize(path).ok())
        .flatten()
        .and_then(|t| t.parent().map(Path::to_path_buf))
        .filter(|t| *t != own);
    std::iter::once(own).chain(target).collect()
}

/// [`local_path`] in the first of `dirs` ([`scene_dirs`]) that holds the file; the first folder's
/// reading (or its error: a colon-named file is read only where it exists) where none does.
pub(super) fn local_path_in(dirs: &[PathBuf], uri: &str) -> Result<PathBuf, String> {
    let Some((first, rest)) = dirs.split_first() else {
        return local_path(Path::new(""), uri);
    };
    let own = local_path(first, uri);
    if own.as_ref().is_ok_and(|p| p.is_file()) {
        return own;
    }
    rest.iter()
        .filter_map(|d| local_path(d, uri).ok())
        .find(|p| p.is_file())
        .map_or(own, Ok)
}

/// `base_dir` joined with the decoded relative reference `uri`, or with the first of its browser
/// readings that names a file ([`local_path`]); as written when none does (the error names that).
fn relative_file(base_dir: &Path, uri: &str) -> PathBuf {
    let as_written = base_dir.join(decoded_path(uri));
    if as_written.is_file() {
        return as_written;
    }
    let slashed = uri.replace('\\', "/");
    let readings = [uri, slashed.as_str()].map(|u| u.split(['?', '#']).next().unwrap_or(u));
    [slashed.as_str(), readings[0], readings[1]]
        .into_iter()
        .filter(|u| *u != uri)
        .map(|u| base_dir.join(decoded_path(u)))
        .find(|p| p.is_file())
        .unwrap_or(as_written)
}

/// The path a URI's decoded bytes name: on Unix the bytes themselves (`caf%E9.png` is the Latin-1 file
/// name `caf\xE9.png`, which a lossy UTF-8 decode could never open), elsewhere their text.
fn decoded_path(uri: &str) -> PathBuf {
    let bytes = percent_decode_bytes(uri);
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStringExt;
        PathBuf::from(std::ffi::OsString::from_vec(bytes))
    }
    #[cfg(not(unix))]
    {
        PathBuf::from(String::from_utf8_lossy(&bytes).into_owned())
    }
}

/// Decodes `%XX` escapes of a relative URI (invalid escapes are kept literally), as text for names and
/// messages (bytes that are not UTF-8 shown as U+FFFD; [`decoded_path`] keeps them).
pub(super) fn percent_decode(uri: &str) -> String {
    String::from_utf8_lossy(&percent_decode_bytes(uri)).into_owned()
}

/// The bytes `%XX` escapes of `uri` decode to (invalid escapes kept literally).
fn percent_decode_bytes(uri: &str) -> Vec<u8> {
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
    out
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

/// A URI as messages name it: a `data:` URI by its media type and length (a 2 MB embedded buffer once
/// made a 2.7 MB error message), any other as written.
fn uri_for_messages(uri: &str) -> String {
    match uri.strip_prefix("data:") {
        Some(rest) => {
            let head = rest.split(',').next().unwrap_or("");
            format!("data URI, {head}, {} characters", uri.len())
        }
        None => uri.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Relative references resolve against the folder, `file:` URIs to their absolute path; other
    /// schemes are refused by name, not joined to the folder as a local name.
    #[test]
    fn uris_resolve_to_local_files_or_are_refused_by_scheme() {
        let base = Path::new("/scenes/city");
        let ok = |uri| local_path(base, uri).unwrap();
        assert_eq!(ok("tex/a%20b.png"), Path::new("/scenes/city/tex/a b.png"));
        assert_eq!(ok("./x:y.png"), Path::new("/scenes/city/./x:y.png"));
        assert_eq!(ok("file:///data/s.bin"), Path::new("/data/s.bin"));
        assert_eq!(
            ok("FILE://localhost/data/a%23.bin"),
            Path::new("/data/a#.bin")
        );
        assert_eq!(ok("file:/data/s.bin"), Path::new("/data/s.bin"));
        let err = local_path(base, "http://127.0.0.1:9/scene.bin").unwrap_err();
        assert!(err.contains("the URI scheme 'http:' is not read"), "{err}");
        assert!(local_path(base, "file:rel.bin").is_err());
        let err = local_path(base, "C:/tex/a.png").unwrap_err();
        assert!(err.contains("looks like a Windows path"), "{err}");
        assert!(local_path(base, "s3://bucket/x.png").is_err());
    }

    /// A reference that names no file as written is tried without its query or fragment and with `\` as
    /// `/`; one that does is taken as written; Latin-1 escapes name the bytes.
    #[test]
    fn relative_references_are_read_as_a_browser_reads_them() {
        let dir = tempfile::tempdir().unwrap();
        let base = dir.path();
        std::fs::create_dir(base.join("textures")).unwrap();
        for name in ["textures/tex.png", "a.png", "b#1.png"] {
            std::fs::write(base.join(name), b"x").unwrap();
        }
        let ok = |uri| local_path(base, uri).unwrap();
        assert_eq!(ok("textures\\tex.png"), base.join("textures/tex.png"));
        assert_eq!(ok("a.png?v=2"), base.join("a.png"));
        assert_eq!(ok("a.png#layer"), base.join("a.png"));
        assert_eq!(ok("textures\\tex.png?x"), base.join("textures/tex.png"));
        assert_eq!(ok("b#1.png"), base.join("b#1.png"));
        assert_eq!(ok("missing.png?v=1"), base.join("missing.png?v=1"));
        #[cfg(unix)]
        {
            use std::os::unix::ffi::OsStrExt;
            let latin1 = std::ffi::OsStr::from_bytes(b"caf\xe9.png");
            std::fs::write(base.join(latin1), b"x").unwrap();
            assert_eq!(ok("caf%E9.png"), base.join(latin1));
        }
    }

    #[test]
    fn data_uris_are_named_by_type_and_length() {
        let uri = format!("data:application/octet-stream;base64,{}", "A".repeat(4000));
        let named = uri_for_messages(&uri);
        assert_eq!(
            named,
            "data URI, application/octet-stream;base64, 4037 characters"
        );
        assert_eq!(uri_for_messages("scene.bin"), "scene.bin");
    }

    #[test]
    fn percent_decoding() {
        assert_eq!(percent_decode("a%20b%2Fc.png"), "a b/c.png");
        assert_eq!(percent_decode("100%"), "100%");
        assert_eq!(percent_decode("%zz%4"), "%zz%4");
    }

    #[test]
    fn a_glb_1_header_is_refused_by_version() {
        // glTF 1.0 binary (KHR_binary_glTF): magic, version 1, length, content length, content format 0.
        let mut glb = b"glTF".to_vec();
        for word in [1u32, 20, 0, 0] {
            glb.extend(word.to_le_bytes());
        }
        match split_glb(glb, "f.glb") {
            Err(SceneError::UnsupportedVersion { version, .. }) => {
                assert!(version.starts_with("1.x"))
            }
            other => panic!("{other:?}"),
        }
        // Version 2 goes on to the GLB parser (which rejects this truncated file on its own terms).
        let mut glb = b"glTF".to_vec();
        for word in [2u32, 12] {
            glb.extend(word.to_le_bytes());
        }
        assert!(!matches!(
            split_glb(glb, "f.glb"),
            Err(SceneError::UnsupportedVersion { .. })
        ));
    }
}
