//! The memory budget of a build (issue 22, `--max-memory`): what the stages need, told up front, and the
//! image cache sized to what is left.
//!
//! A build's peak is the plan (the scene's triangles and the per-triangle sizing, layout and assembly data,
//! all held at once: [`PLAN_BYTES_PER_TRIANGLE`]) or the pixel pass (decoded images in the bounded
//! [`super::image_cache::ImageCache`] with a quarter of headroom (`cache_need`), plus a few atlases in f32 per
//! rasteriser thread). The budget fixes the cache; a budget below what the plan and one pass need is an
//! error before any work, with the number needed. Not bounded yet: the plan's share grows with the
//! triangles (no streaming or spilling), in every shard as in one process.

use serde::Serialize;

/// Bytes per scene triangle the import and plan hold at their peak beyond [`BASE_BYTES`]: measured
/// (`build --shard plan`, peak RSS) 150 B on stk_cornfield_crossing (330 k triangles, 111 MiB), 195 B
/// on stk_black_forest (929 k, 245 MiB), 207 B on the all-tracks world (6.0 M, 1.21 GiB; 235 B before
/// the prepared records stopped holding their corners); rounded up, ~1.2× the largest (the old 300 B was
/// ~1.3× its 235 B). Measured with repeats wrapped; baked, a cut piece is a record of its own and keeps
/// its corners (72 bytes more).
pub const PLAN_BYTES_PER_TRIANGLE: u64 = 250;
/// Bytes each piece beyond the first that a triangle is cut into where repeats are baked (`--repeat
/// bake`) adds at the plan's peak (the assembly): its record, its own corners (3 × 3 f64) and about two
/// vertices of its own (cut pieces share few): measured ~500 (2,048 quads cut into 2,097,152 pieces,
/// assembly peak 1.07 GiB; 322 = a triangle's 250 + its corners let that build peak 18 % over its stated
/// need: review of session 32), rounded up ~1.1×.
pub const BAKED_PIECE_BYTES: u64 = 550;
/// Bytes each vertex beyond one a triangle adds at the plan's peak (a triangle soup, one vertex a corner;
/// a mesh instanced by many nodes, its vertices copied per instance): the leaf geometry and its vertex
/// lookup grow with the vertices, which [`PLAN_BYTES_PER_TRIANGLE`] (measured on indexed meshes, about
/// one vertex a triangle) leaves out. 3 M soup triangles (9 M vertices) peaked at 2.00 GiB against 924
/// MiB stated, and 2¹⁶ instances of a 64-triangle mesh (4.2 M triangles, 12.6 M vertices) passed a
/// 1,500 MiB budget and aborted allocating (fault hunt, session 36): ~130 bytes a vertex beyond one a
/// triangle, rounded up to 160; at 160, 1.5 M and 3 M soup triangles admitted at their stated need
/// peaked 7 % and 12 % over it, at the assembly (1,095 MiB for 1,024, 2,060 for 1,839; session 37):
/// ~199 bytes measured, rounded up ~1.1× as the constants above.
pub const PLAN_BYTES_PER_EXTRA_VERTEX: u64 = 220;
/// Bytes the import holds per byte of glTF JSON while it parses it (the text, its `serde_json` value,
/// the `gltf` document and the raw nodes and materials, all alive at once; freed before the plan):
/// measured 13.5 (21.5 MB of JSON for 40,000 one-quad primitives, import peak 357 MiB: 290 over the
/// base and the triangles), rounded up.
pub const JSON_BYTES_FACTOR: u64 = 16;
/// The process itself, its libraries and small tables.
pub const BASE_BYTES: u64 = 64 << 20;
/// Decoded bytes per source texel in the image cache: RGBA8 (4) and the linear f32 mip chain (16 × 4/3).
/// The cache holds at most one of each image, whoever draws it (`image_cache::ImageCache::get`): measured
/// peak 6.45 GiB for a build of one 16384² texture (268 M texels, 25.8 bytes a texel with everything
/// else the process holds).
pub const CACHE_BYTES_PER_TEXEL: u64 = 26;
/// Atlases' worth of f32 RGBA texels one rasteriser thread holds (the atlas, its mip chain, the halves of
/// its children waiting to be combined, the encoded block). Beside them, not counted: the colour bleed's
/// 8 bytes a texel of the level it converts (kept between levels up to 16 MiB a thread; a 4096²
/// original's level 0 takes 128 MiB while it is converted), which the slack below the cache covers.
pub const ATLASES_PER_THREAD: u64 = 4;
/// The image cache gets 1/this of what plan and rasteriser leave: with the quarter of headroom on top,
/// 5/12 of it. The rest covers what the model leaves out — decode buffers, entries still held by a thread
/// after eviction (a leaf's images stay held while it is drawn), the allocator's retained pages: measured
/// 160–300 MiB over the model's sum on Berlin ×1 and a Berlin ×4 shard at a 2 GiB budget with a 4/5 share
/// (peaks 2.09 and 2.34 GiB), and growing with the cache: a planned shard of the all-tracks world tiled
/// 2 × 2 at 2 GiB peaked at 0.81, 1.59 and 2.18 GiB with caches of 256, 600 and 971 MiB (the last the 1/2
/// share), so the share is 1/3.
pub const CACHE_SHARE_DIVISOR: u64 = 3;
/// Bytes a rasteriser thread holds outside the cache per stored texel of an original texture it
/// resamples and encodes (`image_cache::ImageCache::original`): the resampled f32 chain (21.3), its RGBA8
/// chain (5.3) and the encoded chain (at most 5.3). Stored sides are powers of two up to
/// [`crate::model::MAX_ORIGINAL_CLASS`] (`originals::original_extent`), so a 1025² source is
/// resampled to 2048²: 16 such sources at a stated need of 325 MiB peaked at 394 (fault hunt, session
/// 33).
pub const ORIGINAL_RESAMPLED_BYTES_PER_TEXEL: u64 = 32;
/// [`ORIGINAL_RESAMPLED_BYTES_PER_TEXEL`] for an original stored at its source's own sides (taken from
/// the cached chain: its RGBA8 levels, 5.3, and the encoded chain, at most 5.3), unless alpha mips keep
/// coverage (`--alpha-mips coverage`: the chain is copied in f32 first, as resampled).
pub const ORIGINAL_COPIED_BYTES_PER_TEXEL: u64 = 11;
/// Smallest image cache worth running with.
pub const MIN_IMAGE_CACHE: u64 = 64 << 20;

/// What the plan holds: the scene's triangles and, where repeats are baked, the pieces beyond one a
/// triangle that `prepare::prepare` cuts them into (`prepare::count_pieces`), counted before they exist:
/// a baked build of 2,048 triangles accepted at 300 MiB peaked at 1.08 GiB (fault hunt, session 32).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PlanLoad {
    pub triangles: u64,
    pub extra_pieces: u64,
    /// The scene's vertices beyond one a triangle ([`PLAN_BYTES_PER_EXTRA_VERTEX`] each).
    pub extra_vertices: u64,
}

impl PlanLoad {
    /// `triangles` whole triangles, none cut.
    pub fn triangles(triangles: u64) -> PlanLoad {
        PlanLoad {
            triangles,
            extra_pieces: 0,
            extra_vertices: 0,
        }
    }

    /// What the import and plan hold beyond [`BASE_BYTES`].
    pub fn bytes(self) -> u64 {
        (self.triangles.saturating_mul(PLAN_BYTES_PER_TRIANGLE))
            .saturating_add(self.extra_pieces.saturating_mul(BAKED_PIECE_BYTES))
            .saturating_add(
                self.extra_vertices
                    .saturating_mul(PLAN_BYTES_PER_EXTRA_VERTEX),
            )
    }
}

/// The images a pixel pass may decode, as the image cache holds them: each image at most once in the
/// process (its chain is built by one thread while the others that need it wait, and taken back while
/// any thread still holds it after its eviction: `image_cache::ImageCache::get`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ImageLoad {
    /// Texels of the largest image.
    pub largest_texels: u64,
    /// Texels of the `threads` largest images together: what the rasteriser threads hold at once
    /// when each draws from another of the largest images.
    pub per_thread_texels: u64,
    /// Texels of all the images together: the cache and the threads never hold more than each once.
    pub all_texels: u64,
    /// Bytes the threads hold beside the cache while each resamples and encodes one of the largest
    /// original textures ([`ORIGINAL_RESAMPLED_BYTES_PER_TEXEL`]).
    pub originals_scratch_bytes: u64,
}

impl ImageLoad {
    /// The load of images of `(width, height)` each, drawn by `threads` rasteriser threads
    /// ([`ImageLoad::with_coverage_mips`] where alpha mips keep coverage).
    pub fn of(sides: impl IntoIterator<Item = (u32, u32)>, threads: u64) -> ImageLoad {
        Self::counted(sides, threads, ORIGINAL_COPIED_BYTES_PER_TEXEL)
    }

    /// [`ImageLoad::of`] for a build whose alpha mips keep coverage: an original stored at its source's
    /// sides is copied in f32 first, so it weighs as a resampled one.
    pub fn with_coverage_mips(
        sides: impl IntoIterator<Item = (u32, u32)>,
        threads: u64,
    ) -> ImageLoad {
        Self::counted(sides, threads, ORIGINAL_RESAMPLED_BYTES_PER_TEXEL)
    }

    fn counted(
        sides: impl IntoIterator<Item = (u32, u32)>,
        threads: u64,
        copied: u64,
    ) -> ImageLoad {
        let sides: Vec<(u32, u32)> = sides.into_iter().collect();
        let mut texels: Vec<u64> = (sides.iter())
            .map(|&(w, h)| u64::from(w) * u64::from(h))
            .collect();
        let mut scratch: Vec<u64> = (sides.iter())
            .map(|&(w, h)| {
                let [sw, sh] = super::originals::original_extent(w, h);
                let per_texel = if [sw, sh] == [w, h] {
                    copied
                } else {
                    ORIGINAL_RESAMPLED_BYTES_PER_TEXEL
                };
                u64::from(sw) * u64::from(sh) * per_texel
            })
            .collect();
        let threads = usize::try_from(threads.max(1)).unwrap_or(usize::MAX);
        let largest_sum = |v: &mut Vec<u64>| {
            v.sort_unstable_by(|a, b| b.cmp(a));
            v.iter()
                .take(threads)
                .fold(0u64, |s, &x| s.saturating_add(x))
        };
        ImageLoad {
            largest_texels: texels.iter().copied().max().unwrap_or(0),
            per_thread_texels: largest_sum(&mut texels),
            all_texels: texels.iter().fold(0u64, |s, &x| s.saturating_add(x)),
            originals_scratch_bytes: largest_sum(&mut scratch),
        }
    }
}

/// How a build spends its memory budget (bytes).
#[derive(Clone, Debug, Serialize, serde::Deserialize, PartialEq, Eq)]
pub struct MemoryPlan {
    /// `--max-memory`.
    pub budget: u64,
    /// Import and plan: triangles × [`PLAN_BYTES_PER_TRIANGLE`] + [`BASE_BYTES`].
    pub plan_bytes: u64,
    /// Rasteriser threads' working atlases.
    pub raster_bytes: u64,
    /// The image cache's bound (the need adds a quarter of it as headroom, `cache_need`).
    pub image_cache_bytes: u64,
    /// The least budget this build runs in: plan, raster and a cache that holds the threads' largest
    /// images (at least [`MIN_IMAGE_CACHE`]), never more than every image once.
    pub needed_bytes: u64,
}

/// Why a budget is too small.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[error(
    "the build needs about {needed_mib} MiB ({plan_mib} MiB for the plan: {}; {raster_mib} MiB for {threads} \
     rasteriser {}; {cache_mib} MiB of image cache: {}), over the budget of {budget_mib} MiB (--max-memory; \
     by default half the memory this process may use): raise --max-memory{}{}",
    plan_why(*.triangles, *.extra_pieces, *.extra_vertices),
    if *.threads == 1 { "thread" } else { "threads" },
    cache_why(.largest_image, **.images, *.threads),
    if *.threads > 1 { ", or run fewer rasteriser threads (RAYON_NUM_THREADS=N: each holds its atlases \
     and its images)" } else { "" },
    if *.triangles > 0 { ", or for a sharded build plan once (`build --shard plan`): its shards then hold no \
     triangles" } else { "" }
)]
pub struct MemoryError {
    pub budget_mib: u64,
    pub needed_mib: u64,
    pub triangles: u64,
    /// Pieces beyond one a triangle where repeats are baked ([`PlanLoad::extra_pieces`]).
    pub extra_pieces: u64,
    /// [`PlanLoad::extra_vertices`].
    pub extra_vertices: u64,
    pub plan_mib: u64,
    pub raster_mib: u64,
    pub threads: u64,
    pub cache_mib: u64,
    /// Boxed: the error stays small where it is passed back (clippy `result_large_err`).
    pub images: Box<ImageLoad>,
    /// The largest image's name; filled in by the caller, who knows the images ([`MemoryError::naming`]).
    pub largest_image: String,
}

impl MemoryError {
    /// The error with the largest image named (a forged or absurd image header shows up here).
    pub fn naming(mut self, largest_image: &str) -> Self {
        self.largest_image = largest_image.to_string();
        self
    }
}

/// What the plan's share holds, in words: the process's fixed base and the triangles held, or for a
/// shard that read a plan file (no triangles) the base and the tables' skeleton.
fn plan_why(triangles: u64, extra_pieces: u64, extra_vertices: u64) -> String {
    let base = BASE_BYTES >> 20;
    if extra_vertices > 0 {
        let pieces = if extra_pieces > 0 {
            format!(" (cut into {extra_pieces} more pieces where repeats are baked)")
        } else {
            String::new()
        };
        format!(
            "a {base} MiB base and {triangles} triangles held{pieces}, with {extra_vertices} vertices beyond \
             one a triangle (unshared corners, or meshes instanced with their vertices)"
        )
    } else if extra_pieces > 0 {
        format!(
            "a {base} MiB base and {triangles} triangles held, cut into {extra_pieces} more pieces where \
             repeats are baked (--repeat bake; --repeat wrap cuts none, a smaller --max-pieces fewer)"
        )
    } else if triangles > 0 {
        format!("a {base} MiB base and {triangles} triangles held")
    } else {
        format!("a {base} MiB base and the plan file's tables, no triangles")
    }
}

/// Why the image cache needs what it needs ([`cache_need`]): every image once where that is less
/// (one huge texture), else the threads' largest images in the cache where they pass its minimum
/// ([`MIN_IMAGE_CACHE`]), or the minimum (a small image is not the cause; the docs hunt of session 29
/// found a 64² texture blamed for 80 MiB), and each thread's image once more while it is decoded.
fn cache_why(largest_image: &str, images: ImageLoad, threads: u64) -> String {
    let ImageLoad {
        largest_texels,
        per_thread_texels,
        all_texels,
        originals_scratch_bytes,
    } = images;
    let need = cache_need(images);
    let (all_bound, big) = (need.every_image_bound, need.floor > MIN_IMAGE_CACHE);
    let min_mib = MIN_IMAGE_CACHE >> 20;
    let shares = if all_bound && big {
        format!(
            "every image once ({all_texels} texels; the largest, {largest_image}: {largest_texels}), \
             with a quarter of headroom; downscale the largest if it dominates"
        )
    } else if all_bound {
        // Small images are not blamed (session 29's docs hunt found a 64² texture blamed for 80 MiB).
        format!(
            "a quarter of the cache's minimum of {min_mib} MiB as headroom and every image once \
             ({all_texels} texels)"
        )
    } else if big && threads == 1 {
        format!(
            "the largest image, {largest_image}: {largest_texels} texels, in the cache and once more \
             while it is decoded; downscale it if it dominates"
        )
    } else if big {
        format!(
            "the {threads} largest images ({per_thread_texels} texels; the largest, {largest_image}: \
             {largest_texels}), one a thread in the cache and once more while it is decoded; downscale \
             the largest if they dominate"
        )
    } else {
        // The in-flight share is in the number: named here too (hacienda's shard said 132 MiB for "the
        // minimum of 64 MiB with a quarter", 52 unexplained; fault hunt, session 32).
        format!(
            "the cache's minimum of {min_mib} MiB with a quarter of headroom, and each thread's image \
             (the largest, {largest_image}, {largest_texels} texels) once more while it is decoded"
        )
    };
    let threads_do = if threads == 1 {
        "thread resamples and encodes"
    } else {
        "threads resample and encode"
    };
    format!(
        "{shares}, including {} MiB for the originals the {threads} {threads_do}",
        originals_scratch_bytes.div_ceil(1 << 20)
    )
}

/// What the image cache and the images in flight need at most (`threads` rasteriser threads), with the
/// flag: that is every image once (less than the per-thread count).
///
/// The floor holds the threads' largest images, one each ([`ImageLoad::per_thread_texels`], at least
/// [`MIN_IMAGE_CACHE`]) with a quarter of it as headroom (it held a cache of encoded originals until
/// session 34, when each original came to be encoded once and the cache went; the measured peaks the
/// model was checked against include it, up to 1.21× the need in session 33's memory hunt, so it stays);
/// and each thread holds its
/// image outside the cache while it decodes it and builds its chain (or holds it, evicted, while its
/// leaf is drawn): at the old need, without that, black_forest peaked 13 % over the budget (674 MiB:
/// 759) and a planned shard of it 22 % (512 MiB: 626; session 30's memory hunt). As the process holds
/// an image at most once, all that never passes every image once with the quarter. Beside
/// either, each thread resamples and encodes an original texture outside the cache
/// ([`ImageLoad::originals_scratch_bytes`]).
fn cache_need(images: ImageLoad) -> CacheNeed {
    let bytes = |texels: u64| texels.saturating_mul(CACHE_BYTES_PER_TEXEL);
    let per_threads = bytes(images.per_thread_texels);
    let floor = per_threads.max(MIN_IMAGE_CACHE);
    let in_flight = per_threads;
    let counted = floor.saturating_add(floor / 4).saturating_add(in_flight);
    let every_image = bytes(images.all_texels).saturating_add(floor / 4);
    CacheNeed {
        floor,
        bytes: (counted.min(every_image)).saturating_add(images.originals_scratch_bytes),
        every_image_bound: every_image < counted,
    }
}

/// [`cache_need`]: the cache's floor (the least bound it runs with), what the cache, the images in
/// flight and the originals being encoded need, and whether "every image once" set it.
struct CacheNeed {
    floor: u64,
    bytes: u64,
    every_image_bound: bool,
}

/// Why the plan step of a sharded build does not fit its budget.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[error(
    "the plan needs about {needed_mib} MiB ({triangles} triangles{}{}, all held at once while planning), over \
     the budget of {budget_mib} MiB (--max-memory; by default half the memory this process may use): plan on a machine with more memory (--max-memory {needed_mib}MiB or more; the \
     budget is not part of the plan's key, so the shards may keep a small one)",
    if *.extra_pieces > 0 { format!(" and {} more pieces where repeats are baked", .extra_pieces) } else { String::new() },
    if *.extra_vertices > 0 { format!(", {} vertices beyond one a triangle", .extra_vertices) } else { String::new() }
)]
pub struct PlanStepMemoryError {
    pub budget_mib: u64,
    pub needed_mib: u64,
    pub triangles: u64,
    pub extra_pieces: u64,
    pub extra_vertices: u64,
}

/// Splits `budget` between plan, rasteriser threads and the image cache (at most `cache_wanted`); fails when
/// even the smallest cache does not fit.
pub fn plan_memory(
    budget: u64,
    load: PlanLoad,
    atlas_size: u32,
    threads: u64,
    images: ImageLoad,
    cache_wanted: u64,
) -> Result<MemoryPlan, MemoryError> {
    let pixels = PixelNeeds {
        atlas_size,
        threads,
        images,
        cache_wanted,
    };
    split_budget(budget, load.bytes(), load, pixels)
}

/// [`plan_memory`] for the plan step of a sharded build (`build --shard plan`): the plan alone, no pixel
/// pass and so no image cache.
pub fn plan_step_memory(budget: u64, load: PlanLoad) -> Result<MemoryPlan, PlanStepMemoryError> {
    let plan_bytes = BASE_BYTES.saturating_add(load.bytes());
    if plan_bytes > budget {
        return Err(PlanStepMemoryError {
            budget_mib: budget >> 20,
            needed_mib: plan_bytes.div_ceil(1 << 20),
            triangles: load.triangles,
            extra_pieces: load.extra_pieces,
            extra_vertices: load.extra_vertices,
        });
    }
    Ok(MemoryPlan {
        budget,
        plan_bytes,
        raster_bytes: 0,
        image_cache_bytes: 0,
        needed_bytes: plan_bytes,
    })
}

/// [`plan_memory`] for a shard that read a plan file: it holds no triangle, only the skeleton of the plan's
/// tables (`skeleton_bytes`: nodes, leaves, rects, originals, blocks).
pub fn planned_shard_memory(
    budget: u64,
    skeleton_bytes: u64,
    atlas_size: u32,
    threads: u64,
    images: ImageLoad,
    cache_wanted: u64,
) -> Result<MemoryPlan, MemoryError> {
    let pixels = PixelNeeds {
        atlas_size,
        threads,
        images,
        cache_wanted,
    };
    split_budget(budget, skeleton_bytes, PlanLoad::default(), pixels)
}

/// What the pixel pass's share of a budget depends on.
struct PixelNeeds {
    atlas_size: u32,
    threads: u64,
    images: ImageLoad,
    cache_wanted: u64,
}

/// The split of [`plan_memory`]: `held` bytes of plan data (for `load`) besides [`BASE_BYTES`].
fn split_budget(
    budget: u64,
    held: u64,
    load: PlanLoad,
    pixels: PixelNeeds,
) -> Result<MemoryPlan, MemoryError> {
    let PixelNeeds {
        atlas_size,
        threads,
        images,
        cache_wanted,
    } = pixels;
    let plan_bytes = BASE_BYTES.saturating_add(held);
    let raster_bytes = raster_bytes(atlas_size, threads);
    let CacheNeed {
        floor,
        bytes: cache_bytes,
        ..
    } = cache_need(images);
    let needed_bytes = plan_bytes
        .saturating_add(raster_bytes)
        .saturating_add(cache_bytes);
    if needed_bytes > budget {
        let mib = |b: u64| b.div_ceil(1 << 20);
        return Err(MemoryError {
            budget_mib: budget >> 20,
            needed_mib: mib(needed_bytes),
            triangles: load.triangles,
            extra_pieces: load.extra_pieces,
            extra_vertices: load.extra_vertices,
            plan_mib: mib(plan_bytes),
            raster_mib: mib(raster_bytes),
            threads,
            cache_mib: mib(cache_bytes),
            images: Box::new(images),
            largest_image: "?".to_string(),
        });
    }
    let left = budget - plan_bytes - raster_bytes;
    Ok(MemoryPlan {
        budget,
        plan_bytes,
        raster_bytes,
        image_cache_bytes: (left / CACHE_SHARE_DIVISOR).min(cache_wanted).max(floor),
        needed_bytes,
    })
}

/// The rasteriser threads' working atlases: `threads` (at least one) × [`ATLASES_PER_THREAD`] f32 RGBA
/// atlases of `atlas_size`² texels, in bytes.
fn raster_bytes(atlas_size: u32, threads: u64) -> u64 {
    let atlas = u64::from(atlas_size).pow(2) * 16;
    threads
        .max(1)
        .saturating_mul(ATLASES_PER_THREAD)
        .saturating_mul(atlas)
}

/// Why a budget is too small for any scene: below the process's base and the pixel pass's least share.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[error(
    "any build at --atlas-size {atlas_size} needs at least {needed_mib} MiB, whatever its scene ({} MiB of \
     process base, {raster_mib} MiB for {threads} rasteriser {} and {headroom_mib} MiB of image-cache \
     headroom; the scene's triangles and images add to that), over the budget of {budget_mib} MiB \
     (--max-memory; by default half the memory this process may use): raise --max-memory{}",
    BASE_BYTES >> 20,
    if *.threads == 1 { "thread's atlases" } else { "threads' atlases" },
    if *.threads > 1 { ", or run fewer rasteriser threads (RAYON_NUM_THREADS=N)" } else { "" }
)]
pub struct PixelFloorError {
    pub budget_mib: u64,
    pub needed_mib: u64,
    pub atlas_size: u32,
    pub raster_mib: u64,
    pub threads: u64,
    pub headroom_mib: u64,
}

/// Checks, before the scene is read, that `budget` holds what every build (or shard) with `threads`
/// rasteriser threads at `atlas_size` needs whatever its scene: [`BASE_BYTES`], the threads' atlases
/// and the image cache's headroom (a quarter of [`MIN_IMAGE_CACHE`]: [`cache_need`] with no image at
/// all). A budget below it was refused stage by stage, each refusal naming only its own stage's need
/// (40, 65, 66, 67, then 265 MiB on `data/city`; fault hunt, session 37); the plan step, which draws no
/// pixel, is not checked.
pub fn check_pixel_floor(
    budget: u64,
    atlas_size: u32,
    threads: u64,
) -> Result<(), PixelFloorError> {
    let raster = raster_bytes(atlas_size, threads);
    let headroom = MIN_IMAGE_CACHE / 4;
    let needed = BASE_BYTES.saturating_add(raster).saturating_add(headroom);
    if needed <= budget {
        return Ok(());
    }
    Err(PixelFloorError {
        budget_mib: budget >> 20,
        needed_mib: needed.div_ceil(1 << 20),
        atlas_size,
        raster_mib: raster.div_ceil(1 << 20),
        threads: threads.max(1),
        headroom_mib: headroom >> 20,
    })
}

/// The most bytes of scene input (the file and its buffers, held whole while the import reads them) within
/// `budget`: all of it but [`BASE_BYTES`] (`scene::ImportOptions::max_input_bytes`; a planned shard of a
/// GLB reads the file whole for its images, and counts it).
pub fn max_input_bytes(budget: u64) -> u64 {
    budget.saturating_sub(BASE_BYTES)
}

/// The most triangles a plan holds within `budget` bytes ([`PLAN_BYTES_PER_TRIANGLE`] each beyond
/// [`BASE_BYTES`]): the import refuses a scene past it during its node walk, before reading a vertex
/// (`scene::ImportOptions::max_triangles`). The full check, with the pixel pass, follows the import.
pub fn max_plan_triangles(budget: u64) -> u64 {
    budget.saturating_sub(BASE_BYTES) / PLAN_BYTES_PER_TRIANGLE
}

/// The largest glTF JSON the import parses within `budget` beside [`BASE_BYTES`]
/// ([`JSON_BYTES_FACTOR`] bytes a byte): `scene::ImportOptions::max_json_bytes`, which also leaves the
/// triangles only the rest of the budget.
pub fn max_json_bytes(budget: u64) -> u64 {
    budget.saturating_sub(BASE_BYTES) / JSON_BYTES_FACTOR
}

/// The default budget: half of the memory this process may use where the platform tells (Linux
/// `MemTotal`, or its cgroup's limit where smaller: a Slurm job, a Kubernetes pod), else none.
pub fn default_budget() -> Option<u64> {
    crate::util::memory_limit_bytes().map(|m| m / 2)
}

#[cfg(test)]
mod tests;
