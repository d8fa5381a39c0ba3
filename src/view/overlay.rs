//! The egui inspector drawn over the frame: frame rate and a frame-time graph, the renderer's counters,
//! the paging counters (n/a until a pager is plugged in), the knobs (texel ratio, capacity) and toggles
//! (render mode, level colouring, node bounds, frozen selection, fly/orbit/follow), and the node bounds of
//! the cut projected as lines.

use super::controls::ControlMode;
use crate::camera::Camera;
use crate::render::{FrameStats, Mode};
use egui::{Color32, Pos2, Stroke};
use glam::{DVec3, DVec4};
use std::collections::VecDeque;

/// Frames kept by [`FrameTimes`] (4 s at 60 fps).
pub const HISTORY: usize = 240;
/// Most node boxes drawn by [`paint_bounds`] per frame (12 lines each).
pub const MAX_BOXES: usize = 4096;
/// Texel-ratio slider range (texels per pixel).
pub const TEXEL_RATIO_RANGE: std::ops::RangeInclusive<f64> = 0.125..=4.0;
/// Capacity slider range, blocks.
pub const CAPACITY_RANGE: std::ops::RangeInclusive<u32> = 1..=65_536;

/// Counters of the block pager for one frame (issue: paging under a capacity `k`).
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct PagingStats {
    /// Blocks the frame's cut needs.
    pub needed: u32,
    /// Blocks resident on the GPU.
    pub resident: u32,
    /// Block loads issued but not yet arrived.
    pub in_flight: u32,
    /// Block bytes arriving per second (averaged by the pager).
    pub bytes_per_second: f64,
    /// Fraction of the screen drawn with a coarser level than the cut asked for, in [0, 1].
    pub coarser_share: f64,
}

/// Recent frame times, seconds.
#[derive(Clone, Debug, Default)]
pub struct FrameTimes {
    times: VecDeque<f32>,
}

impl FrameTimes {
    /// Appends the duration of one frame (ignored unless finite and ≥ 0), dropping the oldest beyond
    /// [`HISTORY`].
    pub fn push(&mut self, seconds: f64) {
        if !(seconds.is_finite() && seconds >= 0.0) {
            return;
        }
        if self.times.len() == HISTORY {
            self.times.pop_front();
        }
        self.times.push_back(seconds as f32);
    }

    /// Frames per second over the history (0 when empty).
    pub fn fps(&self) -> f64 {
        let total: f64 = self.times.iter().map(|&t| f64::from(t)).sum();
        if total > 0.0 {
            self.times.len() as f64 / total
        } else {
            0.0
        }
    }

    /// The `q`-quantile (0..=1, nearest rank) of the history, seconds (0 when empty).
    pub fn percentile(&self, q: f64) -> f64 {
        let mut v: Vec<f32> = self.times.iter().copied().collect();
        v.sort_by(f32::total_cmp);
        let rank = ((v.len() as f64 - 1.0) * q.clamp(0.0, 1.0)).round() as usize;
        v.get(rank).map_or(0.0, |&t| f64::from(t))
    }

    /// The longest frame in the history, seconds.
    pub fn max(&self) -> f64 {
        self.times.iter().fold(0.0, |m, &t| m.max(f64::from(t)))
    }

    pub fn iter(&self) -> impl Iterator<Item = f64> + '_ {
        self.times.iter().map(|&t| f64::from(t))
    }

    pub fn len(&self) -> usize {
        self.times.len()
    }

    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }
}

/// The knobs and toggles; the window applies them every frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// Tree, Original or Dummy (level colouring is the separate `levels` toggle).
    pub mode: Mode,
    /// Colour tree-mode draws by atlas level ([`Mode::TreeLevels`]).
    pub levels: bool,
    /// Draw the bounds of the cut's nodes.
    pub bounds: bool,
    /// Keep the cut of the camera at the moment of freezing.
    pub freeze: bool,
    /// Required texels per pixel (scales every node's `min_distance`).
    pub texel_ratio: f64,
    /// Block capacity `k` of the pager (disabled until paging is plugged in).
    pub capacity: u32,
    /// Show the inspector window.
    pub show_overlay: bool,
    pub control: ControlMode,
    /// Follow the camera path (only with `--path`).
    pub follow: bool,
}

impl Settings {
    /// The mode the renderer draws with.
    pub fn render_mode(&self) -> Mode {
        match (self.mode, self.levels) {
            (Mode::Tree | Mode::TreeLevels, true) => Mode::TreeLevels,
            (Mode::TreeLevels, false) => Mode::Tree,
            (m, _) => m,
        }
    }
}

/// One-shot requests from the inspector's buttons.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub struct Requests {
    pub frame_scene: bool,
    pub screenshot: bool,
    pub toggle_recording: bool,
}

/// What the inspector shows that it does not edit.
pub struct Readout<'a> {
    pub stats: &'a FrameStats,
    pub times: &'a FrameTimes,
    pub paging: Option<PagingStats>,
    pub size: (u32, u32),
    pub camera: &'a Camera,
    pub speed: f64,
    pub adapter: &'a str,
    /// Keyframes recorded so far, `None` when not recording.
    pub recording: Option<usize>,
    pub has_path: bool,
    /// The last status message (screenshot written, …).
    pub message: &'a str,
}

/// Draws the inspector window (when shown) and returns the button requests.
pub fn inspector(ctx: &egui::Context, s: &mut Settings, r: &Readout<'_>) -> Requests {
    let mut req = Requests::default();
    if !s.show_overlay {
        return req;
    }
    egui::Window::new("atlastree view")
        .default_pos([8.0, 8.0])
        .default_width(250.0)
        .resizable(false)
        .vscroll(true)
        .show(ctx, |ui| {
            performance(ui, r);
            ui.separator();
            paging(ui, s, r.paging);
            ui.separator();
            knobs(ui, s, r.has_path);
            ui.separator();
            camera_section(ui, r, &mut req);
            if !r.message.is_empty() {
                ui.label(r.message);
            }
        });
    req
}

fn performance(ui: &mut egui::Ui, r: &Readout<'_>) {
    let s = r.stats;
    ui.label(format!(
        "{:.1} fps   {:.1} ms max   {}×{}",
        r.times.fps(),
        r.times.max() * 1e3,
        r.size.0,
        r.size.1
    ));
    frame_graph(ui, r.times);
    let gpu = s.gpu_ms.map_or("n/a".to_owned(), |g| format!("{g:.2} ms"));
    pairs(
        ui,
        "counters",
        &[
            ("nodes drawn", s.plan.nodes_drawn.to_string()),
            ("visited", s.plan.nodes_visited.to_string()),
            ("draw calls", s.draw_calls.to_string()),
            ("binds", s.bind_group_changes.to_string()),
            ("triangles", s.triangles.to_string()),
            ("select", format!("{:.0} µs", s.plan.select_us)),
            ("GPU", gpu),
            ("frame", format!("{:.1} ms", s.frame_ms)),
        ],
    );
}

/// A grid of `(name, value)` pairs, two pairs per row.
fn pairs(ui: &mut egui::Ui, id: &str, items: &[(&str, String)]) {
    egui::Grid::new(id).num_columns(4).show(ui, |ui| {
        for row in items.chunks(2) {
            for (k, v) in row {
                ui.weak(*k);
                ui.monospace(v);
            }
            ui.end_row();
        }
    });
}

/// The frame-time graph: one bar per frame of the history, with the 16.7 ms and 33.3 ms marks.
fn frame_graph(ui: &mut egui::Ui, times: &FrameTimes) {
    let (rect, _) =
        ui.allocate_exact_size(egui::vec2(ui.available_width(), 32.0), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 2.0, Color32::from_black_alpha(120));
    // Scale to 1.5 × the 90th percentile (at least 40 ms): one shader-compile stall does not flatten the
    // rest; taller bars are clipped.
    let top_ms = (times.percentile(0.9) * 1.5e3).max(40.0);
    let y_of = |ms: f64| rect.bottom() - (ms / top_ms) as f32 * rect.height();
    for mark in [1000.0 / 60.0, 1000.0 / 30.0] {
        let y = y_of(mark);
        painter.hline(rect.x_range(), y, Stroke::new(1.0, Color32::from_gray(90)));
    }
    let step = rect.width() / HISTORY as f32;
    let start = HISTORY.saturating_sub(times.len());
    for (i, t) in times.iter().enumerate() {
        let x = rect.left() + (start + i) as f32 * step;
        painter.vline(
            x,
            y_of(t * 1e3)..=rect.bottom(),
            Stroke::new(step.max(1.0), Color32::from_rgb(120, 200, 120)),
        );
    }
}

fn paging(ui: &mut egui::Ui, s: &mut Settings, p: Option<PagingStats>) {
    let na = || "n/a".to_owned();
    ui.label(if p.is_some() {
        "paging"
    } else {
        "paging: n/a (all blocks resident)"
    });
    pairs(
        ui,
        "paging",
        &[
            ("needed", p.map_or_else(na, |p| p.needed.to_string())),
            ("resident", p.map_or_else(na, |p| p.resident.to_string())),
            ("in flight", p.map_or_else(na, |p| p.in_flight.to_string())),
            (
                "MiB/s",
                p.map_or_else(na, |p| format!("{:.1}", p.bytes_per_second / 1048576.0)),
            ),
            (
                "coarser",
                p.map_or_else(na, |p| format!("{:.1} %", p.coarser_share * 100.0)),
            ),
        ],
    );
    ui.add_enabled(
        p.is_some(),
        egui::Slider::new(&mut s.capacity, CAPACITY_RANGE)
            .logarithmic(true)
            .text("capacity k"),
    );
}

fn knobs(ui: &mut egui::Ui, s: &mut Settings, has_path: bool) {
    ui.add(
        egui::Slider::new(&mut s.texel_ratio, TEXEL_RATIO_RANGE)
            .logarithmic(true)
            .text("texels/pixel"),
    );
    ui.horizontal(|ui| {
        ui.radio_value(&mut s.mode, Mode::Tree, "tree [1]");
        ui.radio_value(&mut s.mode, Mode::Original, "original [2]");
        ui.radio_value(&mut s.mode, Mode::Dummy, "dummy [3]");
    });
    ui.horizontal(|ui| {
        ui.add_enabled(
            s.mode == Mode::Tree,
            egui::Checkbox::new(&mut s.levels, "levels [L]"),
        );
        ui.checkbox(&mut s.bounds, "bounds [B]");
        ui.checkbox(&mut s.freeze, "freeze [G]");
    });
    ui.horizontal(|ui| {
        ui.radio_value(&mut s.control, ControlMode::Fly, "fly");
        ui.radio_value(&mut s.control, ControlMode::Orbit, "orbit [O]");
        ui.add_enabled(has_path, egui::Checkbox::new(&mut s.follow, "follow"));
    });
}

fn camera_section(ui: &mut egui::Ui, r: &Readout<'_>, req: &mut Requests) {
    let e = r.camera.eye;
    ui.label(format!(
        "eye {:.1} {:.1} {:.1}   speed {:.1}/s",
        e.x, e.y, e.z, r.speed
    ));
    ui.horizontal(|ui| {
        req.frame_scene = ui.button("frame [F]").clicked();
        req.screenshot = ui.button("shot [P]").clicked();
        let rec = match r.recording {
            Some(n) => format!("stop [R] ({n})"),
            None => "record [R]".to_owned(),
        };
        req.toggle_recording = ui.button(rec).clicked();
    });
    ui.small(r.adapter);
}

/// The level palette of `tree.wgsl`'s `level_colour`, linear RGB.
const LEVEL_PALETTE: [[f64; 3]; 8] = [
    [0.90, 0.10, 0.10],
    [0.10, 0.75, 0.10],
    [0.10, 0.20, 0.95],
    [0.95, 0.85, 0.10],
    [0.85, 0.10, 0.85],
    [0.10, 0.85, 0.85],
    [0.95, 0.50, 0.05],
    [0.50, 0.30, 0.90],
];

/// Colour of level `level` in the bounds overlay: the colour `tree.wgsl`'s level colouring shows, its
/// linear palette encoded to sRGB as the frame's target does (the palette's values taken as sRGB bytes
/// drew level 0 as (230, 26, 26) beside frames of (243, 89, 89); fault hunt, session 38).
pub fn level_colour(level: u8) -> Color32 {
    let [r, g, b] = LEVEL_PALETTE[usize::from(level) % LEVEL_PALETTE.len()]
        .map(crate::util::srgb::linear_to_srgb8);
    Color32::from_rgb(r, g, b)
}

/// The 12 edges of the box `[lo, hi]` projected for `camera` into a `width`×`height` pixel viewport
/// (origin top left, y down), each clipped to the part in front of the near plane; edges wholly behind
/// are dropped. Positions are relative to the eye before anything else (f64), as the renderer does.
pub fn box_lines(camera: &Camera, lo: DVec3, hi: DVec3, width: f64, height: f64) -> Vec<[Pos2; 2]> {
    let m = camera.view_proj_relative();
    let corner = |i: usize| {
        let p = DVec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        );
        m * (p - camera.eye).extend(1.0)
    };
    let clip: [DVec4; 8] = std::array::from_fn(corner);
    const EDGES: [(usize, usize); 12] = [
        (0, 1),
        (2, 3),
        (4, 5),
        (6, 7),
        (0, 2),
        (1, 3),
        (4, 6),
        (5, 7),
        (0, 4),
        (1, 5),
        (2, 6),
        (3, 7),
    ];
    // Clip space w is the view depth; keep the part with w ≥ near.
    let near = camera.near;
    let to_px = |c: DVec4| {
        Pos2::new(
            ((c.x / c.w * 0.5 + 0.5) * width) as f32,
            ((0.5 - c.y / c.w * 0.5) * height) as f32,
        )
    };
    EDGES
        .iter()
        .filter_map(|&(a, b)| {
            let (mut p, mut q) = (clip[a], clip[b]);
            if p.w < near && q.w < near {
                return None;
            }
            if p.w < near {
                p = p + (q - p) * ((near - p.w) / (q.w - p.w));
            } else if q.w < near {
                q = q + (p - q) * ((near - q.w) / (p.w - q.w));
            }
            Some([to_px(p), to_px(q)])
        })
        .collect()
}

/// One node box to outline: world bounds and the node's level.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct NodeBox {
    pub lo: DVec3,
    pub hi: DVec3,
    pub level: u8,
}

/// Paints up to [`MAX_BOXES`] node boxes behind the inspector, coloured by level; returns how many.
pub fn paint_bounds(
    ctx: &egui::Context,
    camera: &Camera,
    boxes: &[NodeBox],
    size_px: (u32, u32),
) -> usize {
    let ppp = f64::from(ctx.pixels_per_point());
    let (w, h) = (f64::from(size_px.0) / ppp, f64::from(size_px.1) / ppp);
    let painter = ctx.layer_painter(egui::LayerId::background());
    let shown = boxes.len().min(MAX_BOXES);
    for b in &boxes[..shown] {
        let stroke = Stroke::new(1.0, level_colour(b.level));
        for [p, q] in box_lines(camera, b.lo, b.hi, w, h) {
            painter.line_segment([p, q], stroke);
        }
    }
    shown
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            eye: DVec3::new(1000.0, 5.0, 2000.0),
            target: DVec3::new(1000.0, 5.0, 1990.0),
            up: DVec3::Y,
            fov_x_deg: 90.0,
            aspect: 2.0,
            near: 0.5,
            far: 1000.0,
        }
    }

    #[test]
    fn frame_times_fps_and_window() {
        let mut t = FrameTimes::default();
        assert_eq!(t.fps(), 0.0);
        for _ in 0..HISTORY + 10 {
            t.push(0.02);
        }
        t.push(f64::NAN);
        t.push(-1.0);
        assert_eq!(t.len(), HISTORY);
        assert!((t.fps() - 50.0).abs() < 1e-3);
        t.push(0.1);
        assert!((t.max() - 0.1).abs() < 1e-6);
        assert!((t.percentile(0.9) - 0.02).abs() < 1e-6);
        assert!((t.percentile(1.0) - 0.1).abs() < 1e-6);
        assert_eq!(FrameTimes::default().percentile(0.5), 0.0);
    }

    #[test]
    fn render_mode_combines_mode_and_levels() {
        let mut s = Settings {
            mode: Mode::Tree,
            levels: false,
            bounds: false,
            freeze: false,
            texel_ratio: 1.0,
            capacity: 1,
            show_overlay: true,
            control: ControlMode::Fly,
            follow: false,
        };
        assert_eq!(s.render_mode(), Mode::Tree);
        s.levels = true;
        assert_eq!(s.render_mode(), Mode::TreeLevels);
        s.mode = Mode::Original;
        assert_eq!(s.render_mode(), Mode::Original);
        s.mode = Mode::Dummy;
        assert_eq!(s.render_mode(), Mode::Dummy);
    }

    #[test]
    fn a_box_ahead_projects_symmetrically() {
        // A 2×2×2 box centred 10 units ahead: 90° horizontal fov, so its front face (9 ahead) spans
        // x = ±1/9 of the half width around the centre.
        let c = camera();
        let centre = c.target;
        let lines = box_lines(&c, centre - 1.0, centre + 1.0, 800.0, 400.0);
        assert_eq!(lines.len(), 12);
        let xs: Vec<f32> = lines.iter().flat_map(|l| [l[0].x, l[1].x]).collect();
        let ys: Vec<f32> = lines.iter().flat_map(|l| [l[0].y, l[1].y]).collect();
        let (min_x, max_x) = xs
            .iter()
            .fold((f32::MAX, f32::MIN), |(a, b), &x| (a.min(x), b.max(x)));
        let (min_y, max_y) = ys
            .iter()
            .fold((f32::MAX, f32::MIN), |(a, b), &y| (a.min(y), b.max(y)));
        assert!((min_x - (400.0 - 400.0 / 9.0)).abs() < 1e-3, "{min_x}");
        assert!((max_x - (400.0 + 400.0 / 9.0)).abs() < 1e-3, "{max_x}");
        // Vertical: tan(fov_y/2) = 1/2, so one unit at depth 9 is (1/9)/(1/2) of the half height.
        assert!(
            (min_y - (200.0 - 200.0 * 2.0 / 9.0)).abs() < 1e-3,
            "{min_y}"
        );
        assert!(
            (max_y - (200.0 + 200.0 * 2.0 / 9.0)).abs() < 1e-3,
            "{max_y}"
        );
    }

    #[test]
    fn boxes_behind_are_dropped_and_straddling_edges_clipped() {
        let c = camera();
        let behind = DVec3::new(1000.0, 5.0, 2010.0);
        assert!(box_lines(&c, behind - 1.0, behind + 1.0, 800.0, 400.0).is_empty());
        // A long box from behind the eye to far ahead: every edge is kept, clipped to finite positions.
        let lo = DVec3::new(998.0, 4.0, 1950.0);
        let hi = DVec3::new(1002.0, 6.0, 2050.0);
        let lines = box_lines(&c, lo, hi, 800.0, 400.0);
        // Edges along z straddle (4), x/y edges of the far face are ahead (4), of the near face behind (4).
        assert_eq!(lines.len(), 8);
        assert!(
            lines
                .iter()
                .flatten()
                .all(|p| p.x.is_finite() && p.y.is_finite())
        );
    }

    #[test]
    fn level_colours_cycle() {
        assert_eq!(level_colour(0), level_colour(8));
        assert_ne!(level_colour(0), level_colour(1));
        // The shader's palette, and level 0 as a level-coloured frame shows it.
        let wgsl = include_str!("../../shaders/tree.wgsl");
        for [r, g, b] in LEVEL_PALETTE {
            let v = format!("vec3<f32>({r:.2}, {g:.2}, {b:.2})");
            assert!(wgsl.contains(&v), "{v} is not in tree.wgsl's palette");
        }
        assert_eq!(level_colour(0), Color32::from_rgb(243, 89, 89));
    }
}
