//! The node walk: the glTF node graph → a flat list of mesh [`Instance`]s with f64 world matrices.
//!
//! The default scene is walked (all root nodes if there is none), depth first and iteratively. Local
//! transforms are read from the raw JSON in f64 (gltf-json keeps them as f32): `matrix`, else T·R·S (a
//! `matrix` beside TRS, or with a projective last row, is warned once per node and used affinely);
//! a zero or non-finite rotation becomes the identity (counted warning). `EXT_mesh_gpu_instancing`
//! multiplies a node's mesh into one instance per T·R·S of its attributes. A node met again on its own
//! path is a [`SceneError::RecursiveNodes`]; a node with several parents is instanced once per parent
//! (warning), and more than [`MAX_NODE_VISITS`] visits is [`SceneError::TooLarge`].

use super::accessors::read_floats;
use super::uri::Buffers;
use crate::scene::ImportReport;
use crate::scene::error::SceneError;
use glam::{DMat4, DQuat, DVec3};
use serde::Deserialize;

/// Cap on node visits during the hierarchy walk (guards against exponential DAG expansion).
pub(super) const MAX_NODE_VISITS: u64 = 1 << 26;
/// Mesh instances the scene may place in all (node visits × `EXT_mesh_gpu_instancing` instances): a few
/// bytes of JSON must not expand into gigabytes of instance records.
pub(super) const MAX_INSTANCES: usize = 1 << 26;

/// A node's transform as written in the JSON, in f64.
#[derive(Deserialize, Default)]
pub(super) struct RawNode {
    matrix: Option<[f64; 16]>,
    translation: Option<[f64; 3]>,
    rotation: Option<[f64; 4]>,
    scale: Option<[f64; 3]>,
}

/// One mesh instance in world space.
pub(super) struct Instance {
    pub(super) node: usize,
    pub(super) mesh: usize,
    pub(super) world: DMat4,
}

/// What the walk reads, and where it counts and warns.
pub(super) struct Walk<'a, 'b> {
    /// The glTF file (for errors and warnings).
    pub(super) file: &'a str,
    pub(super) doc: &'a gltf::Document,
    /// Per glTF node: its raw JSON transform.
    pub(super) raw: &'b [RawNode],
    pub(super) accessors: &'b [gltf::Accessor<'a>],
    /// Instancing attributes are read through these.
    pub(super) buffers: &'b mut Buffers<'a>,
    pub(super) report: &'b mut ImportReport,
    /// [`super::ImportOptions::max_triangles`], less the share of the JSON parsed beside them.
    pub(super) max_triangles: Option<u64>,
    /// The glTF JSON's length, bytes (named by [`SceneError::OverTriangleBudget`]).
    pub(super) json_bytes: u64,
}

impl<'a> Walk<'a, '_> {
    /// Walks the default scene (`scenes[0]` without one; every root node without scenes) iteratively and
    /// returns every mesh instance with its world matrix. A node met again while it is on the current
    /// path is a cycle: error.
    pub(super) fn instances(&mut self) -> Result<Vec<Instance>, SceneError> {
        let n = self.doc.nodes().len();
        // No `scene` index: `scenes[0]`, as three.js and Blender draw (glTF leaves it to the viewer);
        // warned when there are others, which are not drawn. No scene at all: every root node.
        let first = self.doc.scenes().next();
        let scenes = self.doc.scenes().len();
        if self.doc.default_scene().is_none() && scenes > 1 {
            self.report.warn(format!(
                "{}: no `scene` index among {scenes} scenes: drawing scenes[0] only",
                self.file
            ));
        }
        let roots: Vec<usize> = match self.doc.default_scene().or(first) {
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
        let mut warned_shared = vec![false; n];
        let mut parents = vec![0u32; n];
        for node in self.doc.nodes() {
            for c in node.children() {
                if let Some(p) = parents.get_mut(c.index()) {
                    *p = p.saturating_add(1);
                }
            }
        }
        let mut stack: Vec<Step> = roots
            .iter()
            .rev()
            .map(|&r| Step::Enter(r, DMat4::IDENTITY))
            .collect();
        let mut instances = Vec::new();
        let mut visits: u64 = 0;
        // Triangles of the instances met so far, against the caller's budget.
        // Per mesh: its triangles and the vertices they use (`mesh_counts`).
        let mut per_mesh: std::collections::HashMap<usize, (u64, u64)> = Default::default();
        let (mut triangles, mut vertices): (u64, u64) = (0, 0);
        // Every instance met, kept or (past the budget) only counted: the cap bounds the walk's work.
        let mut met: usize = 0;
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
                    file: self.file.to_string(),
                    node: i,
                    node_name: node.name().unwrap_or("").to_string(),
                });
            }
            visits += 1;
            if visits > MAX_NODE_VISITS {
                return Err(SceneError::TooLarge {
                    file: self.file.to_string(),
                    what: format!(
                        "more than {MAX_NODE_VISITS} node visits (nodes shared by many parents)"
                    ),
                });
            }
            // Once per node that has several parents itself (a child of a shared node is visited as
            // often as its parent, and has one).
            if let Some(w) = warned_shared.get_mut(i)
                && !*w
                && parents.get(i).is_some_and(|&p| p > 1)
            {
                *w = true;
                self.report.warn(format!(
                    "{}: node {i} has more than one parent; it is instanced once per parent",
                    self.file
                ));
            }
            if let Some(p) = on_path.get_mut(i) {
                *p = true;
            }
            stack.push(Step::Exit(i));
            let world = parent * self.local_matrix(i);
            if let Some(mesh) = node.mesh() {
                let list = self.gpu_instances(node)?;
                let adding = list.as_ref().map_or(1, Vec::len);
                met = met.saturating_add(adding);
                if met > MAX_INSTANCES {
                    return Err(SceneError::TooLarge {
                        file: self.file.to_string(),
                        what: format!(
                            "more than {MAX_INSTANCES} mesh instances (node visits × GPU instances)"
                        ),
                    });
                }
                if self.max_triangles.is_some() {
                    let (per, per_vertices) = *per_mesh
                        .entry(mesh.index())
                        .or_insert_with(|| super::mesh::mesh_counts(&mesh));
                    triangles = triangles.saturating_add(per.saturating_mul(adding as u64));
                    vertices = vertices.saturating_add(per_vertices.saturating_mul(adding as u64));
                }
                // Past the budget the walk only counts (no instance kept), so the error can say
                // how much the whole scene needs.
                let over = self.max_triangles.is_some_and(|max| triangles > max);
                match list {
                    _ if over => {}
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
        if let Some(max) = self.max_triangles.filter(|&max| triangles > max) {
            return Err(SceneError::OverTriangleBudget {
                file: self.file.to_string(),
                triangles,
                vertices,
                instances: met as u64,
                max,
                json_bytes: self.json_bytes,
            });
        }
        self.report.nodes = visits;
        self.report.instances = instances.len() as u64;
        Ok(instances)
    }

    /// One warning per node of the file whose `matrix` breaks glTF 2.0 (§5.25): given beside
    /// translation, rotation or scale (the matrix is used, the others ignored), or with a last row other
    /// than (0, 0, 0, 1) (not a TRS; the row is ignored: points are transformed affinely).
    pub(super) fn warn_invalid_matrices(&mut self) {
        for (i, raw) in self.raw.iter().enumerate() {
            let Some(m) = raw.matrix else { continue };
            if raw.translation.is_some() || raw.rotation.is_some() || raw.scale.is_some() {
                self.report.warn(format!(
                    "{}: node {i} has both `matrix` and translation/rotation/scale (glTF 2.0 allows one); \
                     using the matrix, ignoring the others",
                    self.file
                ));
            }
            let row = [m[3], m[7], m[11], m[15]];
            if row != [0.0, 0.0, 0.0, 1.0] {
                self.report.warn(format!(
                    "{}: node {i} has a `matrix` whose last row is {row:?}, not (0, 0, 0, 1): glTF 2.0 \
                     requires a TRS matrix; the row is ignored",
                    self.file
                ));
            }
        }
    }

    /// The node's local matrix in f64 from the raw JSON (`matrix`, else T·R·S).
    fn local_matrix(&mut self, i: usize) -> DMat4 {
        let Some(raw) = self.raw.get(i) else {
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
            self.report.warn(format!(
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
        let file = self.file;
        let err = |reason: String| SceneError::Instancing {
            file: file.to_string(),
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
            self.buffers.load_accessor(&self.accessors[idx])?;
            let mut out = Vec::new();
            let acc = &self.accessors[idx];
            read_floats(self.buffers.data(), acc, dims, &mut out, &mut Vec::new())
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
            self.report.warn(format!(
                "{}: node {}: {bad_rot} EXT_mesh_gpu_instancing rotations are zero or non-finite; identity used",
                self.file,
                node.index()
            ));
        }
        Ok(Some(out))
    }
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
