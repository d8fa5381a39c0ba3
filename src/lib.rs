//! # atlastree
//!
//! Texture-atlas trees (Buchholz & Döllner 2005) for massively textured, planar-distributed scenes,
//! rendered with texture-array batching (Trapp & Döllner 2015).
//!
//! ## Data flow
//!
//! ```text
//! glTF ──scene::import──▶ Scene ──preprocess──▶ model::AtlasForest ──store::write──▶ .atlastree file
//!                                                                                       │ memmap2
//!   camera, time ──▶ plan::FramePlanner ─────────────────────────────────────────────────┤
//!                     select (per-frame cut) → paging (ideal set, queue, loads) → resolve  │
//!                     │ plain data: FramePlan (cuts, residency changes, resolved items)    ▼
//!                     ├──▶ render::Renderer (batch → indirect records → wgpu, colour or density)
//!                     └──▶ sim (the same plans on an I/O model, no GPU) · view · sweep · render CLI
//! ```
//!
//! - [`scene`]: glTF 2.0 import into a world-space triangle soup with f64 positions, materials, wrap modes,
//!   alpha modes and lazily decoded images.
//! - [`model`]: the atlas-tree model every stage reads: forest, nodes, leaves, rects, vertex records, the
//!   per-node texture transforms and the per-triangle sizing rule (§5.2.1). No stage imports the preprocessor
//!   to read a tree.
//! - [`preprocess`]: the preprocessor. Sizing (§5.2.1), required areas (§5.2.2) with repeats held as one period
//!   per rect and wrapped in the shader (§8.2 future work; `--repeat bake` stores them as the paper does),
//!   MaxRects packing (§5.2.3), splitting balanced by texel demand (§5.3 condition b), scaled leaves where
//!   deeper atlases would only copy the originals, leaf atlas rasterisation in linear light with borders by
//!   the sampler's rule, inner atlases by 2×2 combine and halve (§5.1), per-node texture transforms in the
//!   exact form of docs/DESIGN.md "Precision", all in a local frame (translation-invariant trees).
//! - [`store`]: the paging file. Pod records read in place from a memory map, 4 KiB-aligned checksummed
//!   blocks, atomic writes; each original texture stored once per tree at its own power-of-two sides, in
//!   blocks grouped by the leaves that show it, referenced by every one of them (format 5).
//! - [`gpu`]: wgpu device setup shared by the renderer and the GPU tests.
//! - [`camera`]: cameras, frusta, distance to bounds, keyframed and generated camera paths (f64).
//! - [`select`]: the per-frame cut (§4): hierarchical culling, distance test, atlas or original textures.
//! - [`plan`]: the frame planner, the one per-frame loop: (camera, time) → [`plan::FramePlan`] by select →
//!   page → resolve, with the residency changes handed to the executor (the renderer's texture arrays, or
//!   nothing for the simulator).
//!
//! - [`render`]: the wgpu renderer, executing plans. Atlases are layers of texture arrays, original textures
//!   layers of one array per class size, uploaded as blocks become resident; [`render::batch`] turns a plan's
//!   cuts into indirect records (plain data), and a frame is one bind group and one multi-draw-indirect call
//!   per pipeline (texture-array batching).
//! - [`texfmt`]: block formats of the paging file (RGBA8, BC1/BC3/BC7): sizes, CPU encode and decode.
//! - [`inspect`]: reports and `verify` (every checksum and tree invariant) of a paging file.
//! - [`report`]: experiment reporting: the one per-frame CSV schema, PSNR/SSIM and texel-density measures, Pareto fronts, deterministic
//!   CSV and SVG + PNG plots (line, heat map, Pareto scatter, bars) with an embedded font.
//! - [`view`]: the interactive window (winit + egui inspector) over the same renderer.
//! - [`export`]: the tree as a 3D Tiles 1.1 tileset for CesiumJS, 3DTilesRendererJS and other clients
//!   (docs/3dtiles.md): one tile per node, geometry once per leaf, levels by `KHR_texture_transform`.
//! - [`sweep`]: what accuracy costs in time: builds and renders a grid of knob values (d_min, atlas size,
//!   border, filter, texel ratio, capacity), compares every frame with the original-texture reference and
//!   writes CSV tables, plots with the Pareto front and a report with recommended defaults.
//!
//! - [`paging`]: prioritised block paging (§6): usage categories, the ideal set under a capacity k, the
//!   re-ranked request queue, loaders (synchronous, threads, HTTP), residency, drawing with missing blocks.
//! - [`sim`]: paging-budget experiments without a GPU: the same frame planner on a frame clock with an I/O
//!   model; grids over capacity × bandwidth × latency × policy.

// An item is `pub` only where a caller outside the crate can reach it (the binary, tests, tools); the rest
// is `pub(crate)` or narrower, so the public surface is what the modules re-export.
#![warn(unreachable_pub)]

pub mod camera;
pub mod export;
pub mod gpu;
pub mod ids;
pub mod inspect;
pub mod memory_window;
pub mod model;
pub mod paging;
pub mod plan;
pub mod preprocess;
pub mod render;
pub mod report;
pub mod scene;
pub mod select;
pub mod sim;
pub mod store;
pub mod sweep;
pub mod texfmt;
pub mod util;
pub mod view;
