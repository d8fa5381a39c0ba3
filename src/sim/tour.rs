//! What a camera path shows of a tree, level by level, decided on the CPU: the frame planner's cut of every
//! tree (all blocks resident) per frame, counted by the level of the atlas drawn and by original-texture
//! draws. `atlastree demo` prints it for its tour, and its test asserts that the tour draws every level of
//! a tree of depth ≥ 3 ([`DemoTour`] holds the demo's settings, so the demo and its test fly the same
//! frames).

use crate::camera::{Camera, CameraError, CameraPath, Ground, PathKind};
use crate::plan::{FramePlanner, NoResidency, PlanError};
use crate::preprocess::{BuildOptions, DMin};
use crate::select::{SelectError, SelectOptions, Source, min_distance_scale};
use crate::store::TreeFile;
use crate::store::format::NodeRecord;

/// The demo's tree and flight (`atlastree demo` flags default to these). The embedded default scene is a
/// 600 m district with 2.2 Mtexels of textures: at the build defaults it fits one scaled leaf (depth 0), so
/// the demo asks for small atlases, a near `d_min` and a small originals budget, which split it into a
/// quadtree whose every level the overview-dive passes through.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct DemoTour {
    /// `build --atlas-size`.
    pub atlas_size: u32,
    /// `build --d-min-ratio`.
    pub d_min_ratio: f64,
    /// `build --leaf-originals`.
    pub leaf_originals: f64,
    /// Frame size of the rendered flights.
    pub width: u32,
    pub height: u32,
    /// Frames sampled evenly over the whole path, first keyframe to last.
    pub frames: usize,
    /// Blocks resident at most in the paged flight.
    pub capacity: u32,
}

impl DemoTour {
    /// The demo's defaults.
    pub const DEFAULT: DemoTour = DemoTour {
        atlas_size: 256,
        d_min_ratio: 8.0,
        leaf_originals: 2.0,
        width: 640,
        height: 480,
        frames: 80,
        capacity: 12,
    };

    /// The build options of the demo's tree: the defaults but for atlas size, `d_min` and the originals
    /// budget, and the border where the default does not fit the atlas (under a quarter of its side: the
    /// demo has no `--border`, and `--atlas-size 64`, the smallest, was refused for the default border
    /// of 16; fault hunt, session 32).
    pub fn build_options(&self) -> BuildOptions {
        let defaults = BuildOptions::default();
        BuildOptions {
            d_min: DMin::Ratio(self.d_min_ratio),
            atlas_size: self.atlas_size,
            leaf_originals_atlases: self.leaf_originals,
            border: defaults.border.min((self.atlas_size / 4).saturating_sub(1)),
            ..defaults
        }
    }

    /// The path clock that spreads `frames` over the whole of `path` (frame `i` at `start + i / fps`, the
    /// last one on the last keyframe).
    pub fn fps(&self, path: &CameraPath) -> f64 {
        let span = path.duration();
        if self.frames < 2 || span <= 0.0 {
            1.0
        } else {
            (self.frames - 1) as f64 / span
        }
    }

    /// The overview-dive over `file`'s ground.
    pub fn path(file: &TreeFile) -> Result<CameraPath, CameraError> {
        PathKind::OverviewDive.resolve_with(|| Ground::from_tree(file))
    }

    /// One camera per frame, the whole path, with the tour's aspect.
    pub fn cameras(&self, path: &CameraPath) -> Vec<Camera> {
        let aspect = f64::from(self.width) / f64::from(self.height.max(1));
        path.frames(self.fps(path), self.frames)
            .map(|mut c| {
                c.aspect = aspect;
                c
            })
            .collect()
    }

    /// The min-distance scale of `file`'s trees for each of `cameras`, at the tour's width (texel ratio 1)
    /// and the camera's own field of view.
    pub fn scales(&self, file: &TreeFile, cameras: &[Camera]) -> Result<Vec<f64>, SelectError> {
        let params = file.to_params();
        cameras
            .iter()
            .map(|c| {
                min_distance_scale(
                    &params,
                    &SelectOptions {
                        screen_width: self.width,
                        texel_ratio: 1.0,
                        fov_x_deg: c.fov_x_deg,
                    },
                )
            })
            .collect()
    }
}

/// Per tree, what a path draws.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TreeLevels {
    /// Deepest level of the tree (root = 0).
    pub depth: u8,
    pub nodes: usize,
    /// Per level 0..=depth: frames that draw at least one node of that level with its atlas.
    pub atlas_frames: Vec<u32>,
    /// Per level: atlas draws (cut items) summed over the frames.
    pub atlas_draws: Vec<u64>,
    /// Frames with at least one leaf drawn with its original textures, and those draws summed.
    pub original_frames: u32,
    pub original_draws: u64,
    /// Per frame: the distinct levels drawn with their atlas.
    pub frame_levels: Vec<u8>,
}

impl TreeLevels {
    fn new(nodes: &[NodeRecord]) -> TreeLevels {
        let depth = depth_of(nodes);
        let n = usize::from(depth) + 1;
        TreeLevels {
            depth,
            nodes: nodes.len(),
            atlas_frames: vec![0; n],
            atlas_draws: vec![0; n],
            original_frames: 0,
            original_draws: 0,
            frame_levels: Vec::new(),
        }
    }

    /// The levels drawn with their atlas at least once, ascending.
    pub fn levels_drawn(&self) -> Vec<u8> {
        (0..=self.depth)
            .filter(|&l| self.atlas_draws[usize::from(l)] > 0)
            .collect()
    }

    /// Every level 0..=depth was drawn with its atlas at least once.
    pub fn all_levels_drawn(&self) -> bool {
        self.atlas_draws.iter().all(|&d| d > 0)
    }
}

/// Depth of a tree: the deepest node's level (the root is 0).
fn depth_of(nodes: &[NodeRecord]) -> u8 {
    nodes
        .iter()
        .map(|n| n.level)
        .max()
        .map_or(0, |l| u8::try_from(l).unwrap_or(u8::MAX))
}

/// What `cameras` draw of every tree of `file` with every block resident, camera `i` at min-distance
/// scale `scales[i]`: the planner's cut per frame, counted by level.
pub fn levels_along(
    file: &TreeFile,
    cameras: &[Camera],
    scales: &[f64],
) -> Result<Vec<TreeLevels>, PlanError> {
    let views = super::with_scales(cameras, scales)?;
    let trees = crate::plan::file_trees(file);
    let mut out: Vec<TreeLevels> = trees.iter().map(|t| TreeLevels::new(t)).collect();
    let mut planner = FramePlanner::new(trees);
    for (cam, scale) in views {
        let plan = planner.plan_still(cam, scale, &mut NoResidency)?;
        for (cut, lv) in plan.cuts.iter().zip(out.iter_mut()) {
            let mut seen = vec![false; lv.atlas_draws.len()];
            let mut originals = false;
            for item in &cut.items {
                match item.source {
                    Source::Atlas => {
                        let l = usize::from(item.level);
                        if let Some(d) = lv.atlas_draws.get_mut(l) {
                            *d += 1;
                            seen[l] = true;
                        }
                    }
                    Source::Original => {
                        lv.original_draws += 1;
                        originals = true;
                    }
                }
            }
            lv.frame_levels
                .push(seen.iter().filter(|&&s| s).count() as u8);
            for (f, s) in lv.atlas_frames.iter_mut().zip(seen) {
                *f += u32::from(s);
            }
            lv.original_frames += u32::from(originals);
        }
    }
    Ok(out)
}
