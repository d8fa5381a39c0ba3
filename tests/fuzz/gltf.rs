//! Target `gltf`: structure-aware mutants of the embedded city (`data/city`: `scene.gltf`, `scene.bin`,
//! 53 PNGs) run through what `atlastree build` runs: [`atlastree::scene::import`], then
//! [`atlastree::preprocess::build`] at small settings (256² atlases, shallow tree) into a temp dir.
//!
//! A mutant is one to three edits: JSON edits ([`crate::json_mut`]: a number set to an edge value, a
//! key deleted, a type swapped, an array duplicated), edits of `scene.bin` (truncated; NaN, ∞ or huge
//! floats and other bytes poked in), edits of one image (truncated, bytes poked, IHDR size set to 0 or
//! 2³¹−1, garbage, a missing file or a broken data URI), or the whole scene packed as a GLB (its
//! header and chunk lengths poked). Verdicts: Refused on an import or build error; Accepted when both
//! succeed and the imported scene keeps its contract (finite vertices, triangle, material and image
//! indices in range), else AcceptedCorruption.
//!
//! Corpus files are seeded bytes, or edit scripts starting with [`MAGIC`] (one edit per line, e.g.
//! `set /meshes/5/primitives/0/attributes/POSITION 2147483648`, `bin-truncate 100`,
//! `image-poke 3 16 7fffffff`, `glb`, `glb-poke 12 ffffffff`, and `expect-error TEXT`).

use crate::harness::{self, Verdict};
use crate::json_mut::{self, JsonEdit, Paths};
use arbitrary::Unstructured;
use atlastree::preprocess::{BuildOptions, DMin, NoProgress, build};
use atlastree::scene::{ImportOptions, Scene, import};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Cases per CI run (see the module docs of `tests/fuzz/main.rs` for the budget).
const DEFAULT_CASES: u64 = 250;

/// First line of an edit-script corpus file.
pub const MAGIC: &str = "#gltf-edits";

/// One edit of a mutant.
#[derive(Clone, Debug, PartialEq)]
enum Edit {
    Json(JsonEdit),
    BinTruncate(usize),
    BinPoke(usize, Vec<u8>),
    ImageTruncate(usize, usize),
    ImagePoke(usize, usize, Vec<u8>),
    /// Pack the scene as a GLB (JSON chunk + `scene.bin` as the BIN chunk).
    Glb,
    /// Poke bytes into the packed GLB (implies [`Edit::Glb`]).
    GlbPoke(usize, Vec<u8>),
}

fn hex(b: &[u8]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

fn unhex(s: &str) -> Option<Vec<u8>> {
    (0..s.len() / 2)
        .map(|i| u8::from_str_radix(s.get(2 * i..2 * i + 2)?, 16).ok())
        .collect()
}

impl Edit {
    #[allow(dead_code)] // for printing a seeded case as a script while debugging
    fn line(&self) -> String {
        match self {
            Edit::Json(e) => e.line(),
            Edit::BinTruncate(n) => format!("bin-truncate {n}"),
            Edit::BinPoke(o, b) => format!("bin-poke {o} {}", hex(b)),
            Edit::ImageTruncate(k, n) => format!("image-truncate {k} {n}"),
            Edit::ImagePoke(k, o, b) => format!("image-poke {k} {o} {}", hex(b)),
            Edit::Glb => "glb".into(),
            Edit::GlbPoke(o, b) => format!("glb-poke {o} {}", hex(b)),
        }
    }

    fn parse(line: &str) -> Option<Edit> {
        let w: Vec<&str> = line.split_whitespace().collect();
        let n = |i: usize| w.get(i).and_then(|s| s.parse::<usize>().ok());
        let b = |i: usize| w.get(i).and_then(|s| unhex(s));
        match *w.first()? {
            "bin-truncate" => Some(Edit::BinTruncate(n(1)?)),
            "bin-poke" => Some(Edit::BinPoke(n(1)?, b(2)?)),
            "image-truncate" => Some(Edit::ImageTruncate(n(1)?, n(2)?)),
            "image-poke" => Some(Edit::ImagePoke(n(1)?, n(2)?, b(3)?)),
            "glb" => Some(Edit::Glb),
            "glb-poke" => Some(Edit::GlbPoke(n(1)?, b(2)?)),
            _ => None,
        }
    }
}

/// The unmutated scene, read once.
struct Base {
    /// `scene.gltf` with every image URI made absolute (the mutant's temp dir holds no textures).
    doc: Value,
    paths: Paths,
    bin: Vec<u8>,
    /// The bytes of each glTF image (by index).
    images: Vec<Vec<u8>>,
}

fn base() -> &'static Base {
    static BASE: OnceLock<Base> = OnceLock::new();
    BASE.get_or_init(|| {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city");
        let text = std::fs::read(dir.join("scene.gltf")).expect("data/city/scene.gltf");
        let mut doc: Value = serde_json::from_slice(&text).expect("the city is JSON");
        let paths = json_mut::paths(&doc);
        let mut images = Vec::new();
        if let Some(list) = doc.get_mut("images").and_then(Value::as_array_mut) {
            for img in list {
                let uri = img["uri"]
                    .as_str()
                    .expect("city images are files")
                    .to_string();
                let path = dir.join(&uri);
                images.push(std::fs::read(&path).expect("city image"));
                img["uri"] = Value::from(path.display().to_string());
            }
        }
        let bin = std::fs::read(dir.join("scene.bin")).expect("data/city/scene.bin");
        Base {
            doc,
            paths,
            bin,
            images,
        }
    })
}

/// Bytes worth poking into binary data: NaN, ±∞ and the largest f32, all-ones, zeros.
const POKES: &[[u8; 4]] = &[
    [0x00, 0x00, 0xc0, 0x7f],
    [0x00, 0x00, 0x80, 0x7f],
    [0x00, 0x00, 0x80, 0xff],
    [0xff, 0xff, 0x7f, 0x7f],
    [0xff, 0xff, 0xff, 0xff],
    [0x00, 0x00, 0x00, 0x00],
];

/// An offset into `len` bytes, biased to the first 64 (headers).
fn offset(u: &mut Unstructured, len: usize) -> arbitrary::Result<usize> {
    let hi = if u.ratio(1, 2)? { len.min(64) } else { len };
    u.int_in_range(0..=hi)
}

fn poke_bytes(u: &mut Unstructured) -> arbitrary::Result<Vec<u8>> {
    if u.ratio(1, 3)? {
        let n = u.int_in_range(1..=8)?;
        return Ok(u.bytes(n)?.to_vec());
    }
    Ok(u.choose(POKES)?.to_vec())
}

fn random_edit(u: &mut Unstructured, b: &Base) -> arbitrary::Result<Edit> {
    Ok(match u.int_in_range(0..=99)? {
        0..=64 => Edit::Json(json_mut::random_edit(u, &b.doc, &b.paths)?),
        65..=69 => Edit::BinTruncate(u.int_in_range(0..=b.bin.len())?),
        70..=76 => Edit::BinPoke(u.int_in_range(0..=b.bin.len())?, poke_bytes(u)?),
        77..=81 => {
            let k = u.choose_index(b.images.len())?;
            Edit::ImageTruncate(k, offset(u, b.images[k].len())?)
        }
        82..=86 => {
            let k = u.choose_index(b.images.len())?;
            Edit::ImagePoke(k, offset(u, b.images[k].len())?, poke_bytes(u)?)
        }
        87..=88 => {
            // IHDR width or height (bytes 16..24 of a PNG) set to 0 or 2^31 - 1.
            let k = u.choose_index(b.images.len())?;
            let at = if u.ratio(1, 2)? { 16 } else { 20 };
            let v: &[u8] = u.choose(&[&[0, 0, 0, 0][..], &[0x7f, 0xff, 0xff, 0xff][..]])?;
            Edit::ImagePoke(k, at, v.to_vec())
        }
        89..=93 => {
            let uris = [
                "nope.png",
                "data:image/png;base64,!!!!",
                "data:image/png,notbase64",
                "data:",
                "",
                "%zz%",
                "/",
            ];
            let which = if u.ratio(1, 3)? {
                "/buffers/0/uri".to_string()
            } else {
                format!("/images/{}/uri", u.choose_index(b.images.len())?)
            };
            Edit::Json(JsonEdit::Set(which, Value::from(*u.choose(&uris)?)))
        }
        94..=96 => Edit::Glb,
        _ => Edit::GlbPoke(offset(u, 64)?, poke_bytes(u)?),
    })
}

/// The mutant's edits and expected refusal: a script, or one to three edits drawn from the bytes.
fn edits(bytes: &[u8], b: &Base) -> Option<(Vec<Edit>, Option<String>)> {
    if let Some(s) = json_mut::parse_script(bytes, MAGIC) {
        let mut edits: Vec<Edit> = s.json.into_iter().map(Edit::Json).collect();
        edits.extend(s.other.iter().filter_map(|l| Edit::parse(l)));
        return Some((edits, s.expect));
    }
    let mut u = Unstructured::new(bytes);
    let n = u.int_in_range(1..=3).ok()?;
    let list = (0..n)
        .map(|_| random_edit(&mut u, b))
        .collect::<arbitrary::Result<_>>()
        .ok()?;
    Some((list, None))
}

/// Writes the mutant into `dir`; returns the scene file to import.
fn write_mutant(dir: &Path, edits: &[Edit], b: &Base) -> PathBuf {
    let mut doc = b.doc.clone();
    let mut bin = b.bin.clone();
    let mut images: Vec<Option<Vec<u8>>> = vec![None; b.images.len()];
    let mut glb = false;
    let mut glb_pokes = Vec::new();
    let poke = |data: &mut Vec<u8>, at: usize, bytes: &[u8]| {
        for (k, &x) in bytes.iter().enumerate() {
            if let Some(slot) = data.get_mut(at + k) {
                *slot = x;
            }
        }
    };
    for e in edits {
        match e {
            Edit::Json(j) => j.apply(&mut doc),
            Edit::BinTruncate(n) => bin.truncate(*n),
            Edit::BinPoke(at, bytes) => poke(&mut bin, *at, bytes),
            Edit::ImageTruncate(k, n) => {
                if let Some(img) = b.images.get(*k) {
                    images[*k].get_or_insert_with(|| img.clone()).truncate(*n);
                }
            }
            Edit::ImagePoke(k, at, bytes) => {
                if let Some(img) = b.images.get(*k) {
                    poke(images[*k].get_or_insert_with(|| img.clone()), *at, bytes);
                }
            }
            Edit::Glb => glb = true,
            Edit::GlbPoke(at, bytes) => {
                glb = true;
                glb_pokes.push((*at, bytes.clone()));
            }
        }
    }
    for (k, img) in images.iter().enumerate() {
        if let Some(bytes) = img {
            let name = format!("image{k}.png");
            std::fs::write(dir.join(&name), bytes).expect("write image");
            if let Some(slot) = doc.pointer_mut(&format!("/images/{k}/uri")) {
                *slot = Value::from(name);
            }
        }
    }
    if !glb {
        std::fs::write(dir.join("scene.bin"), &bin).expect("write scene.bin");
        let path = dir.join("scene.gltf");
        std::fs::write(&path, serde_json::to_vec(&doc).expect("JSON")).expect("write scene.gltf");
        return path;
    }
    if let Some(Value::Object(buf)) = doc.pointer_mut("/buffers/0") {
        buf.remove("uri");
    }
    let mut out = pack_glb(&serde_json::to_vec(&doc).expect("JSON"), &bin);
    for (at, bytes) in glb_pokes {
        poke(&mut out, at, &bytes);
    }
    let path = dir.join("scene.glb");
    std::fs::write(&path, out).expect("write scene.glb");
    path
}

/// A GLB container of `json` and `bin` (chunks padded to 4 bytes).
pub fn pack_glb(json: &[u8], bin: &[u8]) -> Vec<u8> {
    let mut json = json.to_vec();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut bin = bin.to_vec();
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// The import contract every accepted scene keeps; `Some(why)` when broken.
fn broken_contract(s: &Scene) -> Option<String> {
    if let Some(i) = s
        .vertices
        .iter()
        .position(|v| !(v.pos.is_finite() && v.uv.is_finite()))
    {
        return Some(format!("vertex {i} is not finite: {:?}", s.vertices[i]));
    }
    let nv = s.vertices.len();
    for (i, t) in s.triangles.iter().enumerate() {
        if t.v.iter().any(|&v| v as usize >= nv) || t.material.idx() >= s.materials.len() {
            return Some(format!(
                "triangle {i} {t:?} points past {nv} vertices or the materials"
            ));
        }
    }
    if let Some(m) = s.materials.iter().find(|m| m.image.idx() >= s.images.len()) {
        return Some(format!(
            "material {} points past {} images",
            m.name,
            s.images.len()
        ));
    }
    None
}

/// Import and build of one mutant (the function `atlastree build` calls, at small settings).
fn run_one(bytes: &[u8]) -> Verdict {
    let b = base();
    let Some((edits, expect)) = edits(bytes, b) else {
        return Verdict::Skipped;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let path = write_mutant(dir.path(), &edits, b);
    // Messages without the temp dir, so the summary sorts refusals by kind.
    let prefix = format!("{}/", dir.path().display());
    let verdict = match import(&path, &ImportOptions::default()) {
        Err(e) => Verdict::Refused(e.to_string().replace(&prefix, "")),
        Ok(scene) => match broken_contract(&scene) {
            Some(why) => Verdict::AcceptedCorruption(why),
            None => {
                let opts = BuildOptions {
                    d_min: DMin::Ratio(15.0),
                    atlas_size: 256,
                    border: 4,
                    max_depth: 6,
                    image_cache_bytes: 64 << 20,
                    max_file_bytes: 256 << 20,
                    ..BuildOptions::default()
                };
                match build(
                    &scene,
                    &opts,
                    &dir.path().join("out.atlastree"),
                    &NoProgress,
                ) {
                    Ok(_) => Verdict::Accepted,
                    Err(e) => Verdict::Refused(format!("build: {e}").replace(&prefix, "")),
                }
            }
        },
    };
    json_mut::expect_refusal(verdict, expect.as_deref())
}

#[test]
fn gltf() {
    let counts = harness::run("gltf", DEFAULT_CASES, run_one);
    // Both outcomes occur: a base input that stopped working would make every case a refusal.
    assert!(counts.accepted > 0 && counts.refused > 0, "{counts:?}");
}

/// Edit lines survive their text form (the scripts in the corpus are read back this way).
#[test]
fn gltf_edit_lines_round_trip() {
    let edits = [
        Edit::Json(JsonEdit::Set(
            "/meshes/5/primitives/0/attributes/POSITION".into(),
            Value::from(2147483648u64),
        )),
        Edit::Json(JsonEdit::Remove("/accessors/3/bufferView".into())),
        Edit::BinTruncate(100),
        Edit::BinPoke(40, vec![0, 0, 0xc0, 0x7f]),
        Edit::ImageTruncate(3, 20),
        Edit::ImagePoke(3, 16, vec![0x7f, 0xff, 0xff, 0xff]),
        Edit::Glb,
        Edit::GlbPoke(12, vec![0xff; 4]),
    ];
    let script = std::iter::once(MAGIC.to_string())
        .chain(edits.iter().map(Edit::line))
        .collect::<Vec<_>>()
        .join("\n");
    let (back, expect) = self::edits(script.as_bytes(), base()).expect("a script");
    assert_eq!(back, edits);
    assert_eq!(expect, None);
}
