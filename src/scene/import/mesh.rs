//! Geometry: the primitives of each mesh instance → world-space vertices and triangles.
//!
//! Positions (f64, after the instance's world matrix) and UVs (f64, `KHR_texture_transform` baked in,
//! or the solid texel centre) are read per primitive into reused scratch buffers — only the range of
//! vertices its indices use, which are read first (primitives sharing one large accessor each read
//! their part: [`read_float_range`]) — positions with their
//! morph targets added by the default weights (the pose a viewer draws without animation), UVs with their
//! targets' `TEXCOORD_n` deltas added by the same weights; indices (or `0..n`)
//! are checked against the vertex count and assembled for triangle lists, strips and fans. Only
//! vertices used by kept triangles are emitted, once per instance. Triangles with a non-finite position
//! or UV are skipped, UVs beyond ±[`LARGE_UV`] kept; both counted. Non-triangle modes and primitives
//! without POSITION are skipped (counted warning). Bad accessors and out-of-range indices are errors.

use super::accessors::{
    PrimCtx, check_vertex_attribute, plausible_count, read_float_range, read_indices,
};
use super::materials::{Materials, UvSource};
use super::nodes::Instance;
use super::uri::Buffers;
use crate::ids::MaterialId;
use crate::scene::error::SceneError;
use crate::scene::{ImportReport, Triangle, Vertex};
use glam::{DVec2, DVec3};
use gltf::Semantic;
use gltf::mesh::Mode;
use std::collections::HashMap;

/// A mesh's primitives' morph targets as the raw JSON has them (attribute name → accessor index): gltf-json
/// reads a target's POSITION, NORMAL and TANGENT only, and glTF 2.0 §3.7.2.2 allows `TEXCOORD_n` too.
/// Optional as gltf-json's own fields are (`"targets": null` imports).
#[derive(serde::Deserialize, Default)]
pub(super) struct RawMesh {
    primitives: Option<Vec<RawPrimitive>>,
}

#[derive(serde::Deserialize, Default)]
struct RawPrimitive {
    targets: Option<Vec<serde_json::Map<String, serde_json::Value>>>,
}

/// UV components beyond ±this are kept but counted (`large_uv_triangles`).
pub(super) const LARGE_UV: f64 = 1e6;
/// Triangles a scene may place over all its mesh instances (2^28, ~50 GiB of build memory at today's
/// ~200 B per triangle): beyond it a small file repeating one mesh could exhaust memory.
pub(super) const MAX_TRIANGLES: u64 = 1 << 28;

/// Reused per-primitive buffers (no per-vertex allocation).
#[derive(Default)]
struct Scratch {
    floats: Vec<f64>,
    /// A vertex attribute beside POSITION (UVs, a morph target's POSITION deltas).
    attribute: Vec<f64>,
    tmp: Vec<f64>,
    world: Vec<DVec3>,
    uvs: Vec<DVec2>,
    indices: Vec<u32>,
    remap: Vec<u32>,
}

/// The vertices of one primitive that are read: its POSITION accessor (`accessor`, `count` elements)
/// and the range of them its indices use.
struct VertexSpan {
    accessor: usize,
    count: usize,
    used: std::ops::Range<usize>,
}

/// The smallest range holding every index in `indices` (empty for none).
fn used_range(indices: &[u32]) -> std::ops::Range<usize> {
    let Some(&first) = indices.first() else {
        return 0..0;
    };
    let (lo, hi) = (indices.iter()).fold((first, first), |(lo, hi), &i| (lo.min(i), hi.max(i)));
    lo as usize..hi as usize + 1
}

/// Per-primitive triangle counts.
#[derive(Default)]
struct TriCounts {
    bad_pos: u64,
    bad_uv: u64,
    large_uv: u64,
}

/// `(triangles, vertices)` of one instance of `mesh`, from its accessors' counts (capped by their buffer
/// views' sizes: [`plausible_count`]); no data is read.
pub(super) fn mesh_counts(mesh: &gltf::Mesh<'_>) -> (u64, u64) {
    mesh.primitives().fold((0, 0), |(t, v), p| {
        let nv = p
            .get(&Semantic::Positions)
            .map_or(0, |a| plausible_count(&a)) as u64;
        let ni = p.indices().map_or(nv, |a| plausible_count(&a) as u64);
        // A primitive keeps only the vertices its indices use: primitives sharing one large accessor
        // (each with indices of its own) counted it once each, and 50,000 of them over 200,000
        // vertices were refused as 10¹⁰ vertices (fault hunt, session 36).
        (t + ni / 3, v + nv.min(ni))
    })
}

/// The triangle soup built so far.
pub(super) struct Geometry<'a> {
    /// The glTF file (for errors and warnings).
    file: &'a str,
    meshes: Vec<gltf::Mesh<'a>>,
    /// The meshes' morph targets from the raw JSON (for their `TEXCOORD_n`).
    raw_meshes: Vec<RawMesh>,
    accessors: &'a [gltf::Accessor<'a>],
    nodes: Vec<gltf::Node<'a>>,
    pub(super) vertices: Vec<Vertex>,
    pub(super) triangles: Vec<Triangle>,
    scratch: Scratch,
}

impl<'a> Geometry<'a> {
    pub(super) fn new(
        file: &'a str,
        doc: &'a gltf::Document,
        accessors: &'a [gltf::Accessor<'a>],
        raw_meshes: Vec<RawMesh>,
    ) -> Self {
        Geometry {
            file,
            meshes: doc.meshes().collect(),
            raw_meshes,
            accessors,
            nodes: doc.nodes().collect(),
            vertices: Vec::new(),
            triangles: Vec::new(),
            scratch: Scratch::default(),
        }
    }

    /// Reserves the output vectors from the accessor counts (capped by the buffer view sizes). Allocation
    /// failure of the reservation is not an error: the vectors then grow as needed.
    pub(super) fn reserve(&mut self, instances: &[Instance]) -> Result<(), SceneError> {
        let meshes = &self.meshes;
        let mut per_mesh: HashMap<usize, (u64, u64)> = HashMap::new();
        let (mut tris, mut verts) = (0u64, 0u64);
        for inst in instances {
            let (t, v) = *per_mesh
                .entry(inst.mesh)
                .or_insert_with(|| meshes.get(inst.mesh).map_or((0, 0), mesh_counts));
            tris = tris.saturating_add(t);
            verts = verts.saturating_add(v);
        }
        if tris > MAX_TRIANGLES {
            return Err(SceneError::TooLarge {
                file: self.file.to_string(),
                what: format!(
                    "{tris} triangles over all mesh instances exceed {MAX_TRIANGLES} (split the scene)"
                ),
            });
        }
        if verts > u64::from(u32::MAX) {
            return Err(SceneError::TooLarge {
                file: self.file.to_string(),
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

    /// Emits every primitive of `inst`'s mesh.
    pub(super) fn emit_instance(
        &mut self,
        inst: &Instance,
        materials: &mut Materials,
        buffers: &mut Buffers,
        report: &mut ImportReport,
    ) -> Result<(), SceneError> {
        let Some(mesh) = self.meshes.get(inst.mesh).cloned() else {
            return Ok(());
        };
        let mesh_name = mesh.name().unwrap_or("unnamed").to_string();
        // Morph weights (glTF 2.0 §3.7.2.2): the node's, else the mesh's, else 0 (the pose drawn without
        // animation).
        let node_weights = self.nodes.get(inst.node).and_then(|n| n.weights());
        let weights: Vec<f64> = (node_weights.or(mesh.weights()).unwrap_or(&[]).iter())
            .map(|&w| f64::from(w))
            .collect();
        for prim in mesh.primitives() {
            let ctx = PrimCtx {
                mesh: inst.mesh,
                mesh_name: mesh_name.clone(),
                primitive: prim.index(),
            };
            self.emit_primitive(inst, &prim, &ctx, &weights, materials, buffers, report)?;
        }
        Ok(())
    }

    /// Emits one primitive of one instance: world-space vertices (only those used by kept triangles)
    /// and triangles, its morph targets' positions and UVs added by `weights`. See the module docs for what is
    /// skipped and counted.
    #[allow(clippy::too_many_arguments)]
    fn emit_primitive(
        &mut self,
        inst: &Instance,
        prim: &gltf::Primitive<'a>,
        ctx: &PrimCtx,
        weights: &[f64],
        materials: &mut Materials,
        buffers: &mut Buffers,
        report: &mut ImportReport,
    ) -> Result<(), SceneError> {
        let mode = prim.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            report.skipped_primitives += 1;
            report.warn(format!(
                "{}: mesh {} ({}) primitive {}: mode {mode:?} is not triangles; skipped (node {})",
                self.file, ctx.mesh, ctx.mesh_name, ctx.primitive, inst.node
            ));
            return Ok(());
        }
        let Some(pos_acc) = prim.get(&Semantic::Positions) else {
            report.skipped_primitives += 1;
            report.warn(format!(
                "{}: mesh {} ({}) primitive {}: no POSITION attribute; skipped",
                self.file, ctx.mesh, ctx.mesh_name, ctx.primitive
            ));
            return Ok(());
        };
        let has_data = |a: &gltf::Accessor<'_>| a.view().is_some() || a.sparse().is_some();
        let morphed = weighted_position_targets(prim, weights).any(|(_, _, a)| has_data(&a));
        if !has_data(&pos_acc) && !morphed {
            // All zeros by the spec: nothing to draw. A Draco primitive without its uncompressed
            // fallback came out as silent zero-area triangles (fault hunt, session 33).
            let draco = prim.extension_value("KHR_draco_mesh_compression").is_some();
            report.skipped_primitives += 1;
            report.warn(format!(
                "{}: mesh {} ({}) primitive {}: its POSITION accessor {} has no data (no bufferView){}; \
                 skipped",
                self.file,
                ctx.mesh,
                ctx.mesh_name,
                ctx.primitive,
                pos_acc.index(),
                if draco {
                    ": it is compressed with KHR_draco_mesh_compression, which atlastree does not \
                     decode, and has no uncompressed fallback"
                } else {
                    ""
                }
            ));
            return Ok(());
        }
        let (material, uv_source) = materials.material_for(prim, ctx, buffers, report)?;
        let n = pos_acc.count();
        // POSITION's buffer and type first, as before the indices were read first: a primitive with a
        // bad POSITION and bad indices reports the POSITION.
        buffers.load_accessor(&pos_acc)?;
        check_vertex_attribute(&pos_acc).map_err(|e| ctx.error(self.file, "POSITION", e))?;

        // Indices (or 0..n), checked against the vertex count.
        match prim.indices() {
            Some(idx_acc) => {
                buffers.load_accessor(&idx_acc)?;
                let s = &mut self.scratch;
                read_indices(buffers.data(), &idx_acc, &mut s.indices, &mut s.tmp)
                    .map_err(|e| ctx.error(self.file, "indices", e))?;
                if let Some((position, &index)) = self
                    .scratch
                    .indices
                    .iter()
                    .enumerate()
                    .find(|(_, i)| **i as usize >= n)
                {
                    return Err(SceneError::IndexOutOfRange {
                        file: self.file.to_string(),
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
                    file: self.file.to_string(),
                    what: format!(
                        "mesh {} primitive {}: {n} vertices",
                        ctx.mesh, ctx.primitive
                    ),
                })?;
                self.scratch.indices.clear();
                self.scratch.indices.extend(0..count);
            }
        }
        // The vertices the indices use, read alone (primitives sharing one accessor each read their
        // part), the indices rebased to them.
        let span = VertexSpan {
            accessor: pos_acc.index(),
            count: n,
            used: used_range(&self.scratch.indices),
        };
        let first = span.used.start as u32;
        self.scratch.indices.iter_mut().for_each(|i| *i -= first);

        // Positions → world space.
        let s = &mut self.scratch;
        let (used, out) = (span.used.clone(), &mut s.floats);
        read_float_range(buffers.data(), &pos_acc, 3, used, out, &mut s.tmp)
            .map_err(|e| ctx.error(self.file, "POSITION", e))?;
        self.add_morph_positions(prim, weights, &span, ctx, buffers)?;
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
            self.read_beside_positions(&uv_acc, &semantic, 2, &span, ctx, buffers)?;
            let s = &mut self.scratch;
            (s.uvs).extend(s.attribute.chunks_exact(2).map(|c| DVec2::new(c[0], c[1])));
            // The targets' UV deltas times their weights, before the texture transform (which applies
            // to the morphed UVs): a target that moved the UVs was drawn with the base ones (fault hunt,
            // session 35).
            for (i, w, acc) in self.weighted_uv_targets(ctx, set, weights) {
                let semantic = format!("morph target {i} {semantic}");
                self.read_beside_positions(&acc, &semantic, 2, &span, ctx, buffers)?;
                let s = &mut self.scratch;
                for (uv, d) in s.uvs.iter_mut().zip(s.attribute.chunks_exact(2)) {
                    *uv += w * DVec2::new(d[0], d[1]);
                }
            }
            if let Some(t) = xf {
                for uv in &mut self.scratch.uvs {
                    *uv = t.apply(*uv);
                }
            }
        }

        let leftover = match mode {
            Mode::Triangles => self.scratch.indices.len() % 3,
            _ => 0,
        };
        if leftover != 0 {
            report.warn(format!(
                "{}: mesh {} ({}) primitive {}: {} indices is not a multiple of 3; the last {leftover} ignored",
                self.file,
                ctx.mesh,
                ctx.mesh_name,
                ctx.primitive,
                self.scratch.indices.len()
            ));
        }
        let counts = self.assemble(mode, material, span.used.len())?;
        self.report_counts(ctx, &counts, report);
        Ok(())
    }

    /// Adds to the primitive's local positions (`scratch.floats`: `span`'s used vertices) each
    /// morph target's POSITION deltas times its weight (glTF 2.0 §3.7.2.2: the static pose is the base
    /// plus the weighted targets). Targets of weight 0, and their other attributes (normals and tangents,
    /// which are not drawn), are not read.
    fn add_morph_positions(
        &mut self,
        prim: &gltf::Primitive<'a>,
        weights: &[f64],
        span: &VertexSpan,
        ctx: &PrimCtx,
        buffers: &mut Buffers,
    ) -> Result<(), SceneError> {
        for (i, w, acc) in weighted_position_targets(prim, weights) {
            let semantic = format!("morph target {i} POSITION");
            self.read_beside_positions(&acc, &semantic, 3, span, ctx, buffers)?;
            let s = &mut self.scratch;
            for (p, d) in s.floats.iter_mut().zip(&s.attribute) {
                *p += w * d;
            }
        }
        Ok(())
    }

    /// Reads vertex attribute `acc` (`dims` floats a vertex) for `span`'s used vertices into
    /// `scratch.attribute`, after checking that it has as many elements as the primitive's POSITION;
    /// errors name `semantic`.
    fn read_beside_positions(
        &mut self,
        acc: &gltf::Accessor<'a>,
        semantic: &str,
        dims: usize,
        span: &VertexSpan,
        ctx: &PrimCtx,
        buffers: &mut Buffers,
    ) -> Result<(), SceneError> {
        let (base, n) = (span.accessor, span.count);
        if acc.count() != n {
            return Err(SceneError::Accessor {
                file: self.file.to_string(),
                mesh: ctx.mesh,
                mesh_name: ctx.mesh_name.clone(),
                primitive: ctx.primitive,
                accessor: acc.index(),
                reason: format!(
                    "{semantic} has {} elements but POSITION (accessor {base}) has {n}",
                    acc.count()
                ),
            });
        }
        buffers.load_accessor(acc)?;
        let s = &mut self.scratch;
        check_vertex_attribute(acc)
            .and_then(|()| {
                let (used, out) = (span.used.clone(), &mut s.attribute);
                read_float_range(buffers.data(), acc, dims, used, out, &mut s.tmp)
            })
            .map_err(|e| ctx.error(self.file, semantic, e))
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
                            file: self.file.to_string(),
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

    fn report_counts(&self, ctx: &PrimCtx, c: &TriCounts, report: &mut ImportReport) {
        let where_ = format!(
            "{}: mesh {} ({}) primitive {}",
            self.file, ctx.mesh, ctx.mesh_name, ctx.primitive
        );
        if c.bad_pos > 0 {
            report.skipped_triangles += c.bad_pos;
            report.warn(format!(
                "{where_}: {} triangles with NaN/Inf positions skipped",
                c.bad_pos
            ));
        }
        if c.bad_uv > 0 {
            report.skipped_triangles += c.bad_uv;
            report.warn(format!(
                "{where_}: {} triangles with NaN/Inf UVs skipped",
                c.bad_uv
            ));
        }
        if c.large_uv > 0 {
            report.large_uv_triangles += c.large_uv;
            report.warn(format!(
                "{where_}: {} triangles with |uv| > {LARGE_UV:e} kept",
                c.large_uv
            ));
        }
    }

    /// The morph targets of primitive `ctx` that move its UV set `set`: `(index, weight, accessor)` of
    /// each with a non-zero weight in `weights` (a missing weight is 0) and a `TEXCOORD_{set}` attribute
    /// naming an accessor (the raw JSON's indices were checked by `refs`).
    fn weighted_uv_targets(
        &self,
        ctx: &PrimCtx,
        set: u32,
        weights: &[f64],
    ) -> Vec<(usize, f64, gltf::Accessor<'a>)> {
        let name = format!("TEXCOORD_{set}");
        let targets = (self.raw_meshes.get(ctx.mesh))
            .and_then(|m| m.primitives.as_ref()?.get(ctx.primitive))
            .and_then(|p| p.targets.as_deref())
            .unwrap_or_default();
        (targets.iter().enumerate())
            .filter_map(|(i, t)| {
                let w = target_weight(weights, i)?;
                let index = t.get(&name)?.as_u64()?;
                let acc = self.accessors.get(usize::try_from(index).ok()?)?;
                Some((i, w, acc.clone()))
            })
            .collect()
    }
}

/// The morph targets of `prim` that move its static pose: `(index, weight, POSITION accessor)` of each
/// with a non-zero weight in `weights` (a missing weight is 0) and a POSITION attribute. The one rule
/// for both the deltas added and whether a primitive without position data is drawn at all.
fn weighted_position_targets<'a>(
    prim: &gltf::Primitive<'a>,
    weights: &[f64],
) -> impl Iterator<Item = (usize, f64, gltf::Accessor<'a>)> {
    prim.morph_targets().enumerate().filter_map(|(i, t)| {
        let w = target_weight(weights, i)?;
        t.positions().map(|a| (i, w, a))
    })
}

/// Target `i`'s weight in `weights` where it moves anything: a missing weight is 0, and a target of
/// weight 0 is not read.
fn target_weight(weights: &[f64], i: usize) -> Option<f64> {
    weights.get(i).copied().filter(|&w| w != 0.0)
}
