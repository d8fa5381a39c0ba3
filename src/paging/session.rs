//! One frame of paging, the same for the renderer and the simulator: plan → loader → accept, with the
//! motion estimate that [`Policy::Ours`](super::Policy::Ours) uses for its lookahead, and the resolution of
//! the frame's cuts against residency with its screen-space accounting.

use super::loader::Loader;
use super::pager::{Applied, Arrival, Event, Pager, PagerFrameStats};
use super::policy::LOOKAHEAD_S;
use super::resolve::{Coarseness, Resolved, resolve_cut};
use super::usage::ViewInput;
use crate::camera::{Camera, Frustum};
use crate::ids::NodeId;
use crate::select::Cut;
use crate::store::format::NodeRecord;
use glam::DVec3;

/// The pager plus the per-frame state around it.
pub struct PagingSession {
    pub pager: Pager,
    arrivals: Vec<Arrival>,
    last_eye: Option<(DVec3, f64)>,
}

/// What one [`PagingSession::frame`] did.
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct SessionFrame {
    pub pager: PagerFrameStats,
    /// Requests not started / being transferred after the frame's poll.
    pub queued: u32,
    pub in_flight: u32,
}

impl PagingSession {
    pub fn new(pager: Pager) -> PagingSession {
        PagingSession {
            pager,
            arrivals: Vec::new(),
            last_eye: None,
        }
    }

    /// The eye predicted [`LOOKAHEAD_S`] ahead from the last frame's motion (`None` on the first frame or
    /// when the clock did not advance).
    fn lookahead(&mut self, eye: DVec3, now: f64) -> Option<DVec3> {
        let prediction = self.last_eye.and_then(|(e, t)| {
            let dt = now - t;
            (dt > 1e-9).then(|| eye + (eye - e) / dt * LOOKAHEAD_S)
        });
        self.last_eye = Some((eye, now));
        prediction.filter(|p| p.is_finite())
    }

    /// One frame at clock time `now` (seconds): usage and ideal set for `camera`, requests handed to
    /// `loader`, arrivals accepted, residency changes reported to `apply`.
    #[allow(clippy::too_many_arguments)]
    pub fn frame(
        &mut self,
        trees: &[&[NodeRecord]],
        camera: &Camera,
        frustum: &Frustum,
        scale: f64,
        now: f64,
        loader: &mut dyn Loader,
        apply: impl FnMut(Event) -> Applied,
    ) -> SessionFrame {
        let lookahead = self.lookahead(camera.eye, now);
        let view = ViewInput {
            eye: camera.eye,
            frustum,
            scale,
            lookahead,
        };
        let wanted = self.pager.plan(trees, &view);
        loader.set_requests(wanted);
        loader.poll(now, &mut self.arrivals);
        let pager = self.pager.accept(self.arrivals.drain(..), apply);
        SessionFrame {
            pager,
            queued: loader.queued(),
            in_flight: loader.in_flight(),
        }
    }
}

/// Resolves every tree's cut against residency (`atlas_resident(tree, node)`,
/// `originals_ready(tree, leaf node)`) into `out[tree]`, and returns the frame's screen accounting.
pub fn resolve_frame(
    trees: &[&[NodeRecord]],
    cuts: &[Cut],
    camera: &Camera,
    atlas_resident: impl Fn(usize, NodeId) -> bool,
    originals_ready: impl Fn(usize, NodeId) -> bool,
    out: &mut Vec<Vec<Resolved>>,
) -> Coarseness {
    out.resize_with(cuts.len(), Vec::new);
    let mut acc = Coarseness::default();
    for (t, (nodes, cut)) in trees.iter().zip(cuts).enumerate() {
        resolve_cut(
            nodes,
            &cut.items,
            camera,
            |n| atlas_resident(t, n),
            |n| originals_ready(t, n),
            &mut out[t],
            &mut acc,
        );
    }
    acc
}
