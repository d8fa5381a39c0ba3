//! The ground under the camera: a height field over the scene's plane footprint, derived from its
//! triangles, so the generated paths ([`CameraPath::overview_dive_on`](super::CameraPath::overview_dive_on),
//! [`CameraPath::street_on`](super::CameraPath::street_on)) reach street level where the triangles are
//! instead of at the bounding box's lowest point (a coastal scene whose sea floor lies 600 m below the
//! town would otherwise end its dive on the sea floor).
//!
//! **Units.** Metres = world units throughout. Plane coordinates are those of
//! [`UpAxis::plane`](crate::scene::UpAxis::plane); heights are along the up axis
//! ([`UpAxis::height`](crate::scene::UpAxis::height)), absolute (not relative to the bounds).
//!
//! **Grid.** The footprint of the bounds `[lo, hi]` is cut into a regular grid of cells,
//! [`Ground::DEFAULT_CELLS`] along its longer side and proportionally many (at least 1) along the
//! shorter one; every cell holds one height, sampled at its centre.
//!
//! **The rule for a cell's height** (all triangles with finite positions; others are skipped):
//!
//! 1. *Surfaces.* Only near-horizontal triangles are ground: normal within 60° of up
//!    (`|n̂ · up| ≥ 0.5`, either winding). Walls never are.
//! 2. *Points.* Each cell has 4 × 4 sample points (at the centres of its sub-cells). A point's height is
//!    the **lowest** ground triangle covering it (street below roof, floor below ceiling).
//! 3. *Cells.* A cell with at least one covered point is *measured*: its height is the lower quartile
//!    of its covered points (of `n` sorted heights the one at index `n / 4`), so a stray triangle that
//!    covers at most a quarter of a cell's points does not define it.
//! 4. *Neighbourhood.* A 3 × 3 median over the measured cells (the upper median of the measured cells
//!    in the block around each measured cell) removes cells that disagree with most of their neighbours,
//!    e.g. a stray triangle far below a town covering a whole cell; straight edges (a coastline) stay
//!    where they are.
//! 5. *Filling.* Cells without ground triangles take the height of the nearest measured cell (in grid
//!    steps over the 8 neighbours, ties by the measured cells' row-major order), so flying over empty sea
//!    keeps the coast's height. With no measured cell at all the ground is flat at `height(lo)`, as
//!    [`Ground::flat`].
//! 6. Heights are clamped into `[height(lo), height(hi)]`.
//!
//! [`Ground::height_at`] interpolates bilinearly between cell centres (constant beyond the outer
//! centres).
//!
//! **Content** (where a dive should go). Every triangle (any orientation) belongs to the cell holding
//! its centroid. A cell *has content of its own* when
//!
//! - it owns at least a quarter of the *typical* count (rounded up, at least 1), the typical count being
//!   the triangle-weighted median of the per-cell counts (the count of the cell in which the median
//!   triangle lies): where most triangles are (a town's buildings) is content, a sea floor of a few
//!   large triangles next to it is not; and
//! - it is not at the foot of a drop: its height is at most [`Ground::MAX_DROP_M`] m or one cell
//!   diagonal (whichever is more) below each of its 8 neighbours' (the triangles of a cliff or quay
//!   wall above the sea belong to the land, not to the sea floor at its foot); and
//! - it belongs to the scene's *main body*: of the groups of such cells (cells within 5 % of the grid
//!   side of each other connected), the one owning the most triangles (an airplane prop far out over a track's sea is a group of its own, not a street).
//!
//! [`Ground::content_near`] finds the nearest content.

use crate::scene::{Scene, UpAxis};
use crate::store::TreeFile;
use glam::{DVec2, DVec3};
use std::collections::VecDeque;

/// Sample points per cell and axis.
const SUB: usize = 4;
/// `cos 60°`: triangles whose unit normal has at least this component along up are ground.
const MIN_UP_COS: f64 = 0.5;
/// A content cell owns at least `1 / CONTENT_SHARE` of the typical per-cell triangle count.
const CONTENT_SHARE: u32 = 4;
/// Barycentric tolerance: points on a shared edge belong to both triangles (no cracks).
const EDGE_EPS: f64 = 1e-9;

/// Why a ground cannot be derived.
#[derive(Debug, thiserror::Error)]
pub enum GroundError {
    #[error("scene bounds {lo:?}..{hi:?} are not finite or not ordered; cannot derive the ground")]
    BadBounds { lo: [f64; 3], hi: [f64; 3] },
    #[error("the scene has no geometry (0 vertices or 0 trees); cannot derive the ground")]
    NoGeometry,
    #[error("a ground grid needs 1..={max} cells along its longer side, got {cells}")]
    BadCells { cells: usize, max: usize },
    #[error("tree {tree} of {trees} cannot be read")]
    MissingTree { tree: usize, trees: usize },
    #[error(
        "tree {tree}, leaf {leaf}: index range {first}..{end} exceeds the tree's {indices} indices"
    )]
    BadIndexRange {
        tree: usize,
        leaf: usize,
        first: u64,
        end: u64,
        indices: usize,
    },
    #[error(
        "tree {tree}, leaf {leaf}: vertex index {index} exceeds the tree's {vertices} vertices"
    )]
    BadVertex {
        tree: usize,
        leaf: usize,
        index: u32,
        vertices: usize,
    },
}

/// A height field of the ground over the footprint of bounds `[lo, hi]`; see the module docs for the
/// rule, the grid and the units.
#[derive(Clone, Debug, PartialEq)]
pub struct Ground {
    up: UpAxis,
    lo: DVec3,
    hi: DVec3,
    grid: Grid,
    /// Row-major (`iy · nx + ix`), every cell filled.
    heights: Vec<f64>,
    /// Per cell: has content of its own (module docs).
    content: Vec<bool>,
    measured: usize,
    lowest: f64,
    highest: f64,
}

/// The cell layout over the footprint.
#[derive(Copy, Clone, Debug, PartialEq)]
struct Grid {
    /// Plane coordinates of the footprint's low corner.
    origin: DVec2,
    /// Footprint extent per plane axis, world units.
    size: DVec2,
    /// Cell size per plane axis (0 along an axis without extent).
    cell: DVec2,
    nx: usize,
    ny: usize,
}

impl Grid {
    /// The grid over the footprint of `[lo, hi]` after checking the bounds and the cell count.
    fn checked(lo: DVec3, hi: DVec3, up: UpAxis, cells: usize) -> Result<Grid, GroundError> {
        if !(lo.is_finite() && hi.is_finite() && lo.cmple(hi).all()) {
            return Err(GroundError::BadBounds {
                lo: lo.to_array(),
                hi: hi.to_array(),
            });
        }
        if !(1..=Ground::MAX_CELLS).contains(&cells) {
            return Err(GroundError::BadCells {
                cells,
                max: Ground::MAX_CELLS,
            });
        }
        Ok(Grid::new(up.plane(lo), up.plane(hi) - up.plane(lo), cells))
    }

    fn new(origin: DVec2, size: DVec2, cells: usize) -> Grid {
        let long = size.x.max(size.y);
        let count = |s: f64| {
            if long > 0.0 {
                ((s / long * cells as f64).round() as usize).clamp(1, cells)
            } else {
                1
            }
        };
        let (nx, ny) = (count(size.x), count(size.y));
        Grid {
            origin,
            size,
            cell: size / DVec2::new(nx as f64, ny as f64),
            nx,
            ny,
        }
    }

    fn len(&self) -> usize {
        self.nx * self.ny
    }

    /// Plane coordinates of the centre of cell `(ix, iy)`.
    fn centre(&self, ix: usize, iy: usize) -> DVec2 {
        self.origin + self.cell * DVec2::new(ix as f64 + 0.5, iy as f64 + 0.5)
    }

    /// The cell holding plane point `p`, `None` outside the footprint (with a relative tolerance of
    /// 1e-9 for points rounded onto its edge).
    fn cell_of(&self, p: DVec2) -> Option<usize> {
        let d = p - self.origin;
        let tol = 1e-9 * (1.0 + self.origin.abs().max_element() + self.size.max_element());
        let inside = d.cmpge(DVec2::splat(-tol)).all() && d.cmple(self.size + tol).all();
        inside.then(|| self.clamped_cell(p))
    }

    /// The cell holding `p`, or the nearest edge cell.
    fn clamped_cell(&self, p: DVec2) -> usize {
        let d = p - self.origin;
        let one = |d: f64, cell: f64, n: usize| {
            if cell > 0.0 {
                ((d / cell).floor().max(0.0) as usize).min(n - 1)
            } else {
                0
            }
        };
        one(d.y, self.cell.y, self.ny) * self.nx + one(d.x, self.cell.x, self.nx)
    }
}

/// Cell-centre coordinate of plane offset `d` along one axis: the two neighbouring centres and the
/// fraction between them (clamped to the outer centres).
fn centre_axis(d: f64, cell: f64, n: usize) -> (usize, usize, f64) {
    if cell <= 0.0 || n == 1 {
        return (0, 0, 0.0);
    }
    let u = (d / cell - 0.5).clamp(0.0, (n - 1) as f64);
    let i0 = (u.floor() as usize).min(n - 1);
    (i0, (i0 + 1).min(n - 1), u - i0 as f64)
}

/// The centres whose bilinear patches can reach offsets `[d0, d1]` along one axis (inclusive range).
fn centre_range(d0: f64, d1: f64, cell: f64, n: usize) -> (usize, usize) {
    if cell <= 0.0 || n == 1 {
        return (0, 0);
    }
    let last = (n - 1) as f64;
    let u0 = (d0 / cell - 0.5).clamp(0.0, last).floor();
    let u1 = (d1 / cell - 0.5).clamp(0.0, last).ceil();
    (u0 as usize, (u1 as usize).min(n - 1))
}

/// `a + (b - a) · t`: exactly `a` when `a == b`.
fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a + (b - a) * t
}

impl Ground {
    /// Cells along the longer side of the footprint.
    pub const DEFAULT_CELLS: usize = 128;
    /// The most cells [`Ground::from_triangles_in`] accepts along the longer side.
    pub const MAX_CELLS: usize = 4096;
    /// A cell lower than a neighbour by more than this (or one cell diagonal, if more) is at the foot
    /// of a drop and never content, metres.
    pub const MAX_DROP_M: f64 = 20.0;

    /// The bounds-only ground, for callers without geometry: flat at the bounds' lowest point
    /// `height(lo)`, no content anywhere ([`Ground::content_near`] returns its argument). The bounds
    /// are not checked here; the generated paths reject bad ones with
    /// [`CameraError::BadBounds`](super::CameraError::BadBounds).
    pub fn flat(lo: DVec3, hi: DVec3, up: UpAxis) -> Ground {
        let (origin, size) = (up.plane(lo), up.plane(hi) - up.plane(lo));
        let h = up.height(lo);
        Ground {
            up,
            lo,
            hi,
            grid: Grid {
                origin,
                size,
                cell: size,
                nx: 1,
                ny: 1,
            },
            heights: vec![h],
            content: vec![false],
            measured: 0,
            lowest: h,
            highest: h,
        }
    }

    /// The ground of triangles (world positions, f64) over the footprint of `[lo, hi]`, with
    /// [`Ground::DEFAULT_CELLS`] cells along the longer side. Parts of triangles outside the footprint
    /// are ignored.
    pub fn from_triangles(
        lo: DVec3,
        hi: DVec3,
        up: UpAxis,
        triangles: impl IntoIterator<Item = [DVec3; 3]>,
    ) -> Result<Ground, GroundError> {
        Ground::from_triangles_in(lo, hi, up, Ground::DEFAULT_CELLS, triangles)
    }

    /// As [`Ground::from_triangles`] with `cells` (1..=[`Ground::MAX_CELLS`]) along the longer side.
    pub fn from_triangles_in(
        lo: DVec3,
        hi: DVec3,
        up: UpAxis,
        cells: usize,
        triangles: impl IntoIterator<Item = [DVec3; 3]>,
    ) -> Result<Ground, GroundError> {
        let grid = Grid::checked(lo, hi, up, cells)?;
        let mut survey = Survey::new(grid, up);
        for t in triangles {
            survey.add(t);
        }
        Ok(survey.finish(lo, hi))
    }

    /// The ground of an imported scene over its bounds ([`Scene::bounds`]), up axis `scene.up`.
    pub fn from_scene(scene: &Scene) -> Result<Ground, GroundError> {
        let (lo, hi) = scene.bounds().ok_or(GroundError::NoGeometry)?;
        let tris = scene.triangles.iter().map(|t| scene.tri_positions(t));
        Ground::from_triangles(lo, hi, scene.up, tris)
    }

    /// The ground of every tree of a paging file over the union of the trees' root bounds, up axis from
    /// the file's build parameters. World positions are `leaf.origin + vertex.pos` (f64 + f32).
    pub fn from_tree(file: &TreeFile) -> Result<Ground, GroundError> {
        let (lo, hi) = tree_bounds(file)?;
        let up = file.to_params().up;
        let grid = Grid::checked(lo, hi, up, Ground::DEFAULT_CELLS)?;
        let mut survey = Survey::new(grid, up);
        for tree in 0..file.trees() {
            for_each_tree_triangle(file, tree, |t| survey.add(t))?;
        }
        Ok(survey.finish(lo, hi))
    }

    /// The up axis.
    pub fn up(&self) -> UpAxis {
        self.up
    }

    /// The bounds the ground was made for, world units.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        (self.lo, self.hi)
    }

    /// Cells along the two plane axes.
    pub fn cells(&self) -> [usize; 2] {
        [self.grid.nx, self.grid.ny]
    }

    /// Cells whose height came from triangles (the others were filled).
    pub fn measured_cells(&self) -> usize {
        self.measured
    }

    /// Cells with content of their own (module docs).
    pub fn content_cells(&self) -> usize {
        self.content.iter().filter(|&&c| c).count()
    }

    /// The lowest cell height, world units.
    pub fn lowest(&self) -> f64 {
        self.lowest
    }

    /// The highest cell height, world units.
    pub fn highest(&self) -> f64 {
        self.highest
    }

    fn at(&self, ix: usize, iy: usize) -> f64 {
        self.heights
            .get(iy * self.grid.nx + ix)
            .copied()
            .unwrap_or(self.lowest)
    }

    /// The ground height under plane point `p` (finite), bilinear between cell centres.
    pub fn height_at(&self, p: DVec2) -> f64 {
        let d = p - self.grid.origin;
        let (x0, x1, tx) = centre_axis(d.x, self.grid.cell.x, self.grid.nx);
        let (y0, y1, ty) = centre_axis(d.y, self.grid.cell.y, self.grid.ny);
        lerp(
            lerp(self.at(x0, y0), self.at(x1, y0), tx),
            lerp(self.at(x0, y1), self.at(x1, y1), tx),
            ty,
        )
    }

    /// An upper bound of [`Ground::height_at`] over the axis-aligned box spanned by plane points `a` and
    /// `b`: the highest centre of every bilinear patch the box touches. Exact for a flat ground.
    pub fn max_in_box(&self, a: DVec2, b: DVec2) -> f64 {
        let (d0, d1) = (a.min(b) - self.grid.origin, a.max(b) - self.grid.origin);
        let (x0, x1) = centre_range(d0.x, d1.x, self.grid.cell.x, self.grid.nx);
        let (y0, y1) = centre_range(d0.y, d1.y, self.grid.cell.y, self.grid.ny);
        let mut max = f64::NEG_INFINITY;
        for iy in y0..=y1 {
            for ix in x0..=x1 {
                max = max.max(self.at(ix, iy));
            }
        }
        max
    }

    /// An upper bound of [`Ground::height_at`] along the straight segment `a → b`: the segment is cut
    /// into pieces no longer than a cell, each piece's box widened by 1 % of a cell (for rounding), and
    /// [`Ground::max_in_box`] taken over the pieces. Exact for a flat ground.
    pub fn max_along(&self, a: DVec2, b: DVec2) -> f64 {
        let cell = self.grid.cell.max_element();
        let len = (b - a).length();
        let pieces = if cell > 0.0 && len.is_finite() {
            ((len / cell).ceil() as usize).clamp(1, 4 * (self.grid.nx + self.grid.ny))
        } else {
            1
        };
        let pad = DVec2::splat(0.01 * cell);
        (0..pieces)
            .map(|i| {
                let p = a.lerp(b, i as f64 / pieces as f64);
                let q = a.lerp(b, (i + 1) as f64 / pieces as f64);
                self.max_in_box(p.min(q) - pad, p.max(q) + pad)
            })
            .fold(f64::NEG_INFINITY, f64::max)
    }

    /// The plane box of the cells with content of their own (`(low corner, high corner)`), `None` where
    /// no cell has content.
    pub fn content_bounds(&self) -> Option<(DVec2, DVec2)> {
        let nx = self.grid.nx.max(1);
        let cells = (self.content.iter().enumerate()).filter(|(_, c)| **c);
        let half = self.grid.cell * 0.5;
        cells.fold(None, |acc, (i, _)| {
            let c = self.grid.centre(i % nx, i / nx);
            let (lo, hi) = (c - half, c + half);
            Some(acc.map_or((lo, hi), |(a, b): (DVec2, DVec2)| (a.min(lo), b.max(hi))))
        })
    }

    /// Where to go near plane point `p` to find the scene's content: the centre of the nearest cell
    /// with content of its own (Euclidean, ties by row-major order; `p`'s own cell's centre when it
    /// has content), or `p` itself when no cell has (e.g. [`Ground::flat`]).
    pub fn content_near(&self, p: DVec2) -> DVec2 {
        let mut best: Option<(f64, DVec2)> = None;
        for (i, _) in self.content.iter().enumerate().filter(|(_, c)| **c) {
            let c = self.grid.centre(i % self.grid.nx, i / self.grid.nx);
            let d = (c - p).length_squared();
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, c));
            }
        }
        best.map_or(p, |(_, c)| c)
    }
}

/// The union of the trees' root bounds.
fn tree_bounds(file: &TreeFile) -> Result<(DVec3, DVec3), GroundError> {
    let trees = file.trees();
    let mut b: Option<(DVec3, DVec3)> = None;
    for tree in 0..trees {
        let view = file
            .tree(tree)
            .ok_or(GroundError::MissingTree { tree, trees })?;
        let Some(root) = view.nodes.first() else {
            continue;
        };
        let (lo, hi) = (
            DVec3::from_array(root.bounds_min),
            DVec3::from_array(root.bounds_max),
        );
        b = Some(b.map_or((lo, hi), |(a, c)| (a.min(lo), c.max(hi))));
    }
    b.ok_or(GroundError::NoGeometry)
}

/// Calls `f` with the world positions of every triangle of tree `tree`, leaf by leaf.
fn for_each_tree_triangle(
    file: &TreeFile,
    tree: usize,
    mut f: impl FnMut([DVec3; 3]),
) -> Result<(), GroundError> {
    let trees = file.trees();
    let view = file
        .tree(tree)
        .ok_or(GroundError::MissingTree { tree, trees })?;
    for (leaf, rec) in view.leaves.iter().enumerate() {
        let first = rec.first_index as usize;
        let end = first.saturating_add(rec.index_count as usize);
        let indices = view
            .indices
            .get(first..end)
            .ok_or(GroundError::BadIndexRange {
                tree,
                leaf,
                first: first as u64,
                end: end as u64,
                indices: view.indices.len(),
            })?;
        let origin = DVec3::from_array(rec.origin);
        let pos = |index: u32| {
            view.vertices
                .get(index as usize)
                .map(|v| origin + DVec3::from_array(v.pos.map(f64::from)))
                .ok_or(GroundError::BadVertex {
                    tree,
                    leaf,
                    index,
                    vertices: view.vertices.len(),
                })
        };
        for t in indices.chunks_exact(3) {
            f([pos(t[0])?, pos(t[1])?, pos(t[2])?]);
        }
    }
    Ok(())
}

/// The accumulation of triangles into sample points and per-cell triangle counts.
struct Survey {
    grid: Grid,
    up: UpAxis,
    /// Sample spacing per plane axis.
    step: DVec2,
    /// Sample points per plane axis (`SUB ×` the cells).
    sx: usize,
    sy: usize,
    /// Lowest ground height per sample point, `+∞` where none covers it. Row-major.
    lowest: Vec<f64>,
    /// Triangles owned (by centroid) per cell.
    owned: Vec<u32>,
}

impl Survey {
    fn new(grid: Grid, up: UpAxis) -> Survey {
        let (sx, sy) = (grid.nx * SUB, grid.ny * SUB);
        Survey {
            grid,
            up,
            step: grid.cell / SUB as f64,
            sx,
            sy,
            lowest: vec![f64::INFINITY; sx * sy],
            owned: vec![0; grid.len()],
        }
    }

    fn add(&mut self, t: [DVec3; 3]) {
        if !t.iter().all(|p| p.is_finite()) {
            return;
        }
        let plane = t.map(|p| self.up.plane(p));
        if let Some(c) = self.grid.cell_of((plane[0] + plane[1] + plane[2]) / 3.0)
            && let Some(n) = self.owned.get_mut(c)
        {
            *n = n.saturating_add(1);
        }
        let normal = (t[1] - t[0]).cross(t[2] - t[0]);
        let len = normal.length();
        if len > 0.0 && normal.dot(self.up.vector()).abs() >= MIN_UP_COS * len {
            let rel = plane.map(|p| p - self.grid.origin);
            self.rasterise(rel, t.map(|p| self.up.height(p)));
        }
    }

    /// Lowers every sample point inside the triangle (plane offsets `p`, heights `h`) to its height there.
    fn rasterise(&mut self, p: [DVec2; 3], h: [f64; 3]) {
        let (e1, e2) = (p[1] - p[0], p[2] - p[0]);
        let det = e1.perp_dot(e2);
        if det == 0.0 || !det.is_finite() {
            return;
        }
        let lo = p[0].min(p[1]).min(p[2]);
        let hi = p[0].max(p[1]).max(p[2]);
        let (xs, ys) = (
            sample_range(lo.x, hi.x, self.step.x, self.sx),
            sample_range(lo.y, hi.y, self.step.y, self.sy),
        );
        for iy in ys {
            for ix in xs.clone() {
                let q = self.sample_point(ix, iy) - p[0];
                let w1 = q.perp_dot(e2) / det;
                let w2 = e1.perp_dot(q) / det;
                if w1 < -EDGE_EPS || w2 < -EDGE_EPS || 1.0 - w1 - w2 < -EDGE_EPS {
                    continue;
                }
                let height = h[0] + w1 * (h[1] - h[0]) + w2 * (h[2] - h[0]);
                if let Some(s) = self.lowest.get_mut(iy * self.sx + ix) {
                    *s = s.min(height);
                }
            }
        }
    }

    /// Plane offset (from the grid origin) of sample point `(ix, iy)`.
    fn sample_point(&self, ix: usize, iy: usize) -> DVec2 {
        self.step * DVec2::new(ix as f64 + 0.5, iy as f64 + 0.5)
    }

    /// Steps 3–6 of the rule and the content threshold.
    fn finish(self, lo: DVec3, hi: DVec3) -> Ground {
        let (bottom, top) = (self.up.height(lo), self.up.height(hi));
        let raw = self.cell_quartiles();
        let filtered = median3x3(&raw, self.grid.nx, self.grid.ny);
        let measured = filtered.iter().flatten().count();
        let heights: Vec<f64> = fill_nearest(&filtered, self.grid.nx, self.grid.ny).map_or_else(
            || vec![bottom; self.grid.len()],
            |h| h.into_iter().map(|v| v.clamp(bottom, top)).collect(),
        );
        let lowest = heights.iter().copied().fold(f64::INFINITY, f64::min);
        let highest = heights.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let threshold = content_threshold(&self.owned);
        let drop = Ground::MAX_DROP_M.max(self.grid.cell.length());
        let content: Vec<bool> = (0..self.grid.len())
            .map(|i| {
                self.owned.get(i).is_some_and(|&n| n >= threshold)
                    && !foot_of_drop(&heights, self.grid.nx, self.grid.ny, i, drop)
            })
            .collect();
        let content = main_body(&content, &self.owned, self.grid.nx, self.grid.ny);
        Ground {
            up: self.up,
            lo,
            hi,
            grid: self.grid,
            content,
            heights,
            measured,
            lowest,
            highest,
        }
    }

    /// Per cell, the lower quartile of its covered sample points (`None` where none is covered).
    fn cell_quartiles(&self) -> Vec<Option<f64>> {
        let mut out = Vec::with_capacity(self.grid.len());
        let mut buf = Vec::with_capacity(SUB * SUB);
        for cy in 0..self.grid.ny {
            for cx in 0..self.grid.nx {
                buf.clear();
                for sy in cy * SUB..(cy + 1) * SUB {
                    let row = self.lowest.get(sy * self.sx..(sy + 1) * self.sx);
                    let cells = row.and_then(|r| r.get(cx * SUB..(cx + 1) * SUB));
                    buf.extend(cells.unwrap_or(&[]).iter().filter(|h| h.is_finite()));
                }
                buf.sort_by(f64::total_cmp);
                out.push(buf.get(buf.len() / 4).copied());
            }
        }
        out
    }
}

/// Content cells at most this share of the longer grid side apart (Chebyshev, in cells, at least 1)
/// belong to one group in [`main_body`]: a town's blocks across its streets are one body.
const BODY_REACH: f64 = 0.05;

/// The group of `content` cells (row-major, `nx × ny`; cells within [`BODY_REACH`] of each other
/// connected) that owns the most triangles (ties: the first in row-major order); every other content
/// cell is cleared. A scene's main body (a town, a track) rather than an outlier far off in its bounds
/// (an airplane flying over a sea, a skybox prop) is where generated paths go.
fn main_body(content: &[bool], owned: &[u32], nx: usize, ny: usize) -> Vec<bool> {
    let reach = ((nx.max(ny) as f64 * BODY_REACH).round() as i64).max(1);
    let mut label = vec![u32::MAX; content.len()];
    let mut best: Option<(u64, u32)> = None;
    let mut stack = Vec::new();
    for start in 0..content.len() {
        if !content[start] || label[start] != u32::MAX {
            continue;
        }
        let id = start as u32;
        let mut triangles = 0u64;
        label[start] = id;
        stack.push(start);
        while let Some(i) = stack.pop() {
            triangles += u64::from(owned.get(i).copied().unwrap_or(0));
            let (x, y) = (i % nx, i / nx);
            for dy in -reach..=reach {
                for dx in -reach..=reach {
                    let (qx, qy) = (x as i64 + dx, y as i64 + dy);
                    if qx < 0 || qy < 0 || qx >= nx as i64 || qy >= ny as i64 {
                        continue;
                    }
                    let q = qy as usize * nx + qx as usize;
                    if content[q] && label[q] == u32::MAX {
                        label[q] = id;
                        stack.push(q);
                    }
                }
            }
        }
        if best.is_none_or(|(t, _)| triangles > t) {
            best = Some((triangles, id));
        }
    }
    match best {
        Some((_, id)) => label.iter().map(|&l| l == id).collect(),
        None => content.to_vec(),
    }
}

/// Sample indices `i` in `0..n` whose centres `(i + 0.5) · step` lie in `[lo, hi]`.
fn sample_range(lo: f64, hi: f64, step: f64, n: usize) -> std::ops::Range<usize> {
    if step <= 0.0 {
        // No extent along this axis: every sample sits at offset 0.
        return if lo <= 0.0 && 0.0 <= hi { 0..n } else { 0..0 };
    }
    let first = (lo / step - 0.5).ceil().max(0.0);
    let last = (hi / step - 0.5).floor().min(n as f64 - 1.0);
    if first > last {
        0..0
    } else {
        first as usize..last as usize + 1
    }
}

/// Step 4: per measured cell, the upper median of the measured cells in its 3 × 3 block.
fn median3x3(raw: &[Option<f64>], nx: usize, ny: usize) -> Vec<Option<f64>> {
    let mut out = Vec::with_capacity(raw.len());
    let mut block = Vec::with_capacity(9);
    for iy in 0..ny {
        for ix in 0..nx {
            if raw.get(iy * nx + ix).copied().flatten().is_none() {
                out.push(None);
                continue;
            }
            block.clear();
            for y in iy.saturating_sub(1)..(iy + 2).min(ny) {
                for x in ix.saturating_sub(1)..(ix + 2).min(nx) {
                    block.extend(raw.get(y * nx + x).copied().flatten());
                }
            }
            block.sort_by(f64::total_cmp);
            out.push(block.get(block.len() / 2).copied());
        }
    }
    out
}

/// Step 5: every cell takes the value of the nearest measured cell (breadth-first over the 8
/// neighbours from all measured cells in row-major order). `None` when no cell is measured.
fn fill_nearest(cells: &[Option<f64>], nx: usize, ny: usize) -> Option<Vec<f64>> {
    let mut out: Vec<Option<f64>> = cells.to_vec();
    let mut queue: VecDeque<usize> = out
        .iter()
        .enumerate()
        .filter_map(|(i, v)| v.map(|_| i))
        .collect();
    if queue.is_empty() {
        return None;
    }
    while let Some(i) = queue.pop_front() {
        let Some(v) = out.get(i).copied().flatten() else {
            continue;
        };
        let (ix, iy) = (i % nx, i / nx);
        for y in iy.saturating_sub(1)..(iy + 2).min(ny) {
            for x in ix.saturating_sub(1)..(ix + 2).min(nx) {
                let j = y * nx + x;
                if let Some(slot @ None) = out.get_mut(j) {
                    *slot = Some(v);
                    queue.push_back(j);
                }
            }
        }
    }
    Some(out.into_iter().map(|v| v.unwrap_or(f64::NAN)).collect())
}

/// True if cell `i` is more than `drop` below one of its 8 neighbours.
fn foot_of_drop(heights: &[f64], nx: usize, ny: usize, i: usize, drop: f64) -> bool {
    let (ix, iy) = (i % nx, i / nx);
    let Some(&h) = heights.get(i) else {
        return false;
    };
    (iy.saturating_sub(1)..(iy + 2).min(ny)).any(|y| {
        (ix.saturating_sub(1)..(ix + 2).min(nx))
            .any(|x| heights.get(y * nx + x).is_some_and(|&n| n - h > drop))
    })
}

/// The owned-triangle count a cell needs to have content: a quarter of the triangle-weighted median
/// count, rounded up, at least 1.
fn content_threshold(owned: &[u32]) -> u32 {
    let mut counts: Vec<u32> = owned.iter().copied().filter(|&n| n > 0).collect();
    counts.sort_unstable();
    let total: u64 = counts.iter().map(|&n| u64::from(n)).sum();
    let mut seen = 0u64;
    let typical = counts
        .iter()
        .find(|&&n| {
            seen += u64::from(n);
            2 * seen >= total
        })
        .copied()
        .unwrap_or(0);
    typical.div_ceil(CONTENT_SHARE).max(1)
}

#[cfg(test)]
mod tests;
