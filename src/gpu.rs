//! wgpu device setup shared by the renderer and the GPU tests.
//!
//! [`GpuContext::new_headless`] (and [`GpuContext::new_for_surface`] for a window) picks an adapter on the primary backends (Vulkan, Metal, DX12; `WGPU_BACKEND`
//! overrides), preferring a discrete GPU but accepting a software (CPU) adapter such as Mesa's lavapipe, and
//! opens a device with the features the texture-array batching renderer (TAB, Trapp & Döllner 2015) relies on:
//!
//! - **required** `INDIRECT_FIRST_INSTANCE`: every selected node is one indirect record whose `first_instance`
//!   indexes its per-draw data. Without the feature wgpu's indirect validation silently rewrites such records
//!   to draw nothing, so a device without it is refused with [`GpuError::MissingFeature`].
//! - **required** downlevel `INDIRECT_EXECUTION` (what `multi_draw_indexed_indirect` needs in wgpu 30; there is no
//!   separate multi-draw feature flag) and `VERTEX_STORAGE` (per-instance data read from a storage buffer in the
//!   vertex stage).
//! - **optional**, enabled when the adapter has them and recorded in [`GpuFeatures`]: timestamp queries (also
//!   inside encoders and passes), BC texture compression, native multi-draw-indirect-count, anisotropic
//!   filtering (a downlevel flag, nothing to enable).
//!
//! Limits: WebGPU defaults (clamped to the adapter), raised to the adapter's maxima for texture array layers
//! (paging slots), 2D texture size (atlas size), storage-buffer binding size and buffer size.

use std::fmt;
use std::sync::mpsc;

/// An open-files limit below which a missing adapter may be the limit's doing ([`GpuError::NoAdapter`]).
const LOW_OPEN_FILES_LIMIT: u64 = 64;

/// Bytes per texel of the RGBA8 formats [`readback_rgba8`] accepts.
const RGBA8_BYTES_PER_TEXEL: u32 = 4;

/// The open-files limit as a missing adapter's possible cause ([`GpuError::NoAdapter`]).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum OpenFiles {
    /// Unlimited, unknown, or at least [`LOW_OPEN_FILES_LIMIT`]: not the cause.
    Enough,
    /// Below [`LOW_OPEN_FILES_LIMIT`].
    Low(u64),
    /// Reached: not even the limit could be read.
    Reached,
}

/// Errors of device setup and readback.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    /// No adapter at all on the requested backends (no driver, or the driver is hidden by the environment).
    #[error(
        "no GPU adapter found on backends {backends} (on Debian install mesa-vulkan-drivers for lavapipe){}",
        match .open_files {
            OpenFiles::Enough => String::new(),
            OpenFiles::Low(n) => format!("; or the open-files limit of {n} (ulimit -n) is too low for the \
                                          Vulkan loader to open its drivers' files: raise it"),
            OpenFiles::Reached => "; or the open-files limit (ulimit -n) is too low for the Vulkan loader \
                                   to open its drivers' files: raise it".to_string(),
        }
    )]
    NoAdapter {
        backends: String,
        /// The open-files limit where it may be the cause (the loader opens its drivers' manifests and
        /// libraries; under `ulimit -n 7` only the install hint was given; fault hunt, session 38).
        open_files: OpenFiles,
    },
    /// Adapters exist but every one was rejected; `rejected` lists each with its reason.
    #[error("no suitable GPU adapter among {count}: {rejected}")]
    NoSuitableAdapter { count: usize, rejected: String },
    /// The chosen adapter lacks a feature the renderer cannot work without.
    #[error("adapter {adapter} lacks required feature {feature}")]
    MissingFeature {
        adapter: String,
        feature: &'static str,
    },
    /// `Adapter::request_device` failed.
    #[error("request_device on adapter {adapter} failed: {source}")]
    RequestDevice {
        adapter: String,
        #[source]
        source: wgpu::RequestDeviceError,
    },
    /// [`readback_rgba8`] was given a texture whose format is not 4-byte RGBA8.
    #[error("readback expects an Rgba8Unorm/Rgba8UnormSrgb texture, got {format:?}")]
    UnsupportedReadbackFormat { format: wgpu::TextureFormat },
    /// [`readback_rgba8`] was given a texture without `COPY_SRC` usage.
    #[error("texture of {width}x{height} has no COPY_SRC usage, cannot read it back")]
    NotCopySource { width: u32, height: u32 },
    /// The requested array layer does not exist.
    #[error("array layer {layer} out of range: texture has {layers} layers")]
    LayerOutOfRange { layer: u32, layers: u32 },
    /// Readback buffer size overflowed `u64`/`usize`.
    #[error("readback of {width}x{height} texels overflows the buffer size")]
    SizeOverflow { width: u32, height: u32 },
    /// Mapping the readback buffer failed.
    #[error("mapping the readback buffer failed: {0}")]
    Map(#[from] wgpu::BufferAsyncError),
    /// Getting a view of the mapped buffer failed.
    #[error("viewing the mapped readback buffer failed: {0}")]
    MapRange(#[from] wgpu::MapRangeError),
    /// `Device::poll` failed while waiting for the GPU.
    #[error("waiting for the GPU failed: {0}")]
    Poll(#[from] wgpu::PollError),
    /// The map callback was dropped without being called (device lost).
    #[error("the readback map callback never ran (device lost?)")]
    MapCallbackLost,
    /// [`GpuContext::new_for_surface`] could not create a surface for the window.
    #[error("creating a surface for the window failed: {0}")]
    CreateSurface(#[from] wgpu::CreateSurfaceError),
    /// A wgpu validation or out-of-memory error captured by [`GpuContext::scoped`].
    #[error("wgpu error in {what}: {message}")]
    Wgpu { what: String, message: String },
    /// The device ran out of memory in [`GpuContext::scoped`] (reported before the validation errors
    /// that the failed allocation causes later in the scope).
    #[error("{what}: the device is out of memory ({message})")]
    OutOfMemory { what: String, message: String },
}

/// How [`GpuContext::new_headless`] picks its adapter.
#[derive(Debug, Clone)]
pub struct GpuOptions {
    /// Backends to search; `None` means the primary backends (Vulkan, Metal, DX12, WebGPU), overridden by the
    /// `WGPU_BACKEND` environment variable (e.g. `vulkan`, `gl`).
    pub backends: Option<wgpu::Backends>,
    /// Preferred device class: `HighPerformance` ranks discrete above integrated GPUs, `LowPower` the reverse.
    pub power_preference: wgpu::PowerPreference,
    /// Accept a software (CPU) adapter such as lavapipe when no hardware adapter qualifies. Always ranked last.
    pub allow_software: bool,
    /// Debug label of the device.
    pub label: &'static str,
}

impl Default for GpuOptions {
    fn default() -> Self {
        Self {
            backends: None,
            power_preference: wgpu::PowerPreference::HighPerformance,
            allow_software: true,
            label: "atlastree",
        }
    }
}

/// The adapter's identity, copied out of [`wgpu::AdapterInfo`] for logs and reports.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AdapterInfoSummary {
    pub name: String,
    pub backend: wgpu::Backend,
    pub device_type: wgpu::DeviceType,
    pub driver: String,
    pub driver_info: String,
    pub vendor: u32,
    pub device: u32,
}

impl AdapterInfoSummary {
    /// Copies the fields of `info` that identify the adapter.
    pub fn from_info(info: &wgpu::AdapterInfo) -> Self {
        Self {
            name: info.name.clone(),
            backend: info.backend,
            device_type: info.device_type,
            driver: info.driver.clone(),
            driver_info: info.driver_info.clone(),
            vendor: info.vendor,
            device: info.device,
        }
    }

    /// True for software rasterisers (lavapipe, WARP, SwiftShader): timings are not GPU timings.
    pub fn is_software(&self) -> bool {
        self.device_type == wgpu::DeviceType::Cpu
    }
}

impl fmt::Display for AdapterInfoSummary {
    /// `name (backend, device type, driver driver_info)`, e.g.
    /// `llvmpipe (LLVM 15.0.6, 256 bits) (Vulkan, Cpu, llvmpipe Mesa 22.3.6 (LLVM 15.0.6))`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} ({:?}, {:?}, {} {})",
            self.name, self.backend, self.device_type, self.driver, self.driver_info
        )
    }
}

/// What the opened device can do beyond the baseline; the renderer branches on these, never on adapter names.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GpuFeatures {
    /// `Features::INDIRECT_FIRST_INSTANCE`; always true on an opened context (required).
    pub indirect_first_instance: bool,
    /// `DownlevelFlags::INDIRECT_EXECUTION`: `multi_draw_indexed_indirect` is allowed; always true (required).
    pub multi_draw_indirect: bool,
    /// `Features::MULTI_DRAW_INDIRECT_COUNT`: enabled; implies multi-draw is native, not emulated by a loop.
    pub multi_draw_indirect_count: bool,
    /// `Features::TIMESTAMP_QUERY`: timestamps at pass boundaries.
    pub timestamp_query: bool,
    /// `Features::TIMESTAMP_QUERY_INSIDE_ENCODERS`: `CommandEncoder::write_timestamp`.
    pub timestamp_query_inside_encoders: bool,
    /// `Features::TIMESTAMP_QUERY_INSIDE_PASSES`: `RenderPass::write_timestamp`.
    pub timestamp_query_inside_passes: bool,
    /// Nanoseconds per timestamp tick (`Queue::get_timestamp_period`); meaningful only with `timestamp_query`.
    pub timestamp_period_ns: f32,
    /// `Features::TEXTURE_COMPRESSION_BC`: BC1–BC7 textures.
    pub texture_compression_bc: bool,
    /// `DownlevelFlags::ANISOTROPIC_FILTERING`: samplers honour `anisotropy_clamp > 1`.
    pub anisotropic_filtering: bool,
    /// Device limit: texture array layers (paging slots per array).
    pub max_texture_array_layers: u32,
    /// Device limit: width and height of a 2D texture, texels.
    pub max_texture_dimension_2d: u32,
    /// Device limit: bytes of one storage-buffer binding.
    pub max_storage_buffer_binding_size: u64,
    /// Device limit: bytes of one buffer.
    pub max_buffer_size: u64,
}

impl fmt::Display for GpuFeatures {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "layers {} tex2d {} storage-binding {} B buffer {} B; mdi-count {} timestamps {}/{}/{} ({} ns/tick) bc {} aniso {}",
            self.max_texture_array_layers,
            self.max_texture_dimension_2d,
            self.max_storage_buffer_binding_size,
            self.max_buffer_size,
            self.multi_draw_indirect_count,
            self.timestamp_query,
            self.timestamp_query_inside_encoders,
            self.timestamp_query_inside_passes,
            self.timestamp_period_ns,
            self.texture_compression_bc,
            self.anisotropic_filtering
        )
    }
}

/// An opened wgpu device with the renderer's features; create once, share by reference.
#[derive(Debug)]
pub struct GpuContext {
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: AdapterInfoSummary,
    pub features: GpuFeatures,
}

/// Optional features enabled whenever the adapter has them.
const OPTIONAL_FEATURES: wgpu::Features = wgpu::Features::TIMESTAMP_QUERY
    .union(wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS)
    .union(wgpu::Features::TIMESTAMP_QUERY_INSIDE_PASSES)
    .union(wgpu::Features::TEXTURE_COMPRESSION_BC)
    .union(wgpu::Features::MULTI_DRAW_INDIRECT_COUNT);

/// Downlevel flags the renderer cannot work without.
const REQUIRED_DOWNLEVEL: &[(wgpu::DownlevelFlags, &str)] = &[
    (
        wgpu::DownlevelFlags::INDIRECT_EXECUTION,
        "downlevel INDIRECT_EXECUTION (multi-draw-indirect)",
    ),
    (
        wgpu::DownlevelFlags::VERTEX_STORAGE,
        "downlevel VERTEX_STORAGE (storage buffers in vertex shaders)",
    ),
];

impl GpuContext {
    /// Opens a device without a surface (offscreen rendering, tests, benchmarks).
    ///
    /// Errors: [`GpuError::NoAdapter`] when the backends expose no adapter, [`GpuError::MissingFeature`] /
    /// [`GpuError::NoSuitableAdapter`] when none has the required features, [`GpuError::RequestDevice`].
    pub fn new_headless(opts: &GpuOptions) -> Result<GpuContext, GpuError> {
        let (desc, backends) = instance_descriptor(opts);
        GpuContext::open(wgpu::Instance::new(desc), backends, opts, None)
    }

    /// Opens a device that can present to a window: the instance is created with the window system's
    /// `display` connection (required by GL and Wayland, ignored by Vulkan, Metal and DX12), a surface for
    /// `target` (a window), and only adapters that can present to that surface qualify; the features and
    /// limits are those of [`GpuContext::new_headless`].
    ///
    /// Errors: those of [`GpuContext::new_headless`] (an adapter that cannot present is rejected with that
    /// reason), and [`GpuError::CreateSurface`].
    pub fn new_for_surface<'w, D>(
        opts: &GpuOptions,
        display: D,
        target: impl Into<wgpu::SurfaceTarget<'w>>,
    ) -> Result<(GpuContext, wgpu::Surface<'w>), GpuError>
    where
        D: wgpu::rwh::HasDisplayHandle + fmt::Debug + Send + Sync + 'static,
    {
        let (desc, backends) = instance_descriptor(opts);
        let instance = wgpu::Instance::new(desc.with_display_handle(Box::new(display)));
        let surface = instance.create_surface(target)?;
        let ctx = GpuContext::open(instance, backends, opts, Some(&surface))?;
        Ok((ctx, surface))
    }

    /// Picks the adapter (able to present to `surface` when given) and opens the device.
    fn open(
        instance: wgpu::Instance,
        backends: wgpu::Backends,
        opts: &GpuOptions,
        surface: Option<&wgpu::Surface<'_>>,
    ) -> Result<GpuContext, GpuError> {
        let adapters = pollster::block_on(instance.enumerate_adapters(backends));
        let adapter = choose_adapter(adapters, opts, backends, surface)?;
        let info = AdapterInfoSummary::from_info(&adapter.get_info());
        let (device, queue) = open_device(&adapter, &info, opts.label)?;
        let features = GpuFeatures::of_device(&adapter, &device, &queue);
        tracing::info!(adapter = %info, features = %features, "gpu context ready");
        Ok(GpuContext {
            instance,
            adapter,
            device,
            queue,
            info,
            features,
        })
    }

    /// One-line description of the adapter: name, backend, device type, driver.
    pub fn adapter_summary(&self) -> String {
        self.info.to_string()
    }

    /// Runs `f` inside a validation + out-of-memory error scope and turns a captured wgpu error into
    /// [`GpuError::Wgpu`] (instead of the default uncaptured-error panic). `what` names the operation.
    pub fn scoped<T>(&self, what: &str, f: impl FnOnce(&wgpu::Device) -> T) -> Result<T, GpuError> {
        let oom = self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let validation = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let value = f(&self.device);
        let validation_error = pollster::block_on(validation.pop());
        let oom_error = pollster::block_on(oom.pop());
        // Out of memory first: a texture that failed to allocate makes every later use a validation error.
        match (oom_error, validation_error) {
            (Some(error), _) => Err(GpuError::OutOfMemory {
                what: what.to_owned(),
                message: error.to_string(),
            }),
            (None, Some(error)) => Err(GpuError::Wgpu {
                what: what.to_owned(),
                message: error.to_string(),
            }),
            (None, None) => Ok(value),
        }
    }
}

/// The instance descriptor of `opts` (backends, with `WGPU_BACKEND` and the debug flags from the
/// environment) and the backends to search.
fn instance_descriptor(opts: &GpuOptions) -> (wgpu::InstanceDescriptor, wgpu::Backends) {
    let backends = opts
        .backends
        .unwrap_or_else(|| wgpu::Backends::PRIMARY.with_env());
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    desc.backends = backends;
    desc.flags = wgpu::InstanceFlags::from_build_config().with_env();
    (desc, backends)
}

/// Preference rank of a device type (lower is better); software is last regardless of preference.
fn device_type_rank(device_type: wgpu::DeviceType, preference: wgpu::PowerPreference) -> u8 {
    use wgpu::DeviceType as D;
    match (device_type, preference) {
        (D::IntegratedGpu, wgpu::PowerPreference::LowPower) => 0,
        (D::DiscreteGpu, wgpu::PowerPreference::LowPower) => 1,
        (D::DiscreteGpu, _) => 0,
        (D::IntegratedGpu, _) => 1,
        (D::VirtualGpu, _) => 2,
        (D::Other, _) => 3,
        (D::Cpu, _) => 4,
    }
}

/// Why `adapter` cannot serve the renderer, or `None` when it can: the reason, and whether it is a missing
/// required feature (reported as [`GpuError::MissingFeature`] when it is the only adapter).
fn rejection(
    adapter: &wgpu::Adapter,
    opts: &GpuOptions,
    surface: Option<&wgpu::Surface<'_>>,
) -> Option<(&'static str, bool)> {
    let info = adapter.get_info();
    if surface.is_some_and(|s| !adapter.is_surface_supported(s)) {
        return Some(("cannot present to the window's surface", false));
    }
    if info.device_type == wgpu::DeviceType::Cpu && !opts.allow_software {
        return Some((
            "software adapter not allowed (GpuOptions::allow_software = false)",
            false,
        ));
    }
    if !adapter
        .features()
        .contains(wgpu::Features::INDIRECT_FIRST_INSTANCE)
    {
        return Some(("INDIRECT_FIRST_INSTANCE", true));
    }
    let downlevel = adapter.get_downlevel_capabilities().flags;
    REQUIRED_DOWNLEVEL
        .iter()
        .find(|(flag, _)| !downlevel.contains(*flag))
        .map(|(_, name)| (*name, true))
}

/// Picks the best-ranked adapter that has every required feature (and can present to `surface`).
fn choose_adapter(
    adapters: Vec<wgpu::Adapter>,
    opts: &GpuOptions,
    backends: wgpu::Backends,
    surface: Option<&wgpu::Surface<'_>>,
) -> Result<wgpu::Adapter, GpuError> {
    if adapters.is_empty() {
        return Err(GpuError::NoAdapter {
            backends: format!("{backends:?}"),
            open_files: match crate::util::open_files_limit() {
                Ok(Some(n)) if n < LOW_OPEN_FILES_LIMIT => OpenFiles::Low(n),
                Ok(_) => OpenFiles::Enough,
                Err(_) => OpenFiles::Reached,
            },
        });
    }
    let count = adapters.len();
    let mut rejected = Vec::new();
    let mut suitable = Vec::new();
    for adapter in adapters {
        let info = AdapterInfoSummary::from_info(&adapter.get_info());
        match rejection(&adapter, opts, surface) {
            None => suitable.push((
                device_type_rank(info.device_type, opts.power_preference),
                adapter,
            )),
            Some((reason, missing_feature)) => rejected.push((info, reason, missing_feature)),
        }
    }
    suitable.sort_by_key(|(rank, _)| *rank);
    if let Some((_, adapter)) = suitable.into_iter().next() {
        return Ok(adapter);
    }
    if let [(info, reason, true)] = rejected.as_slice() {
        return Err(GpuError::MissingFeature {
            adapter: info.to_string(),
            feature: reason,
        });
    }
    let rejected = rejected
        .iter()
        .map(|(info, reason, _)| format!("{info}: {reason}"))
        .collect::<Vec<_>>()
        .join("; ");
    Err(GpuError::NoSuitableAdapter { count, rejected })
}

/// Limits the device is opened with: WebGPU defaults clamped to the adapter, with the texture-array, 2D-size and
/// storage-buffer maxima raised to the adapter's.
fn required_limits(adapter_limits: &wgpu::Limits) -> wgpu::Limits {
    let mut limits = wgpu::Limits::defaults().or_worse_values_from(adapter_limits);
    limits.max_texture_array_layers = adapter_limits.max_texture_array_layers;
    limits.max_texture_dimension_2d = adapter_limits.max_texture_dimension_2d;
    limits.max_storage_buffer_binding_size = adapter_limits.max_storage_buffer_binding_size;
    limits.max_buffer_size = adapter_limits.max_buffer_size;
    limits
}

/// Opens the device with the required and available optional features.
fn open_device(
    adapter: &wgpu::Adapter,
    info: &AdapterInfoSummary,
    label: &'static str,
) -> Result<(wgpu::Device, wgpu::Queue), GpuError> {
    let features =
        wgpu::Features::INDIRECT_FIRST_INSTANCE | (adapter.features() & OPTIONAL_FEATURES);
    let desc = wgpu::DeviceDescriptor {
        label: Some(label),
        required_features: features,
        required_limits: required_limits(&adapter.limits()),
        experimental_features: wgpu::ExperimentalFeatures::disabled(),
        memory_hints: wgpu::MemoryHints::Performance,
        trace: wgpu::Trace::Off,
    };
    pollster::block_on(adapter.request_device(&desc)).map_err(|source| GpuError::RequestDevice {
        adapter: info.to_string(),
        source,
    })
}

impl GpuFeatures {
    /// Reads what the opened device actually has.
    fn of_device(adapter: &wgpu::Adapter, device: &wgpu::Device, queue: &wgpu::Queue) -> Self {
        let f = device.features();
        let limits = device.limits();
        let downlevel = adapter.get_downlevel_capabilities().flags;
        let timestamp_query = f.contains(wgpu::Features::TIMESTAMP_QUERY);
        Self {
            indirect_first_instance: f.contains(wgpu::Features::INDIRECT_FIRST_INSTANCE),
            multi_draw_indirect: downlevel.contains(wgpu::DownlevelFlags::INDIRECT_EXECUTION),
            multi_draw_indirect_count: f.contains(wgpu::Features::MULTI_DRAW_INDIRECT_COUNT),
            timestamp_query,
            timestamp_query_inside_encoders: f
                .contains(wgpu::Features::TIMESTAMP_QUERY_INSIDE_ENCODERS),
            timestamp_query_inside_passes: f
                .contains(wgpu::Features::TIMESTAMP_QUERY_INSIDE_PASSES),
            timestamp_period_ns: if timestamp_query {
                queue.get_timestamp_period()
            } else {
                0.0
            },
            texture_compression_bc: f.contains(wgpu::Features::TEXTURE_COMPRESSION_BC),
            anisotropic_filtering: downlevel.contains(wgpu::DownlevelFlags::ANISOTROPIC_FILTERING),
            max_texture_array_layers: limits.max_texture_array_layers,
            max_texture_dimension_2d: limits.max_texture_dimension_2d,
            max_storage_buffer_binding_size: limits.max_storage_buffer_binding_size,
            max_buffer_size: limits.max_buffer_size,
        }
    }
}

/// Row pitch of a texel copy: `width · bytes_per_texel` rounded up to `COPY_BYTES_PER_ROW_ALIGNMENT` (256).
fn padded_row_bytes(width: u32, bytes_per_texel: u32) -> Option<u32> {
    let unpadded = width.checked_mul(bytes_per_texel)?;
    let align = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    unpadded.checked_add(align - 1).map(|v| v / align * align)
}

/// Reads mip 0, layer 0 of an `Rgba8Unorm`/`Rgba8UnormSrgb` texture with `COPY_SRC` usage back to the CPU.
///
/// Returns `width · height · 4` bytes, rows top to bottom, no padding. Blocks until the GPU is done.
pub fn readback_rgba8(ctx: &GpuContext, texture: &wgpu::Texture) -> Result<Vec<u8>, GpuError> {
    readback_rgba8_layer(ctx, texture, 0)
}

/// As [`readback_rgba8`] for array layer `layer` of a 2D (array) texture.
pub fn readback_rgba8_layer(
    ctx: &GpuContext,
    texture: &wgpu::Texture,
    layer: u32,
) -> Result<Vec<u8>, GpuError> {
    let format = texture.format();
    if !matches!(
        format,
        wgpu::TextureFormat::Rgba8Unorm | wgpu::TextureFormat::Rgba8UnormSrgb
    ) {
        return Err(GpuError::UnsupportedReadbackFormat { format });
    }
    readback_texels(ctx, texture, layer, RGBA8_BYTES_PER_TEXEL)
}

/// Reads mip 0 of array layer `layer` of a `COPY_SRC` texture whose texels are `bytes_per_texel` bytes
/// (the caller vouches for the format): `width · height · bytes_per_texel` bytes, rows top to bottom, no
/// padding. Blocks until the GPU is done.
pub fn readback_texels(
    ctx: &GpuContext,
    texture: &wgpu::Texture,
    layer: u32,
    bytes_per_texel: u32,
) -> Result<Vec<u8>, GpuError> {
    let (width, height) = (texture.width(), texture.height());
    check_readable(texture, layer)?;
    let overflow = || GpuError::SizeOverflow { width, height };
    let padded = padded_row_bytes(width, bytes_per_texel).ok_or_else(overflow)?;
    let buffer_size = u64::from(padded)
        .checked_mul(u64::from(height))
        .ok_or_else(overflow)?;
    let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("readback"),
        size: buffer_size,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = ctx
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("readback"),
        });
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: wgpu::Origin3d {
                x: 0,
                y: 0,
                z: layer,
            },
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(height),
            },
        },
        wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
    );
    ctx.queue.submit([encoder.finish()]);
    map_and_wait(ctx, &buffer)?;
    let view = buffer.get_mapped_range(..)?;
    let row_bytes = usize::try_from(width)
        .ok()
        .and_then(|w| w.checked_mul(bytes_per_texel as usize))
        .ok_or_else(overflow)?;
    let padded_usize = usize::try_from(padded).map_err(|_| overflow())?;
    let pixels = unpad_rows(&view, padded_usize, row_bytes);
    drop(view);
    buffer.unmap();
    Ok(pixels)
}

/// Checks usage and layer before a readback.
fn check_readable(texture: &wgpu::Texture, layer: u32) -> Result<(), GpuError> {
    if !texture.usage().contains(wgpu::TextureUsages::COPY_SRC) {
        return Err(GpuError::NotCopySource {
            width: texture.width(),
            height: texture.height(),
        });
    }
    let layers = texture.depth_or_array_layers();
    if layer >= layers {
        return Err(GpuError::LayerOutOfRange { layer, layers });
    }
    Ok(())
}

/// Maps the whole of `buffer` for reading and blocks until the mapping completed.
fn map_and_wait(ctx: &GpuContext, buffer: &wgpu::Buffer) -> Result<(), GpuError> {
    let (sender, receiver) = mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, .., move |result| {
        // The receiver outlives the poll below; a failed send only means it was dropped early.
        let _ = sender.send(result);
    });
    ctx.device.poll(wgpu::PollType::wait_indefinitely())?;
    match receiver.recv() {
        Ok(result) => Ok(result?),
        Err(mpsc::RecvError) => Err(GpuError::MapCallbackLost),
    }
}

/// Drops the row padding: `padded`-byte rows in, `row_bytes`-byte rows out.
fn unpad_rows(data: &[u8], padded: usize, row_bytes: usize) -> Vec<u8> {
    data.chunks_exact(padded.max(1))
        .flat_map(|row| row.iter().take(row_bytes))
        .copied()
        .collect()
}

/// A pipeline that draws one full-screen triangle (`vs_main` with no vertex buffers) with `fs_main` of
/// the WGSL `source` into one colour target of `format`, no blending, no depth: the blit of the viewer and
/// the supersampled reference's downsample.
pub fn fullscreen_pipeline(
    device: &wgpu::Device,
    label: &str,
    source: &str,
    layout: &wgpu::BindGroupLayout,
    format: wgpu::TextureFormat,
) -> wgpu::RenderPipeline {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: None,
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format,
                blend: None,
                write_mask: wgpu::ColorWrites::ALL,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// A render pass into `view` alone, cleared to black, no depth: the pass a [`fullscreen_pipeline`] draws in.
pub fn begin_fullscreen_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    view: &wgpu::TextureView,
) -> wgpu::RenderPass<'e> {
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(wgpu::Color::BLACK),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A missing adapter under a low open-files limit names the limit beside the install hint.
    #[test]
    fn no_adapter_names_a_low_open_files_limit() {
        let e = |open_files| {
            GpuError::NoAdapter {
                backends: "VULKAN".into(),
                open_files,
            }
            .to_string()
        };
        assert!(!e(OpenFiles::Enough).contains("ulimit"));
        assert!(e(OpenFiles::Low(7)).contains("the open-files limit of 7 (ulimit -n) is too low"));
        assert!(e(OpenFiles::Reached).contains("the open-files limit (ulimit -n) is too low"));
    }

    #[test]
    fn padded_rows_are_multiples_of_256() {
        assert_eq!(padded_row_bytes(1, 4), Some(256));
        assert_eq!(padded_row_bytes(64, 4), Some(256));
        assert_eq!(padded_row_bytes(65, 4), Some(512));
        assert_eq!(padded_row_bytes(100, 4), Some(512));
        assert_eq!(padded_row_bytes(u32::MAX, 4), None);
        assert_eq!(padded_row_bytes(17, 16), Some(512));
    }

    #[test]
    fn unpad_keeps_only_the_texels() {
        let data: Vec<u8> = (0..16).collect();
        assert_eq!(unpad_rows(&data, 8, 3), vec![0, 1, 2, 8, 9, 10]);
    }

    #[test]
    fn software_adapters_rank_last() {
        let hp = wgpu::PowerPreference::HighPerformance;
        let lp = wgpu::PowerPreference::LowPower;
        assert!(
            device_type_rank(wgpu::DeviceType::DiscreteGpu, hp)
                < device_type_rank(wgpu::DeviceType::IntegratedGpu, hp)
        );
        assert!(
            device_type_rank(wgpu::DeviceType::IntegratedGpu, lp)
                < device_type_rank(wgpu::DeviceType::DiscreteGpu, lp)
        );
        for t in [
            wgpu::DeviceType::DiscreteGpu,
            wgpu::DeviceType::IntegratedGpu,
            wgpu::DeviceType::VirtualGpu,
            wgpu::DeviceType::Other,
        ] {
            assert!(device_type_rank(t, hp) < device_type_rank(wgpu::DeviceType::Cpu, hp));
        }
    }
}
