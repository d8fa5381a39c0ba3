//! The warning list of an import: [`ImportReport::warn`] keeps at most [`MAX_WARNINGS`] messages and
//! counts every one; [`ImportReport::close_warnings`] appends "... and N more" for those not kept.
//!
//! Every stage of the import warns through these two methods (an inherent `impl` visible to the
//! import's files only), so the cap is applied in one place.

use crate::scene::ImportReport;

/// At most this many warning strings are kept; the rest are counted in `warnings_total`.
pub(super) const MAX_WARNINGS: usize = 100;

impl ImportReport {
    /// Records a warning: the string is kept while fewer than [`MAX_WARNINGS`] are, the total is exact.
    /// Keeps `msg` (its control characters escaped: it may quote names from the file) up to
    /// [`MAX_WARNINGS`]; counts it either way.
    pub(super) fn warn(&mut self, msg: String) {
        self.warnings_total += 1;
        if self.warnings.len() < MAX_WARNINGS {
            self.warnings
                .push(crate::util::printable(&msg).into_owned());
        }
    }

    /// Appends "... and N more" when warnings were counted but not kept.
    pub(super) fn close_warnings(&mut self) {
        let kept = self.warnings.len() as u64;
        if self.warnings_total > kept {
            let more = self.warnings_total - kept;
            self.warnings.push(format!("... and {more} more"));
        }
    }
}

/// What the glTF asks for that atlastree does not draw, one counted warning per feature (not per
/// instance): vertex colours (`COLOR_0`), NEAREST magnification filters (atlases and originals are
/// sampled linearly, in linear light), emission (atlases hold the base colour only), skins (meshes are
/// placed by their nodes' transforms), base colour factors outside `[0, 1]` (clamped) and MASK cutoffs
/// below glTF's minimum of 0 (drawn as OPAQUE),
/// counted over the whole file, drawn scene or not. Not warned: `doubleSided: false`, the default of most
/// files — every triangle is drawn from both sides (README, "Bad input and faults").
pub(super) fn warn_undrawn_features(file: &str, doc: &gltf::Document, report: &mut ImportReport) {
    use gltf::texture::MagFilter;
    let coloured: Vec<(usize, usize)> = doc
        .meshes()
        .flat_map(|m| {
            m.primitives()
                .filter(|p| p.get(&gltf::Semantic::Colors(0)).is_some())
                .map(move |p| (m.index(), p.index()))
        })
        .collect();
    if let Some(&(mesh, prim)) = coloured.first() {
        report.warn(format!(
            "{file}: {} primitives carry vertex colours (COLOR_0), which are not drawn: their base colour \
             and texture show untinted (first: mesh {mesh} primitive {prim})",
            coloured.len()
        ));
    }
    let nearest: Vec<usize> = doc
        .samplers()
        // Magnification only: where NEAREST shows (pixel art); a NEAREST min filter drawn trilinear
        // differs little (Khronos' own BoxTextured asks for NEAREST_MIPMAP_LINEAR).
        .filter(|s| s.mag_filter() == Some(MagFilter::Nearest))
        .filter_map(|s| s.index())
        .collect();
    if let Some(&first) = nearest.first() {
        report.warn(format!(
            "{file}: {} samplers ask for NEAREST magnification, drawn with linear filtering (texels blur when \
             magnified; first: sampler {first})",
            nearest.len()
        ));
    }
    // Emission is emissiveTexture × emissiveFactor, the factor [0, 0, 0] by default: a texture alone emits
    // nothing.
    let emissive: Vec<usize> = doc
        .materials()
        .filter(|m| m.emissive_factor().iter().any(|&c| c > 0.0))
        .filter_map(|m| m.index())
        .collect();
    if let Some(&first) = emissive.first() {
        report.warn(format!(
            "{file}: {} materials are emissive (emissiveFactor above 0), drawn without their \
             emission: only the base colour shows (first: material {first})",
            emissive.len()
        ));
    }
    // A skinned mesh is posed by its joints (glTF 2.0 §3.7.3), the node's own transform ignored; here it
    // is placed by the node's transform, as if unskinned.
    let skinned: Vec<usize> = doc
        .nodes()
        .filter(|n| n.skin().is_some() && n.mesh().is_some())
        .map(|n| n.index())
        .collect();
    if let Some(&first) = skinned.first() {
        let n = skinned.len();
        let nodes = if n == 1 {
            "node draws a skinned mesh"
        } else {
            "nodes draw skinned meshes"
        };
        report.warn(format!(
            "{file}: {n} {nodes}; skins are not applied: each mesh is placed by its node's transform, \
             as if unskinned (first: node {first})"
        ));
    }
    warn_undeclared_quantization(file, doc, report);
    // CESIUM_RTC (3D Tiles' b3dm content) moves the whole model by its `center`, given in the tileset's
    // Z-up earth-fixed frame, not the glTF's own: refused where required, and where merely used the
    // model is read as its positions say, which a silent import placed at the origin (fault hunt,
    // session 37).
    if let Some(rtc) = doc.extension_value("CESIUM_RTC") {
        report.warn(format!(
            "{file}: CESIUM_RTC (center {}) is not applied: the model is read relative to that centre, \
             about the origin; its center is in the tileset's earth-fixed frame, so add it there, or \
             bake it into a node translation (glTF's Y-up frame) before building",
            rtc.get("center").map_or("absent".into(), |c| c.to_string())
        ));
    }
    // glTF 2.0's schemas bound baseColorFactor (and the specular-glossiness diffuseFactor, drawn in its
    // place where `Materials::material_for` says) to [0, 1]; beyond, the atlas (8-bit, the factor applied
    // before filtering) and the originals (the factor applied after) would draw different colours.
    let outside_range = |f: [f32; 4]| f.iter().any(|c| !(0.0..=1.0).contains(c));
    let outside: Vec<usize> = doc
        .materials()
        .filter(|m| {
            outside_range(m.pbr_metallic_roughness().base_color_factor())
                || m.pbr_specular_glossiness()
                    .is_some_and(|sg| outside_range(sg.diffuse_factor()))
        })
        .filter_map(|m| m.index())
        .collect();
    if let Some(&first) = outside.first() {
        report.warn(format!(
            "{file}: {} {} a baseColorFactor (or diffuseFactor) outside glTF's range [0, 1], drawn clamped \
             into it (first: material {first})",
            outside.len(),
            if outside.len() == 1 { "material has" } else { "materials have" }
        ));
    }
    for m in doc.materials() {
        if let Some(c) = m.alpha_cutoff().filter(|c| *c < 0.0) {
            report.warn(format!(
                "{file}: material {} ({}): alphaCutoff {c} is below glTF's minimum 0; every texel passes \
                 the MASK test, so it is drawn as OPAQUE",
                m.index().map_or("default".into(), |i| i.to_string()),
                m.name().unwrap_or("unnamed")
            ));
        }
    }
}

/// Integer POSITION, or integer TEXCOORD that is not normalized, is glTF 2.0 only with
/// KHR_mesh_quantization (§3.7.2.1); a file that does not declare it is read as the data says (integer
/// values), with one counted warning naming the first such attribute.
fn warn_undeclared_quantization(file: &str, doc: &gltf::Document, report: &mut ImportReport) {
    use gltf::accessor::DataType;
    if doc.extensions_used().any(|e| e == "KHR_mesh_quantization") {
        return;
    }
    let mut found: Vec<String> = Vec::new();
    for m in doc.meshes() {
        for p in m.primitives() {
            for (semantic, acc) in p.attributes() {
                let integer = acc.data_type() != DataType::F32;
                let bad = match semantic {
                    gltf::Semantic::Positions => integer,
                    gltf::Semantic::TexCoords(_) => integer && !acc.normalized(),
                    _ => false,
                };
                if bad {
                    found.push(format!(
                        "mesh {} primitive {} {} (accessor {}, {:?})",
                        m.index(),
                        p.index(),
                        semantic.to_string(),
                        acc.index(),
                        acc.data_type()
                    ));
                }
            }
        }
    }
    if let Some(first) = found.first() {
        report.warn(format!(
            "{file}: {} vertex attributes are integers that glTF 2.0 allows only with KHR_mesh_quantization, \
             which the file does not declare in extensionsUsed; read as their integer values (first: {first})",
            found.len()
        ));
    }
}
