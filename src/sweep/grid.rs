//! The sweep grid: which knob values are measured, and how they combine into builds and runtime variants.
//!
//! A grid is a *star* around a base variant: the base, plus every listed value of one knob with all other
//! knobs at their base value. A full Cartesian product of five build knobs would need dozens of builds;
//! the star needs `1 + Σ (values − 1)` and still shows each knob's effect in isolation.
//!
//! - Build knobs (one paging file per combination): d_min ratio (`d_min = diagonal / R`, paper §5.2.1),
//!   atlas size, border width (§5.2.2), the atlas down-sampling filter (§5.1, box or Kaiser).
//! - Runtime knobs (same file, other frames): texel-per-pixel ratio (scales every `min_distance`, §4) and
//!   paging capacity k (§6; `None`: everything resident).
//! - Texel ratios run on every build when `texel_ratio_on_every_build` (so each build has its own
//!   accuracy-vs-ratio curve); capacities run on the base build only.
//!
//! - Block compression (`none`, `bc1`, `bc7`) is a build knob like the others; ids carry it only when it is
//!   not `none`, so uncompressed ids stay as they were. So are repeats (`wrap`, `bake`) and alpha mips
//!   (`plain`, `coverage`: α-test coverage kept through the mips of MASK textures), named in ids only
//!   when not the default.

use super::SweepError;
use crate::preprocess::image_ops::{AlphaMips, MipFilter};
use crate::preprocess::{BuildOptions, DMin, RepeatMode};
use crate::texfmt::Compression;
use serde::{Deserialize, Serialize};

/// The most frames a grid may ask for per variant.
pub(super) const MAX_FRAMES: usize = 100_000;
/// The largest frame side a grid may ask for, pixels (wgpu's default `max_texture_dimension_2d`).
pub(super) const MAX_SIDE: u32 = 8192;

/// Values of the build-time knobs of one paging file.
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BuildKnobs {
    /// `d_min = scene diagonal / d_min_ratio` (larger: smaller d_min, deeper tree, bigger file).
    pub d_min_ratio: f64,
    /// Atlas side, texels (power of two).
    pub atlas_size: u32,
    /// Border around each packed area, texels.
    pub border: u32,
    /// Atlas mip / inner-atlas down-sampling kernel.
    #[serde(with = "named")]
    pub filter: MipFilter,
    /// Block compression of atlases and original textures.
    #[serde(default, with = "named")]
    pub compress: Compression,
    /// Repeats wrapped in the shader (one period per rect) or baked into the atlas.
    #[serde(default, with = "named")]
    pub repeat: RepeatMode,
    /// Alpha of MASK textures through the mips: plain, or rescaled to keep level 0's coverage.
    #[serde(default, with = "named")]
    pub alpha_mips: AlphaMips,
}

/// Values of the runtime knobs of one variant.
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RuntimeKnobs {
    /// Texels per pixel required at run time (1: the build's guarantee).
    pub texel_ratio: f64,
    /// Paging capacity k in blocks; `None`: every block resident.
    pub capacity: Option<u32>,
}

/// The base variant of a grid (all knobs; JSON: one flat object).
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Base {
    pub d_min_ratio: f64,
    pub atlas_size: u32,
    pub border: u32,
    #[serde(with = "named")]
    pub filter: MipFilter,
    #[serde(default, with = "named")]
    pub compress: Compression,
    #[serde(default, with = "named")]
    pub repeat: RepeatMode,
    #[serde(default, with = "named")]
    pub alpha_mips: AlphaMips,
    pub texel_ratio: f64,
    #[serde(default)]
    pub capacity: Option<u32>,
}

impl Base {
    pub fn build(&self) -> BuildKnobs {
        BuildKnobs {
            d_min_ratio: self.d_min_ratio,
            atlas_size: self.atlas_size,
            border: self.border,
            filter: self.filter,
            compress: self.compress,
            repeat: self.repeat,
            alpha_mips: self.alpha_mips,
        }
    }
    pub fn runtime(&self) -> RuntimeKnobs {
        RuntimeKnobs {
            texel_ratio: self.texel_ratio,
            capacity: self.capacity,
        }
    }
}

/// Values one knob of a grid may list (a star of 8 knobs × 64 values is already days of rendering).
const MAX_KNOB_VALUES: usize = 64;

/// A sweep grid, read from JSON (`--grid FILE`) or a preset ([`Grid::preset`]). Lists may be empty (the
/// knob stays at its base value); a list need not contain the base value.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Grid {
    pub base: Base,
    #[serde(default)]
    pub d_min_ratio: Vec<f64>,
    #[serde(default)]
    pub atlas_size: Vec<u32>,
    #[serde(default)]
    pub border: Vec<u32>,
    #[serde(default, with = "named_list")]
    pub filter: Vec<MipFilter>,
    #[serde(default, with = "named_list")]
    pub compress: Vec<Compression>,
    #[serde(default, with = "named_list")]
    pub repeat: Vec<RepeatMode>,
    #[serde(default, with = "named_list")]
    pub alpha_mips: Vec<AlphaMips>,
    #[serde(default)]
    pub texel_ratio: Vec<f64>,
    #[serde(default)]
    pub capacity: Vec<u32>,
    /// Run every texel ratio on every build (else on the base build only).
    #[serde(default = "yes")]
    pub texel_ratio_on_every_build: bool,
    /// Frames over the path (the CLI's `--frames` overrides).
    #[serde(default = "default_frames")]
    pub frames: usize,
    /// Frame size in pixels (the CLI's `--width` / `--height` override).
    #[serde(default = "default_width")]
    pub width: u32,
    #[serde(default = "default_height")]
    pub height: u32,
}

fn yes() -> bool {
    true
}
fn default_frames() -> usize {
    6
}
fn default_width() -> u32 {
    320
}
fn default_height() -> u32 {
    240
}

/// One build of a [`Plan`] and the runtime variants rendered from it.
#[derive(Clone, Debug, PartialEq)]
pub struct PlannedBuild {
    pub knobs: BuildKnobs,
    /// The grid's base build (renders the reference frames; always first in a plan).
    pub is_base: bool,
    pub runtimes: Vec<RuntimeKnobs>,
}

/// The expanded grid: builds in order, the base first.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    pub builds: Vec<PlannedBuild>,
    /// The grid's base runtime knobs: with the base build, the variant every knob's effect is measured
    /// against.
    pub base_runtime: RuntimeKnobs,
    pub frames: usize,
    pub width: u32,
    pub height: u32,
}

impl Plan {
    /// Number of (build, runtime) variants.
    pub fn variants(&self) -> usize {
        self.builds.iter().map(|b| b.runtimes.len()).sum()
    }
}

impl BuildKnobs {
    /// Stable short name, e.g. `r10_a512_b8_box` (`_bc1`, `_bake` appended when not the default).
    pub fn id(&self) -> String {
        let compress = match self.compress {
            Compression::None => String::new(),
            c => format!("_{}", c.label()),
        };
        let repeat = match self.repeat {
            RepeatMode::Wrap => String::new(),
            r => format!("_{}", r.label()),
        };
        let alpha = match self.alpha_mips {
            AlphaMips::Plain => String::new(),
            m => format!("_alpha-{}", m.name()),
        };
        format!(
            "r{}_a{}_b{}_{}{compress}{repeat}{alpha}",
            crate::util::short_number(self.d_min_ratio),
            self.atlas_size,
            self.border,
            self.filter.name()
        )
    }

    /// Build options with these knobs (the rest default; the paging file may be up to 64 GiB).
    pub fn options(&self) -> BuildOptions {
        BuildOptions {
            d_min: DMin::Ratio(self.d_min_ratio),
            atlas_size: self.atlas_size,
            border: self.border,
            mip_filter: self.filter,
            alpha_mips: self.alpha_mips,
            compress: self.compress,
            repeat: self.repeat,
            ..BuildOptions::default()
        }
    }
}

impl RuntimeKnobs {
    /// Stable short name, e.g. `t0.5_all` or `t1_k32`.
    pub fn id(&self) -> String {
        match self.capacity {
            None => format!("t{}_all", crate::util::short_number(self.texel_ratio)),
            Some(k) => format!("t{}_k{k}", crate::util::short_number(self.texel_ratio)),
        }
    }
}

/// The id of a variant: build id and runtime id.
pub(super) fn variant_id(b: &BuildKnobs, r: &RuntimeKnobs) -> String {
    format!("{}_{}", b.id(), r.id())
}

/// Largest `d_min_ratio` a grid takes ([`Grid::validate`]).
pub(crate) const MAX_D_MIN_RATIO: f64 = 1e9;

impl Grid {
    /// Both around a base of their own, not the build's defaults (d_min ratio 151, atlas 1024): border 16,
    /// repeats wrapped. `small`: data/city in CI time (d_min =
    /// diagonal / 15; 4 builds: atlas 512/1024, box/Kaiser, repeats baked; 4 texel ratios, one capacity, 6
    /// frames of 320×240). `full`: 12 builds (d_min ratio 10/30/60, atlas 512/1024/2048, border 2/8/16 (the
    /// paper's 8), box/Kaiser, compression none/bc1/bc7, repeats wrap/bake, alpha mips plain/coverage),
    /// 4 texel ratios, capacities 32 and 128, 12 frames of 640×480.
    pub fn preset(name: &str) -> Option<Grid> {
        let ratios = vec![0.25, 0.5, 1.0, 2.0];
        match name {
            "small" => Some(Grid {
                base: Base {
                    d_min_ratio: 15.0,
                    atlas_size: 512,
                    border: 16,
                    filter: MipFilter::Box,
                    compress: Compression::None,
                    repeat: RepeatMode::Wrap,
                    alpha_mips: AlphaMips::Plain,
                    texel_ratio: 1.0,
                    capacity: None,
                },
                d_min_ratio: vec![],
                atlas_size: vec![512, 1024],
                border: vec![],
                filter: vec![MipFilter::Box, MipFilter::Kaiser],
                compress: vec![],
                repeat: vec![RepeatMode::Bake],
                alpha_mips: vec![],
                texel_ratio: ratios,
                capacity: vec![24],
                texel_ratio_on_every_build: true,
                frames: 6,
                width: 320,
                height: 240,
            }),
            "full" => Some(Grid {
                base: Base {
                    d_min_ratio: 30.0,
                    atlas_size: 1024,
                    border: 16,
                    filter: MipFilter::Box,
                    compress: Compression::None,
                    repeat: RepeatMode::Wrap,
                    alpha_mips: AlphaMips::Plain,
                    texel_ratio: 1.0,
                    capacity: None,
                },
                d_min_ratio: vec![10.0, 30.0, 60.0],
                atlas_size: vec![512, 1024, 2048],
                border: vec![2, 8, 16],
                filter: vec![MipFilter::Box, MipFilter::Kaiser],
                compress: vec![Compression::Bc1, Compression::Bc7],
                repeat: vec![RepeatMode::Bake],
                alpha_mips: vec![AlphaMips::Coverage],
                texel_ratio: ratios,
                capacity: vec![32, 128],
                texel_ratio_on_every_build: true,
                frames: 12,
                width: 640,
                height: 480,
            }),
            _ => None,
        }
    }

    /// Parses a JSON grid; `origin` names the file in errors.
    pub fn from_json(text: &str, origin: &str) -> Result<Grid, SweepError> {
        serde_json::from_str(text).map_err(|e| SweepError::Grid {
            origin: origin.to_string(),
            message: e.to_string(),
        })
    }

    /// Checks every value (positive, finite, atlas sizes powers of two, at least one frame, at most
    /// [`MAX_FRAMES`] frames of at most [`MAX_SIDE`]² pixels, every planned build's border below a quarter
    /// of its atlas side as the preprocessor requires).
    pub fn validate(&self, origin: &str) -> Result<(), SweepError> {
        let bad = |message: String| {
            Err(SweepError::Grid {
                origin: origin.to_string(),
                message,
            })
        };
        // Each knob's list is bounded before anything iterates it (duplicates are removed by linear
        // search, and every value is at least one build or rendered variant).
        let lengths = [
            ("d_min_ratio", self.d_min_ratio.len()),
            ("atlas_size", self.atlas_size.len()),
            ("border", self.border.len()),
            ("filter", self.filter.len()),
            ("compress", self.compress.len()),
            ("repeat", self.repeat.len()),
            ("alpha_mips", self.alpha_mips.len()),
            ("texel_ratio", self.texel_ratio.len()),
            ("capacity", self.capacity.len()),
        ];
        if let Some((knob, n)) = lengths.iter().find(|(_, n)| *n > MAX_KNOB_VALUES) {
            return bad(format!(
                "{knob} lists {n} values; at most {MAX_KNOB_VALUES} per knob"
            ));
        }
        let b = &self.base;
        let ratios = self.d_min_ratio.iter().chain([&b.d_min_ratio]);
        // Beyond 10⁹ d_min is a billionth of the scene's diagonal: on small scenes the texel density at it
        // overflows, which the preprocessor refuses.
        if let Some(r) =
            (ratios.into_iter()).find(|r| !(r.is_finite() && **r > 0.0 && **r <= MAX_D_MIN_RATIO))
        {
            return bad(format!(
                "d_min_ratio {} must be a number in (0, {}]",
                crate::util::short_number(*r),
                crate::util::short_number(MAX_D_MIN_RATIO)
            ));
        }
        let sizes = self.atlas_size.iter().chain([&b.atlas_size]);
        if let Some(s) = sizes
            .into_iter()
            .find(|s| !crate::preprocess::valid_atlas_size(**s))
        {
            return bad(format!(
                "atlas_size {s} must be a power of two from 64 to 16384"
            ));
        }
        let texel = self.texel_ratio.iter().chain([&b.texel_ratio]);
        if let Some(t) = texel.into_iter().find(|t| !(t.is_finite() && **t > 0.0)) {
            return bad(format!(
                "texel_ratio {} must be a positive number",
                crate::util::short_number(*t)
            ));
        }
        let caps = self.capacity.iter().chain(b.capacity.as_ref());
        if caps.into_iter().any(|k| *k == 0) {
            return bad("capacity 0: a paged renderer needs at least the root blocks".into());
        }
        if self.frames == 0 || self.width == 0 || self.height == 0 {
            return bad(format!(
                "frames {} and size {}×{} must be positive",
                self.frames, self.width, self.height
            ));
        }
        if !crate::report::metrics::ssim_fits(self.width, self.height) {
            let window = crate::report::metrics::SSIM_WINDOW;
            return bad(format!(
                "size {}×{}: every variant's frames are scored by SSIM, which needs at least \
                 {window}×{window} pixels",
                self.width, self.height
            ));
        }
        if self.frames > MAX_FRAMES || self.width > MAX_SIDE || self.height > MAX_SIDE {
            return bad(format!(
                "frames {} and size {}×{} must be at most {MAX_FRAMES} frames of {MAX_SIDE}×{MAX_SIDE}",
                self.frames, self.width, self.height
            ));
        }
        // Every build of the star, as the preprocessor will check it (border < atlas / 4), in u64 so no
        // border overflows the comparison.
        let plan = self.plan();
        if let Some(k) = plan
            .builds
            .iter()
            .map(|b| b.knobs)
            .find(|k| !crate::preprocess::valid_border(k.border, k.atlas_size))
        {
            return bad(format!(
                "border {} must be less than a quarter of atlas_size {} (build {})",
                k.border,
                k.atlas_size,
                k.id()
            ));
        }
        // Values that differ past the ids' 12 significant digits would be two rows under one id.
        let mut seen = std::collections::HashSet::new();
        let mut variants = (plan.builds.iter())
            .flat_map(|b| (b.runtimes.iter()).map(move |r| variant_id(&b.knobs, r)));
        if let Some(id) = variants.find(|id| !seen.insert(id.clone())) {
            return bad(format!(
                "two variants print as {id}: values that agree to 12 significant digits are one value \
                 here; give it once"
            ));
        }
        Ok(())
    }

    /// The builds of the star (base first, duplicates removed) and their runtime variants.
    pub fn plan(&self) -> Plan {
        let base = self.base.build();
        let mut builds = vec![base];
        let mut push = |k: BuildKnobs| {
            if !builds.contains(&k) {
                builds.push(k);
            }
        };
        for &r in &self.d_min_ratio {
            push(BuildKnobs {
                d_min_ratio: r,
                ..base
            });
        }
        for &a in &self.atlas_size {
            push(BuildKnobs {
                atlas_size: a,
                ..base
            });
        }
        for &w in &self.border {
            push(BuildKnobs { border: w, ..base });
        }
        for &f in &self.filter {
            push(BuildKnobs { filter: f, ..base });
        }
        for &c in &self.compress {
            push(BuildKnobs {
                compress: c,
                ..base
            });
        }
        for &r in &self.repeat {
            push(BuildKnobs { repeat: r, ..base });
        }
        for &m in &self.alpha_mips {
            push(BuildKnobs {
                alpha_mips: m,
                ..base
            });
        }
        let builds = builds
            .into_iter()
            .enumerate()
            .map(|(i, knobs)| PlannedBuild {
                knobs,
                is_base: i == 0,
                runtimes: self.runtimes(i == 0),
            })
            .collect();
        Plan {
            builds,
            base_runtime: self.base.runtime(),
            frames: self.frames,
            width: self.width,
            height: self.height,
        }
    }

    /// Runtime variants of the base build (`base`) or another build, duplicates removed.
    fn runtimes(&self, base: bool) -> Vec<RuntimeKnobs> {
        let rb = self.base.runtime();
        let mut out = vec![rb];
        let mut push = |k: RuntimeKnobs| {
            if !out.contains(&k) {
                out.push(k);
            }
        };
        if base || self.texel_ratio_on_every_build {
            for &t in &self.texel_ratio {
                push(RuntimeKnobs {
                    texel_ratio: t,
                    ..rb
                });
            }
        }
        if base {
            for &k in &self.capacity {
                push(RuntimeKnobs {
                    capacity: Some(k),
                    ..rb
                });
            }
        }
        out.sort_by(|a, b| {
            (a.capacity.is_some(), a.capacity, a.texel_ratio)
                .partial_cmp(&(b.capacity.is_some(), b.capacity, b.texel_ratio))
                .unwrap_or(std::cmp::Ordering::Equal)
        });
        out
    }
}

/// A knob value written in grids and reports by its lower-case name, read back with its `FromStr`.
trait Named: std::str::FromStr<Err = String> {
    fn name(&self) -> &'static str;
}

impl Named for crate::preprocess::image_ops::MipFilter {
    fn name(&self) -> &'static str {
        crate::preprocess::image_ops::MipFilter::name(*self)
    }
}

impl Named for AlphaMips {
    fn name(&self) -> &'static str {
        AlphaMips::name(*self)
    }
}

impl Named for crate::preprocess::RepeatMode {
    fn name(&self) -> &'static str {
        self.label()
    }
}

impl Named for crate::texfmt::Compression {
    fn name(&self) -> &'static str {
        self.label()
    }
}

/// serde of a [`Named`] value as its name (`#[serde(with = "named")]`).
mod named {
    use super::Named;
    use serde::{Deserialize, Deserializer, Serializer};

    pub(super) fn serialize<T: Named, S: Serializer>(v: &T, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(v.name())
    }
    pub(super) fn deserialize<'de, T: Named, D: Deserializer<'de>>(d: D) -> Result<T, D::Error> {
        String::deserialize(d)?
            .parse()
            .map_err(serde::de::Error::custom)
    }
}

/// serde of a list of [`Named`] values as their names (`#[serde(with = "named_list")]`).
mod named_list {
    use super::Named;
    use serde::{Deserialize, Deserializer, Serializer};

    pub(super) fn serialize<T: Named, S: Serializer>(v: &[T], s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(v.iter().map(|x| x.name()))
    }
    pub(super) fn deserialize<'de, T: Named, D: Deserializer<'de>>(
        d: D,
    ) -> Result<Vec<T>, D::Error> {
        Vec::<String>::deserialize(d)?
            .iter()
            .map(|s| s.parse().map_err(serde::de::Error::custom))
            .collect()
    }
}
