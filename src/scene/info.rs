//! `scene-info`: a summary of an imported [`Scene`] — sizes, textures, per-material UV ranges and repeat
//! counts, wrap and alpha modes, bounds and planarity — as a readable report ([`std::fmt::Display`]) and
//! as JSON (`Serialize`).

use super::image_source::ImageData;
use super::{AlphaMode, ImportReport, Scene, UpAxis, Wrap};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt;

/// Summary of a scene.
#[derive(Clone, Debug, Serialize)]
pub struct SceneInfo {
    pub source: String,
    pub triangles: u64,
    pub vertices: u64,
    pub instances: u64,
    pub nodes: u64,
    pub materials: Vec<MaterialInfo>,
    pub textures: Vec<TextureInfo>,
    /// Materials per alpha mode.
    pub alpha: AlphaCounts,
    /// Materials per `(wrap_s, wrap_t)` pair, e.g. `"Repeat/ClampToEdge"`.
    pub wrap_modes: BTreeMap<String, u64>,
    /// World bounds; `None` for an empty scene.
    pub bounds: Option<Bounds>,
    pub up: UpAxis,
    /// Height extent / largest extent in the distribution plane (0 = perfectly planar); `None` when the
    /// plane extent is zero.
    pub planarity: Option<f64>,
    /// Σ width·height over all images (solid and fallback images included).
    pub texture_texels: u64,
    /// Images per kind: "file", "embedded", "solid", "fallback".
    pub image_kinds: BTreeMap<String, u64>,
    /// Periods (texture copies, in UV² units) the triangles' UVs unroll: Σ over triangles of the UV area,
    /// every repetition of the scene once. Not what `--repeat bake` stores: it shifts triangles by whole
    /// periods, so triangles share periods, and holds each rect's hull.
    pub periods_spanned: f64,
    /// Periods one copy per material holds: Σ over materials of the UV box area with every REPEAT /
    /// MIRRORED_REPEAT axis capped at one period — what a node holding the whole scene stores with
    /// repeats wrapped in the shader (`--repeat wrap`, the default).
    pub periods_wrapped: f64,
    pub report: ImportReport,
}

/// Per-material statistics.
#[derive(Clone, Debug, Serialize)]
pub struct MaterialInfo {
    pub id: u32,
    /// The glTF material it comes from ([`crate::scene::Material::gltf_material`]): the number import
    /// warnings name; `None` for glTF's default material.
    pub gltf_material: Option<u32>,
    pub name: String,
    pub image: u32,
    pub wrap: [Wrap; 2],
    pub alpha: AlphaMode,
    pub texture_transform: bool,
    pub triangles: u64,
    /// Smallest / largest UV over the material's triangles (`None` without triangles).
    pub uv_min: Option<[f64; 2]>,
    pub uv_max: Option<[f64; 2]>,
    /// `uv_max - uv_min` per axis: how many times the texture repeats across the whole material.
    pub uv_bbox_span: Option<[f64; 2]>,
    /// Max over triangles of the triangle's own UV span per axis: the largest repetition within one
    /// triangle (what an atlas must reserve for a single triangle).
    pub max_triangle_uv_span: Option<[f64; 2]>,
    /// Σ over the material's triangles of their UV area (periods unrolled; see [`SceneInfo::periods_spanned`]).
    pub periods_spanned: f64,
    /// The UV box area with wrapped axes capped at one period (see [`SceneInfo::periods_wrapped`]).
    pub periods_wrapped: f64,
}

/// Per-image statistics.
#[derive(Clone, Debug, Serialize)]
pub struct TextureInfo {
    pub id: u32,
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub color: String,
    pub has_alpha: bool,
    /// "file", "embedded", "solid" or "fallback".
    pub kind: String,
    /// Materials using this image.
    pub materials: u64,
    /// Triangles whose material uses this image.
    pub triangles: u64,
    /// The earlier image read from the same glTF image: one drawn by OPAQUE materials and by alpha
    /// materials is two images, one decoded with its alpha dropped.
    pub same_as: Option<u32>,
}

/// Material counts per alpha mode.
#[derive(Clone, Debug, Default, Serialize)]
pub struct AlphaCounts {
    pub opaque: u64,
    pub mask: u64,
    pub blend: u64,
}

/// Axis-aligned world bounds.
#[derive(Clone, Debug, Serialize)]
pub struct Bounds {
    pub min: [f64; 3],
    pub max: [f64; 3],
    pub size: [f64; 3],
}

/// Per-material UV accumulator.
#[derive(Clone, Copy)]
struct UvAcc {
    tris: u64,
    min: [f64; 2],
    max: [f64; 2],
    tri_span: [f64; 2],
    /// Σ |UV area| of the triangles.
    area: f64,
}

impl Default for UvAcc {
    fn default() -> Self {
        UvAcc {
            tris: 0,
            min: [f64::INFINITY; 2],
            max: [f64::NEG_INFINITY; 2],
            tri_span: [0.0; 2],
            area: 0.0,
        }
    }
}

/// Analyses `scene` in one pass over its triangles.
pub fn analyze(scene: &Scene) -> SceneInfo {
    let mut acc = vec![UvAcc::default(); scene.materials.len()];
    for t in &scene.triangles {
        let Some(a) = acc.get_mut(t.material.idx()) else {
            continue;
        };
        let uvs = t.v.map(|i| {
            scene
                .vertices
                .get(i as usize)
                .map_or(glam::DVec2::ZERO, |v| v.uv)
        });
        a.tris += 1;
        let (e1, e2) = (uvs[1] - uvs[0], uvs[2] - uvs[0]);
        let area = 0.5 * e1.perp_dot(e2).abs();
        if area.is_finite() {
            a.area += area;
        }
        for axis in 0..2 {
            let (lo, hi) = uvs
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), uv| {
                    (lo.min(uv[axis]), hi.max(uv[axis]))
                });
            a.min[axis] = a.min[axis].min(lo);
            a.max[axis] = a.max[axis].max(hi);
            a.tri_span[axis] = a.tri_span[axis].max(hi - lo);
        }
    }
    let mut alpha = AlphaCounts::default();
    let mut wrap_modes = BTreeMap::new();
    let mut img_use = vec![(0u64, 0u64); scene.images.len()];
    let materials: Vec<MaterialInfo> = scene
        .materials
        .iter()
        .zip(&acc)
        .enumerate()
        .map(|(i, (m, a))| {
            match m.alpha {
                AlphaMode::Opaque => alpha.opaque += 1,
                AlphaMode::Mask { .. } => alpha.mask += 1,
                AlphaMode::Blend => alpha.blend += 1,
            }
            *wrap_modes
                .entry(format!("{:?}/{:?}", m.wrap[0], m.wrap[1]))
                .or_insert(0) += 1;
            if let Some(u) = img_use.get_mut(m.image.idx()) {
                u.0 += 1;
                u.1 += a.tris;
            }
            let has = a.tris > 0;
            // REPEAT / MIRRORED_REPEAT: one period; CLAMP_TO_EDGE: beyond [0, 1] only edge texels.
            let wrapped_span = |k: usize| (a.max[k] - a.min[k]).clamp(0.0, 1.0);
            let periods_wrapped = if has && a.max.iter().chain(&a.min).all(|x| x.is_finite()) {
                wrapped_span(0) * wrapped_span(1)
            } else {
                0.0
            };
            MaterialInfo {
                id: i as u32,
                gltf_material: m.gltf_material,
                name: m.name.clone(),
                image: m.image.0,
                wrap: m.wrap,
                alpha: m.alpha,
                texture_transform: m.texture_transform,
                triangles: a.tris,
                uv_min: has.then_some(a.min),
                uv_max: has.then_some(a.max),
                uv_bbox_span: has.then_some([a.max[0] - a.min[0], a.max[1] - a.min[1]]),
                max_triangle_uv_span: has.then_some(a.tri_span),
                periods_spanned: a.area,
                periods_wrapped,
            }
        })
        .collect();
    let mut image_kinds = BTreeMap::new();
    let mut first_of_gltf: BTreeMap<u32, u32> = BTreeMap::new();
    let textures: Vec<TextureInfo> = scene
        .images
        .iter()
        .zip(&img_use)
        .enumerate()
        .map(|(i, (img, u))| {
            let kind = match img.data {
                ImageData::File(_) => "file",
                ImageData::Bytes(_) => "embedded",
                ImageData::Solid(_) => "solid",
                ImageData::Fallback => "fallback",
            };
            *image_kinds.entry(kind.to_string()).or_insert(0) += 1;
            let same_as = img.gltf_image.and_then(|g| match first_of_gltf.entry(g) {
                std::collections::btree_map::Entry::Occupied(e) => Some(*e.get()),
                std::collections::btree_map::Entry::Vacant(e) => {
                    e.insert(i as u32);
                    None
                }
            });
            TextureInfo {
                id: i as u32,
                name: img.name.clone(),
                width: img.width,
                height: img.height,
                color: img.color.clone(),
                has_alpha: img.has_alpha,
                kind: kind.to_string(),
                materials: u.0,
                triangles: u.1,
                same_as,
            }
        })
        .collect();
    // Summed from +0.0: an empty f64 sum is -0.0, printed as such in the JSON of a scene without
    // triangles (fault hunt, session 37).
    let periods_spanned = (materials.iter()).fold(0.0, |s, m| s + m.periods_spanned);
    let periods_wrapped = (materials.iter()).fold(0.0, |s, m| s + m.periods_wrapped);
    let bounds = scene.bounds();
    let planarity = bounds.and_then(|(lo, hi)| {
        let e = hi - lo;
        let plane = scene.up.plane(e);
        let horizontal = plane.x.max(plane.y);
        (horizontal > 0.0).then(|| scene.up.height(e) / horizontal)
    });
    SceneInfo {
        source: scene.source.display().to_string(),
        triangles: scene.triangles.len() as u64,
        vertices: scene.vertices.len() as u64,
        instances: scene.report.instances,
        nodes: scene.report.nodes,
        materials,
        textures,
        alpha,
        wrap_modes,
        bounds: bounds.map(|(lo, hi)| Bounds {
            min: lo.to_array(),
            max: hi.to_array(),
            size: (hi - lo).to_array(),
        }),
        up: scene.up,
        planarity,
        texture_texels: scene.images.iter().map(|i| i.texels()).sum(),
        image_kinds,
        periods_spanned,
        periods_wrapped,
        report: scene.report.clone(),
    }
}

fn opt2(v: Option<[f64; 2]>) -> String {
    v.map_or("-".to_string(), |[a, b]| format!("({a:.4}, {b:.4})"))
}

impl fmt::Display for SceneInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "scene: {}", self.source)?;
        writeln!(
            f,
            "  triangles {}, vertices {}, mesh instances {}, node visits {}",
            self.triangles, self.vertices, self.instances, self.nodes
        )?;
        match &self.bounds {
            Some(b) => writeln!(
                f,
                "  bounds min [{:.3}, {:.3}, {:.3}] max [{:.3}, {:.3}, {:.3}] size [{:.3}, {:.3}, {:.3}]",
                b.min[0],
                b.min[1],
                b.min[2],
                b.max[0],
                b.max[1],
                b.max[2],
                b.size[0],
                b.size[1],
                b.size[2]
            )?,
            None => writeln!(f, "  bounds: empty scene")?,
        }
        let planarity = self
            .planarity
            .map_or("-".to_string(), |p| format!("{p:.4}"));
        writeln!(
            f,
            "  up axis {:?}, planarity (height / plane extent) {planarity}",
            self.up
        )?;
        writeln!(
            f,
            "  alpha materials: {} opaque, {} mask, {} blend",
            self.alpha.opaque, self.alpha.mask, self.alpha.blend
        )?;
        let wraps: Vec<String> = self
            .wrap_modes
            .iter()
            .map(|(k, v)| format!("{k} ×{v}"))
            .collect();
        let wraps = if wraps.is_empty() {
            "none".to_string()
        } else {
            wraps.join(", ")
        };
        writeln!(f, "  wrap modes: {wraps}")?;
        // `+ 0.0` turns the −0.0 of an empty float sum into 0.0.
        let (spanned, wrapped) = (self.periods_spanned + 0.0, self.periods_wrapped + 0.0);
        let ratio = if wrapped > 0.0 {
            format!("{:.1}× less", spanned / wrapped)
        } else {
            "none wrapped".to_string()
        };
        writeln!(
            f,
            "  periods the UVs span {spanned:.1} (Σ triangle UV areas); one wrapped copy per material {wrapped:.1} \
             ({ratio})"
        )?;
        let kinds: Vec<String> = self
            .image_kinds
            .iter()
            .map(|(k, v)| format!("{v} {k}"))
            .collect();
        writeln!(
            f,
            "  images: {} ({}), {} texels in total",
            self.textures.len(),
            kinds.join(", "),
            self.texture_texels
        )?;
        for t in &self.textures {
            let again = t.same_as.map_or(String::new(), |first| {
                format!(" (the image of #{first} again: OPAQUE and alpha materials draw it, one of the two with its alpha dropped)")
            });
            writeln!(
                f,
                "    #{:<4} {:>5}x{:<5} {:<9} alpha={:<5} {:<8} mats {:<3} tris {:<8} {}{again}",
                t.id,
                t.width,
                t.height,
                t.color,
                t.has_alpha,
                t.kind,
                t.materials,
                t.triangles,
                t.name
            )?;
        }
        writeln!(f, "  materials: {}", self.materials.len())?;
        for m in &self.materials {
            writeln!(
                f,
                "    #{:<4} {:?} ({}) image #{} wrap {:?}/{:?} {}tris {} uv {}..{} bbox span {} max tri span {}",
                m.id,
                m.name,
                m.gltf_material
                    .map_or("glTF default material".to_string(), |i| format!(
                        "glTF material {i}"
                    )),
                m.image,
                m.wrap[0],
                m.wrap[1],
                match m.alpha {
                    AlphaMode::Opaque => String::new(),
                    AlphaMode::Mask { cutoff } => format!("MASK<{cutoff} "),
                    AlphaMode::Blend => "BLEND ".into(),
                } + if m.texture_transform { "xform " } else { "" },
                m.triangles,
                opt2(m.uv_min),
                opt2(m.uv_max),
                opt2(m.uv_bbox_span),
                opt2(m.max_triangle_uv_span),
            )?;
        }
        let r = &self.report;
        writeln!(
            f,
            "  import: {} warnings, {} skipped primitives, {} skipped triangles, {} missing images, {} truncated \
             images, {} primitives without their TEXCOORD, {} triangles with huge UVs",
            r.warnings_total,
            r.skipped_primitives,
            r.skipped_triangles,
            r.missing_images,
            r.truncated_images,
            r.missing_texcoords,
            r.large_uv_triangles
        )?;
        for w in &r.warnings {
            writeln!(f, "    warning: {w}")?;
        }
        Ok(())
    }
}

/// The cost of just reading a scene's textures: every image a triangle uses, decoded once to RGBA8 — the
/// baseline of the preprocessor's throughput target (a build within 3× of it).
#[derive(Clone, Debug, Default, Serialize)]
pub struct DecodeReport {
    /// Distinct images used by at least one triangle (solid 1×1 images included, they cost nothing; a
    /// glTF image that OPAQUE and alpha materials draw is two, decoded twice, as the build does).
    pub images: usize,
    /// Texels decoded (width × height summed).
    pub texels: u64,
    /// Encoded bytes read from image files and embedded buffers.
    pub encoded_bytes: u64,
    /// Images that failed to decode (each would become the fallback checker in a build).
    pub failures: usize,
    /// Images the import could not find or read, already the fallback checker (counted in `images`, each
    /// named by an import warning): "decoded 55 images, failures 0" was read as 55 good images where 53
    /// were missing (fault hunt, session 32).
    pub fallbacks: usize,
    /// The first [`DECODE_ERRORS_SHOWN`] of those failures' errors (each names its image).
    pub errors: Vec<String>,
    /// Wall-clock seconds over `threads` threads.
    pub seconds: f64,
    pub threads: usize,
}

/// Bytes of the decodes in flight, held within `budget`: a decode waits while others hold some and its
/// own need would pass it (one alone always runs, its need taken as at most the budget).
struct DecodeGate {
    held: std::sync::Mutex<u64>,
    freed: std::sync::Condvar,
    budget: u64,
}

/// A decode's share of a [`DecodeGate`], given back when dropped.
struct Held<'g> {
    gate: &'g DecodeGate,
    bytes: u64,
}

impl DecodeGate {
    fn new(budget: u64) -> Self {
        DecodeGate {
            held: std::sync::Mutex::new(0),
            freed: std::sync::Condvar::new(),
            budget,
        }
    }

    fn enter(&self, need: u64) -> Held<'_> {
        let bytes = need.min(self.budget);
        let mut held = self.held.lock().unwrap_or_else(|p| p.into_inner());
        while *held > 0 && *held + bytes > self.budget {
            held = self.freed.wait(held).unwrap_or_else(|p| p.into_inner());
        }
        *held += bytes;
        Held { gate: self, bytes }
    }
}

impl Drop for Held<'_> {
    fn drop(&mut self) {
        let mut held = self.gate.held.lock().unwrap_or_else(|p| p.into_inner());
        *held -= self.bytes;
        self.gate.freed.notify_all();
    }
}

/// Failed decodes whose errors a [`DecodeReport`] keeps.
pub const DECODE_ERRORS_SHOWN: usize = 5;

/// Decodes every image a triangle of `scene` uses once, in parallel on the rayon pool (the build's pool),
/// dropping each result at once. Units: seconds of wall time, texels.
pub fn decode_all(scene: &Scene) -> DecodeReport {
    use rayon::prelude::*;
    let mut used = vec![false; scene.images.len()];
    for t in &scene.triangles {
        used[scene.materials[t.material.idx()].image.idx()] = true;
    }
    let images: Vec<_> = scene
        .images
        .iter()
        .zip(&used)
        .filter(|(_, u)| **u)
        .map(|(i, _)| i)
        .collect();
    let start = std::time::Instant::now();
    // Decodes in flight hold at most one decode's limit together (each is refused past it alone), so
    // two huge images are decoded one after the other, not side by side (a hostile scene's pair could
    // take all the memory the process may use: fault hunt, session 35).
    let gate = DecodeGate::new(super::image_source::decode_alloc_limit());
    let results: Vec<Result<u64, String>> = images
        .par_iter()
        .map(|img| {
            // The decoder's buffer and its RGBA8 copy: at most 8 + 4 bytes a texel (RGBA16).
            let need = (u64::from(img.width) * u64::from(img.height)).saturating_mul(12);
            let _held = gate.enter(need);
            match img.decode() {
                Ok(d) => Ok(u64::from(d.width) * u64::from(d.height)),
                Err(e) => Err(e.to_string()),
            }
        })
        .collect();
    let texels = results.iter().filter_map(|r| r.as_ref().ok()).sum();
    let errors: Vec<String> = results.into_iter().filter_map(Result::err).collect();
    DecodeReport {
        images: images.len(),
        texels,
        encoded_bytes: images.iter().map(|i| i.encoded_bytes()).sum(),
        failures: errors.len(),
        fallbacks: images.iter().filter(|i| i.is_fallback()).count(),
        errors: errors.into_iter().take(DECODE_ERRORS_SHOWN).collect(),
        seconds: start.elapsed().as_secs_f64(),
        threads: rayon::current_num_threads(),
    }
}

impl fmt::Display for DecodeReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "decoded {} images ({:.1} Mtexels from {}) in {:.2} s on {} threads: {:.1} Mtexels/s{}",
            self.images,
            self.texels as f64 / 1e6,
            crate::util::human_bytes(self.encoded_bytes),
            self.seconds,
            self.threads,
            self.texels as f64 / 1e6 / self.seconds.max(1e-9),
            if self.failures > 0 {
                format!(", {} failed", self.failures)
            } else {
                String::new()
            }
        )?;
        if self.fallbacks > 0 {
            write!(
                f,
                "; {} of them missing or unreadable at import, the fallback checker (see the warnings)",
                self.fallbacks
            )?;
        }
        for e in &self.errors {
            write!(f, "\n  failed: {e}")?;
        }
        if self.failures > self.errors.len() {
            write!(f, "\n  … and {} more", self.failures - self.errors.len())?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A decode whose need would pass the budget beside one in flight waits for it; one alone runs
    /// whatever its need.
    #[test]
    fn decodes_in_flight_stay_within_the_gate() {
        let gate = DecodeGate::new(100);
        let huge = gate.enter(1_000);
        assert_eq!(*gate.held.lock().unwrap(), 100);
        drop(huge);
        let first = gate.enter(60);
        let entered = std::sync::atomic::AtomicBool::new(false);
        std::thread::scope(|s| {
            s.spawn(|| {
                let _second = gate.enter(60);
                entered.store(true, std::sync::atomic::Ordering::SeqCst);
            });
            std::thread::sleep(std::time::Duration::from_millis(50));
            assert!(!entered.load(std::sync::atomic::Ordering::SeqCst));
            let small = gate.enter(40);
            drop(small);
            drop(first);
        });
        assert!(entered.load(std::sync::atomic::Ordering::SeqCst));
        assert_eq!(*gate.held.lock().unwrap(), 0);
    }
}
