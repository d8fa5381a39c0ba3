//! The image cache of the pixel pass: each scene image decoded once and held with its linear-light mip
//! chain within a byte budget (`--max-memory`'s image share), one thread building an image's chain while
//! the others that need it wait; and the original textures resampled and encoded from those chains.
//! [`super::raster`] draws atlases from it.

use super::BuildError;
use super::image_ops::{
    CoverageRegion, LinearImage, MipChain, mip_chain_rgba8, preserve_coverage, resample_rect,
};
use super::raster::image_err;
use crate::ids::ImageId;
use crate::scene::{DecodedImage, Scene};
use crate::texfmt::{Encoded, TexFormat, encode_chain_rect, encode_levels_rect};
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// A decoded image and its linear-light mip chain, shared between leaves.
pub struct CachedImage {
    pub decoded: Arc<DecodedImage>,
    pub chain: MipChain,
}

impl CachedImage {
    /// The RGBA8 mip levels of this image stored at its own sides: what [`mip_chain_rgba8`] of
    /// [`resample_rect`] gives where [`resample_is_identity`] holds, without resampling or a second chain
    /// (the cached chain is that chain: box-filtered, and the box ignores wrap). Level 0 of an image
    /// without translucent texels is the decoded bytes themselves, borrowed: sRGB8 → linear → sRGB8 is
    /// the identity on opaque texels ([`super::image_ops::srgb8_to_linear`]).
    fn stored_levels_rgba8(&self) -> Vec<std::borrow::Cow<'_, [u8]>> {
        use std::borrow::Cow;
        let mut levels = self.chain.levels.iter();
        let mut out = Vec::with_capacity(self.chain.levels.len());
        if self.decoded.is_opaque() {
            out.push(Cow::Borrowed(self.decoded.pixels.as_flattened()));
            levels.next();
        }
        out.extend(levels.map(|l| Cow::Owned(l.to_rgba8())));
        out
    }

    /// Bytes it holds: the linear chain and the decoded pixels.
    pub(super) fn bytes(&self) -> u64 {
        let chain: u64 = self
            .chain
            .levels
            .iter()
            .map(|l| l.data.len() as u64 * 16)
            .sum();
        chain + self.decoded.pixels.len() as u64 * 4
    }
}

/// A bounded cache of decoded images, so a scene with hundreds of textures never holds them all decoded
/// (issue: lazy decoding). Two tiers, each least recently used first out: the images with their linear
/// mip chains (what rasterising reads; ~21 bytes a texel) within 3/4 of `cap_bytes`, and the decoded
/// sRGB8 images alone (4 bytes a texel) within 1/4, so an image whose chain was evicted is rebuilt from
/// its pixels (~2 ms per Mtexel) rather than decoded again (PNG: ~10 ms per Mtexel). On a 23.8 M-triangle
/// world whose leaves draw the same textures far apart, the one-tier cache decoded 870 images 33,767 times.
pub struct ImageCache<'a> {
    scene: &'a Scene,
    cap_bytes: u64,
    chains: Mutex<Lru<Arc<CachedImage>>>,
    sources: Mutex<Lru<Arc<DecodedImage>>>,
    pub decodes: AtomicU64,
    /// Texels of the images decoded (each decode counted, so re-decodes after eviction too).
    pub decoded_texels: AtomicU64,
    pub warnings: Mutex<Vec<String>>,
    /// Per image: every material that uses it is OPAQUE, so its alpha channel is ignored (glTF: "the
    /// rendered output is fully opaque and any alpha value is ignored"). Decoded with alpha 1, such an
    /// image keeps the colour of texels whose stored alpha is 0 (premultiplying would lose it).
    opaque_only: Vec<bool>,
    /// Per image, what was noted of its decodes ([`NOTED_ALPHA_IGNORED`]: its alpha ignored although
    /// some texel had alpha < 255; [`NOTED_FALLBACK`]: it failed and the visible fallback replaced it),
    /// once however often it is decoded again after eviction: [`Self::fallbacks`],
    /// [`Self::alpha_ignored`].
    noted: Vec<std::sync::atomic::AtomicU8>,
    /// Per image: its chain entry while anything holds it (this cache, or a thread drawing a leaf after
    /// the entry's eviction), so an image has one chain in the process, whoever asks for it
    /// ([`Self::get`]; the memory budget counts each image once: `memory::ImageLoad`).
    live: Vec<Mutex<std::sync::Weak<CachedImage>>>,
    /// The images whose entries a thread is building now; the threads that need one of them too wait on
    /// [`Self::built`] and take the result.
    building: Mutex<std::collections::HashSet<ImageId>>,
    built: std::sync::Condvar,
    /// Chain entries built (each image once, again only after its entry was evicted and let go).
    pub chain_builds: AtomicU64,
    /// Per image: `xxh3_128` of the pixels its first decode gave (before an OPAQUE-only image's alpha is
    /// dropped, so the scene images of one glTF image hash alike; the fallback's own when it failed). A
    /// shard file carries them, so the merge refuses shards that decoded one file to different pixels
    /// ([`Self::pixel_hashes`]).
    pixel_hashes: Vec<std::sync::OnceLock<[u64; 2]>>,
    /// Per image: the other scene images read from the same file ([`file_twins`]).
    twins: Vec<Vec<usize>>,
    /// Images a later decode (after eviction) gave other pixels than the first: the file changed during
    /// the build ([`Self::check_decodes`]).
    changed: Mutex<Vec<ImageId>>,
    /// The first decode the open-files limit stopped (`SceneError::OutOfDescriptors`): a limit of the
    /// machine, not of the image, so the build fails ([`Self::check_decodes`]) where it drew the
    /// fallback and exited 0 (fault hunt, session 38).
    out_of_descriptors: Mutex<Option<crate::scene::SceneError>>,
    /// Original textures stored smaller than their source (a side above
    /// [`crate::model::MAX_ORIGINAL_CLASS`]): by image, its decoded and its stored sides (reported).
    pub downsampled: Mutex<std::collections::BTreeMap<ImageId, Downsampled>>,
    /// Original textures stored larger than their source on a side (not a power of two, or under
    /// [`crate::model::MIN_ORIGINAL_CLASS`]): by image, its decoded and its stored sides (reported).
    pub upsampled: Mutex<std::collections::BTreeMap<ImageId, Downsampled>>,
}

/// A cache that decoded `images` distinct images `decodes` times in all, with a bound of `cap_bytes`:
/// a warning where it decoded them more than [`REDECODE_RATIO`] times each on average and at least
/// [`REDECODE_MIN`] times more than once, else `None`. The file is the same whatever the cache holds,
/// but each decode costs time: the all-tracks world given exactly the `--max-memory` its refusal named
/// decoded its 870 images ~9,000 times in 139 s, against 932 decodes in 39 s with the default budget,
/// and said nothing (fault hunt, session 39).
pub fn redecode_note(decodes: u64, images: u64, cap_bytes: u64) -> Option<String> {
    let again = decodes.saturating_sub(images);
    if images == 0 || decodes <= images.saturating_mul(REDECODE_RATIO) || again < REDECODE_MIN {
        return None;
    }
    Some(format!(
        "the image cache ({}) decoded {images} images {decodes} times ({:.2} each): it holds too few \
         of them at once for how this scene's leaves share them; a larger --max-memory (the cache gets \
         what the plan and the pixel pass leave) or --image-cache-mib builds the same file with fewer \
         decodes",
        crate::util::human_bytes(cap_bytes),
        decodes as f64 / images as f64
    ))
}

/// Decodes per image past which [`redecode_note`] warns.
pub const REDECODE_RATIO: u64 = 2;
/// Decodes beyond one an image below which [`redecode_note`] stays silent (a small scene's few evictions).
pub const REDECODE_MIN: u64 = 64;

/// [`ImageCache::first_note`]: the image's alpha was ignored (OPAQUE materials only).
const NOTED_ALPHA_IGNORED: u8 = 1;
/// [`ImageCache::first_note`]: the image fell back to the magenta checker.
const NOTED_FALLBACK: u8 = 2;

/// An original texture stored smaller than its source: the decoded `[width, height]`, then the stored.
pub type Downsampled = ([u32; 2], [u32; 2]);

/// An original texture as stored: image, stored `[width, height]`, wrap modes (resampling depends on
/// them), storage format and compared channels (the encoding depends on them), and the bits of the MASK
/// cutoff whose coverage its mips keep ([`AlphaMips::Coverage`]; `None`: plain mips).
pub type OriginalKey = (
    ImageId,
    [u32; 2],
    [crate::scene::Wrap; 2],
    TexFormat,
    usize,
    Option<u32>,
);
/// Per scene image, the other scene images read from the same file: one glTF image (its OPAQUE and
/// alpha twins), or glTF images naming one path (two `images` entries with the same `uri`: replaced
/// during a build, they mixed two versions without a word; fault hunt, session 37). Mostly empty.
fn file_twins(scene: &Scene) -> Vec<Vec<usize>> {
    use crate::scene::ImageData;
    let mut groups: std::collections::HashMap<FileKey<'_>, Vec<usize>> = Default::default();
    for (i, img) in scene.images.iter().enumerate() {
        let key = match (&img.data, img.gltf_image) {
            (ImageData::File(p), _) => FileKey::Path(p),
            (_, Some(g)) => FileKey::Gltf(g),
            _ => continue,
        };
        groups.entry(key).or_default().push(i);
    }
    let mut twins = vec![Vec::new(); scene.images.len()];
    for group in groups.values().filter(|g| g.len() > 1) {
        for &i in group {
            twins[i] = group.iter().copied().filter(|&j| j != i).collect();
        }
    }
    twins
}

/// What names an image's file: its path, else its glTF image.
#[derive(PartialEq, Eq, Hash)]
enum FileKey<'a> {
    Path(&'a std::path::Path),
    Gltf(u32),
}

/// Per image of `scene`: used by at least one material and by OPAQUE materials only.
fn opaque_only_images(scene: &Scene) -> Vec<bool> {
    let mut used = vec![false; scene.images.len()];
    let mut alpha = vec![false; scene.images.len()];
    for m in &scene.materials {
        if let Some(u) = used.get_mut(m.image.idx()) {
            *u = true;
            alpha[m.image.idx()] |= m.alpha.uses_alpha();
        }
    }
    used.iter().zip(&alpha).map(|(&u, &a)| u && !a).collect()
}

/// Values by image, at most `cap` bytes of them (a value of its own larger than `cap` stays alone),
/// the least recently used evicted first.
struct Lru<V> {
    map: HashMap<ImageId, (V, u64, u64)>,
    bytes: u64,
    tick: u64,
    cap: u64,
}

impl<V: Clone> Lru<V> {
    fn new(cap: u64) -> Self {
        Lru {
            map: HashMap::new(),
            bytes: 0,
            tick: 0,
            cap,
        }
    }

    fn get(&mut self, id: ImageId) -> Option<V> {
        self.tick += 1;
        let tick = self.tick;
        self.map.get_mut(&id).map(|e| {
            e.1 = tick;
            e.0.clone()
        })
    }

    fn insert(&mut self, id: ImageId, value: V, bytes: u64) {
        self.tick += 1;
        if let Some(old) = self.map.insert(id, (value, self.tick, bytes)) {
            self.bytes -= old.2;
        }
        self.bytes += bytes;
        while self.bytes > self.cap && self.map.len() > 1 {
            let Some((&victim, _)) = self
                .map
                .iter()
                .filter(|(k, _)| **k != id)
                .min_by_key(|(_, v)| v.1)
            else {
                break;
            };
            if let Some(e) = self.map.remove(&victim) {
                self.bytes -= e.2;
            }
        }
    }
}

thread_local! {
    /// Entries this thread is building now ([`ImageCache::get`]).
    static BUILDING: std::cell::Cell<u32> = const { std::cell::Cell::new(0) };
}

/// A thread's claim to build one image's entry ([`ImageCache::get`]): released when dropped (a panic
/// included), waking the threads that wait for it.
struct Claim<'c, 'a> {
    cache: &'c ImageCache<'a>,
    id: ImageId,
}

impl<'c, 'a> Claim<'c, 'a> {
    /// The claim on `id`, already entered in `cache.building`.
    fn taken(cache: &'c ImageCache<'a>, id: ImageId) -> Self {
        BUILDING.with(|b| b.set(b.get() + 1));
        Claim { cache, id }
    }
}

impl Drop for Claim<'_, '_> {
    fn drop(&mut self) {
        BUILDING.with(|b| b.set(b.get() - 1));
        lock(&self.cache.building).remove(&self.id);
        self.cache.built.notify_all();
    }
}

/// Locks `m`, recovering the data of a poisoned lock (a panicking thread aborts the build anyway).
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl<'a> ImageCache<'a> {
    pub fn new(scene: &'a Scene, cap_bytes: u64) -> Self {
        ImageCache {
            scene,
            cap_bytes,
            chains: Mutex::new(Lru::new(cap_bytes / 4 * 3)),
            sources: Mutex::new(Lru::new(cap_bytes / 4)),
            decodes: AtomicU64::new(0),
            decoded_texels: AtomicU64::new(0),
            warnings: Mutex::new(Vec::new()),
            opaque_only: opaque_only_images(scene),
            noted: scene.images.iter().map(|_| Default::default()).collect(),
            live: scene.images.iter().map(|_| Default::default()).collect(),
            building: Mutex::default(),
            built: std::sync::Condvar::new(),
            chain_builds: AtomicU64::new(0),
            pixel_hashes: scene.images.iter().map(|_| Default::default()).collect(),
            twins: file_twins(scene),
            changed: Mutex::new(Vec::new()),
            out_of_descriptors: Mutex::new(None),
            downsampled: Mutex::new(Default::default()),
            upsampled: Mutex::new(Default::default()),
        }
    }

    /// The cache's bound in bytes (both tiers).
    pub fn capacity(&self) -> u64 {
        self.cap_bytes
    }

    /// Per image of the scene, the hash of the pixels this cache decoded, `None` for one it never
    /// decoded.
    pub fn pixel_hashes(&self) -> Vec<Option<[u64; 2]>> {
        self.pixel_hashes.iter().map(|h| h.get().copied()).collect()
    }

    /// A warning where this cache decoded its images again and again ([`redecode_note`]).
    pub fn redecode_warning(&self) -> Option<String> {
        let images = self
            .pixel_hashes
            .iter()
            .filter(|h| h.get().is_some())
            .count() as u64;
        redecode_note(self.decodes.load(Ordering::Relaxed), images, self.cap_bytes)
    }

    /// What makes this build's decodes unfit to write: a decode the open-files limit stopped, or the
    /// first image whose pixels changed between two decodes of this build (its file was rewritten
    /// meanwhile: the atlases drawn from it would mix two versions), as an error naming it.
    pub fn check_decodes(&self) -> Result<(), BuildError> {
        if let Some(e) = lock(&self.out_of_descriptors).take() {
            return Err(BuildError::Scene(Box::new(e)));
        }
        let Some(&id) = lock(&self.changed).iter().min() else {
            return Ok(());
        };
        Err(BuildError::ImageChanged {
            image: id.0,
            name: self.image_name(id).to_string(),
        })
    }

    /// Image `id`'s name in the scene (`?` for an id the scene lacks).
    pub fn image_name(&self, id: ImageId) -> &str {
        self.scene.images.get(id.idx()).map_or("?", |i| &i.name)
    }

    /// Records the pixels of a decode of `id`; a second decode with other pixels marks it changed, as
    /// does a decode of another scene image of the same file ([`Self::twins`]) with other pixels:
    /// one build that decoded the two before and after the file was rewritten mixed them.
    fn record_pixels(&self, id: ImageId, d: &DecodedImage) {
        let Some(slot) = self.pixel_hashes.get(id.idx()) else {
            return;
        };
        let hash = crate::store::shard::hash128(bytemuck::cast_slice(&d.pixels));
        let twins = self.twins.get(id.idx()).map_or(&[][..], Vec::as_slice);
        let twin_differs = (twins.iter()).any(|&i| {
            (self.pixel_hashes.get(i)).is_some_and(|h| h.get().is_some_and(|&h| h != hash))
        });
        if *slot.get_or_init(|| hash) != hash || twin_differs {
            lock(&self.changed).push(id);
        }
    }

    /// The decoded image `id` with its chain, decoded and built if needed, once: threads that miss it
    /// together wait for the one that builds it, and an entry evicted while a thread still holds it is
    /// taken back, not built again, so the process holds at most one chain of an image (a 16384²
    /// texture drawn by two threads was two chains, ~11 GiB: the budget counted every image once per
    /// thread; fault hunt, session 32). A decode failure yields a magenta/black checker (visible, never
    /// silently wrong), counted in `fallbacks` with a warning naming the image.
    ///
    /// The build runs on the calling thread alone ([`super::image_ops::on_this_thread`]): the waiters
    /// block inside rayon tasks, so no piece of the build may be a task one of them could be holding.
    pub fn get(&self, id: ImageId) -> Arc<CachedImage> {
        loop {
            if let Some(e) = self.held(id) {
                return e;
            }
            let mut building = lock(&self.building);
            if building.insert(id) {
                break;
            }
            let nested = BUILDING.with(|b| b.get()) > 0;
            // Nothing under a claim runs rayon work today; a change that did would show here in tests.
            debug_assert!(
                !nested,
                "image {} asked for while this thread builds another",
                id.0
            );
            if nested {
                // This thread is building another entry further up its stack (a build that ran a rayon
                // task would get here): it never waits, which could close a cycle, but builds a copy
                // the budget does not count.
                drop(building);
                return Arc::new(self.build(id));
            }
            while building.contains(&id) {
                building = self.built.wait(building).unwrap_or_else(|e| e.into_inner());
            }
        }
        let _claim = Claim::taken(self, id);
        // Built and let go between this thread's miss and its claim (review of session 33).
        if let Some(e) = self.held(id) {
            return e;
        }
        let entry = Arc::new(super::image_ops::on_this_thread(|| self.build(id)));
        if let Some(live) = self.live.get(id.idx()) {
            *lock(live) = Arc::downgrade(&entry);
        }
        lock(&self.chains).insert(id, entry.clone(), entry.bytes());
        self.chain_builds.fetch_add(1, Ordering::Relaxed);
        entry
    }

    /// Image `id`'s entry where the cache or a thread holds it (taken back into the cache then).
    fn held(&self, id: ImageId) -> Option<Arc<CachedImage>> {
        if let Some(e) = lock(&self.chains).get(id) {
            return Some(e);
        }
        let e = lock(self.live.get(id.idx())?).upgrade()?;
        lock(&self.chains).insert(id, e.clone(), e.bytes());
        Some(e)
    }

    /// Image `id` decoded (or taken from the sources tier) and its linear chain built.
    fn build(&self, id: ImageId) -> CachedImage {
        // Its own statement: the guard of a lock in the condition would live through the closure.
        let cached_source = lock(&self.sources).get(id);
        let decoded = cached_source.unwrap_or_else(|| {
            let d = Arc::new(self.decode(id));
            lock(&self.sources).insert(id, d.clone(), d.pixels.len() as u64 * 4);
            d
        });
        // `decode` checked the pixel count, the only way `from_decoded` fails.
        let linear = LinearImage::from_decoded(&decoded)
            .unwrap_or_else(|_| LinearImage::new_filled(1, 1, [1.0, 0.0, 1.0, 1.0]));
        CachedImage {
            decoded,
            chain: MipChain::build(linear),
        }
    }

    /// Image `id` decoded (alpha dropped where only OPAQUE materials use it). A decode failure or a pixel
    /// count that is not width × height yields a magenta/black checker (visible, never silently wrong),
    /// counted in `fallbacks` with a warning naming the image.
    fn decode(&self, id: ImageId) -> DecodedImage {
        self.decodes.fetch_add(1, Ordering::Relaxed);
        let src = &self.scene.images[id.idx()];
        let opaque = self.opaque_only.get(id.idx()).copied().unwrap_or(false);
        let decoded = src
            .decode()
            .map_err(|e| self.decode_error(e))
            .and_then(|mut d| {
                let texels = u64::from(d.width) * u64::from(d.height);
                if d.pixels.len() as u64 != texels {
                    return Err(format!(
                        "{} pixels for {}×{}",
                        d.pixels.len(),
                        d.width,
                        d.height
                    ));
                }
                // The file's own pixels: the scene images one glTF image becomes for OPAQUE and alpha
                // materials hash alike, so the merge compares shards that decoded one each (fault hunt,
                // session 37).
                self.record_pixels(id, &d);
                if opaque && !d.is_opaque() {
                    self.first_note(id, NOTED_ALPHA_IGNORED);
                    d.pixels.iter_mut().for_each(|p| p[3] = 255);
                }
                self.decoded_texels.fetch_add(texels, Ordering::Relaxed);
                Ok(d)
            });
        // Replaced at import (a missing or unreadable file, already warned about there): counted here
        // too, so "images decoded N (F fallbacks)" agrees with the import's count (it said 0; fault
        // hunt, session 28).
        if src.is_fallback() {
            self.first_note(id, NOTED_FALLBACK);
        }
        decoded.unwrap_or_else(|e| {
            if self.first_note(id, NOTED_FALLBACK) {
                let mut w = lock(&self.warnings);
                if w.len() < 100 {
                    w.push(format!(
                        "image {} ({}): {e}; used the magenta fallback",
                        id.0, src.name
                    ));
                }
            }
            // At most an original's largest side (an 8192² header's board would be 256 MiB).
            let side = |v: u32| v.min(crate::model::MAX_ORIGINAL_CLASS);
            let checker = crate::scene::fallback_checker_sized(side(src.width), side(src.height));
            self.record_pixels(id, &checker);
            checker
        })
    }
}

impl ImageCache<'_> {
    /// A decode's error as its warning's text, the first that the open-files limit caused kept for
    /// [`Self::check_decodes`].
    fn decode_error(&self, e: crate::scene::SceneError) -> String {
        let text = e.to_string();
        if matches!(e, crate::scene::SceneError::OutOfDescriptors { .. }) {
            lock(&self.out_of_descriptors).get_or_insert(e);
        }
        text
    }

    /// Images that failed to decode and were replaced by the visible fallback (reported).
    pub fn fallbacks(&self) -> u64 {
        self.noted_count(NOTED_FALLBACK)
    }

    /// Images used only by OPAQUE materials whose alpha was ignored although some texel had alpha < 255
    /// (reported).
    pub fn alpha_ignored(&self) -> u64 {
        self.noted_count(NOTED_ALPHA_IGNORED)
    }

    fn noted_count(&self, what: u8) -> u64 {
        let noted = self.noted.iter().map(|n| n.load(Ordering::Relaxed));
        noted.filter(|n| n & what != 0).count() as u64
    }

    /// Whether this is the first time `what` ([`NOTED_ALPHA_IGNORED`], [`NOTED_FALLBACK`]) is noted for
    /// image `id`: an image decoded again after eviction is counted and warned about once.
    fn first_note(&self, id: ImageId, what: u8) -> bool {
        self.noted
            .get(id.idx())
            .is_none_or(|n| n.fetch_or(what, Ordering::Relaxed) & what == 0)
    }

    /// The stored bytes (and compression error) of original texture `key`, resampled and encoded. Not
    /// kept: a tree stores each original once (`assemble::StoredOriginal`), so its one writer asks for it
    /// once (a cache of encoded originals held up to a quarter of the budget for nothing; session 34).
    pub fn original(&self, key: OriginalKey) -> Result<Encoded, BuildError> {
        let [w, h] = key.1;
        let what = || format!("original texture {} at {w}×{h}", key.0.0);
        let img = self.get(key.0);
        let identity = resample_is_identity(&img, w, h);
        let source = [img.decoded.width, img.decoded.height];
        if source[0] > w || source[1] > h {
            lock(&self.downsampled).insert(key.0, (source, [w, h]));
        } else if (source[0] < w || source[1] < h)
            && (img.decoded.pixels.iter()).any(|p| *p != img.decoded.pixels[0])
        {
            // One colour (a solid material's 1 × 1) resamples to itself: nothing to say.
            lock(&self.upsampled).insert(key.0, (source, [w, h]));
        }
        // The cached chain is box-filtered, as resampling wants; so is the stored chain.
        let resampled = || resample_rect(&img.chain, w, h, key.2).map_err(|e| image_err(what(), e));
        let encode_err = |source| BuildError::Encode {
            what: what(),
            source,
        };
        let enc = match key.5 {
            None if identity => {
                let levels = img.stored_levels_rgba8();
                let levels: Vec<&[u8]> = levels.iter().map(|l| &**l).collect();
                encode_levels_rect(key.3, &levels, w, h, key.4).map_err(encode_err)?
            }
            None => {
                let rgba8 = mip_chain_rgba8(&resampled()?);
                encode_chain_rect(key.3, &rgba8, w, h, key.4).map_err(encode_err)?
            }
            Some(bits) => {
                let mut levels = if identity {
                    img.chain.levels.clone()
                } else {
                    MipChain::build(resampled()?).levels
                };
                let region = CoverageRegion {
                    rect: [0.0, 0.0, f64::from(w), f64::from(h)],
                    cutoff: f32::from_bits(bits),
                };
                preserve_coverage(&mut levels, &[region]);
                let rgba8 = MipChain { levels }.to_rgba8();
                encode_chain_rect(key.3, &rgba8, w, h, key.4).map_err(encode_err)?
            }
        };
        Ok(enc)
    }
}

/// True where [`resample_rect`] of `img`'s chain to `w × h` returns level 0 unchanged: the decoded image
/// and the chain's level 0 have those sides, each a power of two. Then every destination texel centre
/// `(x + 0.5) / w` maps back onto source texel `x` with no rounding (division and multiplication by a
/// power of two are exact in f64), so its one bilinear tap has weights exactly 1 and 0.
fn resample_is_identity(img: &CachedImage, w: u32, h: u32) -> bool {
    let level0 = img.chain.levels.first();
    img.decoded.width == w
        && img.decoded.height == h
        && level0.is_some_and(|l| l.width == w && l.height == h)
        && w.is_power_of_two()
        && h.is_power_of_two()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Wrap;

    /// Deterministic pixels: a hash of the index; `alpha` picks opaque, mixed or with transparent texels.
    fn image(w: u32, h: u32, alpha: u8) -> DecodedImage {
        let pixels = (0..w * h)
            .map(|i| {
                let x = i.wrapping_mul(2_654_435_761).rotate_left(7) ^ 0x9e37_79b9;
                let [r, g, b, a] = x.to_le_bytes();
                let a = match alpha {
                    0 => 255,
                    1 => a | 1,
                    _ => a & 0x1f, // many 0s and small alphas
                };
                [r, g, b, a]
            })
            .collect();
        DecodedImage {
            width: w,
            height: h,
            pixels,
        }
    }

    /// [`super::redecode_note`]: quiet up to twice each or 64 decodes again, a warning past both.
    #[test]
    fn redecodes_warn_past_twice_each_and_sixty_four_more() {
        use super::{REDECODE_MIN, REDECODE_RATIO, redecode_note};
        assert_eq!(redecode_note(0, 0, 1 << 30), None);
        // Twice each is quiet; once more over it, with enough decodes again, warns.
        assert_eq!(redecode_note(200 * REDECODE_RATIO, 200, 1 << 30), None);
        let w = redecode_note(200 * REDECODE_RATIO + 1, 200, 1 << 30).unwrap();
        assert!(
            w.contains("decoded 200 images 401 times (2.00 each)"),
            "{w}"
        );
        assert!(w.contains("1.00 GiB") && w.contains("--max-memory"), "{w}");
        // Ten images decoded five times each: 40 decodes again, under the minimum of 64.
        assert_eq!(REDECODE_MIN, 64);
        assert_eq!(redecode_note(50, 10, 1 << 30), None);
        assert!(redecode_note(10 + REDECODE_MIN, 10, 1 << 30).is_some());
        // The all-tracks world at its refusal's budget.
        assert!(redecode_note(9_000, 870, 300 << 20).is_some());
    }

    /// Re-decodes after eviction count nothing twice: two images with transparent texels used only by
    /// OPAQUE materials, fetched a, b, a through a cache that holds neither, decode three times and count
    /// two images whose alpha was ignored (it counted every decode: hacienda's 3 images read 10 at a
    /// 1 MiB cache).
    #[test]
    fn an_image_decoded_again_is_counted_once() {
        use crate::scene::synthetic::SceneBuilder;
        use crate::scene::{AlphaMode, UpAxis};
        let mut b = SceneBuilder::new(UpAxis::Y);
        let ids: Vec<ImageId> = ["a", "b"]
            .into_iter()
            .map(|name| {
                let img = b.image(name, 8, 8, |x, _| [9, 9, 9, if x < 4 { 255 } else { 0 }]);
                let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
                b.triangle(
                    [glam::DVec3::ZERO, glam::DVec3::X, glam::DVec3::Z],
                    [glam::DVec2::ZERO; 3],
                    m,
                );
                img
            })
            .collect();
        let scene = b.build();
        let cache = ImageCache::new(&scene, 1);
        for &id in [ids[0], ids[1], ids[0]].iter() {
            cache.get(id);
        }
        assert_eq!(cache.decodes.load(Ordering::Relaxed), 3);
        assert_eq!(cache.alpha_ignored(), 2);
    }

    /// Threads that need one image together build its chain once, and an entry evicted while a thread
    /// still holds it is taken back, not built again: the process holds one chain of an image, as the
    /// memory budget counts it (`memory::ImageLoad`).
    #[test]
    fn an_image_has_one_chain_however_many_threads_draw_it() {
        use crate::scene::synthetic::SceneBuilder;
        use crate::scene::{AlphaMode, UpAxis};
        use rayon::prelude::*;
        let mut b = SceneBuilder::new(UpAxis::Y);
        let [big, small] = [("big", 512), ("small", 8)].map(|(name, side)| {
            let img = b.image(name, side, side, |x, y| [x as u8, y as u8, 7, 255]);
            let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
            b.triangle(
                [glam::DVec3::ZERO, glam::DVec3::X, glam::DVec3::Z],
                [glam::DVec2::ZERO; 3],
                m,
            );
            img
        });
        let scene = b.build();
        // Holds one entry at a time.
        let cache = ImageCache::new(&scene, 1);
        let builds = || cache.chain_builds.load(Ordering::Relaxed);
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(4)
            .build()
            .unwrap();
        let held: Vec<Arc<CachedImage>> =
            pool.install(|| (0..16).into_par_iter().map(|_| cache.get(big)).collect());
        assert!(held.iter().all(|e| Arc::ptr_eq(e, &held[0])));
        assert_eq!((builds(), cache.decodes.load(Ordering::Relaxed)), (1, 1));
        // `small` evicts `big`, which `held` keeps: taken back, the same entry.
        drop(cache.get(small));
        assert!(Arc::ptr_eq(&cache.get(big), &held[0]));
        assert_eq!(builds(), 2);
        // Let go and evicted, it is built again.
        drop(held);
        drop(cache.get(small));
        drop(cache.get(big));
        assert_eq!(builds(), 4);
    }

    #[test]
    fn lru_evicts_the_least_recently_used_within_its_bytes() {
        let mut lru = Lru::new(10);
        lru.insert(ImageId(0), 'a', 4);
        lru.insert(ImageId(1), 'b', 4);
        assert_eq!(lru.get(ImageId(0)), Some('a')); // 0 is now the most recently used
        lru.insert(ImageId(2), 'c', 4); // 12 > 10: evicts 1
        assert_eq!(lru.get(ImageId(1)), None);
        assert_eq!(
            (lru.get(ImageId(0)), lru.get(ImageId(2))),
            (Some('a'), Some('c'))
        );
        assert_eq!(lru.bytes, 8);
        lru.insert(ImageId(3), 'd', 50); // alone over the cap: stays, everything else goes
        assert_eq!((lru.map.len(), lru.bytes), (1, 50));
        lru.insert(ImageId(3), 'e', 5); // replacing a value counts its bytes once
        assert_eq!((lru.get(ImageId(3)), lru.bytes), (Some('e'), 5));
    }

    #[test]
    fn stored_chain_at_the_source_size_equals_the_resampled_chain() {
        let wraps = [
            [Wrap::Repeat, Wrap::MirroredRepeat],
            [Wrap::ClampToEdge, Wrap::Repeat],
        ];
        for (w, h) in [(1, 1), (2, 1), (8, 8), (16, 4), (1, 32), (256, 64)] {
            for alpha in 0..3 {
                let decoded = image(w, h, alpha);
                let chain = MipChain::build(LinearImage::from_decoded(&decoded).unwrap());
                let img = CachedImage {
                    decoded: Arc::new(decoded),
                    chain,
                };
                assert!(resample_is_identity(&img, w, h));
                let fast = img.stored_levels_rgba8().concat();
                for wrap in wraps {
                    let lin = resample_rect(&img.chain, w, h, wrap).unwrap();
                    let slow = mip_chain_rgba8(&lin);
                    assert_eq!(fast.len(), slow.len(), "{w}×{h} alpha {alpha}");
                    let diff = fast.iter().zip(&slow).filter(|(a, b)| a != b).count();
                    assert_eq!(
                        diff, 0,
                        "{w}×{h} alpha {alpha} {wrap:?}: {diff} bytes differ"
                    );
                }
            }
        }
        // Not the identity: other sides, sides that are not powers of two, a chain of other sides.
        let cached = |decoded: DecodedImage, chain: LinearImage| CachedImage {
            decoded: Arc::new(decoded),
            chain: MipChain::build(chain),
        };
        let d = image(6, 4, 0);
        let c = cached(d.clone(), LinearImage::from_decoded(&d).unwrap());
        assert!(!resample_is_identity(&c, 6, 4));
        assert!(!resample_is_identity(&c, 8, 4));
        let d = image(8, 4, 0);
        let c = cached(d, LinearImage::new_filled(1, 1, [1.0; 4]));
        assert!(!resample_is_identity(&c, 8, 4));
    }
}
